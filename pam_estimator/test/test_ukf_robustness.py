"""The filter (PamUkf) on bad data: garbage measurements, reset, locked joint, covariance
repair. ukf_node's core (EstimatorCore) has its own file, test_estimator_core.py."""

import numpy as np
import pytest

from pam_estimator.pam_ukf import PAPER_TUNING, PamUkf, UkfTuning
from pam_estimator.unscented import julier_sigma_points, repair_covariance, sqrt_psd
from pam_model.model import PamModel
from pam_model.simulate import simulate

X0 = (0.0, 0.0, 4.5e5, 4.5e5)


def test_garbage_measurements_skip_the_update_and_never_give_nan():
    ukf = PamUkf(x0=X0)
    garbage = [(np.nan, 4e5), (4e5, np.inf), (-np.inf, np.nan), (-5.0, 4e5), (1e12, 4e5),
               (0.0, 0.0)]
    for y in garbage:
        out = ukf.step(y, (5.5, 5.5))
        assert out.update_skipped
        assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))
        assert np.isfinite(out.torque) and np.isfinite(out.torque_variance) and out.nis == 0.0
    assert ukf.rejected_samples == len(garbage)
    out = ukf.step((4.5e5, 4.5e5), (5.5, 5.5))
    assert not out.update_skipped and out.nis > 0.0


def test_garbage_commands_do_not_poison_the_filter():
    ukf = PamUkf(x0=X0)
    for u in [(np.nan, 5.0), (np.inf, -np.inf), (-100.0, 1e9)]:
        out = ukf.step((4.5e5, 4.5e5), u)
        assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))


def test_extreme_states_and_covariances_stay_finite():
    ukf = PamUkf(x0=(0.5, 50.0, 3e6, 1e3))
    ukf.P = np.diag([10.0, 1e4, 1e13, 1e13])
    for _ in range(50):
        out = ukf.step((4e5, 4e5), (10.0, 0.0))
        assert np.all(np.isfinite(out.x)) and np.all(np.isfinite(out.P))


def test_indefinite_covariance_is_repaired_and_counted():
    ukf = PamUkf(x0=X0)
    ukf.P = np.diag([1e-5, 1e-4, 1e6, 1e6])
    ukf.P[2, 3] = ukf.P[3, 2] = 5e6              # not positive definite
    out = ukf.step((4.5e5, 4.5e5), (5.5, 5.5))
    assert ukf.repairs >= 1 and np.all(np.isfinite(out.x))
    assert np.all(np.linalg.eigvalsh(out.P) > 0)


def test_sqrt_psd_falls_back_to_an_eigenvalue_clip():
    P = np.array([[1.0, 2.0], [2.0, 1.0]])
    L, repaired, P_used = sqrt_psd(P)
    assert repaired
    np.testing.assert_allclose(L @ L.T, P_used, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(repair_covariance(P)) > 0)
    sigmas, repaired = julier_sigma_points(np.zeros(2), np.eye(2), 0.0)
    assert not repaired and sigmas.shape == (5, 2)


def test_nis_gate_rejects_outliers():
    ukf = PamUkf(x0=X0, nis_gate=13.8)
    for _ in range(20):
        ukf.step((4.5e5, 4.5e5), (5.5, 5.5))
    out = ukf.step((6.5e5, 2.0e5), (5.5, 5.5))      # a 200 kPa jump in one sample
    assert out.update_skipped and out.nis > 13.8 and ukf.gated_samples == 1


def test_reset_restores_state_and_covariance_and_counters():
    ukf = PamUkf(x0=X0, tuning=PAPER_TUNING)
    for _ in range(10):
        ukf.step((5e5, 4e5), (7.0, 4.0))
    ukf.step((np.nan, 1.0), (7.0, 4.0))
    ukf.reset()
    np.testing.assert_array_equal(ukf.x, X0)
    np.testing.assert_array_equal(ukf.P, np.diag(PAPER_TUNING.P0))
    assert ukf.rejected_samples == 0
    ukf.reset(x0=(0.1, 0.0, 3e5, 3e5), P0=np.eye(4))
    assert ukf.x[0] == 0.1 and ukf.P[3, 3] == 1.0
    with pytest.raises(ValueError):
        ukf.reset(x0=(np.nan, 0, 0, 0))
    with pytest.raises(ValueError):
        ukf.reset(P0=-np.eye(4))


def test_invalid_tuning_is_rejected():
    with pytest.raises(ValueError, match='R'):
        PamUkf(tuning=UkfTuning(Q=(0, 0, 0, 0), R=(0.0, 1e8), P0=(1, 1, 1, 1)))
    with pytest.raises(ValueError, match='Q'):
        PamUkf(tuning=UkfTuning(Q=(1, 1, 1), R=(1e8, 1e8), P0=(1, 1, 1, 1)))


def test_locked_joint_estimates_torque_with_the_angle_held():
    plant = PamModel(locked=True)
    U = np.tile([7.5, 3.5], (3000, 1))
    run = simulate(plant, U, X0)
    ukf = PamUkf(model=PamModel(locked=True), x0=X0)
    for k in range(1, len(U)):
        out = ukf.step(run.p_measured[k], U[k - 1])
    assert out.x[0] == 0.0 and out.x[1] == 0.0
    assert out.torque == pytest.approx(run.torque[-1], abs=0.02)
    assert 0.0 < out.torque_variance < 0.01


def test_free_joint_tracks_the_angle_of_a_perfect_plant():
    U = np.tile([7.0, 4.0], (4000, 1))
    run = simulate(PamModel(), U, X0)
    ukf = PamUkf(x0=X0)
    for k in range(1, len(U)):
        out = ukf.step(run.p_measured[k], U[k - 1])
    assert out.x[0] == pytest.approx(run.x[-1, 0], abs=np.radians(0.5))
    assert out.torque == pytest.approx(run.torque[-1], abs=0.05)
