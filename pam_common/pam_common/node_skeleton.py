"""The skeleton every PAM node follows: how it gets its parameters and what its main() does.

    @dataclass(frozen=True)
    class MyConfig(NodeConfig):          # pam_common.node_params: one field per table row
        rate: float
        hardware_id: str

    def build_config(values: dict) -> MyConfig:
        return MyConfig.from_values(check_all(PARAMETERS, values))   # and the node's own checks

    class MyNode(Node):
        def __init__(self, **kwargs):
            kwargs.setdefault('namespace', DEFAULT_NAMESPACE)       # pam_common.topics
            super().__init__(NODE_NAME, **kwargs)
            self.config = parameter_values(self, PARAMETERS, check=build_config)

        def start(self):                 # optional: threads, once every node is on the executor
            ...

    COMPONENT = Component(NODE_NAME, MyNode, start=MyNode.start)

    def main(args=None) -> int:
        return component_main(COMPONENT, usage_text(NODE_NAME, SUMMARY, PARAMETERS), args)

parameter_values: every ParamSpec of the node's table declared with its descriptor (description,
unit, range, read-only); a name given on the command line or in a params file that no spec
declares is a warning naming the closest known one; the values merged over the defaults and
checked, and the node's frozen config built from them once. A bad value is a ConfigError naming
the parameter, which run_nodes prints as one line (exit code 2).

component_main (node_main: the same for a node without start or stop hooks): -h/--help prints
the usage (exit code 0); an argument that is not a ROS argument, a bad params file or -p rule is
one line and exit code 2, all before rclpy starts; then run_nodes (build, start, executor, stop
signals, a finite node's finish(), stop, shutdown).

pam_common/test/test_layout.py holds every node to this skeleton.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

from .executors import Component, run_nodes
from .node_params import ParamSpec, check_all, cli_preamble, declare_parameters, merge_overrides

__all__ = ['Component', 'component_main', 'container_main', 'node_main', 'parameter_values']


def parameter_values(node, specs: Sequence[ParamSpec],
                     check: Callable[[dict], Any] | None = None):
    """The node's checked parameters: `check(values)` if given (e.g. a build_config that checks
    and builds the node's configuration: its result is returned), else check_all's values."""
    values = merge_overrides(specs, declare_parameters(node, specs))
    return check(values) if check is not None else check_all(specs, values)


def node_main(node_factory, name: str, usage: str, args=None, stop=None) -> int:
    """component_main for a node without a start hook: `stop(node)` runs at the end with ROS
    still up. Returns the exit code."""
    return component_main(Component(name, node_factory, stop=stop), usage, args)


def component_main(component: Component, usage: str, args=None) -> int:
    """The main() of a node module's COMPONENT (the same node alone in its process): --help and
    argument checks (cli_preamble), then run_nodes (build, start, spin, stop). Returns the exit
    code."""
    argv = sys.argv if args is None else list(args)
    code = cli_preamble(argv, component.name, usage)
    if code is not None:
        return code
    return run_nodes([component], component.name, args=argv)


def container_main(components: Sequence[Component], name: str, usage: str, args: Sequence[str],
                   node_kwargs: Sequence[dict], on_started=None) -> int:
    """The main() of a process that composes several nodes (pam_container): `args` are the
    program name and the ROS arguments only (the container parsed its own options), checked as
    node_main checks a node's; then run_nodes."""
    argv = list(args)
    code = cli_preamble(argv, name, usage)
    if code is not None:
        return code
    return run_nodes(components, name, args=argv, node_kwargs=node_kwargs, on_started=on_started)
