#!/usr/bin/env bash
# End-to-end HIL test of the ECU: a simulated drive played live into devices
# while `markloop` runs live on them, in the qemu VM (or natively where vcan
# and vivid exist):
#   host: markloop-sim renders the drive for the 640x480 HIL camera
#   VM:   vivid's HDMI output is looped back to its capture node;
#         markloop-sim live writes the frames into the output and the
#         odometry onto vcan0 in real time; markloop captures from vivid and
#         reads/writes vcan0; candump records the bus;
#   then: SIGTERM to markloop (map saved, exit 0), and the candump log must
#         hold complete, E2E-valid LoopDetection detections and Status.
#
#   ecu-live-e2e.sh BUILD_DIR RESULTS_DIR [--frames N (0: all)] [--scenario NAME] [--speed M/S]
#
# The drive goes at 10 m/s by default: at 20 m/s the emulated ECU drops
# enough frames that few loops are left to see.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=$(cd "$here/../.." && pwd)
[ $# -ge 2 ] || { echo "usage: ecu-live-e2e.sh BUILD_DIR RESULTS_DIR [--frames N] [--scenario NAME] [--speed M/S]" >&2; exit 2; }
bin=$(cd "$1" && pwd)
results=$2
shift 2
frames=0  # the whole drive: the second lap gives the loops
scenario=loop
speed=10
while [ $# -gt 0 ]; do
  case "$1" in
    --frames) frames=$2; shift 2 ;;
    --scenario) scenario=$2; shift 2 ;;
    --speed) speed=$2; shift 2 ;;
    *) echo "ecu-live-e2e: unknown option $1" >&2; exit 2 ;;
  esac
done
for tool in bin/markloop-sim bin/markloop bin/markloop-hil-can-check; do
  [ -x "$bin/$tool" ] || { echo "ecu-live-e2e: $bin/$tool missing (build first)" >&2; exit 1; }
done
# The VM runs the host's own v4l2-ctl to set vivid up.
command -v v4l2-ctl >/dev/null ||
  { echo "ecu-live-e2e: v4l2-ctl not found: run .ci/setup (package v4l-utils)" >&2; exit 1; }
mkdir -p "$results"
results=$(cd "$results" && pwd)
drive=$results/drive
camera=$src/app/cameras/hil-640x480.yaml

if [ ! -s "$drive/frames.y4m" ] || [ "$(cat "$drive/.args" 2>/dev/null)" != "$scenario $frames $speed" ]; then
  rm -rf "$drive"
  echo "ecu-live-e2e: rendering $frames frames of '$scenario' at $speed m/s for the HIL camera"
  limit=()
  [ "$frames" = 0 ] || limit=(--max-frames "$frames")
  "$bin/bin/markloop-sim" drive --scenario "$scenario" --seed 1 --speed "$speed" --camera "$camera" \
    "${limit[@]}" --out "$drive" >/dev/null
  echo "$scenario $frames $speed" >"$drive/.args"
fi

rm -rf "$results/vm"
bash "$here/run-in-vm.sh" --with-vivid --mode "${MARKLOOP_HIL_MODE:-vm}" --results "$results/vm" \
  --timeout 1200 \
  "bash $here/ecu-live-e2e-vm.sh $bin $drive $camera"
# run-in-vm.sh fails when the command failed; show what the VM left.
cat "$results/vm/out/summary.txt"
