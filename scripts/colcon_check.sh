#!/usr/bin/env bash
# Every package as an apt ROS user builds and tests it: a colcon workspace (build/colcon_ws) over
# this checkout, built against the venv's ROS 2 Jazzy (the PyPI wheels), then `colcon test` with
# pytest for every package, one package at a time, ending with `colcon test-result --verbose`.
# Used by `make test` (after scripts/setup.sh) and so by CI.
#
#   scripts/colcon_check.sh [colcon package selection for the tests] [-- pytest arguments]
#   e.g. scripts/colcon_check.sh --packages-select pam_model -- -k valve -x
# pytest runs in each package's folder: a test file is given relative to it
# (--packages-select pam_model -- test/test_signals.py).
# Every package is built whatever the selection (seconds when little changed): tests run nodes of
# other packages, and those come from the workspace.
#
# What differs from an apt install, and why:
#   - pam_interfaces is configured with -DCMAKE_PROJECT_INCLUDE=scripts/cmake/fix_wheel_python_
#     includes.cmake (the message wheels export the wheel builder's /opt/python include paths);
#     colcon warns that .venv (on AMENT_PREFIX_PATH) has no local_setup.* files: expected, the
#     venv is a pip install, not a colcon prefix;
#   - LD_LIBRARY_PATH is set here, once, in a fixed order, with _ROS_WHEELS_BOOTSTRAP_COMPLETE=1
#     (the wheels' bootstrapper would rebuild it in each interpreter in set order, so the
#     workspace's pam_interfaces libraries would not always come before the venv's copies);
#   - PYTHONSAFEPATH=1 (Python >= 3.11): `python -m pytest` in a package folder does not put
#     that folder first on sys.path, so the tests import what colcon installed
#     (build/colcon_ws/install), as the nodes they start do (with 3.10: the package's sources).
# colcon picks pytest from setup.py's extras_require={'test': ['pytest']} (tests_require, which
# setuptools >= 72 ignores, made it fall back to unittest and run no test); a package whose tests
# did not run through pytest, or ran none, fails the check.
# pytest runs in each package folder of this checkout, so pytest.ini and conftest.py of the
# repository root apply (timeout 300, -ra, --repeat N). The workspace stays between runs: colcon
# rebuilds only what changed (pam_interfaces' C/C++: about 25 s on an idle machine, once).
# Environment: COLCON_WS (default build/colcon_ws).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
VPY="$VENV/bin/python"
WS="${COLCON_WS:-$ROOT/build/colcon_ws}"
CMAKE_FIX="$ROOT/scripts/cmake/fix_wheel_python_includes.cmake"

say() { echo "colcon_check: $*"; }
die() { echo "colcon_check: error: $*" >&2; exit 1; }

selection=()
pytest_args=()
while (($#)); do
  if [[ "$1" == -- ]]; then shift; pytest_args=("$@"); break; fi
  selection+=("$1"); shift
done

[[ -x "$VPY" ]] || die ".venv is missing: run scripts/setup.sh (or make setup) first"
COLCON="$VENV/bin/colcon"
[[ -x "$COLCON" ]] || die "colcon is not in .venv: run scripts/setup.sh (or make setup)"

# An outer ROS environment (a sourced /opt/ros/jazzy or another workspace) must not leak in.
unset PYTHONPATH PYTHONHOME CMAKE_PREFIX_PATH COLCON_PREFIX_PATH AMENT_CURRENT_PREFIX \
      LD_LIBRARY_PATH _ROS_WHEELS_BOOTSTRAP_COMPLETE || true
export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV"
export LD_LIBRARY_PATH
LD_LIBRARY_PATH="$("$VPY" -c 'import ros_wheels_bootstrapper as b, os
print(os.pathsep.join(sorted(b.get_ros_paths().split(os.pathsep))))')"
export _ROS_WHEELS_BOOTSTRAP_COMPLETE=1 PYTHONSAFEPATH=1
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"

mkdir -p "$WS"
cd "$WS"
# One run per workspace at a time (two at once would build into the same folders).
exec 8>"$WS/.colcon_check.lock"
flock -n 8 || { say "waiting for another colcon_check run on ${WS#"$ROOT"/}..."; flock 8; }
colcon() { "$COLCON" --log-base "$WS/log" "$@"; }

say "colcon build in ${WS#"$ROOT"/} (sources: $ROOT)..."
t0=$SECONDS
colcon build --base-paths "$ROOT" \
  --cmake-args -DPython3_EXECUTABLE="$VPY" -DCMAKE_PROJECT_INCLUDE="$CMAKE_FIX" \
  -DCMAKE_BUILD_TYPE=Release
say "build done in $((SECONDS - t0)) s"

# The whole workspace, sourced as an apt user does before `colcon test`: colcon itself adds only
# a package's dependencies to its tests' environment, and some tests run executables of packages
# above them (pam_common's tests start every node): those must come from the workspace, never
# from the venv's pip-installed copies.
set +u
# shellcheck disable=SC1091
source "$WS/install/setup.bash"
set -u

# numba's on-disk cache of the installed pam_model/pam_estimator/pam_controller kernels (next to
# the installed sources): compiled once (about a minute), not inside the first tests.
t0=$SECONDS
if ! "$VPY" "$ROOT/scripts/warm_numba_cache.py" >"$WS/log/numba-warm-up.log" 2>&1; then
  tail -n 40 "$WS/log/numba-warm-up.log" >&2
  die "compiling the numba kernels failed (log: ${WS#"$ROOT"/}/log/numba-warm-up.log)"
fi
say "numba kernels ready in $((SECONDS - t0)) s"

colcon test-result --test-result-base "$WS/build" --delete-yes >/dev/null
spaced=()
for a in "${pytest_args[@]}"; do spaced+=(" $a"); done   # colcon: a leading space keeps "-x" ours
t0=$SECONDS
rc=0
colcon test --base-paths "$ROOT" "${selection[@]}" --executor sequential \
  --event-handlers console_cohesion+ ${spaced[@]+--pytest-args "${spaced[@]}"} || rc=$?
say "tests done in $((SECONDS - t0)) s (build, warm-up and tests: $SECONDS s)"
colcon test-result --test-result-base "$WS/build" --verbose || rc=1

# Every Python package ran its tests through pytest (a pytest.xml), and at least one unless
# pytest arguments (-k ...) select a part.
while read -r name _ type; do
  [[ "$type" == "(ros.ament_python)" ]] || continue
  xml="$WS/build/$name/pytest.xml"
  if [[ ! -f "$xml" ]]; then
    echo "colcon_check: error: $name: its tests did not run through pytest (no ${xml#"$WS"/})" >&2
    rc=1
  elif ((${#pytest_args[@]} == 0)) && ! grep -qE '<testsuite [^>]*tests="[1-9]' "$xml"; then
    echo "colcon_check: error: $name: no test ran (${xml#"$WS"/})" >&2
    rc=1
  fi
done < <(colcon list --base-paths "$ROOT" "${selection[@]}")
exit "$rc"
