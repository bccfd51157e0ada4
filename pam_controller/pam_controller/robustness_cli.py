"""pam-robustness: which imperfection of a rig matters, and how much.

Sweeps each unmodelled effect (pam_model.effects) over its magnitude on top of a base mismatch,
and Monte Carlo parameter deviations, through the estimators and the sensor-less closed loop
(pam_controller.robustness); prints the table, ranks the effects, optionally writes JSON and
plots. docs/robustness.md has the figures and what they mean.
"""

from __future__ import annotations

import argparse
import json
import sys
import textwrap
import time
from pathlib import Path

from pam_model.cli.common import run_cli

from .robustness_plants import PARAMETERS, ROWS

ESTIMATORS = ('nominal', 'oracle', 'oracle+ext', 'identified', 'identified+ext')
DEFAULT_ESTIMATORS = ESTIMATORS[:3]

QUICK = {'magnitudes': (0.0, 1.0, 2.0), 'monte_carlo': 2, 'duration': 12.0,
         'closed_loop': 16.0, 'hold': 8.0}
DEFAULTS = {'magnitudes': (0.0, 0.5, 1.0, 2.0), 'monte_carlo': 6, 'duration': 130.0,
            'closed_loop': 64.0, 'hold': 8.0}
EXAMPLES = '''examples:
  pam-robustness --quick                          every effect at 0, 1, 2 x, short runs (~1 min)
  pam-robustness --json out/robustness.json --plots out/robustness   the full benchmark (~8 min)
  pam-robustness --effects hysteresis,dead_volume --magnitudes 0,0.25,0.5,1,2,4
  pam-robustness --base realistic --effects hysteresis   hysteresis on top of every other effect
  pam-robustness --effects parameters --monte-carlo 20   parameter deviations only
  pam-robustness --quick --identified --effects hysteresis,dead_volume
                          add the identified estimators (a calibration campaign and
                          pam-identify --partial per plant: slow)

rows: {rows}
  a row scales its effect to magnitude x its value in the 'realistic' scenario; 'all' scales
  every effect at once; 'parameters' draws --monte-carlo plants around the base plant.
columns (--estimators): nominal = the UKF with the shipped parameters; oracle = the UKF with
  the plant's TRUE parameters and no model of the effects (perfect identification); oracle+ext =
  the oracle with the plant's true valve lag, dead volume, hysteresis and sensor offset/gain as
  model extensions (docs/model_extensions.md); identified, identified+ext (--identified):
  pam-identify --partial on a simulated calibration campaign of each plant, the paper's model
  only / with the extensions it identifies (its extensions.yaml).
'''


class OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors are one line on stderr (exit 2)."""

    def error(self, message):
        self.exit(2, f'{self.prog}: error: {message} (see --help)\n')


def number_list(text: str) -> tuple:
    try:
        values = tuple(float(v) for v in text.split(',') if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected comma-separated numbers, got {text!r}') \
            from None
    if not values or any(not 0.0 <= v <= 100.0 for v in values):
        raise argparse.ArgumentTypeError(f'magnitudes must be numbers in [0, 100], got {text!r}')
    return tuple(sorted(set(values)))


def name_list(known: tuple, what: str):
    """An argparse type: comma-separated names out of `known` (in the order given, once each)."""
    def parse(text: str) -> tuple:
        names = tuple(dict.fromkeys(v.strip() for v in text.split(',') if v.strip()))
        unknown = [n for n in names if n not in known]
        if unknown or not names:
            raise argparse.ArgumentTypeError(f'unknown {what} {unknown[0] if unknown else text!r}'
                                             f' (known: {", ".join(known)})')
        return names
    return parse


def positive(kind):
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f'must be > 0, got {text!r}')
        return value
    return parse


def parse_args(argv=None) -> argparse.Namespace:
    parser = OneLineParser(
        prog='pam-robustness', formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            'For each unmodelled effect of a real rig (valve lag, dead volume, supply '
            'droop and ripple, force hysteresis, temperature drift, sensor offset and '
            'gain, sensor filter), swept over its magnitude on top of a base mismatch, '
            'and for Monte Carlo parameter deviations: the UKF\'s Q of angle and torque '
            'over the validation profile, and the sensor-less closed loop\'s worst '
            'steady-state error and settling over the demo\'s angle steps (pi_node\'s '
            'default gains). Prints the table and what matters most.', 79),
        epilog=EXAMPLES.format(rows=', '.join(ROWS)))
    parser.add_argument('--base', default='mild', metavar='NAME|FILE',
                        help="mismatch scenario under the sweep: 'mild', 'strong', 'realistic', "
                             "'harsh' or a YAML file (default: %(default)s)")
    parser.add_argument('--effects', type=name_list(ROWS, 'effect'), default=ROWS,
                        metavar='ROW,...',
                        help='rows to sweep (default: all of them)')
    parser.add_argument('--magnitudes', type=number_list, default=None, metavar='M,...',
                        help='multiples of the realistic value (default: 0,0.5,1,2; '
                             '--quick: 0,1,2)')
    parser.add_argument('--monte-carlo', type=int, default=None, metavar='N',
                        help='plants per magnitude of the parameters row (default: 6; --quick: '
                             '2; 0 drops the row)')
    parser.add_argument('--duration', type=positive(float), default=None, metavar='S',
                        help='validation profile length (default: 130; --quick: 12)')
    parser.add_argument('--closed-loop', type=positive(float), default=None, metavar='S',
                        help='closed-loop angle steps length (default: 64; --quick: 16)')
    parser.add_argument('--hold', type=positive(float), default=None, metavar='S',
                        help='closed-loop hold per step (default: 8, the demo\'s)')
    parser.add_argument('--quick', action='store_true',
                        help='few magnitudes, short runs, 2 Monte Carlo plants (about a minute)')
    parser.add_argument('--estimators', type=name_list(ESTIMATORS, 'estimator'),
                        default=DEFAULT_ESTIMATORS, metavar='NAME,...',
                        help=f'columns, of {", ".join(ESTIMATORS)} '
                             f'(default: {",".join(DEFAULT_ESTIMATORS)})')
    parser.add_argument('--identified', action='store_true',
                        help='add the identified estimators (identified, identified+ext): a '
                             'simulated calibration campaign (effects included) and partial '
                             'identification, without and with the extensions, per plant; slow '
                             '(about 25 s of CPU per plant and column with --quick\'s shortened '
                             'campaign, more with the full one; NaN where identify fails)')
    parser.add_argument('--seed', type=int, default=1,
                        help='validation profile, sensor noise and Monte Carlo seed '
                             '(default: %(default)s)')
    parser.add_argument('--json', metavar='FILE', help='write the results as JSON')
    parser.add_argument('--plots', metavar='DIR', help='write robustness_<figure>.png here')
    args = parser.parse_args(argv)
    chosen = QUICK if args.quick else DEFAULTS
    for name in ('magnitudes', 'monte_carlo', 'duration', 'closed_loop', 'hold'):
        if getattr(args, name) is None:
            setattr(args, name, chosen[name])
    if args.monte_carlo < 0:
        parser.error(f'--monte-carlo must be >= 0, got {args.monte_carlo}')
    if args.hold < 2.0 or args.closed_loop < 2 * args.hold:
        parser.error(f'--closed-loop must hold two steps of --hold >= 2 s, got '
                     f'{args.closed_loop:g} s and {args.hold:g} s')
    if args.monte_carlo == 0:
        args.effects = tuple(r for r in args.effects if r != PARAMETERS)
        if not args.effects:
            parser.error('nothing to run: --monte-carlo 0 and only the parameters row')
    return args


def body(argv=None) -> int:
    args = parse_args(argv)
    from pam_model.identification.campaign import CampaignPlan
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel

    from .pi_config import PiConfig
    from .robustness import Settings, run_sweep
    from .robustness_report import format_ranking, format_table, json_document, plot, table_rows

    clock = time.perf_counter()
    base = load_scenario(args.base)
    pi = PiConfig.default()
    gains = pi.angle
    plan = (CampaignPlan(hold=5.0, pair_hold=2.0, free_duration=30.0, seed=args.seed)
            if args.quick else CampaignPlan(seed=args.seed))
    estimators = args.estimators + tuple(
        name for name in ESTIMATORS[3:] if args.identified and name not in args.estimators)
    settings = Settings(base=base, rows=args.effects, magnitudes=args.magnitudes,
                        monte_carlo=args.monte_carlo, seed=args.seed,
                        validation_duration=args.duration, closed_loop_duration=args.closed_loop,
                        reference_hold=args.hold,
                        estimators=estimators, campaign=plan, gains=(gains.kp, gains.ki),
                        limits=gains,
                        anti_windup=pi.anti_windup, tracking_time=pi.tracking_time)
    print(f"pam-robustness: base '{base.name}' ({base.effects.describe()} effects), "
          f'magnitudes {", ".join(f"{m:g}" for m in args.magnitudes)} x realistic, seed '
          f'{args.seed}, gains kp {gains.kp:g} V/rad ki {gains.ki:g} V/(rad s)', flush=True)
    results, timing = run_sweep(settings, PamModel(),
                                log=lambda line: print(line, file=sys.stderr, flush=True))
    rows = table_rows(results, estimators)
    print(format_table(rows, estimators))
    print(format_ranking(rows, estimators))
    elapsed = time.perf_counter() - clock
    print('time: ' + ', '.join(f'{k} {v:.1f} s' for k, v in timing.items() if v)
          + f'; elapsed {elapsed:.1f} s')
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(json_document(settings, rows, results, timing, elapsed),
                                   indent=1) + '\n')
        print(f'wrote {path}')
    if args.plots:
        for path in plot(rows, estimators, args.plots):
            print(f'wrote {path}')
    return 0


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
