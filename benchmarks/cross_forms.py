#!/usr/bin/env python3
"""Estimator form x plant family: the UKF's Q after identification on every plant family the
project ships with unmodelled effects (`realistic`: the forms of the estimator's extensions;
`other_forms`: other laws of the same physics, docs/realistic_rig.md).

Per family, with the installed tools as a lab runs them (realistic_targets.identified_model):
  1. pam-calibration-bags: the calibration campaign exactly as it plans it (its defaults), on the
     simulated plant of that scenario (parameter mismatch, sensor, unmodelled effects), seed
     --campaign-seed;
  2. pam-identify --partial on those bags (params.yaml, kappa.csv, extensions.yaml, tuning.yaml:
     the UKF's velocity process noise chosen on the free calibration run);
  3. per profile seed (three by default): the validation profile (--duration s, 130 as the
     paper's) on the plant, free joint and locked, through the UKF as pam-evaluate runs it
     (pam_estimator.evaluation: start state, run_ukf, whole-run metrics) for four estimator
     forms: the nominal model; the identified parameters and valve map without extensions.yaml
     (the paper's model); the identified model with its extensions.yaml and tuning.yaml; the
     same with the default tuning instead of tuning.yaml (what a lab gets if pam-identify's
     noise choice keeps the default) (all but the third with the default tuning).
Prints the table estimator form x family, Q angle (free) and Q torque (locked) in % of the
range, the worst over the seeds; then the WORST cell, over all forms and after identification.

    .venv/bin/python benchmarks/cross_forms.py [--families realistic,other_forms]
        [--seeds 1,2,3] [--duration 130] [--campaign-seed 0] [--keep DIR]
"""

import argparse
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from pam_estimator.calibration_runs import identified_tuning
from pam_estimator.evaluation import measured_and_estimated, run_ukf, start_state
from pam_estimator.pam_ukf import DEFAULT_TUNING
from pam_model.metrics import metrics
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.model_extensions import NO_EXTENSIONS
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate
from pam_model.valve_map import load_valve_map
from realistic_targets import identified_model

FAMILIES = 'realistic,other_forms'
NOMINAL, PAPER, EXTENDED = 'nominal model', "identified, paper's model", 'identified + extensions'
EXTENDED_DEFAULT = 'identified + extensions, default tuning'
FORMS = (NOMINAL, PAPER, EXTENDED, EXTENDED_DEFAULT)
IDENTIFIED = (PAPER, EXTENDED, EXTENDED_DEFAULT)


def estimators(nominal: PamModel, identified, tuning) -> dict:
    """{form: (PamModel, extensions, UKF tuning)} of the estimator forms; `tuning`, the one
    pam-identify chose for its model with extensions (tuning.yaml), goes with that form; the
    others take the default tuning."""
    model, extensions = identified
    return {NOMINAL: (nominal, NO_EXTENSIONS, DEFAULT_TUNING),
            PAPER: (model, NO_EXTENSIONS, DEFAULT_TUNING),
            EXTENDED: (model, extensions, tuning),
            EXTENDED_DEFAULT: (model, extensions, DEFAULT_TUNING)}


def ukf_q(run_, model: PamModel, extensions, tuning=DEFAULT_TUNING) -> float:
    """The UKF's whole-run Q (%) over one run, as pam-evaluate computes it (its start state, the
    model in the run's joint mode)."""
    estimate = run_ukf(run_, replace(model, locked=run_.locked), tuning,
                       x0=start_state(run_, extensions=extensions), extensions=extensions)
    return 100.0 * metrics(*measured_and_estimated(run_, estimate)).Q


def family_cells(scenario, plant: PamModel, forms: dict, seeds, duration: float) -> dict:
    """{form: {'Q_psi': [per seed], 'Q_tau': [per seed]}} (%) on the validation profiles of
    `seeds` (duration s), free joint (angle) and locked (torque)."""
    cells = {form: {'Q_psi': [], 'Q_tau': []} for form in forms}
    for seed in seeds:
        profile = validation_profile(seed, duration, plant.h)
        for locked, key in ((False, 'Q_psi'), (True, 'Q_tau')):
            run_ = simulate(replace(plant, locked=locked), profile.u, REST_STATE,
                            scenario.sensor, seed, effects=scenario.effects)
            for form, (model, extensions, tuning) in forms.items():
                cells[form][key].append(ukf_q(run_, model, extensions, tuning))
    return cells


def worst_cell(table: dict, forms=FORMS):
    """(family, form, worst Q_psi %, worst Q_tau %) of the cell whose larger Q is the largest,
    over `forms`; table: {family: {form: {'Q_psi': [...], 'Q_tau': [...]}}}."""
    return max(((family, form, max(cells[form]['Q_psi']), max(cells[form]['Q_tau']))
                for family, cells in table.items() for form in forms if form in cells),
               key=lambda cell: max(cell[2], cell[3]))


def format_table(table: dict) -> list:
    """Markdown lines: estimator form x family, 'Q angle / Q torque' (worst over the seeds)."""
    families = list(table)
    lines = ['| estimator form | ' + ' | '.join(f'`{f}`: Q angle / Q torque' for f in families)
             + ' |', '| --- |' + ' --- |' * len(families)]
    for form in FORMS:
        if not all(form in table[f] for f in families):
            continue
        lines.append(f'| {form} | ' + ' | '.join(
            f'{max(table[f][form]["Q_psi"]):.2f} % / {max(table[f][form]["Q_tau"]):.2f} %'
            for f in families) + ' |')
    return lines


def print_worst(table: dict) -> None:
    rule = '=' * 78
    print(rule)
    for label, forms in (('WORST CELL', FORMS),
                         ('WORST CELL after pam-identify', IDENTIFIED)):
        family, form, q_psi, q_tau = worst_cell(table, forms)
        print(f'{label}: {form} on `{family}`: Q angle {q_psi:.2f} %, Q torque {q_tau:.2f} % '
              '(worst over the seeds)')
    print(rule)


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--families', default=FAMILIES,
                        help='scenarios (names or YAML files), comma-separated (default: '
                             '%(default)s)')
    parser.add_argument('--seeds', default='1,2,3', help='validation profile seeds')
    parser.add_argument('--duration', type=float, default=130.0, metavar='S',
                        help='validation profile length (default: %(default)s s)')
    parser.add_argument('--campaign-seed', type=int, default=0)
    parser.add_argument('--keep', metavar='DIR', help='keep the bags and results in DIR')
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(',')]
    start = time.perf_counter()
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='pam_cross_forms_'))
    nominal = PamModel(params=load_parameters('default'), valve_map=load_valve_map('default'))
    table = {}
    try:
        for name in args.families.split(','):
            t0 = time.perf_counter()
            scenario = load_scenario(name)
            out = work / Path(name).stem
            out.mkdir(parents=True, exist_ok=True)
            print(f'\n== {name}: {scenario.effects.describe()}', flush=True)
            identified = identified_model(out, name, args.campaign_seed)
            plant = PamModel(params=scenario.apply(nominal.params), valve_map=nominal.valve_map)
            tuning = identified_tuning(out / 'identified')
            print(f'  UKF process noise of the identified model: {list(tuning.Q)}', flush=True)
            table[name] = family_cells(scenario, plant, estimators(nominal, identified, tuning),
                                       seeds, args.duration)
            for form, cells in table[name].items():
                print(f'  {form:<40} Q angle ' + ' '.join(f'{q:5.2f}' for q in cells['Q_psi'])
                      + ' %   Q torque ' + ' '.join(f'{q:5.2f}' for q in cells['Q_tau'])
                      + ' %', flush=True)
            print(f'  ({time.perf_counter() - t0:.0f} s)', flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(f'\nUKF Q (% of range, whole run), worst over profile seeds {args.seeds}, '
          f'{args.duration:g} s profiles, campaign seed {args.campaign_seed}:')
    print('\n'.join(format_table(table)))
    print_worst(table)
    print(f'wall time {time.perf_counter() - start:.0f} s')


if __name__ == '__main__':
    main()
