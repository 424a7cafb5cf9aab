#!/usr/bin/env bash
# tests/loops/replay-table.sh on a table of one drive: a `turn-ins` drive
# without rendering, its simulated detections written as the ECU writes its
# own (ecu-detections.csv, in the car's frame) with its poses as the ECU's
# odometry. The script runs, closes the revisits and names no loop wrong.
set -euo pipefail
bin=$1 work=$2
rm -rf "$work" && mkdir -p "$work/table/turn-ins-1/posegraph"
drive=$work/table/turn-ins-1
"$bin/bin/markloop-sim" drive --scenario turn-ins --seed 1 --no-render --out "$drive" >"$work/sim.log" 2>&1
cp "$drive/poses.txt" "$drive/posegraph/before.kitti"
# World x right, z ahead (KITTI) -> the car's frame: ground_x ahead, ground_y left.
awk 'NR == FNR { pose[FNR - 1] = $0; next }
     FNR == 1 { print "frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y"; next }
     {
       split(pose[$1], m, " ")
       yaw = atan2(-m[3], m[11]); dx = $4 - m[12]; dy = -$2 + m[4]
       printf "%d,%s,0.900,0,0,0,0,0,0,0,0,%.3f,%.3f\n", $1, $5,
         cos(yaw) * dx + sin(yaw) * dy, -sin(yaw) * dx + cos(yaw) * dy
     }' "$drive/poses.txt" "$drive/markings.txt" >"$drive/ecu-detections.csv"
bash "$(dirname "$0")/../loops/replay-table.sh" --bin "$bin" --table "$work/table" --out "$work/out"
grep -Eq 'events of 50 m or more closed +[1-9][0-9]* /' "$work/out/summary.txt"
grep -Eq 'wrong loops +0$' "$work/out/summary.txt"
