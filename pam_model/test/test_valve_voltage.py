"""The one voltage sanitiser (pam_model.valve_voltage): its rule, and that the model's own input
paths (the compiled kernel physics.valve_opening, the vectorised ValveMap) read a bad voltage
exactly as the sanitised one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pam_model import physics, rig
from pam_model.valve_map import load_valve_map
from pam_model.valve_voltage import SANITISE_RULE, U_MAX, U_MIN, sanitise_command

BAD_AND_GOOD = [math.nan, math.inf, -math.inf, -1.0, -1e300, 0.0, 3.25, 10.0, 10.5, 1e300]


@pytest.mark.parametrize('u, expected', [
    (math.nan, (0.0, 'non-finite')), (math.inf, (0.0, 'non-finite')),
    (-math.inf, (0.0, 'non-finite')), (-1.0, (0.0, 'out of range')),
    (12.0, (10.0, 'out of range')), (0.0, (0.0, '')), (10.0, (10.0, '')), (5.5, (5.5, '')),
])
def test_rule(u, expected):
    assert sanitise_command(u) == expected


def test_limits_narrower_than_the_valve_range():
    assert sanitise_command(9.5, 1.0, 9.0) == (9.0, 'out of range')
    assert sanitise_command(0.5, 1.0, 9.0) == (1.0, 'out of range')
    assert sanitise_command(math.nan, 1.0, 9.0) == (U_MIN, 'non-finite')   # vent, always


def test_one_function_one_range():
    assert rig.sanitise_command is sanitise_command       # the name the nodes knew
    assert (physics.U_MIN, physics.U_MAX) == (U_MIN, U_MAX) == (0.0, 10.0)
    assert SANITISE_RULE == 'non-finite -> 0 V vent, else clipped to [0, 10] V'


def test_the_model_reads_a_bad_voltage_as_the_sanitised_one():
    valve_map = load_valve_map()
    for u in BAD_AND_GOOD:
        safe, _ = sanitise_command(u)
        assert physics.valve_opening(u, valve_map.u, valve_map.alpha) == \
            physics.valve_opening(safe, valve_map.u, valve_map.alpha), u
    sanitised = np.array([sanitise_command(u)[0] for u in BAD_AND_GOOD])
    np.testing.assert_array_equal(valve_map(np.array(BAD_AND_GOOD)), valve_map(sanitised))


def test_the_plants_array_form_sanitises_as_the_scalar_rule():
    """effects.sanitised_voltages (the valves' start) reads every voltage as sanitise_command
    does: NaN and both infinities vent (U_MIN), the rest is clipped."""
    from pam_model.effects import sanitised_voltages
    u = [math.nan, math.inf, -math.inf, -3.0, 4.5, 12.0]
    assert sanitised_voltages(u).tolist() == [sanitise_command(v)[0] for v in u]
