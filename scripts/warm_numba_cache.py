"""Compile the numba kernels once and leave them in numba's on-disk cache (called by setup.sh
after it (re)installs a package: pip's reinstall drops the cache next to the sources).

Without it the first node or tool of a fresh install spends 10-60 s compiling (the UKF node
would miss its first seconds of samples; the first tests would time out on a loaded machine).
"""

import numpy as np

from pam_controller.closed_loop import simulate_closed_loop
from pam_estimator.pam_ukf import PamUkf
from pam_model.effects import Effects
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate

X0 = (0.0, 0.0, 4.5e5, 4.5e5)
# the estimator's extensions (an identified model's extensions.yaml): its kernel with effects
EXTENSIONS = Effects(valve_time_constant=0.005, dead_volume=1e-6, hysteresis_band=1.0,
                     sensor_offset=(1e3, -1e3))
for locked in (False, True):
    model = PamModel(locked=locked)
    model.step(np.array(X0), (5.5, 5.5))
    simulate(model, np.full((3, 2), 5.5), X0, sensor=PressureSensor(2000.0, 12))
    simulate(model, np.full((3, 2), 5.5), X0, effects=load_scenario('realistic').effects)
    PamUkf(model=model, x0=X0).step((4.5e5, 4.5e5), (5.5, 5.5))
    PamUkf(model=model, x0=X0, extensions=EXTENSIONS).step((4.5e5, 4.5e5), (5.5, 5.5))
    simulate_closed_loop(model, model, np.zeros(3), [(1.0, 1.0)], mode='torque' if locked
                         else 'angle')
print('numba kernels compiled and cached')
