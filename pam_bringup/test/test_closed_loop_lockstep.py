"""The sensor-less closed loop over DDS in lockstep: sim_node ('mild' plant, its sensor), ukf_node
and pi_node as separate processes; reference steps held 8 s of simulated time. Asserts the
acceptance targets on the TRUE angle / torque: steady-state error <= 3.0 % (angle) and <= 3.5 %
(torque) of the 40 deg / 4 N m range, settling <= 3 s, no sustained oscillation."""

import pytest

from pam_bringup.lockstep_run import run_lockstep_steps
from pam_common.testing import claim_domain

CASES = {'angle': ([0.0, 0.25, -0.15], 3.0), 'torque': ([0.0, 1.5, -1.0], 3.5)}


@pytest.mark.parametrize('mode', sorted(CASES))
def test_lockstep_closed_loop_meets_the_targets(mode):
    levels, target = CASES[mode]
    domain, lock = claim_domain(f'lockstep_{mode}')
    with lock:
        report, t, _reference, _truth = run_lockstep_steps(
            mode, levels, hold=8.0, domain_id=domain, timeout=240.0)
    assert len(report.steps) == 3 and t[-1] >= 24.0
    assert report.worst_error <= target, '\n'.join(report.lines())
    assert report.worst_settling <= 3.0, '\n'.join(report.lines())
    assert report.worst_ripple < 1.0 and report.worst_overshoot < 25.0
