#!/usr/bin/env bash
# SIGTERM ends a file-mode run blocked on a stalled pipe at once, with the
# map saved. A wall-clock limit: labelled timing, so that CI runs it with
# nothing beside it. Arguments: a scratch dir, then the command that runs
# markloop (a cross build puts its emulator in front).
set -euo pipefail
work=$1; shift
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"
source "$(dirname "$0")/recording.sh"
cd "$work"
make_video frames.y4m 6
make_log can.log 11

# limit_ms: 100 natively; an emulator (cross builds) or a sanitizer's exit
# checks (MARKLOOP_STOP_LIMIT_MS, set by the build) add their own time.
limit_ms=${MARKLOOP_STOP_LIMIT_MS:-100}
[ ${#ecu[@]} -gt 1 ] && limit_ms=1000
stalled() {  # stalled NAME INPUT_OPTION...: the pipe holds a little, then nothing
  local name=$1; shift
  rm -f stalled.map
  "${ecu[@]}" --quiet --map stalled.map "$@" &
  local pid=$!
  sleep 2
  local start end status=0
  start=$(date +%s%N)
  kill -TERM "$pid"
  wait "$pid" || status=$?
  end=$(date +%s%N)
  local ms=$(((end - start) / 1000000))
  if [ "$status" != 0 ] || [ "$ms" -gt "$limit_ms" ] || [ ! -s stalled.map ]; then
    echo "FAIL $name: status $status after $ms ms (limit $limit_ms), map $(stat -c %s stalled.map 2>/dev/null || echo missing)"
    failures=$((failures + 1))
  else
    echo "ok   $name: stopped $ms ms after SIGTERM, map saved"
  fi
}
mkfifo camera.fifo can.fifo
(head -c $((41 + 3 * (frame_bytes + 6))) frames.y4m; exec sleep 30) >camera.fifo &
writer=$!
stalled "SIGTERM while the camera pipe stalls" --camera-file camera.fifo --can-in can.log
kill "$writer" 2>/dev/null || true
(head -5 can.log; exec sleep 30) >can.fifo &
writer=$!
stalled "SIGTERM while the CAN pipe stalls" --camera-file frames.y4m --can-in can.fifo
kill "$writer" 2>/dev/null || true

finish
