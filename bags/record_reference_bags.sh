#!/usr/bin/env bash
# Regenerates the reference bags in bags/ by recording the live stack (real processes over DDS):
#   sim_node (mismatch:=mild, realtime, 1 kHz) + ukf_node + profile_player (20 s validation
#   profile, open loop) + bag_record, once with a free joint and once with a locked joint.
# Usage: bags/record_reference_bags.sh [free|locked ...]   (default: both)
# Needs `make setup`. Uses its own ROS_DOMAIN_ID (default 77; override with PAM_BAG_DOMAIN) and
# localhost-only discovery, so it does not disturb (or hear) other stacks. Existing bags of the
# same name are replaced.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/env.sh"
export ROS_DOMAIN_ID="${PAM_BAG_DOMAIN:-77}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY
DURATION="${PAM_BAG_DURATION:-20.0}"   # s of the validation profile (130 s would be ~15 MB per bag)
TOPICS=/pam/pressures,/pam/valve_command,/pam/joint_measured   # what pam-evaluate needs
MODES=("$@"); [ ${#MODES[@]} -eq 0 ] && MODES=(free locked)
LOGDIR="$(mktemp -d)"
PIDS=()

cleanup() {
  local pid
  for pid in "${PIDS[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  PIDS=()
}
trap cleanup EXIT
trap 'exit 130' INT TERM

record() {
  local mode="$1" name="validation_mild_$1"
  local out="$ROOT/bags/$name"
  rm -rf "$out"
  echo "== $name: recording $DURATION s of the validation profile ($mode joint), logs in $LOGDIR"
  bag_record --ros-args -p output:="$out" -p topics:="$TOPICS" >"$LOGDIR/$name.record.log" 2>&1 &
  local rec=$!; PIDS+=("$rec")
  sim_node --ros-args -p mismatch:=mild -p joint_mode:="$mode" >"$LOGDIR/$name.sim.log" 2>&1 &
  PIDS+=("$!")
  ukf_node --ros-args -p joint_mode:="$mode" >"$LOGDIR/$name.ukf.log" 2>&1 &
  PIDS+=("$!")
  sleep 2   # let bag_record discover the topics before the profile starts
  profile_player --ros-args -p duration:="$DURATION" -p joint_mode:="$mode" \
    -p wait_for_estimator:=30.0 2>&1 | tee "$LOGDIR/$name.player.log" | tail -n 25
  sleep 0.5  # the last messages reach the recorder
  kill -INT "$rec"; wait "$rec" || { echo "bag_record failed:"; cat "$LOGDIR/$name.record.log"; exit 1; }
  cleanup
  pam-bag-info "$out"
}

for mode in "${MODES[@]}"; do
  case "$mode" in free|locked) record "$mode" ;; *) echo "unknown mode $mode" >&2; exit 2 ;; esac
done
