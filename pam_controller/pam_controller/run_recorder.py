"""RunRecorder: collects a run from timestamped messages (no node, no topics) and summarises it.

Samples are keyed by their stamp (ns): ground truth and estimates are matched to the pressure
sample with the same stamp, whatever order they arrive in.
"""

from __future__ import annotations

import numpy as np

from pam_common.stamps import stamp_ns


class RunRecorder:
    """Up to `capacity` samples: pressures, commands, truth and estimates by stamp."""

    def __init__(self, capacity: int, locked: bool = False):
        self.capacity = capacity
        self.locked = locked
        self.stamps = np.zeros(capacity + 1, dtype=np.int64)
        self.p = np.full((capacity + 1, 2), np.nan)
        self.u = np.full((capacity + 1, 2), np.nan)
        self.n = 0
        self.duplicates = 0
        self._index = {}
        self._truth = {}
        self._estimates = {}

    def add_pressures(self, stamp, p1: float, p2: float) -> int | None:
        """Record a sample; its index, or None for a repeated stamp (a re-published sample)."""
        key = stamp_ns(stamp)
        if key in self._index:
            self.duplicates += 1
            return None
        j = self.n
        if j <= self.capacity:
            self.stamps[j] = key
            self.p[j] = (p1, p2)
            self._index[key] = j
        self.n += 1
        return j

    def set_command(self, j: int, u1: float, u2: float) -> None:
        self.u[j] = (u1, u2)

    def add_truth(self, stamp, angle: float, angular_velocity: float, torque: float) -> None:
        self._truth[stamp_ns(stamp)] = (angle, angular_velocity, torque)

    def add_estimate(self, stamp, angle: float, torque: float) -> None:
        self._estimates[stamp_ns(stamp)] = (angle, torque)

    @property
    def estimates_received(self) -> int:
        """The estimates recorded (one per stamp)."""
        return len(self._estimates)

    def _matched(self, table: dict, width: int) -> np.ndarray:
        count = min(self.n, self.capacity)
        out = np.full((count, width), np.nan)
        for j in range(count):
            row = table.get(int(self.stamps[j]))
            if row is not None:
                out[j] = row
        return out

    def summary(self, rate: float) -> list[str]:
        """Human-readable lines: samples, timing, ranges, online estimation metrics."""
        from pam_model.metrics import metrics
        count = min(self.n, self.capacity)
        lines = [f'profile_player summary: {count} samples of {self.capacity} '
                 f'({self.duplicates} re-published duplicates ignored)']
        if count < 2:
            return lines
        t = (self.stamps[:count] - self.stamps[0]) * 1e-9
        gaps = np.diff(t)
        missing = max(0, round(t[-1] * rate) + 1 - count)
        lines.append(f'  stamps span {t[-1]:.3f} s: mean rate {(count - 1) / max(t[-1], 1e-9):.1f}'
                     f' Hz, {missing} samples missing, largest gap {gaps.max() * 1e3:.2f} ms')
        p = self.p[:count]
        lines.append(f'  pressures P1 {p[:, 0].min() / 1e3:.0f}..{p[:, 0].max() / 1e3:.0f} kPa, '
                     f'P2 {p[:, 1].min() / 1e3:.0f}..{p[:, 1].max() / 1e3:.0f} kPa')
        truth = self._matched(self._truth, 3)
        est = self._matched(self._estimates, 2)
        have_truth = ~np.isnan(truth[:, 0])
        if have_truth.any():
            psi = np.degrees(truth[have_truth, 0])
            tau = truth[have_truth, 2]
            lines.append(f'  ground truth ({have_truth.sum()} samples): angle '
                         f'{psi.min():+.2f}..{psi.max():+.2f} deg, torque {tau.min():+.3f}..'
                         f'{tau.max():+.3f} N m')
        both = have_truth & ~np.isnan(est[:, 0])
        if both.sum() > 1:
            if self.locked:
                m = metrics(truth[both, 2], est[both, 1])
                lines.append(f'  online torque estimate ({both.sum()} samples): {m.row(" N m")}')
            else:
                m = metrics(np.degrees(truth[both, 0]), np.degrees(est[both, 0]))
                lines.append(f'  online angle estimate ({both.sum()} samples): {m.row(" deg")}')
        elif self._estimates:
            lines.append('  estimates arrived but none matched a ground-truth stamp')
        else:
            lines.append('  no estimates received (no estimator running)')
        return lines

    def save(self, path, h: float):
        """Save in pam-simulate's format (SimulationResult): pam-evaluate reads it."""
        from pam_model.simulate import SimulationResult
        count = min(self.n, self.capacity)
        truth = self._matched(self._truth, 3)
        x = np.column_stack([truth[:, 0], truth[:, 1], self.p[:count]])
        run = SimulationResult(t=(self.stamps[:count] - self.stamps[0]) * 1e-9,
                               u=np.nan_to_num(self.u[:count], nan=0.0), x=x,
                               torque=truth[:, 2], force=np.full((count, 2), np.nan),
                               friction=np.full(count, np.nan),
                               subsystem=np.zeros(count, dtype=int),
                               p_measured=self.p[:count].copy(), locked=self.locked)
        return run.save(path)
