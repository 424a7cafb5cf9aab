#!/usr/bin/env bash
# The landmarks the ECU writes (--landmarks-out), end to end: a short
# simulated drive through the ECU in file mode, judged by markloop-eval. The
# file must hold every landmark of the database (the summary's count), each
# with the car's pose, and markloop-eval must place them on the simulator's
# markings of their class (the placement itself, under a drifted odometry
# frame, is tested in test_eval.cpp); a loaded map's landmarks are not
# written. Arguments: a scratch dir,
# markloop-sim, markloop-eval, then the command that runs markloop.
set -euo pipefail
work=$1 sim=$2 eval_tool=$3; shift 3
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"

"$sim" drive --scenario loop --seed 3 --max-frames 300 --out "$work" >/dev/null
"${ecu[@]}" --camera-file "$work/frames.y4m" --can-in "$work/odometry.log" \
  --calibration "$work/camera.yaml" --can-out "$work/ecu-can.log" \
  --detections-out "$work/ecu-detections.csv" --landmarks-out "$work/ecu-landmarks.csv" \
  --summary "$work/ecu-summary.json" --set realtime.mlockall=false --map "$work/first.map" 2>"$work/ecu.log"
"$eval_tool" "$work" --json "$work/eval.json" >"$work/eval.txt"
# The same drive again, the first run's map loaded: the file holds this
# run's landmarks only, not the map's (their frames are another run's).
"${ecu[@]}" --camera-file "$work/frames.y4m" --can-in "$work/odometry.log" \
  --calibration "$work/camera.yaml" --can-out "$work/again-can.log" --map "$work/first.map" \
  --set map.save_on_exit=false --landmarks-out "$work/again-landmarks.csv" \
  --summary "$work/again-summary.json" --set realtime.mlockall=false 2>"$work/again.log"

python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
summary = json.load(open(f"{work}/ecu-summary.json"))
rows = open(f"{work}/ecu-landmarks.csv").read().splitlines()
landmarks = json.load(open(f"{work}/eval.json"))["landmarks"]
passes = json.load(open(f"{work}/eval.json"))["passes"]
checks = [
    ("the header", rows[0] == "label,observations,first_frame,last_frame,x,y,car_x,car_y,car_yaw,has_car_pose,facing", rows[0]),
    ("a few landmarks", summary["landmarks"] >= 5, summary["landmarks"]),
    ("one row per landmark of the database", len(rows) - 1 == summary["landmarks"], len(rows) - 1),
    ("all judged by markloop-eval", landmarks["count"] == summary["landmarks"] and landmarks["without_pose"] == 0,
     landmarks),
    ("at least 90 % on a marking of their label", landmarks["right_label"] >= 0.9 * landmarks["count"],
     landmarks["right_label"]),
    ("within 0.5 m of it at the median", landmarks["distance_m"]["median"] <= 0.5, landmarks["distance_m"]),
    ("passes judged", passes["count"] >= 5, passes["count"]),
    ("with a map loaded, the database holds both runs' landmarks",
     json.load(open(f"{work}/again-summary.json"))["landmarks"] == 2 * summary["landmarks"],
     json.load(open(f"{work}/again-summary.json"))["landmarks"]),
    ("and the file this run's alone", open(f"{work}/again-landmarks.csv").read() == "\n".join(rows) + "\n",
     len(open(f"{work}/again-landmarks.csv").read().splitlines()) - 1),
]
failed = 0
for name, ok, got in checks:
    print(("ok   " if ok else "FAIL ") + f"{name}: {got}")
    failed += not ok
sys.exit(1 if failed else 0)
PY
