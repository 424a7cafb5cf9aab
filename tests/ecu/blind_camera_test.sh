#!/usr/bin/env bash
# A covered lens, end to end: the simulator covers the camera for 4 s of a
# drive (frames 50..89), the ECU runs the drive in file mode, and what it
# sent on CAN must say so: FaultCameraBlind from the 10th covered frame
# (camera.blind_frames) until the 10th frame showing road again, and
# FramesBlind 40. Arguments: a scratch dir, markloop-sim, markloop-eval,
# then the command that runs markloop.
set -euo pipefail
work=$1 sim=$2 eval_tool=$3; shift 3
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"

"$sim" drive --scenario loop --seed 3 --max-frames 150 --cover-lens 5:9 --out "$work" >/dev/null
"${ecu[@]}" --camera-file "$work/frames.y4m" --can-in "$work/odometry.log" \
  --calibration "$work/camera.yaml" --can-out "$work/ecu-can.log" \
  --detections-out "$work/ecu-detections.csv" --summary "$work/ecu-summary.json" \
  --set realtime.mlockall=false --set map.file= 2>"$work/ecu.log"
"$eval_tool" "$work" --json "$work/eval.json" >"$work/eval.txt"

python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
summary = json.load(open(f"{work}/ecu-summary.json"))
status = json.load(open(f"{work}/eval.json"))["status"]
blind_cycles = status["fault_frames"]["camera_blind"]
checks = [
    ("the ECU counted the covered frames", summary["frames_blind"] == 40, summary["frames_blind"]),
    ("Status FramesBlind", status["frames_blind"] == 40, status["frames_blind"]),
    # Blind from frame 59 to frame 98 (40 frames, 4 s): a Status cycle every 100 ms.
    ("Status cycles with FaultCameraBlind", 38 <= blind_cycles <= 42, blind_cycles),
    ("no camera-lost fault", status["fault_frames"]["camera_lost"] == 0, status["fault_frames"]["camera_lost"]),
]
failed = 0
for name, ok, got in checks:
    print(("ok   " if ok else "FAIL ") + f"{name}: {got}")
    failed += not ok
sys.exit(1 if failed else 0)
PY
