"""The PAM stack: which nodes make it, for which options. THE node list.

pam-bringup (pam_bringup.bringup), the launch file (launch/pam_sim.launch.py) and the lockstep
run (pam_bringup.lockstep_run) all take their node list from stack_nodes().
No ROS import here: the launch file reads this module.

Every node is started as `<executable> --ros-args -r __ns:=<namespace> --params-file <file>`
(node_argv), its node name being its executable name, with one params file for all
(default_params_file: one section per node, keyed by the node's full name, /pam/<node>).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from pam_common.executables import executable_candidates, find_executable
from pam_common.topics import DEFAULT_NAMESPACE  # noqa: F401 - re-exported for the launch file

PACKAGE = 'pam_bringup'


@dataclass(frozen=True)
class NodeSpec:
    """One node of the stack: its name (= executable name = log prefix), package and role."""

    name: str
    package: str
    role: str


#: The rig, by --rig / rig:= value: the simulated rig or the hardware driver (same topics).
RIGS = {'sim': NodeSpec('sim_node', 'pam_driver', 'rig (sim)'),
        'driver': NodeSpec('driver_node', 'pam_driver', 'rig (driver)')}
ESTIMATOR = NodeSpec('ukf_node', 'pam_estimator', 'estimator')
REFERENCE = NodeSpec('reference_node', 'pam_controller', 'reference')
CONTROLLER = NodeSpec('pi_node', 'pam_controller', 'controller')
#: The process that composes the stack's nodes (pam_bringup.container).
CONTAINER = NodeSpec('pam_container', PACKAGE, 'the stack, composed')


def stack_nodes(rig: str = 'sim', reference: bool = True,
                controller: bool = True, with_rig: bool = True) -> list[NodeSpec]:
    """The nodes to start, in start order: the rig (RIGS[rig], if `with_rig`), ukf_node,
    reference_node (if `reference`), pi_node (if `controller`). ValueError for an unknown
    rig."""
    if rig not in RIGS:
        raise ValueError(f"unknown rig {rig!r}: one of {', '.join(sorted(RIGS))}")
    nodes = [RIGS[rig], ESTIMATOR] if with_rig else [ESTIMATOR]
    if reference:
        nodes.append(REFERENCE)
    if controller:
        nodes.append(CONTROLLER)
    # The bag recorder joins here once it exists (its own option to switch it off).
    return nodes


def normal_namespace(text: str) -> str:
    """A namespace as rcl writes it: leading '/', no trailing one ('pam/' -> '/pam'); ValueError
    if it is not a valid ROS namespace."""
    ns = text.strip()
    if not ns.startswith('/'):
        ns = '/' + ns
    if ns != '/':
        ns = ns.rstrip('/')
    if not re.fullmatch(r'/|(/[A-Za-z_][A-Za-z0-9_]*)+', ns):
        raise ValueError(f'{text!r} is not a valid ROS namespace')
    return ns


def container_options(rig: str = 'sim', reference: bool = True,
                      controller: bool = True, links: bool = False,
                      with_rig: bool = True) -> list[str]:
    """pam_container's options for the stack_nodes() of these arguments."""
    return (['--rig', rig] + ([] if reference else ['--no-reference'])
            + ([] if controller else ['--no-controller']) + (['--links'] if links else [])
            + ([] if with_rig else ['--no-rig']))


def every_node() -> list[NodeSpec]:
    """Every node the stack can start (each rig), for the params file and descriptions."""
    return [*RIGS.values(), ESTIMATOR, REFERENCE, CONTROLLER]


def needs_arming(rig: str, controller: bool) -> bool:
    """The hardware driver with the controller: driver_node may latch safe while pi_node starts
    (pam_bringup.arming arms it once the commands flow)."""
    return rig == 'driver' and controller


def default_params_file() -> Path:
    """share/pam_bringup/config/bringup.yaml of the install, else of this source tree."""
    try:
        from ament_index_python.packages import get_package_share_directory
        installed = Path(get_package_share_directory(PACKAGE)) / 'config' / 'bringup.yaml'
        if installed.is_file():
            return installed
    except Exception:  # noqa: BLE001 - not installed: fall back to the source tree
        pass
    return Path(__file__).resolve().parent.parent / 'config' / 'bringup.yaml'


class MissingExecutable(LookupError):
    """A node's executable is not installed (the message says where it was looked for)."""


def locate_executables(nodes: list[NodeSpec]) -> dict[str, str]:
    """The executable path of each node, by name (pam_common.executables); MissingExecutable
    (one line: which, and where it was looked for) for the first one not found."""
    paths = {}
    for node in nodes:
        exe = find_executable(node.name, node.package)
        if exe is None:
            where = '; '.join(executable_candidates(node.name, node.package))
            hint = ' (run `make setup` or source scripts/env.sh / your install)'
            raise MissingExecutable(f"executable '{node.name}' of {node.package} not "
                                    f'found{hint}; looked in: {where}')
        paths[node.name] = exe
    return paths


def node_argv(executable: str, namespace: str, params_file: Path) -> list[str]:
    """The command of a stack node: in `namespace`, with the stack's params file."""
    return [executable, '--ros-args', '-r', f'__ns:={namespace}', '--params-file',
            str(params_file)]
