#!/usr/bin/env bash
# The whole chain on a simulated drive: the simulator renders the drive
# (frames.y4m + odometry.log), the ECU processes it in file mode (markloop),
# and the evaluation judges what the ECU sent against the simulator's truth.
#
#   sim/drive-through-ecu.sh [--bin BUILD_DIR] [--out DIR]
#                            [--scenario NAME | --route POSE_FILE] [--seed N] [--realtime] [--keep-frames] [--map FILE]
#                            [-- extra markloop-sim drive options]
#
# Outputs in DIR: the sim's files, ecu-can.log (everything the ECU sent),
# ecu-detections.csv, ecu-landmarks.csv, ecu-summary.json (timings, counters),
# posegraph/ (markloop-posegraph: before/after.tum and .kitti, posegraph.svg,
# solver.txt), eval.json and loops.svg/loops.png (markloop-eval, with the
# corrected trajectory drawn). frames.y4m (about 0.65 MB
# per frame) is deleted after the ECU ran unless --keep-frames.
set -euo pipefail

bin=build/host
out=
scenario=loop
route=
seed=1
realtime=()
keep_frames=0
map_args=()
sim_extra=()

usage() { sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "drive-through-ecu: $*" >&2; exit 2; }

while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scenario) scenario=$2; shift 2 ;;
    --route) route=$2; shift 2 ;;
    --seed) seed=$2; shift 2 ;;
    --realtime) realtime=(--realtime); shift ;;
    --keep-frames) keep_frames=1; shift ;;
    --map) map_args=(--map "$2"); shift 2 ;;
    --help|-h) usage; exit 0 ;;
    --) shift; sim_extra=("$@"); break ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
if [ -n "$route" ]; then
  [ -r "$route" ] || die "cannot read route file $route"
  world=(--route "$route")
  name=$(basename "$route")
else
  world=(--scenario "$scenario")
  name=$scenario
fi
[ -n "$out" ] || out=build/demo-ecu-${name%%.*}
for tool in bin/markloop-sim bin/markloop bin/markloop-posegraph bin/markloop-eval; do
  [ -x "$bin/$tool" ] || die "$bin/$tool is missing: build first (cmake --build --preset host)"
done

mkdir -p "$out"
echo "drive-through-ecu: simulating '$name' (seed $seed) into $out"
"$bin/bin/markloop-sim" drive "${world[@]}" --seed "$seed" --out "$out" "${sim_extra[@]}"
echo "drive-through-ecu: markloop (file mode${realtime:+, real time})"
"$bin/bin/markloop" --camera-file "$out/frames.y4m" --can-in "$out/odometry.log" \
  --calibration "$out/camera.yaml" --can-out "$out/ecu-can.log" \
  --detections-out "$out/ecu-detections.csv" --landmarks-out "$out/ecu-landmarks.csv" \
  --summary "$out/ecu-summary.json" \
  --set realtime.mlockall=false "${map_args[@]}" "${realtime[@]}"
[ "$keep_frames" = 1 ] || rm -f "$out/frames.y4m"
echo "drive-through-ecu: pose graph (odometry and the ECU's loops)"
"$bin/bin/markloop-posegraph" --can-in "$out/odometry.log" --can-out "$out/ecu-can.log" \
  --truth "$out/frames.csv" --out "$out/posegraph"
echo "drive-through-ecu: evaluation"
"$bin/bin/markloop-eval" "$out" --json "$out/eval.json" --corrected "$out/posegraph/after.tum"
