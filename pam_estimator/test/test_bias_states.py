"""The UKF's bias states (docs/model_extensions.md "Bias states"): off, the
filter is the one it always was, bit for bit; on, a constant pressure-sensor offset is estimated
by b1, b2 and the pressure estimates no longer carry it; bad input never gives a non-finite
output; ukf_node's bias_states parameter (a real process on an isolated domain) runs the same
filter and publishes the paper's 4 states."""

import math
import re
import subprocess
import time
from dataclasses import replace

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray

from pam_common.diagnostics import status_values
from pam_common.stamps import ns_stamp
from pam_common.testing import diagnostic_statuses, executable
from pam_estimator.bias_ukf import DEFAULT_BIAS_STATES, TORQUE_BIAS_STATES, BiasStates
from pam_estimator.evaluation import run_ukf
from pam_estimator.pam_ukf import PamUkf
from pam_interfaces.msg import JointEstimate, Pressures
from pam_model.effects import Effects
from pam_model.model import PamModel
from pam_model.profiles import validation_profile
from pam_model.sensor import PressureSensor
from pam_model.simulate import simulate
from test_ukf_node_topics import answered_then_reset

X0 = (0.0, 0.0, 4.5e5, 4.5e5)
RIG = Effects(valve_time_constant=0.005, dead_volume=6.0e-6, hysteresis_band=2.0,
              sensor_offset=(2000.0, -3000.0), sensor_gain_error=(0.005, -0.005))
OFFSET = np.array([8.0e3, -6.0e3])      # Pa, the sensors' constant offsets of the plant


def short_run(locked, effects, seconds):
    model = replace(PamModel(), locked=locked)
    profile = validation_profile(1, seconds, model.h)
    return model, simulate(model, profile.u, X0, PressureSensor(2000.0, 12), 1, effects=effects)


@pytest.mark.parametrize('extensions', [None, RIG])
@pytest.mark.parametrize('locked', [False, True])
def test_bias_states_off_is_the_filter_as_it_was_bit_for_bit(locked, extensions):
    """bias_states=None (the default) computes exactly what PamUkf computed before the option,
    with and without the model's extensions."""
    model, run = short_run(locked, RIG, seconds=1.0)
    kwargs = {} if extensions is None else {'extensions': extensions}
    before = PamUkf(model=model, x0=X0, **kwargs)
    off = PamUkf(model=model, x0=X0, bias_states=None, **kwargs)
    assert off.x.shape == (4,) and off.P.shape == (4, 4)
    for k in range(1, len(run.t)):
        a = before.step(run.p_measured[k], run.u[k - 1])
        b = off.step(run.p_measured[k], run.u[k - 1])
        assert np.array_equal(a.x, b.x) and np.array_equal(a.P, b.P)
        assert (a.force1, a.force2, a.torque, a.torque_variance, a.subsystem, a.nis) == (
            b.force1, b.force2, b.torque, b.torque_variance, b.subsystem, b.nis)
    est = run_ukf(run, model)
    assert est.biases is None and est.x.shape == (len(run.t), 4)


@pytest.mark.parametrize('locked', [True, False])
def test_a_constant_sensor_offset_is_estimated_by_b1_b2(locked):
    """Plant sensors read P + (8, -6) kPa for 40 s. With bias states b1, b2 end within 20 % of
    the offsets and the pressure estimates of the last 10 s are within 25 % of them of the true
    pressures; without, the estimates carry at least 75 % of the offsets (measured: b ends at
    (7.1, -5.4) kPa locked, (6.7, -5.3) kPa free; pressure error 1.0 / 0.6 kPa vs 7.8 / 5.9)."""
    model, run = short_run(locked, Effects(sensor_offset=tuple(OFFSET)), seconds=40.0)
    with_bias = run_ukf(run, model, bias_states=DEFAULT_BIAS_STATES)
    without = run_ukf(run, model)
    assert with_bias.biases.shape == (len(run.t), 3)
    b1, b2, b_tau = with_bias.biases[-1]
    assert np.all(np.abs(np.array([b1, b2]) - OFFSET) < 0.2 * np.abs(OFFSET)), (b1, b2)
    assert abs(b_tau) < 1e-3          # frozen by default
    last = run.t >= run.t[-1] - 10.0
    error_with = np.abs(with_bias.x[last, 2:] - run.x[last, 2:]).mean(axis=0)
    error_without = np.abs(without.x[last, 2:] - run.x[last, 2:]).mean(axis=0)
    assert np.all(error_with < 0.25 * np.abs(OFFSET)), error_with
    assert np.all(error_without > 0.75 * np.abs(OFFSET)), error_without


def test_pam_evaluate_bias_states(tmp_path):
    """pam-evaluate --bias-states runs the UKF with them and prints the final b1, b2."""
    _, run = short_run(True, Effects(sensor_offset=tuple(OFFSET)), seconds=40.0)
    path = run.save(tmp_path / 'locked.npz')
    pam_evaluate = executable('pam-evaluate', 'pam_estimator')
    plain, biased = (subprocess.run([pam_evaluate, str(path), *flag], capture_output=True,
                                    text=True, timeout=300) for flag in ([], ['--bias-states']))
    assert plain.returncode == 0 and biased.returncode == 0, plain.stderr + biased.stderr
    assert 'bias states' not in plain.stdout
    found = re.search(r'bias states at the end: b1 (\S+) Pa, b2 (\S+) Pa', biased.stdout)
    assert found, biased.stdout
    b = np.array([float(found.group(1)), float(found.group(2))])
    assert np.all(np.abs(b - OFFSET) < 0.2 * np.abs(OFFSET)), b


@pytest.mark.parametrize('bias_states', [DEFAULT_BIAS_STATES, TORQUE_BIAS_STATES])
@pytest.mark.parametrize('locked', [False, True])
def test_bad_input_never_gives_a_non_finite_output(locked, bias_states):
    """NaN, infinite and out-of-range pressures and commands, as the main UKF handles them: the
    update is skipped (counted), every output stays finite."""
    model, run = short_run(locked, RIG, seconds=0.3)
    ukf = PamUkf(model=model, x0=X0, extensions=RIG, bias_states=bias_states)
    bad_y = [(np.nan, 4e5), (np.inf, -np.inf), (1e9, 4e5), (-5.0, 4e5)]
    bad_u = [(np.nan, 5.0), (np.inf, -np.inf), (1e6, -1e6)]
    for k in range(1, len(run.t)):
        y, u = run.p_measured[k], run.u[k - 1]
        if k % 7 == 0:
            y = bad_y[(k // 7) % len(bad_y)]
        if k % 11 == 0:
            u = bad_u[(k // 11) % len(bad_u)]
        out = ukf.step(y, u)
        values = [*out.x, *out.P.ravel(), out.force1, out.force2, out.torque,
                  out.torque_variance, out.nis]
        assert np.all(np.isfinite(values)), k
        assert out.x.shape == (7,)
    assert ukf.rejected_samples >= (len(run.t) - 1) // 7


def test_bias_states_validation():
    for bad in (BiasStates(sensor_rate=-1.0), BiasStates(sensor_variance=0.0),
                BiasStates(torque_rate=float('nan')), BiasStates(torque_variance=float('inf'))):
        with pytest.raises(ValueError, match='bias_states'):
            PamUkf(bias_states=bad)


def test_ukf_node_bias_states_parameter(node_process, probe):
    """-p bias_states:=true: the node's estimates are PamUkf's with DEFAULT_BIAS_STATES, number
    for number, with the paper's 4 states and 4x4 covariance; /diagnostics shows b1, b2."""
    samples = 60
    node = node_process('ukf_node', 'pam_estimator', '-p', 'joint_states_rate:=0.0',
                        '-p', 'bias_states:=true')
    estimates = probe.subscribe(JointEstimate, '/pam/estimate', depth=1000)
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    pub = probe.publisher(Pressures, '/pam/pressures')
    node.wait_for(lambda: pub.get_subscription_count() > 0, 60.0, 'ukf_node subscribed')

    def warm_up_sample(k):
        msg = Pressures(p1=4.5e5, p2=4.5e5)
        msg.header.stamp = ns_stamp(round((1.0 + k * 1e-3) * 1e9))
        pub.publish(msg)
    answered_then_reset(probe, estimates, warm_up_sample)
    offline = PamUkf(model=PamModel(), x0=X0, bias_states=DEFAULT_BIAS_STATES)
    expected = []
    for k in range(1, samples + 1):
        y = (4.5e5 + 0.6e5 * math.sin(0.2 * k), 4.5e5 - 0.6e5 * math.sin(0.2 * k))
        msg = Pressures(sample=k)
        msg.p1, msg.p2 = y
        msg.header.stamp = ns_stamp(round((100.0 + k * 1e-3) * 1e9))
        pub.publish(msg)
        time.sleep(0.002)
        out = offline.step(y, (5.5, 5.5))
        expected.append((*out.x[:4], out.torque))
    node.wait_for(lambda: len(estimates) >= samples, 30.0, f'{samples} estimates')
    got = estimates.messages()
    assert [(m.angle, m.angular_velocity, m.p1, m.p2, m.torque) for m in got] == expected
    assert all(len(m.covariance) == 16 for m in got)
    assert 'bias states: sensor offsets b1, b2' in node.stderr + node.stdout

    def offsets():
        statuses = diagnostic_statuses(diagnostics, 'ukf_node')
        return status_values(statuses[-1]).get('sensor offsets b1, b2 (kPa)') if statuses else None

    node.wait_for(lambda: offsets() is not None, 10.0, '/diagnostics with b1, b2')
