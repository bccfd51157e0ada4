"""Actions of the fault campaign (benchmarks/fault_campaign.py): each does one case's inputs
to the group's stack or to command-line tools (act(ctx) -> facts for its check): numbered feeds,
valve commands, references, run-time parameter changes, kills, a pam-emulator with a fault,
damaged bags through every bag tool, params files and signals to every node. Factories take the
case's parameters and return act(ctx).
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

from fault_inputs import Feed, Parameters, command_message, copy_bag, lockstep_command
from fault_stack import maps_holds, run_tool
from pam_common.sample_gaps import SampleGaps
from pam_common.stamps import stamp_ns
from pam_common.testing import NodeProcess, malformed_params_file, wait_until

BAGS = Path(__file__).resolve().parents[1] / 'bags'


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
    runs = {'recover': ctx.tool('pam-bag-recover', 'pam_bag', bag)}
    runs['info (recovered)'] = ctx.tool('pam-bag-info', 'pam_bag', bag)
    return {'runs': runs, 'bag_name': 'recorded'}


# --- bags
READERS = ('info', 'play', 'evaluate', 'identify')


def bag_tools(ctx, bag: Path) -> dict:
    """Every bag tool on `bag`: pam-bag-info, bag_play, pam-evaluate, pam-identify; then
    pam-bag-recover and pam-bag-info on what it rebuilt."""
    runs = {'info': ctx.tool('pam-bag-info', 'pam_bag', bag),
            'play': ctx.tool('bag_play', 'pam_bag', '--ros-args', '-p', f'bag:={bag}',
                             '-p', 'rate:=50.0', '-p', 'delay:=0.0'),
            'evaluate': ctx.tool('pam-evaluate', 'pam_estimator', bag),
            'identify': ctx.tool('pam-identify', 'pam_estimator', bag, '-o',
                                 ctx.folder / 'identified')}
    runs['recover'] = ctx.tool('pam-bag-recover', 'pam_bag', bag)
    runs['info (recovered)'] = ctx.tool('pam-bag-info', 'pam_bag', bag)
    return runs


def replay(source: str, topics: str):
    """bag_play bags/<source> (these topics, rate 1) into the group's ukf_node; facts: the
    recorded /pam/pressures and the gaps already in their sample counter."""
    def act(ctx):
        from pam_bag.bags import load_bag, make_typestore
        contents, gaps = load_bag(BAGS / source, ['/pam/pressures']), SampleGaps()
        counters = [msg.sample for _, msg in contents.deserialized('/pam/pressures',
                                                                   make_typestore())]
        for sample in counters:
            gaps.update(sample)
        ctx.tool('bag_play', 'pam_bag', '--ros-args', '-p', f'bag:={BAGS / source}',
                 '-p', f'topics:={topics}')
        return {'recorded': gaps.received + gaps.uncounted, 'in_bag': gaps.lost,
                'counters': (counters[0], counters[-1])}
    return act


def damaged_bag(source: str, *damages):
    """A copy of bags/<source> with each damage(bag) applied, through every bag tool."""
    def act(ctx):
        bag = copy_bag(BAGS / source, ctx.folder)
        done = [damage(bag) for damage in damages]
        return {'runs': bag_tools(ctx, bag), 'bag_name': source, 'done': done}
    return act


# --- params files
PARAMS_FILE_EXES = (('sim_node', 'pam_driver'), ('driver_node', 'pam_driver'),
                    ('profile_player', 'pam_controller'), ('bag_record', 'pam_bag'),
                    ('bag_play', 'pam_bag'), ('ukf_node', 'pam_estimator'),
                    ('pi_node', 'pam_controller'), ('reference_node', 'pam_controller'),
                    ('tracking_report', 'pam_bringup'))


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


def params_file_to_all(kind: str):
    """The malformed params file of `kind` (pam_common.testing.MALFORMED_PARAMS_FILES) to every
    node and pam-bringup, three at a time."""
    def act(ctx):
        path, line = malformed_params_file(ctx.folder, kind)
        jobs = {exe: (exe, package, '--ros-args', '--params-file', path)
                for exe, package in PARAMS_FILE_EXES}
        jobs['pam-bringup'] = ('pam-bringup', 'pam_bringup', '--params-file', path,
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
            return {'runs': {exe: f.result() for exe, f in futures.items()},
                    'params': DOUBLE_PARAM}
    return act


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
