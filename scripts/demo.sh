#!/usr/bin/env bash
# The main job (`make demo`): sensor-less angle control of the simulated rig in real time.
# pam-bringup starts, as separate processes talking over DDS, the simulated rig (sim_node at
# 1 kHz, the 'mild' mismatched plant with its noisy 12-bit pressure sensors), the UKF (ukf_node,
# nominal model), the PI controller (pi_node, feedback = the estimate) and reference_node
# (paper-style angle steps within +-20 deg, 8 s each), from pam_bringup/config/bringup.yaml.
# tracking_report records DURATION seconds, then prints per step the steady-state error against
# the true (measured) angle and the settling time, the estimation error, and writes a figure like
# the paper's Fig. 14 to out/demo_tracking.png.
#
# Environment: DURATION (s, default 64), ROS_DOMAIN_ID (default: a random one in 110..199, so
# the demo does not talk to other graphs). Expects the venv on PATH and AMENT_PREFIX_PATH set
# (make demo does both).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

DURATION="${DURATION:-64}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( (RANDOM % 90) + 110 ))}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
mkdir -p out/logs

bringup_pid=
cleanup() { [ -n "$bringup_pid" ] && kill -INT "$bringup_pid" 2>/dev/null && wait "$bringup_pid" || true; }
trap cleanup EXIT

echo "demo: ROS_DOMAIN_ID=$ROS_DOMAIN_ID, ${DURATION} s of closed-loop angle tracking; node logs in out/logs/"
pam-bringup --log-dir out/logs >out/logs/bringup.log 2>&1 &
bringup_pid=$!
tracking_report --ros-args -p "duration:=$(printf %.1f "$DURATION")" -p plot:=out/demo_tracking.png
status=$?
if ! kill -0 "$bringup_pid" 2>/dev/null; then
  echo "demo: pam-bringup stopped early; its log:" >&2
  tail -n 30 out/logs/bringup.log >&2
  exit 1
fi
exit $status
