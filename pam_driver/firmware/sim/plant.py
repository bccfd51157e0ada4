"""The joint for pam-board-sim: pam_model's SimulatedRig stepped once per simulated millisecond.

Run by the harness as a child process (its stdin/stdout are the harness's pipes): at start it
writes the first sample; then, per millisecond, it reads the valve voltages after the board's
op-amp stage (2 little-endian doubles, V), steps the rig with them and writes the sample the board
sees: P1, P2, torque-meter and P_supply transducer voltages (4 doubles, V) and the encoder count
(int64). The SI -> volts chain is the board calibration's (board_calibration.yaml), exactly as
pam-emulator's SI -> counts chain is the driver calibration's: the same plant, seed and noise as
pam-emulator with the same options.
"""

from __future__ import annotations

import argparse
import struct
import sys

COMMAND = struct.Struct('<2d')
SAMPLE = struct.Struct('<4dq')


def build_parser() -> argparse.ArgumentParser:
    from pam_model.cli.common import add_model_arguments
    parser = argparse.ArgumentParser(prog='plant.py', description=__doc__.splitlines()[0])
    parser.add_argument('--calibration', required=True, metavar='FILE')
    parser.add_argument('--x0', type=float, nargs=4, default=[0.0, 0.0, 450e3, 450e3])
    parser.add_argument('--noise-std', type=float, default=500.0, metavar='PA')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--initial-command', type=float, nargs=2, default=[0.0, 0.0],
                        metavar=('U1', 'U2'),
                        help="the valves' voltages before the board's first DAC word (V)")
    parser.add_argument('--offset-volts', type=float, nargs=2, default=[0.0, 0.0],
                        metavar=('P1', 'P2'),
                        help="the P1 and P2 transducers' zero error (V), for the board's "
                             'auto-zero')
    add_model_arguments(parser)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from pam_driver.calibration import SUPPLY, load
    from pam_driver.supply_sensor import SupplySensor
    from pam_model.cli.common import build_model
    from pam_model.rig import SimulatedRig
    from pam_model.sensor import PressureSensor

    cal = load(args.calibration)
    model, scenario = build_model(args)
    sensor = PressureSensor(noise_std=max(args.noise_std, 0.0), bits=0, range_min=0.0,
                            range_max=2e6)
    rig = SimulatedRig(model, args.x0, sensor=sensor, seed=args.seed,
                       u0=tuple(args.initial_command),
                       effects=scenario.effects)
    supply = SupplySensor(rig, sensor, args.seed)
    out = sys.stdout.buffer
    inp = sys.stdin.buffer

    def sample() -> bytes:
        s = rig.sample()
        volts = (cal.pressure_volts(0, float(s.p_measured[0])) + args.offset_volts[0],
                 cal.pressure_volts(1, float(s.p_measured[1])) + args.offset_volts[1],
                 cal.torque_zero_volts + float(s.torque) / cal.torque_nm_per_volt,
                 cal.pressure_volts(SUPPLY, supply.measure()))
        return SAMPLE.pack(*volts, cal.encoder_counts(float(s.x[0])))

    out.write(sample())
    out.flush()
    while True:
        data = inp.read(COMMAND.size)
        if len(data) < COMMAND.size:
            return 0
        rig.set_command(*(min(max(u, 0.0), 10.0) for u in COMMAND.unpack(data)))
        rig.step()
        out.write(sample())
        out.flush()


if __name__ == '__main__':
    sys.exit(main())
