"""Parameter files: the two shipped sets, and validation errors that name key and file."""

import math

import pytest
import yaml

from pam_model.mismatch import load_scenario
from pam_model.parameters import (
    ParameterError,
    Parameters,
    load_parameters,
    resolve_parameter_file,
    save_parameters,
)


def write_variant(tmp_path, edit):
    data = yaml.safe_load(resolve_parameter_file('default').read_text())
    edit(data)
    path = tmp_path / 'params.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def test_default_and_printed_sets_differ_only_in_pam2_p_w2():
    default, printed = load_parameters('default'), load_parameters('printed')
    assert default.p_w2_2 == 15.75 and printed.p_w2_2 == -15.75
    diff = [f for f in Parameters._fields if getattr(default, f) != getattr(printed, f)]
    assert diff == ['p_w2_2']


def test_table_ii_values():
    p = load_parameters()
    assert (p.r_p, p.r, p.L0, p.J, p.P_tank, p.P_out) == (0.006, 0.0365, 0.165, 4.263e-4,
                                                         0.71e6, 0.1013e6)
    assert (p.A1_1, p.A2_1, p.A1_2, p.A2_2) == (5.184e-8, 7.776e-8, 5.184e-8, 7.776e-8)


def test_round_trip(tmp_path):
    p = load_parameters()
    save_parameters(p, tmp_path / 'copy.yaml')
    assert load_parameters(tmp_path / 'copy.yaml') == p


@pytest.mark.parametrize('edit, message', [
    (lambda d: d.update(J2=1.0), "unknown key 'J2'"),
    (lambda d: d['pam1'].update(A3=1.0), "unknown key pam1.'A3'"),
    (lambda d: d.pop('k_s'), "missing key 'k_s'"),
    (lambda d: d['pam2'].pop('p_w1'), "missing key pam2.'p_w1'"),
    (lambda d: d.update(J=0.0), "key 'J': must be > 0"),
    (lambda d: d['pam1'].update(A1=-5e-8), "key 'pam1.A1': must be > 0"),
    (lambda d: d.update(c_s=float('nan')), "key 'c_s': must be finite"),
    (lambda d: d.update(mu_p=float('inf')), "key 'mu_p': must be finite"),
    (lambda d: d.update(k='fast'), "key 'k': expected a number"),
    (lambda d: d.update(P_tank=0.9e5), "key 'P_tank': must exceed P_out"),
    (lambda d: d.update(k=1.0), "key 'k'"),
    (lambda d: d.update(D3=-1.0), "muscle volume at L0"),
])
def test_invalid_values_name_key_and_file(tmp_path, edit, message):
    path = write_variant(tmp_path, edit)
    with pytest.raises(ParameterError) as info:
        load_parameters(path)
    assert message in str(info.value)
    assert str(path) in str(info.value)


def test_numbers_written_without_a_dot_are_accepted(tmp_path):
    """YAML 1.1 reads 1e-5 as a string; the loader accepts numeric strings."""
    path = write_variant(tmp_path, lambda d: d.update(J='4.263e-4'))
    assert load_parameters(path).J == 4.263e-4


@pytest.mark.parametrize('text, message', [
    ('r_p: [0.006\n', 'not valid YAML'),
    ('- 1\n- 2\n', 'expected a mapping'),
    ('', 'expected a mapping'),
])
def test_malformed_files(tmp_path, text, message):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(ParameterError, match=message):
        load_parameters(path)


def test_missing_file_is_a_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match='cannot read'):
        load_parameters(tmp_path / 'nope.yaml')


def test_mild_mismatch_scenario():
    nominal = load_parameters()
    scenario = load_scenario('mild')
    plant = scenario.apply(nominal)
    assert plant.mu_s == pytest.approx(1.2 * nominal.mu_s)
    assert plant.mu_p == pytest.approx(0.7 * nominal.mu_p)
    assert plant.A1_1 == pytest.approx(1.15 * nominal.A1_1)
    assert plant.A1_2 == pytest.approx(1.15 * nominal.A1_2)
    assert plant.A2_1 == pytest.approx(0.9 * nominal.A2_1)
    assert plant.k1 == pytest.approx(1.05 * nominal.k1)
    assert plant.k2 == pytest.approx(0.95 * nominal.k2)
    assert plant.p_w2_1 == pytest.approx(nominal.p_w2_1 + 2.0)
    assert plant.p_w2_2 == pytest.approx(nominal.p_w2_2 - 1.5)
    assert plant.J == nominal.J
    assert scenario.sensor.noise_std == 2000.0 and scenario.sensor.bits == 12
    assert scenario.sensor.resolution == pytest.approx(1e6 / 4095)


@pytest.mark.parametrize('text, message', [
    ('factors: {Jx: 2}\n', "unknown parameter key factors.'Jx'"),
    ('offsets: {pam3.p_w2: 1}\n', "unknown parameter key offsets.'pam3.p_w2'"),
    ('factors: {J: -1}\n', "key 'J': must be > 0"),
    ('factors: {J: .nan}\n', 'must be finite'),
    ('sensor: {noise: 3}\n', "unknown sensor key 'noise'"),
    ('colour: red\n', "unknown key 'colour'"),
])
def test_invalid_scenarios(tmp_path, text, message):
    path = tmp_path / 'scenario.yaml'
    path.write_text(text)
    with pytest.raises(ParameterError, match=message.replace('.', r'\.').replace('(', r'\(')):
        load_scenario(path).apply(load_parameters())


def test_parameters_pass_into_compiled_kernels_unchanged():
    from pam_model import physics
    p = load_parameters()
    gas = physics.gas_constants(p)
    assert gas.c_star == pytest.approx((2 / 2.4) ** (1.4 / 0.4))
    assert math.isclose(gas.c_star, 0.528, abs_tol=1e-3)
