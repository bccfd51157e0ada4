"""No term of the PI law becomes non-finite (once, a finite but huge reference made Kp e
overflow and back-calculation compute inf - inf, NaN for good), and ControlLoop clamps a
reference outside the rig's envelope to it."""

import math

import pytest

from pam_controller.control_loop import ANGLE, ENVELOPE, TORQUE, ControlLoop
from pam_controller.pi import ANTI_WINDUP, PiController, PiGains, pi_step
from pam_model.parameters import load_parameters
from pam_model.physics import joint_torque, muscle_forces

SCHEMES = ANTI_WINDUP
HUGE = [1e308, 5e306, -1e308, math.inf, -math.inf]
ANGLE_GAINS, TORQUE_GAINS = PiGains(40.0, 50.0), PiGains(6.0, 8.0)   # pi_node's defaults


def finite(*values) -> bool:
    return all(math.isfinite(v) for v in values)


@pytest.mark.parametrize('scheme', SCHEMES)
@pytest.mark.parametrize('e', [*HUGE, math.nan])
def test_pi_step_stays_finite_and_recovers(scheme, e):
    pi = PiController(ANGLE_GAINS, scheme)
    for _ in range(10):
        out = pi.step(e, 0.001)
        assert finite(out.u1, out.u2, out.p_term, out.i_term), out
    back = -0.05 if not e < 0.0 else 0.05                   # a small error the other way
    for k in range(5000):
        out = pi.step(back, 0.001)
        assert finite(out.u1, out.u2, out.p_term, out.i_term), (k, out)
    # controlling again (the output follows the new error), with no re-enable
    assert (out.u1 - 5.5) * back > 0.0, out


@pytest.mark.parametrize('scheme', [0, 1])
def test_pi_step_with_extreme_gains_and_tracking_time(scheme):
    """Finite but extreme numbers everywhere: still no inf and no NaN."""
    u1, u2, p, i, _ = pi_step(1e308, 0.1, -1e308, 1e308, 1e308, 5.5, 0.0, 10.0, scheme,
                              1e-300, 0.1)
    assert finite(u1, u2, p, i) and 0.0 <= u2 <= u1 <= 10.0


def test_non_finite_tracking_time_or_dt_max_is_refused():
    with pytest.raises(ValueError, match='finite'):
        PiController(ANGLE_GAINS, tracking_time=math.inf)
    with pytest.raises(ValueError, match='finite'):
        PiController(ANGLE_GAINS, dt_max=math.inf)


def loop(scheme, mode=ANGLE):
    return ControlLoop(ANGLE_GAINS, TORQUE_GAINS, anti_windup=scheme, mode=mode)


@pytest.mark.parametrize('scheme', SCHEMES)
@pytest.mark.parametrize('mode', [ANGLE, TORQUE])
@pytest.mark.parametrize('huge', [1e308, 5e306, -1e308])
def test_a_huge_reference_acts_as_the_envelope_edge(scheme, mode, huge):
    """The issue's case: (nan, nan) commands until re-enabled. Now the huge reference is the
    envelope's edge (same outputs as that reference), and a sane one afterwards is tracked."""
    edge = math.copysign(ENVELOPE[mode], huge)
    a, b = loop(scheme, mode), loop(scheme, mode)
    stamp = 1_000_000
    for reference in (huge, 0.1):
        message = a.set_reference(mode, reference)
        b.set_reference(mode, edge if reference == huge else reference)
        if reference == huge:
            assert 'clamped' in message and a.reference == edge
        for _ in range(2000):
            stamp += 1_000_000
            out_a, out_b = a.on_feedback(0.0, stamp), b.on_feedback(0.0, stamp)
            assert finite(*out_a[:5]), out_a
            assert out_a == out_b
    assert a.clamped_references == 1 and b.clamped_references == 0
    assert out_a.active and out_a.error == 0.1


@pytest.mark.parametrize('value', [math.inf, -math.inf, math.nan])
def test_a_non_finite_reference_is_ignored(value):
    control = loop('back_calculation')
    control.set_reference(ANGLE, 0.2)
    assert 'not finite' in control.set_reference(ANGLE, value)
    assert control.reference == 0.2 and control.clamped_references == 0


def test_a_reference_inside_the_envelope_is_kept():
    control = loop('conditional')
    assert control.set_reference(ANGLE, ENVELOPE[ANGLE]) == ''
    assert control.set_reference(TORQUE, -ENVELOPE[TORQUE]).startswith('mode angle -> torque')
    assert control.reference == -ENVELOPE[TORQUE] and control.clamped_references == 0


def test_the_envelope_is_within_what_the_rig_gives():
    """+-25 deg is the joint range of MODEL.md; +-3 N m does not exceed the torque the muscles
    give at psi = 0 with one muscle at the tank pressure and the other vented."""
    assert ENVELOPE[ANGLE] == pytest.approx(math.radians(25.0))
    p = load_parameters()
    for high in (0, 1):
        pressures = [p.P_out, p.P_out]
        pressures[high] = p.P_tank
        tau = joint_torque(0.0, *muscle_forces(0.0, *pressures, p, 0), p)
        assert abs(tau) >= ENVELOPE[TORQUE]
