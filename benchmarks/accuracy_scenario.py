"""The accuracy scenario of the estimator issue, shared by the benchmark scripts.

The 130 s validation profile on the 'mild' mismatched plant with its sensor model (2 kPa noise,
12-bit ADC over 0-1 MPa): a free-joint run for the angle and a locked-joint run for the torque.
The filter and the model alone use the nominal (default) parameters.
"""

from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters
from pam_model.profiles import validation_profile
from pam_model.rest import REST_STATE
from pam_model.simulate import simulate

X0 = REST_STATE


def scenario_runs(seed: int = 0, duration: float = 130.0):
    """{'angle': free-joint run, 'torque': locked-joint run} on the mild plant."""
    scenario = load_scenario('mild')
    plant_params = scenario.apply(load_parameters('default'))
    profile = validation_profile(seed, duration)
    return {kind: simulate(PamModel(params=plant_params, locked=locked), profile.u, X0,
                           sensor=scenario.sensor, seed=seed + 1)
            for kind, locked in (('angle', False), ('torque', True))}
