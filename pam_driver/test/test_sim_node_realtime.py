"""sim_node in real-time mode, as a separate process, seen from topics."""

from __future__ import annotations

import itertools
import math
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import FluidPressure

from pam_interfaces.msg import JointMeasurement, Pressures, ValveCommand

RATE = 1000.0                  # Hz, default rate
MEASURE = 3.0                  # s of samples for the rate test
STARTUP = 45.0                 # s, first message from a fresh process (loaded machine)


def _command(u1: float, u2: float) -> ValveCommand:
    msg = ValveCommand()
    msg.u1, msg.u2 = float(u1), float(u2)
    return msg


def _hold(publisher, u1, u2, duration, period=0.01):
    """Publish (u1, u2) every `period` s for `duration` s."""
    end = time.monotonic() + duration
    while time.monotonic() < end:
        publisher.publish(_command(u1, u2))
        time.sleep(period)


def _mean(values):
    values = list(values)
    return sum(values) / len(values)


def test_realtime_rate_near_1khz(sim_node, probe, helpers):
    sim = sim_node('--params-file', helpers.installed_config('sim_node.yaml', 'pam_driver'))
    got = probe.subscribe(Pressures, '/pam/pressures')
    supply = probe.subscribe(FluidPressure, '/pam/supply_pressure')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=10)
    sim.wait_for(lambda: len(got) > 0, STARTUP, 'the first /pam/pressures sample')

    time.sleep(0.5)  # let discovery and the first bursts settle
    # MEASURE s of the rig's clock (the samples' stamps), not of arrival: on a loaded machine a
    # sample taken on time may arrive late, behind a backlog; 1 s more for those to arrive
    start_ns = helpers.stamp_ns(got.messages()[-1].header.stamp)
    wall_at_start = time.time()
    time.sleep(MEASURE + 1.0)
    window = [m for m in got.messages() if start_ns <= helpers.stamp_ns(m.header.stamp)
              < start_ns + int(MEASURE * 1e9)]
    stamps = [helpers.stamp_ns(m.header.stamp) * 1e-9 for m in window]

    assert len(stamps) > 100, f'only {len(stamps)} samples in {MEASURE} s'
    assert len(supply) == 0, 'publish_supply_pressure is off by default'
    assert probe.node.count_publishers('/pam/supply_pressure') == 0
    assert all(b > a for a, b in itertools.pairwise(stamps)), 'stamps must strictly increase'
    counters = [m.sample for m in window]
    assert all(b > a for a, b in itertools.pairwise(counters)), 'so must Pressures.sample'
    assert counters[-1] - counters[0] + 1 >= len(window) and counters[0] >= 1
    span = stamps[-1] - stamps[0]
    rate = (len(stamps) - 1) / span
    assert abs(rate - RATE) <= 0.05 * RATE, f'achieved {rate:.1f} Hz from the stamps'
    # the stamps are the system clock's (the deadline of each sample): the last one received
    # before the window was taken at most a second before it arrived
    assert abs(start_ns * 1e-9 - wall_at_start) < 1.0, (start_ns * 1e-9, wall_at_start)
    assert len(stamps) >= 0.9 * MEASURE * RATE, (
        f'{len(stamps)} samples in {MEASURE} s of stamps, expected about {MEASURE * RATE:.0f}')
    assert all(helpers.all_finite((m.p1, m.p2)) for m in window)
    assert window[-1].header.frame_id == 'pam_joint'

    # /diagnostics: about 1 Hz, reporting real-time operation at about the target rate
    sim.wait_for(lambda: len(helpers.diagnostic_statuses(diagnostics)) >= 2, 10.0,
                 'two /diagnostics messages')
    status = helpers.diagnostic_statuses(diagnostics)[-1]
    assert status.name == '/pam/sim_node: simulated rig'    # the fully qualified node name
    assert status.hardware_id == '/pam'                     # hardware_id: the namespace
    values = {kv.key: kv.value for kv in status.values}
    for key in ('timing', 'rate target (Hz)', 'achieved rate (Hz)', 'late steps (last window)',
                'max lateness (ms)', 'samples taken', 'late samples', 'missed samples',
                'worst stall (ms)',
                'latency p99 (ms)', 'samples published', 'commands received',
                'non-finite commands', 'out-of-range commands', 'past commands ignored',
                'last command u1 (V)', 'last command u2 (V)', 'joint mode', 'plant parameters'):
        assert key in values, f'/diagnostics misses {key!r}: {values}'
    assert values['timing'] == 'realtime'
    assert values['joint mode'] == 'free'
    assert values['plant parameters'] == 'default'
    assert float(values['rate target (Hz)']) == RATE
    assert abs(float(values['achieved rate (Hz)']) - RATE) <= 0.1 * RATE, values
    assert int(values['samples published']) > 1000
    assert status.level in (DiagnosticStatus.OK, DiagnosticStatus.WARN)  # WARN if overloaded


def test_a_stalled_rig_never_pauses_its_plant_and_reports_the_stall(sim_node, probe, helpers):
    """The sampler frozen for STALL s (SIGSTOP, as a machine that starves it): on resuming the
    plant has gone on through the stall with the held command: the samples it missed (all but
    max_catch_up, published back to back) are a gap in the counter, the stamps stay on the wall
    clock (sample k stamped start + k/rate: no jump, no pause), and /diagnostics counts the
    late and missed samples and the worst stall."""
    import signal
    stall = 0.3
    sim = sim_node('--params-file', helpers.installed_config('sim_node.yaml', 'pam_driver'))
    got = probe.subscribe(Pressures, '/pam/pressures', depth=1000)
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=10)
    sim.wait_for(lambda: len(got) > 0, STARTUP, 'the first /pam/pressures sample')
    time.sleep(0.5)
    sim.proc.send_signal(signal.SIGSTOP)
    time.sleep(stall)
    sim.proc.send_signal(signal.SIGCONT)
    time.sleep(1.0)
    msgs = got.messages()
    # stamps are the deadlines: k / rate, whatever the stall, across every sample and gap
    for a, b in itertools.pairwise(msgs):
        elapsed = (helpers.stamp_ns(b.header.stamp) - helpers.stamp_ns(a.header.stamp)) * 1e-9
        assert b.sample > a.sample and abs(elapsed - (b.sample - a.sample) / RATE) < 2e-6
    gaps = [b.sample - a.sample - 1 for a, b in itertools.pairwise(msgs) if b.sample > a.sample + 1]
    stalled = max(gaps, default=0)          # (a start-up hiccup may have missed a few more)
    assert stalled >= 0.5 * stall * RATE, f'the stall is a gap in the counter: {gaps}'
    # and the plant did not pause: the latest sample's stamp (its deadline) comes back to within
    # 0.2 s of the wall clock (a plant that paused would stay behind by the stall; the probe
    # itself may receive a stretch late on a loaded machine, so it is waited for, bounded)
    def lag() -> float:
        return time.time() - helpers.stamp_ns(got.messages()[-1].header.stamp) * 1e-9
    sim.wait_for(lambda: lag() < 0.2, 5.0, 'the plant time within 0.2 s of the wall clock')
    sim.wait_for(lambda: len(helpers.diagnostic_statuses(diagnostics)) >= 1, 10.0, 'diagnostics')
    time.sleep(1.2)
    values = {kv.key: kv.value for kv in helpers.diagnostic_statuses(diagnostics)[-1].values}
    assert int(values['missed samples']) >= stalled, values
    assert int(values['late samples']) >= stalled, values
    assert float(values['worst stall (ms)']) >= 0.8 * stall * 1e3, values


def test_raising_u1_raises_p1_and_moves_the_joint(sim_node, probe, helpers):
    sim = sim_node('--params-file', helpers.installed_config('sim_node_mild.yaml', 'pam_driver'))
    pressures = probe.subscribe(Pressures, '/pam/pressures')
    joint = probe.subscribe(JointMeasurement, '/pam/joint_measured')
    command = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(pressures) > 0 and len(joint) > 0, STARTUP,
                 'the first pressures and joint_measured samples')
    sim.wait_for(lambda: command.get_subscription_count() > 0, 10.0,
                 'sim_node to subscribe valve_command')

    _hold(command, 5.5, 5.5, 0.5)
    before_p = pressures.messages()[-50:]
    before_j = joint.messages()[-50:]
    p1_0, p2_0 = _mean(m.p1 for m in before_p), _mean(m.p2 for m in before_p)
    psi_0 = _mean(m.angle for m in before_j)

    _hold(command, 9.0, 2.0, 1.5)
    after_p = pressures.messages()[-50:]
    after_j = joint.messages()[-50:]
    p1_1, p2_1 = _mean(m.p1 for m in after_p), _mean(m.p2 for m in after_p)
    psi_1 = _mean(m.angle for m in after_j)

    assert p1_1 > p1_0 + 50e3, f'P1 {p1_0:.0f} -> {p1_1:.0f} Pa'
    assert p2_1 < p2_0 - 50e3, f'P2 {p2_0:.0f} -> {p2_1:.0f} Pa'
    assert psi_1 > psi_0 + 0.05, f'angle {psi_0:.4f} -> {psi_1:.4f} rad'
    assert all(helpers.all_finite((m.angle, m.angular_velocity, m.torque))
               for m in joint.messages())
    # the mild plant has a noisy, 12-bit sensor: readings sit on the ADC grid
    step = 1.0e6 / (2 ** 12 - 1)
    assert all(abs(m.p1 / step - round(m.p1 / step)) < 1e-6 for m in after_p)


def test_bad_commands_are_sanitised_counted_and_reported(sim_node, probe, helpers):
    sim = sim_node()
    pressures = probe.subscribe(Pressures, '/pam/pressures')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=10)
    command = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(pressures) > 0, STARTUP, 'the first pressures sample')
    sim.wait_for(lambda: command.get_subscription_count() > 0, 10.0,
                 'sim_node to subscribe valve_command')

    for u1 in (math.nan, math.inf, -3.0, 15.0):  # 2 non-finite, 2 out of range; u2 is fine
        command.publish(_command(u1, 5.5))
        time.sleep(0.02)
    sent_at = time.monotonic()

    def reported():
        for status in helpers.diagnostic_statuses(diagnostics):
            values = {kv.key: kv.value for kv in status.values}
            if values.get('commands received') == '4':
                return status, values
        return None

    sim.wait_for(lambda: reported() is not None, 10.0,
                 '/diagnostics to report the 4 commands')
    status, values = reported()
    assert values['non-finite commands'] == '2', values
    assert values['out-of-range commands'] == '2', values
    assert values['past commands ignored'] == '0', values
    assert float(values['last command u1 (V)']) == 10.0   # 15 V clipped
    assert float(values['last command u2 (V)']) == 5.5
    assert status.level == DiagnosticStatus.WARN, (status.level, status.message)

    # still alive and publishing finite pressures
    count = len(pressures)
    sim.wait_for(lambda: len(pressures) > count + 200, 10.0, 'more samples after bad commands')
    assert sim.alive()
    assert all(helpers.all_finite((m.p1, m.p2)) for m in pressures.messages())
    assert len(list(pressures.since(sent_at))) > 200
    # the warning is throttled: a handful of lines, not one per command per second
    assert sim.stderr.count('bad valve_command') <= 3, sim.stderr


def test_namespace_remap_overrides_the_default(sim_node, probe, helpers):
    sim = sim_node('-r', '__ns:=/other')
    other = probe.subscribe(Pressures, '/other/pressures')
    default = probe.subscribe(Pressures, '/pam/pressures')
    sim.wait_for(lambda: len(other) > 0, STARTUP, 'the first /other/pressures sample')
    time.sleep(0.3)
    assert len(default) == 0
    assert '/other/valve_command' in sim.stderr  # start-up log names the resolved topics


@pytest.mark.parametrize('scenario, effect', [('realistic', 'valve lag 5 ms'),
                                              ('other_forms', '2nd-order valve 30 Hz')])
def test_realistic_plant_keeps_1khz(sim_node, probe, helpers, scenario, effect):
    """-p scenario:=realistic (or other_forms, the second family): the plant with unmodelled
    effects still samples at 1 kHz with finite pressures, and the start-up log names its
    effects. The rate is read from the samples' stamps (2 s of the rig's clock), not from when
    they arrived: on a loaded machine a late sample arrives late but was taken on time."""
    sim = sim_node('-p', f'scenario:={scenario}')
    got = probe.subscribe(Pressures, '/pam/pressures')
    sim.wait_for(lambda: len(got) > 0, STARTUP, 'the first /pam/pressures sample')
    time.sleep(0.5)
    start_ns = helpers.stamp_ns(got.messages()[-1].header.stamp)
    time.sleep(3.0)                       # 2 s of samples and 1 s for the late ones to arrive
    window = [m for m in got.messages()
              if start_ns <= helpers.stamp_ns(m.header.stamp) < start_ns + 2_000_000_000]
    assert len(window) >= 0.9 * 2.0 * RATE, f'{len(window)} samples in 2 s of stamps'
    assert all(helpers.all_finite((m.p1, m.p2)) for m in window)
    assert f'unmodelled effects: {effect}' in sim.stderr + sim.stdout
