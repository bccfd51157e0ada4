"""pam_bringup.params_namespace: the stack's params file made to apply in another namespace.

The copy is judged by what rcl gives a node from it: nodes of this test process (rclpy, its real
rcl parse of --params-file and its matching of the keys; no DDS traffic needed) read the source
file in /pam and the copy in /joint2, and must get the same parameters. rcl's own rules the copy
relies on are held first (sections in file order, the later winning; a key given twice is one
section at its first place). Then the rewrite itself: re-keyed sections in place, `/**` and other
wildcard sections and other namespaces' sections kept, the file's own section for the namespace
winning, nested keys and parameters, value types kept, the root and nested namespaces, no copy
when none is needed, the warnings, and the one-line errors of a malformed file.
"""

from __future__ import annotations

import itertools
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from pam_bringup.params_namespace import (
    file_sections,
    for_namespace,
    rekeyed,
    run_directory,
    stack_params,
)
from pam_bringup.stack import DEFAULT_NAMESPACE, default_params_file, every_node
from pam_common.testing import MALFORMED_PARAMS_FILES, malformed_params_file

STACK = [node.name for node in every_node()]
_names = itertools.count()


def write(folder: Path, text: str, name: str = 'params.yaml') -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


def node_parameters(ros_context, fqn: str, path: Path | None) -> dict:
    """{name: value} of a real rclpy node of this process of full name `fqn`, started with
    `--params-file path` (every override declared)."""
    import rclpy
    namespace, _, name = fqn.rpartition('/')
    args = ['--ros-args', '--params-file', str(path)] if path is not None else []
    node = rclpy.create_node(name, namespace=namespace or '/', context=ros_context,
                             cli_args=args, automatically_declare_parameters_from_overrides=True,
                             start_parameter_services=False, enable_rosout=False)
    try:
        values = {n: p.value for n, p in node.get_parameters_by_prefix('').items()}
    finally:
        node.destroy_node()
    return {n: list(v) if not isinstance(v, (str, bool, int, float)) else v
            for n, v in values.items()}


def rcl_parameters(ros_context, path: Path, fqn: str) -> dict:
    """The parameters rcl gives the node of full name `fqn` from `--params-file path`, less
    those every rclpy node declares itself (use_sim_time, ...) at their own values."""
    own = node_parameters(ros_context, fqn, None)
    return {n: v for n, v in node_parameters(ros_context, fqn, path).items()
            if n not in own or own[n] != v}


def copy_for(tmp_path: Path, source: Path, namespace: str = '/joint2', nodes=('sim_node',)):
    out = tmp_path / f'run{next(_names)}'
    out.mkdir()
    return stack_params(source, namespace, list(nodes), out)


# ---------------------------------------------------------------------------- rcl's rules
def test_rcl_takes_the_sections_of_a_node_in_file_order_the_later_winning(tmp_path,
                                                                           ros_context):
    """Between `/**/sim_node:` and `/joint2/sim_node:` in one file the one further down wins,
    not the more specific one; a key given twice is one section, at its first place."""
    wildcard_first = write(tmp_path, '''\
        /**/sim_node: {ros__parameters: {rate: 500.0, seed: 1}}
        /joint2/sim_node: {ros__parameters: {rate: 2000.0}}
        ''', 'a.yaml')
    explicit_first = write(tmp_path, '''\
        /joint2/sim_node: {ros__parameters: {rate: 2000.0}}
        /**/sim_node: {ros__parameters: {rate: 500.0, seed: 1}}
        ''', 'b.yaml')
    twice = write(tmp_path, '''\
        /joint2/sim_node: {ros__parameters: {rate: 2000.0}}
        /**: {ros__parameters: {rate: 500.0}}
        /joint2/sim_node: {ros__parameters: {rate: 3000.0, seed: 4}}
        ''', 'c.yaml')
    assert rcl_parameters(ros_context, wildcard_first, '/joint2/sim_node') == {
        'rate': 2000.0, 'seed': 1}
    assert rcl_parameters(ros_context, explicit_first, '/joint2/sim_node') == {
        'rate': 500.0, 'seed': 1}
    assert rcl_parameters(ros_context, twice, '/joint2/sim_node') == {'rate': 500.0, 'seed': 4}


# ---------------------------------------------------------------------------- the default file
def test_the_default_file_gives_every_node_in_joint2_what_it_gives_it_in_pam(tmp_path,
                                                                             ros_context):
    source = default_params_file()
    params = copy_for(tmp_path, source, 'joint2', STACK)     # as the launch argument gives it
    assert params.source == source and params.file.parent.parent == tmp_path
    keys = [key for key, _ in file_sections(source)]
    assert sorted(keys) == sorted(f'/pam/{name}' for name in STACK)
    assert params.moved == tuple(keys) and params.warnings == ()
    assert [key for key, _ in file_sections(params.file)] == [
        key.replace('/pam/', '/joint2/') for key in keys]
    for name in STACK:
        in_pam = rcl_parameters(ros_context, source, f'/pam/{name}')
        assert in_pam, f'the default file sets nothing for /pam/{name}'
        # the bug: the file itself gives the node nothing in /joint2
        assert rcl_parameters(ros_context, source, f'/joint2/{name}') == {}
        assert rcl_parameters(ros_context, params.file, f'/joint2/{name}') == in_pam, name
    assert rcl_parameters(ros_context, params.file, '/joint2/sim_node')['scenario'] == 'mild'
    assert 'bringup.yaml' in params.describe() and str(params.file) in params.describe()


def test_no_copy_in_the_default_namespace_or_without_a_section_to_move(tmp_path):
    source = default_params_file()
    for namespace in (DEFAULT_NAMESPACE, 'pam', '/pam/'):
        params = copy_for(tmp_path, source, namespace, STACK)
        assert params.file == source and params.moved == () and params.warnings == ()
        assert not list(params.file.parent.glob('run*'))
    wildcards = write(tmp_path, '/**/sim_node: {ros__parameters: {rate: 500.0}}\n')
    params = copy_for(tmp_path, wildcards)
    assert params.file == wildcards and params.moved == () and params.warnings == ()
    assert not [p for p in tmp_path.rglob('*.yaml') if p != wildcards]
    assert params.describe() == f'params file {wildcards}'


# ---------------------------------------------------------------------------- the rewrite
def test_rekeyed_moves_only_keys_under_the_default_namespace():
    assert rekeyed('/pam/sim_node', '/joint2') == '/joint2/sim_node'
    assert rekeyed('pam/sim_node', '/joint2') == '/joint2/sim_node'
    assert rekeyed('/pam/*', '/joint2') == '/joint2/*'
    assert rekeyed('/pam/**', '/lab/joint2') == '/lab/joint2/**'
    assert rekeyed('/pam/sim_node', '/') == '/sim_node'
    for key in ('/**', '/**/sim_node', '/*/sim_node', '/joint3/sim_node', '/pam', 'sim_node',
                '/pama/sim_node', '/pa*/sim_node'):
        assert rekeyed(key, '/joint2') is None, key


def test_wildcard_sections_and_other_namespaces_are_kept_in_place(tmp_path, ros_context):
    source = write(tmp_path, '''\
        /**: {ros__parameters: {seed: 1}}
        /**/sim_node: {ros__parameters: {rate: 500.0}}
        /pam/sim_node: {ros__parameters: {rate: 2000.0, scenario: mild}}
        /*/sim_node: {ros__parameters: {joint_mode: locked}}
        /joint3/sim_node: {ros__parameters: {scenario: strong}}
        /pam/*: {ros__parameters: {frame_id: here}}
        ''')
    params = copy_for(tmp_path, source)
    assert params.moved == ('/pam/sim_node', '/pam/*')
    assert [key for key, _ in file_sections(params.file)] == [
        '/**', '/**/sim_node', '/joint2/sim_node', '/*/sim_node', '/joint3/sim_node',
        '/joint2/*']
    expected = {'seed': 1, 'rate': 2000.0, 'scenario': 'mild', 'joint_mode': 'locked',
                'frame_id': 'here'}
    assert rcl_parameters(ros_context, source, '/pam/sim_node') == expected
    assert rcl_parameters(ros_context, params.file, '/joint2/sim_node') == expected
    # /joint3's own section still applies there only
    assert rcl_parameters(ros_context, params.file, '/joint3/sim_node') == {
        'seed': 1, 'rate': 500.0, 'joint_mode': 'locked', 'scenario': 'strong'}


@pytest.mark.parametrize('own_first', [False, True])
def test_the_files_own_section_for_the_namespace_wins(tmp_path, ros_context, own_first):
    default = '/pam/sim_node: {ros__parameters: {rate: 2000.0, scenario: mild, seed: 3}}\n'
    own = 'joint2:\n  sim_node: {ros__parameters: {rate: 500.0, seed: 8}}\n'
    source = write(tmp_path, own + default if own_first else default + own)
    params = copy_for(tmp_path, source)
    assert params.moved == ('/pam/sim_node',)
    assert [key for key, _ in file_sections(params.file)] == ['/joint2/sim_node']
    assert rcl_parameters(ros_context, params.file, '/joint2/sim_node') == {
        'rate': 500.0, 'scenario': 'mild', 'seed': 8}
    assert rcl_parameters(ros_context, params.file, '/joint4/sim_node') == {}


def test_values_keep_their_text_and_rcl_types(tmp_path, ros_context):
    """rcl types a plain `1e3` as a double (PyYAML: a string), `'1.0'` as a string; nested keys
    and nested parameters (dotted names) read the same; every document counts."""
    source = write(tmp_path, '''\
        pam:
          sim_node:
            ros__parameters:
              gains: {kp: 1.5, inner: {n: 2}}
              rate: 1e3
              label: '1.0'
              word: "yes"
              flag: on
              ints: [1, 2]
              text: !!str 5
              folded: "a
                b"
        /**:
          ros__parameters: {seed: 4}
        ---
        /pam/ukf_node: {ros__parameters: {nis_gate: 9.0}}
        ''')
    params = copy_for(tmp_path, source, '/joint2', ['sim_node', 'ukf_node'])
    for name in ('sim_node', 'ukf_node'):
        in_pam = rcl_parameters(ros_context, source, f'/pam/{name}')
        assert rcl_parameters(ros_context, params.file, f'/joint2/{name}') == in_pam
    assert in_pam == {'seed': 4, 'nis_gate': 9.0}
    sim = rcl_parameters(ros_context, params.file, '/joint2/sim_node')
    assert sim == {'gains.kp': 1.5, 'gains.inner.n': 2, 'rate': 1000.0, 'label': '1.0',
                   'word': 'yes', 'flag': True, 'ints': [1, 2], 'text': '5', 'folded': 'a b',
                   'seed': 4}


@pytest.mark.parametrize('namespace, key', [('/', '/sim_node'),
                                            ('/lab/joint2', '/lab/joint2/sim_node'),
                                            ('lab/joint2/', '/lab/joint2/sim_node')])
def test_root_and_nested_namespaces(tmp_path, ros_context, namespace, key):
    source = write(tmp_path, '/pam/sim_node: {ros__parameters: {rate: 2000.0}}\n')
    params = copy_for(tmp_path, source, namespace)
    assert [k for k, _ in file_sections(params.file)] == [key]
    assert params.file.name == ('params.root.yaml' if namespace == '/' else
                                'params.lab.joint2.yaml')
    assert rcl_parameters(ros_context, params.file, key) == {'rate': 2000.0}
    assert params.warnings == ()


def test_a_node_no_section_is_for_is_warned_about(tmp_path):
    source = write(tmp_path, '''\
        /joint3/sim_node: {ros__parameters: {rate: 500.0}}
        /pam/ukf_node: {ros__parameters: {nis_gate: 9.0}}
        ''')
    params = copy_for(tmp_path, source, '/joint2', ['sim_node', 'ukf_node'])
    assert params.warnings == (
        'warning: no section of the params file is for /joint2/sim_node (sections: '
        '/joint3/sim_node, /joint2/ukf_node): it runs with its defaults',)
    only_wildcards = write(tmp_path, '/**: {ros__parameters: {seed: 1}}\n', 'w.yaml')
    params = copy_for(tmp_path, only_wildcards, '/joint2', ['sim_node'])
    assert params.file == only_wildcards
    assert params.warnings == (
        'warning: no section of the params file is for /joint2/sim_node (sections: /**): it '
        'runs with its defaults and /**',)


def test_for_namespace_merges_as_rcl_does():
    """The table directly: first places kept, the own section's names win over the moved
    one's, a moved key twice (nested and flat) one section."""
    sections = [('/pam/sim_node', [('a', 1), ('b', 1)]), ('/**', [('a', 2)]),
                ('/joint2/sim_node', [('b', 3)]), ('/pam/sim_node', [('c', 4), ('b', 5)])]
    table, moved = for_namespace(sections, '/joint2')
    assert list(table) == ['/joint2/sim_node', '/**']
    assert table['/joint2/sim_node'] == {'a': 1, 'b': 3, 'c': 4}
    assert moved == ['/pam/sim_node']


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize('kind', MALFORMED_PARAMS_FILES)
def test_a_malformed_file_is_the_one_line_error_naming_it(tmp_path, kind):
    path, line = malformed_params_file(tmp_path, kind)
    with pytest.raises(ValueError) as caught:
        copy_for(tmp_path, path)
    message = str(caught.value)
    assert '\n' not in message and message.startswith(f'params file {path}: '), message
    if line is not None:
        assert message.endswith(f'(line {line})'), message
    assert not list(tmp_path.rglob('params*.yaml'))


def test_an_invalid_namespace_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match='not a valid ROS namespace'):
        copy_for(tmp_path, default_params_file(), '/joint-2')


def test_run_directory_is_removed_when_the_process_exits():
    first, second = run_directory('pam_test_'), run_directory('pam_test_')
    assert first != second and first.is_dir() and not list(first.iterdir())
    script = ('import sys; from pam_bringup.params_namespace import run_directory; '
              "d = run_directory('pam_test_'); (d / 'x.yaml').write_text('{}'); print(d)")
    run = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stderr
    made = Path(run.stdout.strip())
    assert made.name.startswith('pam_test_') and not made.exists()
