"""Every shipped params file (each package's config/*.yaml of node parameters) against the node's
parameter table (its ParamSpec rows): every key is a parameter of the node, every value of the
parameter's type and inside its range or choices. A file named after its node (sim_node.yaml,
driver_node.yaml, ukf_node.yaml) says it holds the node's defaults: each value is the table's
default and every parameter with a value is there. So a copy of ukf_node.yaml with `tuning:
paper` gets the paper's tuning (the file once also set process_noise, measurement_noise and
initial_covariance, whose defaults are empty, and those silently overrode the preset)."""

from pathlib import Path

import pytest
import yaml

from pam_common.node_params import check_all, defaults
from pam_common.params_files import PARAMETERS_KEY, ros_args_problem
from pam_controller import pi_node, reference_node
from pam_driver import driver_config, sim_config
from pam_estimator import ukf_config

ROOT = Path(__file__).resolve().parents[2]
TABLES = {'sim_node': sim_config.PARAMETERS, 'driver_node': driver_config.PARAMETERS,
          'ukf_node': ukf_config.PARAMETERS, 'pi_node': pi_node.PARAMETERS,
          'reference_node': reference_node.PARAMETERS}
ROS_OWN = {'use_sim_time'}          # rclpy's own parameter of every node
TYPES = {'string': (str,), 'double': (float,), 'integer': (int,), 'bool': (bool,)}
FILES = sorted(f for f in ROOT.glob('pam_*/config/*.yaml') if PARAMETERS_KEY in f.read_text())
DEFAULTS_FILES = [f for f in FILES if f.stem in TABLES]


def sections(path: Path) -> list[tuple[str, dict]]:
    """(node, parameter values) of each section; a '/**' section is the node the file is named
    after (sim_node_mild.yaml: sim_node)."""
    found = []
    for key, section in yaml.safe_load(path.read_text()).items():
        node = key.rsplit('/', 1)[-1]
        if key == '/**':
            node = max((n for n in TABLES if path.stem.startswith(n)), key=len)
        found.append((node, section[PARAMETERS_KEY]))
    return found


def type_problem(spec, value) -> str:
    """'' if `value` (as the YAML parser reads it, like rcl) has the parameter's type."""
    element = spec.type_name.removesuffix('[]')
    values = value if spec.type_name.endswith('[]') and isinstance(value, list) else [value]
    if spec.type_name.endswith('[]') != isinstance(value, list) or not all(
            isinstance(v, TYPES[element]) and (element == 'bool' or not isinstance(v, bool))
            for v in values):
        return f'{spec.name}: {value!r} is not {spec.type_name}'
    return ''


def test_the_files_are_found():
    names = {str(f.relative_to(ROOT)) for f in FILES}
    assert names == {'pam_bringup/config/bringup.yaml', 'pam_driver/config/driver_node.yaml',
                     'pam_driver/config/sim_node.yaml', 'pam_driver/config/sim_node_mild.yaml',
                     'pam_estimator/config/ukf_node.yaml',
                     'pam_estimator/config/ukf_node_paper.yaml'}
    assert [f.stem for f in DEFAULTS_FILES] == ['driver_node', 'sim_node', 'ukf_node']


@pytest.mark.parametrize('path', FILES, ids=lambda f: f'{f.parent.parent.name}/{f.name}')
def test_every_key_and_value_fits_the_table(path):
    assert ros_args_problem(['node', '--ros-args', '--params-file', str(path)]) is None
    for node, values in sections(path):
        specs = {spec.name: spec for spec in TABLES[node]}
        assert set(values) - set(specs) - ROS_OWN == set(), node
        problems = [type_problem(specs[name], v) for name, v in values.items() if name in specs]
        assert not any(problems), (node, problems)
        given = {name: v for name, v in values.items() if name in specs}
        check_all(TABLES[node], {**defaults(TABLES[node]), **given})     # ranges, choices


@pytest.mark.parametrize('path', DEFAULTS_FILES, ids=lambda f: f.name)
def test_a_file_named_after_its_node_holds_its_defaults(path):
    [(node, values)] = sections(path)
    table = defaults(TABLES[node])
    assert {name: (v, table[name]) for name, v in values.items() if v != table[name]} == {}
    # an empty default (e.g. ukf_node's process_noise: 'empty: from the tuning preset') cannot
    # be written as a value: such a parameter is named in the file's comments instead
    empty = {name for name, v in table.items() if v == []}
    assert set(table) - set(values) == empty
    text = path.read_text()
    assert all(name in text for name in empty)


def test_a_copy_of_ukf_node_yaml_with_the_paper_tuning_gets_the_papers_tuning():
    from pam_estimator.pam_ukf import TUNINGS
    [(_, values)] = sections(ROOT / 'pam_estimator' / 'config' / 'ukf_node.yaml')
    for tuning in ('default', 'paper'):
        config = ukf_config.build_config({**values, 'tuning': tuning})
        assert config.ukf.tuning == TUNINGS[tuning]


def _node_configs():
    """(parameter table, its NodeConfig class) of every node whose config is one field per
    row (the others build richer objects from their rows: SimConfig, DriverConfig, UkfConfig,
    PiConfig)."""
    from pam_bag import bag_play, bag_record
    from pam_bringup import foxglove_view, tracking_report
    from pam_controller import profile_player
    return [(reference_node.PARAMETERS, reference_node.ReferenceConfig),
            (profile_player.PARAMETERS, profile_player.PlayerConfig),
            (bag_record.PARAMETERS, bag_record.RecordOptions),
            (bag_play.PARAMETERS, bag_play.PlayOptions),
            (tracking_report.PARAMETERS, tracking_report.ReportConfig),
            (foxglove_view.PARAMETERS, foxglove_view.ViewConfig)]


def test_every_node_config_has_one_field_per_parameter():
    for table, config in _node_configs():
        assert config.parameter_names() == [spec.name for spec in table], config.__name__
        built = config.from_values(defaults(table))
        with pytest.raises(AttributeError):      # frozen
            setattr(built, table[0].name, None)
