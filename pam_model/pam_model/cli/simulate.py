"""pam-simulate: run the joint model open loop over an input profile and save the run."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from ..profiles import validation_profile
from ..rest import REST_STATE
from ..sensor import PressureSensor
from ..simulate import simulate
from .common import add_model_arguments, build_model, run_cli


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='pam-simulate',
        description='Batch simulator of the antagonistic PAM joint (Shin et al. 2021): runs the '
                    'model open loop over a valve-voltage profile and writes inputs, true states, '
                    'measured pressures and true torque to a CSV or npz file. SI units.')
    parser.add_argument('-o', '--output', required=True, metavar='FILE',
                        help='output file, .csv or .npz')
    parser.add_argument('--profile', default='validation', choices=['validation'],
                        help='built-in input profile (default: %(default)s, 130 s like Fig. 8)')
    parser.add_argument('--inputs', metavar='CSV',
                        help='use this CSV of valve voltages instead (columns u1,u2 in V, one row '
                             'per sample, header row; a leading t column is ignored)')
    parser.add_argument('--duration', type=float, default=130.0,
                        help='profile duration in s (default: %(default)s)')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the profile and the sensor noise (default: %(default)s)')
    parser.add_argument('--x0', type=float, nargs=4, default=list(REST_STATE),
                        metavar=('PSI', 'PSI_DOT', 'P1', 'P2'),
                        help='initial state in rad, rad/s, Pa, Pa (default: 0 0 450e3 450e3)')
    parser.add_argument('--noise-std', type=float, metavar='PA',
                        help='pressure sensor noise std in Pa (default: from --scenario, else 0)')
    parser.add_argument('--bits', type=int, metavar='N',
                        help='pressure ADC bits over 0-1 MPa (default: from --scenario, else none)')
    add_model_arguments(parser)
    return parser.parse_args(argv)


def read_inputs(path: str) -> np.ndarray:
    table = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    if table.shape[1] not in (2, 3):
        raise ValueError(f'{path}: expected columns u1,u2 or t,u1,u2, got {table.shape[1]}')
    return table[:, -2:]


def body(argv=None) -> int:
    args = parse_args(argv)
    model, scenario = build_model(args)
    sensor = scenario.sensor
    if args.noise_std is not None or args.bits is not None:
        sensor = PressureSensor(
            noise_std=sensor.noise_std if args.noise_std is None else args.noise_std,
            bits=sensor.bits if args.bits is None else args.bits,
            range_min=sensor.range_min, range_max=sensor.range_max)
    U = read_inputs(args.inputs) if args.inputs else validation_profile(args.seed, args.duration).u
    start = time.perf_counter()
    result = simulate(model, U, args.x0, sensor=sensor, seed=args.seed, effects=scenario.effects)
    elapsed = time.perf_counter() - start
    path = result.save(args.output)
    duration = len(U) * model.h
    psi = np.degrees(result.x[:, 0])
    print(f'pam-simulate: {duration:.1f} s at {1 / model.h:.0f} Hz, params {args.params!r}, '
          f'mismatch {scenario.name!r}, friction {model.friction}, force {model.force}, '
          f'joint {"locked" if model.locked else "free"}')
    print(f'  psi {psi.min():+.2f} .. {psi.max():+.2f} deg, '
          f'P {result.x[:, 2:].min() / 1e3:.0f} .. {result.x[:, 2:].max() / 1e3:.0f} kPa, '
          f'tau {result.torque.min():+.3f} .. {result.torque.max():+.3f} N m')
    print(f'  unmodelled effects: {scenario.effects.describe()}')
    print(f'  sensor noise {sensor.noise_std:g} Pa, {sensor.bits or "no"} bits; '
          f'{elapsed:.3f} s wall ({duration / elapsed:.0f}x real time incl. first-call compile)')
    print(f'  wrote {path}')
    return 0


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
