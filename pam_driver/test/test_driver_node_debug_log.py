"""driver_node's DEBUG lines, against pam-emulator over a real pty: with
`--log-level pam.driver_node:=debug` a watchdog trip and an ~/arm each give a line with the
safety state they left; without it there is no DEBUG line."""

import pytest

from pam_common.testing import assert_no_debug_lines, wait_for_log
from test_driver_node import Rig  # the same test folder (pytest's prepend import mode)

LOGGER = 'pam.driver_node'


@pytest.mark.parametrize('debug', [True, False], ids=['debug', 'default'])
def test_watchdog_trip_and_arm_at_debug_only(node_process, probe, helpers, tmp_path, debug):
    def start(name, package, *args, **kwargs):      # node_process, DEBUG on for driver_node
        if name == 'driver_node' and debug:
            args = (*args, '--log-level', f'{LOGGER}:=debug')
        return node_process(name, package, *args, **kwargs)

    r = Rig(start, probe, helpers, tmp_path)
    r.send(8.0, 2.0, duration=0.2)
    r.wait_values(lambda v: v['watchdog trips'] == '1', 5.0, 'the watchdog trip')
    assert r.call('arm').success
    if not debug:
        assert_no_debug_lines(r.driver)
        return
    lines = wait_for_log(r.driver, 'DEBUG', LOGGER, 'decided: ~/arm: armed')
    trip = [line for line in lines if 'decided: safe output [0.0, 0.0] V: command watchdog' in line]
    assert len(trip) == 1 and '-> armed False, connected True' in trip[0], lines
    assert 'watchdog trips 1 (last after ' in trip[0] and 'timeout 50 ms' in trip[0], trip
    armed = [line for line in lines if 'decided: ~/arm: armed' in line]
    assert len(armed) == 1 and '-> armed True' in armed[0] and 'safe reason none' in armed[0]
