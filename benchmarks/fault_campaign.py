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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from rclpy.context import Context

from fault_actions import (
    READERS,
    arm_driver,
    board,
    commanding,
    commands_to,
    damaged_bag,
    driver_commands,
    feed_values,
    in_turn,
    kill,
    kill_board,
    kill_recorder,
    lockstep,
    lockstep_decreasing,
    loop_running,
    observe,
    params_file_to_all,
    reference,
    replay,
    set_parameters,
    start_with_bad_value,
    stopped_while_importing,
    unknown_name_in_every_node,
    wait_diag,
)
from fault_checks import (
    Verdict,
    accepted,
    alive,
    all_of,
    applied,
    bad_value_refused,
    commands_of,
    diag_is,
    estimates_of,
    every_answer,
    level_at_least,
    params_file_refused,
    quiet_exits,
    refused,
    replay_counts,
    replay_estimated,
    rises,
    safe_within,
    status_seen,
    stepped,
    streams_on,
    tools_answer,
    unknown_name_warned,
)
from fault_inputs import (
    HUGE,
    INF,
    NAN,
    Feed,
    command_message,
    estimate_message,
    flip_in_chunk,
    flip_unnoticed,
    lockstep_command,
    pressures_message,
    remove_metadata,
    remove_split_file,
    truncate,
)
from fault_stack import (
    NodeSpec,
    Stack,
    Tool,
    campaign_domain,
    new_folder,
    number,
    run_tool,
    traceback_count,
)
from pam_common.sample_gaps import SampleGaps
from pam_common.testing import MALFORMED_PARAMS_FILES, NodeProcess, Probe, child_env

SETTLE = 0.3          # s after a case's inputs before the /diagnostics it is judged on
SAFE_SLACK = 0.5      # s allowed on top of a watchdog's time on a loaded machine
VERBOSE = False       # --verbose


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

    def __init__(self, run: GroupRun):
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

    def after_status(self, node: str):
        """The DiagnosticStatus of `node` after() reads its values from (None if none came)."""
        self.after(node)
        return self.stack.status(node, self.t_acted + SETTLE)

    def delta(self, node: str, key: str) -> float:
        return number(self.after(node), key) - number(self.before.get(node, {}), key, 0.0)

    def received(self, topic: str) -> list:
        return self.stack.topics[topic].since(self.t0)

    def tool(self, exe: str, package: str, *args) -> Tool:
        result = run_tool(exe, package, args, self.env, self.folder)
        self.tools.append(result)
        return result


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

    from pam_interfaces.msg import (
        ControllerState,
        JointEstimate,
        JointMeasurement,
        Pressures,
        Reference,
        ValveCommand,
    )
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


def replay_loss(ctx, facts):
    if 'recorded' not in facts:
        return '-'
    missing, reported = replay_counts(ctx, facts)
    return max(missing - reported, 0)


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
DRIVER_OUT = [*RIG_OUT, (M['ValveCommand'], '/pam/driver_node/applied_command')]
LOOP_OUT = [*RIG_OUT, (M['JointEstimate'], '/pam/estimate'),
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
                     'bag_record': NodeSpec('bag_record', 'pam_bag',
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
         tools_answer({**dict.fromkeys(READERS, 2), 'recover': 0, 'info (recovered)': 0})),
    Case('bag.chunk_crc', 'bags', 'closed_mild_angle, 8 bytes flipped in a chunk so that zstd '
         'still decompresses it (only its CRC tells)', 'exit 2 naming the file; recover: exit '
         '0, then info reads it', damaged_bag('closed_mild_angle', flip_unnoticed),
         tools_answer({**dict.fromkeys(READERS, 2), 'recover': 0, 'info (recovered)': 0})),
    Case('bag.truncated', 'bags', 'closed_mild_angle cut at 60 % (mid-chunk, no summary)',
         'exit 2 naming the file; recover: exit 0, then info reads it',
         damaged_bag('closed_mild_angle', truncate),
         tools_answer({**dict.fromkeys(READERS, 2), 'recover': 0, 'info (recovered)': 0})),
    Case('bag.split_file_missing', 'bags', 'validation_mild_locked without its 2nd file',
         'exit 2 naming the missing file; recover: rebuilds the rest, exit 2 naming what is '
         'lost; then info reads it', damaged_bag('validation_mild_locked', remove_split_file),
         tools_answer({**dict.fromkeys(READERS, 2), 'recover': 2, 'info (recovered)': 0})),
    Case('bag.no_metadata', 'bags', 'closed_mild_angle without metadata.yaml', 'exit 2 naming '
         'the repair; recover: exit 0, then info reads it',
         damaged_bag('closed_mild_angle', remove_metadata),
         tools_answer({**dict.fromkeys(READERS, 2), 'recover': 0, 'info (recovered)': 0})),

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
    global VERBOSE   # noqa: PLW0603 - set once, from --verbose, before any case runs
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
