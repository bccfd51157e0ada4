"""pam_container: the nodes of one or several PAM stacks composed in one process, on one executor.

Each node is the very node class its own executable runs (the node module's COMPONENT), built
with the same parameters, so its topics, parameters, services and /diagnostics are the same as
those of the separate processes; only the process is shared. What composition saves and costs:
docs/composition.md.

    pam_container --ros-args -r __ns:=/pam --params-file bringup.yaml     # the stack of pam-bringup
    pam_container --namespace /joint1 /joint2 --ros-args --params-file f.yaml   # two stacks

Launch files start it as any node (no `name=`: a node-name remap would rename every node):
    Node(package='pam_bringup', executable='pam_container', namespace='pam',
         parameters=[params_file])
"""

from __future__ import annotations

import argparse
import importlib
import sys

from pam_common.node_skeleton import Component, container_main

from .stack import RIGS, normal_namespace, stack_nodes

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
              '[--no-controller] [--namespace NS [NS ...]] [--ros-args ...]',
        description='The nodes of the PAM stack (the rig, ukf_node, reference_node, pi_node) '
                    'composed in one process on one executor: the same node classes, topics, '
                    'parameters, services and diagnostics as the separate executables. With '
                    'several --namespace values, one complete stack per namespace.',
        epilog='ROS arguments (after --ros-args) apply to every node: --params-file FILE (one '
               'section per node full name, e.g. /pam/ukf_node, or /**/ukf_node for any '
               'namespace), -p NAME:=VALUE (every node that declares NAME), -r __ns:=/NS (one '
               'stack only; with --namespace, leave it out), --log-level.\n\nExamples:\n'
               f'  {PROG} --ros-args -r __ns:=/pam --params-file bringup.yaml\n'
               f'  {PROG} --namespace /joint1 /joint2 --ros-args --params-file joints.yaml')
    p.add_argument('--rig', choices=sorted(RIGS), default='sim',
                   help='sim: sim_node, the simulated rig; driver: driver_node (default sim)')
    p.add_argument('--no-reference', action='store_true', help='without reference_node')
    p.add_argument('--no-controller', action='store_true', help='without pi_node')
    p.add_argument('--namespace', nargs='+', metavar='NS', default=[],
                   help='one stack per namespace (default: one stack, in /pam unless the ROS '
                        'arguments remap __ns)')
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
                        controller=not args.no_controller)
    components, node_kwargs = [], []
    for ns in namespaces or [None]:
        for spec in specs:
            components.append(component(spec.package, spec.name))
            node_kwargs.append({} if ns is None else {'namespace': ns})

    def started(nodes) -> None:
        nodes[0].get_logger().info(
            f'{PROG}: {len(nodes)} nodes in one process: '
            + ', '.join(node.get_fully_qualified_name() for node in nodes))

    return container_main(components, PROG, p.format_usage(), [PROG, *ros_args],
                          node_kwargs=node_kwargs, on_started=started)


if __name__ == '__main__':
    sys.exit(main())
