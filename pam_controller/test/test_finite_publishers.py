"""The rule 'no node publishes a non-finite number' holds by construction: in every module of the
three node packages, each publisher of a message type with a float field is made inside a
FiniteGuard.wrap(...) call. bag_play is the one exception (it republishes recorded bytes as
they were recorded; see README)."""

import ast
import importlib
import pkgutil

import pytest

from pam_common.finite_guard import float_fields

PACKAGES = ('pam_common', 'pam_bag', 'pam_driver', 'pam_estimator', 'pam_controller', 'pam_bringup')
EXEMPT = {'pam_bag.bag_play'}          # raw recorded bytes, published as recorded


def node_modules():
    for package in PACKAGES:
        root = importlib.import_module(package)
        for info in pkgutil.walk_packages(root.__path__, package + '.'):
            spec = importlib.util.find_spec(info.name)
            source = spec.loader.get_source(info.name) if spec and spec.loader else None
            if source and 'create_publisher(' in source and info.name not in EXEMPT:
                yield info.name, source


def unguarded_publishers(module_name: str, source: str) -> list[str]:
    """'line: type' of each create_publisher(T, ...) with a float field in T, outside wrap()."""
    module = importlib.import_module(module_name)
    tree = ast.parse(source)
    wrapped = {id(inner) for call in ast.walk(tree)
               if isinstance(call, ast.Call) and getattr(call.func, 'attr', '') == 'wrap'
               for inner in ast.walk(call)}
    found = []
    for call in ast.walk(tree):
        if not (isinstance(call, ast.Call) and getattr(call.func, 'attr', '') ==
                'create_publisher' and call.args and isinstance(call.args[0], ast.Name)):
            continue
        msg_type = getattr(module, call.args[0].id, None)
        if msg_type is None or not hasattr(msg_type, 'SLOT_TYPES'):
            continue                          # a parameter of a helper (e.g. the probe's)
        if float_fields(msg_type) is not None and id(call) not in wrapped:
            found.append(f'line {call.lineno}: {msg_type.__name__}')
    return found


MODULES = sorted(node_modules())


def test_the_node_modules_are_found():
    names = {name for name, _ in MODULES}
    assert {'pam_driver.sim_node', 'pam_driver.driver_node', 'pam_controller.profile_player',
            'pam_estimator.ukf_node', 'pam_controller.pi_node',
            'pam_controller.reference_node'} <= names


@pytest.mark.parametrize('name, source', MODULES, ids=[name for name, _ in MODULES])
def test_every_float_publisher_is_guarded(name, source):
    assert unguarded_publishers(name, source) == []
