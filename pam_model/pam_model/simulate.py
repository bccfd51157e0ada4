"""Batch (open-loop) simulation of the joint over an input profile, with an optional sensor model.

The loop runs in one compiled kernel over the scalar RK4 step, so a 130 s profile at 1 kHz takes
well under a second after the first (cached) compilation. A plant with unmodelled effects
(pam_model.effects) steps sample by sample through SimulatedRig instead (numpy around a numba
step, about 25x slower: a few seconds for 130 s).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from .effects import Effects
from .model import PamModel
from .physics import rk4_step, valve_opening
from .sensor import PressureSensor


@njit(cache=True)
def simulate_kernel(x0, U, h, p_array, kappa_u, kappa_alpha, friction_law, force_model, locked):
    """States X (N+1, 4), friction T_f (N,) and sigma (N,) over inputs U (N, 2) in V.

    p_array: Parameters.as_record_array()."""
    p = p_array[0]
    n = U.shape[0]
    X = np.empty((n + 1, 4))
    T_f = np.empty(n)
    sigma = np.empty(n, dtype=np.int64)
    X[0, :] = x0
    for j in range(n):
        alpha1 = valve_opening(U[j, 0], kappa_u, kappa_alpha)
        alpha2 = valve_opening(U[j, 1], kappa_u, kappa_alpha)
        psi, psi_dot, P1, P2, T_f[j], sigma[j] = rk4_step(
            X[j, 0], X[j, 1], X[j, 2], X[j, 3], alpha1, alpha2, h, p, friction_law, force_model,
            locked)
        X[j + 1, 0] = psi
        X[j + 1, 1] = psi_dot
        X[j + 1, 2] = P1
        X[j + 1, 3] = P2
    return X, T_f, sigma


@dataclass
class SimulationResult:
    """One open-loop run: time t (s), inputs u (V), true states x, outputs, measured pressures.

    Row j holds the state at t[j] and the input applied from t[j] to t[j+1] (zero-order hold).
    """

    t: np.ndarray                # (N,) s
    u: np.ndarray                # (N, 2) V
    x: np.ndarray                # (N, 4) rad, rad/s, Pa abs, Pa abs
    torque: np.ndarray           # (N,) N m, true joint torque tau of eq. (8)
    force: np.ndarray            # (N, 2) N, F1 and F2
    friction: np.ndarray         # (N,) N m, T_f used in the step from row j
    subsystem: np.ndarray        # (N,) sigma in 1..18
    p_measured: np.ndarray       # (N, 2) Pa abs, sensor readings (equal to x[:, 2:] without one)
    locked: bool = False

    COLUMNS = ('t', 'u1', 'u2', 'psi', 'psi_dot', 'P1', 'P2', 'tau', 'F1', 'F2', 'T_f',
               'sigma', 'P1_meas', 'P2_meas')
    UNITS = ('s', 'V', 'V', 'rad', 'rad/s', 'Pa', 'Pa', 'N m', 'N', 'N', 'N m', '-', 'Pa', 'Pa')

    def table(self) -> np.ndarray:
        """All columns side by side, (N, 14), in COLUMNS order."""
        return np.column_stack([self.t, self.u, self.x, self.torque, self.force, self.friction,
                                self.subsystem, self.p_measured])

    def save(self, path: str | Path) -> Path:
        """Write .npz (named arrays) or .csv (one header row with units) by the file suffix."""
        path = Path(path)
        if path.suffix == '.npz':
            np.savez_compressed(path, **dict(zip(self.COLUMNS, self.table().T, strict=True)),
                                locked=np.array(self.locked))
        elif path.suffix == '.csv':
            header = ','.join(f'{c} [{u}]' for c, u in zip(self.COLUMNS, self.UNITS, strict=True))
            np.savetxt(path, self.table(), delimiter=',', header=header, comments='',
                       fmt='%.10g')
        else:
            raise ValueError(f'{path}: output must end in .csv or .npz')
        return path

    @classmethod
    def load(cls, path: str | Path) -> SimulationResult:
        """Read back a file written by save()."""
        path = Path(path)
        if path.suffix == '.npz':
            with np.load(path) as f:
                cols = {c: f[c] for c in cls.COLUMNS}
                locked = bool(f['locked'])
        else:
            table = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
            cols = dict(zip(cls.COLUMNS, table.T, strict=True))
            locked = False
        return cls(t=cols['t'], u=np.column_stack([cols['u1'], cols['u2']]),
                   x=np.column_stack([cols['psi'], cols['psi_dot'], cols['P1'], cols['P2']]),
                   torque=cols['tau'], force=np.column_stack([cols['F1'], cols['F2']]),
                   friction=cols['T_f'], subsystem=cols['sigma'].astype(int),
                   p_measured=np.column_stack([cols['P1_meas'], cols['P2_meas']]),
                   locked=locked)


def simulate(model: PamModel, U, x0, sensor: PressureSensor | None = None,
             seed: int = 0, effects: Effects | None = None) -> SimulationResult:
    """Run the model open loop over inputs U (N, 2) in V from state x0 (4,).

    The sensor model (noise, quantisation) draws from numpy's default generator seeded by seed.
    With effects active, the plant of pam_model.effects (torque, forces and readings include them).
    """
    U = np.ascontiguousarray(U, dtype=float)
    if U.ndim != 2 or U.shape[1] != 2:
        raise ValueError(f'inputs must have shape (N, 2), got {U.shape}')
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (4,) or not np.all(np.isfinite(x0)):
        raise ValueError(f'initial state must be 4 finite numbers, got {x0!r}')
    if effects is not None and effects.active:
        return simulate_with_effects(model, U, x0, sensor, seed, effects)
    X, T_f, sigma = simulate_kernel(x0, U, model.h, model.params_array, model.valve_map.u,
                                    model.valve_map.alpha,
                                    model.friction_code, model.force_code, model.locked)
    X = X[:-1]
    F1, F2, tau = model.outputs(X)
    P_true = X[:, 2:]
    P_meas = P_true.copy() if sensor is None else sensor.measure(P_true,
                                                                 np.random.default_rng(seed))
    return SimulationResult(t=np.arange(len(U)) * model.h, u=U, x=X, torque=tau,
                            force=np.column_stack([F1, F2]), friction=T_f, subsystem=sigma,
                            p_measured=P_meas, locked=model.locked)


def simulate_with_effects(model: PamModel, U, x0, sensor, seed, effects) -> SimulationResult:
    """simulate() through a SimulatedRig carrying the effects' internal states, one sample at a
    time (the sensor draws its noise per sample)."""
    from .rig import SimulatedRig
    n = len(U)
    ideal = PressureSensor(bits=0, range_max=1.0e9)   # no sensor: the readings before noise/ADC
    rig = SimulatedRig(model, x0, sensor=sensor or ideal,
                       seed=seed, u0=U[0] if n else (0.0, 0.0), effects=effects)
    X = np.empty((n, 4))
    force = np.empty((n, 2))
    torque = np.empty(n)
    P_meas = np.empty((n, 2))
    T_f = np.empty(n)
    sigma = np.empty(n, dtype=np.int64)
    for j in range(n):
        rig.set_command(U[j, 0], U[j, 1])
        sample = rig.sample()
        X[j], force[j], torque[j], P_meas[j] = sample.x, sample.force, sample.torque, \
            sample.p_measured
        T_f[j], sigma[j] = rig.step_full()
    return SimulationResult(t=np.arange(n) * model.h, u=U, x=X, torque=torque, force=force,
                            friction=T_f, subsystem=sigma, p_measured=P_meas, locked=model.locked)
