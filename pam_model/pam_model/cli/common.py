"""Helpers shared by the pam-* command-line tools."""

from __future__ import annotations

import argparse
import sys

from ..parameters import ParameterError
from ..valve_map import ValveMapError


def run_cli(main_body, argv=None) -> int:
    """Run a tool's body; user errors (bad files, values) print one line and exit 2."""
    try:
        return main_body(argv) or 0
    except (ParameterError, ValveMapError, ValueError, OSError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def add_model_arguments(parser: argparse.ArgumentParser, laws: bool = True) -> None:
    """--params, --scenario (alias --mismatch), --valve-map (alias --kappa) and (laws=True)
    --friction, --force, --locked (docs/glossary.md: one name per concept)."""
    from ..model_choices import ForceModel, FrictionLaw
    parser.add_argument('--params', default='default', metavar='SET|FILE',
                        help="Table II set: 'default' (corrected), 'printed', or a YAML file "
                             "(default: %(default)s)")
    parser.add_argument('--scenario', '--mismatch', dest='scenario', default='',
                        metavar='NAME|FILE',
                        help="the plant's scenario, applied to --params: 'mild', 'strong', "
                             "'realistic', 'harsh', 'other_forms' (with unmodelled effects) or a "
                             "YAML file; its sensor model and effects are used too (default: "
                             "none). --mismatch is the former name")
    parser.add_argument('--valve-map', '--kappa', dest='valve_map', default='default',
                        metavar='FILE',
                        help='valve map table CSV (voltage_V,alpha) (default: shipped table). '
                             '--kappa is the former name')
    if not laws:
        parser.set_defaults(friction=str(FrictionLaw.PROPOSED), force=str(ForceModel.PROPOSED),
                            locked=False)
        return
    parser.add_argument('--friction', default=str(FrictionLaw.PROPOSED),
                        choices=FrictionLaw.names(),
                        help='friction law (Table III) (default: %(default)s)')
    parser.add_argument('--force', default=str(ForceModel.PROPOSED), choices=ForceModel.names(),
                        help='contraction force model (default: %(default)s)')
    parser.add_argument('--locked', action='store_true',
                        help='lock the joint at its initial angle (torque experiments)')


def build_model(args):
    """(PamModel, MismatchScenario) from the arguments of add_model_arguments."""
    from ..mismatch import NOMINAL, load_scenario
    from ..model import PamModel
    from ..parameters import load_parameters
    from ..valve_map import load_valve_map
    params = load_parameters(args.params)
    scenario = load_scenario(args.scenario) if args.scenario else NOMINAL
    model = PamModel(params=scenario.apply(params), valve_map=load_valve_map(args.valve_map),
                     friction=args.friction, force=args.force, locked=args.locked)
    return model, scenario
