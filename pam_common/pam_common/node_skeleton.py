"""The skeleton every PAM node follows: how it gets its parameters and what its main() does.

    class MyNode(Node):
        def __init__(self, **kwargs):
            kwargs.setdefault('namespace', DEFAULT_NAMESPACE)       # pam_common.topics
            super().__init__(NODE_NAME, **kwargs)
            self.values = parameter_values(self, PARAMETERS)        # or check=build_config

    def main(args=None) -> int:
        return node_main(MyNode, NODE_NAME, usage_text(NODE_NAME, SUMMARY, PARAMETERS), args)

parameter_values: every ParamSpec of the node's table declared with its descriptor (description,
unit, range, read-only); a name given on the command line or in a params file that no spec
declares is a warning naming the closest known one; the values merged over the defaults and
checked. A bad value is a ConfigError naming the parameter, which run_node prints as one line
(exit code 2).

node_main: -h/--help prints the usage (exit code 0); an argument that is not a ROS argument, a bad
params file or -p rule is one line and exit code 2, all before rclpy starts; then run_node
(executor, stop signals, a finite node's finish(), shutdown).

pam_common/test/test_layout.py holds every node to this skeleton.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

from .executors import run_node
from .node_params import ParamSpec, check_all, cli_preamble, declare_parameters, merge_overrides


def parameter_values(node, specs: Sequence[ParamSpec],
                     check: Callable[[dict], Any] | None = None):
    """The node's checked parameters: `check(values)` if given (e.g. a build_config that checks
    and builds the node's configuration: its result is returned), else check_all's values."""
    values = merge_overrides(specs, declare_parameters(node, specs))
    return check(values) if check is not None else check_all(specs, values)


def node_main(node_factory, name: str, usage: str, args=None, stop=None) -> int:
    """The main() of a node: --help and argument checks (cli_preamble), then run_node(node_factory,
    ...; `stop(node)` runs at the end with ROS still up). Returns the exit code."""
    argv = sys.argv if args is None else list(args)
    code = cli_preamble(argv, name, usage)
    if code is not None:
        return code
    return run_node(node_factory, name, args=argv, stop=stop)
