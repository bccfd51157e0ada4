#!/usr/bin/env bash
# Records a calibration campaign for pam-identify LIVE (real processes over DDS) into bags:
#   OUT/locked_<angle>deg  per lock angle: the rig with the joint locked at the angle +
#                          profile_player profile:=calibration_locked (static holds, then jumps)
#   OUT/free               the rig with the joint free + profile_player profile:=calibration_free
# each recorded by bag_record (/pam/pressures, /pam/valve_command, /pam/joint_measured).
# Then: pam-identify OUT/locked_* OUT/free -o RESULT   (printed at the end).
#
# Rigs:
#   --rig sim     (default) sim_node, realtime 1 kHz, plant = nominal + mismatch scenario
#                 (--scenario, default mild, with its pressure sensor model); a locked run starts
#                 sim_node with joint_mode:=locked and initial_state:=[angle, 0, 450 kPa, 450 kPa]
#                 (the locked simulator holds its initial angle). No pauses.
#   --rig driver  driver_node on the real rig (DAQ board with encoder and torque meter fitted).
#                 Before each run the script pauses: lock the joint by hand at the angle (then
#                 unlock it for the free run) and press Enter. driver_node is started for each run
#                 and stopped after it (its shutdown vents both muscles), so the muscles are
#                 vented while you change the lock. Its command watchdog is relaxed to
#                 PAM_CAL_WATCHDOG (default 5 s) during the runs: the valves hold the last command
#                 until bag_record has stopped, so the bag's tail shows what the valves got (the
#                 player commands every sample; the board still vents after 250 ms without host
#                 frames).
#
# Usage: scripts/record_calibration_bags.sh [options]     (options override the environment)
#   -o, --out DIR          output directory (PAM_CAL_OUT, default out/calibration); the bags in it
#                          must not exist yet (never overwritten)
#   --rig sim|driver       (PAM_CAL_RIG, default sim)
#   --angles DEG,...       lock angles (PAM_CAL_ANGLES, default -15,0,15; at least 2, >= 10 deg
#                          apart, for the force coefficients); '' or none: no locked runs
#   --hold S               static hold per voltage (PAM_CAL_HOLD, default 10; 0: none)
#   --pair-hold S          hold per voltage pair (PAM_CAL_PAIR_HOLD, default 3; 0: none)
#   --voltages V,...       hold voltages (PAM_CAL_VOLTAGES, default: profile_player's, the 16
#                          nodes of the valve-map table); a locked run lasts
#                          len(voltages) x (hold + pair_hold) s: 208 s by default
#   --free-duration S      free run (PAM_CAL_FREE_DURATION, default 60; >= 18; 0: none)
#   --scenario NAME|FILE   sim only: the plant's scenario (PAM_CAL_MISMATCH, default mild;
#                          '' or none: the nominal plant; --mismatch: its former name)
#   --seed N               profile seed (PAM_CAL_SEED, default 0)
#   --port DEV             driver only: serial port of the DAQ board (PAM_CAL_PORT, default
#                          /dev/ttyUSB0)
#   --driver-params FILE   driver only: a driver_node parameter file (PAM_CAL_DRIVER_PARAMS)
# Needs `make setup`. Uses its own ROS_DOMAIN_ID (default 78; override with PAM_CAL_DOMAIN) and
# localhost-only discovery, so it does not disturb (or hear) other stacks. Logs in OUT/logs.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/env.sh"
export ROS_DOMAIN_ID="${PAM_CAL_DOMAIN:-78}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY
OUT="${PAM_CAL_OUT:-$ROOT/out/calibration}"
RIG="${PAM_CAL_RIG:-sim}"
ANGLES="${PAM_CAL_ANGLES--15,0,15}"
HOLD="${PAM_CAL_HOLD:-10.0}"
PAIR_HOLD="${PAM_CAL_PAIR_HOLD:-3.0}"
VOLTAGES="${PAM_CAL_VOLTAGES:-}"
FREE_DURATION="${PAM_CAL_FREE_DURATION:-60.0}"
MISMATCH="${PAM_CAL_MISMATCH-mild}"
SEED="${PAM_CAL_SEED:-0}"
PORT="${PAM_CAL_PORT:-/dev/ttyUSB0}"
DRIVER_PARAMS="${PAM_CAL_DRIVER_PARAMS:-}"
WATCHDOG="${PAM_CAL_WATCHDOG:-5.0}"
TOPICS=/pam/pressures,/pam/valve_command,/pam/joint_measured   # what pam-identify reads

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'; }
die() { echo "record_calibration_bags: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    -o|--out) OUT="${2:?$1 needs a value}"; shift ;;
    --rig) RIG="${2:?$1 needs a value}"; shift ;;
    --angles) ANGLES="${2?$1 needs a value}"; shift ;;
    --hold) HOLD="${2:?$1 needs a value}"; shift ;;
    --pair-hold) PAIR_HOLD="${2:?$1 needs a value}"; shift ;;
    --voltages) VOLTAGES="${2:?$1 needs a value}"; shift ;;
    --free-duration) FREE_DURATION="${2:?$1 needs a value}"; shift ;;
    --scenario|--mismatch) MISMATCH="${2?$1 needs a value}"; shift ;;
    --seed) SEED="${2:?$1 needs a value}"; shift ;;
    --port) PORT="${2:?$1 needs a value}"; shift ;;
    --driver-params) DRIVER_PARAMS="${2:?$1 needs a value}"; shift ;;
    --*=*) set -- "${1%%=*}" "${1#*=}" "${@:2}"; continue ;;   # --angles=-15,15
    *) die "unknown argument '$1' (see --help)" ;;
  esac
  shift
done
case "$RIG" in sim|driver) ;; *) die "--rig must be sim or driver, got '$RIG'" ;; esac
[ "$MISMATCH" = none ] && MISMATCH=""
[ "$ANGLES" = none ] && ANGLES=""
IFS=, read -r -a ANGLE_LIST <<<"${ANGLES// /}"
isnum() { [[ "$1" =~ ^[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)$ ]]; }
for a in "${ANGLE_LIST[@]}"; do isnum "$a" || die "--angles: '$a' is not a number"; done
for v in "$HOLD" "$PAIR_HOLD" "$FREE_DURATION" "$WATCHDOG"; do
  isnum "$v" || die "'$v' is not a number"
done
dbl() {  # a number as a ROS double: 2 -> 2.0
  awk -v v="$1" 'BEGIN { x = v + 0; if (x == int(x)) printf "%d.0", x; else printf "%.12g", x }'
}
HOLD="$(dbl "$HOLD")" PAIR_HOLD="$(dbl "$PAIR_HOLD")" FREE_DURATION="$(dbl "$FREE_DURATION")"
WATCHDOG="$(dbl "$WATCHDOG")"
# floats "0,5,10" -> "[0.0, 5.0, 10.0]" (a ROS double[]), or fail
floats() {
  python3 -c 'import sys; print("[%s]" % ", ".join(str(float(v)) for v in sys.argv[1].split(",")))'\
    "$1" 2>/dev/null
}
VOLTAGE_ARGS=()
if [ -n "$VOLTAGES" ]; then
  list="$(floats "$VOLTAGES")" || die "--voltages: expected numbers separated by commas"
  VOLTAGE_ARGS=(-p "voltages:=$list")
fi
FREE_RUN=1
awk -v d="$FREE_DURATION" 'BEGIN { exit !(d + 0 == 0) }' && FREE_RUN=0
[ ${#ANGLE_LIST[@]} -gt 0 ] || [ "$FREE_RUN" = 1 ] || die "nothing to record"
[ ${#ANGLE_LIST[@]} -ge 2 ] || echo "note: fewer than 2 lock angles: pam-identify cannot" \
  "identify the force coefficients (nor, then, mu_s, mu_p) from this campaign" >&2

# bag name of a lock angle, as pam-calibration-bags names them: locked_m15deg, locked_0deg, ...
run_name() { awk -v a="$1" 'BEGIN { a += 0; s = (a < 0) ? "m" : ((a > 0) ? "p" : "")
  printf "locked_%s%gdeg", s, (a < 0) ? -a : a }'; }
NAMES=()
for a in "${ANGLE_LIST[@]}"; do NAMES+=("$(run_name "$a")"); done
[ "$FREE_RUN" = 1 ] && NAMES+=(free)
for name in "${NAMES[@]}"; do
  [ ! -e "$OUT/$name" ] || die "$OUT/$name exists: not overwriting it (choose another --out)"
done
mkdir -p "$OUT/logs" "$OUT/.recording"
OUT="$(cd "$OUT" && pwd)"
LOGDIR="$OUT/logs"
PENDING="$OUT/.recording"   # bags being recorded
NAME="" REC="" RIGPID=""

source "$ROOT/scripts/stack_processes.sh"   # PIDS, stop_all
STOP_WAIT=10
cleanup() { stop_all; }
trap cleanup EXIT
trap 'exit 130' INT TERM

# wait_log FILE PATTERN PID: wait (at most 60 s) until FILE holds PATTERN; fail if PID exits
wait_log() {
  for _ in $(seq 600); do
    grep -q "$2" "$1" 2>/dev/null && return 0
    kill -0 "$3" 2>/dev/null || { echo "$(basename "$1" .log) exited:"; cat "$1"; exit 1; }
    sleep 0.1
  done
  echo "timed out waiting for '$2' in $1:"; cat "$1"; exit 1
}

# rig JOINT ANGLE_RAD: sim_node or driver_node, in the background
rig() {
  if [ "$RIG" = sim ]; then
    sim_node --ros-args -p scenario:="$MISMATCH" -p joint_mode:="$1" \
      -p "initial_state:=[$2, 0.0, 450000.0, 450000.0]" >"$LOGDIR/$NAME.rig.log" 2>&1 &
  else
    local params=()
    [ -n "$DRIVER_PARAMS" ] && params=(--params-file "$DRIVER_PARAMS")
    driver_node --ros-args "${params[@]}" -p port:="$PORT" -p watchdog_timeout:="$WATCHDOG" \
      -p arm_at_start:=true >"$LOGDIR/$NAME.rig.log" 2>&1 &
  fi
  RIGPID=$!; PIDS+=("$RIGPID")
}

# run JOINT ANGLE_DEG PLAYER_ARGS...: one run into $OUT/$NAME. bag_record and profile_player start
# first: bag_record subscribes to the player's valve_command before the rig runs (the player
# commands from the first pressure sample on, so every command is recorded); then the rig. The
# bag is recorded into $PENDING/$NAME and moved to $OUT/$NAME once complete and checked (an
# aborted run leaves no bag that pam-identify OUT/locked_* would pick up).
run() {
  local joint="$1" angle_deg="$2" rad player
  shift 2
  rad="$(dbl "$(awk -v d="$angle_deg" 'BEGIN { printf "%.12g", d * atan2(0, -1) / 180 }')")"
  if [ "$RIG" = driver ]; then
    if [ "$joint" = locked ]; then
      echo "== $NAME: LOCK the joint at $angle_deg deg (encoder and torque meter fitted)"
    else
      echo "== $NAME: UNLOCK the joint (free; encoder fitted)"
    fi
    read -r -p "   then press Enter (Ctrl-C aborts) " _ || die "no input: aborted"
  fi
  echo "== $NAME: recording into $OUT/$NAME, logs in $LOGDIR"
  rm -rf "${PENDING:?}/$NAME"
  bag_record --ros-args -p output:="$PENDING/$NAME" -p topics:="$TOPICS" -p discovery_period:=0.1 \
    >"$LOGDIR/$NAME.record.log" 2>&1 &
  REC=$!; PIDS+=("$REC")
  profile_player --ros-args -p joint_mode:="$joint" -p seed:="$SEED" -p startup_timeout:=60.0 \
    "$@" >"$LOGDIR/$NAME.player.log" 2>&1 &
  player=$!; PIDS+=("$player")
  wait_log "$LOGDIR/$NAME.player.log" 'playing the' "$player"
  grep 'playing the' "$LOGDIR/$NAME.player.log" | sed 's/^.*\]: /   /'
  wait_log "$LOGDIR/$NAME.record.log" 'subscribed to /pam/valve_command' "$REC"
  rig "$joint" "$rad"
  while kill -0 "$player" 2>/dev/null; do
    kill -0 "$RIGPID" 2>/dev/null || { echo "the rig exited:"; tail -n 20 "$LOGDIR/$NAME.rig.log"
                                       exit 1; }
    sleep 0.2
  done
  wait "$player" || { echo "profile_player failed:"; cat "$LOGDIR/$NAME.player.log";
                      echo "rig log:"; tail -n 20 "$LOGDIR/$NAME.rig.log"; exit 1; }
  # stop bag_record first (SIGINT: it closes the bag), then the rig
  kill -INT "$REC"; wait "$REC" || { echo "bag_record failed:"; cat "$LOGDIR/$NAME.record.log"
                                      exit 1; }
  cleanup
  # the player's summary: its INFO lines from 'profile_player summary:' on, without the prefix
  sed -n '/profile_player summary: /,$p' "$LOGDIR/$NAME.player.log" | sed 's/^.*\]: /   /'
  check "$PENDING/$NAME" "$joint" "$angle_deg" || {
    echo "the bag is left in $PENDING/$NAME"; exit 1; }
  mv "$PENDING/$NAME" "$OUT/$NAME"
}

# check BAG JOINT ANGLE_DEG: read the bag as pam-identify will; say what it holds, warn on surprises
check() {
  python3 - "$@" <<'EOF'
import math, sys
from pam_estimator.bag_runs import load_bag_run
path, joint, angle = sys.argv[1], sys.argv[2], float(sys.argv[3])
try:
    got = load_bag_run(path)
except Exception as exc:  # noqa: BLE001
    sys.exit(f'   {path}: not usable: {exc}')
run = got.run
psi = [math.degrees(v) for v in run.x[:, 0]]
print(f'   bag: {len(run.t)} samples ({run.t[-1]:.1f} s), {got.commands} valve commands, '
      f'joint {"locked" if run.locked else "free"}, angle {min(psi):+.2f}..{max(psi):+.2f} deg, '
      f'torque {min(run.torque):+.3f}..{max(run.torque):+.3f} N m')
if got.commands == 0:
    sys.exit('   no valve commands recorded: pam-identify cannot use this bag')
gaps = [b - a for a, b in zip(run.t[:-1], run.t[1:])]
if max(gaps) > 0.02:
    print(f'   WARNING: sampling stalled (largest gap {1e3 * max(gaps):.0f} ms, '
          f'{sum(g > 0.005 for g in gaps)} gaps over 5 ms; a loaded machine?): the transient and '
          'friction fits (A1, A2, k2, mu_p) may suffer; if pam-identify finds them uncertain, '
          'record this run again with less load')
if got.measured_missing > 0.05 * len(run.t):
    print(f'   WARNING: {got.measured_missing} samples without joint_measured (encoder / torque '
          'meter not reported by the rig?)')
if joint == 'locked' and not run.locked:
    print('   WARNING: the angle moved during this locked run (pam-identify reads a bag as locked '
          'only when the measured angle is constant): check the lock and the encoder')
if joint == 'locked' and abs(sorted(psi)[len(psi) // 2] - angle) > 2.0:
    print(f'   WARNING: locked at {sorted(psi)[len(psi) // 2]:+.2f} deg, not {angle:+g} deg')
if joint == 'free' and max(psi) - min(psi) < 5.0:
    print('   WARNING: the joint moved less than 5 deg: pam-identify needs more travel for k2, '
          'mu_s and mu_p (a longer --free-duration)')
EOF
}

LOCK_ARGS=(-p profile:=calibration_locked -p hold:="$HOLD" -p pair_hold:="$PAIR_HOLD"
           "${VOLTAGE_ARGS[@]}")
echo "calibration campaign on the $RIG rig into $OUT:" \
  "${#ANGLE_LIST[@]} locked runs${ANGLES:+ at $ANGLES deg}, free run ${FREE_DURATION} s" \
  "$([ "$RIG" = sim ] && echo "(plant mismatch '${MISMATCH:-none}')")"
for i in "${!ANGLE_LIST[@]}"; do
  NAME="$(run_name "${ANGLE_LIST[$i]}")"
  run locked "${ANGLE_LIST[$i]}" "${LOCK_ARGS[@]}"
done
if [ "$FREE_RUN" = 1 ]; then
  NAME=free
  run free 0 -p profile:=calibration_free -p duration:="$FREE_DURATION"
fi

rmdir "$PENDING" 2>/dev/null || true
runs=()
for a in "${ANGLE_LIST[@]}"; do runs+=("$OUT/$(run_name "$a")"); done
[ "$FREE_RUN" = 1 ] && runs+=("$OUT/free")
echo
echo "done. Next: identify the parameters from these bags:"
extra=""
# no static holds, fewer than 2 lock angles or no free run: some parameters stay at their priors
if [ "$HOLD" = 0.0 ] || [ ${#ANGLE_LIST[@]} -lt 2 ] || [ "$FREE_RUN" = 0 ]; then
  extra=" --partial"
fi
[ "$RIG" = sim ] && [ -n "$MISMATCH" ] && extra="$extra --truth-scenario $MISMATCH"
echo "  pam-identify ${runs[*]} -o $OUT/identified$extra"
