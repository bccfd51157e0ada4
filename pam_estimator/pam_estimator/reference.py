"""The same filter built on filterpy's UnscentedKalmanFilter: the test oracle and the speed
baseline. Each sigma point goes through the scalar model step (PamModel.step); filterpy 2.x
redraws the sigma points after the prediction, as MODEL.md section 5 asks. filterpy is needed
only here (a test and benchmark dependency)."""

from __future__ import annotations

import numpy as np

from pam_model.model import PamModel

from .pam_ukf import UkfTuning


def filterpy_ukf(model: PamModel, tuning: UkfTuning, x0):
    """A filterpy UnscentedKalmanFilter with JulierSigmaPoints(kappa=0) over the PAM model.

    Step it with ukf.predict(u=u_prev); ukf.update(y).
    """
    from filterpy.kalman import JulierSigmaPoints, UnscentedKalmanFilter

    def fx(x, dt, u):
        return model.step(x, u)[0]

    def hx(x):
        return x[2:4]

    ukf = UnscentedKalmanFilter(dim_x=4, dim_z=2, dt=model.h, hx=hx, fx=fx,
                                points=JulierSigmaPoints(4, kappa=0.0))
    ukf.x = np.array(x0, dtype=float)
    ukf.P = np.diag(tuning.P0)
    ukf.Q = np.diag(tuning.Q)
    ukf.R = np.diag(tuning.R)
    return ukf
