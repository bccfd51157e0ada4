"""The lab workflow pam-demo follows, as plain steps without processes: where each step's output
goes, the parameter file of the real-time run, the nominal-vs-identified comparison on the batch
closed loop, and the summary of the whole demo.

A lab fits the model to its joint with the encoder and the torque meter still fitted (the
calibration campaign, pam-identify), then drops them and runs the sensor-less stack with the
identified model. pam-demo does that on the simulated rig of a named scenario (default
'realistic': the 'mild' parameter mismatch plus the unmodelled effects of a real rig). The
comparison of the nominal and the identified model runs on the batch closed loop with the
plant's effects (batch_comparison: deterministic, independent of the machine's load); the one
real-time run (the identified stack) is judged for its real-time health by tracking_report.
"""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass, replace
from pathlib import Path

import yaml

MARKER = '.pam-demo'        # in every directory pam-demo writes, so that it may replace it
RUNS = ('nominal', 'identified')
REALTIME_RUN = 'identified'  # the one real-time run

#: pam-calibration-bags' plan for each --campaign choice: 'full' is the documented campaign
#: (3 lock angles, 10 s static holds, 3 s pair holds, 60 s free run); 'quick' a short one
#: (two lock angles, five voltages) for a fast look and the tests: pam-identify then keeps
#: more at the prior (it says which).
CAMPAIGNS = {
    'full': [],
    'quick': ['--angles=-15,15', '--hold', '4', '--pair-hold', '2', '--voltages', '0,3,5,7,10',
              '--free-duration', '30'],
}


@dataclass(frozen=True)
class DemoPaths:
    """Everything pam-demo writes, under out (default ./out)."""

    out: Path

    @property
    def work(self) -> Path:
        """The calibration bags, the identified model and the run parameter files."""
        return self.out / 'demo'

    @property
    def calibration(self) -> Path:
        return self.work / 'calibration'

    @property
    def identified(self) -> Path:
        return self.work / 'identified'

    @property
    def logs(self) -> Path:
        return self.out / 'logs'

    @property
    def summary(self) -> Path:
        return self.out / 'demo_summary.json'

    def params_file(self, run: str) -> Path:
        return self.work / f'bringup_{run}.yaml'

    def report_summary(self, run: str) -> Path:
        return self.work / f'tracking_{run}.json'

    def figure(self, run: str) -> Path:
        """The identified run's figure is the demo's figure (demo_tracking.png)."""
        return self.out / ('demo_tracking.png' if run == 'identified'
                           else f'demo_tracking_{run}.png')

    def prepare(self) -> None:
        """Create out/demo (replacing one an earlier pam-demo wrote) and out/logs.

        ValueError if out/demo exists and was not written by pam-demo (nothing is removed)."""
        if self.work.exists():
            if not (self.work / MARKER).is_file():
                raise ValueError(f'{self.work} exists and was not written by pam-demo; not '
                                 'replacing it (move it away or choose another --out)')
            shutil.rmtree(self.work)
        self.work.mkdir(parents=True)
        (self.work / MARKER).write_text('written by pam-demo; replaced by the next pam-demo\n')
        self.logs.mkdir(parents=True, exist_ok=True)


#: SCHED_FIFO priority of the real-time run's threads on the 1 kHz path (the real-time knobs,
#: docs/realtime.md): granted to root or with an rtprio limit; refused, the nodes say so and
#: run at normal scheduling, and the run's health decides whether its figures are results
REALTIME_PRIORITY = 80
#: the nodes of the real-time run that take the real-time knobs
REALTIME_NODES = ('sim_node', 'ukf_node', 'pi_node', 'reference_node')


def run_params(base: dict, scenario: str, identified: Path | None) -> dict:
    """The stack's parameter file for one run: base (config/bringup.yaml's content) with the
    simulated rig on `scenario`, the real-time knobs on (REALTIME_PRIORITY) and, for the
    identified run, ukf_node on the identified model (params.yaml, kappa.csv, extensions.yaml
    of pam-identify's output directory, and tuning.yaml's process_noise when it is there)."""
    data = json.loads(json.dumps(base))          # a deep copy of plain YAML data
    for node in REALTIME_NODES:
        data.setdefault(f'/pam/{node}', {}).setdefault('ros__parameters', {})[
            'thread_priority'] = REALTIME_PRIORITY
    sim = data.setdefault('/pam/sim_node', {}).setdefault('ros__parameters', {})
    sim['scenario'] = scenario
    if identified is not None:
        from pam_estimator.calibration_runs import identified_ukf_parameters
        data.setdefault('/pam/ukf_node', {}).setdefault('ros__parameters', {}).update(
            identified_ukf_parameters(identified))
    return data


def write_run_params(paths: DemoPaths, base_file: Path, scenario: str) -> dict:
    """Write the real-time run's parameter file (the identified model); {run: path}."""
    base = yaml.safe_load(Path(base_file).read_text())
    data = run_params(base, scenario, paths.identified)
    path = paths.params_file(REALTIME_RUN)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return {REALTIME_RUN: path}


def _section(base: dict, node: str) -> dict:
    return (base.get(f'/pam/{node}') or {}).get('ros__parameters') or {}


def loop_settings(base: dict) -> dict:
    """What the batch closed loop takes from the stack's parameter file (config/bringup.yaml's
    content): pi_node's angle gains, bias, limits and anti-windup (pi_node's own defaults for
    any the file leaves out), the rig's rest state (sim_node's initial_state) and the
    reference's hold (reference_node's)."""
    pi, sim, ref = (_section(base, n) for n in ('pi_node', 'sim_node', 'reference_node'))
    keys = ('kp_angle', 'ki_angle', 'beta', 'u_min', 'u_max', 'anti_windup', 'tracking_time')
    if any(k not in pi for k in keys):
        from pam_controller.pi_config import PARAMETERS  # its table: the defaults
        pi = {**{p.name: p.default for p in PARAMETERS if p.name in keys}, **pi}
    x0 = sim.get('initial_state')
    hold = ref.get('hold')
    if x0 is None or hold is None:
        raise ValueError("the parameter file gives no /pam/sim_node initial_state or "
                         "/pam/reference_node hold")
    return {'gains': (float(pi['kp_angle']), float(pi['ki_angle'])),
            'limits': (float(pi['beta']), float(pi['u_min']), float(pi['u_max'])),
            'anti_windup': str(pi['anti_windup']), 'tracking_time': float(pi['tracking_time']),
            'x0': tuple(float(v) for v in x0), 'hold': float(hold)}


def demo_models(identified: Path) -> dict:
    """{run: (estimator model, extensions, UKF tuning)}: the nominal Table II model without
    extensions with the default tuning, and pam-identify's output (params.yaml, kappa.csv,
    extensions.yaml, tuning.yaml)."""
    from pam_estimator.calibration_runs import identified_tuning, load_identified
    from pam_estimator.pam_ukf import DEFAULT_TUNING
    from pam_model.model import PamModel
    from pam_model.model_extensions import NO_EXTENSIONS
    from pam_model.parameters import load_parameters
    from pam_model.valve_map import load_valve_map
    nominal = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    return {'nominal': (nominal, NO_EXTENSIONS, DEFAULT_TUNING),
            'identified': (*load_identified(identified), identified_tuning(identified))}


def batch_comparison(scenario: str, models: dict, settings: dict, duration: float,
                     seed: int) -> dict:
    """The models ({run: (PamModel, extensions, UKF tuning)}) compared on the batch closed loop
    with the plant's effects (pam_controller.closed_loop.simulate_closed_loop_with_effects): the
    plant is the nominal model with the scenario's mismatch, stepped with its effects and read
    through its sensor; the reference the paper-style angle steps
    (pam_model.profiles.step_reference_profile, `seed`, `duration` s, the reference's hold); PI,
    rest state from `settings` (loop_settings).
    Deterministic: the same arguments give the same figures, whatever the machine's load.
    {run: figures}, each as tracking_report's summary (angle mode, deg, errors against the true
    angle in % of the 40 deg range, settling in s, estimation I / M in deg and Q in %)."""
    from pam_controller.closed_loop import simulate_closed_loop_with_effects
    from pam_controller.pi import PiGains
    from pam_controller.step_metrics import ANGLE_SPAN
    from pam_model.metrics import metrics
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.parameters import load_parameters
    from pam_model.profiles import step_reference_profile
    from pam_model.valve_map import load_valve_map
    rig = load_scenario(scenario)
    nominal = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    plant = PamModel(params=rig.apply(nominal.params), valve_map=nominal.valve_map)
    reference = step_reference_profile('angle', seed, duration, settings['hold'], plant.h).value
    scale = math.degrees(1.0)
    out = {}
    for run, (model, extensions, tuning) in models.items():
        loop = simulate_closed_loop_with_effects(
            plant, rig.effects, replace(model, locked=plant.locked), reference,
            settings['gains'], sensor=rig.sensor, tuning=tuning, mode='angle',
            anti_windup=settings['anti_windup'], tracking_time=settings['tracking_time'],
            limits=PiGains(0.0, 0.0, *settings['limits']), x0=settings['x0'], seed=seed,
            extensions=extensions)
        report = loop.report(ANGLE_SPAN, 2.0)
        m = metrics(loop.truth * scale, loop.estimate * scale)
        out[run] = {
            'mode': 'angle', 'unit': 'deg', 'simulated_s': float(loop.t[-1]),
            'samples': len(loop.t), 'gains': list(settings['gains']),
            'steps': [{'t_start_s': st.t_start, 'reference': st.reference * scale,
                       'steady_state_error_pct': st.steady_error,
                       'settling_time_s': st.settling_time, 'overshoot_pct': st.overshoot,
                       'ripple_pct': st.ripple} for st in report.steps],
            'worst_steady_state_error_pct': report.worst_error,
            'worst_settling_time_s': report.worst_settling,
            'estimation': {'whole': {'I': m.I, 'M': m.M, 'Q_pct': 100.0 * m.Q}},
        }
    return out


def demo_summary(scenario: str, campaign: str, identification: dict, comparison: dict,
                 realtime: dict | None, valid: bool, timer_floor: dict | None = None,
                 model_cost: dict | None = None) -> dict:
    """out/demo_summary.json: the scenario, the campaign, what identification left at the
    prior; 'comparison': per model ('nominal', 'identified') the batch closed loop's figures
    (batch_comparison); 'timer_floor': the machine's own timer and 'model_cost' the stack's
    models' compute per sample (s; pam_bringup.model_cost), both measured just before the
    real-time run; 'realtime': the identified real-time run's tracking_report summary with its
    'health'; 'valid': whether that run was real time (its figures are results)."""
    return {'scenario': scenario, 'campaign': campaign, 'identification': identification,
            'comparison': comparison, 'timer_floor': timer_floor, 'model_cost': model_cost,
            'realtime': realtime, 'valid': valid}


def settling(seconds) -> str:
    """A settling time for the table: 'never' for a step that never settled (null, inf)."""
    return 'never' if seconds is None or seconds == float('inf') else f'{seconds:.2f} s'


def comparison_lines(comparison: dict) -> list[str]:
    """The nominal-vs-identified table of the batch comparison (errors against the true angle):
    per model the worst steady-state error, worst settling, estimation I / M / Q; then per
    step the steady-state error and settling of each model."""
    runs = [run for run in RUNS if run in comparison]
    rows = [f'{"model":<12}{"worst ss error":>16}{"worst settling":>16}{"estimation I":>14}'
            f'{"M":>10}{"Q":>9}']
    for run in runs:
        r = comparison[run]
        m = r['estimation']['whole']
        rows.append(f'{run:<12}{r["worst_steady_state_error_pct"]:>14.2f} %'
                    f'{settling(r["worst_settling_time_s"]):>16}'
                    f'{m["I"]:>10.3f} deg{m["M"]:>6.2f} deg{m["Q_pct"]:>7.2f} %')
    rows.append('per step (steady-state error % of 40 deg, settling):')
    rows.append(f'{"t (s)":>7}{"reference":>12}' + ''.join(f'{run:>24}' for run in runs))
    steps = comparison[runs[0]].get('steps', []) if runs else []
    for i, step in enumerate(steps):
        cells = ''
        for run in runs:
            s = comparison[run]['steps'][i]
            cells += f'{s["steady_state_error_pct"]:>12.2f} %{settling(s["settling_time_s"]):>10}'
        rows.append(f'{step["t_start_s"]:>7.1f}{step["reference"]:>8.2f} deg' + cells)
    return rows
