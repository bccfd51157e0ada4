"""pi_node's DEBUG lines: with `--ros-args --log-level debug` the output going
into saturation (and the anti-windup at work) and out of it, and a reference change, each give a
line from our own code; without it the same run prints no DEBUG line at all."""

import pytest

from pam_common.diagnostics import status_values
from pam_common.testing import assert_no_debug_lines, diagnostic_statuses, log_lines, wait_for_log
from pam_controller.control_loop import ANGLE
from pam_interfaces.msg import Reference

LOGGER = 'pam.pi_node'
SATURATED = 30      # estimates with a 0.3 rad error: kp 40 V/rad gives 12 V, the limit is 4.5 V


@pytest.mark.parametrize('debug', [True, False], ids=['debug', 'default'])
def test_saturation_and_reference_at_debug_only(node_process, probe, debug):
    from test_pi_node_topics import start_pi_node
    pi, commands, states, diagnostics, references, feed = start_pi_node(
        node_process, probe, '-p', 'feedback_timeout:=30.0',     # no safe output in between
        *(['--log-level', 'debug'] if debug else []))
    feed(5)                                          # reference 0, angle 0: not saturated
    pi.wait_for(lambda: len(commands) >= 5, 20.0, 'the first 5 commands')   # before the new
    references.publish(Reference(mode=ANGLE, value=0.3))                   # reference

    def reference():
        statuses = diagnostic_statuses(diagnostics, 'pi_node')
        return status_values(statuses[-1]).get('reference') if statuses else None
    pi.wait_for(lambda: reference() == '0.3', 20.0, 'the reference taken (/diagnostics)')
    before = len(commands)
    feed(SATURATED, angle=0.0, start=1.1)
    feed(10, angle=0.3, start=1.2)                   # error 0: the frozen integral is still 0
    pi.wait_for(lambda: len(commands) >= before + SATURATED + 10, 20.0, 'the commands')
    saturated = [s.saturated for s in states.messages()][-(SATURATED + 10):]
    assert saturated == [True] * SATURATED + [False] * 10
    if not debug:
        assert_no_debug_lines(pi)
        return
    lines = wait_for_log(pi, 'DEBUG', LOGGER, 'out of saturation')
    into = [line for line in lines if ': saturated: ' in line]
    assert len(into) == 1 and 'u1 10.000 V, u2 1.000 V at the limits [0, 10] V' in into[0], lines
    assert 'anti-windup: the integral frozen while the error pushes further' in into[0], into
    out = [line for line in lines if 'out of saturation' in line]
    assert len(out) == 1 and f'out of saturation after {SATURATED} samples' in out[0], lines
    assert any('angle reference 0 -> 0.3 ' in line for line in lines), lines
    assert len(log_lines(pi.stderr, 'DEBUG')) > len(lines), 'rcl debug lines too: global level'
