"""ControlLoop: what pi_node does with each message, with no ROS in it.

Holds the reference (mode ANGLE in rad or TORQUE in N m), one PI controller per mode, the
enable flag and the last feedback stamp. on_feedback(value, stamp_ns) gives the valve command:
dt comes from consecutive feedback stamps (a dt <= 0 or > dt_max does not update the integral);
when disabled, or before any reference, the command is the safe value. A new reference mode
resets the integral of the new mode.

A reference outside the rig's envelope (ENVELOPE: +-25 deg in angle mode, +-3 N m in torque
mode) is clamped to it and counted (clamped_references); a non-finite one is ignored.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pam_model.rest import REST_COMMAND

from .pi import PiController, PiGains, PiOutput, validate_gains

ANGLE, TORQUE = 0, 1           # pam_interfaces/Reference constants
MODE_NAMES = {ANGLE: 'angle', TORQUE: 'torque'}
MODE_UNITS = {ANGLE: 'rad', TORQUE: 'N m'}
#: The rig's envelope, the largest |reference| per mode (MODEL.md section 1): the joint range
#: +-25 deg (the paper's), and +-3 N m, within what the muscles can give at psi = 0 (the default
#: parameters: +3.17 / -3.20 N m with one muscle at P_tank, the other vented to P_out).
ENVELOPE = {ANGLE: math.radians(25.0), TORQUE: 3.0}


class LoopOutput(NamedTuple):
    u1: float
    u2: float
    error: float
    p_term: float
    i_term: float
    saturated: bool
    active: bool               # False: the safe command (disabled, no reference, bad feedback)


class ControlLoop:
    """Angle and torque PI loops; the feedback must match the reference's mode."""

    def __init__(self, angle_gains: PiGains, torque_gains: PiGains, anti_windup='conditional',
                 tracking_time=0.1, dt_max=0.1, safe_command=REST_COMMAND, mode=ANGLE,
                 reference: float | None = 0.0, enabled: bool = True):
        self.controllers = {ANGLE: PiController(angle_gains, anti_windup, tracking_time, dt_max),
                            TORQUE: PiController(torque_gains, anti_windup, tracking_time,
                                                 dt_max)}
        self.safe_command = tuple(float(u) for u in safe_command)
        self.mode = mode
        self.reference = reference
        self.enabled = enabled
        self.last_stamp_ns: int | None = None
        self.bad_dt = 0
        self.bad_feedback = 0
        self.clamped_references = 0

    @property
    def controller(self) -> PiController:
        return self.controllers[self.mode]

    def set_gains(self, angle_gains: PiGains, torque_gains: PiGains,
                  anti_windup: str | None = None, tracking_time: float | None = None) -> None:
        """Both modes' gains (and, None: unchanged, the anti-windup scheme and tracking time in
        s) at once, as PiController.set_gains checks them: a ValueError changes neither mode."""
        validate_gains(torque_gains)       # the angle call checks the rest before changing it
        self.controllers[ANGLE].set_gains(angle_gains, anti_windup, tracking_time)
        self.controllers[TORQUE].set_gains(torque_gains, anti_windup, tracking_time)

    def set_reference(self, mode: int, value: float) -> str:
        """Accept a reference; returns a message if it was refused, clamped to the envelope or
        changed the mode (a message that starts with 'mode' says only that)."""
        if mode not in MODE_NAMES:
            return f'reference mode {mode} unknown (0 angle, 1 torque): ignored'
        if not math.isfinite(value):
            return f'reference value {value} not finite: ignored'
        message = ''
        if mode != self.mode:
            message = f'mode {MODE_NAMES[self.mode]} -> {MODE_NAMES[mode]}: integral reset'
            self.mode = mode
            self.controller.reset()
        limit = ENVELOPE[mode]
        self.reference = min(max(float(value), -limit), limit)
        if self.reference != value:
            self.clamped_references += 1
            clamp = (f'{MODE_NAMES[mode]} reference {value:g} {MODE_UNITS[mode]} outside the '
                     f"rig's envelope +-{limit:g}: clamped to {self.reference:g} "
                     f'({self.clamped_references} so far)')
            message = f'{clamp}; {message}' if message else clamp
        return message

    def set_enabled(self, enabled: bool) -> None:
        if enabled and not self.enabled:
            self.controller.reset()
            self.last_stamp_ns = None
        self.enabled = enabled

    def safe_output(self) -> LoopOutput:
        return LoopOutput(*self.safe_command, 0.0, 0.0, 0.0, False, False)

    def on_feedback(self, value: float, stamp_ns: int) -> LoopOutput:
        """One control step for a feedback sample (rad or N m, per the current mode)."""
        if not math.isfinite(value):
            self.bad_feedback += 1
            return self.safe_output()
        if not self.enabled or self.reference is None:
            self.last_stamp_ns = stamp_ns
            return self.safe_output()
        dt = 0.0 if self.last_stamp_ns is None else (stamp_ns - self.last_stamp_ns) * 1e-9
        if self.last_stamp_ns is not None and stamp_ns != self.last_stamp_ns and not (
                0.0 < dt <= self.controller.dt_max):
            self.bad_dt += 1      # a repeated stamp (a re-published sample) is not implausible
        if self.last_stamp_ns is None or stamp_ns > self.last_stamp_ns:
            self.last_stamp_ns = stamp_ns
        error = self.reference - value
        out: PiOutput = self.controller.step(error, dt)
        return LoopOutput(out.u1, out.u2, error, out.p_term, out.i_term, out.saturated, True)
