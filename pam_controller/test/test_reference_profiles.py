"""reference_node's profiles (no ROS) and the node as a real process."""

import itertools
import math

import numpy as np
import pytest

from pam_common.node_params import ConfigError, defaults
from pam_controller.reference_node import PARAMETERS, build_config, profile_value, step_levels
from pam_interfaces.msg import Reference


def values(**overrides):
    v = defaults(PARAMETERS)
    v.update(overrides)
    return build_config(v)


def test_steps_stay_within_the_amplitude_and_hold():
    v = values(profile='steps', amplitude=math.radians(20.0), hold=8.0, duration=64.0, seed=3)
    levels = step_levels(v)
    assert len(levels) == 8 and levels[0] == 0.0
    assert np.all(np.abs(levels) <= math.radians(20.0) + 1e-12)
    assert profile_value(v, levels, 8.5) == levels[1] == profile_value(v, levels, 15.9)
    assert profile_value(v, levels, 100.0) == levels[-1]            # holds the last value
    looped = values(profile='steps', seed=3, repeat=True)
    assert profile_value(looped, step_levels(looped), 64.0 + 8.5) == levels[1]


@pytest.mark.parametrize('kind, t, expected', [('sine', 2.5, 0.2), ('ramp', 0.0, 0.0),
                                               ('ramp', 2.5, 0.2), ('ramp', 7.5, -0.2),
                                               ('constant', 3.0, 0.0)])
def test_ramp_sine_constant(kind, t, expected):
    v = values(profile=kind, amplitude=0.2, period=10.0)
    assert profile_value(v, None, t) == pytest.approx(expected)


def test_the_envelope_is_enforced():
    with pytest.raises(ConfigError, match='amplitude'):
        values(mode='torque', amplitude=2.5, offset=1.0)
    with pytest.raises(ConfigError, match='profile'):
        values(profile='square')


def test_reference_node_publishes(node_process, probe):
    got = probe.subscribe(Reference, '/pam/reference')
    node = node_process('reference_node', 'pam_controller', '-p', 'mode:=torque', '-p',
                        'profile:=sine', '-p', 'amplitude:=1.5', '-p', 'period:=1.0')
    node.wait_for(lambda: len(got) >= 150, 30.0, '150 references (1.5 periods)')
    msgs = got.messages()
    assert all(m.mode == Reference.TORQUE for m in msgs)
    assert max(m.value for m in msgs) > 1.0 and min(m.value for m in msgs) < -1.0


def test_reference_node_on_simulated_time_follows_clock(node_process, probe):
    """use_sim_time: the profile ticks on /clock, stamped with it, and stops while /clock stops:
    100 Hz of simulated time, not of the wall clock. /clock goes slowly until the first reference
    arrives (discovery), then covers 2 s four times as fast as real time (a wall-clock timer would
    give about 50 references). On rclpy's EventsExecutor this fails about one run in two:
    repeated stamps (pam_common.executors)."""
    import time

    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    got = probe.subscribe(Reference, '/pam/reference', depth=1000)
    clock = probe.publisher(Clock, '/clock')
    node_process('reference_node', 'pam_controller', '-p', 'use_sim_time:=true')

    def tick(k: int) -> None:                    # /clock at k ms
        clock.publish(Clock(clock=Time(sec=k // 1000, nanosec=(k % 1000) * 1_000_000)))

    k, end = 0, time.monotonic() + 30.0
    while not got.messages():
        assert time.monotonic() < end, 'no reference within 30 s of /clock at 0.2x real time'
        k += 1
        tick(k)
        time.sleep(0.005)
    first = k
    start = time.monotonic()
    for n in range(1, 2001):                     # 2 s of simulated time
        tick(first + n)
        time.sleep(max(0.0, start + n * 0.25e-3 - time.monotonic()))
    took = time.monotonic() - start
    last = (first + 2000) * 1e-3
    deadline = time.monotonic() + 10.0
    while stamp_s(got.messages()[-1]) < last - 0.011:
        assert time.monotonic() < deadline, f'no reference near {last:.3f} s of /clock'
        time.sleep(0.01)
    time.sleep(0.6)       # /clock stopped: so does the profile (no repeated or later stamp)
    stamps = [stamp_s(m) for m in got.messages() if stamp_s(m) > first * 1e-3]
    assert took < 1.0, f'/clock took {took:.2f} s to cover 2 s'
    # a node that takes /clock more slowly than it comes skips ticks (at most 201; 167-178 with
    # two CPU-bound processes beside it), a wall-clock timer would tick about 50 times
    assert 100 <= len(stamps) <= 201, (len(stamps), stamps[:5], stamps[-5:])
    assert stamps[-1] <= last + 1e-9, (stamps[-5:], last)
    repeated = [(a, b) for a, b in itertools.pairwise(stamps) if b <= a]
    assert not repeated, repeated


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
