"""Calibration YAML: the round trip of every conversion and validation errors naming file + key."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from pam_driver import calibration
from pam_driver.calibration import CalibrationError

SHIPPED = Path(__file__).resolve().parent.parent / 'config' / 'driver_calibration.yaml'


def test_shipped_file_loads_and_round_trips():
    cal = calibration.load(SHIPPED)
    for ch in (0, 1):
        for p in (101300.0, 200e3, 453210.0, 700e3):
            counts = cal.pressure_counts(ch, p)
            assert abs(cal.pressure(ch, counts) - p) <= 0.5 * cal.pressure_resolution(ch) + 1e-6
    for a in (-0.4, -0.01, 0.0, 0.123, 0.4):
        assert abs(cal.angle(cal.encoder_counts(a)) - a) <= 0.5 * cal.angle_resolution + 1e-12
    for t in (-2.6, 0.0, 1.234):
        assert abs(cal.torque(cal.torque_counts(t)) - t) <= 0.5 * cal.torque_resolution + 1e-12
    for u in (0.0, 3.3, 5.5, 10.0):
        assert abs(cal.valve_volts(cal.dac_counts(u)) - u) <= 0.5 * 10.0 / cal.dac_full_scale
    assert cal.dac_counts(10.0) == cal.dac_full_scale and cal.dac_counts(0.0) == 0
    # 0.5 V is atmospheric (gauge 0)
    assert math.isclose(cal.pressure(0, cal.adc_counts(0.5)), 101300.0, abs_tol=200.0)


def _write(tmp_path, mutate):
    data = yaml.safe_load(SHIPPED.read_text())
    mutate(data)
    path = tmp_path / 'cal.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def _set(section, key, value):
    return lambda d: d[section].__setitem__(key, value)


@pytest.mark.parametrize('mutate, key', [
    (lambda d: d['pressure']['p1'].__setitem__('pascal_per_volt', -1.0),
     'pressure.p1.pascal_per_volt'),
    (lambda d: d['pressure']['p2'].pop('zero_volts'), 'pressure.p2.zero_volts'),
    (lambda d: d['adc'].__setitem__('bits', 40), 'adc.bits'),
    (lambda d: d['adc'].__setitem__('vref_volts', 'five'), 'adc.vref_volts'),
    (lambda d: d['encoder'].__setitem__('sign', 0), 'encoder.sign'),
    (_set('torque', 'newton_metre_per_volt', 0.0), 'torque.newton_metre_per_volt'),
    (_set('valve', 'volts_at_full_scale', 5.0), 'valve.volts_at_full_scale'),
    (lambda d: d['pressure']['p1'].__setitem__('valid_volts', [4.0, 1.0]),
     'pressure.p1.valid_volts'),
    (lambda d: d.__setitem__('format_version', 2), 'format_version'),
    (lambda d: d.pop('encoder'), 'encoder.counts_per_rev'),
])
def test_validation_names_file_and_key(tmp_path, mutate, key):
    path = _write(tmp_path, mutate)
    with pytest.raises(CalibrationError) as info:
        calibration.load(path)
    assert str(path) in str(info.value) and f"'{key}'" in str(info.value), str(info.value)


def test_unreadable_and_bad_yaml(tmp_path):
    with pytest.raises(CalibrationError, match='cannot read'):
        calibration.load(tmp_path / 'missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('adc: [1, 2\n')
    with pytest.raises(CalibrationError, match='invalid YAML'):
        calibration.load(bad)
    bad.write_text('- 1\n')
    with pytest.raises(CalibrationError, match='mapping'):
        calibration.load(bad)


def test_driver_config_reports_calibration_errors(tmp_path):
    from pam_driver.driver_config import ConfigError, build_config
    path = _write(tmp_path, lambda d: d['adc'].__setitem__('bits', 4))
    with pytest.raises(ConfigError, match=r"calibration_file.*adc\.bits"):
        build_config({'calibration_file': str(path)})
    with pytest.raises(ConfigError, match='valve_limits'):
        build_config({'valve_limits': [5.0, 1.0]})
    assert build_config({'calibration_file': str(SHIPPED)}).safety.watchdog_timeout == 0.05


def test_the_supply_channel_is_optional(tmp_path):
    """The shipped file calibrates the supply transducer (channel SUPPLY); a file without a
    pressure.supply section loads as before, without it; a bad supply value names its key."""
    cal = calibration.load(SHIPPED)
    assert cal.has_supply
    for p in (101300.0, 690e3, 710e3):
        counts = cal.pressure_counts(calibration.SUPPLY, p)
        assert abs(cal.pressure(calibration.SUPPLY, counts) - p) <= 0.5 * cal.pressure_resolution(
            calibration.SUPPLY) + 1e-6
    old = calibration.load(_write(tmp_path, lambda d: d['pressure'].pop('supply')))
    assert not old.has_supply and len(old.channels) == 2
    bad = _write(tmp_path, lambda d: d['pressure']['supply'].update(pascal_per_volt=-1))
    with pytest.raises(CalibrationError, match=r'pressure\.supply\.pascal_per_volt'):
        calibration.load(bad)
