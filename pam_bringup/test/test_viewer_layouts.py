"""The Foxglove and PlotJuggler layouts (config/foxglove_layout.json,
config/plotjuggler_layout.xml): every topic they name is one the stack publishes under /pam
(pam_common.topics) and every field path resolves on that topic's message type (the rosidl
Python classes' get_fields_and_field_types(), nested fields and array indices included, ending
on a number or a bool: something a plot can draw); the files have the structure each tool reads
(Foxglove: valid JSON, a mosaic tree whose panel ids are exactly the configured panels, Plot
paths, user scripts with inputs and an output under /studio_script/; PlotJuggler: the
root/tabbed_widget/Tab/Container/DockSplitter/DockArea/plot/curve tree its xmlLoadState walks,
splitter count and sizes matching the children, custom math snippets with a linked source and
additional sources v1..vn). A misspelt field, an unknown topic and a broken structure in a
modified copy are each found."""

from __future__ import annotations

import importlib
import json
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import JointState

from pam_common import topics
from pam_common.testing import installed_config
from pam_interfaces.msg import (
    ControllerState,
    JointEstimate,
    JointMeasurement,
    Pressures,
    Reference,
    ValveCommand,
)

CONFIG = Path(__file__).resolve().parents[1] / 'config'
FOXGLOVE = 'foxglove_layout.json'
PLOTJUGGLER = 'plotjuggler_layout.xml'
NAMESPACE = topics.DEFAULT_NAMESPACE

#: The stack's topics (pam_common.topics, relative ones under /pam) and their message types.
STACK_TOPICS = {topics.absolute(name): msg_class for name, msg_class in (
    (topics.PRESSURES, Pressures),
    (topics.JOINT_MEASURED, JointMeasurement),
    (topics.VALVE_COMMAND, ValveCommand),
    (topics.ESTIMATE, JointEstimate),
    (topics.JOINT_STATES, JointState),
    (topics.ESTIMATE_JOINT_STATES, JointState),
    (topics.CONTROLLER_STATE, ControllerState),
    (topics.REFERENCE, Reference),
    (topics.DIAGNOSTICS, DiagnosticArray),
)}
PLOTTABLE = {'bool', 'boolean', 'octet', 'byte', 'char', 'float', 'double', 'long double',
             'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64'}
#: Foxglove message path functions (docs.foxglove.dev, message path syntax) the layout may use.
FOXGLOVE_MODIFIERS = {'degrees', 'radians', 'abs', 'negative'}
FOXGLOVE_SCRIPT_PREFIX = '/studio_script/'


# ---------------------------------------------------------------------------- message types
def message_class(msg_type: str):
    """'std_msgs/Header' or 'std_msgs/msg/Header' (a field's type) -> the rosidl class."""
    package, *_, name = msg_type.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def type_name(msg_class) -> str:
    """Pressures -> 'pam_interfaces/Pressures'."""
    return f'{msg_class.__module__.split(".")[0]}/{msg_class.__name__}'


def field_problem(msg_type: str, path: list[str], plot: bool = True) -> str | None:
    """None if `path` (field names, a field may end in '[i]') resolves on `msg_type` (to a
    number a plot can draw if `plot`); else what is wrong."""
    current = msg_type
    for step in path:
        match = re.fullmatch(r'(\w+)(?:\[(\d+)\])?', step)
        if match is None:
            return f'{step!r} is no field name'
        name, index = match.group(1), match.group(2)
        if current in PLOTTABLE or current == 'string' or '/' not in current:
            return f'{step!r}: {current} has no fields'
        fields = message_class(current).get_fields_and_field_types()
        if name not in fields:
            return f'{msg_type} has no field {name!r} (on {current}: {sorted(fields)})'
        current = fields[name]
        array = re.fullmatch(r'(.+)\[(\d+)\]', current) or \
            re.fullmatch(r'sequence<([^,>]+)(?:, (\d+))?>', current)
        if index is not None:
            if array is None:
                return f'{name}[{index}]: {name} is {current}, no array'
            size = array.group(2)
            if size is not None and int(index) >= int(size):
                return f'{name}[{index}]: index out of {current}'
            current = array.group(1)
        elif array is not None and plot:
            return f'{name} is an array ({current}): an index is needed for a plot'
    if plot and current not in PLOTTABLE:
        return f'{".".join(path)} is {current}, not a number a plot can draw'
    return None


def reference_problem(topic: str, path: list[str], plot: bool = True) -> str | None:
    if topic not in STACK_TOPICS:
        return f'{topic}: not a topic of the stack ({sorted(STACK_TOPICS)})'
    problem = field_problem(type_name(STACK_TOPICS[topic]), path, plot)
    return f'{topic}: {problem}' if problem else None


# ---------------------------------------------------------------------------- Foxglove
def foxglove_path(value: str) -> tuple[str, list[str], list[str]]:
    """'/pam/estimate.angle.@degrees' -> ('/pam/estimate', ['angle'], ['degrees'])."""
    topic, _, rest = value.partition('.')
    parts = rest.split('.') if rest else []
    fields = [p for p in parts if not p.startswith('@')]
    modifiers = [p[1:] for p in parts if p.startswith('@')]
    return topic, fields, modifiers


def mosaic_leaves(node, problems: list[str]) -> list[str]:
    if isinstance(node, str):
        return [node]
    if not isinstance(node, dict) or set(node) - {'direction', 'first', 'second',
                                                  'splitPercentage'}:
        problems.append(f'not a mosaic node: {node!r}')
        return []
    if node.get('direction') not in ('row', 'column'):
        problems.append(f'mosaic direction {node.get("direction")!r} (row or column)')
    if not 0 < node.get('splitPercentage', 50) < 100:
        problems.append(f'splitPercentage {node["splitPercentage"]!r}')
    return mosaic_leaves(node.get('first'), problems) + mosaic_leaves(node.get('second'),
                                                                       problems)


def user_script(source: str) -> tuple[list[str], str, set[str], list[list[str]]]:
    """A Foxglove user script's inputs, output topic, Output fields and the message fields it
    reads (event.message.<path>)."""
    inputs = re.search(r'export const inputs\s*=\s*\[([^\]]*)\]', source)
    output = re.search(r'export const output\s*=\s*"([^"]+)"', source)
    out_type = re.search(r'type Output = \{([^}]*)\}', source)
    return (re.findall(r'"([^"]+)"', inputs.group(1)) if inputs else [],
            output.group(1) if output else '',
            set(re.findall(r'(\w+)\s*:\s*number', out_type.group(1))) if out_type else set(),
            [m.split('.') for m in re.findall(r'event\.message\.([\w.]+)', source)])


def foxglove_problems(path: Path) -> list[str]:
    try:
        layout = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        return [f'not JSON: {exc}']
    problems = [f'missing {key!r}' for key in ('configById', 'globalVariables', 'userNodes',
                                               'layout') if key not in layout]
    if problems:
        return problems
    configs = layout['configById']
    leaves = mosaic_leaves(layout['layout'], problems)
    if len(leaves) != len(set(leaves)):
        problems.append(f'a panel twice in the layout tree: {leaves}')
    for missing in sorted(set(leaves) - set(configs)):
        problems.append(f'panel {missing} in the layout tree has no config')
    for unused in sorted(set(configs) - set(leaves)):
        problems.append(f'config {unused} is in no panel of the layout tree')
    scripts = {}
    for script_id, script in layout['userNodes'].items():
        if set(script) != {'name', 'sourceCode'}:
            problems.append(f'user script {script_id}: keys {sorted(script)}')
            continue
        inputs, output, fields, reads = user_script(script['sourceCode'])
        if not inputs or not output.startswith(FOXGLOVE_SCRIPT_PREFIX) or not fields:
            problems.append(f'user script {script_id}: inputs {inputs}, output {output!r}, '
                            f'Output fields {sorted(fields)}')
        for topic in inputs:
            for read in reads:
                problem = reference_problem(topic, read, plot=False)
                if problem:
                    problems.append(f'user script {script_id} reads {".".join(read)}: {problem}')
        scripts[output] = fields
    for panel_id, config in configs.items():
        kind, bang, _ = panel_id.partition('!')
        if not bang or not kind:
            problems.append(f'panel id {panel_id!r} is not <type>!<id>')
        if kind != 'Plot':
            continue
        if not config.get('paths'):
            problems.append(f'{panel_id}: no paths')
        for entry in config.get('paths', []):
            if not isinstance(entry.get('value'), str) or not isinstance(entry.get('enabled'),
                                                                         bool):
                problems.append(f'{panel_id}: a path needs value (str) and enabled (bool): '
                                f'{entry}')
                continue
            topic, fields, modifiers = foxglove_path(entry['value'])
            for modifier in set(modifiers) - FOXGLOVE_MODIFIERS:
                problems.append(f'{panel_id}: {entry["value"]}: unknown function @{modifier}')
            if topic.startswith(FOXGLOVE_SCRIPT_PREFIX):
                if topic not in scripts:
                    problems.append(f'{panel_id}: {topic} is no user script output')
                elif len(fields) != 1 or fields[0] not in scripts[topic]:
                    problems.append(f'{panel_id}: {entry["value"]}: the script outputs '
                                    f'{sorted(scripts[topic])}')
                continue
            problem = reference_problem(topic, fields)
            if problem:
                problems.append(f'{panel_id}: {entry["value"]}: {problem}')
    return problems


# ---------------------------------------------------------------------------- PlotJuggler
def plotjuggler_reference(name: str) -> tuple[str, list[str]] | None:
    """'/pam/estimate/covariance[3]' -> ('/pam/estimate', ['covariance[3]']): the longest
    stack topic the name starts with (topics hold '/': estimate/joint_states); None if none."""
    for topic in sorted(STACK_TOPICS, key=len, reverse=True):
        if name.startswith(topic + '/'):
            return topic, name[len(topic) + 1:].split('/')
    return None


def plotjuggler_problems(path: Path) -> list[str]:
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        return [f'not well-formed XML: {exc}']
    problems = []
    if root.tag != 'root':
        return [f'the top element is <{root.tag}>, PlotJuggler wants <root>']
    snippets = {}
    for snippet in root.iterfind('customMathEquations/snippet'):
        name = snippet.get('name', '')
        linked = (snippet.findtext('linked_source') or '').strip()
        function = (snippet.findtext('function') or '').strip()
        if not name or not linked or 'return' not in function:
            problems.append(f'snippet {name!r}: needs a name, a linked_source and a function '
                            'that returns')
        if snippet.get('language', 'lua') != 'lua':
            problems.append(f'snippet {name}: language {snippet.get("language")!r}')
        extra = snippet.find('additional_sources')
        sources = [] if extra is None else list(extra)
        if [s.tag for s in sources] != [f'v{i}' for i in range(1, len(sources) + 1)]:
            problems.append(f'snippet {name}: additional sources {[s.tag for s in sources]} '
                            '(PlotJuggler reads v1, v2, ... in order)')
        for i in range(len(sources) + 1, 10):
            if re.search(rf'\bv{i}\b', function):
                problems.append(f'snippet {name}: uses v{i}, not among its sources')
        snippets[name] = [linked, *[(s.text or '').strip() for s in sources]]
    for name, sources in snippets.items():
        for source in sources:
            if source in snippets:
                continue
            ref = plotjuggler_reference(source)
            problem = (f'{source}: not under a topic of the stack ({sorted(STACK_TOPICS)})'
                       if ref is None else reference_problem(*ref))
            if problem:
                problems.append(f'snippet {name}: {problem}')
    widgets = root.findall('tabbed_widget')
    if not any(w.get('parent') == 'main_window' for w in widgets):
        problems.append('no <tabbed_widget parent="main_window">')
    curves = 0
    for tab in root.iterfind('tabbed_widget/Tab'):
        containers = tab.findall('Container')
        if not containers or not all(c.find('DockSplitter') is not None for c in containers):
            problems.append(f'tab {tab.get("tab_name")!r}: needs Container/DockSplitter')
        for splitter in tab.iter('DockSplitter'):
            children = [c for c in splitter if c.tag in ('DockArea', 'DockSplitter')]
            sizes = splitter.get('sizes', '').split(';')
            if splitter.get('orientation') not in ('|', '-') or \
                    splitter.get('count') != str(len(children)) or len(sizes) != len(children) \
                    or abs(sum(float(s) for s in sizes) - 1.0) > 1e-3:
                problems.append(f'tab {tab.get("tab_name")!r}: DockSplitter orientation '
                                f'{splitter.get("orientation")!r}, count '
                                f'{splitter.get("count")!r}, sizes {sizes} for '
                                f'{len(children)} children')
        for area in tab.iter('DockArea'):
            plot = area.find('plot')
            if plot is None or plot.get('mode') != 'TimeSeries':
                problems.append(f'dock area {area.get("name")!r}: needs a TimeSeries <plot>')
                continue
            for curve in plot.findall('curve'):
                curves += 1
                name = curve.get('name', '')
                if name in snippets:
                    continue
                ref = plotjuggler_reference(name)
                problem = (f'not a custom series nor under a topic of the stack '
                           f'({sorted(STACK_TOPICS)})' if ref is None else
                           reference_problem(*ref))
                if problem:
                    problems.append(f'curve {name}: {problem}')
    if not curves:
        problems.append('no curve in any plot')
    return problems


# ---------------------------------------------------------------------------- tests
def test_field_paths_resolve_on_the_rosidl_classes():
    assert field_problem('pam_interfaces/JointEstimate', ['covariance[15]']) is None
    assert field_problem('pam_interfaces/Pressures', ['header', 'stamp', 'sec']) is None
    assert field_problem('sensor_msgs/JointState', ['position[0]']) is None
    assert 'out of' in field_problem('pam_interfaces/JointEstimate', ['covariance[16]'])
    assert 'no field' in field_problem('pam_interfaces/Pressures', ['p3'])
    assert 'not a number' in field_problem('pam_interfaces/Pressures', ['header'])
    assert 'not a number' in field_problem('pam_interfaces/Pressures', ['header', 'frame_id'])
    assert 'index is needed' in field_problem('sensor_msgs/JointState', ['position'])
    assert 'no array' in field_problem('pam_interfaces/Pressures', ['p1[0]'])


def test_foxglove_layout_names_what_the_stack_publishes():
    assert foxglove_problems(CONFIG / FOXGLOVE) == []
    layout = json.loads((CONFIG / FOXGLOVE).read_text())
    values = {p['value'] for c in layout['configById'].values() for p in c['paths']}
    for expected in ('/pam/pressures.p1', '/pam/pressures.p2', '/pam/estimate.angle.@degrees',
                     '/pam/joint_measured.angle.@degrees', '/pam/estimate.torque',
                     '/pam/joint_measured.torque', '/pam/valve_command.u1',
                     '/pam/valve_command.u2', '/pam/controller_state.error'):
        assert expected in values, sorted(values)


def test_plotjuggler_layout_names_what_the_stack_publishes():
    assert plotjuggler_problems(CONFIG / PLOTJUGGLER) == []
    root = ET.parse(CONFIG / PLOTJUGGLER).getroot()
    names = {c.get('name') for c in root.iter('curve')}
    for expected in ('/pam/pressures/p1', '/pam/pressures/p2', 'angle_estimate_deg',
                     'angle_measured_deg', 'angle_error_deg', '/pam/estimate/torque',
                     '/pam/joint_measured/torque', 'torque_error', '/pam/valve_command/u1',
                     '/pam/valve_command/u2', '/pam/controller_state/error'):
        assert expected in names, sorted(names)


@pytest.mark.parametrize('name', [FOXGLOVE, PLOTJUGGLER])
def test_layouts_are_installed(name):
    assert Path(installed_config(name, 'pam_bringup')).read_bytes() == \
        (CONFIG / name).read_bytes(), 'make setup installs config/*.json and *.xml'


#: (file, text replaced, its replacement, a piece of the problem expected)
BROKEN = {
    'foxglove_misspelt_field': (FOXGLOVE, '"/pam/pressures.p2"', '"/pam/pressures.p_2"',
                                "no field 'p_2'"),
    'foxglove_field_of_another_type': (FOXGLOVE, '"/pam/joint_measured.torque"',
                                       '"/pam/valve_command.torque"',
                                       "pam_interfaces/ValveCommand has no field 'torque'"),
    'foxglove_unknown_topic': (FOXGLOVE, '"/pam/valve_command.u1"', '"/pam/valve_cmd.u1"',
                               '/pam/valve_cmd: not a topic of the stack'),
    'foxglove_script_reads_a_misspelt_field': (FOXGLOVE, 'event.message.torque - truth',
                                               'event.message.torq - truth', "no field 'torq'"),
    'foxglove_script_input_unknown': (FOXGLOVE, r'\"/pam/estimate\"]', r'\"/pam/estimates\"]',
                                      '/pam/estimates: not a topic of the stack'),
    'foxglove_script_output_field': (FOXGLOVE, 'error.torque_error"', 'error.torque_err"',
                                     'the script outputs'),
    'foxglove_panel_without_config': (FOXGLOVE, '"second": "Plot!pam_torque_error"',
                                      '"second": "Plot!pam_torque_errors"',
                                      'Plot!pam_torque_errors in the layout tree has no config'),
    'foxglove_not_json': (FOXGLOVE, '"configById": {', '"configById": {,', 'not JSON'),
    'plotjuggler_misspelt_field': (PLOTJUGGLER, '"/pam/controller_state/i_term"',
                                   '"/pam/controller_state/iterm"', "no field 'iterm'"),
    'plotjuggler_unknown_topic': (PLOTJUGGLER, '"/pam/pressures/p1"', '"/pam/pressure/p1"',
                                  'not a custom series nor under a topic of the stack'),
    'plotjuggler_snippet_source': (PLOTJUGGLER, '<v1>/pam/joint_measured/torque</v1>',
                                   '<v1>/pam/joint_measured/torque_nm</v1>',
                                   "no field 'torque_nm'"),
    'plotjuggler_snippet_unknown_variable': (PLOTJUGGLER, 'return value - v1',
                                             'return value - v2', 'uses v2'),
    'plotjuggler_splitter_count': (PLOTJUGGLER, 'count="4"', 'count="5"', 'DockSplitter'),
    'plotjuggler_not_xml': (PLOTJUGGLER, '</root>', '</rot>', 'not well-formed'),
}


@pytest.mark.parametrize('case', sorted(BROKEN))
def test_a_broken_copy_is_found(tmp_path, case):
    name, old, new, expected = BROKEN[case]
    copy = tmp_path / name
    shutil.copy(CONFIG / name, copy)
    text = copy.read_text()
    assert text.count(old) >= 1, f'{old!r} not in {name}: the case needs updating'
    copy.write_text(text.replace(old, new, 1))
    problems = (foxglove_problems if name == FOXGLOVE else plotjuggler_problems)(copy)
    assert any(expected in problem for problem in problems), problems
