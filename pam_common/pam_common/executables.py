"""Where the PAM node executables are, found as `ros2 run` finds them: through the ament index.

The index (AMENT_PREFIX_PATH) gives the prefix a package is installed in. A colcon or apt install
puts the package's executables in <prefix>/lib/<package>/; `pip install` into the project venv
(scripts/setup.sh) puts them in <prefix>/bin/ (the venv's bin). Only when the package is not in
the index at all (AMENT_PREFIX_PATH unset) are the interpreter's bin folder and PATH searched.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


def package_prefix(package: str) -> Path | None:
    """The install prefix of `package` from the ament index, or None if it is not there."""
    try:
        from ament_index_python.packages import get_package_prefix
        return Path(get_package_prefix(package))
    except (ImportError, LookupError, OSError, ValueError):
        return None   # no ament_index_python, package not indexed, AMENT_PREFIX_PATH unset


def executable_candidates(name: str, package: str) -> list[str]:
    """Where an executable is looked for, in order: <prefix>/lib/<package>/<name>, then
    <prefix>/bin/<name> for the package's prefix in the ament index; for a package not in the
    index, next to this interpreter (the venv's bin), then PATH."""
    prefix = package_prefix(package)
    if prefix is not None:
        return [str(prefix / 'lib' / package / name), str(prefix / 'bin' / name)]
    found = shutil.which(name)
    return [str(Path(sys.executable).parent / name), found if found else f'PATH ({name})',
            f'<prefix of {package}>/lib/{package}/{name} ({package} not in the ament index: is '
            'AMENT_PREFIX_PATH set?)']


def find_executable(name: str, package: str) -> str | None:
    """Path of a node executable (see executable_candidates), or None."""
    for place in executable_candidates(name, package):
        path = Path(place)
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
    return None
