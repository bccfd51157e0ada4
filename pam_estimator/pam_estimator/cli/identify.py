"""pam-identify: fits the model's parameters to calibration runs (bags) and writes them out."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from pam_model.cli.common import run_cli
from pam_model.identification.identify import IdentificationError, format_report, identify
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.valve_map import load_valve_map

from ..calibration_runs import load_records, write_identification
from ..noise_choice import choose_velocity_noise


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='pam-identify',
        description='Parameter identification (MODEL.md sections 3-4) from calibration runs: '
                    'kappa(u) from static holds, the force coefficients from the torque meter '
                    '(locked joint at 2+ angles), the effective valve areas A1, A2 and k2 from '
                    'the pressure transients, mu_s and mu_p from free-joint runs, with scipy '
                    'least squares; and the estimator\'s extensions the runs reveal (sensor '
                    'offsets from the vented holds, force hysteresis from the torque meter, the '
                    'air lines\' dead volume from the transients; docs/identification.md); '
                    'then the UKF\'s velocity process noise on that model, chosen on the free '
                    'runs (pam_estimator.noise_choice). '
                    'Prints each value with its uncertainty and the residuals, and '
                    'writes OUTPUT/params.yaml, OUTPUT/kappa.csv, OUTPUT/extensions.yaml, '
                    'OUTPUT/tuning.yaml and OUTPUT/report.txt, which ukf_node '
                    '(model_parameters, valve_map, model_extensions, process_noise) and '
                    'pam-evaluate (--params, --valve-map, --extensions, --tuning) '
                    'load. Runs: bags recorded while profile_player played profile:='
                    'calibration_locked (joint locked, one bag per lock angle) and '
                    'calibration_free, or made by pam-calibration-bags on the simulator.')
    parser.add_argument('runs', nargs='+', metavar='RUN',
                        help='calibration run: a bag directory (/pam/pressures, '
                             '/pam/valve_command, /pam/joint_measured) or a .npz/.csv run')
    parser.add_argument('-o', '--output', required=True, metavar='DIR',
                        help='directory to create for the results (must not exist)')
    parser.add_argument('--prior', default='default', metavar='SET|FILE',
                        help='parameter set to start from; also supplies what is not identified '
                             '(geometry, gas, J, k_s, c_s, k1) (default: %(default)s)')
    parser.add_argument('--prior-valve-map', '--kappa-prior', dest='prior_valve_map',
                        default='default', metavar='FILE',
                        help='valve map to start from (default: the shipped table); '
                             '--kappa-prior is the former name')
    parser.add_argument('--partial', action='store_true',
                        help='when the runs cannot identify some parameters, keep their prior '
                             'values (listed in the report) instead of failing')
    parser.add_argument('--no-extensions', dest='extensions', action='store_false',
                        help='identify the paper\'s model only: no sensor offsets, hysteresis or '
                             'dead volume (extensions.yaml is then an empty mapping)')
    parser.add_argument('--truth-scenario', '--truth-mismatch', dest='truth_scenario',
                        metavar='NAME|FILE',
                        help='simulated runs only: the plant was --prior with this scenario (as '
                             'pam-calibration-bags --scenario made it); the report then shows '
                             'the true values (and the scenario\'s effects) and the errors; '
                             '--truth-mismatch is the former name')
    parser.add_argument('--no-velocity-noise', dest='velocity_noise', action='store_false',
                        help="keep the UKF's default tuning: do not choose its velocity process "
                             'noise on the free calibration runs (no tuning.yaml)')
    parser.add_argument('--name', default='identified', help='name written into params.yaml')
    return parser.parse_args(argv)


def body(argv=None) -> int:
    args = parse_args(argv)
    if Path(args.output).exists():
        raise ValueError(f'{args.output}: already exists; not overwriting it (choose another '
                         'output)')
    prior = load_parameters(args.prior)
    prior_map = load_valve_map(args.prior_valve_map)
    records = load_records(args.runs)
    for path, record in zip(args.runs, records, strict=True):
        print(f'{path}: {len(record.t)} samples ({record.t[-1] - record.t[0]:.1f} s), '
              f'{"locked" if record.locked else "free"} joint'
              + (f' at {math.degrees(record.lock_angle):+.1f} deg' if record.locked else '')
              + ('' if record.has_torque else ', no torque'), flush=True)
    try:
        ident = identify(records, prior, prior_map, partial=args.partial,
                         log=lambda line: print(line, flush=True), extensions=args.extensions)
    except IdentificationError as exc:
        raise ValueError(f'{exc}\nnothing written') from exc
    choice = None
    if args.velocity_noise:
        print("choosing the UKF's velocity process noise on the free runs ...", flush=True)
        choice = choose_velocity_noise(
            records, PamModel(params=ident.params, valve_map=ident.valve_map), ident.extensions)
    scenario = load_scenario(args.truth_scenario) if args.truth_scenario else None
    truth = scenario.apply(prior) if scenario is not None else None
    report = format_report(ident, prior, truth, prior_map if truth is not None else None,
                           scenario.effects if scenario is not None else None)
    if choice is not None:
        report += '\n\n' + '\n'.join(choice.report())
    files = write_identification(ident, report, args.output, args.name,
                                 None if choice is None else choice.tuning())
    print()
    print(report)
    print()
    print(f'wrote {", ".join(str(f) for f in files.values())}'
          + ('' if ident.complete else ' (PARTIAL: see "NOT identified" above)'))
    noise = ('' if choice is None else
             f' -p process_noise:="[{", ".join(map(yaml_double, choice.tuning().Q))}]"')
    print(f'use: ros2 run pam_estimator ukf_node --ros-args -p model_parameters:={files["params"]}'
          f' -p valve_map:={files["kappa"]} -p model_extensions:={files["extensions"]}{noise}')
    print(f'     pam-evaluate --params {files["params"]} --valve-map {files["kappa"]} '
          f'--extensions {files["extensions"]}'
          + ('' if choice is None else f' --tuning {files["tuning"]}')
          + ' VALIDATION_BAG')
    return 0


def yaml_double(value: float) -> str:
    """value as every YAML reader reads a double: exact, with a decimal point (1e-09 is a
    string to YAML 1.1 and 1000 an integer, and ROS refuses a list of mixed types)."""
    text = repr(float(value))
    return text.replace('e', '.0e') if 'e' in text and '.' not in text else text


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
