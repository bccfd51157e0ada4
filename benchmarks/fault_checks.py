"""Checks of the fault campaign (benchmarks/fault_campaign.py): each judges one case from what
its action returned (facts) and what the case context saw (ctx: /diagnostics before and after,
the messages received, the stack's processes) and returns a Verdict (as expected?, what was
observed). Factories take the case's parameters and return check(ctx, facts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fault_inputs import unanswered
from pam_common.diagnostics import is_status_of
from pam_common.stamps import stamp_ns
from pam_common.testing import wait_until


@dataclass
class Verdict:
    ok: bool
    observed: str


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
        s = ctx.after_status(node)
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
        for r, g in zip(results, good, strict=True)))


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
                for s in a.status if is_status_of(s.name, node) and s.level[0] >= level
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


def replay_counts(ctx, facts) -> tuple[int, int]:
    """(recorded samples not estimated, of them the ones ukf_node reports lost on the way: its
    'samples lost' less the gaps already in the bag)."""
    missing = facts['recorded'] - len(ctx.received('/pam/estimate'))
    return missing, int(ctx.delta('ukf_node', 'samples lost')) - facts['in_bag']


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


def quiet_exits(ctx, facts):
    """Each run exited with facts['code'] and printed nothing."""
    bad = [f'{exe}: exit {run.code}, {len(run.stdout + run.stderr)} bytes of output'
           for exe, run in facts['runs'].items()
           if run.code != facts['code'] or run.stdout or run.stderr]
    n = len(facts['runs'])
    return Verdict(not bad, f"{n - len(bad)}/{n} exit {facts['code']}, silent" +
                   ('; ' + '; '.join(bad) if bad else ''))


def bad_value_refused(ctx, facts):
    """Every node exited with code 2 and one stderr line naming its parameter."""
    bad = []
    for exe, run in facts['runs'].items():
        lines, name = run.lines(), facts['params'][exe]
        if run.code != 2 or len(lines) != 1 or f"parameter '{name}'" not in lines[0]:
            bad.append(f'{exe}: exit {run.code}, {len(lines)} lines: {(lines or [""])[0][:100]}')
    n = len(facts['runs'])
    return Verdict(not bad, f'{n - len(bad)}/{n} exit 2, one line naming the parameter' +
                   ('; ' + '; '.join(bad) if bad else ''))
