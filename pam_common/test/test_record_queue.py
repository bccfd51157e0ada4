"""pam_common.qos.RECORD_QOS over real DDS: a recorder that has not taken its samples for a while
gets the newest RECORD_DEPTH of them when it does, in order (a keep-last queue). A depth beyond
what Fast DDS keeps (its reader's max_samples, 5000 by default) would keep the oldest 5000 and
refuse the newer ones instead: this test catches a RECORD_DEPTH raised past it."""

import time

from rclpy.executors import SingleThreadedExecutor

from pam_common.qos import RECORD_DEPTH, RECORD_QOS, SAMPLE_QOS
from pam_common.testing import wait_until
from pam_interfaces.msg import JointMeasurement

BACKLOG = 1500      # samples published beyond the queue while the recorder does not take them


def test_a_recorder_behind_gets_the_newest_samples_of_its_queue(ros_context):
    import rclpy

    sender = rclpy.create_node('record_queue_sender', context=ros_context)
    recorder = rclpy.create_node('record_queue_recorder', context=ros_context)
    received = []
    recorder.create_subscription(JointMeasurement, '/record_queue_test',
                                 lambda msg: received.append(int(msg.angle)), RECORD_QOS)
    publisher = sender.create_publisher(JointMeasurement, '/record_queue_test', SAMPLE_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(recorder)
    try:
        assert wait_until(lambda: publisher.get_subscription_count() > 0, 30.0)
        total = RECORD_DEPTH + BACKLOG
        for k in range(total):          # ~2.5 kHz: delivered as sent, nothing to repair
            publisher.publish(JointMeasurement(angle=float(k)))
            if k % 10 == 9:
                time.sleep(0.004)
        time.sleep(1.0)                 # every sample delivered to the recorder's queue
        end = time.monotonic() + 30.0
        while len(received) < RECORD_DEPTH and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        executor.spin_once(timeout_sec=0.2)     # nothing beyond the queue
    finally:
        executor.shutdown()
        recorder.destroy_node()
        sender.destroy_node()
    assert received == list(range(BACKLOG, total)), (len(received), received[:3], received[-3:])


def test_the_probe_refuses_a_queue_deeper_than_a_reader_keeps(probe):
    import pytest
    from std_msgs.msg import Float64

    for depth in (0, RECORD_DEPTH + 1):
        with pytest.raises(ValueError, match=f'depth {depth}: a subscription keeps 1 to '):
            probe.subscribe(Float64, '/record_queue_test/probe', depth=depth)
    assert probe.subscribe(Float64, '/record_queue_test/probe', depth=RECORD_DEPTH) is not None
