#!/usr/bin/env bash
# Revisit events on the town scenarios without rendering: the simulator's
# own observations of `turn-ins`, `opposite`, `closing`, `avenue`, `loop`
# and `grid` (seeds 1..S, and 1..D at three times the odometry's drift)
# through the sequence engine with the ECU's settings (markloop-replay
# --ecu), judged against the truth. Fast: no frames are rendered.
#
#   tests/loops/town-drives.sh --bin BUILD --out DIR [--seeds S] [--drift-seeds D]
#                              [--first-seed F] [-- REPLAY OPTIONS...]
#
# S defaults to 13, D to 6, F (the first seed) to 1. Options after -- go to
# markloop-replay after --ecu (for example --place-pair-bits 0). Each drive
# goes to DIR/NAME-SEED (its replay output in replay.txt); the table is
# printed and written to DIR/summary.txt: events of 50 m or more closed,
# the other direction's, the median and p90 closure distance and the wrong
# loops. Exit status 1 when a drive failed to run, 2 on bad options.
set -euo pipefail

bin=
out=
seeds=13
drift_seeds=6
first_seed=1
replay_extra=()

usage() { sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "town-drives: $*" >&2; exit 2; }
whole() { [[ "$2" =~ ^[0-9]+$ ]] || die "$1 must be a whole number"; }

while [ $# -gt 0 ]; do
  case "$1" in
    --bin|--out|--seeds|--drift-seeds|--first-seed) [ $# -ge 2 ] || die "$1 needs a value" ;;&
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --seeds) whole "$1" "$2"; seeds=$2; shift 2 ;;
    --drift-seeds) whole "$1" "$2"; drift_seeds=$2; shift 2 ;;
    --first-seed) whole "$1" "$2"; first_seed=$2; shift 2 ;;
    --) shift; replay_extra=("$@"); break ;;
    --help|-h) usage; exit 0 ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[ -n "$bin" ] || die "--bin BUILD is required (see --help)"
[ -n "$out" ] || die "--out DIR is required (see --help)"
for tool in markloop-sim markloop-replay; do
  [ -x "$bin/bin/$tool" ] || die "$bin/bin/$tool is missing: build first"
done

mkdir -p "$out"
failed=0
drives=0
run() {  # NAME SEED DIR [sim options...]
  local name=$1 seed=$2 dir=$3
  shift 3
  drives=$((drives + 1))
  if ! "$bin/bin/markloop-sim" drive --scenario "$name" --seed "$seed" --no-render "$@" --out "$dir" \
      > "$dir.sim.log" 2>&1 ||
     ! "$bin/bin/markloop-replay" --markings "$dir/markings.txt" --poses "$dir/poses.txt" \
      --truth "$dir/frames.csv" --truth-radius 5 --ecu "${replay_extra[@]}" > "$dir/replay.txt" 2>&1; then
    echo "town-drives: $name seed $seed failed (see $dir.sim.log, $dir/replay.txt)" >&2
    failed=1
  fi
}
last_seed=$((first_seed + seeds - 1))
last_drift_seed=$((first_seed + drift_seeds - 1))
for name in turn-ins opposite closing avenue loop grid; do
  echo "town-drives: $name" >&2
  for ((seed = first_seed; seed <= last_seed; ++seed)); do run "$name" "$seed" "$out/$name-$seed"; done
  for ((seed = first_seed; seed <= last_drift_seed; ++seed)); do
    run "$name" "$seed" "$out/$name-drift3-$seed" --drift 3
  done
done

# The events of 50 m or more, then the sums.
cat "$out"/*/replay.txt |
  awk -v title="town-drives: $drives drives without rendering, markloop-replay --ecu" \
    -f "$(dirname "$0")/replay-summary.awk" | tee "$out/summary.txt"
exit "$failed"
