"""The PI maths: law, saturation, anti-windup, dt guards, gain validation; ControlLoop; metrics;
and the sensor-less loop on the batch simulator against the acceptance targets."""

import math

import numpy as np
import pytest

from pam_controller.closed_loop import simulate_closed_loop
from pam_controller.control_loop import ANGLE, TORQUE, ControlLoop
from pam_controller.pi import PiController, PiGains, differential_limits, validate_gains
from pam_controller.step_metrics import ANGLE_SPAN, TORQUE_SPAN, step_report
from pam_model.mismatch import load_scenario
from pam_model.model import PamModel
from pam_model.parameters import load_parameters

G = PiGains(kp=10.0, ki=5.0)


def test_law_is_antagonistic_about_beta():
    pi = PiController(G)
    out = pi.step(0.1, 0.001)                 # the output uses the integral up to k-1
    assert out.p_term == pytest.approx(1.0)
    assert out.i_term == pytest.approx(5.0 * 0.1 * 0.001)
    assert out.u1 == pytest.approx(5.5 + 1.0)
    out = pi.step(0.1, 0.001)
    assert out.u1 == pytest.approx(5.5 + 1.0 + 0.0005)
    assert out.u1 + out.u2 == pytest.approx(11.0) and not out.saturated


def test_saturation_keeps_both_valves_in_range():
    assert differential_limits(5.5, 0.0, 10.0) == (-4.5, 4.5)
    out = PiController(G).step(2.0, 0.001)                # v = 20 V -> 4.5 V
    assert (out.u1, out.u2, out.saturated) == (10.0, 1.0, True)
    out = PiController(PiGains(10.0, 0.0, beta=5.0, u_min=1.0, u_max=9.0)).step(-1.0, 0.001)
    assert (out.u1, out.u2) == (1.0, 9.0)


@pytest.mark.parametrize('scheme', ['conditional', 'back_calculation'])
def test_anti_windup_bounds_the_integral_while_saturated(scheme):
    pi = PiController(G, anti_windup=scheme, tracking_time=0.05)
    for _ in range(5000):                                  # 5 s saturated
        pi.step(1.0, 0.001)
    held = pi.i_term
    for _ in range(5000):                                  # 5 s more: no further growth
        pi.step(1.0, 0.001)
    assert abs(pi.i_term) < 6.0 and pi.i_term == pytest.approx(held, abs=1e-6)
    out = pi.step(-0.05, 0.001)                            # the error changes sign
    assert not out.saturated or out.u1 < 10.0              # recovers at once: no windup overshoot


def test_without_saturation_both_schemes_integrate_alike():
    a, b = PiController(G, 'conditional'), PiController(G, 'back_calculation')
    for e in np.linspace(-0.1, 0.1, 50):
        assert a.step(e, 0.001) == pytest.approx(b.step(e, 0.001))


@pytest.mark.parametrize('dt', [0.0, -0.001, 0.5, math.nan])
def test_implausible_dt_freezes_the_integral(dt):
    pi = PiController(G, dt_max=0.1)
    pi.step(0.1, 0.001)
    before = pi.i_term
    out = pi.step(0.1, dt)
    assert pi.i_term == before and out.p_term == pytest.approx(1.0)


def test_changing_ki_causes_no_jump():
    pi = PiController(G)
    for _ in range(100):
        pi.step(0.1, 0.001)
    before = pi.step(0.1, 0.0)                              # no time elapsed: no increment
    pi.set_gains(G._replace(ki=500.0))
    after = pi.step(0.1, 0.0)
    assert after.u1 == before.u1 and after.i_term == before.i_term


@pytest.mark.parametrize('gains', [PiGains(-1.0, 1.0), PiGains(1.0, math.nan),
                                   PiGains(1.0, 1.0, u_min=6.0, u_max=5.0),
                                   PiGains(1.0, 1.0, beta=11.0, u_max=10.0),
                                   PiGains(1.0, 1.0, u_min=-1.0)])
def test_bad_gains_are_rejected(gains):
    with pytest.raises(ValueError):
        validate_gains(gains)


@pytest.mark.parametrize('args', [
    (PiGains(-1.0, 1.0),), (PiGains(1.0, math.nan),), (PiGains(1.0, 1.0, u_min=6.0, u_max=5.0),),
    (PiGains(1.0, 1.0, beta=11.0, u_max=10.0),), (PiGains(1.0, 1.0, u_min=-1.0),),
    (G, 'clamping'), (G, 'conditional', 0.0), (G, 'back_calculation', math.inf),
    (G, 'conditional', math.nan)])
def test_set_gains_rejects_what_the_constructor_rejects_and_changes_nothing(args):
    with pytest.raises(ValueError):
        PiController(*args)
    pi = PiController(G, 'back_calculation', 0.2)
    pi.step(0.1, 0.001)
    before = (pi.gains, pi.anti_windup, pi.tracking_time, pi.i_term)
    with pytest.raises(ValueError):
        pi.set_gains(*args)
    assert (pi.gains, pi.anti_windup, pi.tracking_time, pi.i_term) == before


def test_set_gains_applies_and_keeps_the_integral():
    pi = PiController(G)
    pi.step(0.1, 0.001)
    i_term = pi.i_term
    pi.set_gains(G._replace(kp=1.0), 'back_calculation', 0.5)
    assert (pi.gains.kp, pi.anti_windup, pi.tracking_time, pi.i_term) == (
        1.0, 'back_calculation', 0.5, i_term)
    pi.set_gains(G)                                         # None: scheme and time unchanged
    assert (pi.gains, pi.anti_windup, pi.tracking_time) == (G, 'back_calculation', 0.5)


def test_control_loop_set_gains_changes_both_modes_or_neither():
    loop = ControlLoop(G, PiGains(2.0, 1.0))
    with pytest.raises(ValueError):                         # a bad torque gain: angle untouched
        loop.set_gains(PiGains(3.0, 3.0), PiGains(-2.0, 1.0))
    with pytest.raises(ValueError):                         # a bad scheme: neither changes
        loop.set_gains(PiGains(3.0, 3.0), PiGains(4.0, 4.0), 'clamping')
    assert (loop.controllers[ANGLE].gains, loop.controllers[TORQUE].gains) == (
        G, PiGains(2.0, 1.0))
    loop.set_gains(PiGains(3.0, 3.0), PiGains(4.0, 4.0), 'back_calculation', 0.3)
    assert [(c.gains.kp, c.anti_windup, c.tracking_time) for c in loop.controllers.values()] == [
        (3.0, 'back_calculation', 0.3), (4.0, 'back_calculation', 0.3)]


def test_control_loop_modes_enable_and_stamps():
    loop = ControlLoop(G, PiGains(2.0, 1.0), reference=0.1)
    out = loop.on_feedback(0.0, 1_000_000)
    assert out.active and out.error == pytest.approx(0.1)
    assert loop.set_reference(TORQUE, 1.0).startswith('mode angle -> torque')
    assert loop.controller.i_term == 0.0
    assert loop.on_feedback(0.5, 2_000_000).p_term == pytest.approx(1.0)
    loop.on_feedback(0.5, 1_500_000)                        # stamp from the past: dt < 0
    assert loop.bad_dt == 1
    assert 'not finite' in loop.set_reference(ANGLE, math.nan)
    assert not loop.on_feedback(math.nan, 3_000_000).active
    loop.set_enabled(False)
    out = loop.on_feedback(0.5, 4_000_000)
    assert not out.active and (out.u1, out.u2) == (5.5, 5.5)


def test_step_report_metrics():
    t = np.arange(0, 16.0, 0.001)
    reference = np.where(t < 8.0, 0.0, 0.2)
    y = np.where(t < 8.0, 0.0, 0.2 * (1 - np.exp(-(t - 8.0) / 0.3)) + 0.004)
    report = step_report(t, reference, y, ANGLE_SPAN)
    assert len(report.steps) == 2
    second = report.steps[1]
    assert second.steady_error == pytest.approx(100 * 0.004 / ANGLE_SPAN, rel=1e-3)
    assert 0.3 < second.settling_time < 1.0 and second.overshoot == pytest.approx(2.0, rel=1e-2)


def test_step_report_measures_time_by_the_stamps():
    """A run whose first two samples came in a burst (a real-time loop catching up: 50 us apart)
    and with 300 samples missing in the second hold gives the figures of the uniform run: holds,
    settling and the last second are measured in time, not in samples (with the first gap as the
    period, the 4 s second hold below read as 0.2 s and was skipped: pam-demo once reported no
    step)."""
    t = np.arange(0, 12.0, 0.001)
    reference = np.where(t < 8.0, 0.0, 0.2)
    y = np.where(t < 8.0, 0.0, 0.2 * (1 - np.exp(-(t - 8.0) / 0.3)) + 0.004)
    uniform = step_report(t, reference, y, ANGLE_SPAN)
    keep = np.ones(t.size, dtype=bool)
    keep[9000:9300] = False                       # 0.3 s lost while settling
    t_gappy = t.copy()
    t_gappy[0] = t[1] - 50e-6                     # the burst at the start
    gappy = step_report(t_gappy[keep], reference[keep], y[keep], ANGLE_SPAN)
    assert len(uniform.steps) == len(gappy.steps) == 2
    for u, g in zip(uniform.steps, gappy.steps, strict=True):
        assert g.steady_error == pytest.approx(u.steady_error, rel=1e-6)
        assert g.settling_time == pytest.approx(u.settling_time, abs=1e-6)
        assert g.overshoot == pytest.approx(u.overshoot, rel=1e-6)
    assert step_report(t[:7999], reference[:7999], y[:7999], ANGLE_SPAN).steps[0].t_start == 0.0


@pytest.mark.parametrize('mode, span, target, gains', [
    ('angle', ANGLE_SPAN, 3.0, (40.0, 50.0)), ('torque', TORQUE_SPAN, 3.5, (6.0, 8.0))])
def test_default_gains_meet_the_targets_on_the_batch_loop(mode, span, target, gains):
    """Steps of 8 s on the 'mild' plant with its sensor, UKF feedback (nominal model)."""
    scenario = load_scenario('mild')
    locked = mode == 'torque'
    level = 0.25 if mode == 'angle' else 1.5
    t = np.arange(24000) * 1e-3
    reference = np.select([t < 8.0, t < 16.0], [0.0, level], -0.6 * level)
    run, = simulate_closed_loop(PamModel(params=scenario.apply(load_parameters()),
                                         locked=locked), PamModel(locked=locked), reference,
                                [gains], sensor=scenario.sensor, mode=mode, seed=3)
    report = run.report(span, 2.0)
    assert report.worst_error <= target
    assert report.worst_settling <= 3.0 and report.worst_ripple < 1.0
    assert report.worst_overshoot < 25.0
