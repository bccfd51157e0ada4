"""sim_node in lockstep mode: a step per command, stamped with simulated time, deterministic."""

from __future__ import annotations

import math
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray

from pam_common.stamps import ns_stamp
from pam_interfaces.msg import Pressures, ValveCommand

STEPS = 400
H_NS = 1_000_000          # ns, model step at the default 1 kHz
STARTUP = 45.0            # s
RUN_TIMEOUT = 60.0        # s, for STEPS round trips on a loaded machine


def command_for(k: int) -> tuple[float, float]:
    u1 = 5.5 + 3.0 * math.sin(k / 50.0)
    return u1, 11.0 - u1


def run_lockstep(sim_node, probe, helpers, seed: int, noise: float = 2000.0,
                 steps: int = STEPS, namespace: str = 'pam', args: tuple = ()):
    """Drive a fresh lockstep sim_node (with `args`) for `steps` steps; return [(p1, p2)] for
    k = 0..steps and the node."""
    sim = sim_node('-r', f'__ns:=/{namespace}', '-p', 'timing:=lockstep', '-p', f'seed:={seed}',
                   '-p', f'pressure_noise_std:={noise!r}', '-p', 'lockstep_timeout:=0.2', *args)
    command = probe.publisher(ValveCommand, f'/{namespace}/valve_command')
    samples: dict[int, tuple[float, float]] = {}
    duplicates_differ: list[int] = []
    wrong_counter: list[tuple[int, int]] = []
    lock = threading.Lock()

    def on_sample(msg: Pressures):
        t = helpers.stamp_ns(msg.header.stamp)
        k, rest = divmod(t, H_NS)
        assert rest == 0, f'lockstep stamp {t} ns is not a multiple of h'
        with lock:
            if msg.sample != k + 1:          # Pressures.sample: 1, 2, ...; a re-publication too
                wrong_counter.append((k, msg.sample))
            if k in samples:
                if samples[k] != (msg.p1, msg.p2):
                    duplicates_differ.append(k)
            else:
                samples[k] = (msg.p1, msg.p2)
        if k < steps:
            reply = ValveCommand()
            reply.header.stamp = msg.header.stamp   # "this command is for step k"
            reply.u1, reply.u2 = command_for(k)
            command.publish(reply)

    got = probe.subscribe(Pressures, f'/{namespace}/pressures', callback=on_sample)
    sim.wait_for(lambda: len(got) > 0, STARTUP, 'the first lockstep sample')
    sim.wait_for(lambda: len(samples) > steps, RUN_TIMEOUT, f'{steps} lockstep steps')
    with lock:
        assert not duplicates_differ, f're-published samples differ at steps {duplicates_differ}'
        assert not wrong_counter, f'(step, sample counter) {wrong_counter[:5]}'
        assert sorted(samples) == list(range(len(samples))), 'a step was skipped'
        result = [samples[k] for k in range(steps + 1)]
    assert sim.stop() == 0, 'sim_node should exit cleanly on SIGINT'
    return result, sim


def test_lockstep_is_deterministic(sim_node, probe, helpers):
    first, sim = run_lockstep(sim_node, probe, helpers, seed=7, namespace='run1')
    # started with our nodes' asynchronous default, it says how to step faster
    assert ('lockstep with RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS' in sim.stderr
            and 'RMW_FASTRTPS_PUBLICATION_MODE=SYNCHRONOUS in every node' in sim.stderr), sim.stderr
    second, _ = run_lockstep(sim_node, probe, helpers, seed=7, namespace='run2')
    other, _ = run_lockstep(sim_node, probe, helpers, seed=8, namespace='run3')

    assert first == second, 'same seed + same commands must give bit-identical pressures'
    p1 = [p for p, _ in first]
    assert max(p1) - min(p1) > 20e3, 'the command sequence should move the pressures'
    assert len(set(first)) > STEPS // 2
    assert other != first, 'another seed with sensor noise must give other readings'
    assert all(math.isfinite(v) for pair in first + other for v in pair)


def test_lockstep_clock_at_clock_rate(sim_node, probe, helpers):
    """publish_clock with clock_rate 250 Hz at the 1 kHz rate: /clock carries t_k of the samples
    k = 0, 4, 8, ... and of no other (a node on simulated time pays for each message)."""
    from rosgraph_msgs.msg import Clock
    clock = probe.subscribe(Clock, '/clock')
    steps = 40
    _, sim = run_lockstep(sim_node, probe, helpers, seed=3, steps=steps, namespace='clocked',
                          args=('-p', 'publish_clock:=true', '-p', 'clock_rate:=250.0'))
    expected = {k * H_NS for k in range(0, steps + 1, 4)}
    deadline = time.monotonic() + 10.0               # the last /clock may trail the pressures
    while not expected <= (stamps := {helpers.stamp_ns(m.clock) for m in clock.messages()}):
        assert time.monotonic() < deadline, sorted(stamps)
        time.sleep(0.05)
    assert stamps == expected, sorted(stamps)
    assert '/clock published with 1 sample in 4' in sim.stderr, sim.stderr


def test_lockstep_ignores_commands_from_the_past(sim_node, probe, helpers):
    sim = sim_node('-p', 'timing:=lockstep', '-p', 'lockstep_timeout:=0.2',
                   '-p', 'publish_clock:=true')
    stamps: list[int] = []
    got = probe.subscribe(Pressures, '/pam/pressures',
                          callback=lambda m: stamps.append(helpers.stamp_ns(m.header.stamp)))
    from rosgraph_msgs.msg import Clock
    clock = probe.subscribe(Clock, '/clock')
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics', depth=10)
    command = probe.publisher(ValveCommand, '/pam/valve_command')
    # the sample of step 0 and its /clock are re-published every lockstep_timeout until a
    # command comes: both writers have then matched the probe's readers
    sim.wait_for(lambda: len(got) > 0 and len(clock) > 0, STARTUP,
                 'the first lockstep sample and its /clock')
    sim.wait_for(lambda: command.get_subscription_count() > 0, 10.0,
                 'sim_node to subscribe valve_command')

    def send(stamp_ns: int):
        msg = ValveCommand()
        msg.header.stamp = ns_stamp(stamp_ns)
        msg.u1 = msg.u2 = 5.5
        command.publish(msg)

    send(0)                  # zero stamp: for the current step (0) -> sample 1
    sim.wait_for(lambda: H_NS in stamps, 10.0, 'sample 1')
    send(H_NS)               # for step 1 -> sample 2
    sim.wait_for(lambda: 2 * H_NS in stamps, 10.0, 'sample 2')
    send(H_NS)               # step 1 is past now: ignored
    send(5 * H_NS)           # a future stamp counts for the current step (2) -> sample 3
    sim.wait_for(lambda: 3 * H_NS in stamps, 10.0, 'sample 3')

    def reported():
        for status in helpers.diagnostic_statuses(diagnostics):
            values = {kv.key: kv.value for kv in status.values}
            if values.get('commands received') == '4':
                return status, values
        return None

    sim.wait_for(lambda: reported() is not None, 10.0, '/diagnostics to count 4 commands')
    _status, values = reported()
    assert values['past commands ignored'] == '1', values
    assert values['timing'] == 'lockstep'
    assert max(stamps) == 3 * H_NS, 'no step without a command'
    clock_ns = {helpers.stamp_ns(m.clock) for m in clock.messages()}
    assert {H_NS, 2 * H_NS, 3 * H_NS} <= clock_ns, '/clock carries t_k'
