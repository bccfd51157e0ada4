"""driver_node's diagnostics policy, with no ROS in it: from the node's counters and the
DriverCore's safety state, the level and the one-line message of its /diagnostics status.

ERROR: the device is not connected (refused: the reason), a pressure sensor fault, or the board
vented while armed (its own 250 ms watchdog got no host frame: the commanded control was not
applied). WARN: the safe output is on (not armed: the reason), the board vented while safe, or a
fault counter grew since the last status (CRC errors, garbage bytes, lost frames, protocol
errors, clipped or non-finite commands, disconnects). OK: 'armed, <rate> Hz'.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pam_common.levels import ERROR, OK, WARN

#: the counters whose growth since the last status is a WARN
FAULT_COUNTERS = ('crc errors', 'garbage bytes', 'lost frames', 'protocol errors',
                  'commands clipped', 'non-finite commands', 'disconnects')
BOARD_VENTS = 'board vents'


@dataclass(frozen=True)
class SafetyState:
    """The DriverCore's state a status is judged on."""

    connected: bool
    armed: bool
    sensor_fault: str          # '' when none
    safe_reason: str           # why the output is safe ('' when armed)
    last_error: str            # the session's last error ('' when none)


@dataclass
class DriverHealth:
    """Judges one status after another: the counters' growth is taken against the last call."""

    reported: dict = field(default_factory=dict)

    def judge(self, values: dict, state: SafetyState) -> tuple[bytes, str]:
        """(level, message) of a status with these /diagnostics `values` (they hold the
        FAULT_COUNTERS, BOARD_VENTS, 'device refused' and 'achieved rate (Hz)')."""
        vents = values[BOARD_VENTS] - self.reported.get(BOARD_VENTS, 0)
        new = {k: values[k] - self.reported.get(k, 0) for k in FAULT_COUNTERS}
        self.reported = {k: values[k] for k in (*FAULT_COUNTERS, BOARD_VENTS)}
        problems = []
        level = OK
        if not state.connected and values['device refused'] != 'none':
            level = ERROR
            problems.append(f'device refused: {values["device refused"]}')
        elif not state.connected:
            level = ERROR
            problems.append(f'device not connected ({state.last_error or "connecting"})')
        if state.sensor_fault:
            level = ERROR
            problems.append(f'pressure sensor fault: {state.sensor_fault}')
        if not state.armed:
            level = max(level, WARN)
            problems.append(f'safe output: {state.safe_reason}')
        if vents:
            # the valves were at 0 V for a while whatever the driver commanded: while armed,
            # the control was not applied
            level = max(level, ERROR if state.armed else WARN)
            problems.append(f'board vented {vents} times in the last window '
                            f'({values[BOARD_VENTS]} in all): its own watchdog got no host '
                            'frame for its watchdog time')
        recent = [f'{n} {k}' for k, n in new.items() if n]
        if recent:
            level = max(level, WARN)
            problems.append('in the last window: ' + ', '.join(recent))
        return level, '; '.join(problems) or f'armed, {values["achieved rate (Hz)"]:.1f} Hz'
