"""The filter against references: a closed-form Kalman filter on a linear system, and the same
filter built on filterpy's UnscentedKalmanFilter with JulierSigmaPoints(kappa=0)."""

import numpy as np
import pytest

from pam_estimator.pam_ukf import DEFAULT_TUNING, PAPER_TUNING, PamUkf
from pam_estimator.reference import filterpy_ukf
from pam_estimator.unscented import (
    inverse,
    julier_sigma_points,
    julier_weights,
    measurement_update,
    unscented_transform,
)
from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate


def test_linear_case_equals_the_closed_form_kalman_filter():
    rng = np.random.default_rng(0)
    n, m = 4, 2
    A = np.eye(n) + 0.05 * rng.standard_normal((n, n))
    C = rng.standard_normal((m, n))
    Q = np.diag([1e-3, 2e-3, 1e-2, 5e-3])
    R = np.diag([0.1, 0.2])
    x_ukf = x_kf = np.zeros(n)
    P_ukf = P_kf = np.eye(n)
    W = julier_weights(n, 0.0)
    x_true = rng.standard_normal(n)
    for _ in range(200):
        x_true = A @ x_true + rng.multivariate_normal(np.zeros(n), Q)
        y = C @ x_true + rng.multivariate_normal(np.zeros(m), R)
        # closed form
        x_kf, P_kf = A @ x_kf, A @ P_kf @ A.T + Q
        K = P_kf @ C.T @ np.linalg.inv(C @ P_kf @ C.T + R)
        x_kf, P_kf = x_kf + K @ (y - C @ x_kf), P_kf - K @ C @ P_kf
        # unscented pieces
        sigmas, _ = julier_sigma_points(x_ukf, P_ukf, 0.0)
        x_prior, P_prior = unscented_transform(sigmas @ A.T, W, Q)
        sigmas, _ = julier_sigma_points(x_prior, P_prior, 0.0)
        x_ukf, P_ukf, nis, accepted = measurement_update(x_prior, P_prior, sigmas,
                                                         sigmas @ C.T, W, R, y, 0.0)
        assert accepted and nis >= 0.0
        np.testing.assert_allclose(x_ukf, x_kf, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(P_ukf, P_kf, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize('m', [2, 3], ids=['closed_form', 'lapack'])
def test_the_measurement_update_compiles_without_performance_warnings(m):
    """inverse() returns one layout (C) from every branch: a LAPACK result left Fortran-ordered
    made numba type it 'A', and each product with it warned at the first compile of every UKF
    step (compiled afresh here: a cached kernel would not warn)."""
    import warnings

    from numba import njit
    from numba.core.errors import NumbaPerformanceWarning
    assert inverse(np.eye(m) * 2.0).flags.c_contiguous
    n = 4
    x, P = np.zeros(n), np.eye(n)
    sigmas, _ = julier_sigma_points(x, P, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter('error', NumbaPerformanceWarning)
        fresh = njit(measurement_update.py_func)
        x_post, _, _, accepted = fresh(x, P, sigmas, sigmas[:, :m].copy(),
                                       julier_weights(n, 0.0), np.eye(m), np.ones(m), 0.0)
    assert accepted and np.all(np.isfinite(x_post))


@pytest.mark.parametrize('tuning', [PAPER_TUNING, DEFAULT_TUNING], ids=['paper', 'default'])
def test_agrees_with_filterpy_over_10_s(tuning):
    """10 s of the validation profile (steps: the joint moves) with a noisy 12-bit sensor."""
    profile = validation_profile(seed=2, duration=40.0)
    U = profile.u[10_000:20_000]                        # 10 s of steps: the joint moves
    x0 = [0.1, 0.0, 4.0e5, 5.0e5]
    run = simulate(PamModel(), U, x0, sensor=PressureSensor(2000.0, 12), seed=4)
    model = PamModel()
    ours = PamUkf(model=model, tuning=tuning, x0=(0.0, 0.0, 4.5e5, 4.5e5))
    ref = filterpy_ukf(model, tuning, ours.x)
    scale = np.array([1.0, 1.0, 1e5, 1e5])
    worst = 0.0
    for k in range(1, len(U)):
        out = ours.step(run.p_measured[k], U[k - 1])
        ref.predict(u=U[k - 1])
        ref.update(run.p_measured[k])
        worst = max(worst, np.max(np.abs(out.x - ref.x) / scale))
        assert worst < 1e-9, (k, out.x, ref.x)
        np.testing.assert_allclose(out.P, ref.P, rtol=1e-6, atol=1e-12 * np.max(np.abs(ref.P)))
    assert np.ptp(run.x[:, 0]) > 0.05                    # the run did move the joint
