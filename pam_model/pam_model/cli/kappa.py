"""pam-kappa: the valve map kappa(u) from a measured static voltage/pressure curve
(MODEL.md sec. 4)."""

from __future__ import annotations

import argparse
import sys

from ..parameters import load_parameters
from ..valve_map import (
    DEFAULT_STATIC_CURVE,
    calibrate_valve_map,
    data_path,
    read_two_column_csv,
    steady_pressure,
)
from .common import run_cli


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='pam-kappa',
        description='Valve map kappa(u) by the three-step procedure of Sec. II-C: (a) the model\'s '
                    'static map alpha -> steady pressure, (b) your rig\'s measured map voltage -> '
                    'steady pressure, (c) their composition alpha = Pbar^-1(Pbar(u)). Input: a CSV '
                    'with a header row and columns voltage (V), steady absolute pressure (Pa); '
                    "'#' lines are comments. Output: a kappa table CSV (voltage_V,alpha).")
    parser.add_argument('static_curve', nargs='?', metavar='CSV',
                        help='measured static curve (default: the shipped synthetic curve of the '
                             'simulated rig)')
    parser.add_argument('--params', default='default', metavar='SET|FILE',
                        help="Table II set for step (a): 'default', 'printed' or a YAML file")
    parser.add_argument('-o', '--output', metavar='CSV',
                        help='write the kappa table here (default: print it)')
    return parser.parse_args(argv)


def body(argv=None) -> int:
    args = parse_args(argv)
    params = load_parameters(args.params)
    source = args.static_curve or str(data_path(DEFAULT_STATIC_CURVE))
    u, P = read_two_column_csv(source)
    valve_map = calibrate_valve_map(u, P, params)
    header = (f'# kappa table from {source} with parameters {args.params!r}\n'
              f'# step (a) check: steady pressure at alpha = 0.5 is '
              f'{steady_pressure(0.5, params) / 1e3:.1f} kPa\n')
    text = header + valve_map.to_csv()
    if args.output:
        with open(args.output, 'w') as f:
            f.write(text)
        print(f'pam-kappa: {len(valve_map.u)} points from {source}, wrote {args.output}')
    else:
        sys.stdout.write(text)
    return 0


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
