"""pam-bringup: the whole PAM stack, composed in one process or as separate ones, from one
parameter file.

A small stand-in for `ros2 launch` (not installable with the pinned PyPI wheels): starts the
nodes of pam_bringup.stack (the rig: sim_node, or driver_node with --rig driver; ukf_node;
reference_node; pi_node), by default composed in one process (pam_container, options for the
same node list before --ros-args), with --separate each as

    <exe> --ros-args -r __ns:=<namespace> --params-file <file>

(the same standard ROS 2 params file for every node: one section per node, keyed by the node's
full name, e.g. `/pam/sim_node:`; `/**:` applies to every node). With --namespace other than
/pam the nodes get a copy of the file whose /pam sections are re-keyed to the namespace
(pam_bringup.params_namespace, in a directory of this run removed at exit); a node no section is
for is warned about (pam_bringup.params_sections). pam_bringup.supervisor runs them: each in a
process group of its own, every output line prefixed with `[node_name]` on our stdout (and, with
--log-dir, the raw line in DIR/<node>.log).

Stopping: on SIGINT / SIGTERM / SIGHUP (Ctrl-C) or at the end of --duration every child gets
SIGINT, SIGTERM after 5 s, its threads' stacks (SIGUSR1) and SIGKILL after 10 s
(pam_bringup.supervisor). A second Ctrl-C kills at once. If pam-bringup itself is killed, the
children get SIGTERM (Linux parent-death signal).

Exit code: 0 after a requested stop when every child exited cleanly (0, or ended by our SIGINT /
SIGTERM; never after a SIGKILL); 1 when a child died while running (which one, and its exit code,
is logged; the others are then stopped) or did not stop cleanly; 2 on a usage or set-up error
(missing executable; a params file missing, unreadable or malformed: one line naming the file
and the line, the check every node makes), before anything is started.

Arming the driver (--rig driver with pi_node, unless --no-arm): pam_bringup.arming calls
<namespace>/driver_node/arm once pi_node's commands flow steadily, once, at start-up.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from pam_common.params_files import ros_args_problem

from .arming import DriverArmer
from .params_namespace import StackParams, stack_params
from .stack import (
    CONTAINER,
    DEFAULT_NAMESPACE,
    RIGS,
    MissingExecutable,
    container_options,
    default_params_file,
    locate_executables,
    needs_arming,
    node_argv,
    normal_namespace,
    stack_nodes,
)
from .supervisor import Child, Output, Supervisor, child_environment

PROG = 'pam-bringup'


# ---------------------------------------------------------------------------- command line
def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=PROG,
        description='Start the PAM stack (rig, ukf_node, pi_node, reference_node), composed in '
                    'one process (pam_container) or as separate processes (--separate), from one '
                    'ROS 2 params file; prefix and forward the logs; stop everything on Ctrl-C '
                    '/ SIGTERM; exit non-zero when a process dies.',
        epilog='The params file is a standard ROS 2 one, passed to every node with '
               '`--ros-args --params-file FILE`: one section per node keyed by its full name '
               '(/pam/sim_node:, /pam/ukf_node:, /pam/pi_node:, /pam/reference_node:; '
               '/**/NAME: for any namespace; /**: for every node). A bare `sim_node:` key '
               'means /sim_node and does NOT apply under /pam. With --namespace NS the /pam '
               'sections apply to NS (the nodes get a copy of the file re-keyed to NS; a '
               'section of the file for NS itself wins). Exit codes: 0 requested stop '
               'with every node exiting cleanly, 1 a node died or did not stop cleanly, 2 usage '
               'or set-up error. Example: pam-bringup --no-controller --no-reference '
               '--duration 30 --domain-id 42 --log-dir out/logs')
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument('--composed', dest='separate', action='store_false',
                      help='(the default) every node in one process, pam_container, on one '
                           'executor: a third of the CPU of separate processes and a sample -> '
                           'command p99 of about 0.4 ms instead of 1 ms (docs/composition.md)')
    mode.add_argument('--separate', action='store_true',
                      help='every node a process of its own: a crash or a hang stays in its '
                           'process, each node gets its own log prefix and log file')
    parser.set_defaults(separate=False)
    parser.add_argument('--rig-apart', action='store_true',
                        help='composed: the rig in a process of its own (as the hardware of a '
                             'real rig is), the other nodes composed: the simulated plant and '
                             'the stack then run on two cores (docs/composition.md)')
    parser.add_argument('--links', action='store_true',
                        help='composed: the 1 kHz path between the composed nodes as function '
                             'calls (in-process links), about a quarter of the CPU; a publisher '
                             'of another process on a linked topic is then not heard '
                             '(docs/composition.md)')
    parser.add_argument('--params-file', metavar='FILE', type=Path,
                        help='ROS 2 params YAML with a section per node (default: '
                             'share/pam_bringup/config/bringup.yaml)')
    parser.add_argument('--rig', choices=sorted(RIGS), default='sim',
                        help="'sim': the simulated rig sim_node (default); 'driver': the "
                             "hardware driver driver_node (pam_driver)")
    parser.add_argument('--no-controller', action='store_true',
                        help='do not start pi_node')
    parser.add_argument('--no-reference', action='store_true',
                        help='do not start reference_node')
    parser.add_argument('--no-arm', action='store_true',
                        help='with --rig driver: do not call driver_node ~/arm once the '
                             'controller runs (default: arm it once, at start-up)')
    parser.add_argument('--duration', type=float, metavar='SECONDS',
                        help='stop everything after this long (exit 0 if every node was alive '
                             'and stopped cleanly); default: run until Ctrl-C / SIGTERM')
    parser.add_argument('--domain-id', type=int, metavar='N',
                        help='ROS_DOMAIN_ID of the nodes (default: inherited)')
    parser.add_argument('--namespace', default=DEFAULT_NAMESPACE, metavar='NS',
                        help=f'namespace of every node, -r __ns:=NS (default '
                             f'{DEFAULT_NAMESPACE}); the params file\'s {DEFAULT_NAMESPACE} '
                             'sections apply to it')
    parser.add_argument('--log-dir', type=Path, metavar='DIR',
                        help="also write each node's raw output to DIR/<node>.log")
    parser.add_argument('--no-colour', '--no-color', dest='colour', action='store_false',
                        help='no coloured prefixes (default: coloured when stdout is a terminal '
                             'and NO_COLOR is unset)')
    args = parser.parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        parser.error(f'--duration must be > 0 s, got {args.duration:g}')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        parser.error(f'--domain-id must be in 0..232, got {args.domain_id}')
    if args.separate and (args.rig_apart or args.links):
        parser.error('--rig-apart and --links are options of the composed mode, not --separate')
    try:
        args.namespace = normal_namespace(args.namespace)
    except ValueError:
        parser.error(f'--namespace {args.namespace!r} is not a valid ROS namespace')
    return args


def error(text: str) -> int:
    print(f'{PROG}: error: {text}', file=sys.stderr, flush=True)
    return 2


def main(argv=None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    nodes = stack_nodes(args.rig, reference=not args.no_reference,
                        controller=not args.no_controller)

    params_file = (args.params_file or default_params_file()).expanduser().resolve()
    # the nodes' own check (pam_common.params_files, rcl's parse included), before any start
    problem = ros_args_problem([PROG, '--ros-args', '--params-file', str(params_file)])
    if problem is not None:
        missing = not (args.params_file or params_file.exists())
        return error(problem + (' (run `make setup`, or pass --params-file)' if missing else ''))
    try:
        executables = locate_executables(
            nodes if args.separate else [nodes[0], CONTAINER] if args.rig_apart else [CONTAINER])
    except MissingExecutable as exc:
        return error(str(exc))
    with tempfile.TemporaryDirectory(prefix=f'{PROG}-') as run_dir:
        try:
            params = stack_params(params_file, args.namespace, [n.name for n in nodes],
                                  Path(run_dir))
        except ValueError as exc:
            return error(str(exc))
        return run(args, nodes, executables, params)


def run(args, nodes, executables: dict[str, str], params: StackParams) -> int:
    """Start the nodes with `params` and supervise them until the stop; the exit code."""
    log_dir = None
    if args.log_dir is not None:
        log_dir = args.log_dir.expanduser().resolve()
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            return error(f'cannot create --log-dir {log_dir}: {exc.strerror}')

    colour = args.colour and sys.stdout.isatty() and 'NO_COLOR' not in os.environ
    env = child_environment(args.domain_id, colour)
    if not args.separate:
        argv = node_argv(executables[CONTAINER.name], args.namespace, params.file)
        argv[1:1] = container_options(args.rig, reference=not args.no_reference,
                                      controller=not args.no_controller, links=args.links,
                                      with_rig=not args.rig_apart)
        composed = nodes[1:] if args.rig_apart else nodes
        children = [Child(CONTAINER.name, argv, ', '.join(n.name for n in composed))]
        if args.rig_apart:
            rig = nodes[0]
            children.insert(0, Child(rig.name, node_argv(executables[rig.name], args.namespace,
                                                         params.file), rig.role))
    else:
        children = [Child(node.name, node_argv(executables[node.name], args.namespace,
                                               params.file), node.role) for node in nodes]
    output = Output(PROG, [c.name for c in children], colour)
    supervisor = Supervisor(children, env, output, log_dir)

    output.say(f"ROS_DOMAIN_ID={env.get('ROS_DOMAIN_ID', '(unset: 0)')}, namespace "
               f"{args.namespace}, {params.describe()}"
               + (f', logs in {log_dir}' if log_dir else '')
               + (f', duration {args.duration:g} s' if args.duration else ', Ctrl-C to stop'))
    for warning in params.warnings:
        output.say(warning)

    supervisor.install_signal_handlers()
    try:
        supervisor.start()
    except (OSError, subprocess.SubprocessError) as exc:
        output.say(f'error: could not start a node: {exc}')
        supervisor.stop()
        return 1
    armer = None
    if needs_arming(args.rig, not args.no_controller) and not args.no_arm:
        armer = DriverArmer(args.namespace, args.domain_id, output)
        armer.start()   # after the children: no fork while its threads run
    try:
        return supervisor.run(args.duration, duration_name='--duration')
    finally:
        if armer is not None:
            armer.stop()


if __name__ == '__main__':
    sys.exit(main())
