# Sourced by the scripts that run the live stack (bags/record_reference_bags.sh,
# scripts/record_calibration_bags.sh): the processes they start go into PIDS; stop_all stops them
# all: SIGINT to each, then up to STOP_WAIT s (default 10) for each to exit, then SIGKILL.
PIDS=()

stop_all() {
  local pid
  for pid in "${PIDS[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for pid in "${PIDS[@]}"; do
    for _ in $(seq "$(( ${STOP_WAIT:-10} * 10 ))"); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  PIDS=()
}
