#!/usr/bin/env bash
# Live mode against real kernel devices: a short drive recorded on the host
# (640x480, a size vivid's HDMI output offers) is played by
# `markloop-sim live` in the HIL VM into vivid's output node and vcan0.
# Passes when every frame was accepted by V4L2 and candump saw exactly the
# recorded odometry frames, in order.
#   live_hil_test.sh MARKLOOP_SIM RUN_IN_VM WORK_DIR
set -euo pipefail
sim=$1 run_in_vm=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
cat >"$work/cam640.yaml" <<'YAML'
%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 450., 0., 319.5, 0., 450., 239.5, 0., 0., 1. ]
mount_height: 1.5
mount_pitch_deg: 12.
YAML
"$sim" drive --scenario loop --camera "$work/cam640.yaml" --max-frames 30 --out "$work/drive" >/dev/null 2>&1
cat >"$work/guest.sh" <<GUEST
#!/bin/sh
set -eu
out=\$HIL_RESULTS
node=
for n in /sys/class/video4linux/video*; do
  grep -q 'vivid-000-vid-out' "\$n/name" && node=/dev/\$(basename "\$n")
done
[ -n "\$node" ] || { echo "no vivid output node"; exit 1; }
candump -L vcan0 >"\$out/candump.txt" &
cpid=\$!
sleep 0.3
"$sim" live --from "$work/drive" --video "\$node" --can vcan0 | tee "\$out/live.txt"
sleep 0.3
kill \$cpid
GUEST
bash "$run_in_vm" --with-vivid --mode vm --results "$work/results" --timeout 600 "sh $work/guest.sh"
live=$(cat "$work/results/out/live.txt")
echo "$live"
echo "$live" | grep -q "30 frames sent (0 failed), 146 CAN frames sent (0 failed)" ||
  { echo "FAIL: live mode did not send every frame"; exit 1; }
# What went onto the bus is the recorded odometry, frame for frame.
sed 's/^([0-9]*\.[0-9]*) //' "$work/results/out/candump.txt" >"$work/bus.txt"
sed 's/^([0-9]*\.[0-9]*) //' "$work/drive/odometry.log" | cmp - "$work/bus.txt" ||
  { echo "FAIL: the bus carried other frames than odometry.log"; exit 1; }
echo "live HIL: ok"
