"""The ROS closed loop in lockstep: sim_node (lockstep), ukf_node and pi_node as separate
processes, reference steps published by a probe node at fixed simulated times. Deterministic up
to the reference switch (taken at the first sample whose stamp reaches the switch time).

Used by the topic-level closed-loop test and by benchmarks/closed_loop_acceptance.py. Needs the
project's executables and pytest (pam_common.testing).
"""

from __future__ import annotations

import os
import tempfile
import threading

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context

from pam_common.diagnostics import status_values
from pam_common.testing import NodeProcess, Probe, child_env, diagnostic_statuses, stamp_ns
from pam_interfaces.msg import JointMeasurement, Reference

from .step_metrics import ANGLE_SPAN, TORQUE_SPAN, step_report


def run_lockstep_steps(mode: str, levels, hold: float, domain_id: int, seed: int = 0,
                       mismatch: str = 'mild', timeout: float = 600.0,
                       diagnostics: dict | None = None) -> tuple:
    """Track `levels` (rad or N m), each held `hold` s of simulated time.

    Returns (StepReport of the true angle or torque, t (s), reference, truth). A `diagnostics`
    dict gets the last /diagnostics values of each node, by node name ('ukf_node', ...).
    """
    torque = mode == 'torque'
    os.environ.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env = child_env(domain_id)
    joint = 'locked' if torque else 'free'
    workdir = tempfile.mkdtemp(prefix='pam_lockstep_')
    processes = [
        NodeProcess('sim_node', 'pam_driver', ['--ros-args', '-p', 'timing:=lockstep',
                                               '-p', f'mismatch:={mismatch}', '-p',
                                               f'joint_mode:={joint}', '-p', f'seed:={seed}'],
                    env, workdir),
        NodeProcess('ukf_node', 'pam_estimator', ['--ros-args', '-p', f'joint_mode:={joint}'],
                    env, workdir),
        NodeProcess('pi_node', 'pam_controller', ['--ros-args', '-p', f'mode:={mode}', '-p',
                                                  f'initial_reference:={float(levels[0])}',
                                                  '-p', 'feedback_timeout:=30.0'], env, workdir),
    ]
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    probe = Probe(context, 'lockstep_reference')
    end_ns = int(round(len(levels) * hold * 1e9))
    samples: dict = {}
    done = threading.Event()
    ref_pub = probe.publisher(Reference, '/pam/reference')
    ref_mode = Reference.TORQUE if torque else Reference.ANGLE
    current = [0]

    def on_truth(msg: JointMeasurement):
        t = stamp_ns(msg.header.stamp)
        j = min(int(t // int(round(hold * 1e9))), len(levels) - 1)
        if j != current[0]:
            current[0] = j
            ref_pub.publish(Reference(mode=ref_mode, value=float(levels[j])))
        samples[t] = (msg.torque if torque else msg.angle, float(levels[j]))
        if t >= end_ns:
            done.set()

    probe.subscribe(JointMeasurement, '/pam/joint_measured', on_truth)
    statuses = probe.subscribe(DiagnosticArray, '/diagnostics', depth=100)
    try:
        if not done.wait(timeout):
            alive = {p.name: p.alive() for p in processes}
            logs = '\n'.join(f'--- {p.name} ---\n{p.stderr[-1500:]}' for p in processes)
            raise RuntimeError(f'lockstep run did not reach {end_ns * 1e-9:g} s of simulated '
                               f'time in {timeout:g} s ({len(samples)} samples seen; processes '
                               f'alive: {alive}); logs:\n{logs}')
        dead = [p.name for p in processes if not p.alive()]
        if dead:
            raise RuntimeError(f'processes died: {dead}')
        if diagnostics is not None:
            for p in processes:
                last = diagnostic_statuses(statuses, p.name)
                diagnostics[p.name] = status_values(last[-1]) if last else {}
    finally:
        probe.close()
        context.try_shutdown()
        for p in processes:
            p.close()
    stamps = np.array(sorted(samples))
    truth = np.array([samples[s][0] for s in stamps])
    reference = np.array([samples[s][1] for s in stamps])
    t = stamps * 1e-9
    report = step_report(t, reference, truth, TORQUE_SPAN if torque else ANGLE_SPAN, 2.0)
    return report, t, reference, truth

