#!/usr/bin/env bash
# False loops per 1000 km of driving that never revisits a place: the
# simulator's `far` scenario (a town serpentine, every street once) without
# rendering, its simulated detections run through the sequence engine with
# the ECU's settings (markloop-replay --ecu), judged against the truth.
# Every loop found is false.
#
#   tests/loops/false-loop-rate.sh --bin BUILD --out DIR [--drives N] [--km K]
#                                  [--drift X] [--first-seed S]
#
# N drives (default 10) of K km each (default 100, at most 1000), seeds S..,
# odometry drift X (default 1). Each drive goes to DIR/far-SEED (its
# markloop-replay output in DIR/far-SEED/replay.txt); the table is printed
# and written to DIR/summary.txt. Exit status 1 when a drive failed to run,
# 2 on bad options; the loops found do not change it (read the table).
set -euo pipefail

bin=
out=
drives=10
km=100
drift=1
first_seed=1

usage() { sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "false-loop-rate: $*" >&2; exit 2; }
whole() { [[ "$2" =~ ^[1-9][0-9]*$ ]] || die "$1 must be a whole number of at least 1"; }

while [ $# -gt 0 ]; do
  case "$1" in
    --bin|--out|--drives|--km|--drift|--first-seed) [ $# -ge 2 ] || die "$1 needs a value" ;;&
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --drives) whole "$1" "$2"; drives=$2; shift 2 ;;
    --km) whole "$1" "$2"; km=$2; shift 2 ;;
    --drift) drift=$2; shift 2 ;;
    --first-seed) whole "$1" "$2"; first_seed=$2; shift 2 ;;
    --help|-h) usage; exit 0 ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[ -n "$bin" ] || die "--bin BUILD is required (see --help)"
[ -n "$out" ] || die "--out DIR is required (see --help)"
[ "$km" -le 1000 ] || die "--km must be at most 1000"
for tool in markloop-sim markloop-replay; do
  [ -x "$bin/bin/$tool" ] || die "$bin/bin/$tool is missing: build first"
done

mkdir -p "$out"
total_km=0
total_wrong=0
failed=0
rows=()
for ((seed = first_seed; seed < first_seed + drives; ++seed)); do
  dir=$out/far-$seed
  echo "false-loop-rate: drive $((seed - first_seed + 1)) of $drives (seed $seed, $km km, drift $drift)" >&2
  if ! "$bin/bin/markloop-sim" drive --scenario far --laps "$km" --seed "$seed" --drift "$drift" \
      --no-render --out "$dir" > "$dir.sim.log" 2>&1 ||
     ! "$bin/bin/markloop-replay" --markings "$dir/markings.txt" --poses "$dir/poses.txt" \
      --truth "$dir/frames.csv" --truth-radius 5 --ecu --quiet > "$dir/replay.txt" 2>&1; then
    echo "false-loop-rate: seed $seed failed (see $dir.sim.log, $dir/replay.txt)" >&2
    failed=1
    continue
  fi
  route_m=$(awk -F, 'NR > 2 { d += sqrt(($3 - x) ^ 2 + ($4 - y) ^ 2) } NR > 1 { x = $3; y = $4 } END { printf "%.0f", d }' "$dir/frames.csv")
  loops=$(sed -n 's/^matches: \([0-9]*\).*/\1/p' "$dir/replay.txt")
  loops=${loops:-0}
  total_km=$(awk -v a="$total_km" -v b="$route_m" 'BEGIN { printf "%.1f", a + b / 1000 }')
  total_wrong=$((total_wrong + loops))
  rows+=("$(printf '  seed %-4s %8.1f km %6d loops' "$seed" "$(awk -v m="$route_m" 'BEGIN { print m / 1000 }')" "$loops")")
done

{
  echo "false-loop-rate: far (never revisits), drift $drift, markloop-replay --ecu"
  printf '%s\n' "${rows[@]}"
  awk -v km="$total_km" -v n="$total_wrong" \
    'BEGIN { rate = km > 0 ? 1000 * n / km : 0
             printf "  all       %8.1f km %6d loops: %.2f false loops per 1000 km\n", km, n, rate }'
} | tee "$out/summary.txt"
exit "$failed"
