"""pam-evaluate: offline evaluation of the model alone and the UKF on a recorded run."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pam_bag.bags import BagError
from pam_model.cli.common import run_cli
from pam_model.metrics import DEFAULT_TRANSIENT, Metrics
from pam_model.model import PamModel
from pam_model.model_extensions import load_extensions
from pam_model.parameters import load_parameters
from pam_model.valve_map import load_valve_map

from ..bag_runs import SUPPLY, is_bag, load_bag_run, load_run
from ..bias_ukf import DEFAULT_BIAS_STATES
from ..calibration_runs import load_tuning
from ..evaluation import (
    PAPER_TABLE_III,
    STARTS,
    compare_models,
    evaluate,
    format_table,
    quantity,
    table_after,
)
from ..pam_ukf import TUNINGS


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='pam-evaluate',
        description='Offline evaluation (Sec. IV of Shin et al. 2021): runs the model alone (open '
                    'loop from the valve commands) and the sensor-less UKF (which also sees the '
                    'pressures) over a recorded run, and prints I, M, Q of the angle (deg, free '
                    'joint) or torque (N m, locked joint) errors beside the paper\'s values. '
                    'Input: a run written by pam-simulate (.npz or .csv) or a recorded bag '
                    'directory (/pam/pressures, /pam/valve_command, /pam/joint_measured; see '
                    'README, Bags).')
    parser.add_argument('runs', nargs='+', metavar='RUN',
                        help='recorded run(s): .npz, .csv or a bag directory '
                             '(metadata.yaml + .mcap)')
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument('--locked', dest='locked', action='store_true', default=None,
                      help='treat the run(s) as locked-joint (torque evaluated); default: a bag is '
                           'locked if its measured angle is constant, a file says what it is')
    mode.add_argument('--free', dest='locked', action='store_false',
                      help='treat the run(s) as free-joint (angle evaluated)')
    parser.add_argument('--params', default='default', metavar='SET|FILE',
                        help="parameters the estimator assumes (default: %(default)s)")
    parser.add_argument('--valve-map', '--kappa', dest='valve_map', default='default',
                        metavar='FILE',
                        help='valve map table CSV (default: shipped table); --kappa is the '
                             'former name')
    parser.add_argument('--extensions', default='', metavar='FILE',
                        help='extensions.yaml of the estimators\' model (pam-identify writes it; '
                             'docs/model_extensions.md): valve lag, dead volume, force '
                             'hysteresis for both, sensor offset and gain for the UKF '
                             '(default: none, the paper\'s model)')
    parser.add_argument('--supply', action='store_true',
                        help='the UKF predicts with the measured supply pressure of the bag '
                             '(/pam/supply_pressure) as P_tank; bags only')
    parser.add_argument('--bias-states', action='store_true',
                        help='the UKF also estimates random-walk biases: pressure-sensor offsets '
                             'b1, b2 (Pa) and a joint-torque bias b_tau (N m), with the default '
                             'rates and initial variances (docs/model_extensions.md, Bias states)')
    parser.add_argument('--tuning', default='default', metavar='|'.join(sorted(TUNINGS)) + '|FILE',
                        help='UKF Q, R, P(0): a preset, or the tuning.yaml pam-identify wrote '
                             '(the default preset with its process_noise) (default: '
                             '%(default)s)')
    parser.add_argument('--transient', type=float, default=DEFAULT_TRANSIENT, metavar='S',
                        help='also print I, M, Q over t >= S s only, leaving out the initial '
                             'transient of the filter (default: %(default)g; the headline table '
                             'covers the whole run, as the paper\'s)')
    parser.add_argument('--start', default=STARTS[0], choices=STARTS,
                        help="state both estimators start from: 'measured' (measured angle and "
                             "velocity, first measured pressures) or 'recorded' (the run's "
                             'recorded x[0]: the true state of a pam-simulate run; the same as '
                             "'measured' for a bag) (default: %(default)s)")
    parser.add_argument('--plots', metavar='DIR',
                        help='write one PNG per run into DIR (like the paper\'s Figs. 9-10)')
    parser.add_argument('--compare-models', action='store_true',
                        help='also run the UKF with every friction law (Table III) and force '
                             'model and print their I / M / Q')
    args = parser.parse_args(argv)
    if not (0.0 <= args.transient < float('inf')):
        parser.error(f'--transient must be a finite number of seconds >= 0, got {args.transient:g}')
    return args


def load_run_and_supply(path, locked, use_supply: bool):
    """(run, supply (N,) Pa abs or None); ValueError if use_supply and the run has none."""
    if not use_supply:
        return load_run(path, locked), None
    if not is_bag(path):
        raise ValueError(f'{path}: --supply needs a bag (with {SUPPLY})')
    bag = load_bag_run(path, locked)
    if bag.supply is None:
        raise ValueError(f'{path}: --supply: no {SUPPLY} in the bag')
    return bag.run, bag.supply


def body(argv=None) -> int:
    args = parse_args(argv)
    model = PamModel(params=load_parameters(args.params), valve_map=load_valve_map(args.valve_map))
    if args.tuning not in TUNINGS and not Path(args.tuning).is_file():
        raise ValueError(f'--tuning {args.tuning}: neither a preset ({", ".join(TUNINGS)}) nor '
                         'a file')
    tuning = TUNINGS[args.tuning] if args.tuning in TUNINGS else load_tuning(args.tuning)
    extensions = load_extensions(args.extensions)
    bias_states = DEFAULT_BIAS_STATES if args.bias_states else None
    for path in args.runs:
        try:
            run, supply = load_run_and_supply(path, args.locked, args.supply)
        except BagError as exc:
            raise ValueError(str(exc)) from exc
        kind = quantity(run)
        table, alone, ukf = evaluate(run, model, tuning, args.start, extensions, supply,
                                     bias_states)
        after = table_after(run, alone, ukf, args.transient)
        print(f'{path}: {len(run.t)} samples ({len(run.t) * model.h:.1f} s), '
              f'{"locked" if run.locked else "free"} joint, tuning {args.tuning!r}, start '
              f'{args.start!r}')
        print(f'model extensions: {extensions.describe()}'
              + (f' ({args.extensions})' if args.extensions else '')
              + (', supply pressure: measured' if supply is not None else ''))
        if ukf.biases is not None:
            b1, b2, b_tau = ukf.biases[-1]
            print(f'bias states at the end: b1 {b1:.0f} Pa, b2 {b2:.0f} Pa, b_tau {b_tau:.4f} N m')
        print(format_table(kind, table, after, args.transient))
        beats = all(getattr(table['ukf'], m) < getattr(table['model'], m) for m in 'IMQ')
        print(f'UKF beats the model alone on I, M and Q: {"yes" if beats else "NO"}')
        if args.plots:
            from ..plots import plot_evaluation
            out = Path(args.plots)
            out.mkdir(parents=True, exist_ok=True)
            name = Path(path).resolve().name if Path(path).is_dir() else Path(path).stem
            png = plot_evaluation(run, alone, ukf, out / f'{name}_{kind}.png',
                                  title=f'{name}: {kind}, model alone vs UKF')
            print(f'wrote {png}')
        if args.compare_models:
            print(f'\nUKF with each model variant ({kind}):')
            print(f'{"variant":<30}       I        M        Q   | paper Table III (online angle)')
            for label, m in compare_models(run, model, tuning, args.start, extensions,
                                           supply, bias_states).items():
                law = label.split(' ', 1)[1]
                ref = PAPER_TABLE_III.get(law) if label.startswith('friction') else None
                ref_text = (f'| {ref.I:.2f} / {ref.M:.2f} / {100 * ref.Q:.2f} %'
                            if isinstance(ref, Metrics) else '|')
                print(f'{label:<30} {m.I:8.4f} {m.M:8.4f} {100 * m.Q:7.2f} % {ref_text}')
        print()
    return 0


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
