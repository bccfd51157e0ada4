#!/usr/bin/env bash
# Regenerates the reference bags in bags/ by recording the live stack (real processes over DDS),
# always sim_node (scenario:=mild, realtime, 1 kHz) + ukf_node (nominal model) + bag_record:
#   free, locked    validation_mild_MODE: + profile_player (the 130 s validation profile, open
#                   loop), free or locked joint; topics /pam/pressures, valve_command,
#                   joint_measured; split into files of at most 4 MB (~15 MB in all)
#   closed_angle    closed_mild_angle: + pi_node (sensor-less, on the estimate) + reference_node
#                   (angle steps within +-20 deg, 3 s each, the first at 0), free joint, 12 s
#   closed_torque   closed_mild_torque: the same in torque mode (steps within +-2 N m), locked
#                   joint; closed-loop bags also hold /pam/estimate and /pam/reference
# Usage: bags/record_reference_bags.sh [free|locked|closed_angle|closed_torque ...]  (default: all)
# Needs `make setup`. Uses its own ROS_DOMAIN_ID (default 77; override with PAM_BAG_DOMAIN) and
# localhost-only discovery, so it does not disturb (or hear) other stacks. Existing bags of the
# same name are replaced.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/env.sh"
export ROS_DOMAIN_ID="${PAM_BAG_DOMAIN:-77}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY
DURATION="${PAM_BAG_DURATION:-130.0}"   # s of the validation profile (MODEL.md: 130 s)
MAX_FILE=4000000   # bytes per .mcap file of a validation bag (bag_record max_bag_size)
CLOSED_DURATION="${PAM_BAG_CLOSED_DURATION:-12.0}"   # s of steps (with the estimates: ~3.5 MB)
TOPICS=/pam/pressures,/pam/valve_command,/pam/joint_measured   # what pam-evaluate needs
MODES=("$@"); [ ${#MODES[@]} -eq 0 ] && MODES=(free locked closed_angle closed_torque)
LOGDIR="$(mktemp -d)"
NAME="" REC=""

source "$ROOT/scripts/stack_processes.sh"   # PIDS, stop_all
STOP_WAIT=5
cleanup() { stop_all; }
trap cleanup EXIT
trap 'exit 130' INT TERM

# wait_log FILE PATTERN [N]: wait (at most 60 s) until FILE holds N (default 1) lines with PATTERN
wait_log() {
  local n
  for _ in $(seq 600); do
    n="$(grep -c "$2" "$1" 2>/dev/null || true)"
    [ "${n:-0}" -ge "${3:-1}" ] && return 0
    sleep 0.1
  done
  echo "timed out waiting for '$2' in $1:"; cat "$1"; exit 1
}

# rig JOINT: sim_node (mild plant) and ukf_node, in the background
rig() {
  sim_node --ros-args -p scenario:=mild -p joint_mode:="$1" >"$LOGDIR/$NAME.sim.log" 2>&1 &
  PIDS+=("$!")
  ukf_node --ros-args -p joint_mode:="$1" >"$LOGDIR/$NAME.ukf.log" 2>&1 &
  PIDS+=("$!")
}

# record TOPICS [PARAM...]: bag_record of TOPICS into bags/$NAME (more -p PARAMs), in the
# background
record() {
  rm -rf "$ROOT/bags/$NAME"
  echo "== $NAME: recording, logs in $LOGDIR"
  local extra=(); for p in "${@:2}"; do extra+=(-p "$p"); done
  bag_record --ros-args -p output:="$ROOT/bags/$NAME" -p topics:="$1" -p discovery_period:=0.1 \
    "${extra[@]}" >"$LOGDIR/$NAME.record.log" 2>&1 &
  REC=$!; PIDS+=("$REC")
}

# finish: stop bag_record (SIGINT: it closes the bag), then the rest; print the bag's info
finish() {
  sleep 0.5  # the last messages reach the recorder
  kill -INT "$REC"; wait "$REC" || { echo "bag_record failed:"; cat "$LOGDIR/$NAME.record.log"; exit 1; }
  cleanup
  local report
  report="$(pam-bag-info --verify "$ROOT/bags/$NAME")"   # every chunk read, its CRC checked
  echo "$report"
  if grep -q '(no CRC' <<<"$report"; then
    echo "error: bags/$NAME has chunks without a CRC (is bag_record installed? make setup)" >&2
    exit 1
  fi
  local f size
  for f in "$ROOT/bags/$NAME"/*.mcap; do
    size="$(stat -c %s "$f")"
    [ "$size" -lt 4500000 ] || echo "warning: $f has $size bytes (> 4.5 MB): record it again" >&2
  done
}

record_validation() {  # free | locked
  NAME="validation_mild_$1"
  record "$TOPICS" max_bag_size:="$MAX_FILE"
  rig "$1"
  # bag_record subscribes to the rig's two topics before the profile starts (DDS matches each
  # pair of processes on its own, up to one 3 s announcement period late: README)
  wait_log "$LOGDIR/$NAME.record.log" 'subscribed to' 2
  sleep 1
  profile_player --ros-args -p duration:="$DURATION" -p joint_mode:="$1" \
    -p wait_for_estimator:=30.0 2>&1 | tee "$LOGDIR/$NAME.player.log" | tail -n 25
  finish
}

record_closed() {  # angle | torque (torque: locked joint)
  local mode="$1" joint=free amplitude=0.3490658503988659   # rad (20 deg)
  [ "$mode" = torque ] && joint=locked amplitude=2.0         # N m
  NAME="closed_mild_$mode"
  rig "$joint"
  pi_node --ros-args -p mode:="$mode" >"$LOGDIR/$NAME.pi.log" 2>&1 &
  PIDS+=("$!")
  wait_log "$LOGDIR/$NAME.ukf.log" 'estimating:'   # the loop is closed (holding 0)
  # the steps' first level is 0 for 3 s: bag_record finds the topics meanwhile (checked below)
  record "$TOPICS,/pam/estimate,/pam/reference"
  reference_node --ros-args -p mode:="$mode" -p amplitude:="$amplitude" -p hold:=3.0 \
    -p duration:="$CLOSED_DURATION" >"$LOGDIR/$NAME.reference.log" 2>&1 &
  PIDS+=("$!")
  wait_log "$LOGDIR/$NAME.reference.log" 'profile'
  sleep 2.5
  [ "$(grep -c 'subscribed to' "$LOGDIR/$NAME.record.log")" -ge 5 ] || {
    echo "bag_record found not every topic before the first step: run again"; exit 1; }
  sleep "$(python3 -c "print($CLOSED_DURATION - 3.0)")"   # stop 0.5 s before the profile's end
  finish
}

for mode in "${MODES[@]}"; do
  case "$mode" in
    free|locked) record_validation "$mode" ;;
    closed_angle|closed_torque) record_closed "${mode#closed_}" ;;
    *) echo "unknown mode $mode" >&2; exit 2 ;;
  esac
done
