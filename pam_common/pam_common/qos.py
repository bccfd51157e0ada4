"""The stack's QoS profiles: the one place they are written (the topic names: pam_common.topics).

    SAMPLE_QOS  pressures, supply_pressure, joint_measured, valve_command, estimate,
                controller_state (both ends), joint_states and estimate/joint_states
                (publishers), and every subscription of the 1 kHz loop (pi_node's reference
                too)
    LATEST_QOS  reference (reference_node's publisher), the driver's ~/applied_command,
                /diagnostics, /clock (CLOCK_QOS)
    VIEW_QOS    every subscription of a viewer (pam-foxglove)
    RECORD_QOS  every subscription of a recorder of the loop (tracking_report)

bag_record and bag_play do not use these: they take each topic's QoS from its publishers or
from the bag.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: The 1 kHz sample streams and what answers them: reliable, keep last 100, volatile. A 1 kHz
#: loop across processes loses nothing with depth 100; a subscriber that joins late gets no
#: history.
SAMPLE_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        depth=100, durability=DurabilityPolicy.VOLATILE)
#: Slower topics where the latest values matter: reliable, keep last 10, volatile (rclpy's
#: default profile, what a bare depth of 10 gives).
LATEST_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        depth=10, durability=DurabilityPolicy.VOLATILE)
#: /clock: LATEST_QOS, compatible with rclpy's best-effort /clock subscription.
CLOCK_QOS = LATEST_QOS
#: A viewer's subscriptions (pam-foxglove): best effort, keep last 100, volatile. Compatible with
#: every publisher above (and /rosout's); a publisher resends nothing to it and waits for no
#: acknowledgement from it, so a slow viewer never holds the stack up (it misses samples instead).
VIEW_QOS = QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT, history=HistoryPolicy.KEEP_LAST,
                      depth=100, durability=DurabilityPolicy.VOLATILE)
#: The deepest keep-last queue a subscription gets: Fast DDS caps a reader's history at its
#: resource limit max_samples, 5000 by default (rclpy cannot set it), and a deeper KEEP_LAST
#: depth then keeps the OLDEST 5000 samples and refuses the newer ones (measured with rclpy on
#: Jazzy: depth 6000 or 30000 -> samples 0..4999 of 12000 kept, depth 4999 -> the last 4999).
RECORD_DEPTH = 5000
#: A recorder's subscriptions of the 1 kHz streams (tracking_report): SAMPLE_QOS with a queue of
#: RECORD_DEPTH. A recorder is not part of the loop: a lockstep loop goes as fast as its three
#: nodes answer (600-1500 steps/s on the 2-core development machine), and a recorder starved of
#: CPU for a moment (a busy machine, a collection) falls behind; the queue lets it catch up
#: afterwards instead of losing what arrived meanwhile. Memory is taken as samples queue (about
#: 0.1 kB each), none while it keeps up.
RECORD_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        depth=RECORD_DEPTH, durability=DurabilityPolicy.VOLATILE)
