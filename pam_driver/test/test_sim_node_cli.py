"""sim_node's command line: --help, and invalid parameters that must stop it with a clear error."""

from __future__ import annotations

import subprocess
import time

import pytest

EXIT_TIMEOUT = 30.0   # s; a bad configuration is detected before any sampling starts

# The parameter contract of sim_node (names, and a unit or default shown by --help).
CONTRACT = {
    'plant_parameters': "'default'", 'scenario': "''", 'friction_law': "'proposed'",
    'force_model': "'proposed'", 'joint_mode': "'free'",
    'initial_state': '[0.0, 0.0, 450000.0, 450000.0]', 'initial_command': '[5.5, 5.5]',
    'pressure_noise_std': 'Pa', 'quantisation_bits': '-1', 'seed': '0',
    'timing': "'realtime'", 'rate': '1000.0', 'publish_clock': 'false',
    'lockstep_timeout': '0.5', 'frame_id': "'pam_joint'", 'publish_supply_pressure': 'false',
}


def test_help_lists_every_parameter(sim_node):
    sim = sim_node('--help', raw=True)
    assert sim.wait_exit(EXIT_TIMEOUT) == 0, sim.stderr
    text = sim.stdout
    lines = {line.strip().split(' ', 1)[0]: line for line in text.splitlines()
             if line.startswith('  ') and not line.startswith('    ')}
    for name, shown in CONTRACT.items():
        assert name in lines, f'--help does not list {name!r}:\n{text}'
        assert shown in lines[name], f'--help line of {name!r} lacks {shown!r}: {lines[name]}'
    for unit in ('Hz', 'Pa', 'rad', ' V', ' s'):
        assert unit in text
    assert '(old name: mismatch)' in lines['scenario'], lines['scenario']


@pytest.mark.parametrize('args, expected', [
    (['-p', 'joint_mode:=sideways'], ['joint_mode', 'sideways', 'free, locked']),
    (['-p', 'plant_parameters:=/nonexistent.yaml'], ['plant_parameters', '/nonexistent.yaml']),
    (['-p', 'initial_state:=[0.0, 0.0, 450000.0]'], ['initial_state', '4 numbers']),
    (['-p', 'rate:=1000'], ['rate', '1000.0']),
    (['-p', 'timing:=fast'], ['timing', 'lockstep']),
    (['-p', 'rate:=50.0'], ['rate', 'out of range']),
], ids=['joint_mode', 'missing_plant_file', 'initial_state_length', 'rate_type', 'timing',
        'rate_range'])
def test_invalid_parameter_exits_with_a_clear_error(sim_node, args, expected):
    start = time.monotonic()
    sim = sim_node(*args)
    try:
        code = sim.wait_exit(EXIT_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f'sim_node kept running with {args}; stderr:\n{sim.stderr}')
    err = sim.stderr
    assert code != 0
    assert 'Traceback' not in err, err
    for word in expected:
        assert word in err, f'{word!r} not in stderr:\n{err}'
    assert time.monotonic() - start < EXIT_TIMEOUT


def test_malformed_scenario_file_is_reported(sim_node, tmp_path):
    bad = tmp_path / 'bad_scenario.yaml'
    bad.write_text('name: bad\nfactors:\n  no_such_key: 2.0\n')
    sim = sim_node('-p', f'scenario:={bad}')
    assert sim.wait_exit(EXIT_TIMEOUT) != 0
    err = sim.stderr
    assert 'Traceback' not in err, err
    assert "parameter 'scenario'" in err and 'no_such_key' in err, err


def test_the_old_parameter_name_still_works_with_a_warning(sim_node):
    """-p mismatch:=mild (the name of earlier releases) is read as scenario, with a warning
    saying so; the node declares only scenario."""
    sim = sim_node('-p', 'mismatch:=mild', '-p', 'timing:=lockstep')
    sim.wait_for(lambda: "scenario: 'mild'" in sim.stderr, EXIT_TIMEOUT, 'the scenario line')
    assert "parameter 'mismatch' is the old name of 'scenario'" in sim.stderr, sim.stderr
    assert 'ignoring unknown parameter' not in sim.stderr, sim.stderr


def test_unknown_command_line_argument(sim_node):
    sim = sim_node('--rate', '500', raw=True)
    assert sim.wait_exit(EXIT_TIMEOUT) == 2
    assert "unknown argument '--rate'" in sim.stderr
