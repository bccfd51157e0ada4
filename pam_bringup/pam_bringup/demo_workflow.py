"""The lab workflow pam-demo follows, as plain steps without processes: where each step's output
goes, the parameter files of the two tracking runs, and the summary of the whole demo.

A lab fits the model to its joint with the encoder and the torque meter still fitted (the
calibration campaign, pam-identify), then drops them and runs the sensor-less stack with the
identified model. pam-demo does that on the simulated rig of a named scenario (default
'realistic': the 'mild' parameter mismatch plus the unmodelled effects of a real rig), and runs
the nominal model beside the identified one for comparison.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import yaml

MARKER = '.pam-demo'        # in every directory pam-demo writes, so that it may replace it
RUNS = ('nominal', 'identified')

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


def run_params(base: dict, scenario: str, identified: Path | None) -> dict:
    """The stack's parameter file for one run: base (config/bringup.yaml's content) with the
    simulated rig on `scenario` and, for the identified run, ukf_node on the identified model
    (params.yaml, kappa.csv, extensions.yaml of pam-identify's output directory: it always
    writes all three)."""
    data = json.loads(json.dumps(base))          # a deep copy of plain YAML data
    sim = data.setdefault('/pam/sim_node', {}).setdefault('ros__parameters', {})
    sim['mismatch'] = scenario
    if identified is not None:
        ukf = data.setdefault('/pam/ukf_node', {}).setdefault('ros__parameters', {})
        ukf['model_parameters'] = str(identified / 'params.yaml')
        ukf['valve_map'] = str(identified / 'kappa.csv')
        ukf['model_extensions'] = str(identified / 'extensions.yaml')
    return data


def write_run_params(paths: DemoPaths, base_file: Path, scenario: str) -> dict:
    """Write the two runs' parameter files; {run: path}."""
    base = yaml.safe_load(Path(base_file).read_text())
    files = {}
    for run in RUNS:
        data = run_params(base, scenario, paths.identified if run == 'identified' else None)
        files[run] = paths.params_file(run)
        files[run].write_text(yaml.safe_dump(data, sort_keys=False))
    return files


def demo_summary(scenario: str, campaign: str, reports: dict, identification: dict) -> dict:
    """out/demo_summary.json: the scenario; per run ('nominal', 'identified') the worst
    steady-state error (% of range), worst settling time (s), the estimation I / M (deg) and
    Q (%) over the whole record and after the transient, and the per-step figures."""
    return {'scenario': scenario, 'campaign': campaign, 'identification': identification,
            **{run: reports.get(run) for run in RUNS}}


def settling(seconds) -> str:
    """A settling time for the table: 'never' for a step that never settled (null, inf)."""
    return 'never' if seconds is None or seconds == float('inf') else f'{seconds:.2f} s'


def comparison_lines(reports: dict) -> list[str]:
    """The nominal-vs-identified table of the demo's end (errors against the true angle)."""
    rows = [f'{"model":<12}{"worst ss error":>16}{"worst settling":>16}{"estimation I":>14}'
            f'{"M":>10}{"Q":>9}{"Q after transient":>19}']
    nan = float('nan')
    for run in RUNS:
        r = reports.get(run)
        if r is None:
            rows.append(f'{run:<12}{"(no report)":>16}')
            continue
        whole = r['estimation'].get('whole', {})
        late = r['estimation'].get('after_transient', {})
        rows.append(f'{run:<12}{r["worst_steady_state_error_pct"]:>14.2f} %'
                    f'{settling(r["worst_settling_time_s"]):>16}'
                    f'{whole.get("I", nan):>10.3f} deg{whole.get("M", nan):>6.2f} deg'
                    f'{whole.get("Q_pct", nan):>7.2f} %{late.get("Q_pct", nan):>17.2f} %')
    return rows
