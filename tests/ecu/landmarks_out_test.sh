#!/usr/bin/env bash
# The landmarks the ECU writes (--landmarks-out), end to end: a short
# simulated drive through the ECU in file mode, judged by markloop-eval. The
# file must hold every landmark of the database (the summary's count), each
# with the car's pose, and markloop-eval must place them on the simulator's
# markings of their class (the placement itself, under a drifted odometry
# frame, is tested in test_eval.cpp). Arguments: a scratch dir,
# markloop-sim, markloop-eval, then the command that runs markloop.
set -euo pipefail
work=$1 sim=$2 eval_tool=$3; shift 3
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"

"$sim" drive --scenario loop --seed 3 --max-frames 400 --out "$work" >/dev/null
"${ecu[@]}" --camera-file "$work/frames.y4m" --can-in "$work/odometry.log" \
  --calibration "$work/camera.yaml" --can-out "$work/ecu-can.log" \
  --detections-out "$work/ecu-detections.csv" --landmarks-out "$work/ecu-landmarks.csv" \
  --summary "$work/ecu-summary.json" --set realtime.mlockall=false --set map.file= 2>"$work/ecu.log"
"$eval_tool" "$work" --json "$work/eval.json" >"$work/eval.txt"

python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
summary = json.load(open(f"{work}/ecu-summary.json"))
rows = open(f"{work}/ecu-landmarks.csv").read().splitlines()
landmarks = json.load(open(f"{work}/eval.json"))["landmarks"]
passes = json.load(open(f"{work}/eval.json"))["passes"]
checks = [
    ("the header", rows[0] == "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose", rows[0]),
    ("a few landmarks", summary["landmarks"] >= 5, summary["landmarks"]),
    ("one row per landmark of the database", len(rows) - 1 == summary["landmarks"], len(rows) - 1),
    ("all judged by markloop-eval", landmarks["count"] == summary["landmarks"] and landmarks["without_pose"] == 0,
     landmarks),
    ("at least 90 % on a marking of their label", landmarks["right_label"] >= 0.9 * landmarks["count"],
     landmarks["right_label"]),
    ("within 0.5 m of it at the median", landmarks["distance_m"]["median"] <= 0.5, landmarks["distance_m"]),
    ("passes judged", passes["count"] >= 5, passes["count"]),
]
failed = 0
for name, ok, got in checks:
    print(("ok   " if ok else "FAIL ") + f"{name}: {got}")
    failed += not ok
sys.exit(1 if failed else 0)
PY
