"""DriverCore: what driver_node decides, with no ROS and no serial port in it.

driver_node feeds it events with their monotonic time (s) and carries out what each returns, an
Action: the output (V) to write to the valves now, whether it changed (~/applied_command is
published on a change), log lines, and a request's reply. The core keeps the safety state and the
counters /diagnostics reports (report_values).

Safety (the choice, documented in README and PROTOCOL.md): the driver is either ARMED (valid
commands, clipped to valve_limits, go to the valves) or SAFE (safe_output, default 0 V = vent both
muscles). It goes SAFE, latched, on: the command watchdog (no valid command for watchdog_timeout
after one was received; on_tick), ~/estop (on_estop), a pressure sensor fault (out of range for
OUT_OF_RANGE_SAMPLES samples in a row, or stuck for stuck_time; on_sample; the supply-pressure
transducer, when the board has one, is checked for the range only: a regulated supply may hold one
reading for long, and a stuck supply reading misleads nobody more than the nominal P_tank would),
the device lost
(on_device_lost), a device refused at the handshake (on_device_refused: nothing is written to it)
and an internal error (on_internal_error). The reason kept is the first one since the last arm
(an e-stop replaces it). It goes back to ARMED only through ~/arm (on_arm), refused while the
device is not connected or a sensor fault persists; even then the valves stay at safe_output until
the next valid command. A device of protocol 1.2 or later (on_connected(device_arm=True): the
reference board) latches faults of its own (its e-stop input, over-pressure, a watchdog reset) and
ignores COMMANDs until it gets ARM: a granted ~/arm asks the node to send ARM too
(Action.device_arm), so that one ~/arm re-arms the rig; the board keeps the faults whose cause
persists (an e-stop still pressed) and the node's /diagnostics goes on reporting its vents. A 1.1
device has no ARM: the reply says so. on_connected starts every session from safe_output;
on_shutdown ends it there.

Commands (on_command) go through the stack's one voltage sanitiser
(pam_model.valve_voltage.sanitise_command) with valve_limits: a command with a non-finite voltage
is ignored and counted (not vented: the watchdog acts if no valid command follows); a finite one
is clipped to valve_limits (counted when it had to be), then applied if armed and connected, else
counted as ignored.

Not thread-safe by itself: driver_node calls every method, and writes the output it returns,
under one lock (the reader thread's samples, watchdog ticks and connection events against the
executor's commands and services), so that a decision and its COMMAND frame are one step.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from pam_model.valve_voltage import U_MAX, U_MIN, sanitise_command

#: Consecutive implausible readings of a pressure sensor that make a sensor fault.
OUT_OF_RANGE_SAMPLES = 5
#: The pressure channels' names in log lines and /diagnostics: P1, P2 and the supply transducer.
CHANNEL_NAMES = ('P1', 'P2', 'P_supply')
STUCK_CHECKED = 2       # the stuck check covers the muscles' sensors only (P1, P2)

Output = tuple[float, float]


@dataclass(frozen=True)
class SafetyConfig:
    """The parameters the decisions use (driver_config: their defaults, --help and checks).

    safe_output: [u1, u2] V of the safe state; valve_limits: [min, max] V commands are clipped
    to; watchdog_timeout: s without a valid command before the safe output (0: no watchdog);
    pressure_limits: [min, max] Pa abs of a plausible reading; stuck_time: s of one identical
    reading that make a stuck sensor (0: no check); arm_at_start: start armed.
    """

    safe_output: Output
    valve_limits: Output
    watchdog_timeout: float
    pressure_limits: Output
    stuck_time: float
    arm_at_start: bool

    def __post_init__(self):
        for name in ('safe_output', 'valve_limits', 'pressure_limits'):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != 2 or not all(math.isfinite(v) for v in value):
                raise ValueError(f'{name}: need 2 finite numbers, got {list(value)}')
            object.__setattr__(self, name, value)
        low, high = self.valve_limits
        if not U_MIN <= low < high <= U_MAX:
            raise ValueError(f'valve_limits: need {U_MIN} <= min < max <= {U_MAX} V, got '
                             f'{list(self.valve_limits)}')
        if not all(U_MIN <= u <= U_MAX for u in self.safe_output):
            raise ValueError(f'safe_output: voltages must be in [{U_MIN}, {U_MAX}] V, got '
                             f'{list(self.safe_output)}')
        for name in ('watchdog_timeout', 'stuck_time'):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f'{name}: must be >= 0 s, got {getattr(self, name)}')

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> SafetyConfig:
        """From driver_config.build_config's checked values."""
        return cls(values['safe_output'], values['valve_limits'], values['watchdog_timeout'],
                   values['pressure_limits'], values['stuck_time'], values['arm_at_start'])


class Log(NamedTuple):
    """A line for the node's log."""

    level: str                 # 'info', 'warning' or 'error'
    text: str
    throttled: bool = False    # a line of the command path (up to 1 kHz): the node throttles it


class Action(NamedTuple):
    """What the node does for one event."""

    output: Output | None = None   # V: write this COMMAND frame now (None: nothing to write)
    changed: bool = False          # the output differs from the previous one: publish it
    logs: tuple[Log, ...] = ()
    ok: bool = True                # a command applied, a request granted
    message: str = ''              # the reply of a request (~/arm, ~/estop)
    device_arm: bool = False       # send ARM to the device (protocol 1.2) before the output


NOTHING = Action()


class DriverCore:
    """The safety state of driver_node and the decisions on it (see the module docstring)."""

    def __init__(self, config: SafetyConfig, calibration):
        """calibration: a pam_driver.calibration.Calibration (the pressure sensors' valid
        voltages)."""
        self.config = config
        self.cal = calibration
        self.armed = bool(config.arm_at_start)
        self.safe_reason = '' if self.armed else 'not armed at start'
        self.output: Output = config.safe_output
        self.connected = False
        self.device_arm = False     # the connected device takes ARM (protocol 1.2)
        self.device_arms = 0        # ARM frames asked for (granted ~/arm on such a device)
        self.last_command_time: float | None = None   # s, the last valid command applied
        self.connects = 0
        self.disconnects = 0
        self.internal_errors = 0
        self.watchdog_trips = 0
        self.last_trip_ms = math.nan
        self.estops = 0
        self.sensor_fault = ''
        self.sensor_faults = 0
        self.commands = 0
        self.commands_clipped = 0
        self.commands_nonfinite = 0
        self.commands_ignored = 0
        self._out_of_range_run = [0] * len(CHANNEL_NAMES)
        self._stuck: list[list] = [[None, 0.0], [None, 0.0]]   # per sensor: counts, since (s)
        #: per channel of the last on_sample: its reading was plausible (valid volts, within
        #: pressure_limits)
        self.plausible: tuple[bool, ...] = ()

    # ------------------------------------------------------------------ the output
    def _send(self, output: Output, logs: Sequence[Log] = (), message: str = '') -> Action:
        changed = output != self.output
        self.output = output
        return Action(output, changed, tuple(logs), True, message)

    def _go_safe(self, reason: str, override: bool = False, logs: Sequence[Log] = (),
                 message: str = '') -> Action:
        """safe_output now, disarmed (latched) until ~/arm. The reason kept is the first one
        since the last arm, unless override (e-stop)."""
        was_armed = self.armed
        self.armed = False
        if was_armed or override or not self.safe_reason:
            self.safe_reason = reason
        self.last_command_time = None
        logs = list(logs)
        if was_armed or override:
            logs.append(Log('warning', f'safe output {list(self.config.safe_output)} V: '
                                       f'{reason}; call ~/arm to resume'))
        return self._send(self.config.safe_output, logs, message)

    # ------------------------------------------------------------------ the executor's events
    def on_command(self, u1: float, u2: float, now: float) -> Action:
        """A valve_command (V) received at `now` (s). ok: it went to the valves."""
        (v1, problem1), (v2, problem2) = (sanitise_command(u, *self.config.valve_limits)
                                          for u in (u1, u2))
        if 'non-finite' in (problem1, problem2):
            self.commands_nonfinite += 1
            return Action(ok=False, logs=(Log('warning', f'non-finite valve_command {(u1, u2)} '
                                                         'ignored', throttled=True),))
        self.commands += 1
        if problem1 or problem2:
            self.commands_clipped += 1
        if not self.armed or not self.connected:
            self.commands_ignored += 1
            return Action(ok=False)
        self.last_command_time = now
        return self._send((v1, v2))

    def on_arm(self) -> Action:
        """~/arm: refused while the device is not connected or a sensor fault persists."""
        if not self.connected:
            ok, message = False, 'refused: device not connected'
        elif self.sensor_fault:
            ok, message = False, f'refused: sensor fault: {self.sensor_fault}'
        else:
            previous = self.safe_reason
            self.armed = True
            self.safe_reason = ''
            self.last_command_time = None
            ok, message = True, (f'armed (was safe: {previous or "-"}); the next valid '
                                 'valve_command is applied')
            if self.device_arm:
                self.device_arms += 1
                message += ('; ARM sent to the board: it clears its latched faults whose cause '
                            'is gone (an e-stop still pressed stays latched: see board vents on '
                            '/diagnostics)')
            else:
                message += '; the board speaks protocol 1.1: it has no ARM (nothing sent)'
        return Action(ok=ok, message=message, logs=(Log('info', f'~/arm: {message}'),),
                      device_arm=ok and self.device_arm)

    def on_estop(self) -> Action:
        """~/estop: safe output, latched, whatever the state."""
        self.estops += 1
        return self._go_safe('e-stop (~/estop)', override=True,
                             message=f'safe output {list(self.config.safe_output)} V; ~/arm to '
                                     'resume')

    # ------------------------------------------------------------------ the reader's events
    def on_tick(self, now: float) -> Action:
        """The command watchdog at `now` (s): trips once no valid command came for
        watchdog_timeout while armed (a command newer than `now` does not trip it)."""
        timeout = self.config.watchdog_timeout
        last = self.last_command_time
        if timeout <= 0.0 or not self.armed or last is None or now - last <= timeout:
            return NOTHING
        self.watchdog_trips += 1
        self.last_trip_ms = (now - last) * 1e3
        return self._go_safe(f'command watchdog: no valve_command for {self.last_trip_ms:.1f} ms')

    def on_sample(self, counts: Sequence[int], pressures: Sequence[float], now: float) -> Action:
        """A sample's pressure readings: ADC counts and Pa abs of P1, P2 (and P_supply when the
        board has the supply transducer: a third of each), read at `now` (s)."""
        low, high = self.config.pressure_limits
        stuck_time = self.config.stuck_time
        problems = []
        plausible = []
        for i in range(len(counts)):
            ok = (self.cal.pressure_volts_valid(i, counts[i])
                  and low <= pressures[i] <= high)   # False for NaN
            plausible.append(ok)
            self._out_of_range_run[i] = 0 if ok else self._out_of_range_run[i] + 1
            if self._out_of_range_run[i] >= OUT_OF_RANGE_SAMPLES:
                problems.append(f'{CHANNEL_NAMES[i]} out of range ({pressures[i]:.0f} Pa, '
                                f'{self.cal.adc_volts(counts[i]):.3f} V)')
            if i >= STUCK_CHECKED:
                continue
            last = self._stuck[i]
            if counts[i] != last[0]:
                last[0], last[1] = counts[i], now
            elif stuck_time > 0.0 and now - last[1] >= stuck_time:
                problems.append(f'{CHANNEL_NAMES[i]} stuck at {counts[i]} counts for '
                                f'{now - last[1]:.2f} s')
        self.plausible = tuple(plausible)
        fault = '; '.join(problems)
        logs = []
        if fault and not self.sensor_fault:
            self.sensor_faults += 1
            logs.append(Log('error', f'pressure sensor fault: {fault}'))
        elif self.sensor_fault and not fault:
            logs.append(Log('info', 'pressure sensors plausible again; ~/arm to resume'))
        self.sensor_fault = fault
        if fault and (self.armed or self.output != self.config.safe_output):
            return self._go_safe(f'pressure sensor fault: {fault}', logs=logs)
        return Action(logs=tuple(logs)) if logs else NOTHING

    def on_connected(self, device_arm: bool = False) -> Action:
        """A device passed the handshake: whatever its valves had before, safe_output.
        device_arm: it takes ARM (protocol 1.2 and later; daq_protocol.DeviceInfo.has_arm)."""
        self.connected = True
        self.device_arm = bool(device_arm)
        self.connects += 1
        return self._send(self.config.safe_output)

    def on_disconnected(self) -> bool:
        """The port is being closed; True if a device was connected (on_device_lost next)."""
        was, self.connected = self.connected, False
        self.disconnects += int(was)
        return was

    def on_device_lost(self, error: str) -> Action:
        """A connected device was lost (unplugged, silent, a write failed)."""
        return self._go_safe(f'device lost ({error})',
                             logs=(Log('error', f'device lost: {error}; reconnecting'),))

    def on_device_refused(self, why: str) -> Action:
        """A device refused at the handshake: disarmed, and nothing is written to it."""
        self.armed = False
        self.last_command_time = None
        self.safe_reason = f'incompatible device: {why}'
        return NOTHING

    def on_internal_error(self, error: str) -> Action:
        """An exception in the node's serial thread (`error` describes it)."""
        self.internal_errors += 1
        return self._go_safe(error, logs=(Log('error', error),))

    def on_shutdown(self) -> Action:
        """The node stops: safe_output, disarmed."""
        self.armed = False
        self.safe_reason = 'shutdown'
        return self._send(self.config.safe_output)

    # ------------------------------------------------------------------ diagnostics
    def report_values(self) -> dict:
        """The safety state and counters, keyed as on /diagnostics."""
        return {
            'armed': self.armed,
            'safe reason': self.safe_reason or 'none',
            'output u1 (V)': self.output[0],
            'output u2 (V)': self.output[1],
            'watchdog timeout (ms)': self.config.watchdog_timeout * 1e3,
            'watchdog trips': self.watchdog_trips,
            'last watchdog trip after (ms)': self.last_trip_ms,
            'e-stops': self.estops,
            'board ARMs sent': self.device_arms,
            'sensor fault': self.sensor_fault or 'none',
            'sensor faults': self.sensor_faults,
            'commands received': self.commands,
            'commands clipped': self.commands_clipped,
            'non-finite commands': self.commands_nonfinite,
            'commands ignored (safe)': self.commands_ignored,
        }
