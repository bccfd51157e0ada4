"""Offline evaluation (Sec. IV of the paper): model alone vs UKF on a recorded run.

A recorded run holds valve commands u (V), measured pressures (Pa abs) and the measured angle
(rad) or torque (N m). The model alone runs open loop from the commands; the UKF additionally
sees the pressures. Metrics I, M, Q of MODEL.md section 6 compare both with the measurement:
angle errors in degrees (free joint), torque errors in N m (locked joint).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pam_model.metrics import Metrics, metrics
from pam_model.model import PamModel
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.simulate import SimulationResult, simulate

from .pam_ukf import DEFAULT_TUNING, PamUkf, UkfTuning

#: The paper's offline results (MODEL.md section 6), model alone -> UKF.
PAPER_OFFLINE = {
    'angle': {'model': Metrics(1.053, 3.50, 0.0887), 'ukf': Metrics(0.838, 2.42, 0.0613)},
    'torque': {'model': Metrics(0.162, 0.494, 0.1023), 'ukf': Metrics(0.108, 0.238, 0.0494)},
}
#: Table III (online angle, I / M / Q) of the paper, by our friction-law names.
PAPER_TABLE_III = {'proposed': Metrics(1.16, 3.06, 0.0791), 'linear': Metrics(2.61, 6.74, 0.192),
                   'coulomb': Metrics(1.36, 3.39, 0.0990), 'tondu': Metrics(1.43, 3.38, 0.0983),
                   'none': Metrics(1.57, 3.87, 0.113)}


@dataclass
class Estimates:
    """Time series of one estimator over a run: states (N, 4) and torque (N,)."""

    x: np.ndarray
    torque: np.ndarray


def run_ukf(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING,
            x0=None) -> Estimates:
    """The UKF over a run: at sample k it predicts with u[k-1] and updates with p_measured[k]."""
    x0 = run.x[0] if x0 is None else x0
    ukf = PamUkf(model=model, tuning=tuning, x0=tuple(x0))
    n = len(run.t)
    X = np.empty((n, 4))
    tau = np.empty(n)
    X[0] = ukf.x
    tau[0] = model.outputs(ukf.x)[2]
    for k in range(1, n):
        out = ukf.step(run.p_measured[k], run.u[k - 1])
        X[k] = out.x
        tau[k] = out.torque
    return Estimates(X, tau)


def run_model_alone(run: SimulationResult, model: PamModel, x0=None) -> Estimates:
    """The model open loop from the run's commands (and its initial state)."""
    alone = simulate(model, run.u, run.x[0] if x0 is None else x0)
    return Estimates(alone.x, alone.torque)


def quantity(run: SimulationResult) -> str:
    """'torque' for a locked-joint run, 'angle' otherwise."""
    return 'torque' if run.locked else 'angle'


def measured_and_estimated(run: SimulationResult, est: Estimates):
    """(measured, estimated) in the metric's unit: degrees for angle, N m for torque."""
    if run.locked:
        return run.torque, est.torque
    return np.degrees(run.x[:, 0]), np.degrees(est.x[:, 0])


def evaluate(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING):
    """{'model': Metrics, 'ukf': Metrics} and the two Estimates for one recorded run."""
    model = PamModel(params=model.params, valve_map=model.valve_map, friction=model.friction,
                     force=model.force, locked=run.locked, h=model.h)
    alone = run_model_alone(run, model)
    ukf = run_ukf(run, model, tuning)
    table = {name: metrics(*measured_and_estimated(run, est))
             for name, est in (('model', alone), ('ukf', ukf))}
    return table, alone, ukf


def compare_models(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING):
    """The UKF with each friction law (Table III) and each force model: {label: Metrics}."""
    results = {}
    for friction in FrictionLaw:
        variant = PamModel(params=model.params, valve_map=model.valve_map, friction=friction,
                           force=ForceModel.PROPOSED, locked=run.locked, h=model.h)
        results[f'friction {friction}'] = metrics(
            *measured_and_estimated(run, run_ukf(run, variant, tuning)))
    for force in (f for f in ForceModel if f is not ForceModel.PROPOSED):
        variant = PamModel(params=model.params, valve_map=model.valve_map,
                           friction=FrictionLaw.PROPOSED, force=force, locked=run.locked,
                           h=model.h)
        results[f'force {force}'] = metrics(
            *measured_and_estimated(run, run_ukf(run, variant, tuning)))
    return results


def format_table(kind: str, table: dict) -> str:
    """The paper-style table: ours (model alone, UKF) beside the paper's offline values."""
    unit = 'deg' if kind == 'angle' else 'N m'
    paper = PAPER_OFFLINE[kind]
    lines = [f'{kind} ({unit})         I        M        Q      | paper I   paper M   paper Q',
             '-' * 78]
    for name, label in (('model', 'model alone'), ('ukf', 'UKF')):
        ours, ref = table[name], paper[name]
        lines.append(f'{label:<14} {ours.I:8.4f} {ours.M:8.4f} {100 * ours.Q:7.2f} %  | '
                     f'{ref.I:7.3f}  {ref.M:8.3f}  {100 * ref.Q:7.2f} %')
    return '\n'.join(lines)
