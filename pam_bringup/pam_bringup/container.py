"""pam_container: the nodes of one or several PAM stacks composed in one process, on one executor.

Each node is the very node class its own executable runs (the node module's COMPONENT), built
with the same parameters, so its topics, parameters, services and /diagnostics are the same as
those of the separate processes; only the process is shared. What composition saves and costs:
docs/composition.md.

    pam_container --ros-args -r __ns:=/pam --params-file bringup.yaml     # the stack of pam-bringup
    pam_container --namespace /joint1 /joint2 --params-file bringup.yaml  # two stacks

--params-file FILE applies the file in every namespace as `pam-bringup --namespace` does
(pam_bringup.params_namespace: the /pam/<node> sections re-keyed, a section of the namespace's
own wins); a file given after --ros-args is passed to every node as it is.

Launch files start it as any node (no `name=`: a node-name remap would rename every node):
    Node(package='pam_bringup', executable='pam_container', namespace='pam',
         parameters=[params_file])
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
from pathlib import Path

from pam_common.executors import PUBLICATION_MODE_VARIABLE
from pam_common.links import enable_links
from pam_common.node_skeleton import Component, container_main

from .params_namespace import stack_params
from .stack import DEFAULT_NAMESPACE, RIGS, normal_namespace, stack_nodes

PROG = 'pam_container'


def split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """(the container's own options, the ROS arguments from `--ros-args` on)."""
    if '--ros-args' in argv:
        at = argv.index('--ros-args')
        return argv[:at], argv[at:]
    return argv, []


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter,
        usage=f'{PROG} [-h] [--rig {{{",".join(sorted(RIGS))}}}] [--no-reference] '
              '[--no-controller] [--no-rig] [--links] [--namespace NS [NS ...]] '
              '[--params-file FILE] [--ros-args ...]',
        description='The nodes of the PAM stack (the rig, ukf_node, reference_node, pi_node) '
                    'composed in one process on one executor: the same node classes, topics, '
                    'parameters, services and diagnostics as the separate executables. With '
                    'several --namespace values, one complete stack per namespace.',
        epilog='ROS arguments (after --ros-args) apply to every node: --params-file FILE (one '
               'section per node full name, e.g. /pam/ukf_node, or /**/ukf_node for any '
               'namespace), -p NAME:=VALUE (every node that declares NAME), -r __ns:=/NS (one '
               'stack only; with --namespace, leave it out), --log-level.\n\nExamples:\n'
               f'  {PROG} --ros-args -r __ns:=/pam --params-file bringup.yaml\n'
               f'  {PROG} --namespace /joint1 /joint2 --params-file bringup.yaml\n'
               f'  {PROG} --ros-args -r __ns:=/pam -p thread_priority:=80   # docs/realtime.md')
    p.add_argument('--rig', choices=sorted(RIGS), default='sim',
                   help='sim: sim_node, the simulated rig; driver: driver_node (default sim)')
    p.add_argument('--no-reference', action='store_true', help='without reference_node')
    p.add_argument('--no-controller', action='store_true', help='without pi_node')
    p.add_argument('--no-rig', action='store_true',
                   help='without the rig: it runs in a process of its own (pam-bringup '
                        '--rig-apart), as the hardware of a real rig does')
    p.add_argument('--links', action='store_true',
                   help='in-process links: a message between two nodes of this process is '
                        'handed to the subscriber as a function call (no DDS, no '
                        'serialisation), and published on DDS only for other processes; '
                        'a publisher of another process on a linked topic is then not heard '
                        '(pam_common.links, docs/composition.md)')
    p.add_argument('--namespace', nargs='+', metavar='NS', default=[],
                   help='one stack per namespace (default: one stack, in /pam unless the ROS '
                        'arguments remap __ns)')
    p.add_argument('--params-file', type=Path, metavar='FILE',
                   help="the stack's params file, applied in each namespace as pam-bringup "
                        'does (its /pam/<node> sections re-keyed to the namespace)')
    return p


def component(package: str, name: str) -> Component:
    """The COMPONENT of node module <package>.<name> (e.g. pam_estimator.ukf_node)."""
    return importlib.import_module(f'{package}.{name}').COMPONENT


def main(argv=None) -> int:
    ours, ros_args = split_ros_args(list(sys.argv[1:] if argv is None else argv))
    p = parser()
    args = p.parse_args(ours)
    try:
        namespaces = [normal_namespace(ns) for ns in args.namespace]
    except ValueError as exc:
        p.error(f'--namespace: {exc}')
    if len(set(namespaces)) != len(namespaces):
        p.error('--namespace: a namespace is given twice')
    if namespaces and any('__ns:=' in a for a in ros_args):
        p.error('-r __ns:= and --namespace both set the namespace: use one of them')
    specs = stack_nodes(args.rig, reference=not args.no_reference,
                        controller=not args.no_controller, with_rig=not args.no_rig)
    remapped = [a.split(':=', 1)[1] for a in ros_args if a.startswith('__ns:=')]
    links = enable_links() if args.links else None
    with tempfile.TemporaryDirectory(prefix=f'{PROG}-') as run_dir:
        components, node_kwargs = [], []
        for ns in namespaces or [None]:
            kwargs = {} if ns is None else {'namespace': ns}
            if args.params_file is not None:
                try:
                    params = stack_params(args.params_file.expanduser(),
                                          ns or (remapped[-1] if remapped else DEFAULT_NAMESPACE),
                                          [spec.name for spec in specs], Path(run_dir))
                except ValueError as exc:
                    print(f'{PROG}: error: {exc}', file=sys.stderr)
                    return 2
                for warning in params.warnings:
                    print(f'{PROG}: {warning}', file=sys.stderr)
                kwargs['cli_args'] = ['--ros-args', '--params-file', str(params.file)]
            for spec in specs:
                components.append(component(spec.package, spec.name))
                node_kwargs.append(kwargs)

        def started(nodes) -> None:
            from rclpy.logging import get_logger
            logger = get_logger(PROG)
            logger.info(f'{len(nodes)} nodes in one process: ' + ', '.join(
                node.get_fully_qualified_name() for node in nodes))
            logger.info(f'DDS publication: {PUBLICATION_MODE_VARIABLE}='
                        f'{os.environ.get(PUBLICATION_MODE_VARIABLE)}')
            if links is not None:
                for line in links.links():
                    logger.info(f'in-process link {line}')
                links.open()

        return container_main(components, PROG, p.format_usage(), [PROG, *ros_args],
                              node_kwargs=node_kwargs, on_started=started)


if __name__ == '__main__':
    sys.exit(main())
