#!/usr/bin/env bash
# Issue 64's table: runs drives through the whole chain (simulator, ECU,
# markloop-eval: sim/drive-through-ecu.sh) and prints markloop-eval
# --summary of their eval.json files: revisit events closed by kind and
# length, median and p90 closure distance, wrong loop detections, relative
# pose error.
#
#   tests/loops/revisit-table.sh --bin BUILD --out DIR [--jobs N] [DRIVE...]
#
# A DRIVE is SCENARIO:SEED[:SIM_OPTIONS], the markloop-sim drive options
# separated by commas: loop:1, grid:2:--light,night, ring:3:--drift,3.
# Without DRIVEs, the default list below (DEFAULT_DRIVES). Each drive goes to
# DIR/NAME (NAME: the DRIVE with ':' and ',' as '_'), its log in
# DIR/NAME/run.log; frames.y4m is deleted after the ECU ran. The summary is
# DIR/summary.txt and DIR/summary.json. --jobs N runs N drives at once
# (default 1; each renders for minutes on one core). Exit status 1 when a
# drive failed (the table sums the others), 2 on bad options.
set -euo pipefail

# The default drives: the town's revisit shapes (turn-ins, opposite,
# closing, the look-alike avenue) and the older scenarios, over several
# seeds, some at night, with worn paint, many vehicles ahead or three times
# the odometry's drift. A new scenario is one more line here.
DEFAULT_DRIVES=(
  turn-ins:1 turn-ins:2 turn-ins:3:--light,night turn-ins:4:--wear,0.7 turn-ins:5:--occluders,0.8
  turn-ins:6:--drift,3
  opposite:1 opposite:2 opposite:3:--light,night opposite:4:--drift,3
  closing:1 closing:2:--wear,0.7 closing:3:--occluders,0.8 closing:4:--drift,3
  avenue:1 avenue:2:--light,night avenue:3:--drift,3
  loop:1 loop:2:--drift,3 grid:1 grid:2:--light,night figure8:1 two-days:1 ring:1
)

here=$(cd "$(dirname "$0")" && pwd)
chain=$here/../../sim/drive-through-ecu.sh
bin=
out=
jobs=1
drives=()

usage() { sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "revisit-table: $*" >&2; exit 2; }

while [ $# -gt 0 ]; do
  case "$1" in
    --bin) [ $# -ge 2 ] || die "--bin needs a value"; bin=$2; shift 2 ;;
    --out) [ $# -ge 2 ] || die "--out needs a value"; out=$2; shift 2 ;;
    --jobs) [ $# -ge 2 ] || die "--jobs needs a value"; jobs=$2; shift 2 ;;
    --help|-h) usage; exit 0 ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) drives+=("$1"); shift ;;
  esac
done
[ -n "$bin" ] || die "--bin BUILD is required (see --help)"
[ -n "$out" ] || die "--out DIR is required (see --help)"
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || die "--jobs must be a whole number of at least 1"
[ -x "$bin/bin/markloop-eval" ] || die "$bin/bin/markloop-eval is missing: build first"
[ ${#drives[@]} -gt 0 ] || drives=("${DEFAULT_DRIVES[@]}")
for drive in "${drives[@]}"; do
  [[ "$drive" =~ ^[A-Za-z0-9_.-]+:[0-9]+(:.*)?$ ]] || die "bad DRIVE '$drive': SCENARIO:SEED[:SIM_OPTIONS]"
done

# One drive through the chain into DIR/NAME; its output in run.log.
run_drive() {
  local drive=$1 scenario seed options name
  IFS=: read -r scenario seed options <<<"$drive"
  name=${drive//[:,]/_}
  local sim=()
  [ -z "$options" ] || IFS=, read -r -a sim <<<"$options"
  mkdir -p "$out/$name"
  rm -f "$out/$name/eval.json"
  if "$chain" --bin "$bin" --out "$out/$name" --scenario "$scenario" --seed "$seed" -- "${sim[@]}" \
      >"$out/$name/run.log" 2>&1; then
    echo "revisit-table: $drive done"
  else
    echo "revisit-table: $drive FAILED (see $out/$name/run.log)"
    return 1
  fi
}

mkdir -p "$out"
echo "revisit-table: ${#drives[@]} drives, $jobs at a time, into $out"
failed=0
running=0
for drive in "${drives[@]}"; do
  if [ "$running" -ge "$jobs" ]; then
    wait -n || failed=$((failed + 1))
    running=$((running - 1))
  fi
  run_drive "$drive" &
  running=$((running + 1))
done
while [ "$running" -gt 0 ]; do
  wait -n || failed=$((failed + 1))
  running=$((running - 1))
done

results=()
for drive in "${drives[@]}"; do
  f=$out/${drive//[:,]/_}/eval.json
  [ -s "$f" ] && results+=("$f")
done
[ ${#results[@]} -gt 0 ] || { echo "revisit-table: no drive finished" >&2; exit 1; }
"$bin/bin/markloop-eval" --summary "${results[@]}" --json "$out/summary.json" | tee "$out/summary.txt"
[ "$failed" = 0 ] || { echo "revisit-table: $failed drive(s) failed" >&2; exit 1; }
