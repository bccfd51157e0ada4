"""CalibrationRecord: one calibration run as the identification reads it (SI units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class RecordError(ValueError):
    """A run cannot be used for identification (the message names the run and the problem)."""


@dataclass(frozen=True)
class CalibrationRecord:
    """Samples k = 0..N-1 of one run.

    source: where it came from (shown in messages); t (N,) s; u (N, 2) V, the command in effect
    from t[k] to t[k+1]; psi (N,) rad and psi_dot (N,) rad/s from the encoder; P (N, 2) Pa abs,
    the measured pressures; tau (N,) N m from the torque meter (NaN: not fitted); locked: the
    joint was held (torque experiments).
    """

    source: str
    t: np.ndarray
    u: np.ndarray
    psi: np.ndarray
    psi_dot: np.ndarray
    P: np.ndarray
    tau: np.ndarray
    locked: bool

    def __post_init__(self):
        n = len(self.t)
        if n < 100:
            raise RecordError(f'{self.source}: only {n} samples (need at least 100)')
        shapes = {'u': (n, 2), 'psi': (n,), 'psi_dot': (n,), 'P': (n, 2), 'tau': (n,)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise RecordError(f'{self.source}: {name} has shape '
                                  f'{np.shape(getattr(self, name))}, expected {shape}')
        for name in ('t', 'u', 'psi', 'psi_dot', 'P'):
            bad = np.count_nonzero(~np.isfinite(getattr(self, name)))
            if bad:
                raise RecordError(f'{self.source}: {bad} non-finite values in {name}')
        if np.any(np.diff(self.t) <= 0.0):
            raise RecordError(f'{self.source}: sample times are not strictly increasing')

    @classmethod
    def from_run(cls, run, source: str) -> CalibrationRecord:
        """From a SimulationResult (pam-simulate file or a bag read by pam_estimator.bag_runs):
        its measured pressures, commands, angle, velocity and torque."""
        return cls(source=source, t=np.asarray(run.t, dtype=float),
                   u=np.asarray(run.u, dtype=float), psi=np.asarray(run.x[:, 0], dtype=float),
                   psi_dot=np.asarray(run.x[:, 1], dtype=float),
                   P=np.asarray(run.p_measured, dtype=float),
                   tau=np.asarray(run.torque, dtype=float), locked=bool(run.locked))

    def since(self, k: int) -> CalibrationRecord:
        """The record from sample k on (RecordError if too few samples remain)."""
        return self if k == 0 else self.between(k, len(self.t))

    def between(self, k0: int, k1: int) -> CalibrationRecord:
        """The record of samples k0..k1-1 (RecordError if fewer than 100)."""
        return CalibrationRecord(self.source, self.t[k0:k1], self.u[k0:k1], self.psi[k0:k1],
                                 self.psi_dot[k0:k1], self.P[k0:k1], self.tau[k0:k1],
                                 self.locked)

    @property
    def dt(self) -> np.ndarray:
        """(N-1,) s, the step from each sample to the next."""
        return np.diff(self.t)

    @property
    def has_torque(self) -> bool:
        """A torque meter was read: finite and not identically zero."""
        return bool(np.all(np.isfinite(self.tau)) and np.any(self.tau != 0.0))

    @property
    def lock_angle(self) -> float:
        """rad, the median angle (the lock angle of a locked run)."""
        return float(np.median(self.psi))

    @property
    def travel(self) -> float:
        """rad, the range of the angle."""
        return float(np.ptp(self.psi))
