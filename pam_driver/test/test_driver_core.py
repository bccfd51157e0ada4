"""DriverCore, driver_node's safety decisions, without ROS: every decision and its counters."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from pam_driver import calibration
from pam_driver.calibration import SUPPLY
from pam_driver.driver_config import build_config
from pam_driver.driver_core import NOTHING, OUT_OF_RANGE_SAMPLES, DriverCore, Log, SafetyConfig

CAL = calibration.load()
SAFE = (0.0, 0.0)
WATCHDOG = 0.05          # s, driver_config's default
P_OK = 450e3             # Pa abs, plausible
T0 = 100.0               # s, a monotonic time


def make(connected: bool = True, **overrides) -> DriverCore:
    """A core with driver_config's defaults (and overrides), connected unless told."""
    core = DriverCore(build_config(overrides).safety, CAL)
    if connected:
        core.on_connected()
    return core


def counts(p1: float = P_OK, p2: float = P_OK) -> tuple[int, int]:
    return CAL.pressure_counts(0, p1), CAL.pressure_counts(1, p2)


def sample(core: DriverCore, now: float, adc: tuple[int, int] | None = None):
    adc = adc or counts()
    return core.on_sample(adc, (CAL.pressure(0, adc[0]), CAL.pressure(1, adc[1])), now)


def warnings(action) -> list[str]:
    return [log.text for log in action.logs if log.level == 'warning']


def trip_watchdog(core: DriverCore) -> None:
    core.on_command(8.0, 2.0, T0)
    core.on_tick(T0 + 1.0)
    assert not core.armed


def test_the_core_imports_no_ros():
    code = ('import sys, pam_driver.driver_core; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "rcl_interfaces", "pam_interfaces", "serial")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == '[]', out.stdout


def test_start_state_follows_arm_at_start():
    core = make(connected=False)
    assert core.armed and core.safe_reason == '' and core.output == SAFE
    assert not core.connected
    core = make(connected=False, arm_at_start=False, safe_output=[5.5, 5.5])
    assert not core.armed and core.safe_reason == 'not armed at start'
    assert core.output == (5.5, 5.5)


# ---------------------------------------------------------------------- the command path
def test_a_valid_command_goes_to_the_valves_when_armed_and_connected():
    core = make()
    action = core.on_command(8.0, 2.0, T0)
    assert action.ok and action.output == (8.0, 2.0) and action.changed
    assert core.output == (8.0, 2.0) and core.last_command_time == T0
    again = core.on_command(8.0, 2.0, T0 + 0.01)
    assert again.output == (8.0, 2.0) and not again.changed, 'written each time, published once'
    assert core.commands == 2 and core.commands_clipped == 0 and core.commands_ignored == 0


def test_commands_before_the_device_connects_are_ignored_and_counted():
    core = make(connected=False)
    action = core.on_command(8.0, 2.0, T0)
    assert not action.ok and action.output is None
    assert core.commands == 1 and core.commands_ignored == 1
    assert core.output == SAFE and core.last_command_time is None


def test_commands_while_disarmed_are_ignored_and_counted():
    core = make(arm_at_start=False)
    action = core.on_command(8.0, 2.0, T0)
    assert not action.ok and action.output is None and core.output == SAFE
    assert core.commands_ignored == 1 and core.last_command_time is None


@pytest.mark.parametrize('limits, command, expected', [
    ([0.0, 10.0], (12.0, -1.0), (10.0, 0.0)),
    ([0.0, 10.0], (1e300, 5.0), (10.0, 5.0)),
    ([1.0, 9.0], (0.5, 9.5), (1.0, 9.0)),
    ([1.0, 9.0], (5.0, 9.0001), (5.0, 9.0)),
])
def test_commands_are_clipped_to_valve_limits_and_counted(limits, command, expected):
    core = make(valve_limits=limits)
    action = core.on_command(*command, T0)
    assert action.ok and action.output == expected
    assert core.commands_clipped == 1 and core.commands == 1
    core.on_command(*expected, T0 + 0.01)
    assert core.commands_clipped == 1, 'a command inside the limits is not counted'


@pytest.mark.parametrize('command', [(math.nan, 2.0), (8.0, math.inf), (-math.inf, math.nan)])
def test_a_non_finite_command_is_ignored_counted_and_logged_throttled(command):
    core = make()
    core.on_command(8.0, 2.0, T0)
    action = core.on_command(*command, T0 + 0.03)
    assert not action.ok and action.output is None
    assert action.logs == (Log('warning', f'non-finite valve_command {command} ignored', True),)
    assert core.commands_nonfinite == 1 and core.commands == 1, 'not a command received'
    assert core.commands_clipped == 0 and core.commands_ignored == 0
    assert core.output == (8.0, 2.0) and core.armed
    # it does not feed the watchdog: the trip is measured from the last valid command
    assert core.on_tick(T0 + WATCHDOG + 0.001).output == SAFE
    assert core.last_trip_ms == pytest.approx((WATCHDOG + 0.001) * 1e3)


# ---------------------------------------------------------------------- the watchdog
def test_the_watchdog_trips_after_its_timeout_to_the_safe_output():
    core = make(safe_output=[1.5, 2.5], watchdog_timeout=0.25)   # times exact in binary
    core.on_command(8.0, 2.0, T0)
    assert core.on_tick(T0 + 0.25) is NOTHING, 'not at the timeout, after it'
    action = core.on_tick(T0 + 0.2578125)
    assert action.output == (1.5, 2.5) and action.changed
    assert not core.armed and core.output == (1.5, 2.5) and core.last_command_time is None
    assert core.watchdog_trips == 1 and core.last_trip_ms == 257.8125
    assert core.safe_reason == 'command watchdog: no valve_command for 257.8 ms'
    assert warnings(action) == ['safe output [1.5, 2.5] V: command watchdog: no valve_command '
                                'for 257.8 ms; call ~/arm to resume']
    assert core.on_tick(T0 + 1.0) is NOTHING and core.watchdog_trips == 1, 'one trip'


def test_each_valid_command_restarts_the_watchdog():
    core = make()
    for k in range(10):
        core.on_command(8.0, 2.0, T0 + 0.04 * k)
        assert core.on_tick(T0 + 0.04 * k + 0.045) is NOTHING
    assert core.armed and core.watchdog_trips == 0


def test_the_watchdog_waits_for_the_first_command():
    core = make()
    assert core.on_tick(T0 + 3600.0) is NOTHING
    assert core.armed and core.watchdog_trips == 0


def test_a_watchdog_timeout_of_zero_never_trips():
    core = make(watchdog_timeout=0.0)
    core.on_command(8.0, 2.0, T0)
    assert core.on_tick(T0 + 3600.0) is NOTHING
    assert core.armed and core.output == (8.0, 2.0)


def test_a_command_newer_than_the_tick_does_not_trip_it():
    """The reader thread reads its clock, then the executor applies a command, then the reader
    ticks with its (older) time: the command is from the tick's future, not a stale one."""
    core = make()
    core.on_command(8.0, 2.0, T0)
    assert core.on_tick(T0 - 0.5) is NOTHING
    assert core.armed and core.watchdog_trips == 0


# ---------------------------------------------------------------------- arm, latch, e-stop
def test_the_safe_state_is_latched_until_arm_and_arming_does_not_move_the_valves():
    core = make()
    trip_watchdog(core)
    for k in range(3):
        action = core.on_command(8.0, 2.0, T0 + 2.0 + k)
        assert not action.ok and action.output is None
    assert core.commands_ignored == 3 and core.output == SAFE
    action = core.on_arm()
    assert action.ok and action.output is None and core.output == SAFE
    assert action.message == ('armed (was safe: command watchdog: no valve_command for 1000.0 '
                              'ms); the next valid valve_command is applied; the board speaks '
                              'protocol 1.1: it has no ARM (nothing sent)')
    assert action.logs == (Log('info', f'~/arm: {action.message}'),)
    assert not action.device_arm and core.device_arms == 0
    assert core.armed and core.safe_reason == '' and core.last_command_time is None
    assert core.on_tick(T0 + 10.0) is NOTHING, 'the watchdog restarts with the next command'
    assert core.on_command(7.0, 3.0, T0 + 10.0).output == (7.0, 3.0)


def test_arming_when_armed_restarts_the_watchdog_with_the_next_command():
    core = make()
    core.on_command(8.0, 2.0, T0)
    assert core.on_arm().message.startswith('armed (was safe: -)')
    assert core.on_tick(T0 + 1.0) is NOTHING and core.armed


def test_arm_asks_for_the_boards_arm_only_from_a_device_that_takes_it():
    """A 1.2 device (on_connected(device_arm=True)): a granted ~/arm carries device_arm (the
    node sends ARM before anything else), counted on /diagnostics; refused, it does not; the
    next session's device decides again."""
    core = DriverCore(build_config({}).safety, CAL)
    core.on_connected(device_arm=True)
    trip_watchdog(core)
    action = core.on_arm()
    assert action.ok and action.device_arm and action.output is None
    assert 'ARM sent to the board' in action.message, action.message
    assert core.device_arms == 1 and core.report_values()['board ARMs sent'] == 1
    assert core.on_command(7.0, 3.0, T0 + 10.0).output == (7.0, 3.0)
    core.on_disconnected()
    refused = core.on_arm()
    assert not refused.ok and not refused.device_arm and core.device_arms == 1
    core.on_connected()                     # a 1.1 device next
    action = core.on_arm()
    assert action.ok and not action.device_arm and 'has no ARM' in action.message
    assert core.device_arms == 1


def test_arm_is_refused_while_the_device_is_not_connected():
    core = make(connected=False, arm_at_start=False)
    action = core.on_arm()
    assert not action.ok and action.message == 'refused: device not connected'
    assert action.logs == (Log('info', '~/arm: refused: device not connected'),)
    assert not core.armed and core.safe_reason == 'not armed at start'


def test_arm_is_refused_while_a_sensor_fault_persists():
    core = make(stuck_time=0.2)
    adc = counts()
    for k in range(5):
        sample(core, T0 + 0.1 * k, adc)
    assert core.sensor_fault.startswith('P1 stuck') and not core.armed
    action = core.on_arm()
    assert not action.ok and action.message == f'refused: sensor fault: {core.sensor_fault}'
    assert not core.armed


def test_estop_latches_the_safe_output_and_replaces_the_reason():
    core = make()
    core.on_command(8.0, 2.0, T0)
    action = core.on_estop()
    assert action.ok and action.output == SAFE and action.changed
    assert action.message == 'safe output [0.0, 0.0] V; ~/arm to resume'
    assert warnings(action) == ['safe output [0.0, 0.0] V: e-stop (~/estop); call ~/arm to resume']
    assert not core.armed and core.estops == 1 and core.safe_reason == 'e-stop (~/estop)'
    assert core.on_command(8.0, 2.0, T0 + 0.01).output is None
    # already safe for another reason: the e-stop is said and kept all the same
    core = make()
    trip_watchdog(core)
    action = core.on_estop()
    assert core.safe_reason == 'e-stop (~/estop)' and core.estops == 1
    assert action.output == SAFE and not action.changed and warnings(action)


def test_the_first_reason_since_the_last_arm_is_kept():
    core = make()
    trip_watchdog(core)
    reason = core.safe_reason
    core.on_disconnected()
    action = core.on_device_lost('no sample for 200 ms')
    assert core.safe_reason == reason
    assert warnings(action) == [], 'already safe: no second safe-output warning'
    assert action.output == SAFE, 'the safe output is written all the same'


# ---------------------------------------------------------------------- pressure sensors
def test_out_of_range_pressures_make_a_fault_after_five_samples_in_a_row():
    core = make(pressure_limits=[500e3, 900e3])
    core.on_command(8.0, 2.0, T0)
    low = counts(p1=450e3, p2=600e3)
    for k in range(OUT_OF_RANGE_SAMPLES - 1):
        assert sample(core, T0 + k * 1e-3, low) is NOTHING
    sample(core, T0 + 0.004, counts(p1=600e3, p2=600e3))    # a plausible one resets the run
    for k in range(OUT_OF_RANGE_SAMPLES - 1):
        assert sample(core, T0 + 0.005 + k * 1e-3, low) is NOTHING
    assert core.armed and core.sensor_faults == 0
    action = sample(core, T0 + 0.01, low)
    p1 = CAL.pressure(0, low[0])
    fault = f'P1 out of range ({p1:.0f} Pa, {CAL.adc_volts(low[0]):.3f} V)'
    assert core.sensor_fault == fault and core.sensor_faults == 1
    assert action.output == SAFE and not core.armed
    assert core.safe_reason == f'pressure sensor fault: {fault}'
    assert [(log.level, log.text) for log in action.logs] == [
        ('error', f'pressure sensor fault: {fault}'),
        ('warning', f'safe output [0.0, 0.0] V: pressure sensor fault: {fault}; call ~/arm to '
                    'resume')]
    again = sample(core, T0 + 0.011, low)
    assert again is NOTHING and core.sensor_faults == 1, 'one fault, said once'


def test_a_reading_outside_the_sensor_voltages_is_a_fault_whatever_its_pressure():
    core = make(pressure_limits=[1.0, 5e6])
    adc = (CAL.adc_counts(4.9), counts()[1])        # 1.2 MPa: within the limits, not 4.75 V
    for k in range(OUT_OF_RANGE_SAMPLES):
        action = sample(core, T0 + k * 1e-3, (adc[0] + k % 2, adc[1] + k % 2))
    assert core.sensor_fault.startswith('P1 out of range') and action.output == SAFE


def test_a_stuck_sensor_is_a_fault_after_stuck_time():
    core = make(stuck_time=0.5)
    p1, p2 = counts()
    for k in range(100):                              # P1 moves, P2 is stuck
        action = sample(core, T0 + 0.005 * k, (p1 + k % 2, p2))
        assert action is NOTHING, k
    action = sample(core, T0 + 0.5, (p1, p2))
    assert core.sensor_fault == f'P2 stuck at {p2} counts for 0.50 s'
    assert action.output == SAFE and not core.armed


def test_the_supply_transducer_is_checked_for_its_range_not_for_being_stuck():
    """A board with the supply transducer: a third reading. A regulated supply may hold one
    reading: never 'stuck'; out of its valid volts for OUT_OF_RANGE_SAMPLES samples in a row: a
    sensor fault like P1's (safe output); `plausible` says which readings may be published."""
    core = make(stuck_time=0.5)
    supply = CAL.pressure_counts(SUPPLY, 710e3)
    for k in range(200):                               # P1, P2 move, the supply holds
        p1, p2 = counts()
        adc = (p1 + k % 2, p2 + k % 2, supply)
        action = core.on_sample(adc, [CAL.pressure(i, c) for i, c in enumerate(adc)],
                                T0 + 0.005 * k)
        assert action is NOTHING, (k, core.sensor_fault)
    assert core.plausible == (True, True, True)
    broken = (*counts(), 0)                            # 0 V: below valid_volts
    for k in range(OUT_OF_RANGE_SAMPLES):
        action = core.on_sample(broken, [CAL.pressure(i, c) for i, c in enumerate(broken)],
                                T0 + 1.0 + k * 1e-3)
        assert core.plausible == (True, True, False)
    assert core.sensor_fault.startswith('P_supply out of range'), core.sensor_fault
    assert action.output == SAFE and not core.armed


def test_a_stuck_time_of_zero_never_finds_a_stuck_sensor():
    core = make(stuck_time=0.0)
    for k in range(10):
        assert sample(core, T0 + k, counts()) is NOTHING
    assert core.armed and core.sensor_fault == ''


def test_a_fault_while_already_safe_is_logged_but_keeps_the_reason():
    core = make(arm_at_start=False, stuck_time=0.1)
    for k in range(3):
        action = sample(core, T0 + 0.1 * k)
    assert core.sensor_fault and core.sensor_faults == 1
    assert action.output is None, 'already at the safe output: nothing written'
    assert core.safe_reason == 'not armed at start'


def test_a_fault_while_disarmed_but_not_at_the_safe_output_writes_it():
    core = make(stuck_time=0.1)
    core.on_command(8.0, 2.0, T0)
    core.on_device_refused('test')      # disarmed without a write
    assert core.output == (8.0, 2.0)
    for k in range(3):
        action = sample(core, T0 + 0.1 * k)
        if action.output is not None:
            break
    assert action.output == SAFE and core.output == SAFE


def test_plausible_readings_clear_the_fault_and_arming_works_again():
    core = make(stuck_time=0.1)
    adc = counts()
    sample(core, T0, adc)
    sample(core, T0 + 0.2, adc)
    assert core.sensor_fault and not core.on_arm().ok
    action = sample(core, T0 + 0.21, (adc[0] + 1, adc[1] + 1))
    assert action.logs == (Log('info', 'pressure sensors plausible again; ~/arm to resume'),)
    assert core.sensor_fault == '' and not core.armed, 'still latched'
    assert core.on_arm().ok and core.armed


# ---------------------------------------------------------------------- the connection
def test_every_connection_starts_from_the_safe_output():
    core = make(safe_output=[5.5, 5.5])
    core.on_command(8.0, 2.0, T0)
    assert core.on_disconnected() is True and core.disconnects == 1
    assert core.on_disconnected() is False and core.disconnects == 1
    action = core.on_connected()
    assert action.output == (5.5, 5.5) and action.changed and core.connects == 2
    assert action.logs == ()


def test_a_lost_device_goes_safe_and_says_so():
    core = make()
    core.on_command(8.0, 2.0, T0)
    core.on_disconnected()
    action = core.on_device_lost('no sample for 200 ms')
    assert action.output == SAFE and not core.armed and not core.connected
    assert core.safe_reason == 'device lost (no sample for 200 ms)'
    assert [(log.level, log.text) for log in action.logs] == [
        ('error', 'device lost: no sample for 200 ms; reconnecting'),
        ('warning', 'safe output [0.0, 0.0] V: device lost (no sample for 200 ms); call ~/arm '
                    'to resume')]
    assert not core.on_arm().ok


def test_a_refused_device_disarms_and_gets_nothing_written():
    core = make(connected=False)
    action = core.on_device_refused('protocol version mismatch')
    assert action.output is None and action.logs == ()
    assert not core.armed and core.safe_reason == 'incompatible device: protocol version mismatch'


def test_an_internal_error_goes_safe_and_is_counted():
    core = make()
    core.on_command(8.0, 2.0, T0)
    action = core.on_internal_error('internal error: InjectedError: boom')
    assert action.output == SAFE and not core.armed and core.internal_errors == 1
    assert action.logs[0] == Log('error', 'internal error: InjectedError: boom')
    assert core.safe_reason == 'internal error: InjectedError: boom'


def test_shutdown_writes_the_safe_output_and_disarms():
    core = make(safe_output=[2.0, 3.0])
    core.on_command(8.0, 2.0, T0)
    action = core.on_shutdown()
    assert action.output == (2.0, 3.0) and action.changed
    assert not core.armed and core.safe_reason == 'shutdown'
    assert core.on_shutdown().output == (2.0, 3.0), 'written even when already there'
    assert core.on_tick(T0 + 1.0) is NOTHING and core.watchdog_trips == 0, 'no trip once stopped'


# ---------------------------------------------------------------------- diagnostics, config
def test_report_values_carry_the_state_and_counters():
    core = make()
    core.on_command(12.0, 2.0, T0)
    core.on_command(math.nan, 2.0, T0)
    core.on_estop()
    core.on_command(8.0, 2.0, T0)
    values = core.report_values()
    assert values == {
        'armed': False, 'safe reason': 'e-stop (~/estop)', 'output u1 (V)': 0.0,
        'output u2 (V)': 0.0, 'watchdog timeout (ms)': 50.0, 'watchdog trips': 0,
        'last watchdog trip after (ms)': values['last watchdog trip after (ms)'], 'e-stops': 1,
        'board ARMs sent': 0, 'sensor fault': 'none', 'sensor faults': 0, 'commands received': 2,
        'commands clipped': 1, 'non-finite commands': 1, 'commands ignored (safe)': 1}
    assert math.isnan(values['last watchdog trip after (ms)'])


@pytest.mark.parametrize('field, value, words', [
    ('valve_limits', (5.0, 5.0), 'min < max'),
    ('valve_limits', (-1.0, 5.0), 'min < max'),
    ('safe_output', (0.0, 11.0), 'must be in'),
    ('safe_output', (math.nan, 0.0), 'finite'),
    ('pressure_limits', (1.0,), '2 finite numbers'),
    ('watchdog_timeout', -0.1, '>= 0'),
    ('stuck_time', math.nan, '>= 0'),
])
def test_safety_config_refuses_bad_values_naming_the_field(field, value, words):
    values = dict(safe_output=(0.0, 0.0), valve_limits=(0.0, 10.0), watchdog_timeout=0.05,
                  pressure_limits=(5e4, 9e5), stuck_time=0.5, arm_at_start=True)
    values[field] = value
    with pytest.raises(ValueError, match=f'^{field}: .*{words}'):
        SafetyConfig(**values)
