"""sim_node's DEBUG line: with `--log-level pam.sim_node:=debug` the valve
command applied gives a line when it changes markedly (the first command, then a move of more
than 0.5 V from the last logged one, a sanitised command as applied); small moves give none;
without the option the same run prints no DEBUG line at all."""

import math

import pytest

from pam_common.testing import assert_no_debug_lines, log_lines, wait_for_log
from pam_interfaces.msg import Pressures, ValveCommand

LOGGER = 'pam.sim_node'
STARTUP = 45.0   # s
# (u1, u2) sent in lockstep, one step each; True: a DEBUG line is due
COMMANDS = [((5.0, 5.0), True),          # the first command
            ((5.3, 4.8), False),         # within 0.5 V of (5, 5)
            ((5.45, 5.45), False),       # still within 0.5 V of (5, 5): drift is not a change
            ((5.6, 5.0), True),          # 0.6 V from (5, 5) in u1
            ((5.6, 6.2), True),          # 1.2 V from (5.6, 5) in u2
            ((math.nan, 12.0), True)]    # sanitised to (0, 10): applied, logged as applied


@pytest.mark.parametrize('debug', [True, False], ids=['debug', 'default'])
def test_marked_command_changes_at_debug_only(node_process, probe, debug):
    sim = node_process('sim_node', 'pam_driver', '-p', 'timing:=lockstep',
                       '-p', 'lockstep_timeout:=0.5',
                       *(['--log-level', f'{LOGGER}:=debug'] if debug else []))
    samples = probe.subscribe(Pressures, '/pam/pressures')
    command = probe.publisher(ValveCommand, '/pam/valve_command')
    sim.wait_for(lambda: len(samples) > 0, STARTUP, 'the first lockstep sample')
    sim.wait_for(lambda: command.get_subscription_count() > 0, 10.0,
                 'sim_node to subscribe valve_command')
    for k, ((u1, u2), _) in enumerate(COMMANDS):     # zero stamp: for the current step
        command.publish(ValveCommand(u1=u1, u2=u2))
        sim.wait_for(lambda k=k: any(m.sample == k + 2 for m in samples.messages()), 10.0,
                     f'sample {k + 2}')
    if not debug:
        assert_no_debug_lines(sim)
        return
    lines = wait_for_log(sim, 'DEBUG', LOGGER, 'u1 0.000 V, u2 10.000 V')
    applied = [line.split('valve command applied: ', 1)[1] for line in lines
               if 'valve command applied: ' in line]
    assert len(applied) == sum(due for _, due in COMMANDS), lines
    assert applied[0].startswith('u1 5.000 V, u2 5.000 V at step 0, command 1; the first '
                                 'command (held the initial command u1 5.5 V, u2 5.5 V'), applied
    assert applied[1].startswith('u1 5.600 V, u2 5.000 V at step 3, command 4; was u1 5.000 V, '
                                 'u2 5.000 V'), applied
    assert applied[2].startswith('u1 5.600 V, u2 6.200 V at step 4, command 5'), applied
    assert applied[3].startswith('u1 0.000 V, u2 10.000 V at step 5, command 6; was u1 5.600 V, '
                                 'u2 6.200 V'), applied
    assert log_lines(sim.stderr, 'DEBUG') == lines, 'only our logger at DEBUG'
