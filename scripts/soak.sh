#!/usr/bin/env bash
# Soak run: one test (or any pytest selection) N times in a row in one pytest session, e.g.
#   scripts/soak.sh 100 'pam_bringup/test/test_bringup.py::test_rig_driver_runs_against_the_emulator'
# Prints pytest's summary, the pass/fail count and the wall time; exit code 0 only if every round
# passed. Rounds run on one module domain and probe context, as in `make test`.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [[ $# -lt 2 || ! "$1" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: scripts/soak.sh N PYTEST_SELECTION..." >&2
  exit 2
fi
ROUNDS="$1"; shift
bash "$ROOT/scripts/setup.sh" >/dev/null
source "$ROOT/scripts/env.sh"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
cd "$ROOT"
start=$(date +%s)
set +e
python -m pytest -p no:cacheprovider -q -rf --repeat "$ROUNDS" "$@" | tee "${SOAK_LOG:-/dev/null}" | tail -n 30
code=${PIPESTATUS[0]}
set -e
echo "soak: $ROUNDS rounds of $*: pytest exit code $code, $(( $(date +%s) - start )) s"
exit "$code"
