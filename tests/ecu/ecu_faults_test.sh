#!/usr/bin/env bash
# The ECU against damaged, hostile and careless inputs in file mode: every
# rejection names the file (and line), the map is never lost or damaged,
# and failed writes are not reported as success (ecu_stop_test.sh: SIGTERM
# on a stalled pipe). Arguments: a scratch dir, then the command that runs
# markloop (a cross build puts its emulator in front).
set -euo pipefail
work=$1; shift
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"
source "$(dirname "$0")/recording.sh"
cd "$work"

make_video frames.y4m 6
make_log can.log 11  # 0 to 0.5 s, as the frames
run=("${ecu[@]}" --camera-file frames.y4m --can-in can.log --quiet)
sha() { sha256sum "$1" | cut -d' ' -f1; }

check "clean run saves a map" 0 "map saved to map.bin" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in can.log --map map.bin
[ -s map.bin ] || { echo "FAIL no map after a clean run"; failures=$((failures + 1)); }

# --- inputs: bounded, named, never accepted silently -------------------------
check "config from /dev/zero" 2 "^markloop: /dev/zero: larger than 1 MiB, the limit for a configuration file" -- \
  "${ecu[@]}" --config /dev/zero
check "config is a directory" 2 "^markloop: $work: is a directory, not a configuration file" -- "${ecu[@]}" --config "$work"
check "camera file is a directory" 2 "^markloop: $work: is a directory" -- \
  "${ecu[@]}" --camera-file "$work" --can-in can.log
check "CAN log is a directory" 2 "^markloop: $work: is a directory" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in "$work"
check "database beyond memory" 2 "database.landmark_capacity = 1073741824 .* more than the .* MiB of memory available" -- \
  "${run[@]}" --set database.landmark_capacity=1073741824
make_video slow.y4m 1 "YUV4MPEG2 W1280 H512 F1:99999999 Ip A1:1 Cmono"
check "absurd frame rate" 2 "^markloop: slow.y4m: frame rate 1:99999999 .* is outside 0.1 to 1000" -- \
  "${ecu[@]}" --camera-file slow.y4m --can-in can.log --can-out out.log
check "first frame beyond the end" 2 "frames.y4m: --first-frame \(file.first_frame\) is 50, but the file ends after 6 frames" -- \
  "${run[@]}" --first-frame 50
sed 's/^(0000000000/(1700000000/' can.log >epoch.log
check "epoch-stamped log" 2 "^markloop: epoch.log:1: timestamp 1700000000.000000 s is a wall-clock \(epoch\) time" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in epoch.log
{ head -3 can.log; echo "(0000099999.000000) vcan0 7FF#00"; tail -n +4 can.log; } >future.log
check "a frame stamped far ahead" 2 "^markloop: future.log:5: timestamp .* is earlier than the line before's \(99999.000000 s\)" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in future.log
{ cat can.log; echo "(0000000003.000000) vcan0 7FF#00"; } >late.log
check "log frames after the last camera frame are counted" 0 "1 log frames after the last camera frame" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in late.log
{ echo "YUV4MPEG2 W1280 H512 F10:1 Ip A1:1 C420jpeg"
  for i in 1 2 3; do echo FRAME; head -c $((frame_bytes * 3 / 2)) /dev/zero; done; } >c420.y4m
check "4:2:0 through a pipe" 0 "3 frames processed" -- \
  bash -c 'cat c420.y4m | "$@" --camera-file /dev/stdin --can-in can.log' _ "${ecu[@]}"

# --- the map: never lost, never damaged --------------------------------------
check "map is a directory" 2 "map refused: $work: is a directory, not a map file" -- "${run[@]}" --map "$work"
mkfifo map.fifo
check "map is a FIFO (no hang)" 2 "map refused: map.fifo: is a FIFO" -- timeout 10 "${run[@]}" --map map.fifo
ln -s /dev/null device.map
check "map is a device node" 2 "map refused: device.map: is a character device" -- "${run[@]}" --map device.map
[ -c /dev/null ] || { echo "FAIL /dev/null is no longer a device"; failures=$((failures + 1)); }
if [ "$(id -u)" = 0 ]; then
  mknod null.map c 1 3
  check "map is a device node (mknod)" 2 "map refused: null.map: is a character device" -- "${run[@]}" --map null.map
  [ -c null.map ] || { echo "FAIL null.map was replaced"; failures=$((failures + 1)); }
fi
ln -s map.bin link.map
check "map behind a symbolic link" 0 "map saved to link.map" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in can.log --map link.map
[ -L link.map ] || { echo "FAIL the link was replaced by a file"; failures=$((failures + 1)); }

# A map or an output named like an input would destroy it.
cp can.log kept.log
kept_sha=$(sha kept.log)
check "map is the CAN log" 2 "^markloop: --map kept.log is the file given as --can-in" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in kept.log --map kept.log
ln -s kept.log kept-link.log
check "output is an input under another name" 2 "^markloop: --can-out kept-link.log is the file given as --can-in" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in kept.log --can-out kept-link.log
printf 'engine.k = 4\n' >kept.conf
check "summary is the configuration" 2 "^markloop: --summary kept.conf is the file given as --config" -- \
  "${run[@]}" --config kept.conf --summary kept.conf
[ "$(sha kept.log)" = "$kept_sha" ] && grep -q "engine.k" kept.conf || { echo "FAIL an input was changed"; failures=$((failures + 1)); }
check "forgotten value" 2 "^markloop: --map needs a value, got the option --quiet" -- "${run[@]}" --map --quiet
mkfifo calibration.fifo
check "calibration through a FIFO" 2 "^markloop: calibration.fifo: is a pipe or socket, not a calibration file" -- \
  timeout 10 "${run[@]}" --calibration calibration.fifo

# Unreadable: run as an unprivileged user where we are root (root reads anything).
as_user=()
[ "$(id -u)" = 0 ] && command -v setpriv >/dev/null && as_user=(setpriv --reuid=nobody --regid=nogroup --clear-groups)
mkdir -p locked && cp map.bin locked/map.bin && chmod 000 locked/map.bin && chmod 777 locked
if [ "$(id -u)" != 0 ] || [ ${#as_user[@]} -gt 0 ]; then
  chmod o+rx "$work" .
  check "unreadable map" 2 "map refused: locked/map.bin: cannot open: Permission denied; the map is left as it is" -- \
    "${as_user[@]}" "${run[@]}" --map locked/map.bin
  [ "$(sha map.bin)" = "$(chmod 644 locked/map.bin && sha locked/map.bin)" ] ||
    { echo "FAIL the unreadable map was changed"; failures=$((failures + 1)); }
else
  echo "FAIL unreadable map: running as root without setpriv"; failures=$((failures + 1))
fi

# Two ECUs on one map: the second is refused while the first runs.
make_video long.y4m 3 "YUV4MPEG2 W1280 H512 F1:1 Ip A1:1 Cmono"  # 3 s with --realtime
"${ecu[@]}" --camera-file long.y4m --can-in can.log --quiet --realtime --map shared.map &
first=$!
sleep 1
check "second ECU on one map" 2 "map refused: shared.map: in use by another markloop" -- "${run[@]}" --map shared.map
kill -TERM "$first"; wait "$first" || { echo "FAIL the first ECU did not stop cleanly"; failures=$((failures + 1)); }

# A late input error keeps what was learnt, and still exits 2.
head -c $(($(stat -c %s frames.y4m) - 1000)) frames.y4m >truncated.y4m
rm -f late.map
check "truncated last frame" 2 "^markloop: truncated.y4m: frame 5: truncated \(luma plane incomplete\)" -- \
  "${ecu[@]}" --camera-file truncated.y4m --can-in can.log --map late.map
[ -s late.map ] || { echo "FAIL truncated last frame: no map saved"; failures=$((failures + 1)); }
{ cat can.log; echo "garbage"; } >bad.log
rm -f late.map
check "malformed last CAN line" 2 "^markloop: bad.log:12:1: expected '\(' starting the timestamp" -- \
  "${ecu[@]}" --camera-file frames.y4m --can-in bad.log --map late.map
[ -s late.map ] || { echo "FAIL malformed last line: no map saved"; failures=$((failures + 1)); }

# --- failed writes are failures --------------------------------------------------
check "summary to /dev/full" 1 "^markloop: /dev/full: cannot write the summary: No space left on device" -- \
  "${run[@]}" --summary /dev/full
check "summary to a directory" 1 "^markloop: $work: cannot write the summary: Is a directory" -- \
  "${run[@]}" --summary "$work"
check "CAN output to /dev/full" 1 "^markloop: /dev/full: No space left on device" -- "${run[@]}" --can-out /dev/full

finish
