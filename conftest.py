"""Repository-wide pytest options. `--repeat N` runs every selected test N times in one session
(one module domain and probe context, as in a full run): the soak runs of scripts/soak.sh."""


def pytest_addoption(parser):
    parser.addoption('--repeat', type=int, default=1, metavar='N',
                     help='run each selected test N times (soak runs, see scripts/soak.sh)')


def pytest_generate_tests(metafunc):
    rounds = metafunc.config.getoption('repeat')
    if rounds > 1:
        metafunc.fixturenames.append('soak_round')
        metafunc.parametrize('soak_round', range(1, rounds + 1))


# ---------------------------------------------------------------------------- markers
#: end-to-end tests: the whole stack, or a rig and the stack, as a user runs them (minutes each)
SYSTEM_TESTS = {'test_demo.py', 'test_closed_loop_driver.py', 'test_bringup.py',
                'test_two_hosts.py', 'test_firmware_driver.py', 'test_container.py',
                'test_container_realtime.py', 'test_closed_loop_lockstep.py'}
#: what makes a test module a process test: it starts processes or speaks ROS
_PROCESS = ('node_process', 'probe', 'subprocess', 'rclpy', 'Popen', 'ros_domain',
            'ros_context')
_KINDS = ('unit', 'process', 'system')


def _kind(path) -> str:
    """'system' for the end-to-end modules, 'process' for a module that starts processes or
    uses ROS (its source names one of _PROCESS), else 'unit' (ROS-free, in-process)."""
    if path.name in SYSTEM_TESTS:
        return 'system'
    text = path.read_text(errors='replace')
    return 'process' if any(word in text for word in _PROCESS) else 'unit'


def pytest_configure(config):
    # A shell starts a background job with SIGINT and SIGQUIT ignored, and an ignored signal
    # stays ignored across exec: every node the tests start would then ignore the Ctrl-C the
    # tests send (seen: `make test &` from a script; nodes hung 30 s at start-up, stops took the
    # SIGKILL timeout). Handled here instead of ignored, the children get the default again.
    import signal
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if signal.getsignal(signal.SIGQUIT) == signal.SIG_IGN:
        signal.signal(signal.SIGQUIT, signal.SIG_DFL)
    for kind, what in (('unit', 'ROS-free, in one process (make test-unit)'),
                       ('process', 'starts processes or speaks ROS/DDS'),
                       ('system', 'the whole stack end to end, as a user runs it')):
        config.addinivalue_line('markers', f'{kind}: {what}')


def pytest_collection_modifyitems(config, items):
    """Every test gets exactly one of the markers unit / process / system, from its module
    (an explicit one on the test or its module wins): `-m unit` selects the fast tests."""
    import pytest
    kinds: dict = {}
    for item in items:
        if any(item.get_closest_marker(kind) for kind in _KINDS):
            continue
        path = item.path
        if path not in kinds:
            kinds[path] = _kind(path)
        item.add_marker(getattr(pytest.mark, kinds[path]))
