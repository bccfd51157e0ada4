"""Offline evaluation (Sec. IV of the paper): model alone vs UKF on a recorded run.

A recorded run holds valve commands u (V), measured pressures (Pa abs) and the measured angle
(rad) or torque (N m). The model alone runs open loop from the commands; the UKF additionally
sees the pressures. Metrics I, M, Q of MODEL.md section 6 compare both with the measurement:
angle errors in degrees (free joint), torque errors in N m (locked joint), over the whole run (the
paper's definition, the headline) and after an initial transient (metrics_after, t >= 1 s).

Both start from one state, start_state(run, start):
* 'measured' (the default): what the rig measures at sample 0: the measured angle and angular
  velocity and the first MEASURED pressures (noisy, as a live filter starts; with the sensor
  extensions, read through them as the UKF reads every sample);
* 'recorded': the run's recorded state x[0] (pam-evaluate's former default): in a bag the same
  as 'measured' (a bag's x holds the measured pressures); in a pam-simulate run the TRUE pressures,
  which no estimator on a rig can know. MODEL.md fixes no initial state; the metrics' definitions
  do not depend on the start.

Both may carry the estimator's model extensions (pam_model.model_extensions,
docs/model_extensions.md): the UKF all of them, the model alone all but the sensors' offset and
gain (it reads no pressure); the UKF may also read a measured supply pressure.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pam_model.effects import Effects
from pam_model.metrics import DEFAULT_TRANSIENT, Metrics, metrics, metrics_after
from pam_model.model import PamModel
from pam_model.model_choices import ForceModel, FrictionLaw
from pam_model.model_extensions import NO_EXTENSIONS
from pam_model.simulate import SimulationResult, simulate

from .bias_ukf import BiasStates
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
    """Time series of one estimator over a run: states (N, 4) and torque (N,); biases (N, 3):
    the UKF's bias states b1, b2 (Pa), b_tau (N m) when it carries them, else None."""

    x: np.ndarray
    torque: np.ndarray
    biases: np.ndarray | None = None


#: The initial states start_state() builds (see the module doc); the first is the default.
STARTS = ('measured', 'recorded')


def read_pressures(y, extensions: Effects = NO_EXTENSIONS) -> np.ndarray:
    """Pa abs: the readings y (Pa) through the extensions' sensor offset o and gain error g as
    the UKF reads them, (y - o) / (1 + g)."""
    return ((np.asarray(y, dtype=float) - np.asarray(extensions.sensor_offset))
            / (1.0 + np.asarray(extensions.sensor_gain_error)))


def start_state(run: SimulationResult, start: str = STARTS[0],
                extensions: Effects = NO_EXTENSIONS) -> np.ndarray:
    """The state (4,) [psi rad, psi_dot rad/s, P1 Pa, P2 Pa] the UKF and the model alone start
    from: 'measured' (measured angle and velocity, first measured pressures, read through the
    extensions' sensor offset o and gain error g as the UKF reads them: (y - o) / (1 + g)) or
    'recorded' (the run's x[0])."""
    if start == 'measured':
        pressures = read_pressures(run.p_measured[0], extensions)
        x0 = np.array([run.x[0, 0], run.x[0, 1], pressures[0], pressures[1]], dtype=float)
    elif start == 'recorded':
        x0 = np.array(run.x[0], dtype=float)
    else:
        raise ValueError(f"start must be one of {', '.join(STARTS)}, got {start!r}")
    if not np.all(np.isfinite(x0)):
        raise ValueError(f'the run\'s first sample gives no finite initial state ({start}): '
                         f'{x0.tolist()}')
    return x0


def run_ukf(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING,
            x0=None, extensions: Effects = NO_EXTENSIONS, supply=None,
            bias_states: BiasStates | None = None) -> Estimates:
    """The UKF over a run: at sample k it predicts with u[k-1] and updates with p_measured[k].

    x0: its initial state, default start_state(run, extensions=extensions); extensions: its
    model's
    (pam_model.model_extensions); supply (N,): the measured supply pressure (Pa abs) at each
    sample, P_tank of the step from it (None: the model's P_tank; NaN: the model's for that
    step); bias_states: None or the UKF's bias states (bias_ukf.BiasStates)."""
    x0 = start_state(run, extensions=extensions) if x0 is None else x0
    ukf = PamUkf(model=model, tuning=tuning, x0=tuple(x0), extensions=extensions,
                 bias_states=bias_states)
    X, tau = filter_samples(ukf, run.p_measured, run.u, supply)
    return Estimates(X[:, :4], tau, X[:, 4:] if bias_states is not None else None)


def filter_samples(ukf: PamUkf, pressures, commands, supply=None):
    """The UKF `ukf` (at sample 0's state) over samples 1..N-1: at sample k it predicts with
    commands[k-1] (V, (N, 2)) and updates with pressures[k] (Pa abs, (N, 2)); supply (N,) as in
    run_ukf. (X (N, state size), torque (N,) N m), sample 0 the initial state."""
    n = len(pressures)
    X = np.empty((n, len(ukf.x)))
    tau = np.empty(n)
    X[0] = ukf.x
    tau[0] = ukf.model.outputs(ukf.x[:4])[2]
    for k in range(1, n):
        out = ukf.step(pressures[k], commands[k - 1],
                       None if supply is None else float(supply[k - 1]))
        X[k] = out.x
        tau[k] = out.torque
    return X, tau


def model_alone_effects(extensions: Effects) -> Effects:
    """The extensions the model alone carries: all but the sensors' (it reads no pressure, so a
    sensor's offset or gain error changes nothing it computes)."""
    return replace(extensions, sensor_offset=(0.0, 0.0), sensor_gain_error=(0.0, 0.0))


def run_model_alone(run: SimulationResult, model: PamModel, x0=None,
                    extensions: Effects = NO_EXTENSIONS) -> Estimates:
    """The model open loop from the run's commands, from x0 (default start_state(run)), with
    the extensions' valve lag, dead volume and hysteresis (pam_model.effects.EffectsPlant, through
    simulate); the paper's model (one compiled loop) without."""
    alone = simulate(model, run.u, start_state(run, extensions=extensions) if x0 is None else x0,
                     effects=model_alone_effects(extensions))
    return Estimates(alone.x, alone.torque)


def quantity(run: SimulationResult) -> str:
    """'torque' for a locked-joint run, 'angle' otherwise."""
    return 'torque' if run.locked else 'angle'


def measured_and_estimated(run: SimulationResult, est: Estimates):
    """(measured, estimated) in the metric's unit: degrees for angle, N m for torque."""
    if run.locked:
        return run.torque, est.torque
    return np.degrees(run.x[:, 0]), np.degrees(est.x[:, 0])


def evaluate(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING,
             start: str = STARTS[0], extensions: Effects = NO_EXTENSIONS, supply=None,
             bias_states: BiasStates | None = None):
    """{'model': Metrics, 'ukf': Metrics} (whole run) and the two Estimates for one recorded
    run; both estimators start from start_state(run, start) and carry the extensions; supply,
    bias_states: see run_ukf (the UKF's only)."""
    model = PamModel(params=model.params, valve_map=model.valve_map, friction=model.friction,
                     force=model.force, locked=run.locked, h=model.h)
    x0 = start_state(run, start, extensions)
    alone = run_model_alone(run, model, x0, extensions)
    ukf = run_ukf(run, model, tuning, x0, extensions, supply, bias_states)
    table = {name: metrics(*measured_and_estimated(run, est))
             for name, est in (('model', alone), ('ukf', ukf))}
    return table, alone, ukf


def table_after(run: SimulationResult, alone: Estimates, ukf: Estimates,
                transient: float = DEFAULT_TRANSIENT) -> dict:
    """{'model': Metrics, 'ukf': Metrics} over the samples at t >= t[0] + transient (s)."""
    return {name: metrics_after(run.t, *measured_and_estimated(run, est), transient)
            for name, est in (('model', alone), ('ukf', ukf))}


def compare_models(run: SimulationResult, model: PamModel, tuning: UkfTuning = DEFAULT_TUNING,
                   start: str = STARTS[0], extensions: Effects = NO_EXTENSIONS, supply=None,
                   bias_states: BiasStates | None = None):
    """The UKF with each friction law (Table III) and each force model: {label: Metrics}
    (each with the extensions, the supply and the bias states of run_ukf)."""
    x0 = start_state(run, start, extensions)
    results = {}
    for friction in FrictionLaw:
        variant = PamModel(params=model.params, valve_map=model.valve_map, friction=friction,
                           force=ForceModel.PROPOSED, locked=run.locked, h=model.h)
        results[f'friction {friction}'] = metrics(
            *measured_and_estimated(run, run_ukf(run, variant, tuning, x0, extensions, supply,
                                                   bias_states)))
    for force in (f for f in ForceModel if f is not ForceModel.PROPOSED):
        variant = PamModel(params=model.params, valve_map=model.valve_map,
                           friction=FrictionLaw.PROPOSED, force=force, locked=run.locked,
                           h=model.h)
        results[f'force {force}'] = metrics(
            *measured_and_estimated(run, run_ukf(run, variant, tuning, x0, extensions, supply,
                                                   bias_states)))
    return results


def format_table(kind: str, table: dict, after: dict | None = None,
                 transient: float = DEFAULT_TRANSIENT) -> str:
    """The paper-style table: ours (model alone, UKF) over the whole run beside the paper's
    offline values; with `after` (table_after's), the same rows after the initial transient."""
    unit = 'deg' if kind == 'angle' else 'N m'
    paper = PAPER_OFFLINE[kind]
    lines = [f'{kind} ({unit})         I        M        Q      | paper I   paper M   paper Q',
             '-' * 78]
    for name, label in (('model', 'model alone'), ('ukf', 'UKF')):
        ours, ref = table[name], paper[name]
        lines.append(f'{label:<14} {ours.I:8.4f} {ours.M:8.4f} {100 * ours.Q:7.2f} %  | '
                     f'{ref.I:7.3f}  {ref.M:8.3f}  {100 * ref.Q:7.2f} %')
    if after is not None:
        lines.append(f'after the initial transient (t >= {transient:g} s; the paper\'s figures '
                     'cover the whole run):')
        for name, label in (('model', 'model alone'), ('ukf', 'UKF')):
            ours = after[name]
            lines.append(f'{label:<14} {ours.I:8.4f} {ours.M:8.4f} {100 * ours.Q:7.2f} %')
    return '\n'.join(lines)
