# Shared by the ECU's file-mode tests (sourced, not run): a recording
# markloop accepts, blank 1280x512 frames at 10 fps and a CAN log of frames
# it does not receive (no odometry is needed to exercise the files).
frame_bytes=$((1280 * 512))
make_video() {  # make_video FILE FRAMES [HEADER]
  local header=${3:-"YUV4MPEG2 W1280 H512 F10:1 Ip A1:1 Cmono"} i
  { echo "$header"; for ((i = 0; i < $2; i++)); do echo FRAME; head -c "$frame_bytes" /dev/zero; done; } >"$1"
}
make_log() {  # make_log FILE LINES: one foreign frame every 50 ms
  local i
  for ((i = 0; i < $2; i++)); do printf '(%010d.%06d) vcan0 7FF#00\n' $((i / 20)) $((i % 20 * 50000)); done >"$1"
}
