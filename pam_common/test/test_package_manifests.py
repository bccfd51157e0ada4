"""The repository's packages are standard ROS 2 packages that colcon builds unchanged on an apt
install of Jazzy: package.xml (format 3) valid for catkin_pkg (the parser colcon uses), named as
its folder, each dependency once; ament_python packages with the setup.cfg script dirs that put
executables where `ros2 run` looks, the ament index marker, and setup.py's version equal to
package.xml's; the interface package an ament_cmake rosidl package."""

import collections
import configparser
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = sorted(p.parent for p in ROOT.glob('*/package.xml'))


def test_every_package_folder_is_found():
    assert {p.name for p in PACKAGES} == {
        'pam_model', 'pam_interfaces', 'pam_common', 'pam_bag', 'pam_driver', 'pam_estimator',
        'pam_controller', 'pam_bringup', 'pam_description'}


@pytest.mark.parametrize('folder', PACKAGES, ids=lambda p: p.name)
def test_manifest_is_valid_format_3_and_names_its_folder(folder):
    from catkin_pkg.package import parse_package
    package = parse_package(folder / 'package.xml')
    package.validate()        # raises InvalidPackage
    assert package.package_format == 3
    assert package.name == folder.name
    build_types = [e.content for e in package.exports if e.tagname == 'build_type']
    assert build_types in (['ament_python'], ['ament_cmake']), build_types


@pytest.mark.parametrize('folder', PACKAGES, ids=lambda p: p.name)
def test_each_dependency_is_listed_once(folder):
    from catkin_pkg.package import parse_package
    package = parse_package(folder / 'package.xml')
    kinds = ('build_depends', 'buildtool_depends', 'build_export_depends',
             'buildtool_export_depends', 'exec_depends', 'test_depends', 'doc_depends')
    for kind in kinds:
        counts = collections.Counter(d.name for d in getattr(package, kind))
        assert not [n for n, c in counts.items() if c > 1], f'{kind} listed twice: {counts}'


@pytest.mark.parametrize('folder', [p for p in PACKAGES if (p / 'setup.py').exists()],
                         ids=lambda p: p.name)
def test_ament_python_layout(folder):
    from catkin_pkg.package import parse_package
    package = parse_package(folder / 'package.xml')
    name = folder.name
    config = configparser.ConfigParser()
    config.read(folder / 'setup.cfg')
    assert config['install']['install_scripts'] == f'$base/lib/{name}'
    assert config['develop']['script_dir'] == f'$base/lib/{name}'
    assert (folder / 'resource' / name).is_file(), 'ament index marker'
    assert (folder / name / '__init__.py').is_file()
    setup = (folder / 'setup.py').read_text()
    assert re.search(rf"version='{re.escape(package.version)}'", setup), 'versions differ'
    assert "'resource/' + package_name" in setup or f"resource/{name}" in setup
    assert "'package.xml'" in setup, 'package.xml not installed to share/'


def test_interface_package_is_an_ament_cmake_rosidl_package():
    from catkin_pkg.package import parse_package
    folder = ROOT / 'pam_interfaces'
    package = parse_package(folder / 'package.xml')
    assert 'rosidl_interface_packages' in [g.name for g in package.member_of_groups]
    assert 'rosidl_default_generators' in [d.name for d in package.buildtool_depends]
    cmake = (folder / 'CMakeLists.txt').read_text()
    assert re.search(r'project\(\s*pam_interfaces\b', cmake)
    assert 'rosidl_generate_interfaces' in cmake and 'ament_package()' in cmake
    for msg in sorted((folder / 'msg').glob('*.msg')):
        assert f'msg/{msg.name}' in cmake, f'{msg.name} not generated'
