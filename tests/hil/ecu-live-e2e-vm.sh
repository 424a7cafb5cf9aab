#!/usr/bin/env bash
# Inside the HIL VM (see ecu-live-e2e.sh): vivid loop-back + vcan0, markloop
# live, the drive played live, candump as the witness.
#   ecu-live-e2e-vm.sh BUILD_DIR DRIVE_DIR CAMERA_YAML
set -euo pipefail
bin=$1
drive=$2
camera=$3
out=${HIL_RESULTS:?run me through run-in-vm.sh}
scratch=${TMPDIR:-/tmp}
say() { echo "ecu-live-e2e: $*" | tee -a "$out/summary.txt"; }

node_named() {  # the /dev node of the vivid device whose name ends in $1
  local d
  for d in /sys/class/video4linux/video*; do
    case "$(cat "$d/name")" in *"$1") echo "/dev/$(basename "$d")"; return 0 ;; esac
  done
  return 1
}
capture=$(node_named vid-cap) || { say "no vivid capture node"; exit 1; }
output=$(node_named vid-out) || { say "no vivid output node"; exit 1; }
say "vivid capture $capture, output $output"
# HDMI in and out at the first DV timings (640x480p60), output looped back.
v4l2-ctl -d "$capture" --set-input 3 >/dev/null
v4l2-ctl -d "$capture" --set-dv-bt-timings index=0 >/dev/null
v4l2-ctl -d "$output" --set-output 1 >/dev/null
v4l2-ctl -d "$output" --set-dv-bt-timings index=0 >/dev/null
v4l2-ctl -d "$capture" --set-ctrl loop_video=1 >/dev/null
ip link show vcan0 >/dev/null

# Under TCG the VM's clock runs but its CPU is emulated: the player's odometry
# frames arrive up to a few hundred ms late, which the car's 60 ms timeout
# would take for lost odometry; the HIL run allows 500 ms. vivid loops at
# 60 Hz what the player writes at 10 fps: markloop takes 10 frames a second,
# at normal priority, so that it does not starve the player of the VM's CPUs.
candump -L vcan0 >"$out/candump.log" 2>"$out/candump.err" &
candump_pid=$!
"$bin/bin/markloop" --camera-device "$capture" --set camera.input=3 --set camera.fps=0 \
  --can-interface vcan0 --calibration "$camera" --map "$scratch/map.bin" \
  --can-out "$out/ecu-can.log" --summary "$out/ecu-summary.json" \
  --set realtime.priority=0 --set camera.max_rate=10 --set odometry.timeout_ms=500 \
  >"$out/markloop.out" 2>"$out/markloop.err" &
ecu_pid=$!
sleep 3
kill -0 "$ecu_pid" || { say "markloop exited early"; cat "$out/markloop.err"; exit 1; }

start=$(date +%s)
sim_status=0
"$bin/bin/markloop-sim" live --from "$drive" --video "$output" --output 1 --can vcan0 \
  >"$out/sim-live.out" 2>"$out/sim-live.err" || sim_status=$?
say "drive played in $(($(date +%s) - start)) s (exit status $sim_status): $(tail -1 "$out/sim-live.out")"
sleep 2
kill -TERM "$ecu_pid"
ecu_status=0
wait "$ecu_pid" || ecu_status=$?
kill -TERM "$candump_pid" 2>/dev/null || true
wait "$candump_pid" 2>/dev/null || true
cat "$out/markloop.err" >>"$out/summary.txt"
say "markloop exit status $ecu_status after SIGTERM"
[ "$ecu_status" = 0 ] || exit 1
[ -s "$scratch/map.bin" ] || { say "map not saved"; exit 1; }
say "map saved: $(stat -c %s "$scratch/map.bin") bytes"
# The witness: complete, E2E-valid detections and Status on the bus.
"$bin/bin/markloop-hil-can-check" "$out/candump.log" --min-detections 1 --min-status 30 \
  | tee -a "$out/summary.txt"
