"""sim_node's sample -> command latency at the rig, a real process seen from topics.

The probe answers samples with valve commands stamped like pi_node's (the stamp of the sample
they answer): answered at once, a command is timed with a small latency; answered with the stamp
of a sample five periods old, it is timed about 5 ms late and counted as after the next sample.
~/reset_statistics starts the figures afresh.
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray
from std_srvs.srv import Trigger

from pam_common.diagnostics import status_values
from pam_interfaces.msg import Pressures, ValveCommand

STARTUP = 45.0                 # s, first message from a fresh process (loaded machine)
ANSWERS = 300                  # commands per phase


def latest_values(diagnostics, since: float) -> dict | None:
    for received, msg in reversed(diagnostics.items()):
        if received < since:
            return None
        for status in msg.status:
            if status.name.startswith('/pam/sim_node: '):
                return status_values(status)
    return None


def answer(probe, publisher, samples, count: int, lag: int, helpers) -> None:
    """Send `count` commands, each stamped with the sample `lag` samples before the latest one
    received when it is sent."""
    sent = 0
    seen = len(samples)

    def one_more() -> bool:
        nonlocal sent, seen
        if len(samples) > seen and len(samples) > lag:
            seen = len(samples)
            command = ValveCommand(u1=5.5, u2=5.5)
            command.header.stamp = samples.messages()[-1 - lag].header.stamp
            publisher.publish(command)
            sent += 1
        return sent >= count
    assert helpers.wait_until(one_more, 30.0, period=0.0005), f'sent {sent} of {count}'


def reset(probe, helpers) -> None:
    client = probe.client(Trigger, '/pam/sim_node/reset_statistics')
    assert client.wait_for_service(timeout_sec=STARTUP)
    future = client.call_async(Trigger.Request())
    assert helpers.wait_until(future.done, 10.0)
    assert future.result().success


def figures(diagnostics, helpers) -> dict:
    """The next /diagnostics values of sim_node, with its latency figures as numbers."""
    import time
    since = time.monotonic()
    values = {}

    def fresh() -> bool:
        values.update(latest_values(diagnostics, since) or {})
        return bool(values)
    assert helpers.wait_until(fresh, 5.0), 'no fresh /diagnostics from sim_node'
    return {k: float(values[k]) if values[k] != 'n/a' else math.nan for k in (
        'commands timed', 'commands after the next sample', 'latency p50 (ms)',
        'latency p99 (ms)', 'latency max (ms)')}


def test_latency_at_the_rig(sim_node, probe, helpers):
    sim = sim_node()
    samples = probe.subscribe(Pressures, '/pam/pressures', depth=1000)
    diagnostics = probe.subscribe(DiagnosticArray, '/diagnostics')
    publisher = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(samples) > 10, STARTUP, 'the first /pam/pressures samples')
    sim.wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP, 'sim_node subscribing')

    reset(probe, helpers)
    nothing = figures(diagnostics, helpers)
    assert nothing['commands timed'] == 0 and math.isnan(nothing['latency p50 (ms)'])

    answer(probe, publisher, samples, ANSWERS, 5, helpers)   # five samples old: late
    old = figures(diagnostics, helpers)
    assert old['commands timed'] >= 0.9 * ANSWERS
    assert old['commands after the next sample'] == old['commands timed']
    assert old['latency p50 (ms)'] >= 4.0, old

    reset(probe, helpers)
    answer(probe, publisher, samples, ANSWERS, 0, helpers)   # the latest sample
    fresh = figures(diagnostics, helpers)
    assert fresh['commands timed'] >= 0.9 * ANSWERS
    assert fresh['latency p50 (ms)'] < old['latency p50 (ms)'], (fresh, old)
    assert fresh['commands after the next sample'] < fresh['commands timed']
    assert all(math.isfinite(v) for v in fresh.values())
