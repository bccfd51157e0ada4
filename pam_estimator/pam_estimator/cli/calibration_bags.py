"""pam-calibration-bags: a calibration campaign on the simulated rig, written as bags."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from pam_bag.bags import BagError
from pam_model.cli.common import add_model_arguments, build_model, run_cli
from pam_model.identification.campaign import CampaignPlan, simulate_campaign
from pam_model.parallel import cpus
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

from ..bag_runs import write_run_bag


def float_list(text: str) -> tuple:
    try:
        return tuple(float(v) for v in text.split(',') if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'expected comma-separated numbers, got {text!r}') from None


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='pam-calibration-bags',
        description='Simulates the calibration runs pam-identify needs on a plant (batch '
                    'simulator, as fast as it computes) and writes each as a bag with the topics, '
                    'types and stamps the live stack records (sim_node + profile_player + '
                    'bag_record): OUT/locked_<angle>deg per lock angle (profile '
                    'calibration_locked) and OUT/free (calibration_free). Optionally also '
                    'validation bags of the validation profile with another seed.')
    parser.add_argument('out', metavar='OUT', nargs='?',
                        help='directory for the bags (created; bags in it must not exist yet); '
                             'not with --plan')
    parser.add_argument('--plan', action='store_true',
                        help='write nothing: print the planned runs and the expected 1-sigma of '
                             'every parameter pam-identify fits from them, at the prior (--params '
                             'and --valve-map; the campaign simulated on that model and read '
                             'through the sensor of --scenario, default the mild one: the fits\' '
                             'own Fisher information), and what the campaign cannot identify')
    add_model_arguments(parser, laws=False)
    plan = CampaignPlan()
    parser.add_argument('--angles', type=float_list, default=plan.lock_angles, metavar='DEG,...',
                        help='lock angles of the locked runs; write --angles=-15,0,15 (with =) '
                             'when the first is negative (default: -15,0,15)')
    parser.add_argument('--hold', type=float, default=plan.hold, metavar='S',
                        help='static hold per voltage (default: %(default)s; 0: none)')
    parser.add_argument('--pair-hold', type=float, default=plan.pair_hold, metavar='S',
                        help='hold per voltage pair of the jump phase '
                             '(default: %(default)s; 0: none)')
    parser.add_argument('--voltages', type=float_list, default=plan.voltages, metavar='V,...',
                        help='hold voltages (default: the shipped valve-map table nodes)')
    parser.add_argument('--free-duration', type=float, default=plan.free_duration, metavar='S',
                        help='length of the free run (default: %(default)s; 0: none)')
    parser.add_argument('--seed', type=int, default=plan.seed, help='profile and noise seed')
    parser.add_argument('--validation', type=float, default=0.0, metavar='S',
                        help='also write validation_free and validation_locked: S seconds of the '
                             'validation profile with seed+1 (default: none)')
    args = parser.parse_args(argv)
    if args.out is None and not args.plan:
        parser.error('OUT is required (or --plan)')
    return args


#: The sensor --plan reads the campaign through when --scenario names none: the 'mild' one.
PLAN_SENSOR_SCENARIO = 'mild'


def print_plan(args, plan: CampaignPlan) -> int:
    """--plan: the runs, their length, and the expected uncertainty of every fitted parameter."""
    from pam_model.identification.identify import expected_fits, format_plan
    from pam_model.mismatch import load_scenario
    from pam_model.model import PamModel
    from pam_model.parameters import load_parameters
    from pam_model.valve_map import load_valve_map
    prior = PamModel(params=load_parameters(args.params), valve_map=load_valve_map(args.valve_map))
    sensor_of = args.scenario or PLAN_SENSOR_SCENARIO
    sensor = load_scenario(sensor_of).sensor
    runs = simulate_campaign(prior, sensor, plan)
    total = sum(len(run.t) for _, run in runs) * prior.h
    print(f'pam-calibration-bags --plan: {len(runs)} runs, {total:.0f} s of rig time')
    for name, run in runs:
        print(f'  {name}: {len(run.t) * prior.h:.1f} s, {"locked" if run.locked else "free"} '
              'joint')
    print(f"expected at the prior {args.params!r}, read through the sensor of '{sensor_of}' "
          f'(noise {sensor.noise_std:g} Pa, {sensor.bits}-bit ADC):', flush=True)
    print(format_plan(expected_fits(prior, runs)))
    return 0


def body(argv=None) -> int:
    args = parse_args(argv)
    plan = CampaignPlan(lock_angles=args.angles, hold=args.hold, pair_hold=args.pair_hold,
                        voltages=args.voltages, free_duration=args.free_duration, seed=args.seed)
    if args.plan:
        return print_plan(args, plan)
    model, scenario = build_model(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    count = len(plan.lock_angles) + (plan.free_duration > 0.0)
    print(f'simulating {count} runs and writing their bags in up to {min(count, cpus())} '
          'processes ...', flush=True)
    # the scenario's unmodelled effects too (a 'realistic' rig), not only its sensor; each run's
    # bag is written where it was simulated (the runs in parallel processes)
    runs = simulate_campaign(model, scenario.sensor, plan, effects=scenario.effects,
                             finish=partial(write_bag, out, model.h))
    if args.validation > 0.0:
        profile = validation_profile(args.seed + 1, args.validation, model.h)
        x0 = np.array(REST_STATE)
        for mode, locked in (('free', False), ('locked', True)):
            name = f'validation_{mode}'
            runs.append((name, write_bag(out, model.h, name, simulate(
                replace(model, locked=locked), profile.u, x0, scenario.sensor, args.seed + 1,
                effects=scenario.effects))))
    for _, line in runs:
        print(line, flush=True)
    return 0


def write_bag(out: Path, h: float, name: str, run) -> str:
    """Writes `run` as the bag OUT/name; the line that says so. ValueError if it cannot."""
    try:
        path = write_run_bag(run, out / name)
    except BagError as exc:
        raise ValueError(str(exc)) from exc
    return (f'wrote {path}: {len(run.t)} samples ({len(run.t) * h:.1f} s), '
            f'{"locked" if run.locked else "free"} joint')


def main(argv=None) -> None:
    sys.exit(run_cli(body, argv))


if __name__ == '__main__':
    main()
