"""sim_node: the simulated antagonistic PAM rig, a drop-in for the hardware driver.

A thin ROS wrapper around pam_driver.sim_core.SimCore, which holds every decision without ROS
(when the plant steps, which commands apply, what a sample reads, the rig's health) over
pam_model.rig.SimulatedRig (physics, sensor model, command sanitising and counting). Run
`sim_node --help` for the parameters.

Topics (relative names resolve under the node namespace, '/pam' unless remapped with
`--ros-args -r __ns:=/other`):

    pressures       pam_interfaces/Pressures         published, one per sample (1 kHz by default):
                                                     measured P1, P2 (Pa abs) with sensor noise;
                                                     sample = the plant's step k + 1 (1, 2, ...)
    joint_measured  pam_interfaces/JointMeasurement  published with every sample: ground truth
                                                     angle (rad), angular velocity (rad/s) and
                                                     true torque (N m)
    valve_command   pam_interfaces/ValveCommand      subscribed: u1, u2 (V), held until the next
    joint_states    sensor_msgs/JointState           joint_measured for the standard tools: one
                                                     joint (joint_name), position rad, velocity
                                                     rad/s, effort N m, the same stamps; every
                                                     sample, or fewer (joint_states_rate)
    /diagnostics    diagnostic_msgs/DiagnosticArray  published about once a second (absolute name)
    /clock          rosgraph_msgs/Clock              if publish_clock: with 1 sample in
                                                     round(rate / clock_rate), every by default
    supply_pressure sensor_msgs/FluidPressure        published with every sample if
                                                     publish_supply_pressure: the plant's supply
                                                     pressure P_tank (Pa abs; the effects' droop
                                                     and ripple, when the scenario has them)
                                                     measured by the pressure sensor model,
                                                     the stamp of the sample's pressures, variance
                                                     noise^2 + resolution^2/12 (Pa^2)
                                                     (pam_driver.supply_sensor)

QoS: pressures, joint_measured, joint_states and valve_command are RELIABLE, KEEP_LAST depth 100,
VOLATILE (a 1 kHz loop across processes loses none with depth 100; a subscriber that joins late
gets no history). /diagnostics is reliable, keep last 10; /clock reliable, keep last 10 (compatible
with rclpy's best-effort /clock subscription).

Timing 'realtime': a dedicated thread (not an rclpy timer) sleeps to absolute deadlines
start + n/rate on the monotonic clock, so there is no drift. At each deadline it steps the model
once with the command held at that moment (h = 1/rate), reads the sensors and publishes, stamped
with the deadline's time on the node clock (system time; this node never runs on simulated
time): sample k is stamped start + k/rate, whenever it left. The simulated rig behaves like a
rig: its plant follows the wall clock and NEVER PAUSES. A controller that answers late finds the
valves holding its last command (zero-order hold) while the joint moves on. If the sampling
thread itself wakes up late (the machine is overloaded), the plant has stepped through every
deadline that passed, each one model step h after the previous one with the command held then,
and those samples wait in a backlog and are published in order, late, as a DAQ board's samples
wait in the serial line for a late driver (pam_driver.sim_core.RealtimeSampler): the loop sees
every sample as it was. At most max_catch_up overdue samples wait; after a longer stall the
oldest are dropped unpublished (*missed samples*, a gap in the sample counter), so the plant's
time stays on the wall clock and an overloaded process is not handed a backlog it cannot take.
Samples published from the backlog and missed samples are *late samples*
(published more than one period after their deadline, or never), and the longest lateness is
the *worst stall*. A run with late
samples was not real time: the rig reports it (/diagnostics) and tracking_report / pam-demo mark
such a run INVALID (pam_common.run_health), never as a result. Consumers step their models by h,
not by stamp differences. Subscriptions and timers are spun by
rclpy.experimental.EventsExecutor (SingleThreadedExecutor if that is unavailable), in bounded
slices (see pam_common.executors). The real-time knobs thread_priority (SCHED_FIFO), cpu_affinity
and lock_memory apply to the executor thread and the sampler thread (sim_node_sampler), each
logged when granted and a warning when refused (pam_common.realtime_knobs, docs/realtime.md).

Sample counter (Pressures.sample): k + 1 for the sample after k model steps, in both timings. A
re-published lockstep sample keeps its counter (a repeat); a missed sample (realtime, above) and
a non-finite sample suppressed leave a gap (a sample the rig took and nobody got), counted by the
rig; any other gap seen downstream is a sample lost on its way.

Timing 'lockstep': sample k is stamped with simulated time t_k = k/rate. The plant steps k -> k+1
only when a command for step k arrives: a ValveCommand whose header.stamp >= t_k (a zero stamp
means "for the current step"); the node applies it, steps, and publishes sample k+1. A command
with stamp < t_k comes from the past: it is ignored and counted. While waiting, the current sample
is re-published unchanged (same stamp, same noise draw) every lockstep_timeout s, so a controller
that joins late can start. Same seed + same commands give bit-identical pressures. With
publish_clock, /clock carries t_k (of 1 sample in round(rate / clock_rate)).

Bad input: non-finite voltages become 0 V (vent), out-of-range ones are clipped to [0, 10] V (by
SimulatedRig.set_command); they are counted, logged at most once a second, and reported on
/diagnostics (level WARN while bad commands arrived in the last window). The node never dies on
input and never publishes a non-finite sample.

/diagnostics: one DiagnosticStatus '/pam/sim_node: simulated rig' (the node's fully qualified
name; hardware_id the parameter, by default the namespace) with the timing, target and
achieved rate, late steps and max lateness (ms) of the last window, samples published, last
sample counter, commands received, non-finite / out-of-range commands, past commands ignored,
last command u1/u2 (V, as applied), joint mode and plant set; in realtime, since the start or the
last `~/reset_statistics` call (std_srvs/Trigger): 'samples taken', 'late samples', 'missed
samples', 'worst stall (ms)' (the rig's own timing) and the sample -> command latency at the
rig (pam_common.latency: each command's arrival minus the stamp of the sample it answers,
p50/p99/p99.9/max in ms, and the commands that came after the next sample was taken); log lines
suppressed
(the warnings on the sample and command paths are throttled to one a second each, the lines left
out counted, pam_common.throttled_log). Level ERROR if the sampling thread failed or a
non-finite sample was ever suppressed; WARN if, in the last window, bad or past commands
arrived, or (realtime) the achieved rate was off by more than 5 % or any sample was late (the
loop was not real time); OK otherwise.

At DEBUG (`--ros-args --log-level pam.sim_node:=debug`): the valve command applied, when it
changes markedly: the first command, then one that differs from the last such line's by more than
COMMAND_STEP_DEBUG (0.5 V) in u1 or u2 (a sanitised command as applied). A command from the past
(lockstep) is no applied command.
"""

from __future__ import annotations

import os
import sys
import threading
import time

import rclpy
from rclpy.logging import LoggingSeverity
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure
from std_srvs.srv import Trigger

from pam_common.diagnostics import DiagnosticsPublisher
from pam_common.executors import LOCKSTEP_PUBLICATION_MODE, PUBLICATION_MODE_VARIABLE
from pam_common.links import LinkedNode, ProcessLinks, SampleLoop, process_links
from pam_common.node_skeleton import Component, component_main, parameter_values
from pam_common.qos import CLOCK_QOS, SAMPLE_QOS
from pam_common.realtime_knobs import RealtimeKnobs
from pam_common.stamps import ns_stamp, stamp_ns
from pam_common.throttled_log import ThrottledLogs
from pam_common.topics import (
    CLOCK,
    DEFAULT_NAMESPACE,
    SUPPLY_PRESSURE,
    VALVE_COMMAND,
)
from pam_driver.rig_publishers import (
    build_header,
    build_joint,
    build_pressures,
    rig_publishers,
)
from pam_driver.sim_config import PARAMETERS, ConfigError, build_config, usage_text
from pam_driver.sim_core import RealtimeSampler, SimCore, SimSample
from pam_interfaces.msg import ValveCommand
from pam_model.valve_voltage import SANITISE_RULE

NODE_NAME = 'sim_node'
DIAGNOSTICS_PERIOD = 1.0   # s
LOG_THROTTLE = 1.0         # s between two log lines about bad input
COMMAND_STEP_DEBUG = 0.5   # V: a DEBUG line when the applied command moves this far



class SimNode(LinkedNode):
    """The simulated rig. Construct, then configure() (raises ConfigError), then start()."""

    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = None
        self.core = None            # SimCore: the plant and every decision
        self._stop = threading.Event()
        self._thread = None
        self._lockstep_timer = None
        self._marked_command = None  # the applied command of the last marked change (V)
        self._previous_marked = None  # the one before it
        self._last_publish = 0.0    # monotonic time of the last (re)publication
        self._logs = ThrottledLogs(self.get_logger(), LOG_THROTTLE)
        self._log_nonfinite = self._logs.new('error')
        self._log_past, self._log_bad = self._logs.new(), self._logs.new()

    # ------------------------------------------------------------------ set-up
    def configure(self) -> None:
        """Declare and check every parameter, build the plant and the ROS interfaces."""
        self.config = config = parameter_values(self, PARAMETERS, check=build_config)
        if self.get_parameter('use_sim_time').value:
            self.get_logger().warning('use_sim_time is true: ignored, the simulated rig runs on '
                                      'the system clock (it publishes /clock itself with '
                                      'publish_clock)')
            self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, False)])

        # the knobs of the 1 kHz path (pam_common.realtime_knobs): this thread is the executor's
        self._realtime = RealtimeKnobs(self.get_logger(), config.realtime)
        self._realtime.apply_to_executor()
        self.core = SimCore(config)
        warm_up = config.make_rig()  # load the compiled model now, not at the 2nd sample
        warm_up.step()
        warm_up.sample()
        self._frame_id = config.frame_id
        self._lockstep = config.lockstep

        # non-finite -> the last finite value; JointState from joint_measured after its guard
        rate = config.joint_states_rate
        rig = rig_publishers(self, self._frame_id, config.joint_name, rate, config.rate)
        self._guard, self._pub_pressures, self._pub_joint, self._joint_states = (
            rig.guard, rig.pressures, rig.joint, rig.joint_states)
        self._pub_clock = (self.create_publisher(Clock, CLOCK, CLOCK_QOS)
                           if config.publish_clock else None)
        self._pub_supply = None
        if config.publish_supply_pressure:
            self._pub_supply = self._guard.wrap(
                self.create_publisher(FluidPressure, SUPPLY_PRESSURE, SAMPLE_QOS), hold=True)
        self._sub_command = self.create_subscription(ValveCommand, VALVE_COMMAND,
                                                     self._on_command, SAMPLE_QOS)
        reset_latency = self.core.timing.reset_callback(self.get_logger())

        def reset_statistics(request, response):    # the rig's timing totals and the latency
            self.core.stats.reset_totals()
            response = reset_latency(request, response)
            response.message = 'sample timing and ' + response.message
            return response
        self.create_service(Trigger, '~/reset_statistics', reset_statistics)
        self._diagnostics = DiagnosticsPublisher(self, 'simulated rig', config.hardware_id,
                                                 self._report, DIAGNOSTICS_PERIOD)
        self._diagnostics.add_check(self._guard.report)
        self._diagnostics.add_check(self._logs.report)
        self._diagnostics.add_check(self._realtime.report)
        for line in self.config.summary:
            self.get_logger().info(line)
        mode = os.environ.get(PUBLICATION_MODE_VARIABLE)
        if self._lockstep and mode != LOCKSTEP_PUBLICATION_MODE:
            self.get_logger().info(
                f'lockstep with {PUBLICATION_MODE_VARIABLE}={mode}: each step waits for a round '
                f'trip of the loop, about twice as fast with {PUBLICATION_MODE_VARIABLE}='
                f'{LOCKSTEP_PUBLICATION_MODE} in every node of the loop')
        self.get_logger().info(
            f'topics: publishing {self._pub_pressures.topic_name}, '
            f'{self._pub_joint.topic_name}, '
            + (f'{self._joint_states.describe()}, ' if rate else '')
            + '/diagnostics'
            + (', /clock' if self._pub_clock else '')
            + (f', {self._pub_supply.topic_name}' if self._pub_supply else '')
            + f'; subscribing {self._sub_command.topic_name}')

    def start(self) -> None:
        """Start sampling: the realtime thread, or sample 0 and the lockstep watchdog."""
        self.core.stats.restart(time.monotonic())
        if self._lockstep:
            self._publish(self._messages(self.core.first_lockstep_sample()))
            timeout = self.config.lockstep_timeout
            if timeout > 0.0:
                self._lockstep_timer = self.create_timer(max(timeout / 4.0, 0.005),
                                                         self._on_lockstep_watchdog)
        else:
            # The sampler competes for the GIL with the executor thread: run_nodes shortens
            # the process's switch interval (pam_common.executors.shorten_switch_interval).
            self._thread = threading.Thread(target=self._realtime_loop, name='sim_node_sampler',
                                            daemon=True)
            self._thread.start()

    def stop(self) -> None:
        """Stop the sampling thread (safe to call twice)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    # ------------------------------------------------------------------ sampling
    def _messages(self, sample: SimSample | None):
        """The messages of a sample (None: a non-finite one, suppressed: logged)."""
        if sample is None:
            self._log_nonfinite(f'non-finite sample at step {self.core.rig.k} suppressed: state '
                                f'{self.core.nonfinite_state}')
            return None
        stamp = ns_stamp(sample.t_ns)
        pressures = build_pressures(build_header(stamp, self._frame_id), sample.p1, sample.p2,
                                    sample.counter)
        joint = build_joint(build_header(stamp, self._frame_id), sample.angle, sample.velocity,
                            sample.torque)
        clock = (Clock(clock=stamp) if self._pub_clock is not None
                 and (sample.counter - 1) % self.config.clock_every == 0 else None)
        supply = None
        if sample.supply is not None:
            supply = FluidPressure(fluid_pressure=sample.supply,
                                   variance=self.core.supply.variance)
            supply.header = pressures.header
        return clock, pressures, joint, supply

    def _publish(self, messages) -> None:
        if messages is None:
            return
        clock, pressures, joint, supply = messages
        if clock is not None:
            self._pub_clock.publish(clock)
        self._pub_pressures.publish(pressures)
        if supply is not None:
            self._pub_supply.publish(supply)
        self._pub_joint.publish(joint)
        self._joint_states.publish(joint.header.stamp, pressures.sample, joint.angle,
                                   joint.angular_velocity, joint.torque)
        self._last_publish = time.monotonic()
        self.core.published()

    def _realtime_loop(self) -> None:
        self._realtime.apply_to_thread('sim_node_sampler')
        start = time.monotonic()
        start_ns = self.get_clock().now().nanoseconds   # deadline 0 on the node clock
        core = self.core
        sampler = RealtimeSampler(core, 1.0 / self.config.rate, start, start_ns,
                                  self.config.max_catch_up)
        core.stats.restart(start)
        links = process_links()
        loop = self._drive(links) if links is not None else None
        tick = loop.tick if loop is not None and loop.timers else None
        try:
            while not self._stop.is_set():
                delay = sampler.wait(time.monotonic())
                if delay > 0.0:
                    time.sleep(delay)
                taken = sampler.next(time.monotonic())
                if taken is None:
                    continue
                sample, lateness, missed = taken
                self._publish(self._messages(sample))
                core.stats.record(lateness, missed)
                if tick is not None:
                    tick()
        except Exception as exc:  # noqa: BLE001 - report, do not die silently
            if self._stop.is_set() or not rclpy.ok(context=self.context):
                return  # shutting down: the publishers went away under us
            core.fault = f'sampling thread stopped: {type(exc).__name__}: {exc}'
            self.get_logger().error(core.fault)
        finally:
            if loop is not None:
                loop.release()

    def _drive(self, links: ProcessLinks) -> SampleLoop:
        """With the in-process links: this sampler runs the loop timers of its namespace
        (ros2_control's update loop; pam_common.links.ProcessLinks.drive), each logged."""
        loop = links.drive(1.0 / self.config.rate, self.get_namespace())
        for loop_timer in loop.timers:
            self.get_logger().info(f'sample loop runs {loop_timer.describe()}')
        return loop

    # ------------------------------------------------------------------ commands
    def _on_command(self, msg: ValveCommand) -> None:
        out = self.core.on_command(msg.u1, msg.u2, stamp_ns(msg.header.stamp), time.time_ns())
        if self._lockstep and not out.past:              # it stepped the plant
            messages = self._messages(out.sample)         # None: a non-finite sample, logged
            if messages is not None:
                self.core.stats.record(0.0)
                self._publish(messages)
        if out.applied is not None and self._marked_change(out.applied) and \
                self.get_logger().is_enabled_for(LoggingSeverity.DEBUG):
            self._debug_command(out.applied, out.received, out.step)
        if out.past:
            self._log_past(f'ignored a valve_command from the past (stamp '
                           f'{stamp_ns(msg.header.stamp) / 1e9:.6f} s < t_k = '
                           f'{out.t_k_ns / 1e9:.6f} s of step {out.step}); {out.past} so far')
        if not out.ok:
            u = self.core.rig.u
            self._log_bad(
                f'bad valve_command u1={msg.u1!r} V, u2={msg.u2!r} V sanitised to '
                f'({u[0]:g}, {u[1]:g}) V ({SANITISE_RULE}); so far '
                f'{out.non_finite} non-finite, {out.out_of_range} out-of-range voltages')

    def _marked_change(self, applied: tuple[float, float]) -> bool:
        """True for the first applied command and for one more than COMMAND_STEP_DEBUG away
        from the last marked one (which it becomes); two comparisons per command, no formatting:
        cheap at 1 kHz whatever the log level."""
        marked = self._marked_command
        if marked is not None and abs(applied[0] - marked[0]) <= COMMAND_STEP_DEBUG and \
                abs(applied[1] - marked[1]) <= COMMAND_STEP_DEBUG:
            return False
        self._previous_marked, self._marked_command = marked, applied
        return True

    def _debug_command(self, applied: tuple[float, float], received: int, step: int) -> None:
        """DEBUG: the applied valve command changed markedly (see _marked_change)."""
        previous = self._previous_marked
        since = ('the first command (held the initial command u1 '
                 f'{self.config.initial_command[0]:g} V, u2 '
                 f'{self.config.initial_command[1]:g} V until now)'
                 if previous is None else
                 f'was u1 {previous[0]:.3f} V, u2 {previous[1]:.3f} V at the last such line')
        self.get_logger().debug(
            f'valve command applied: u1 {applied[0]:.3f} V, u2 {applied[1]:.3f} V at step '
            f'{step}, command {received}; {since} (changes within '
            f'{COMMAND_STEP_DEBUG:g} V of it are not logged)')

    def _on_lockstep_watchdog(self) -> None:
        timeout = self.config.lockstep_timeout
        if self.core.current is None or time.monotonic() - self._last_publish < timeout:
            return
        sample, k = self.core.republish()
        self.get_logger().info(f'lockstep: waiting for a valve_command for step {k} '
                               f'(t = {self.core.stamp(k) / 1e9:.6f} s); re-publishing '
                               'the current sample', throttle_duration_sec=10.0)
        self._publish(self._messages(sample))

    # ------------------------------------------------------------------ diagnostics
    def _report(self):
        return self.core.report(time.monotonic())


def configured_sim_node(**node_kwargs) -> SimNode:
    """A configured SimNode, not sampling yet (ConfigError if its parameters are invalid);
    `node_kwargs` go to rclpy's Node (namespace, cli_args, ...)."""
    node = SimNode(**node_kwargs)
    try:
        node.configure()
    except ConfigError:
        node.destroy_node()
        raise
    return node


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, configured_sim_node, start=SimNode.start, stop=SimNode.stop)


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(), args)


if __name__ == '__main__':
    sys.exit(main())
