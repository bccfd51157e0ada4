"""driver_node's diagnostics policy (pam_driver.driver_health), called directly: no node, no
device."""

from pam_driver.driver_health import ERROR, FAULT_COUNTERS, OK, WARN, DriverHealth, SafetyState

ARMED = SafetyState(connected=True, armed=True, sensor_fault='', safe_reason='', last_error='')


def values(**changes) -> dict:
    base = dict.fromkeys(FAULT_COUNTERS, 0)
    base.update({'board vents': 0, 'device refused': 'none', 'achieved rate (Hz)': 999.96})
    base.update(changes)
    return base


def test_armed_and_quiet_is_ok_with_the_rate():
    assert DriverHealth().judge(values(), ARMED) == (OK, 'armed, 1000.0 Hz')


def test_not_connected_refused_and_sensor_fault_are_errors():
    lost = SafetyState(False, False, '', 'device lost', 'read timeout')
    level, message = DriverHealth().judge(values(), lost)
    assert level == ERROR
    assert message == 'device not connected (read timeout); safe output: device lost'
    refused = DriverHealth().judge(values(**{'device refused': 'protocol 2.0'}), lost)
    assert refused[0] == ERROR and refused[1].startswith('device refused: protocol 2.0')
    fault = SafetyState(True, False, 'p1 stuck', 'pressure sensor fault', '')
    level, message = DriverHealth().judge(values(), fault)
    assert level == ERROR and 'pressure sensor fault: p1 stuck' in message


def test_a_vent_is_an_error_while_armed_and_a_warning_while_safe():
    health = DriverHealth()
    level, message = health.judge(values(**{'board vents': 2}), ARMED)
    assert level == ERROR
    assert message.startswith('board vented 2 times in the last window (2 in all)')
    assert health.judge(values(**{'board vents': 2}), ARMED) == (OK, 'armed, 1000.0 Hz')
    safe = SafetyState(True, False, '', 'e-stop', '')
    level, message = health.judge(values(**{'board vents': 3}), safe)
    assert level == WARN and 'board vented 1 times' in message and 'safe output: e-stop' in message


def test_fault_counters_warn_only_while_they_grow():
    health = DriverHealth()
    level, message = health.judge(values(**{'crc errors': 2, 'disconnects': 1}), ARMED)
    assert level == WARN
    assert message == 'in the last window: 2 crc errors, 1 disconnects'
    assert health.judge(values(**{'crc errors': 2, 'disconnects': 1}), ARMED)[0] == OK
