#!/usr/bin/env bash
# The main job (`make demo`): the simulated rig (sim_node, real time at 1 kHz, default parameters)
# driven open loop through the 130 s validation profile by profile_player, with the sensor-less
# estimator (ukf_node) running beside it: three separate processes talking over DDS. At the end
# profile_player prints a summary (rate, missing samples, ranges, online angle-estimate metrics)
# and the run is saved to out/demo_run.npz (readable by pam-evaluate).
#
# Environment: DURATION (s, default 130), ROS_DOMAIN_ID (default: a random free-ish one, so the
# demo does not talk to other graphs), PAM_DEMO_OUT (default out/demo_run.npz).
# Expects the venv on PATH and AMENT_PREFIX_PATH set (make demo does both).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

DURATION="${DURATION:-130}"
OUT="${PAM_DEMO_OUT:-out/demo_run.npz}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 90) + 110 ))}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
mkdir -p "$(dirname "$OUT")" out/logs

pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  sleep 1
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
}
trap cleanup EXIT

echo "demo: ROS_DOMAIN_ID=$ROS_DOMAIN_ID, ${DURATION} s of the validation profile; node logs in out/logs/"
sim_node >out/logs/sim_node.log 2>&1 & pids+=($!)
ukf_node >out/logs/ukf_node.log 2>&1 & pids+=($!)
profile_player --ros-args -p "duration:=$(printf %.1f "$DURATION")" -p "save:=$OUT" -p startup_timeout:=90.0 -p wait_for_estimator:=60.0
