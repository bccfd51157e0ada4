"""Calibration runs for pam-identify: read from bags (or pam-simulate files) as CalibrationRecords,
and the identified set written out (parameter YAML, kappa table, the estimator's extensions,
report) all or nothing.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import yaml

from pam_model.identification.records import CalibrationRecord, RecordError
from pam_model.model_extensions import load_extensions, save_extensions
from pam_model.parallel import map_in_processes
from pam_model.parameters import load_parameters, read_yaml, save_parameters
from pam_model.simulate import SimulationResult
from pam_model.valve_map import load_valve_map

from .bag_runs import COMMAND, is_bag, load_bag_run

PARAMS_FILE = 'params.yaml'
KAPPA_FILE = 'kappa.csv'
REPORT_FILE = 'report.txt'
EXTENSIONS_FILE = 'extensions.yaml'
#: ukf_node's process_noise chosen for the identified model (pam_estimator.noise_choice)
TUNING_FILE = 'tuning.yaml'


def identified_ukf_parameters(directory) -> dict:
    """ukf_node's parameters that put it on the model in `directory` (pam-identify's output:
    it always writes the first three files; tuning.yaml, when there, adds process_noise)."""
    directory = Path(directory)
    values = {'model_parameters': str(directory / PARAMS_FILE),
              'valve_map': str(directory / KAPPA_FILE),
              'model_extensions': str(directory / EXTENSIONS_FILE)}
    if (directory / TUNING_FILE).exists():
        values['process_noise'] = list(load_tuning(directory / TUNING_FILE).Q)
    return values


def identified_tuning(directory):
    """The UKF's tuning on the model in `directory`: load_tuning of its tuning.yaml when the file
    is there, else the default tuning."""
    from .pam_ukf import DEFAULT_TUNING
    path = Path(directory) / TUNING_FILE
    return load_tuning(path) if path.exists() else DEFAULT_TUNING


def save_tuning(tuning, path, name: str = 'identified') -> None:
    """Write the layout load_tuning reads: name and process_noise, the tuning's Q (a
    pam_estimator.pam_ukf.UkfTuning)."""
    Path(path).write_text(yaml.safe_dump(
        {'name': name, 'process_noise': [float(q) for q in tuning.Q]}, sort_keys=False))


def load_tuning(path):
    """The default tuning with the process_noise of a tuning.yaml (pam-identify's layout: name,
    process_noise); ValueError naming the file when it is missing or malformed."""
    from .pam_ukf import DEFAULT_TUNING, UkfTuning
    path = Path(path)
    data = read_yaml(path)
    unknown = sorted(set(map(str, data)) - {'name', 'process_noise'})
    if unknown:
        raise ValueError(f'{path}: unknown key {unknown[0]!r} (known: name, process_noise)')
    q = data.get('process_noise')
    if not isinstance(q, list) or not all(isinstance(v, (int, float)) for v in q):
        raise ValueError(f'{path}: process_noise must be a list of 4 numbers, got {q!r}')
    try:
        return UkfTuning(tuple(float(v) for v in q), DEFAULT_TUNING.R,
                         DEFAULT_TUNING.P0).validate()
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from exc


def load_identified(directory):
    """(PamModel, ModelExtensions) of pam-identify's output `directory`, read as ukf_node
    reads them."""
    from pam_model.model import PamModel
    directory = Path(directory)
    return (PamModel(params=load_parameters(directory / PARAMS_FILE),
                     valve_map=load_valve_map(directory / KAPPA_FILE)),
            load_extensions(directory / EXTENSIONS_FILE))


def load_record(path) -> CalibrationRecord:
    """One calibration run; ValueError naming the file and what is wrong or missing. A bag's
    samples before its first recorded valve command are left out (the rig's valves were at a
    command the bag does not hold: a driver's safe output, a simulator's initial command)."""
    from pam_bag.bags import BagError
    path = Path(path)
    if is_bag(path):
        try:
            bag_run = load_bag_run(path)
        except BagError as exc:
            raise ValueError(str(exc)) from exc
        if bag_run.commands == 0:
            raise ValueError(f'{path}: no {COMMAND} messages: the valve map and the valve '
                             'transients need the commands the rig was driven with')
        run = bag_run.run
        start = bag_run.first_commanded     # before it, what the valves got is unknown
    elif path.is_file():
        run = SimulationResult.load(path)
        start = 0
    else:
        raise ValueError(f'{path}: no such bag directory or run file')
    try:
        return CalibrationRecord.from_run(run, str(path)).since(start)
    except RecordError as exc:
        raise ValueError(str(exc)) from exc


def load_records(paths, workers: int | None = None) -> list[CalibrationRecord]:
    """load_record of each path, in that order; the bags are read in parallel processes (one
    per CPU, or `workers`): reading is most of pam-identify's time."""
    return map_in_processes(load_record, [str(p) for p in paths], workers,
                            cost=lambda p: _size(Path(p)))


def _size(path: Path) -> int:
    """Bytes of a run's file or bag directory (what reading it costs)."""
    if path.is_dir():
        return sum(f.stat().st_size for f in path.iterdir() if f.is_file())
    return path.stat().st_size if path.is_file() else 0


def write_identification(ident, report: str, out_dir, name: str = 'identified',
                         tuning=None) -> dict:
    """Write params.yaml, kappa.csv, extensions.yaml (an empty mapping when none was identified),
    report.txt and, with a tuning (pam_estimator.pam_ukf.UkfTuning), tuning.yaml (its Q as
    ukf_node's process_noise) into out_dir, which must not exist.

    The files are written into a temporary sibling, read back with the loaders the nodes use,
    and only then renamed to out_dir: a failure leaves nothing behind. Returns {kind: path}.
    """
    out_dir = Path(out_dir)
    if out_dir.exists():
        raise ValueError(f'{out_dir}: already exists; not overwriting it (choose another output)')
    parent = out_dir.parent if str(out_dir.parent) else Path('.')
    parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f'.{out_dir.name}.', dir=parent))
    try:
        save_parameters(ident.params, staging / PARAMS_FILE, name=name)
        ident.valve_map.save(staging / KAPPA_FILE)
        save_extensions(ident.extensions, staging / EXTENSIONS_FILE, name=name)
        (staging / REPORT_FILE).write_text(report + '\n')
        if tuning is not None:
            save_tuning(tuning, staging / TUNING_FILE, name=name)
            if load_tuning(staging / TUNING_FILE).Q != tuple(float(q) for q in tuning.Q):
                raise ValueError(f'{TUNING_FILE}: does not read back as written')
        load_parameters(staging / PARAMS_FILE)        # what ukf_node will load
        load_valve_map(staging / KAPPA_FILE)
        if load_extensions(staging / EXTENSIONS_FILE) != ident.extensions:
            raise ValueError(f'{EXTENSIONS_FILE}: does not read back as written')
        os.rename(staging, out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return {kind: out_dir / f for kind, f in
            (('params', PARAMS_FILE), ('kappa', KAPPA_FILE), ('extensions', EXTENSIONS_FILE),
             ('report', REPORT_FILE), ('tuning', TUNING_FILE)) if (out_dir / f).exists()}
