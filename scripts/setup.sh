#!/usr/bin/env bash
# The one set-up path of this repository (used by `make setup|test|demo` and CI):
#   1. checks prerequisites (python 3.10-3.13, cmake >= 3.21, gcc, g++, make),
#   2. creates .venv/ and installs the pinned requirements.txt (only when it changed),
#   3. installs the ament_python packages (every folder with package.xml + setup.py) into .venv,
#      non-editably (only those whose sources changed), and compiles the numba kernels (in the
#      background, while step 4 runs),
#   4. builds and installs the ament_cmake packages (pam_interfaces) into .venv with cmake
#      (only when their sources changed or the venv was rebuilt).
# Idempotent; a run with nothing to do takes well under 2 s.
# Override the interpreter used to create the venv with PYTHON=/path/to/python3.X.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
VENV="$ROOT/.venv"
VPY="$VENV/bin/python"
STAMPS="$VENV/.pam-setup"          # stamps live in the venv: a new venv redoes every step
BUILD="$ROOT/build"
LOGS="$BUILD/setup-logs"
CMAKE_FIX="$ROOT/scripts/cmake/fix_wheel_python_includes.cmake"

# An outer ROS environment (e.g. a sourced /opt/ros/jazzy) must not leak into this venv's builds.
unset PYTHONPATH CMAKE_PREFIX_PATH COLCON_PREFIX_PATH PYTHONHOME || true
export AMENT_PREFIX_PATH="$VENV"
export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_INPUT=1 PIP_NO_WARN_SCRIPT_LOCATION=1

say() { echo "setup: $*"; }
die() { echo "setup: error: $*" >&2; exit 1; }

# Run a step quietly; on failure show the end of its log and return 1.
run_logged() {
  local name="$1"; shift
  mkdir -p "$LOGS"
  local log="$LOGS/$name.log"
  if ! "$@" >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "setup: error: $name failed (full log: ${log#"$ROOT"/})" >&2
    return 1
  fi
}

# sha256 over a package folder's source files (paths and contents), without build leftovers and
# without its test/ folder (tests are not installed: editing them needs no reinstall).
hash_dir() {
  local dir="$1"
  (
    cd "$dir"
    find . \( -type d \( -name build -o -name install -o -name log -o -name '*.egg-info' \
             -o -name __pycache__ -o -name .pytest_cache -o -name .git -o -path ./test \) \) -prune \
           -o -type f ! -name '*.pyc' -print0 \
      | LC_ALL=C sort -z | xargs -0 -r sha256sum
  ) | sha256sum | cut -d' ' -f1
}
hash_str() { printf '%s' "$*" | sha256sum | cut -d' ' -f1; }
stamp_ok() { [[ -f "$STAMPS/$1" && "$(cat "$STAMPS/$1")" == "$2" ]]; }
stamp_set() { mkdir -p "$STAMPS"; printf '%s\n' "$2" >"$STAMPS/$1"; }

# ---------------------------------------------------------------- 1. prerequisites
python_ok() {  # prints "X.Y ok|badversion hdr|nohdr venv|novenv" for interpreter $1; fails if it does not run
  "$1" - <<'EOF' 2>/dev/null
import sys, os, sysconfig
v = sys.version_info
ok = sys.implementation.name == 'cpython' and (3, 10) <= v[:2] <= (3, 13)
hdr = os.path.exists(os.path.join(sysconfig.get_paths()['include'], 'Python.h'))
try:
    import venv, ensurepip  # noqa: F401
    has_venv = True
except ImportError:
    has_venv = False
print(f"{v[0]}.{v[1]} {'ok' if ok else 'badversion'} {'hdr' if hdr else 'nohdr'} {'venv' if has_venv else 'novenv'}")
EOF
}

check_prereqs() {
  local missing=() apt=() py="${PYTHON:-python3}" info="" extra=""
  if [[ -x "$VPY" ]] && info="$(python_ok "$VPY")"; then
    :  # existing venv: check its interpreter
  elif command -v "$py" >/dev/null 2>&1 && info="$(python_ok "$py")"; then
    :
  else
    info=""
  fi
  if [[ -z "$info" ]]; then
    missing+=("python3 3.10-3.13 ('$py' does not run)"); apt+=(python3 python3-venv python3-dev)
  else
    read -r pyver pyok pyhdr pyvenv <<<"$info"
    if [[ "$pyok" != ok ]]; then
      missing+=("CPython 3.10-3.13 (found $pyver at $py; the ROS wheels are cp310-cp313 only)")
      apt+=(python3); extra=" (or set PYTHON=/path/to/python3.11)"
    fi
    [[ "$pyhdr" == hdr ]] || { missing+=("Python $pyver headers (Python.h)"); apt+=(python3-dev); }
    if [[ ! -x "$VPY" && "$pyvenv" != venv ]]; then missing+=("python venv module"); apt+=(python3-venv); fi
  fi
  if [[ "$(uname -m)" != x86_64 ]]; then
    die "the ROS 2 wheels exist for x86_64 only (this machine: $(uname -m))"
  fi
  if command -v cmake >/dev/null 2>&1; then
    local cv; cv="$(cmake --version | head -n1 | sed -E 's/[^0-9]*([0-9]+\.[0-9]+(\.[0-9]+)?).*/\1/')"
    if [[ "$(printf '%s\n3.21\n' "$cv" | sort -V | head -n1)" != 3.21 ]]; then
      missing+=("cmake >= 3.21 (found $cv)"); apt+=(cmake); extra+=" (or: pip install cmake)"
    fi
  else
    missing+=("cmake >= 3.21"); apt+=(cmake)
  fi
  command -v gcc >/dev/null 2>&1 || { missing+=("gcc"); apt+=(gcc); }
  command -v g++ >/dev/null 2>&1 || { missing+=("g++"); apt+=(g++); }
  command -v make >/dev/null 2>&1 || { missing+=("make"); apt+=(make); }
  if ((${#missing[@]})); then
    local list; list="$(printf ', %s' "${missing[@]}")"
    die "missing prerequisite(s): ${list:2} -- install with: apt-get install ${apt[*]}$extra"
  fi
}
check_prereqs

mkdir -p "$BUILD"
# colcon must not mistake the build tree or the venv's installed package.xml files for sources
# (a colcon build in this same checkout, see docs/colcon.md).
touch "$BUILD/COLCON_IGNORE"
# Serialise concurrent runs (two `make test` at once).
exec 9>"$BUILD/.setup.lock"
flock 9

did=0

# ---------------------------------------------------------------- 2. venv + pinned requirements
if [[ ! -x "$VPY" ]] || ! "$VPY" -c 'import sys' >/dev/null 2>&1; then
  say "creating .venv with ${PYTHON:-python3} ($("${PYTHON:-python3}" -c 'import sys; print(sys.version.split()[0])'))..."
  rm -rf "$VENV"
  run_logged venv "${PYTHON:-python3}" -m venv "$VENV"
  did=1
fi
touch "$VENV/COLCON_IGNORE"

# Hash of the pins only: editing comments of requirements.txt triggers nothing.
req_hash="$(sed -e 's/#.*//' -e 's/[[:space:]]*$//' -e '/^$/d' requirements.txt | sha256sum | cut -d' ' -f1)"
if ! stamp_ok requirements "$req_hash"; then
  say "installing pinned requirements (requirements.txt)..."
  rm -f "$STAMPS"/requirements "$STAMPS"/cmake-* "$STAMPS"/py-*   # new dependencies: rebuild our packages against them
  run_logged requirements "$VPY" -m pip install -r requirements.txt
  stamp_set requirements "$req_hash"
  did=1
fi

# The packages: folders at the repo root with package.xml, and CMakeLists.txt (ament_cmake,
# today pam_interfaces) or setup.py (ament_python).
cmake_pkgs=()
py_pkgs=()
for d in */; do
  d="${d%/}"
  [[ -f "$d/package.xml" ]] || continue
  if [[ -f "$d/CMakeLists.txt" ]]; then cmake_pkgs+=("$d");
  elif [[ -f "$d/setup.py" ]]; then py_pkgs+=("$d"); fi
done

# ---------------------------------------------------------------- 3. ament_python packages
clean_inplace() { rm -rf "$1/build" "$1"/*.egg-info; }
changed=()
declare -A py_hash
for pkg in "${py_pkgs[@]}"; do
  py_hash[$pkg]="$(hash_dir "$pkg")"
  stamp_ok "py-$pkg" "${py_hash[$pkg]}" || changed+=("$pkg")
done
if ((${#changed[@]})); then
  # One pip call for all of them (one interpreter start-up, one pass of pip's set-up).
  # Not editable: pip install -e would skip data_files (ament index marker, package.xml).
  say "installing ${changed[*]}..."
  for pkg in "${changed[@]}"; do rm -f "$STAMPS/py-$pkg"; clean_inplace "$pkg"; done
  if ! run_logged python-packages-install "$VPY" -m pip install --no-deps --no-build-isolation \
       --no-index --force-reinstall "${changed[@]/#/./}"; then
    for pkg in "${changed[@]}"; do clean_inplace "$pkg"; done
    exit 1
  fi
  for pkg in "${changed[@]}"; do clean_inplace "$pkg"; stamp_set "py-$pkg" "${py_hash[$pkg]}"; done
  did=1
fi

# A package folder that went away (or stopped being an ament_python package): uninstall it.
if [[ -d "$STAMPS" ]]; then
  for s in "$STAMPS"/py-*; do
    [[ -e "$s" ]] || continue
    pkg="${s##*/py-}"
    if [[ ! " ${py_pkgs[*]} " == *" $pkg "* ]]; then
      say "uninstalling $pkg (folder gone)..."
      run_logged "$pkg-uninstall" "$VPY" -m pip uninstall -y "$pkg"
      rm -f "$s"
      did=1
    fi
  done
fi

# A script that moved between two packages (bag_play, from pam_driver to pam_bag) is
# deleted by the old owner's reinstall when that comes after the new owner's install: reinstall
# every package one of whose console scripts is missing from the venv's bin.
if ((did)); then
  mapfile -t lost < <("$VPY" - "${py_pkgs[@]}" <<'PYEOF'
import sys
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path
bin_dir = Path(sys.executable).parent
for pkg in sys.argv[1:]:
    try:
        scripts = [e.name for e in distribution(pkg).entry_points if e.group == 'console_scripts']
    except PackageNotFoundError:
        continue
    if any(not (bin_dir / name).exists() for name in scripts):
        print(pkg)
PYEOF
  )
  for pkg in "${lost[@]}"; do
    say "reinstalling $pkg (a console script of it was removed by another package's reinstall)..."
    clean_inplace "$pkg"
    run_logged "$pkg-install" "$VPY" -m pip install --no-deps --no-build-isolation --no-index \
      --force-reinstall "./$pkg" || { clean_inplace "$pkg"; exit 1; }
    clean_inplace "$pkg"
  done
fi

# pip's reinstall dropped numba's on-disk cache of the compiled kernels: compile them now, once,
# rather than in the first node or test that runs. The kernels need no ROS package, so they
# compile in the background while the ament_cmake packages build (on 2 cores: about 30 s saved).
warm_pid=""
if ((did)); then
  say "compiling the numba kernels (once per install; in the background)..."
  run_logged numba-warm-up "$VPY" "$ROOT/scripts/warm_numba_cache.py" &
  warm_pid=$!
  trap '[[ -n "$warm_pid" ]] && kill "$warm_pid" 2>/dev/null' EXIT
fi

# ---------------------------------------------------------------- 4. ament_cmake packages

pyver_full="$("$VPY" -c 'import sys; print(sys.version)' 2>/dev/null || true)"
for pkg in "${cmake_pkgs[@]}"; do
  h="$(hash_str "$(hash_dir "$pkg")" "$(sha256sum "$CMAKE_FIX")" "$req_hash" "$pyver_full")"
  stamp_ok "cmake-$pkg" "$h" && continue
  say "building $pkg (cmake)..."
  rm -f "$STAMPS/cmake-$pkg"
  bdir="$BUILD/$pkg"
  rm -rf "$bdir"   # clean configure: the venv or the generators may have changed
  run_logged "$pkg-configure" cmake -S "$ROOT/$pkg" -B "$bdir" \
    -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DCMAKE_PREFIX_PATH="$VENV" \
    -DPython3_EXECUTABLE="$VPY" \
    -DBUILD_TESTING=OFF \
    -DCMAKE_PROJECT_INCLUDE="$CMAKE_FIX"
  run_logged "$pkg-build" cmake --build "$bdir" --parallel "$(nproc 2>/dev/null || echo 2)"
  run_logged "$pkg-install" cmake --install "$bdir"
  stamp_set "cmake-$pkg" "$h"
  did=1
done

if [[ -n "$warm_pid" ]]; then
  wait "$warm_pid" || exit 1
  warm_pid=""
  say "numba kernels compiled"
fi

if ((did)); then say "done"; else say "up to date"; fi
