"""Where the PAM node executables are: the project venv, PATH, or a colcon install."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


def executable_candidates(name: str, package: str) -> list[str]:
    """Where an executable is looked for, in order: next to this interpreter (the venv's bin),
    PATH, the ament index's <prefix>/lib/<package> (a colcon install)."""
    places = [str(Path(sys.executable).parent / name)]
    found = shutil.which(name)
    places.append(found if found else f'PATH ({name})')
    try:
        from ament_index_python.packages import get_package_prefix
        places.append(str(Path(get_package_prefix(package)) / 'lib' / package / name))
    except Exception:  # noqa: BLE001 - package not in the ament index: not a place then
        places.append(f'<prefix of {package}>/lib/{package}/{name} (package not in the ament '
                      'index: is AMENT_PREFIX_PATH set?)')
    return places


def find_executable(name: str, package: str) -> str | None:
    """Path of a node executable (see executable_candidates), or None."""
    for place in executable_candidates(name, package):
        path = Path(place)
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
    return None
