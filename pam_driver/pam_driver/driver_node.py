"""driver_node: the hardware driver of the PAM rig, a drop-in for sim_node.

It talks to the DAQ board over a serial port with the protocol of pam_driver/PROTOCOL.md
(pam_driver.daq_protocol, pyserial) and converts with the calibration YAML
(pam_driver.calibration). Run `driver_node --help` for the parameters.

Topics (same contract as sim_node; relative names under '/pam' by default): publishes
`pressures` per sample (1 kHz, stamped with the node clock on receipt; `sample` counts the
device's ticks, 1 for the first sample received, so a SAMPLE frame lost on the line or the stream
down while reconnecting is a gap downstream: daq_protocol.TickCounter) and, when the board
reports an encoder and a torque meter fitted, `joint_measured` (angle from the encoder, torque
from the torque meter, angular velocity by finite difference of the angle) and, when it reports
an encoder, `joint_states` (sensor_msgs/JointState for the standard tools: joint_name, the same
angle and velocity, the torque as effort, empty without a torque meter; 1 sample in
round(board rate / joint_states_rate)), and, when it reports a supply-pressure transducer
(PROTOCOL.md 1.1) and the calibration has its pressure.supply section, `supply_pressure`
(sensor_msgs/FluidPressure, P_tank in Pa abs, the stamp of the pressures sample it came with,
variance 0: unknown; a reading outside its valid volts or pressure_limits is not published, and
OUT_OF_RANGE_SAMPLES of them in a row are a sensor fault like P1's); subscribes
`valve_command`; publishes `~/applied_command` (the voltages the valves actually get, on each
change) and `/diagnostics`. Services `~/arm`, `~/estop` and `~/reset_statistics` (std_srvs/Trigger;
the last restarts the sample -> command latency figures on /diagnostics, pam_common.latency).
A granted `~/arm` also sends ARM (PROTOCOL.md 1.2) to a board that announced protocol 1.2 or later
(the reference board: it clears its own latched faults whose cause is gone; its reply says what
was sent); a 1.1 device gets nothing more than before.

Threads: the reader thread of the serial session (pam_driver.serial_session, no ROS: connect,
handshake, read samples, send the heartbeat, reconnect with exponential backoff) reports each
event to this node, which feeds the DriverCore the samples and the command watchdog tick; the
executor thread (EventsExecutor via run_nodes) runs the subscription, services and the
diagnostics timer. Both hand every event to the DriverCore (pam_driver.driver_core) under one
lock and write the output it decides under that same lock, so a decision and its COMMAND frame are
one step (a watchdog trip cannot be overtaken by a command decided before it). Lifecycle: the node
is built (parameters, interfaces), then started (the session's thread) once every node of the
process is on the executor, then stopped (safe output first). The real-time knobs
thread_priority (SCHED_FIFO), cpu_affinity and lock_memory apply to both threads, each logged
when granted and a warning when refused (pam_common.realtime_knobs, docs/realtime.md).

Safety (the choice, documented in README and PROTOCOL.md): ARMED (valid commands, clipped to
valve_limits, go to the valves) or SAFE (safe_output, latched until ~/arm) on the command watchdog,
~/estop, a pressure sensor fault, the device lost or refused, an internal exception (the safe
COMMAND is written before the port is closed): the decisions are pam_driver.driver_core's, whose
docstring lists them. At shutdown (SIGINT, SIGTERM) the driver sends safe_output before closing
the port.
The port is opened for exclusive use (flock): a second driver on it is refused. The board itself
vents both valves when no host frame arrives for 250 ms (its own watchdog); the SAMPLE status
bit and the DEVICE_HEARTBEAT trip counter report it, and /diagnostics counts these 'board vents'
(daq_protocol.BoardVents): a vent in the last window is an ERROR while armed (the commanded
output was not applied), a WARN otherwise. The non-finite command warning is throttled to one
line a second, the lines left out counted on /diagnostics. At DEBUG (`--ros-args --log-level
pam.driver_node:=debug`) every decision the core reports (arming, going safe, a watchdog trip, a
sensor fault, the device lost) is followed by one line with the safety state it left.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable

from rclpy.logging import LoggingSeverity
from sensor_msgs.msg import FluidPressure
from std_srvs.srv import Trigger

from pam_common.diagnostics import DiagnosticsPublisher
from pam_common.latency import CommandTiming
from pam_common.links import LinkedNode
from pam_common.node_skeleton import Component, component_main, parameter_values
from pam_common.qos import LATEST_QOS, SAMPLE_QOS
from pam_common.realtime_knobs import RealtimeKnobs
from pam_common.stamps import ns_stamp, stamp_ns
from pam_common.throttled_log import ThrottledLogs
from pam_common.timing import RateStatistics
from pam_common.topics import (
    APPLIED_COMMAND,
    DEFAULT_NAMESPACE,
    SUPPLY_PRESSURE,
    VALVE_COMMAND,
)
from pam_driver import daq_protocol as proto
from pam_driver.calibration import SUPPLY
from pam_driver.driver_config import PARAMETERS, DriverConfig, build_config, usage_text
from pam_driver.driver_core import Action, DriverCore
from pam_driver.driver_health import DriverHealth, SafetyState
from pam_driver.rig_publishers import build_header, build_joint, build_pressures, rig_publishers
from pam_driver.serial_session import SerialSession
from pam_interfaces.msg import ValveCommand

NODE_NAME = 'driver_node'
DIAGNOSTICS_PERIOD = 1.0
LOG_THROTTLE = 1.0
REFUSED_LOG_PERIOD = 10.0     # s, an incompatible device is logged again at most this often


class DriverNode(LinkedNode):
    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config: DriverConfig = parameter_values(self, PARAMETERS, check=build_config)
        config = self.config
        self.cal = config.calibration
        # the knobs of the 1 kHz path (pam_common.realtime_knobs): this thread is the executor's
        self._realtime = RealtimeKnobs(self.get_logger(), config.realtime)
        self._realtime.apply_to_executor()
        self._frame_id = config.frame_id
        self._lock = threading.Lock()        # the core, the state and counters
        self._stats = RateStatistics(1e-3, time.monotonic())
        # the safety decisions, fed under self._lock (monotonic times)
        self._core = DriverCore(config.safety, self.cal)
        # the serial link (reader thread started by start())
        self._session = SerialSession(config.link, self)
        self._refused = ('', -math.inf)      # the reason last logged and when (monotonic)
        self._logs = ThrottledLogs(self.get_logger(), LOG_THROTTLE)
        self._log_nonfinite = self._logs.new()
        self._health = DriverHealth()          # the diagnostics policy (driver_health)
        self._prev_angle = None
        self._supply = False                 # this session publishes supply_pressure
        self._pub_supply = None              # made at the first board that has the transducer
        self._supply_value = math.nan        # Pa abs, the last one published
        self._supply_dropped = 0             # readings not published (implausible, missing)

        # the board's sample rate (for the JointState's samples) comes at the handshake
        rig = rig_publishers(self, self._frame_id, config.joint_name, config.joint_states_rate,
                             None)
        self._guard, self._pub_pressures, self._pub_joint, self._joint_states = (
            rig.guard, rig.pressures, rig.joint, rig.joint_states)
        self._pub_applied = self._guard.wrap(
            self.create_publisher(ValveCommand, APPLIED_COMMAND, LATEST_QOS),
            safe=dict(zip(('u1', 'u2'), config.safety.safe_output, strict=True)), whole=True)
        self._sub = self.create_subscription(ValveCommand, VALVE_COMMAND, self._on_command,
                                             SAMPLE_QOS)
        self.create_service(Trigger, '~/arm', self._on_arm)
        self.create_service(Trigger, '~/estop', self._on_estop)
        self._timing = CommandTiming()      # sample -> command latency at the rig
        self.create_service(Trigger, '~/reset_statistics',
                            self._timing.reset_callback(self.get_logger()))
        # hardware_id: the parameter (the stack's namespace by default); the board itself is
        # named in the values (port, device protocol)
        self._diagnostics = DiagnosticsPublisher(self, 'DAQ board', config.hardware_id,
                                                 self._report, DIAGNOSTICS_PERIOD)
        self._diagnostics.add_check(self._guard.report)
        self._diagnostics.add_check(self._logs.report)
        self._diagnostics.add_check(self._realtime.report)
        self.get_logger().info(
            f'port {config.link.port} at {config.link.baud} baud, calibration '
            f'{self.cal.source}; watchdog {config.safety.watchdog_timeout * 1e3:g} ms, safe '
            f'output {list(self._core.output)} V, {"armed" if self._core.armed else "disarmed"}')

    def start(self) -> None:
        """Start the serial session (its reader thread competes for the GIL with the executor
        thread: run_nodes shortens the process's switch interval,
        pam_common.executors.shorten_switch_interval)."""
        self._session.start()

    # ------------------------------------------------------------------ output
    def _apply(self, action: Action, paced: bool = False) -> bool:
        """Write the action's output to the valves and publish ~/applied_command if it changed;
        False if there was nothing to write or no device to write it to (or the write failed).
        paced: the loop's command, at most one COMMAND frame per SAMPLE (SerialSession); every
        other output (safe, shutdown, connect) goes at once. The caller holds self._lock (the
        decision and its COMMAND frame are one step)."""
        if action.device_arm:       # before the output: the board applies the next COMMAND
            self._session.send_arm()
        if action.output is None:
            return False
        u1, u2 = action.output
        sent = self._session.send_command(self.cal.dac_counts(u1), self.cal.dac_counts(u2),
                                          paced)
        if action.changed:
            msg = ValveCommand()
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self._frame_id
            msg.u1, msg.u2 = float(u1), float(u2)
            try:
                self._pub_applied.publish(msg)
            except Exception:  # noqa: BLE001 - shutting down
                pass
        return sent

    def _decide(self, event: Callable[[], Action], paced: bool = False) -> Action:
        """One event through the core: decided and its output written under self._lock (paced:
        see _apply), then its lines logged (outside the lock)."""
        with self._lock:
            action = event()
            self._apply(action, paced)
        # one call site per severity: rclpy refuses two severities from one line of code
        logger = self.get_logger()
        for log in action.logs:
            if log.throttled:
                self._log_nonfinite(log.text)
            elif log.level == 'error':
                logger.error(log.text)
            elif log.level == 'warning':
                logger.warning(log.text)
            else:
                logger.info(log.text)
        if action.logs and logger.is_enabled_for(LoggingSeverity.DEBUG):
            self._debug_decision(action)
        return action

    def _debug_decision(self, action: Action) -> None:
        """DEBUG: the safety state after a decision the core reported (arming, going safe, a
        watchdog trip, a sensor fault...); not after the throttled non-finite command lines."""
        decided = [log.text for log in action.logs if not log.throttled]
        if not decided:
            return
        core = self._core
        with self._lock:
            state = (f'armed {core.armed}, connected {core.connected}, safe reason '
                     f'{core.safe_reason or "none"}, output {list(core.output)} V, sensor fault '
                     f'{core.sensor_fault or "none"}, watchdog trips {core.watchdog_trips} '
                     f'(last after {core.last_trip_ms:.1f} ms, timeout '
                     f'{core.config.watchdog_timeout * 1e3:g} ms), e-stops {core.estops}')
        self.get_logger().debug(f'decided: {"; ".join(decided)} -> {state}')

    # ------------------------------------------------------------------ ROS callbacks
    def _on_command(self, msg: ValveCommand) -> None:
        self._timing.on_command(stamp_ns(msg.header.stamp), time.time_ns())
        action = self._decide(lambda: self._core.on_command(msg.u1, msg.u2, time.monotonic()),
                              paced=True)
        inject = self.config.inject_internal_error
        if action.ok and self._session.inject_at is None and inject > 0.0:
            self._session.inject_at = time.monotonic() + inject

    def _on_arm(self, request, response):
        action = self._decide(self._core.on_arm)
        response.success, response.message = action.ok, action.message
        return response

    def _on_estop(self, request, response):
        action = self._decide(self._core.on_estop)
        response.success, response.message = action.ok, action.message
        return response

    # ------------------------------------------------------------------ serial session events
    def on_thread_start(self) -> None:
        self._realtime.apply_to_thread('driver_reader')

    def on_connected(self, info: proto.DeviceInfo) -> bool:
        """The handshake succeeded: start from the safe output (whatever the valves had before),
        set up this session's topics, log the device. Returns whether SAMPLE frames carry the
        supply-pressure field this driver reads."""
        if info.adc_bits != self.cal.adc_bits or info.dac_bits != self.cal.dac_bits:
            self.get_logger().warning(
                f'device reports {info.adc_bits}-bit ADC / {info.dac_bits}-bit DAC, calibration '
                f'says {self.cal.adc_bits} / {self.cal.dac_bits}', throttle_duration_sec=10.0)
        self._refused = ('', -math.inf)
        with self._lock:        # its action logs nothing: the line below says it
            self._apply(self._core.on_connected(device_arm=info.has_arm))
        self._prev_angle = None
        supply = self._start_supply(info)
        if not self._joint_states.set_sample_rate(info.rate):
            self.get_logger().warning(
                f'joint_states_rate {self.config.joint_states_rate:g} Hz is above the '
                f"board's sample rate {info.rate} Hz: every sample is published")
        self.get_logger().info(
            f'connected to {self.config.link.port}: protocol {info.major}.{info.minor}, '
            f'{info.rate} Hz, encoder {"yes" if info.has_encoder else "no"}, torque meter '
            f'{"yes" if info.has_torque else "no"}, supply pressure {supply}'
            + (f'; {self._joint_states.describe()}' if info.has_encoder else ''))
        return self._supply

    def on_tick(self, now: float) -> None:
        self._decide(lambda: self._core.on_tick(now))

    def on_connect_failed(self, error: str, backoff: float) -> None:
        """A failed connection attempt (port missing, no handshake) or the device lost: the
        node keeps retrying (the board may be plugged in later); say so on the console, at most
        every 10 s (a device lost while streaming: on_link_down reports it)."""
        if self._core.connected or self._session.stopping:
            return
        self.get_logger().warning(
            f'cannot connect to {self.config.link.port}: {error}; retrying in {backoff:g} s (up '
            f'to every {self.config.link.reconnect_backoff[1]:g} s), safe output meanwhile; '
            '/diagnostics reports ERROR until connected', throttle_duration_sec=10.0)

    def on_refused(self, why: str, backoff: float) -> None:
        """An incompatible device: an error on the console (at once when the reason is new,
        then at most every 10 s), safe and disarmed; the node keeps retrying (the board may be
        re-flashed or replaced). Nothing but HELLO was sent to it."""
        now = time.monotonic()
        reason, logged = self._refused
        self._decide(lambda: self._core.on_device_refused(why))
        if why != reason or now - logged >= REFUSED_LOG_PERIOD:
            self._refused = (why, now)
            self.get_logger().error(
                f'refusing the device on {self.config.link.port}: {why}; not streaming, safe '
                f'output, retrying in {backoff:g} s (up to every '
                f'{self.config.link.reconnect_backoff[1]:g} s)')

    def on_internal_error(self, error: str) -> None:
        self._decide(lambda: self._core.on_internal_error(error))

    def on_link_down(self, error: str, stopping: bool) -> None:
        with self._lock:
            was = self._core.on_disconnected()
        if was and not stopping:
            self._decide(lambda: self._core.on_device_lost(error))

    def _start_supply(self, info: proto.DeviceInfo) -> str:
        """Whether this session publishes supply_pressure (the board reports the transducer and
        the calibration converts it); the start line's words for it."""
        self._supply = info.has_supply and self.cal.has_supply
        if not info.has_supply:
            return 'no'
        if not self.cal.has_supply:
            self.get_logger().warning(
                f'the board reports a supply-pressure transducer but the calibration '
                f'{self.cal.source} has no pressure.supply section: supply_pressure not '
                'published', throttle_duration_sec=10.0)
            return 'yes (not calibrated: not published)'
        if self._pub_supply is None:
            self._pub_supply = self._guard.wrap(
                self.create_publisher(FluidPressure, SUPPLY_PRESSURE, SAMPLE_QOS), hold=True)
        return f'yes (publishing {self._pub_supply.topic_name})'

    def on_sample(self, s: proto.Sample, number: int, now: float) -> None:
        cal = self.cal
        counts = (s.adc_p1, s.adc_p2)
        supply = self._supply and s.adc_supply is not None
        if supply:
            counts += (s.adc_supply,)
        elif self._supply:
            self._session.count_protocol_error()   # a SAMPLE cut short before its supply field
            with self._lock:
                self._supply_dropped += 1
        p = tuple(cal.pressure(i, c) for i, c in enumerate(counts))
        self._decide(lambda: self._core.on_sample(counts, p, now))
        t_ns = self.get_clock().now().nanoseconds
        self._timing.on_sample(t_ns)
        stamp = ns_stamp(t_ns)
        msg = build_pressures(build_header(stamp, self._frame_id), p[0], p[1], number)
        self._pub_pressures.publish(msg)
        if supply:
            self._publish_supply(stamp, p[SUPPLY], self._core.plausible[SUPPLY])
        info = self._session.device
        if info is not None and info.has_encoder:
            angle = cal.angle(s.encoder)
            h = 1.0 / info.rate
            velocity = 0.0 if self._prev_angle is None else (angle - self._prev_angle) / h
            self._prev_angle = angle
            torque = None
            if info.has_torque:
                joint = build_joint(msg.header, angle, velocity, cal.torque(s.adc_torque))
                self._pub_joint.publish(joint)      # its guard holds the last finite values
                angle, velocity, torque = joint.angle, joint.angular_velocity, joint.torque
            self._joint_states.publish(stamp, msg.sample, angle, velocity, torque)
        self._stats.record(0.0)

    def _publish_supply(self, stamp, pressure: float, plausible: bool) -> None:
        """supply_pressure with the pressures sample's stamp; an implausible reading (a wire
        break, out of pressure_limits) is counted, not published."""
        if not plausible:
            with self._lock:
                self._supply_dropped += 1
            return
        supply = FluidPressure()
        supply.header.stamp = stamp
        supply.header.frame_id = self._frame_id
        supply.fluid_pressure = pressure
        supply.variance = 0.0                   # unknown to the driver
        self._pub_supply.publish(supply)
        self._supply_value = pressure

    # ------------------------------------------------------------------ shutdown
    def stop(self) -> None:
        """Safe output to the device, stop the reader thread, close the port (the reader thread
        closes it on its way out: after the safe COMMAND frame was written)."""
        sent = False
        try:
            with self._lock:
                sent = self._apply(self._core.on_shutdown())
        except Exception:  # noqa: BLE001 - shutting down: do what can be done
            pass
        self._session.stop()
        try:
            self.get_logger().info(
                f'shutdown: safe output {list(self.config.safety.safe_output)} V '
                + ('sent to the device, port closed' if sent else '(no device connected)'))
        except Exception:  # noqa: BLE001
            pass

    # ------------------------------------------------------------------ diagnostics
    def _report(self):
        window = self._stats.window(time.monotonic())
        core = self._core
        link = self._session.report_values()
        with self._lock:
            values = {
                'port': self.config.link.port,
                'connected': core.connected,
                **link,
                'supply_pressure published': self._supply,
                'supply pressure (Pa)': self._supply_value,
                'supply readings not published': self._supply_dropped,
                'achieved rate (Hz)': window.achieved_rate if window.samples else 0.0,
                'connects': core.connects,
                'reconnects': max(core.connects - 1, 0),
                'disconnects': core.disconnects,
                **self._timing.histogram.summary(),    # since start or ~/reset_statistics
                'internal errors': core.internal_errors,
                **core.report_values(),
            }
            state = SafetyState(connected=core.connected, armed=core.armed,
                                sensor_fault=core.sensor_fault or '',
                                safe_reason=core.safe_reason or '',
                                last_error=self._session.last_error)
        level, message = self._health.judge(values, state)
        return level, message, values


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, DriverNode, start=DriverNode.start, stop=DriverNode.stop)


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(), args)


if __name__ == '__main__':
    sys.exit(main())
