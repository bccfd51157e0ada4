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

Threads: a reader thread owns the serial connection (connect, handshake, read samples, send the
heartbeat, the command watchdog tick, reconnect with exponential backoff); the executor thread
(EventsExecutor via run_node) runs the subscription, services and the diagnostics timer and
writes COMMAND frames. Both hand every event to the DriverCore (pam_driver.driver_core) under one
lock and write the output it decides under that same lock, so a decision and its COMMAND frame are
one step (a watchdog trip cannot be overtaken by a command decided before it). The real-time knobs
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
from sensor_msgs.msg import FluidPressure, JointState
from std_srvs.srv import Trigger

from pam_common.diagnostics import DiagnosticsPublisher
from pam_common.finite_guard import FiniteGuard
from pam_common.joint_states import JointStates
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
    JOINT_MEASURED,
    JOINT_STATES,
    PRESSURES,
    SUPPLY_PRESSURE,
    VALVE_COMMAND,
)
from pam_driver import daq_protocol as proto
from pam_driver.calibration import SUPPLY
from pam_driver.driver_config import PARAMETERS, build_config, usage_text
from pam_driver.driver_core import Action, DriverCore, SafetyConfig
from pam_driver.driver_health import DriverHealth, SafetyState
from pam_interfaces.msg import JointMeasurement, Pressures, ValveCommand

NODE_NAME = 'driver_node'
DIAGNOSTICS_PERIOD = 1.0
LOG_THROTTLE = 1.0
REFUSED_LOG_PERIOD = 10.0     # s, an incompatible device is logged again at most this often

class DeviceLost(Exception):
    """The device stopped answering (no samples, failed handshake)."""


class IncompatibleDevice(DeviceLost):
    """The device answered the handshake but cannot be driven (another major protocol version,
    an impossible sample rate): it is not streamed from and gets no COMMAND frame."""


class InjectedError(RuntimeError):
    """The internal error of the inject_internal_error parameter (tests of the exception path)."""


class DriverNode(LinkedNode):
    def __init__(self, **kwargs):
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        self.config = parameter_values(self, PARAMETERS, check=build_config)
        self.cal = self.config['calibration']
        # the knobs of the 1 kHz path (pam_common.realtime_knobs): this thread is the executor's
        self._realtime = RealtimeKnobs(self.get_logger(), self.config)
        self._realtime.apply_to_executor()
        self._frame_id = self.config['frame_id']
        self._stop = threading.Event()
        self._io_lock = threading.Lock()     # the serial object and writes
        self._lock = threading.Lock()        # the core, the state and counters
        self._serial = None
        self._tx_seq = 0
        self._decoder = proto.Decoder()
        self._rx_seq = proto.SequenceTracker()
        self._stats = RateStatistics(1e-3, time.monotonic())
        # the safety decisions, fed under self._lock (monotonic times)
        self._core = DriverCore(SafetyConfig.from_values(self.config), self.cal)
        # counters of the serial link
        self._handshake_failures = 0
        self._incompatible = ''              # why the device was refused at the handshake
        self._refused_logged = -math.inf     # monotonic time of the last log line about it
        self._last_error = ''
        self._inject_at = None               # monotonic time of the injected internal error
        self._device = None
        self._device_heartbeat = None
        self._early_frames = []              # frames read with the HELLO_ACK, after it
        self._ticks = proto.TickCounter()    # the device's tick -> Pressures.sample
        self._vents = proto.BoardVents()
        self._logs = ThrottledLogs(self.get_logger(), LOG_THROTTLE)
        self._log_nonfinite = self._logs.new()
        self._samples = 0
        self._protocol_errors = 0
        self._health = DriverHealth()          # the diagnostics policy (driver_health)
        self._prev_angle = None
        self._supply = False                 # this session publishes supply_pressure
        self._pub_supply = None              # made at the first board that has the transducer
        self._supply_value = math.nan        # Pa abs, the last one published
        self._supply_dropped = 0             # readings not published (implausible, missing)

        self._guard = FiniteGuard(self.get_logger())
        self._pub_pressures = self._guard.wrap(
            self.create_publisher(Pressures, PRESSURES, SAMPLE_QOS), hold=True)
        self._pub_joint = self._guard.wrap(
            self.create_publisher(JointMeasurement, JOINT_MEASURED, SAMPLE_QOS), hold=True)
        # the joint as JointState (pam_common.joint_states); the board's rate comes at the
        # handshake
        rate = self.config['joint_states_rate']
        self._joint_states = JointStates(
            self._guard.wrap(self.create_publisher(JointState, JOINT_STATES, SAMPLE_QOS))
            if rate else None, JointState(), self.config['joint_name'], self._frame_id, rate, None)
        self._pub_applied = self._guard.wrap(
            self.create_publisher(ValveCommand, APPLIED_COMMAND, LATEST_QOS),
            safe=dict(zip(('u1', 'u2'), self.config['safe_output'], strict=True)), whole=True)
        self._sub = self.create_subscription(ValveCommand, VALVE_COMMAND, self._on_command,
                                             SAMPLE_QOS)
        self.create_service(Trigger, '~/arm', self._on_arm)
        self.create_service(Trigger, '~/estop', self._on_estop)
        self._timing = CommandTiming()      # sample -> command latency at the rig
        self.create_service(Trigger, '~/reset_statistics',
                            self._timing.reset_callback(self.get_logger()))
        # hardware_id: the parameter (the stack's namespace by default); the board itself is
        # named in the values (port, device protocol)
        self._diagnostics = DiagnosticsPublisher(self, 'DAQ board', self.config['hardware_id'],
                                                 self._report, DIAGNOSTICS_PERIOD)
        self._diagnostics.add_check(self._guard.report)
        self._diagnostics.add_check(self._logs.report)
        self._diagnostics.add_check(self._realtime.report)
        self.get_logger().info(
            f"port {self.config['port']} at {self.config['baud']} baud, calibration "
            f'{self.cal.source}; watchdog {self.config["watchdog_timeout"] * 1e3:g} ms, safe '
            f'output {list(self._core.output)} V, {"armed" if self._core.armed else "disarmed"}')
        # the reader competes for the GIL with the executor thread: run_nodes shortens the
        # process's switch interval (pam_common.executors.shorten_switch_interval)
        self._thread = threading.Thread(target=self._reader_loop, name='driver_reader',
                                        daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ output
    def _write(self, data: bytes) -> bool:
        with self._io_lock:
            ser = self._serial
            if ser is None:
                return False
            try:
                ser.write(data)
                return True
            except Exception as exc:  # noqa: BLE001 - the reader thread notices and reconnects
                self._last_error = f'write failed: {type(exc).__name__}: {exc}'
                return False

    def _next_seq(self) -> int:
        seq = self._tx_seq
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        return seq

    def _apply(self, action: Action) -> bool:
        """Write the action's output to the valves and publish ~/applied_command if it changed;
        False if there was nothing to write or no device to write it to (or the write failed).
        The caller holds self._lock (the decision and its COMMAND frame are one step)."""
        if action.device_arm:       # before the output: the board applies the next COMMAND
            with self._io_lock:
                seq = self._next_seq()
            self._write(proto.arm(seq))
        if action.output is None:
            return False
        u1, u2 = action.output
        with self._io_lock:
            seq = self._next_seq()
        sent = self._write(proto.command(seq, self.cal.dac_counts(u1), self.cal.dac_counts(u2)))
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

    def _decide(self, event: Callable[[], Action]) -> Action:
        """One event through the core: decided and its output written under self._lock, then
        its lines logged (outside the lock)."""
        with self._lock:
            action = event()
            self._apply(action)
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
        action = self._decide(lambda: self._core.on_command(msg.u1, msg.u2, time.monotonic()))
        if action.ok and self._inject_at is None and self.config['inject_internal_error'] > 0.0:
            self._inject_at = time.monotonic() + self.config['inject_internal_error']

    def _on_arm(self, request, response):
        action = self._decide(self._core.on_arm)
        response.success, response.message = action.ok, action.message
        return response

    def _on_estop(self, request, response):
        action = self._decide(self._core.on_estop)
        response.success, response.message = action.ok, action.message
        return response

    # ------------------------------------------------------------------ serial thread
    def _reader_loop(self) -> None:
        self._realtime.apply_to_thread('driver_reader')
        import serial
        first, longest = self.config['reconnect_backoff']
        backoff = first
        while not self._stop.is_set():
            try:
                self._connect(serial)
                backoff = first
                self._stream()
            except IncompatibleDevice as exc:
                self._last_error = str(exc)
                self._refuse_device(str(exc), backoff)
            except DeviceLost as exc:
                self._last_error = str(exc)
                self._incompatible = ''
                self._warn_not_connected(backoff)
            except (serial.SerialException, OSError) as exc:
                self._last_error = f'{type(exc).__name__}: {exc}'
                self._incompatible = ''
                self._warn_not_connected(backoff)
            except Exception as exc:  # noqa: BLE001 - never die: safe output, report, retry
                error = self._last_error = f'internal error: {type(exc).__name__}: {exc}'
                # B023: _decide runs the lambda now, not after the loop moved on
                self._decide(lambda: self._core.on_internal_error(error))  # noqa: B023
            finally:
                try:
                    self._disconnect()
                except Exception as exc:  # noqa: BLE001 - the thread must not die
                    self._last_error = f'internal error: {type(exc).__name__}: {exc}'
            if self._stop.wait(backoff):
                break
            backoff = min(2.0 * backoff, longest)

    def _warn_not_connected(self, backoff: float) -> None:
        """A failed connection attempt (port missing, no handshake): the node keeps retrying
        (the board may be plugged in later); say so on the console, at most every 10 s."""
        if self._core.connected or self._stop.is_set():
            return   # lost while streaming: _disconnect() reports it
        self.get_logger().warning(
            f"cannot connect to {self.config['port']}: {self._last_error}; retrying in "
            f'{backoff:g} s (up to every {self.config["reconnect_backoff"][1]:g} s), safe output '
            'meanwhile; /diagnostics reports ERROR until connected', throttle_duration_sec=10.0)

    def _refuse_device(self, why: str, backoff: float) -> None:
        """An incompatible device: an error on the console (at once when the reason is new,
        then at most every 10 s), safe and disarmed; the node keeps retrying (the board may be
        re-flashed or replaced). Nothing but HELLO was sent to it."""
        now = time.monotonic()
        say = why != self._incompatible or now - self._refused_logged >= REFUSED_LOG_PERIOD

        def refuse() -> Action:
            self._incompatible = why
            return self._core.on_device_refused(why)
        self._decide(refuse)
        text = (f"refusing the device on {self.config['port']}: {why}; not streaming, safe "
                f'output, retrying in {backoff:g} s (up to every '
                f'{self.config["reconnect_backoff"][1]:g} s)')
        if say:
            self._refused_logged = now
            self.get_logger().error(text)

    def _check_device(self, info: proto.DeviceInfo) -> None:
        """Raise IncompatibleDevice unless the HELLO_ACK describes a device this driver drives."""
        if info.major != proto.PROTOCOL_MAJOR:
            raise IncompatibleDevice(
                f'protocol version mismatch: the device speaks {info.major}.{info.minor}, this '
                f'driver {proto.PROTOCOL_MAJOR}.{proto.PROTOCOL_MINOR} (major versions must be '
                'equal)')
        if info.rate == 0:
            raise IncompatibleDevice('the device reports a sample rate of 0 Hz')

    def _connect(self, serial) -> None:
        # exclusive: an advisory lock (flock) on the port, so that a second driver_node (or any
        # other pyserial program asking for one) cannot share the board and steal its bytes
        ser = serial.Serial(self.config['port'], self.config['baud'], timeout=0.002,
                            write_timeout=0.1, exclusive=True)
        ser.reset_input_buffer()
        with self._io_lock:
            self._serial = ser
            seq = self._next_seq()
        self._decoder.reset()
        self._rx_seq.reset()
        self._early_frames = []
        self._write(proto.hello(seq))
        deadline = time.monotonic() + self.config['handshake_timeout']
        info = None
        while info is None and time.monotonic() < deadline and not self._stop.is_set():
            frames = self._decoder.feed(ser.read(max(ser.in_waiting, 1)))
            for i, frame in enumerate(frames):
                if frame.type == proto.HELLO_ACK:
                    info = proto.parse_hello_ack(frame)
                    self._early_frames = frames[i + 1:]   # already streamed: _stream's
                    break
        if info is None:
            with self._lock:
                self._handshake_failures += 1
            raise DeviceLost('no HELLO_ACK within handshake_timeout')
        try:
            self._check_device(info)
        except IncompatibleDevice:
            with self._lock:
                self._handshake_failures += 1
            raise
        if info.adc_bits != self.cal.adc_bits or info.dac_bits != self.cal.dac_bits:
            self.get_logger().warning(
                f'device reports {info.adc_bits}-bit ADC / {info.dac_bits}-bit DAC, calibration '
                f'says {self.cal.adc_bits} / {self.cal.dac_bits}', throttle_duration_sec=10.0)
        with self._lock:
            self._device = info
            self._incompatible = ''
            # whatever the valves had before: start from the safe output
            self._apply(self._core.on_connected(device_arm=info.has_arm))
        self._prev_angle = None
        supply = self._start_supply(info)
        if not self._joint_states.set_sample_rate(info.rate):
            self.get_logger().warning(
                f"joint_states_rate {self.config['joint_states_rate']:g} Hz is above the "
                f"board's sample rate {info.rate} Hz: every sample is published")
        self.get_logger().info(
            f'connected to {self.config["port"]}: protocol {info.major}.{info.minor}, '
            f'{info.rate} Hz, encoder {"yes" if info.has_encoder else "no"}, torque meter '
            f'{"yes" if info.has_torque else "no"}, supply pressure {supply}'
            + (f'; {self._joint_states.describe()}' if info.has_encoder else ''))

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

    def _disconnect(self) -> None:
        with self._lock:
            was = self._core.on_disconnected()
        with self._io_lock:
            ser, self._serial = self._serial, None
        if ser is not None:
            try:
                ser.close()
            except Exception:  # noqa: BLE001
                pass
        if was and not self._stop.is_set():
            error = self._last_error
            self._decide(lambda: self._core.on_device_lost(error))

    def _stream(self) -> None:
        ser = self._serial
        last_sample = time.monotonic()
        next_heartbeat = last_sample
        early, self._early_frames = self._early_frames, []
        while not self._stop.is_set():
            data = ser.read(max(ser.in_waiting, 1))
            now = time.monotonic()
            if self._inject_at is not None and now >= self._inject_at:
                self._inject_at = math.inf   # once
                raise InjectedError('injected by the inject_internal_error parameter')
            frames, early = early + (self._decoder.feed(data) if data else []), []
            for frame in frames:
                self._rx_seq.update(frame.seq)
                try:
                    if frame.type == proto.SAMPLE:
                        self._on_sample(proto.parse_sample(frame, self._supply), now)
                        last_sample = now
                    elif frame.type == proto.DEVICE_HEARTBEAT:
                        heartbeat = frame.fields()
                        with self._lock:
                            self._device_heartbeat = heartbeat
                            self._vents.on_heartbeat(heartbeat[2])
                    elif frame.type == proto.HELLO_ACK:
                        pass
                    else:
                        frame.fields()  # raises for an unknown type
                except proto.ProtocolError:
                    with self._lock:
                        self._protocol_errors += 1
            self._decide(lambda: self._core.on_tick(now))  # noqa: B023 - _decide runs it now
            if now >= next_heartbeat:
                with self._io_lock:
                    seq = self._next_seq()
                if not self._write(proto.heartbeat(seq)):
                    raise DeviceLost(self._last_error or 'write failed')
                next_heartbeat = now + self.config['heartbeat_period']
            if now - last_sample > self.config['stream_timeout']:
                raise DeviceLost(f'no sample for {self.config["stream_timeout"] * 1e3:g} ms')

    def _on_sample(self, s: proto.Sample, now: float) -> None:
        cal = self.cal
        counts = (s.adc_p1, s.adc_p2)
        supply = self._supply and s.adc_supply is not None
        if supply:
            counts += (s.adc_supply,)
        elif self._supply:
            with self._lock:
                self._protocol_errors += 1     # a SAMPLE cut short before its supply field
                self._supply_dropped += 1
        p = tuple(cal.pressure(i, c) for i, c in enumerate(counts))
        self._decide(lambda: self._core.on_sample(counts, p, now))
        t_ns = self.get_clock().now().nanoseconds
        self._timing.on_sample(t_ns)
        stamp = ns_stamp(t_ns)
        msg = Pressures()
        msg.header.stamp = stamp
        msg.header.frame_id = self._frame_id
        msg.p1, msg.p2 = p[0], p[1]
        msg.sample = self._ticks.update(s.tick)
        self._pub_pressures.publish(msg)
        if supply:
            self._publish_supply(stamp, p[SUPPLY], self._core.plausible[SUPPLY])
        info = self._device
        if info is not None and info.has_encoder:
            angle = cal.angle(s.encoder)
            h = 1.0 / info.rate
            velocity = 0.0 if self._prev_angle is None else (angle - self._prev_angle) / h
            self._prev_angle = angle
            torque = None
            if info.has_torque:
                joint = JointMeasurement()
                joint.header = msg.header
                joint.angle = angle
                joint.angular_velocity = velocity
                joint.torque = cal.torque(s.adc_torque)
                self._pub_joint.publish(joint)      # its guard holds the last finite values
                angle, velocity, torque = joint.angle, joint.angular_velocity, joint.torque
            self._joint_states.publish(stamp, msg.sample, angle, velocity, torque)
        self._stats.record(0.0)
        with self._lock:
            self._samples += 1
            self._vents.on_sample(s.status)

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
        self._stop.set()
        self._thread.join(timeout=2.0)
        try:
            self.get_logger().info(
                f'shutdown: safe output {list(self.config["safe_output"])} V '
                + ('sent to the device, port closed' if sent else '(no device connected)'))
        except Exception:  # noqa: BLE001
            pass

    # ------------------------------------------------------------------ diagnostics
    def _report(self):
        window = self._stats.window(time.monotonic())
        d = self._decoder
        core = self._core
        with self._lock:
            info = self._device
            values = {
                'port': self.config['port'],
                'connected': core.connected,
                'device protocol': f'{info.major}.{info.minor}' if info else 'none',
                'encoder fitted': bool(info and info.has_encoder),
                'torque meter fitted': bool(info and info.has_torque),
                'supply transducer fitted': bool(info and info.has_supply),
                'supply_pressure published': self._supply,
                'supply pressure (Pa)': self._supply_value,
                'supply readings not published': self._supply_dropped,
                'achieved rate (Hz)': window.achieved_rate if window.samples else 0.0,
                'samples received': self._samples,
                'connects': core.connects,
                'reconnects': max(core.connects - 1, 0),
                'disconnects': core.disconnects,
                'handshake failures': self._handshake_failures,
                'device refused': self._incompatible or 'none',
                **self._timing.histogram.summary(),    # since start or ~/reset_statistics
                'crc errors': d.crc_errors,
                'garbage bytes': d.garbage_bytes,
                'lost frames': self._rx_seq.lost,
                'sequence gaps': self._rx_seq.gaps,
                'protocol errors': self._protocol_errors,
                'internal errors': core.internal_errors,
                **core.report_values(),
                'last error': self._last_error or 'none',
                'board vents': self._vents.count,
                'board vented now': self._vents.vented,
                'last sample counter': self._ticks.value,
                'device restarts (tick went back)': self._ticks.restarts,
            }
            if self._device_heartbeat is not None:
                rx, crc, trips, _ = self._device_heartbeat
                values.update({'device rx frames': rx, 'device rx crc errors': crc,
                               'device watchdog trips': trips})
            state = SafetyState(connected=core.connected, armed=core.armed,
                                sensor_fault=core.sensor_fault or '',
                                safe_reason=core.safe_reason or '',
                                last_error=self._last_error or '')
        level, message = self._health.judge(values, state)
        return bytes([level]), message, values


#: The node as a component of a composed process (pam_container, pam-bringup --composed).
COMPONENT = Component(NODE_NAME, DriverNode, stop=lambda node: node.stop())


def main(args=None) -> int:
    return component_main(COMPONENT, usage_text(), args)


if __name__ == '__main__':
    sys.exit(main())
