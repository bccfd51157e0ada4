"""The ROS closed loop in lockstep: sim_node (lockstep), ukf_node and pi_node as separate
processes, reference steps published by a node of this process at fixed simulated times.
Deterministic up to the reference switch (taken at the first sample whose stamp reaches the switch
time).

The nodes are those of pam_bringup.stack (the simulated rig and the controller, no
reference_node), run by pam_bringup.supervisor with their output kept, not echoed (the last lines
of each go into the error when a run fails). Used by the topic-level closed-loop test
(pam_bringup/test/test_closed_loop_lockstep.py) and by benchmarks/closed_loop_acceptance.py.
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.task import Future

from pam_common.diagnostics import is_status_of, status_values
from pam_common.executors import lockstep_publication, make_executor
from pam_common.finite_guard import FiniteGuard
from pam_common.qos import SAMPLE_QOS
from pam_common.stamps import stamp_ns
from pam_common.topics import DIAGNOSTICS, JOINT_MEASURED, REFERENCE, absolute
from pam_controller.step_metrics import ANGLE_SPAN, TORQUE_SPAN, step_report
from pam_interfaces.msg import JointMeasurement, Reference

from .stack import locate_executables, stack_nodes
from .supervisor import Child, Output, Supervisor, child_environment

SPIN_SLICE = 0.2    # s, the spin thread checks for the end this often
POLL = 0.2          # s, the waiting thread checks for dead nodes this often
LOG_TAIL = 1500     # characters of each node's last output in an error


def node_arguments(mode: str, first_level: float, joint: str, scenario: str,
                   seed: int) -> dict[str, list[str]]:
    """The ROS arguments of each node of the lockstep run, by node name."""
    return {
        'sim_node': ['-p', 'timing:=lockstep', '-p', f'scenario:={scenario}',
                     '-p', f'joint_mode:={joint}', '-p', f'seed:={seed}'],
        'ukf_node': ['-p', f'joint_mode:={joint}'],
        'pi_node': ['-p', f'mode:={mode}', '-p', f'initial_reference:={first_level}',
                    '-p', 'feedback_timeout:=30.0'],
    }


def _logs(supervisor: Supervisor) -> str:
    return '\n'.join(f'--- {c.name} ---\n' + '\n'.join(c.tail)[-LOG_TAIL:]
                     for c in supervisor.children)


class _ReferenceNode:
    """This process's node: publishes the reference level of each sample's simulated time,
    records the true value of each sample and the last /diagnostics status of each node."""

    def __init__(self, context, levels, hold: float, torque: bool, node_names: list[str]):
        self.levels = levels
        self.hold_ns = round(hold * 1e9)
        self.end_ns = round(len(levels) * hold * 1e9)
        self.torque = torque
        self.samples: dict = {}            # stamp ns -> (true value, reference)
        self.statuses: dict = {}           # node name -> its last DiagnosticStatus
        self.done = threading.Event()
        self._names = node_names
        self._current = 0
        self._mode = Reference.TORQUE if torque else Reference.ANGLE
        self.context = context
        self.node = rclpy.create_node('lockstep_reference', context=context)
        self._reference = FiniteGuard(self.node.get_logger()).wrap(
            self.node.create_publisher(Reference, absolute(REFERENCE), SAMPLE_QOS), hold=True)
        self.node.create_subscription(JointMeasurement, absolute(JOINT_MEASURED),
                                      self._on_truth, SAMPLE_QOS)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS, self._on_diagnostics,
                                      SAMPLE_QOS)
        self._executor = make_executor(events=True, context=context)
        self._executor.add_node(self.node)
        self._finished = Future()
        self._thread = threading.Thread(target=self._spin, name='lockstep_spin', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._finished.done() and self.context.ok():
            self._executor.spin_until_future_complete(self._finished, timeout_sec=SPIN_SLICE)

    def _on_truth(self, msg: JointMeasurement) -> None:
        t = stamp_ns(msg.header.stamp)
        j = min(t // self.hold_ns, len(self.levels) - 1)
        if j != self._current:
            self._current = j
            self._reference.publish(Reference(mode=self._mode, value=float(self.levels[j])))
        self.samples[t] = (msg.torque if self.torque else msg.angle, float(self.levels[j]))
        if t >= self.end_ns:
            self.done.set()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            for name in self._names:
                if is_status_of(status.name, name):
                    self.statuses[name] = status

    def close(self) -> None:
        if not self._finished.done():
            self._finished.set_result(None)
        try:
            self._executor.wake()
        except Exception:  # noqa: BLE001 - not every executor has wake()
            pass
        self._thread.join(timeout=5.0)
        self._executor.remove_node(self.node)
        self.node.destroy_node()
        self._executor.shutdown()


def run_lockstep_steps(mode: str, levels, hold: float, domain_id: int, seed: int = 0,
                       scenario: str = 'mild', timeout: float = 600.0,
                       diagnostics: dict | None = None) -> tuple:
    """Track `levels` (rad or N m), each held `hold` s of simulated time.

    Returns (StepReport of the true angle or torque, t (s), reference, truth). A `diagnostics`
    dict gets the last /diagnostics values of each node, by node name ('ukf_node', ...).
    RuntimeError (with the end of each node's output) when a node dies or the run does not
    reach its end within `timeout` s.
    """
    torque = mode == 'torque'
    os.environ.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env = child_environment(domain_id)
    env['AMENT_PREFIX_PATH'] = env.get('AMENT_PREFIX_PATH') or sys.prefix
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    lockstep_publication(env)
    env.pop('ROS_LOCALHOST_ONLY', None)
    nodes = stack_nodes('sim', reference=False, controller=True)
    arguments = node_arguments(mode, float(levels[0]), 'locked' if torque else 'free', scenario,
                               seed)
    executables = locate_executables(nodes)
    children = [Child(n.name, [executables[n.name], '--ros-args', *arguments[n.name]], n.role)
                for n in nodes]
    supervisor = Supervisor(children, env,
                            Output('lockstep', [c.name for c in children], False, echo=False),
                            cwd=tempfile.mkdtemp(prefix='pam_lockstep_'))
    supervisor.start()
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    run = None
    try:
        run = _ReferenceNode(context, levels, hold, torque, [c.name for c in children])
        deadline = time.monotonic() + timeout
        while not run.done.wait(POLL):
            if supervisor.dead() or time.monotonic() >= deadline:
                break
        dead = [c.name for c in supervisor.dead()]
        if not run.done.is_set() and not dead:
            raise RuntimeError(f'lockstep run did not reach {run.end_ns * 1e-9:g} s of simulated '
                               f'time in {timeout:g} s ({len(run.samples)} samples seen); '
                               f'logs:\n{_logs(supervisor)}')
        if dead:
            raise RuntimeError(f'processes died: {dead} ({supervisor.codes()}); logs:\n'
                               f'{_logs(supervisor)}')
        if diagnostics is not None:
            for name in (c.name for c in children):
                status = run.statuses.get(name)
                diagnostics[name] = status_values(status) if status is not None else {}
    finally:
        if run is not None:
            run.close()
        context.try_shutdown()
        supervisor.stop()
    stamps = np.array(sorted(run.samples))
    truth = np.array([run.samples[s][0] for s in stamps])
    reference = np.array([run.samples[s][1] for s in stamps])
    t = stamps * 1e-9
    report = step_report(t, reference, truth, TORQUE_SPAN if torque else ANGLE_SPAN, 2.0)
    return report, t, reference, truth
