#!/usr/bin/env bash
# The revisit table again from what the ECU saw, in seconds: each drive of a
# revisit-table.sh (or drive-through-ecu.sh) output, its ECU's detections
# (ecu-detections.csv) placed with the ECU's own odometry
# (posegraph/before.kitti) and run through the engine with the ECU's
# settings (markloop-replay --ecu-detections ... --ecu), judged against the
# truth. It tracks the ECU's own table closely, so engine settings and
# changes can be tried on rendered drives without rendering them again.
#
#   tests/loops/replay-table.sh --bin BUILD --table DIR --out DIR [-- REPLAY OPTIONS...]
#
# Options after -- go to markloop-replay after --ecu (for example
# --place-pair-bits 0). Each drive's replay output goes to OUT/NAME.txt; the
# table (events of 50 m or more closed, the other direction's, the median
# and p90 closure distance and the wrong loops) is printed and written to
# OUT/summary.txt. Exit status 1 when a drive failed to run, 2 on bad
# options or a table without drives.
set -euo pipefail

bin=
table=
out=
replay_extra=()

usage() { sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "replay-table: $*" >&2; exit 2; }

while [ $# -gt 0 ]; do
  case "$1" in
    --bin|--table|--out) [ $# -ge 2 ] || die "$1 needs a value" ;;&
    --bin) bin=$2; shift 2 ;;
    --table) table=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --) shift; replay_extra=("$@"); break ;;
    --help|-h) usage; exit 0 ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[ -n "$bin" ] || die "--bin BUILD is required (see --help)"
[ -n "$table" ] || die "--table DIR is required (see --help)"
[ -n "$out" ] || die "--out DIR is required (see --help)"
[ -x "$bin/bin/markloop-replay" ] || die "$bin/bin/markloop-replay is missing: build first"

mkdir -p "$out"
rm -f "$out"/*.txt
failed=0
drives=0
for dir in "$table"/*/; do
  dir=${dir%/}
  [ -f "$dir/ecu-detections.csv" ] || continue
  name=$(basename "$dir")
  drives=$((drives + 1))
  if ! "$bin/bin/markloop-replay" --ecu-detections "$dir/ecu-detections.csv" \
      --poses "$dir/posegraph/before.kitti" --truth "$dir/frames.csv" --truth-radius 5 \
      --ecu "${replay_extra[@]}" > "$out/$name.txt" 2>&1; then
    echo "replay-table: $name failed (see $out/$name.txt)" >&2
    failed=1
  fi
done
[ "$drives" -gt 0 ] || die "$table holds no drive with an ecu-detections.csv"

cat "$out"/*.txt |
  awk -v title="replay-table: $drives drives of $table, the ECU's detections through markloop-replay --ecu" \
    -f "$(dirname "$0")/replay-summary.awk" > "$out/summary.tmp"
mv "$out/summary.tmp" "$out/summary.txt"
cat "$out/summary.txt"
exit "$failed"
