#!/usr/bin/env python3
"""Fault campaign: a table of bad inputs against live nodes, printed as
case | expected | observed | deaths | non-finite | lost unreported | tracebacks.

Every input topic (NaN, inf, huge values, stamps from the past, decreasing and zero stamps, a
burst), run-time parameter changes (the rcl_interfaces SetParameters service `ros2 param set`
uses: NaN, out of range, wrong types, unknown and read-only names) and bad start-up values, a
reference bag replayed into ukf_node and damaged copies of it (bytes flipped in a chunk, with and
without CRCs, a truncated file, a split file or metadata.yaml missing) fed to every bag tool,
malformed params files fed to every node and pam-bringup, every serial fault of pam-emulator
against driver_node, and processes killed mid-run or during their imports.

The nodes run as real processes on an isolated ROS domain with localhost discovery; an rclpy
probe in this process feeds their inputs (standing in for the rig, the estimator or the
controller: numbered, stamped messages) and watches every output topic. Per case:
  deaths            processes of the stack (or tools) dead at the end that the case did not kill
                    on purpose; a tool killed by a signal or hung (an exit code is an answer);
  non-finite        NaN/inf values received on the output topics (/pam/pressures, estimate,
                    valve_command, controller_state, joint_measured, driver_node/applied_command,
                    /diagnostics values that read as numbers);
  lost unreported   messages sent minus messages answered minus the loss the consumer reports
                    ('samples lost' on its /diagnostics, from the sample counter); '-' where a
                    case has no stream to count, 'n/a' where the node has no such report;
  tracebacks        'Traceback' in any process's output during the case.
Exit code 0 only if every case's observation matches its expectation and the totals are 0.

    .venv/bin/python benchmarks/fault_campaign.py [--only PATTERN] [--list] [--verbose]

(with AMENT_PREFIX_PATH=.venv and .venv/bin on PATH: `source scripts/env.sh`). --only runs the
cases whose name or group matches the regular expression; a group's stack starts once for its
cases (serial faults: a pam-emulator per case, driver_node and ukf_node running on). About 4-5
minutes in all on 2 cores.
"""

from __future__ import annotations

import argparse
import math
import re
import signal
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, NamedTuple

import rclpy
from rclpy.context import Context

from fault_inputs import (HUGE, INF, NAN, Feed, Parameters, command_message,
                          copy_bag, estimate_message, flip_in_chunk, flip_unnoticed,
                          lockstep_command, pressures_message, remove_metadata,
                          remove_split_file, truncate, unanswered)
from fault_stack import (NodeSpec, Stack, Tool, campaign_domain, maps_holds, new_folder, number,
                         run_tool, traceback_count)
from pam_driver.sample_gaps import SampleGaps
from pam_driver.testing import (MALFORMED_PARAMS_FILES, NodeProcess, Probe, child_env,
                                malformed_params_file, stamp_ns, wait_until)

ROOT = Path(__file__).resolve().parents[1]
BAGS = ROOT / 'bags'
SETTLE = 0.3          # s after a case's inputs before the /diagnostics it is judged on
SAFE_SLACK = 0.5      # s allowed on top of a watchdog's time on a loaded machine
VERBOSE = False       # --verbose


@dataclass
class Verdict:
    ok: bool
    observed: str


@dataclass
class Case:
    """One row of the table: the input given, the behaviour expected, how to do it
    (act(ctx) -> facts) and how to judge it (check(ctx, facts) -> Verdict)."""

    name: str
    group: str
    given: str
    expected: str
    act: Callable
    check: Callable


@dataclass
class Row:
    case: Case
    verdict: Verdict
    deaths: list
    non_finite: list
    lost: object          # int, 'n/a' (no loss report on /diagnostics) or '-' (not counted)
    tracebacks: int


# ============================================================================ case context
class Ctx:
    """What a case's act and check see: the group's stack and inputs, /diagnostics before and
    after, the tools it ran."""

    def __init__(self, run: 'GroupRun'):
        self.run = run
        self.stack: Stack | None = run.stack
        self.io = run.io
        self.folder = new_folder(run.folder, 'case')
        self.env = child_env(run.domain)
        self.domain = run.domain
        self.t0 = time.monotonic()
        self.t_acted = self.t0
        self.tools: list[Tool] = []
        self.procs: list[NodeProcess] = []       # processes a case starts on its own
        self.killed: set[int] = set()            # ids of those it killed on purpose
        self.before = {n: self.stack.values(n) for n in run.group.diag_nodes} if self.stack \
            else {}
        self._after: dict[str, dict] = {}

    def rebase(self) -> None:
        """Judge the case from now on: /diagnostics before = the first status from now, the
        messages received from now."""
        now = time.monotonic()
        self.before = {n: self.stack.fresh_values(n, now) for n in self.run.group.diag_nodes}
        self.t0 = now

    def after(self, node: str) -> dict:
        """/diagnostics of `node` from the first status after the case's inputs settled."""
        if node not in self._after:
            self._after[node] = self.stack.fresh_values(node, self.t_acted + SETTLE)
        return self._after[node]

    def delta(self, node: str, key: str) -> float:
        return number(self.after(node), key) - number(self.before.get(node, {}), key, 0.0)

    def received(self, topic: str) -> list:
        return self.stack.topics[topic].since(self.t0)

    def tool(self, exe: str, package: str, *args) -> Tool:
        result = run_tool(exe, package, args, self.env, self.folder)
        self.tools.append(result)
        return result


# ============================================================================ checks
def all_of(*checks):
    def check(ctx, facts):
        verdicts = [c(ctx, facts) for c in checks]
        return Verdict(all(v.ok for v in verdicts), '; '.join(v.observed for v in verdicts))
    return check


def rises(node: str, key: str, at_least: float, at_most: float = math.inf):
    """A /diagnostics counter of `node` went up by at_least .. at_most during the case."""
    def check(ctx, facts):
        d = ctx.delta(node, key)
        return Verdict(at_least <= d <= at_most, f"'{key}' +{d:g}")
    return check


def diag_is(node: str, key: str, predicate):
    """predicate(value) of a /diagnostics value of `node` after the case."""
    def check(ctx, facts):
        value = ctx.after(node).get(key, '(missing)')
        return Verdict(bool(predicate(value)), f"'{key}' {value}")
    return check


def level_at_least(node: str, level: int):
    def check(ctx, facts):
        ctx.after(node)
        s = ctx.stack.status(node, ctx.t_acted + SETTLE)
        got = s.level[0] if s else -1
        names = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE', -1: 'none'}
        return Verdict(got >= level, f'{node} {names[got]}: {s.message if s else ""}'[:140])
    return check


def estimates_of(ctx, sent) -> list:
    """The pressure samples sent that have no estimate (matched by counter)."""
    got = {m.sample for m in ctx.received('/pam/estimate')}
    return [s for s, _ in sent if s not in got]


def commands_of(ctx, sent) -> list:
    """The estimates sent that have no valve command (matched by stamp)."""
    return unanswered(sent, [stamp_ns(m.header.stamp)
                             for m in ctx.received('/pam/valve_command')])


def every_answer(node: str, missing_of, what: str):
    """Every message sent was answered (missing_of(ctx, sent) empty, waiting up to 3 s for the
    last), or `node` reported the missing ones lost ('samples lost' on /diagnostics)."""
    def check(ctx, facts):
        sent = facts['sent']
        wait_until(lambda: not missing_of(ctx, sent), 3.0, 0.05)
        missing = missing_of(ctx, sent)
        text = f'{len(sent) - len(missing)}/{len(sent)} {what}'
        if not missing:
            return Verdict(True, text)
        reported = ctx.delta(node, 'samples lost')
        return Verdict(reported >= len(missing),
                       f"{text} (counters {missing[0]}..{missing[-1]} missing), {reported:g} "
                       f"reported as 'samples lost'")
    return check


def streams_on(at_least: int):
    """At least `at_least` pressure samples reached the probe during the case."""
    def check(ctx, facts):
        n = len(ctx.received('/pam/pressures'))
        return Verdict(n >= at_least, f'{n} samples received')
    return check


def stepped(n: int):
    """A lockstep sim_node stepped for n of the commands."""
    def check(ctx, facts):
        k = facts['stepped']
        return Verdict(k == n, f'stepped {k}/{len(facts["results"])}')
    return check


def applied(u1: float, u2: float):
    """driver_node's last ~/applied_command is (u1, u2)."""
    def check(ctx, facts):
        items = ctx.stack.topics['/pam/driver_node/applied_command'].messages()
        last = (items[-1].u1, items[-1].u2) if items else None
        return Verdict(last == (u1, u2), f'applied {last}')
    return check


def refused(ctx, facts):
    """Every parameter change in facts['results'] was refused with a reason, and the value read
    back afterwards is the one before."""
    results = facts['results']
    bad = [f'{r.name}={r.value!r}: {"accepted" if r.ok else "no reason"}' for r in results
           if r.ok or not r.reason]
    changed = [f'{r.name} {r.before!r} -> {r.after!r}' for r in results
               if r.before != r.after and not (_is_nan(r.before) and _is_nan(r.after))]
    total = len(results)
    text = f'{total - len(bad)}/{total} refused with a reason, values unchanged'
    if bad or changed:
        text = f'{total - len(bad)}/{total} refused; ' + '; '.join(bad + changed)
    return Verdict(not bad and not changed, text)


def accepted(ctx, facts):
    """Every parameter change in facts['results'] was accepted and reads back."""
    results = facts['results']
    good = [r.ok and r.after == r.value for r in results]
    return Verdict(all(good), ', '.join(
        f'{r.name}={r.value!r} ' + ('set' if g else f'NOT set ({r.reason}) -> {r.after!r}')
        for r, g in zip(results, good)))


def _is_nan(value) -> bool:
    return isinstance(value, float) and math.isnan(value)


def safe_within(topic: str, safe: tuple, limit: float, what: str):
    """After the kill, the first message on `topic` equal to `safe` arrives within `limit` s."""
    def check(ctx, facts):
        t_kill = facts['killed_at']
        hits = [t for t, m in ctx.stack.topics[topic].items()
                if t >= t_kill and (m.u1, m.u2) == safe]
        if not hits:
            return Verdict(False, f'{what}: no {safe} on {topic} after the kill')
        dt = hits[0] - t_kill
        return Verdict(dt <= limit, f'{what} {safe} {dt * 1e3:.0f} ms after the kill '
                                    f'(limit {limit * 1e3:.0f} ms)')
    return check


def status_seen(node: str, level: int, text: str):
    """A status of `node` at `level` or worse whose message holds `text` came during the case."""
    def check(ctx, facts):
        seen = [s for t, a in ctx.stack.topics['/diagnostics'].items() if t >= ctx.t0
                for s in a.status if s.name.startswith(node) and s.level[0] >= level
                and text in s.message]
        return Verdict(bool(seen), f"{len(seen)} statuses with '{text}'" if seen else
                       f"no status with '{text}'")
    return check


def alive(*names):
    def check(ctx, facts):
        dead = [n for n in names if not ctx.stack.procs[n].alive()]
        return Verdict(not dead, 'dead: ' + ', '.join(dead) if dead else
                       ', '.join(names) + ' alive')
    return check


def tools_answer(expected: dict, naming: bool = True):
    """Each tool run of the case exited with its expected code (and, if `naming`, named the bag
    on stderr when it failed); expected: label -> code."""
    def check(ctx, facts):
        parts, ok = [], True
        for label, code in expected.items():
            run = facts['runs'].get(label)
            if run is None:
                parts.append(f'{label} not run')
                ok = False
                continue
            named = (not naming or run.code == 0
                     or any(facts['bag_name'] in line for line in run.lines()))
            good = run.code == code and named
            ok &= good
            shown = 'hung' if run.code is None else run.code
            parts.append(f'{label} {shown}' + ('' if named else ' (error does not name the bag)'))
        return Verdict(ok, ', '.join(parts))
    return check


def params_file_refused(ctx, facts):
    """Every executable exited with code 2 and one stderr line naming the file (and line)."""
    path, line = facts['path'], facts['line']
    bad = []
    for exe, run in facts['runs'].items():
        lines = run.lines()
        one = (len(lines) == 1 and f'params file {path}: ' in lines[0]
               and (line is None or lines[0].endswith(f'(line {line})')))
        if run.code != 2 or not one:
            bad.append(f'{exe}: exit {run.code}, {len(lines)} lines: '
                       f'{(lines or [""])[0][:100]}')
    n = len(facts['runs'])
    return Verdict(not bad, f'{n - len(bad)}/{n} exit 2 with one line' +
                   ('; ' + '; '.join(bad) if bad else ''))


def unknown_name_warned(ctx, facts):
    missing = [exe for exe, seen in facts['warned'].items() if not seen]
    n = len(facts['warned'])
    return Verdict(not missing, f'{n - len(missing)}/{n} warned' +
                   (': missing ' + ', '.join(missing) if missing else ''))


# ============================================================================ actions
def feed_values(feed: str, values, stamps='forward', period=0.001, before=None):
    """Publish `before(ctx)` first (if given), then one message of `feed` per value, then a
    closing good one."""
    def act(ctx):
        if before is not None:
            before(ctx)
            time.sleep(0.05)
        f: Feed = ctx.io[feed]
        sent = f.send(values, stamps, period) + f.close()
        return {'sent': sent}
    return act


def commands_to(topic_key: str, commands):
    """Publish the valve commands (u1, u2) on the publisher io[topic_key]."""
    def send(ctx):
        for u1, u2 in commands:
            ctx.io[topic_key].publish(command_message(u1, u2))
            time.sleep(0.002)
    return send


def reference(mode: int, value: float):
    def send(ctx):
        from pam_interfaces.msg import Reference
        ctx.io['reference'].publish(Reference(mode=mode, value=float(value)))
    return send


def lockstep(commands, stamps='current'):
    """Commands to a lockstep sim_node, each waiting for the step it makes (or 0.2 s)."""
    def act(ctx):
        results = [lockstep_command(ctx.io['commands'], ctx.stack.topics['/pam/pressures'],
                                    u1, u2, stamps, timeout=1.0 if stamps != 'past' else 0.2)
                   for u1, u2 in commands]
        lockstep_command(ctx.io['commands'], ctx.stack.topics['/pam/pressures'], 5.5, 5.5)
        return {'results': results, 'stepped': sum(results)}
    return act


def lockstep_decreasing(n: int):
    """A command for the current step, then n stamped 1 ms, 2 ms, ... before it."""
    def act(ctx):
        pressures = ctx.stack.topics['/pam/pressures']
        t_k = stamp_ns(pressures.messages()[-1].header.stamp)
        results = [lockstep_command(ctx.io['commands'], pressures, 5.5, 5.5)]
        for i in range(1, n + 1):
            ctx.io['commands'].publish(command_message(5.5, 5.5, t_k - i * 1_000_000))
            time.sleep(0.01)
            results.append(False)
        lockstep_command(ctx.io['commands'], pressures, 5.5, 5.5)
        return {'results': results, 'stepped': int(results[0])}
    return act


def driver_commands(commands, stamps='now'):
    """Valve commands to driver_node, stamped now, 0, 10 s back or 1, 2, ... s back."""
    def act(ctx):
        for i, (u1, u2) in enumerate(commands):
            ns = {'now': None, 'zero': 0, 'past': time.time_ns() - 10_000_000_000,
                  'decreasing': time.time_ns() - (i + 1) * 1_000_000_000}[stamps]
            ctx.io['commands'].publish(command_message(u1, u2, ns))
            time.sleep(0.005)
        time.sleep(0.2)
        return {}
    return act


def in_turn(*acts):
    def act(ctx):
        facts = {}
        for a in acts:
            facts.update(a(ctx) or {})
        return facts
    return act


class ParamChange(NamedTuple):
    """One run-time parameter change and its answer."""

    name: str
    value: object
    ok: bool
    reason: str
    before: object       # the value read back before the change
    after: object        # and after it


def set_parameters(node: str, changes, then=None):
    """Set each (name, value) alone through node's SetParameters service (ParamChange each),
    then `then(ctx)` if given."""
    def act(ctx):
        client = Parameters(ctx.stack.probe, f'/pam/{node}')
        results = []
        for name, value in changes:
            before = client.get(name)
            ok, reason = client.set(name, value)
            results.append(ParamChange(name, value, ok, reason, before, client.get(name)))
        facts = {'results': results}
        if then is not None:
            facts.update(then(ctx))
        return facts
    return act


def kill(name: str, then_wait: float = 1.5, before=None):
    def act(ctx):
        if before is not None:
            before(ctx)
        t = ctx.stack.kill(name)
        time.sleep(then_wait)
        return {'killed_at': t}
    return act


def trigger(ctx, service: str):
    """Call a std_srvs/Trigger service; its response (None if no answer within 5 s)."""
    from std_srvs.srv import Trigger
    client = ctx.stack.probe.client(Trigger, service)
    if not client.wait_for_service(timeout_sec=5.0):
        return None
    future = client.call_async(Trigger.Request())
    return future.result() if wait_until(future.done, 5.0) else None


def arm_driver(ctx) -> None:
    """Make sure driver_node applies the controller's commands (call ~/arm if it latched safe
    during start-up) and they flow for 1 s."""
    applied = ctx.stack.topics['/pam/driver_node/applied_command']

    def applying():
        return applied.messages() and applied.messages()[-1].u1 != 0.0
    if not wait_until(applying, 3.0):
        trigger(ctx, '/pam/driver_node/arm')
        wait_until(applying, 5.0)
    time.sleep(1.0)


def board(args, then, ready=None):
    """A pam-emulator with `args` on the group's link (driver_node's port) for this case. The
    case is judged from before it starts (the new stream's gaps all fall in the case); when
    `ready(ctx)` (default: samples flow), driver_node is armed (it latched safe when the last
    board went), then `then`; the board is stopped at the end, unless the case killed it, and
    the stream's end given time to reach ukf_node."""
    def act(ctx):
        ctx.rebase()
        link = ctx.run.folder / 'pam_daq'
        emulator = NodeProcess('pam-emulator', 'pam_driver', ['--link', str(link), *args],
                               ctx.env, cwd=ctx.folder)
        ctx.procs.append(emulator)
        up = ready or (lambda c: len(c.received('/pam/pressures')) > 100)
        if not wait_until(lambda: up(ctx) or not emulator.alive(), 20.0, 0.05):
            raise RuntimeError(f'the board did not come up: {emulator.stderr[-300:]}')
        trigger(ctx, '/pam/driver_node/arm')
        facts = then(ctx)
        if id(emulator) not in ctx.killed:
            emulator.stop()
            time.sleep(0.5)
        return facts
    return act


def commanding(seconds: float, period: float, u=(5.5, 5.5)):
    """Valve commands every `period` s for `seconds` s."""
    def act(ctx):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            ctx.io['commands'].publish(command_message(*u))
            time.sleep(period)
        return {}
    return act


def kill_board(then_wait: float):
    def act(ctx):
        emulator = ctx.procs[-1]
        ctx.killed.add(id(emulator))
        emulator.proc.kill()
        time.sleep(then_wait)
        return {}
    return act


def loop_running(ctx) -> None:
    """Wait (at most 30 s) until the closed loop runs: pi_node answered 500 estimates since the
    case began and its last command is fresh."""
    commands = ctx.stack.topics['/pam/valve_command']
    wait_until(lambda: len(commands.since(ctx.t0)) > 500 and
               commands.items()[-1][0] > time.monotonic() - 0.1, 30.0, 0.05)


def observe(seconds: float):
    def act(ctx):
        time.sleep(seconds)
        return {}
    return act


def wait_diag(node: str, predicate, timeout: float):
    """Wait (at most timeout s) for a /diagnostics status of node whose values satisfy
    predicate(values, values before the case)."""
    def act(ctx):
        wait_until(lambda: predicate(ctx.stack.values(node, ctx.t0), ctx.before.get(node, {})),
                   timeout, 0.1)
        return {}
    return act


def kill_recorder(ctx):
    """SIGKILL bag_record after 3 s of recording, then pam-bag-recover and pam-bag-info."""
    time.sleep(3.0)
    ctx.stack.kill('bag_record')
    bag = ctx.run.folder / 'recorded'
    runs = {'recover': ctx.tool('pam-bag-recover', 'pam_driver', bag)}
    runs['info (recovered)'] = ctx.tool('pam-bag-info', 'pam_driver', bag)
    return {'runs': runs, 'bag_name': 'recorded'}


# --- bags
READERS = ('info', 'play', 'evaluate', 'identify')


def bag_tools(ctx, bag: Path) -> dict:
    """Every bag tool on `bag`: pam-bag-info, bag_play, pam-evaluate, pam-identify; then
    pam-bag-recover and pam-bag-info on what it rebuilt."""
    runs = {'info': ctx.tool('pam-bag-info', 'pam_driver', bag),
            'play': ctx.tool('bag_play', 'pam_driver', '--ros-args', '-p', f'bag:={bag}',
                             '-p', 'rate:=50.0', '-p', 'delay:=0.0'),
            'evaluate': ctx.tool('pam-evaluate', 'pam_estimator', bag),
            'identify': ctx.tool('pam-identify', 'pam_estimator', bag, '-o',
                                 ctx.folder / 'identified')}
    runs['recover'] = ctx.tool('pam-bag-recover', 'pam_driver', bag)
    runs['info (recovered)'] = ctx.tool('pam-bag-info', 'pam_driver', bag)
    return runs


def replay(source: str, topics: str):
    """bag_play bags/<source> (these topics, rate 1) into the group's ukf_node; facts: the
    recorded /pam/pressures and the gaps already in their sample counter."""
    def act(ctx):
        from pam_driver.bags import load_bag, make_typestore
        contents, gaps = load_bag(BAGS / source, ['/pam/pressures']), SampleGaps()
        counters = [msg.sample for _, msg in contents.deserialized('/pam/pressures',
                                                                   make_typestore())]
        for sample in counters:
            gaps.update(sample)
        ctx.tool('bag_play', 'pam_driver', '--ros-args', '-p', f'bag:={BAGS / source}',
                 '-p', f'topics:={topics}')
        return {'recorded': gaps.received + gaps.uncounted, 'in_bag': gaps.lost,
                'counters': (counters[0], counters[-1])}
    return act


def replay_counts(ctx, facts) -> tuple[int, int]:
    """(recorded samples not estimated, of them the ones ukf_node reports lost on the way: its
    'samples lost' less the gaps already in the bag)."""
    missing = facts['recorded'] - len(ctx.received('/pam/estimate'))
    return missing, int(ctx.delta(UKF, 'samples lost')) - facts['in_bag']


def replay_estimated(ctx, facts):
    """An estimate for every recorded pressure sample, or the loss reported."""
    missing, reported = replay_counts(ctx, facts)
    play = ctx.tools[-1]
    got = sorted(m.sample for m in ctx.received('/pam/estimate'))
    seen = f', counters {got[0]}..{got[-1]} of {facts["counters"][0]}..{facts["counters"][1]}' \
        if got else ''
    return Verdict(play.code == 0 and reported >= missing,
                   f"bag_play exit {play.code}; {facts['recorded'] - missing}/"
                   f"{facts['recorded']} samples estimated{seen}, {reported} reported as "
                   f"'samples lost' ({facts['in_bag']} more: gaps recorded in the bag)")


def replay_loss(ctx, facts):
    if 'recorded' not in facts:
        return '-'
    missing, reported = replay_counts(ctx, facts)
    return max(missing - reported, 0)


def damaged_bag(source: str, *damages):
    """A copy of bags/<source> with each damage(bag) applied, through every bag tool."""
    def act(ctx):
        bag = copy_bag(BAGS / source, ctx.folder)
        done = [damage(bag) for damage in damages]
        return {'runs': bag_tools(ctx, bag), 'bag_name': source, 'done': done}
    return act


# --- params files
PARAMS_FILE_EXES = (('sim_node', 'pam_driver'), ('driver_node', 'pam_driver'),
                    ('profile_player', 'pam_driver'), ('bag_record', 'pam_driver'),
                    ('bag_play', 'pam_driver'), ('ukf_node', 'pam_estimator'),
                    ('pi_node', 'pam_controller'), ('reference_node', 'pam_controller'),
                    ('tracking_report', 'pam_controller'))


# --- stops during start-up
#: C extensions of numpy and rclpy: the first one mapped, a process's imports are under way
IMPORTING = ('_multiarray_umath', '_rclpy_pybind11')
STARTUP_EXES = (*PARAMS_FILE_EXES, ('pam-evaluate', 'pam_estimator'),
                ('pam-identify', 'pam_estimator'))


def stopped_while_importing(sig: int):
    """`sig` to every node and batch tool during its imports, three at a time."""
    def act(ctx):
        importing = (sig, maps_holds(*IMPORTING))
        with ThreadPoolExecutor(3) as pool:
            futures = {exe: pool.submit(run_tool, exe, package, (), ctx.env, ctx.folder, 60.0,
                                        importing) for exe, package in STARTUP_EXES}
            runs = {exe: f.result() for exe, f in futures.items()}
        ctx.tools += runs.values()
        return {'runs': runs, 'code': 128 + sig}
    return act


def quiet_exits(ctx, facts):
    """Each run exited with facts['code'] and printed nothing."""
    bad = [f'{exe}: exit {run.code}, {len(run.stdout + run.stderr)} bytes of output'
           for exe, run in facts['runs'].items()
           if run.code != facts['code'] or run.stdout or run.stderr]
    n = len(facts['runs'])
    return Verdict(not bad, f"{n - len(bad)}/{n} exit {facts['code']}, silent" +
                   ('; ' + '; '.join(bad) if bad else ''))


def params_file_to_all(kind: str):
    """The malformed params file of `kind` (pam_driver.testing.MALFORMED_PARAMS_FILES) to every
    node and pam-bringup, three at a time."""
    def act(ctx):
        path, line = malformed_params_file(ctx.folder, kind)
        jobs = {exe: (exe, package, '--ros-args', '--params-file', path)
                for exe, package in PARAMS_FILE_EXES}
        jobs['pam-bringup'] = ('pam-bringup', 'pam_controller', '--params-file', path,
                               '--domain-id', ctx.domain, '--duration', 5)
        with ThreadPoolExecutor(3) as pool:
            futures = {exe: pool.submit(ctx.tool, *job) for exe, job in jobs.items()}
            runs = {exe: f.result() for exe, f in futures.items()}
        return {'runs': runs, 'path': path, 'line': line}
    return act


#: A double parameter of each node, for bad start-up values.
DOUBLE_PARAM = {'sim_node': 'rate', 'driver_node': 'watchdog_timeout', 'ukf_node': 'pressure_min',
                'pi_node': 'kp_angle', 'reference_node': 'amplitude',
                'profile_player': 'duration', 'bag_record': 'chunk_interval', 'bag_play': 'rate',
                'tracking_report': 'duration'}


def start_with_bad_value(value: str):
    """Every node started with `-p <one of its double parameters>:=value`, three at a time."""
    def act(ctx):
        with ThreadPoolExecutor(3) as pool:
            futures = {exe: pool.submit(ctx.tool, exe, package, '--ros-args', '-p',
                                        f'{DOUBLE_PARAM[exe]}:={value}')
                       for exe, package in PARAMS_FILE_EXES}
            return {'runs': {exe: f.result() for exe, f in futures.items()}}
    return act


def bad_value_refused(ctx, facts):
    """Every node exited with code 2 and one stderr line naming its parameter."""
    bad = []
    for exe, run in facts['runs'].items():
        lines = run.lines()
        if run.code != 2 or len(lines) != 1 or f"parameter '{DOUBLE_PARAM[exe]}'" not in lines[0]:
            bad.append(f'{exe}: exit {run.code}, {len(lines)} lines: {(lines or [""])[0][:100]}')
    n = len(facts['runs'])
    return Verdict(not bad, f'{n - len(bad)}/{n} exit 2, one line naming the parameter' +
                   ('; ' + '; '.join(bad) if bad else ''))


def unknown_name_in_every_node(ctx):
    """Every node started with a params file setting an unknown name (and the bag it needs):
    each must warn about it; stopped as soon as all did (or after 60 s)."""
    path = ctx.folder / 'unknown.yaml'
    path.write_text('/**:\n  ros__parameters:\n    no_such_parameter: 1.0\n')
    extra = {'bag_play': ['-p', f'bag:={BAGS / "closed_mild_angle"}'],
             'profile_player': ['-p', 'startup_timeout:=300.0'],
             'tracking_report': ['-p', 'startup_timeout:=300.0'],
             'bag_record': ['-p', f'output:={ctx.folder / "rec"}'],
             'driver_node': ['-p', f'port:={ctx.folder / "no_device"}']}
    for exe, package in PARAMS_FILE_EXES:
        ctx.procs.append(NodeProcess(exe, package, ['--ros-args', '--params-file', str(path),
                                                    *extra.get(exe, [])], ctx.env,
                                     cwd=ctx.folder))
    text = "ignoring unknown parameter 'no_such_parameter'"
    wait_until(lambda: all(text in p.stderr for p in ctx.procs), 60.0, 0.2)
    return {'warned': {p.name: text in p.stderr for p in ctx.procs}}


# ============================================================================ groups
@dataclass
class Group:
    """A stack (nodes, the outputs it publishes, the inputs the probe feeds it) shared by its
    cases; nodes None: command-line tools only."""

    name: str
    nodes: dict | None = None
    outputs: list = field(default_factory=list)
    inputs: Callable | None = None       # inputs(stack) -> io dict (publishers, feeds)
    diag_nodes: tuple = ()
    loss: Callable | None = None         # loss(ctx, facts) -> int | 'n/a' | '-'


def _msgs():
    from diagnostic_msgs.msg import DiagnosticArray  # noqa: F401
    from pam_interfaces.msg import (ControllerState, JointEstimate, JointMeasurement,
                                    Pressures, Reference, ValveCommand)
    return dict(ControllerState=ControllerState, JointEstimate=JointEstimate,
                JointMeasurement=JointMeasurement, Pressures=Pressures, Reference=Reference,
                ValveCommand=ValveCommand)


M = _msgs()


def ros(*params) -> tuple:
    """--ros-args -p NAME:=VALUE ... for each 'NAME:=VALUE'."""
    args = ['--ros-args']
    for p in params:
        args += ['-p', p]
    return tuple(args)


def answered_ping(ping, answered):
    """ready(stack, since) of a node the probe feeds: at each poll ping(stack) sends it a good
    input, until answered(stack, since) sees it answered. A publisher that sees its subscriber
    can still be unknown to it (DDS matches each pair of endpoints on its own, up to one 3 s
    announcement period apart), and what it sends before then is dropped."""
    def ready(stack, since):
        if answered(stack, since):
            return True
        ping(stack)
        return False
    return ready


def received_since(topic: str, predicate=lambda m: True):
    return lambda stack, since: any(predicate(m) for m in stack.topics[topic].since(since))


def diag_since(node: str, key: str):
    """A /diagnostics counter of `node` received after `since` is above 0."""
    return lambda stack, since: number(stack.values(node, since), key, 0.0) > 0


def both(*checks):
    return lambda stack, since: all(c(stack, since) for c in checks)


def ukf_ping(stack):
    stack.io['commands'].publish(command_message(5.5, 5.5))
    stack.io['pressures'].send([None], period=0.0)


def pi_ping(stack):
    stack.io['estimates'].send([0.0], period=0.0)


def lockstep_ping(stack):
    lockstep_command(stack.io['commands'], stack.topics['/pam/pressures'], 5.5, 5.5,
                     timeout=0.1)


def driver_ping(stack):
    stack.io['commands'].publish(command_message(5.5, 5.5))


def feed_loss(node: str, unanswered_of):
    """Messages of the case's feed not answered (unanswered_of(ctx, sent)), less the samples
    `node` reports lost ('samples lost' on /diagnostics)."""
    def loss(ctx, facts):
        sent = facts.get('sent')
        if not sent:
            return '-'
        reported = ctx.delta(node, 'samples lost')
        if math.isnan(reported):
            return 'n/a'
        return max(len(unanswered_of(ctx, sent)) - int(reported), 0)
    return loss


def serial_loss(ctx, facts):
    """Gaps in the sample counter of /pam/pressures as the probe received it, less the samples
    the consumer ukf_node reports lost (the driver numbers the device's ticks: a frame lost on
    the line or the stream down while reconnecting is a gap downstream)."""
    gaps = SampleGaps()
    for m in ctx.received('/pam/pressures'):
        gaps.update(m.sample)
    if gaps.received == 0:
        return '-'
    reported = ctx.delta('ukf_node', 'samples lost')
    if math.isnan(reported):
        return 'n/a'
    return max(gaps.lost - int(reported), 0)


def ukf_io(stack, counted: bool = True):
    return {'pressures': Feed(stack.probe.publisher(M['Pressures'], '/pam/pressures'),
                              pressures_message, counted),
            'commands': stack.probe.publisher(M['ValveCommand'], '/pam/valve_command')}


def pi_io(stack):
    return {'estimates': Feed(stack.probe.publisher(M['JointEstimate'], '/pam/estimate'),
                              estimate_message),
            'reference': stack.probe.publisher(M['Reference'], '/pam/reference')}


def commands_io(stack):
    return {'commands': stack.probe.publisher(M['ValveCommand'], '/pam/valve_command')}


def emulator(*args) -> NodeSpec:
    """pam-emulator on a pty linked at ./pam_daq (in the group's folder)."""
    return NodeSpec('pam-emulator', 'pam_driver', ('--link', 'pam_daq', *args),
                    ready=lambda stack, since: (stack.folder / 'pam_daq').is_symlink())


def driver(*params, streams: bool = True, ping: bool = False) -> NodeSpec:
    """driver_node on ./pam_daq; ready when samples flow (streams) and, with ping, when a
    command from the probe reached it ('commands received' on /diagnostics)."""
    checks = [received_since('/pam/pressures')] if streams else []
    if ping:
        checks.append(diag_since('driver_node', 'commands received'))
    ready = answered_ping(driver_ping if ping else (lambda stack: None), both(*checks))
    return NodeSpec('driver_node', 'pam_driver', ros('port:=pam_daq', *params),
                    diag_name='driver_node', ready=ready)


RIG_OUT = [(M['Pressures'], '/pam/pressures'), (M['JointMeasurement'], '/pam/joint_measured')]
DRIVER_OUT = RIG_OUT + [(M['ValveCommand'], '/pam/driver_node/applied_command')]
LOOP_OUT = RIG_OUT + [(M['JointEstimate'], '/pam/estimate'),
                      (M['ValveCommand'], '/pam/valve_command'),
                      (M['ControllerState'], '/pam/controller_state')]


GROUPS = {g.name: g for g in [
    Group('ukf', {'ukf_node': NodeSpec('ukf_node', 'pam_estimator', (), 'ukf_node',
                                       answered_ping(ukf_ping, both(
                                           received_since('/pam/estimate'),
                                           diag_since('ukf_node', 'valve commands received'))))},
          [(M['JointEstimate'], '/pam/estimate')], ukf_io, ('ukf_node',),
          feed_loss('ukf_node', estimates_of)),
    Group('pi', {'pi_node': NodeSpec('pi_node', 'pam_controller', (), 'pi_node',
                                     answered_ping(pi_ping, received_since(
                                         '/pam/valve_command')))},
          [(M['ValveCommand'], '/pam/valve_command'),
           (M['ControllerState'], '/pam/controller_state')], pi_io, ('pi_node',),
          feed_loss('pi_node', commands_of)),
    Group('sim', {'sim_node': NodeSpec('sim_node', 'pam_driver', ros('timing:=lockstep'),
                                       'sim_node', answered_ping(lockstep_ping, diag_since(
                                           'sim_node', 'commands received')))},
          RIG_OUT, commands_io, ('sim_node',)),
    Group('driver', {'pam-emulator': emulator('--initial-command', '5.5', '5.5'),
                     'driver_node': driver('watchdog_timeout:=0.0', ping=True)},
          DRIVER_OUT, commands_io, ('driver_node',)),
    Group('serial', {'ukf_node': NodeSpec('ukf_node', 'pam_estimator', (), 'ukf_node'),
                     'driver_node': driver('watchdog_timeout:=0.0', streams=False)},
          [*DRIVER_OUT, (M['JointEstimate'], '/pam/estimate')], commands_io,
          ('driver_node', 'ukf_node'), serial_loss),
    Group('loop_sim', {'sim_node': NodeSpec('sim_node', 'pam_driver', (), 'sim_node'),
                       'ukf_node': NodeSpec('ukf_node', 'pam_estimator', (), 'ukf_node'),
                       'pi_node': NodeSpec('pi_node', 'pam_controller', (), 'pi_node')},
          LOOP_OUT, None, ('sim_node', 'ukf_node', 'pi_node')),
    Group('loop_driver', {'pam-emulator': emulator('--initial-command', '5.5', '5.5'),
                          'driver_node': driver('watchdog_timeout:=0.3'),
                          'ukf_node': NodeSpec('ukf_node', 'pam_estimator', (), 'ukf_node'),
                          'pi_node': NodeSpec('pi_node', 'pam_controller', (), 'pi_node')},
          [*LOOP_OUT, (M['ValveCommand'], '/pam/driver_node/applied_command')], None,
          ('driver_node', 'ukf_node', 'pi_node')),
    Group('record', {'sim_node': NodeSpec('sim_node', 'pam_driver', (), 'sim_node'),
                     'bag_record': NodeSpec('bag_record', 'pam_driver',
                                            ros('output:=recorded'))},
          RIG_OUT, None, ('sim_node',)),
    Group('replay', {'ukf_node': NodeSpec('ukf_node', 'pam_estimator', (), 'ukf_node',
                                          answered_ping(ukf_ping, received_since(
                                              '/pam/estimate')))},
          [(M['JointEstimate'], '/pam/estimate')], lambda stack: ukf_io(stack, counted=False),
          ('ukf_node',), replay_loss),
    Group('bags'),
    Group('params_files'),
    Group('startup'),
]}


# ============================================================================ the table
def pressures(value, n=20):
    return [value] * n


def bad_params(node: str, *changes):
    return set_parameters(node, changes)


UKF, PI, SIM, DRV = 'ukf_node', 'pi_node', 'sim_node', 'driver_node'
ANGLE, TORQUE = 0, 1
ANSWERED_UKF = every_answer(UKF, estimates_of, 'samples estimated')
ANSWERED_PI = every_answer(PI, commands_of, 'estimates answered')
PF = MALFORMED_PARAMS_FILES

CASES = [
    # --- ukf_node: the probe is the rig (numbered, stamped pressures) -------------------------
    Case('ukf.good', 'ukf', '200 good samples at 1 kHz', 'an estimate per sample',
         feed_values('pressures', pressures(None, 200)), ANSWERED_UKF),
    Case('ukf.p1_nan', 'ukf', '20 samples p1 = NaN', 'estimated (update skipped), counted as '
         'rejected', feed_values('pressures', pressures((NAN, 4.5e5))),
         all_of(ANSWERED_UKF, rises(UKF, 'rejected samples (invalid)', 20))),
    Case('ukf.p2_inf', 'ukf', '20 samples p2 = +inf, 20 p1 = -inf', 'estimated (update '
         'skipped), counted', feed_values('pressures', pressures((4.5e5, INF)) +
                                          pressures((-INF, 4.5e5))),
         all_of(ANSWERED_UKF, rises(UKF, 'rejected samples (invalid)', 40))),
    Case('ukf.huge', 'ukf', '20 samples p1 = p2 = 1e300 Pa', 'estimated (update skipped: above '
         'pressure_max), counted', feed_values('pressures', pressures((HUGE, HUGE))),
         all_of(ANSWERED_UKF, rises(UKF, 'rejected samples (invalid)', 20))),
    Case('ukf.negative', 'ukf', '20 samples p1 = -1e5 Pa, 20 p2 = 0 Pa', 'estimated (update '
         'skipped: below pressure_min), counted',
         feed_values('pressures', pressures((-1e5, 4.5e5)) + pressures((4.5e5, 0.0))),
         all_of(ANSWERED_UKF, rises(UKF, 'rejected samples (invalid)', 40))),
    Case('ukf.stamps_past', 'ukf', '20 samples stamped 10 s in the past', 'filter reset (time '
         'went backwards), counted; estimated', feed_values('pressures', pressures(None),
                                                            'past'),
         all_of(ANSWERED_UKF, rises(UKF, 'resets on time going backwards', 1))),
    Case('ukf.stamps_decreasing', 'ukf', '20 samples, each stamped 1 ms before the previous',
         'a reset per step back, counted; estimated',
         feed_values('pressures', pressures(None), 'decreasing'),
         all_of(ANSWERED_UKF, rises(UKF, 'resets on time going backwards', 20))),
    Case('ukf.stamps_zero', 'ukf', '20 samples stamped 0', 'one reset, then duplicates (last '
         'estimate repeated), counted', feed_values('pressures', pressures(None), 'zero'),
         all_of(ANSWERED_UKF, rises(UKF, 'resets on time going backwards', 1),
                rises(UKF, 'duplicate samples (estimate repeated)', 19))),
    Case('ukf.command_nonfinite', 'ukf', 'valve_command NaN, +inf, -inf V, then 20 samples',
         'commands sanitised (0 V), counted; estimates finite',
         feed_values('pressures', pressures(None), before=commands_to(
             'commands', [(NAN, 5.5), (5.5, INF), (-INF, -INF), (5.5, 5.5)])),
         all_of(ANSWERED_UKF, rises(UKF, 'bad valve commands', 3, 3))),
    Case('ukf.command_range', 'ukf', 'valve_command 1e300, -5, 11 V, then 20 samples',
         'commands clipped to [0, 10] V, counted',
         feed_values('pressures', pressures(None), before=commands_to(
             'commands', [(HUGE, 5.5), (5.5, -5.0), (11.0, 5.5), (5.5, 5.5)])),
         all_of(ANSWERED_UKF, rises(UKF, 'bad valve commands', 3, 3))),
    Case('ukf.burst', 'ukf', '5000 samples back to back (no pause)', 'every sample estimated '
         "or its loss on /diagnostics ('samples lost')",
         feed_values('pressures', pressures(None, 5000), period=0.0),
         ANSWERED_UKF),
    Case('ukf.params', 'ukf', 'run-time set: pressure_min NaN, nis_gate -1, joint_mode '
         "'bogus', tuning 5 (integer), no_such_name 1.0", 'each refused with a reason (read-only '
         'or unknown), value unchanged',
         bad_params(UKF, ('pressure_min', NAN), ('nis_gate', -1.0), ('joint_mode', 'bogus'),
                    ('tuning', 5), ('no_such_name', 1.0)), refused),

    # --- pi_node: the probe is the estimator and the reference -----------------------------
    Case('pi.good', 'pi', '200 good estimates at 1 kHz', 'a command per estimate',
         feed_values('estimates', [0.0] * 200), ANSWERED_PI),
    Case('pi.estimate_nan', 'pi', '20 estimates angle = NaN', 'finite commands, counted as '
         'non-finite feedback', feed_values('estimates', [NAN] * 20),
         all_of(ANSWERED_PI, rises(PI, 'non-finite feedback', 20))),
    Case('pi.estimate_inf', 'pi', '10 estimates angle = +inf, 10 = -inf', 'finite commands, '
         'counted', feed_values('estimates', [INF] * 10 + [-INF] * 10),
         all_of(ANSWERED_PI, rises(PI, 'non-finite feedback', 20))),
    Case('pi.estimate_huge', 'pi', '20 estimates angle = 1e300 rad', 'finite commands '
         '(saturated)', feed_values('estimates', [HUGE] * 20), ANSWERED_PI),
    Case('pi.torque_nan', 'pi', 'reference TORQUE 1 N m, 20 estimates torque = NaN',
         'finite commands, counted', feed_values('estimates', [NAN] * 20,
                                                 before=reference(TORQUE, 1.0)),
         all_of(ANSWERED_PI, rises(PI, 'non-finite feedback', 20))),
    Case('pi.reference_nan', 'pi', 'reference ANGLE NaN, then 20 estimates', 'reference '
         'refused; finite commands', feed_values('estimates', [0.0] * 20,
                                                 before=reference(ANGLE, NAN)),
         all_of(ANSWERED_PI, diag_is(PI, 'reference', lambda v: math.isfinite(float(v))))),
    Case('pi.reference_inf', 'pi', 'reference ANGLE +inf, then -inf, then 20 estimates',
         'reference refused or clamped to the envelope; finite commands',
         feed_values('estimates', [0.0] * 20, before=lambda ctx: (
             reference(ANGLE, INF)(ctx), reference(ANGLE, -INF)(ctx))),
         all_of(ANSWERED_PI, diag_is(PI, 'reference', lambda v: math.isfinite(float(v))))),
    Case('pi.reference_huge', 'pi', 'reference ANGLE 1e308 rad, then 20 estimates', 'reference '
         'clamped to the envelope; finite commands',
         feed_values('estimates', [0.0] * 20, before=reference(ANGLE, 1e308)),
         all_of(ANSWERED_PI, diag_is(PI, 'reference', lambda v: abs(float(v)) <= 1.0))),
    Case('pi.reference_mode', 'pi', 'reference mode 7 (no such mode), then 20 estimates',
         'reference refused; finite commands',
         feed_values('estimates', [0.0] * 20, before=lambda ctx: (
             reference(ANGLE, 0.0)(ctx), time.sleep(0.05), reference(7, 0.1)(ctx))),
         all_of(ANSWERED_PI, diag_is(PI, 'mode', lambda v: v == 'angle'))),
    Case('pi.stamps_past', 'pi', '20 estimates stamped 10 s in the past', 'answered; the '
         'step back does not update the integral (counted as implausible dt)',
         feed_values('estimates', [0.0] * 20, 'past'),
         all_of(ANSWERED_PI, rises(PI, 'implausible dt (skipped)', 1))),
    Case('pi.stamps_decreasing', 'pi', '20 estimates, each stamped 1 ms before the previous',
         'answered; no integral update on a step back, counted',
         feed_values('estimates', [0.0] * 20, 'decreasing'),
         all_of(ANSWERED_PI, rises(PI, 'implausible dt (skipped)', 19))),
    Case('pi.stamps_zero', 'pi', '20 estimates stamped 0', 'answered; dt 0 does not update the '
         'integral, counted', feed_values('estimates', [0.0] * 20, 'zero'),
         all_of(ANSWERED_PI, rises(PI, 'implausible dt (skipped)', 19))),
    Case('pi.burst', 'pi', '5000 estimates back to back (no pause)', 'a command per estimate '
         "or the loss on /diagnostics ('samples lost')",
         feed_values('estimates', [0.0] * 5000, period=0.0),
         ANSWERED_PI),
    Case('pi.params_nonfinite', 'pi', 'run-time set: kp_angle NaN, ki_angle +inf, beta NaN, '
         'u_max -inf', 'each refused with a reason, value unchanged',
         bad_params(PI, ('kp_angle', NAN), ('ki_angle', INF), ('beta', NAN), ('u_max', -INF)),
         refused),
    Case('pi.params_range', 'pi', 'run-time set: kp_angle -1, kp_angle 1e9, tracking_time 0, '
         'beta 11', 'each refused with a reason, value unchanged',
         bad_params(PI, ('kp_angle', -1.0), ('kp_angle', 1e9), ('tracking_time', 0.0),
                    ('beta', 11.0)), refused),
    Case('pi.params_type', 'pi', "run-time set: kp_angle 'abc', kp_angle 30 (integer), "
         'anti_windup 5, ki_torque true', 'each refused with a reason, value unchanged',
         bad_params(PI, ('kp_angle', 'abc'), ('kp_angle', 30), ('anti_windup', 5),
                    ('ki_torque', True)), refused),
    Case('pi.params_limits', 'pi', "run-time set: u_min 9 (beta 5.5 below it), u_max 2, "
         "anti_windup 'bogus'", 'each refused with a reason, value unchanged',
         bad_params(PI, ('u_min', 9.0), ('u_max', 2.0), ('anti_windup', 'bogus')), refused),
    Case('pi.params_names', 'pi', 'run-time set: kp_anglee (unknown), mode, feedback, '
         'dt_max (read-only)', 'each refused with a reason, value unchanged',
         bad_params(PI, ('kp_anglee', 30.0), ('mode', 'torque'), ('feedback', 'measured'),
                    ('dt_max', 1.0)), refused),
    Case('pi.params_valid', 'pi', 'run-time set: kp_angle 30, then 40 again; 20 estimates',
         'accepted, read back; finite commands',
         set_parameters(PI, [('kp_angle', 30.0), ('kp_angle', 40.0)],
                        then=feed_values('estimates', [0.0] * 20)),
         all_of(accepted, ANSWERED_PI)),

    # --- sim_node, lockstep: the probe is the controller -----------------------------------
    Case('sim.good', 'sim', '50 commands (5.5, 5.5) V for the current step', 'a step each',
         lockstep([(5.5, 5.5)] * 50), stepped(50)),
    Case('sim.command_nan', 'sim', '10 commands u1 = NaN', 'a step each, u1 vented (0 V), '
         'counted', lockstep([(NAN, 5.5)] * 10),
         all_of(stepped(10), rises(SIM, 'non-finite commands', 10))),
    Case('sim.command_inf', 'sim', '10 commands u2 = +inf, 10 u1 = -inf', 'a step each, vented, '
         'counted', lockstep([(5.5, INF)] * 10 + [(-INF, 5.5)] * 10),
         all_of(stepped(20), rises(SIM, 'non-finite commands', 20))),
    Case('sim.command_range', 'sim', '10 commands 1e300 V, 10 at -5 V', 'a step each, clipped '
         'to [0, 10] V, counted', lockstep([(HUGE, 5.5)] * 10 + [(5.5, -5.0)] * 10),
         all_of(stepped(20), rises(SIM, 'out-of-range commands', 20))),
    Case('sim.stamps_zero', 'sim', '10 commands stamped 0', 'a step each (0: for the current '
         'step)', lockstep([(5.5, 5.5)] * 10, 'zero'), stepped(10)),
    Case('sim.stamps_past', 'sim', '10 commands stamped for the step before (t_k - 1 ms)',
         'ignored '
         '(no step), counted', lockstep([(5.5, 5.5)] * 10, 'past'),
         all_of(stepped(0), rises(SIM, 'past commands ignored', 10))),
    Case('sim.stamps_decreasing', 'sim', 'a command for the current step, then 10 stamped 1, 2, '
         '... ms before it', 'one step; the 10 ignored, counted', lockstep_decreasing(10),
         all_of(stepped(1), rises(SIM, 'past commands ignored', 10))),
    Case('sim.params', 'sim', "run-time set: rate NaN, timing 'bogus', seed -1, "
         'no_such_name 1.0', 'each refused with a reason (read-only or unknown)',
         bad_params(SIM, ('rate', NAN), ('timing', 'bogus'), ('seed', -1), ('no_such_name', 1.0)),
         refused),

    # --- driver_node + pam-emulator: the probe is the controller ---------------------------
    Case('driver.good', 'driver', '50 commands (4, 6) V', 'applied',
         driver_commands([(4.0, 6.0)] * 50), all_of(applied(4.0, 6.0),
                                                    rises(DRV, 'commands received', 50))),
    Case('driver.command_nonfinite', 'driver', '10 commands u1 = NaN, 10 u2 = +inf, 10 -inf',
         'ignored (the valves keep (4, 6) V), counted',
         driver_commands([(NAN, 5.0)] * 10 + [(5.0, INF)] * 10 + [(-INF, -INF)] * 10),
         all_of(applied(4.0, 6.0), rises(DRV, 'non-finite commands', 30))),
    Case('driver.command_range', 'driver', '10 commands (1e300, -5) V', 'clipped to '
         'valve_limits (10, 0) V, counted', driver_commands([(HUGE, -5.0)] * 10),
         all_of(applied(10.0, 0.0), rises(DRV, 'commands clipped', 10))),
    Case('driver.stamps', 'driver', '10 commands (4, 6) V stamped 0, 10 stamped 10 s back, 10 '
         'decreasing', 'applied: driver_node does not use command stamps',
         in_turn(*(driver_commands([(4.0, 6.0)] * 10, s) for s in ('zero', 'past',
                                                                  'decreasing'))),
         all_of(applied(4.0, 6.0), rises(DRV, 'commands received', 30))),
    Case('driver.params', 'driver', 'run-time set: watchdog_timeout NaN, port 5, '
         'safe_output [NaN, 0], no_such_name 1.0', 'each refused with a reason',
         bad_params(DRV, ('watchdog_timeout', NAN), ('port', 5), ('safe_output', [NAN, 0.0]),
                    ('no_such_name', 1.0)), refused),

    # --- serial faults: a pam-emulator per case, driver_node and ukf_node running on -------
    Case('serial.garbage', 'serial', 'garbage bytes between frames every 20 ms', 'counted '
         '(garbage bytes); samples stream on', board(('--garbage-every', '0.02'), observe(3.0)),
         all_of(rises(DRV, 'garbage bytes', 1), streams_on(2000))),
    Case('serial.corrupt', 'serial', 'a byte of a sample frame flipped every 20 ms', 'CRC errors '
         'counted, the frames lost reported', board(('--corrupt-every', '0.02'), observe(3.0)),
         all_of(rises(DRV, 'crc errors', 100), rises(DRV, 'lost frames', 100))),
    Case('serial.drop', 'serial', 'a sample frame left out every 20 ms', 'sequence gaps counted '
         'as lost frames', board(('--drop-every', '0.02'), observe(3.0)),
         rises(DRV, 'lost frames', 100)),
    Case('serial.replug', 'serial', 'unplugged 3 s after the handshake, replugged 1 s later (a '
         'new pty)', 'disconnect and reconnect counted; samples again after',
         board(('--disconnect-at', '3.0', '--disconnect-for', '1.0'),
               wait_diag(DRV, lambda v, b: number(v, 'reconnects', 0) >= number(
                   b, 'reconnects', 0) + 2 and v.get('connected') == 'true', 15.0)),
         all_of(rises(DRV, 'disconnects', 1), rises(DRV, 'reconnects', 2), streams_on(500))),
    Case('serial.board_watchdog', 'serial', 'board watchdog 5 ms, commands every 20 ms',
         "the board's vents reported on /diagnostics (ERROR while armed)",
         board(('--device-watchdog', '0.005'), commanding(3.0, 0.02)),
         all_of(rises(DRV, 'board vents', 10), status_seen(DRV, 2, 'board vented'))),
    Case('serial.stuck_sensor', 'serial', 'p1 ADC frozen 1 s after the handshake', 'sensor '
         'fault: safe output, reported',
         board(('--stuck-sensor', 'p1', '--stuck-at', '1.0'),
               wait_diag(DRV, lambda v, b: v.get('sensor fault', 'none') != 'none', 10.0)),
         all_of(diag_is(DRV, 'sensor fault', lambda v: v not in ('none', '(missing)')),
                diag_is(DRV, 'armed', lambda v: v == 'false'))),
    Case('serial.version', 'serial', 'a board of protocol 2.0', 'refused at the handshake, '
         'reported (ERROR); the node runs on',
         board(('--protocol-version', '2.0'), observe(1.0),
               ready=lambda ctx: ctx.stack.values(DRV, ctx.t0).get('device refused', 'none')
               != 'none'),
         all_of(status_seen(DRV, 2, 'protocol version mismatch'), alive('driver_node'))),
    Case('serial.unplugged', 'serial', 'the board process killed (unplugged, never back)',
         'device lost reported (ERROR), safe; the node runs on, retrying',
         board((), kill_board(2.5)),
         all_of(diag_is(DRV, 'connected', lambda v: v == 'false'),
                level_at_least(DRV, 2), alive('driver_node', 'ukf_node'))),

    # --- processes killed mid-run ----------------------------------------------------------
    Case('kill.ukf_node', 'loop_sim', 'SIGKILL of ukf_node in the closed loop on sim_node',
         'pi_node sends safe_command (5.5, 5.5) V within feedback_timeout (0.1 s)',
         kill('ukf_node', before=loop_running),
         all_of(safe_within('/pam/valve_command', (5.5, 5.5), 0.1 + SAFE_SLACK,
                            'pi_node safe_command'), alive('sim_node', 'pi_node'))),
    Case('kill.pi_node_sim', 'loop_sim', 'SIGKILL of pi_node in the closed loop on sim_node',
         'sim_node holds the last command (it has no command watchdog) and runs on',
         kill('pi_node', before=loop_running),
         all_of(alive('sim_node', 'ukf_node'), rises(SIM, 'samples published', 500))),
    Case('kill.sim_node', 'loop_sim', 'SIGKILL of sim_node in the closed loop',
         'ukf_node reports its input stale; pi_node sends safe_command within 0.1 s',
         kill('sim_node', before=loop_running),
         all_of(level_at_least(UKF, 1), safe_within('/pam/valve_command', (5.5, 5.5),
                                                    0.1 + SAFE_SLACK, 'pi_node safe_command'),
                alive('ukf_node', 'pi_node'))),
    Case('kill.pi_node_driver', 'loop_driver', 'SIGKILL of pi_node in the closed loop on '
         'driver_node (watchdog 0.3 s)', 'driver_node applies safe_output (0, 0) V within its '
         'watchdog', kill('pi_node', before=arm_driver),
         all_of(safe_within('/pam/driver_node/applied_command', (0.0, 0.0), 0.3 + SAFE_SLACK,
                            'driver_node safe_output'),
                diag_is(DRV, 'safe reason', lambda v: 'watchdog' in v),
                alive('driver_node', 'ukf_node'))),
    Case('kill.sigint_importing', 'startup', 'SIGINT to every node and batch tool during its '
         'imports (Ctrl-C at start-up)', 'exit 130 at once, nothing printed',
         stopped_while_importing(signal.SIGINT), quiet_exits),
    Case('kill.sigterm_importing', 'startup', 'SIGTERM to every node and batch tool during its '
         'imports (pam-bringup stopping a node not started yet)', 'exit 143 at once, nothing '
         'printed', stopped_while_importing(signal.SIGTERM), quiet_exits),
    Case('kill.bag_record', 'record', 'SIGKILL of bag_record after 3 s of recording',
         'pam-bag-recover rebuilds the bag (exit 0), pam-bag-info reads it',
         kill_recorder, tools_answer({'recover': 0, 'info (recovered)': 0})),

    # --- bags: a reference bag replayed into a live node; damaged copies through every tool -
    Case('bag.replay', 'replay', 'bag_play bags/closed_mild_angle (/pam/pressures, '
         '/pam/valve_command, 12 s) into ukf_node', 'an estimate per recorded sample, or the '
         'loss reported', replay('closed_mild_angle', '/pam/pressures,/pam/valve_command'),
         replay_estimated),
    Case('bag.intact', 'bags', 'closed_mild_angle as shipped (the baseline)', 'info, play, '
         'evaluate: exit 0; identify: exit 2 (not calibration runs); recover: exit 2 (needs '
         'no recovery)', damaged_bag('closed_mild_angle'),
         tools_answer({'info': 0, 'play': 0, 'evaluate': 0, 'identify': 2, 'recover': 2,
                       'info (recovered)': 0}, naming=False)),
    Case('bag.chunk_flipped', 'bags', 'closed_mild_angle, 16 bytes flipped in a chunk '
         '(zstd fails)', 'info, play, evaluate, identify: exit 2 naming the file; recover: '
         'exit 0, then info reads it', damaged_bag('closed_mild_angle', flip_in_chunk),
         tools_answer({**{r: 2 for r in READERS}, 'recover': 0, 'info (recovered)': 0})),
    Case('bag.chunk_crc', 'bags', 'closed_mild_angle, 8 bytes flipped in a chunk so that zstd '
         'still decompresses it (only its CRC tells)', 'exit 2 naming the file; recover: exit '
         '0, then info reads it', damaged_bag('closed_mild_angle', flip_unnoticed),
         tools_answer({**{r: 2 for r in READERS}, 'recover': 0, 'info (recovered)': 0})),
    Case('bag.truncated', 'bags', 'closed_mild_angle cut at 60 % (mid-chunk, no summary)',
         'exit 2 naming the file; recover: exit 0, then info reads it',
         damaged_bag('closed_mild_angle', truncate),
         tools_answer({**{r: 2 for r in READERS}, 'recover': 0, 'info (recovered)': 0})),
    Case('bag.split_file_missing', 'bags', 'validation_mild_locked without its 2nd file',
         'exit 2 naming the missing file; recover: rebuilds the rest, exit 2 naming what is '
         'lost; then info reads it', damaged_bag('validation_mild_locked', remove_split_file),
         tools_answer({**{r: 2 for r in READERS}, 'recover': 2, 'info (recovered)': 0})),
    Case('bag.no_metadata', 'bags', 'closed_mild_angle without metadata.yaml', 'exit 2 naming '
         'the repair; recover: exit 0, then info reads it',
         damaged_bag('closed_mild_angle', remove_metadata),
         tools_answer({**{r: 2 for r in READERS}, 'recover': 0, 'info (recovered)': 0})),

    # --- malformed params files to every node and pam-bringup ------------------------------
    *[Case(f'params_file.{kind}', 'params_files', f'params file: {kind}',
           'every node and pam-bringup: exit 2, one line naming the file' +
           ('' if PF[kind][1] is None else ' and the line'),
           params_file_to_all(kind), params_file_refused) for kind in PF],
    Case('params.start_nan', 'params_files', 'every node started with a double parameter '
         '-p NAME:=nan', 'exit 2, one line naming the parameter', start_with_bad_value('nan'),
         bad_value_refused),
    Case('params.start_huge', 'params_files', 'every node started with a double parameter '
         '-p NAME:=1e300', 'exit 2, one line naming the parameter',
         start_with_bad_value('1e300'), bad_value_refused),
    Case('params.start_type', 'params_files', "every node started with a double parameter "
         "-p NAME:=abc", 'exit 2, one line naming the parameter', start_with_bad_value('abc'),
         bad_value_refused),
    Case('params_file.unknown_name', 'params_files', 'params file setting no_such_parameter',
         'every node warns, naming it', unknown_name_in_every_node, unknown_name_warned),
]


# ============================================================================ running
class GroupRun:
    """A group's stack (started on the first case, restarted where a case killed a node)."""

    def __init__(self, group: Group, context, domain: int, folder: Path):
        self.group = group
        self.domain = domain
        self.folder = new_folder(folder, group.name)
        self.stack = None
        self.io = {}
        if group.nodes:
            probe = Probe(context, f'fault_probe_{group.name}')
            self.stack = Stack(probe, domain, self.folder, group.nodes, group.outputs)
            self.io = self.stack.io = group.inputs(self.stack) if group.inputs else {}

    def close(self):
        if self.stack is not None:
            self.stack.close()
            self.stack.probe.close()


def run_case(run: GroupRun, case: Case) -> Row:
    """One case: (re)start what is missing of the group's stack (a process that died since the
    last case is this case's death; what comes out of a start-up is counted too), act, judge."""
    window = time.monotonic()
    tracebacks0 = run.stack.tracebacks() if run.stack else 0
    deaths = run.stack.deaths() if run.stack else []
    if run.stack is not None:
        run.stack.ensure()
        time.sleep(0.3)
    ctx = Ctx(run)
    try:
        facts = case.act(ctx) or {}
        ctx.t_acted = time.monotonic()
        verdict = case.check(ctx, facts)
        lost = run.group.loss(ctx, facts) if run.group.loss else '-'
    except Exception as exc:  # noqa: BLE001 - a harness problem fails the case, not the run
        verdict, lost = Verdict(False, f'harness error: {type(exc).__name__}: {exc}'[:300]), '-'
    deaths += run.stack.deaths() if run.stack else []
    deaths += [f'{t.argv[0]} ({"hung" if t.code is None else t.code})' for t in ctx.tools
               if t.died]
    deaths += [f'{p.name} (exit {p.proc.returncode})' for p in ctx.procs
               if not p.alive() and p.proc.returncode not in (0, 2) and id(p) not in ctx.killed]
    tracebacks = (run.stack.tracebacks() - tracebacks0 if run.stack else 0) + \
        sum(t.tracebacks for t in ctx.tools) + \
        sum(traceback_count(p.stderr + p.stdout) for p in ctx.procs)
    if VERBOSE and (not verdict.ok or deaths or tracebacks):
        outputs = [(' '.join(t.argv), t.stderr) for t in ctx.tools]
        outputs += [(p.name, p.stderr) for p in ctx.procs]
        if run.stack:
            outputs += [(n, p.stderr) for n, p in run.stack.procs.items()]
        for name, err in outputs:
            print(f'--- {case.name}: {name}\n{err[-1500:]}', file=sys.stderr)
    for p in ctx.procs:
        p.close()
    non_finite = run.stack.watch.between(window, time.monotonic()) if run.stack else []
    return Row(case, verdict, deaths, non_finite, lost, tracebacks)


def cell(text) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def print_table(rows: list[Row]) -> bool:
    print('| case | expected | observed | deaths | non-finite | lost unreported | tracebacks |')
    print('| --- | --- | --- | ---: | ---: | ---: | ---: |')
    for r in rows:
        mark = 'ok' if r.verdict.ok else 'FAIL'
        observed = f'{mark}: {r.verdict.observed}'
        if r.deaths:
            observed += '; died: ' + ', '.join(r.deaths)
        if r.non_finite:
            first = r.non_finite[0]
            observed += f'; non-finite e.g. {first.topic} {first.field} = {first.value}'
        print(f'| `{r.case.name}` {cell(r.case.given)} | {cell(r.case.expected)} | '
              f'{cell(observed)} | {len(r.deaths)} | {len(r.non_finite)} | {r.lost} | '
              f'{r.tracebacks} |')
    totals = (sum(len(r.deaths) for r in rows), sum(len(r.non_finite) for r in rows),
              sum(r.lost for r in rows if isinstance(r.lost, int)),
              sum(r.tracebacks for r in rows))
    failed = [r.case.name for r in rows if not r.verdict.ok]
    print(f'| **total** ({len(rows)} cases, {len(rows) - len(failed)} as expected) | | | '
          f'{totals[0]} | {totals[1]} | {totals[2]} | {totals[3]} |')
    if failed:
        print(f'\nnot as expected: {", ".join(failed)}')
    fields: dict[str, int] = {}
    for hit in (h for r in rows for h in r.non_finite):
        where = f'{hit.topic} {hit.field} = {hit.value}'
        fields[where] = fields.get(where, 0) + 1
    if fields:
        print('\nnon-finite values received, by field:')
        for where, n in sorted(fields.items(), key=lambda item: -item[1]):
            print(f'  {n:5d}  {where}')
    return not failed and totals == (0, 0, 0, 0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--only', metavar='PATTERN',
                        help='run the cases whose name or group matches this regular expression')
    parser.add_argument('--list', action='store_true', help='list the cases and exit')
    parser.add_argument('--verbose', action='store_true',
                        help="print the end of every process's stderr of a failed case")
    args = parser.parse_args(argv)
    global VERBOSE
    VERBOSE = args.verbose
    cases = [c for c in CASES if not args.only or re.search(args.only, c.name)
             or re.search(args.only, c.group)]
    if args.list:
        for c in cases:
            print(f'{c.name:28s} [{c.group}] {c.given} -> {c.expected}')
        return 0
    if not cases:
        parser.error(f'no case matches {args.only!r}')
    domain = campaign_domain()
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    rows: list[Row] = []
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix='fault_campaign_') as tmp:
        try:
            for name in dict.fromkeys(c.group for c in cases):
                group_start = time.monotonic()
                run = None
                try:
                    run = GroupRun(GROUPS[name], context, domain, Path(tmp))
                    for case in (c for c in cases if c.group == name):
                        rows.append(run_case(run, case))
                except Exception as exc:  # noqa: BLE001 - e.g. a stack that never came up
                    done = {r.case.name for r in rows}
                    for case in (c for c in cases if c.group == name and c.name not in done):
                        rows.append(Row(case, Verdict(False, f'group {name} failed: {exc}'[:300]),
                                        [], [], '-', 0))
                finally:
                    if run is not None:
                        run.close()
                print(f'[{name}: {time.monotonic() - group_start:.0f} s]', file=sys.stderr,
                      flush=True)
        finally:
            context.try_shutdown()
    print(f'Fault campaign: {len(rows)} cases in {time.monotonic() - start:.0f} s, '
          f'ROS_DOMAIN_ID {domain}\n')
    return 0 if print_table(rows) else 1


if __name__ == '__main__':
    sys.exit(main())
