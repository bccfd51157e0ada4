"""bag_runs: a bag becomes the run pam-evaluate reads (no ROS: bags written with pam_bag.bags)."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

from pam_bag import bags
from pam_common.stamps import ns_pair
from pam_common.testing import executable
from pam_estimator.bag_runs import is_bag, load_bag_run, load_run

REFERENCE = Path(__file__).resolve().parents[2] / 'bags'


def _write(path, samples, commands, measured, store, frame_of=lambda i: 'pam_joint'):
    """samples: [(stamp_ns, p1, p2)], commands: [(stamp_ns, u1, u2)] (in receive order),
    measured: [(stamp_ns, angle, omega, torque)]; frame_of(i): sample i's frame_id."""
    from rosbags.typesys.stores.ros2_jazzy import (
        builtin_interfaces__msg__Time as Time,
        std_msgs__msg__Header as Header,
    )
    P = store.types['pam_interfaces/msg/Pressures']
    V = store.types['pam_interfaces/msg/ValveCommand']
    J = store.types['pam_interfaces/msg/JointMeasurement']

    def header(ns, frame_id='pam_joint'):
        sec, nanosec = ns_pair(ns)
        return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id)
    w = bags.BagWriter(path, typestore=store)
    w.add_topic('/pam/pressures', 'pam_interfaces/msg/Pressures', [bags.make_qos()])
    w.add_topic('/pam/valve_command', 'pam_interfaces/msg/ValveCommand', [bags.make_qos()])
    w.add_topic('/pam/joint_measured', 'pam_interfaces/msg/JointMeasurement', [bags.make_qos()])
    events = []
    for i, (s, a, b) in enumerate(samples):
        events.append((s, 0, i, '/pam/pressures', P(header=header(s, frame_of(i)), p1=a, p2=b,
                                                   sample=i + 1)))
    for i, (s, a, b) in enumerate(commands):
        events.append((s, 1, i, '/pam/valve_command', V(header=header(s), u1=a, u2=b)))
    for i, (s, a, o, t) in enumerate(measured):
        events.append((s, 2, i, '/pam/joint_measured',
                       J(header=header(s), angle=a, angular_velocity=o, torque=t)))
    for t, *_, topic, msg in sorted(events, key=lambda e: e[:3]):
        w.write(topic, t + 100, store.serialize_cdr(msg, msg.__msgtype__))
    w.close()
    return path


@pytest.fixture(scope='module')
def store():
    return bags.make_typestore()


def test_commands_in_effect_measurements_and_mode(store, tmp_path):
    ms = 1_000_000
    t0 = 5 * 10**9
    samples = [(t0 + k * ms, 4e5 + k, 5e5 - k) for k in range(6)]
    samples.append(samples[3])                      # a re-published sample: one sample
    # no command before sample 2; two commands stamped at sample 3: the later one counts
    commands = [(t0 + 2 * ms, 6.0, 5.0), (t0 + 3 * ms, 7.0, 4.0), (t0 + 3 * ms, 8.0, 3.0)]
    measured = [(t0 + k * ms, 0.1 * k, 1.0, 0.5) for k in range(6) if k != 4]
    got = load_bag_run(_write(tmp_path / 'b', samples, commands, measured, store))
    run = got.run
    np.testing.assert_allclose(run.t, np.arange(6) * 1e-3)
    np.testing.assert_array_equal(run.u, [[5.5, 5.5], [5.5, 5.5], [6, 5], [8, 3], [8, 3], [8, 3]])
    np.testing.assert_allclose(run.x[:, 0], 0.1 * np.arange(6))   # sample 4 interpolated
    np.testing.assert_allclose(run.p_measured[:, 0], 4e5 + np.arange(6))
    np.testing.assert_allclose(run.x[:, 2:], run.p_measured)
    np.testing.assert_allclose(run.torque, 0.5)
    assert (got.commands, got.measured_missing, got.duplicates) == (3, 1, 1)
    assert not run.locked and load_bag_run(tmp_path / 'b', locked=True).run.locked
    assert is_bag(tmp_path / 'b') and is_bag(tmp_path / 'b' / 'b.mcap')


def test_a_bag_read_message_by_message_gives_the_same_run(store, tmp_path):
    """The pressures are decoded as columns at once when every message has the same layout;
    one message with another frame_id makes them read one by one: the same run either way."""
    ms = 1_000_000
    rng = np.random.default_rng(1)
    samples = [(10**9 + k * ms, *rng.normal(4e5, 1e4, 2)) for k in range(300)]
    commands = [(10**9 + k * ms, *rng.uniform(0, 10, 2)) for k in range(0, 300, 2)]
    measured = [(10**9 + k * ms, *rng.normal(0, 1, 3)) for k in range(300)]
    runs = [load_bag_run(_write(tmp_path / name, samples, commands, measured, store, frame_of))
            for name, frame_of in (('columns', lambda i: 'pam_joint'),
                                   ('one_by_one', lambda i: 'other' if i == 7 else 'pam_joint'))]
    for field in ('t', 'u', 'x', 'torque', 'p_measured'):
        np.testing.assert_array_equal(getattr(runs[0].run, field), getattr(runs[1].run, field))
    np.testing.assert_array_equal(runs[0].stamps_ns, runs[1].stamps_ns)
    assert runs[0].commands == runs[1].commands == 150


def test_constant_angle_is_a_locked_joint(store, tmp_path):
    samples = [(k * 1_000_000, 4e5, 4e5) for k in range(1, 5)]
    measured = [(s, 0.0, 0.0, 0.1 * i) for i, (s, _, _) in enumerate(samples)]
    run = load_run(_write(tmp_path / 'b', samples, [], measured, store))
    assert run.locked and np.all(run.u == 5.5)
    assert not load_run(tmp_path / 'b', locked=False).locked


def test_a_bag_without_the_needed_topics_is_an_error(store, tmp_path):
    w = bags.BagWriter(tmp_path / 'b', typestore=store)
    w.add_topic('/pam/valve_command', 'pam_interfaces/msg/ValveCommand')
    w.close()
    with pytest.raises(bags.BagError, match='no /pam/pressures'):
        load_bag_run(tmp_path / 'b')
    result = subprocess.run([executable('pam-evaluate', 'pam_estimator'), str(tmp_path / 'b')],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and 'no /pam/pressures' in result.stderr


def test_pam_evaluate_on_reference_bags_prints_the_tables_and_writes_the_figures(tmp_path):
    bags_in = [str(REFERENCE / 'validation_mild_free'), str(REFERENCE / 'validation_mild_locked')]
    result = subprocess.run([executable('pam-evaluate', 'pam_estimator'), *bags_in,
                             '--plots', str(tmp_path)], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert 'free joint' in out and 'locked joint' in out
    assert 'angle (deg)' in out and 'torque (N m)' in out and out.count('UKF  ') >= 2
    for png in ('validation_mild_free_angle.png', 'validation_mild_locked_torque.png'):
        assert (tmp_path / png).stat().st_size > 10_000
