"""Which pressure readings the filter uses (MODEL.md section 5's measurement y = [P1, P2]).

A reading outside [PRESSURE_MIN, PRESSURE_MAX] (Pa abs) is a sensor fault: the update is skipped
and the prediction goes on. NIS_GATE_OFF: no innovation gate (a positive gate rejects an update
whose normalised innovation squared exceeds it). Written once: ukf_node's parameter table,
PamUkf and the batch closed loops take their defaults from here.
"""

PRESSURE_MIN = 1.0e3     # Pa abs: below, a broken or unplugged transducer (vacuum is ~1e3 Pa)
PRESSURE_MAX = 2.0e6     # Pa abs: above, beyond any supply the model is made for
NIS_GATE_OFF = 0.0       # no innovation gate
