"""The valve voltage range and the one rule that makes a commanded voltage safe.

Every place that takes a valve command from outside (sim_node through SimulatedRig, ukf_node
through EstimatorCore, the parameter checks of pam_common.node_params) uses these; the compiled
model kernels (physics.valve_opening, ValveMap) apply the same rule to their input. Pure Python,
no numba and no ROS, so that a node imports it without loading the model.
"""

from __future__ import annotations

import math

U_MIN = 0.0     # V, lowest valve voltage: the valve vents the muscle
U_MAX = 10.0    # V, highest valve voltage: the valve fills the muscle

#: How sanitise_command changes a voltage, for log lines and --help text.
SANITISE_RULE = f'non-finite -> {U_MIN:g} V vent, else clipped to [{U_MIN:g}, {U_MAX:g}] V'


def sanitise_command(u: float, low: float = U_MIN, high: float = U_MAX) -> tuple[float, str]:
    """A valve voltage made safe: non-finite -> U_MIN (0 V: vent), else clipped to [low, high]
    (V; by default the valve range [0, 10] V).

    Returns the voltage and '' if it was fine, 'non-finite' or 'out of range' otherwise.
    """
    if not math.isfinite(u):
        return U_MIN, 'non-finite'
    if u < low or u > high:
        return min(max(u, low), high), 'out of range'
    return float(u), ''
