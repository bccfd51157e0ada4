"""driver_node and pam-emulator command lines: --help and configuration errors."""

from __future__ import annotations

import subprocess

from pam_common.testing import child_env, executable


def _run(name, *args, timeout=30.0):
    return subprocess.run([executable(name, 'pam_driver'), *args], capture_output=True,
                          text=True, timeout=timeout, env=child_env(0))


def test_help_texts():
    out = _run('driver_node', '--help')
    assert out.returncode == 0
    for word in ('port', 'calibration_file', 'watchdog_timeout', 'safe_output', '~/arm',
                 'reconnect_backoff', 'inject_internal_error', 'supply_pressure'):
        assert word in out.stdout
    out = _run('pam-emulator', '--help')
    assert out.returncode == 0
    for word in ('--link', '--locked', '--mismatch', '--garbage-every', '--disconnect-at',
                 '--stuck-sensor', '--drop-every', '--protocol-version', '--status-file',
                 '--supply-sensor', '--broken-sensor'):
        assert word in out.stdout


def test_bad_calibration_is_a_clean_error(tmp_path):
    bad = tmp_path / 'cal.yaml'
    bad.write_text('format_version: 1\nadc: {bits: 12}\n')
    out = _run('driver_node', '--ros-args', '-p', f'calibration_file:={bad}')
    assert out.returncode == 2, out.stderr
    assert "adc.vref_volts" in out.stderr and str(bad) in out.stderr
    out = _run('pam-emulator', '--calibration', str(bad))
    assert out.returncode == 2 and 'adc.vref_volts' in out.stderr, out.stderr


def test_emulator_rejects_a_bad_protocol_version():
    out = _run('pam-emulator', '--protocol-version', '2')
    assert out.returncode == 2 and 'expected MAJOR.MINOR' in out.stderr, out.stderr
    out = _run('pam-emulator', '--protocol-version', '1.256')
    assert out.returncode == 2 and 'versions are bytes' in out.stderr, out.stderr


def test_emulator_supply_sensor_needs_its_calibration(tmp_path):
    """--supply-sensor with a calibration without pressure.supply (a 1.0 board's file): one
    line naming the file; --broken-sensor supply without the transducer likewise."""
    import yaml

    from pam_driver.calibration import default_path
    data = yaml.safe_load(default_path().read_text())
    data['pressure'].pop('supply')
    old = tmp_path / 'cal.yaml'
    old.write_text(yaml.safe_dump(data))
    out = _run('pam-emulator', '--supply-sensor', '--calibration', str(old))
    assert out.returncode == 2 and 'no pressure.supply section' in out.stderr, out.stderr
    assert str(old) in out.stderr
    out = _run('pam-emulator', '--broken-sensor', 'supply')
    assert out.returncode == 2 and 'needs --supply-sensor' in out.stderr, out.stderr


def test_emulator_rejects_an_initial_command_out_of_range():
    out = _run('pam-emulator', '--initial-command', '5.5', '10.5')
    assert out.returncode == 2 and '--initial-command must be within [0, 10] V' in out.stderr, \
        out.stderr


def test_a_bad_joint_states_rate_is_refused():
    """Its range is checked at start-up (the board's rate only at the handshake: above it,
    every sample); one line, exit code 2; --help shows it with its unit and range."""
    for value, words in (('20000.0', 'out of range [0.0, 10000.0]'), ('-5.0', 'out of range')):
        out = _run('driver_node', '--ros-args', '-p', f'joint_states_rate:={value}')
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 2, out.stderr
        assert len(lines) == 1 and "parameter 'joint_states_rate'" in lines[0], out.stderr
        assert words in lines[0], out.stderr
    out = _run('driver_node', '--help')
    assert '  joint_states_rate (double, Hz) = 1000.0  [0.0 .. 10000.0]' in out.stdout
    assert "  joint_name (string) = 'seesaw_joint'" in out.stdout


def test_emulator_builds_the_realistic_plant_and_refuses_bad_effects(tmp_path):
    """--mismatch realistic (unmodelled effects) starts; a bad effects value is one line
    naming the key, exit code 2."""
    out = _run('pam-emulator', '--mismatch', 'realistic', '--duration', '0.5')
    assert out.returncode == 0, out.stderr
    assert 'pam-emulator: device:' in out.stdout, out.stdout
    from pam_driver.emulator import Emulator, build_parser
    rig = Emulator(build_parser().parse_args(['--mismatch', 'realistic'])).rig
    assert rig.plant is not None and rig.plant.effects.hysteresis_band == 2.0
    bad = tmp_path / 'bad_effects.yaml'
    bad.write_text('name: bad\neffects:\n  valve_time_constant: -0.005\n')
    out = _run('pam-emulator', '--mismatch', str(bad))
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and 'effects: valve_time_constant' in lines[0], out.stderr
