#!/usr/bin/env bash
# What must not change when code is restructured: writes, for one build,
# the ECU's CAN output and detections on the main job's drive, markloop-replay's
# output on that drive's paper-format files, markloop-detect's JSON on the
# shared real images, and a digest of the compiled-in model. Two snapshots are
# compared with `diff -r`.
#
#   tests/behaviour/snapshot.sh --bin BUILD_DIR --out DIR [--real DIR] [--drive DIR]
#
#   --bin DIR    build tree (programs in DIR/bin)
#   --out DIR    where the snapshot goes (emptied first)
#   --real DIR   the real images; default ../shared/data/roadmarks-honda
#   --drive DIR  a rendered drive to reuse (frames.y4m, odometry.log,
#                markings.txt, poses.txt); default: render `loop`, seed 1, into
#                DIR/drive and delete its frames afterwards
set -euo pipefail
bin= out= real=../shared/data/roadmarks-honda drive=
die() { echo "snapshot: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=${2:?}; shift 2 ;;
    --out) out=${2:?}; shift 2 ;;
    --real) real=${2:?}; shift 2 ;;
    --drive) drive=${2:?}; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
[ -n "$bin" ] && [ -n "$out" ] || die "--bin and --out are required (see --help)"
for tool in markloop markloop-replay markloop-detect markloop-sim; do
  [ -x "$bin/bin/$tool" ] || die "$bin/bin/$tool is missing: build first"
done
cd "$(dirname "$0")/../.."
rm -rf "$out" && mkdir -p "$out"
render=0
if [ -z "$drive" ]; then
  drive=$out/drive render=1
  echo "snapshot: rendering the main job's drive"
  "$bin/bin/markloop-sim" drive --scenario loop --seed 1 --out "$drive" >"$out/sim.txt"
fi

echo "snapshot: ECU on $drive"
"$bin/bin/markloop" --camera-file "$drive/frames.y4m" --can-in "$drive/odometry.log" \
  --calibration "$drive/camera.yaml" --can-out "$out/ecu-can.log" \
  --detections-out "$out/ecu-detections.csv" --landmarks-out "$out/ecu-landmarks.csv" \
  --set realtime.mlockall=false --quiet
# Status frames (0x2B0) and the times frames are sent at carry the run's
# timings; the frames themselves must match.
grep -v ' 2B0#' "$out/ecu-can.log" | sed 's/^([0-9.]*) //' >"$out/ecu-can-frames.txt" || true

echo "snapshot: replay"
for k in 3 4 6; do
  "$bin/bin/markloop-replay" --markings "$drive/markings.txt" --poses "$drive/poses.txt" --k "$k" \
    >"$out/replay-k$k.txt"
done
"$bin/bin/markloop-replay" --markings "$drive/markings.txt" --compat --k 4 >"$out/replay-compat.txt"

echo "snapshot: detect on $real"
find "$real/images" -type f | sort | xargs "$bin/bin/markloop-detect" --camera app/cameras/honda.yaml \
  >"$out/detect.jsonl"

[ "$render" = 0 ] || rm -f "$drive/frames.y4m"
echo "snapshot: written to $out"
