#!/usr/bin/env bash
# markloop-eval from the outside: help, exit status and FILE:LINE messages on
# bad input, and the table, picture and JSON of the synthetic run.
set -euo pipefail
eval_tool=$1 fixture=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"
fresh() { rm -rf "$work/$1" && "$fixture" "$work/$1" && echo "$work/$1"; }

check "--help" 0 "usage: markloop-eval DIR" -- "$eval_tool" --help
check "no DIR" 2 "^markloop-eval: DIR is required" -- "$eval_tool"
check "unknown option" 2 "unknown option --frobnicate" -- "$eval_tool" "$work" --frobnicate
check "bad tolerance" 2 "--tolerance: not a number" -- "$eval_tool" "$work" --tolerance five
# Options before --help are checked as given; two DIRs or a lone "-" are refused.
check "bad value before --help" 2 "--tolerance: not a number" -- "$eval_tool" --tolerance five --help
check "two DIRs" 2 "^markloop-eval: more than one DIR given: 'a' and 'b'$" -- "$eval_tool" a b
check "a lone -" 2 "^markloop-eval: unknown option - \(see --help\)$" -- "$eval_tool" -
check "missing value" 2 "^markloop-eval: --can needs a value, got the option --json" -- "$eval_tool" "$work" --can --json x
check "no frames.csv" 2 "$work/frames.csv: cannot open: No such file or directory" -- "$eval_tool" "$work"

run=$(fresh run)
check "synthetic run" 0 "precision +50.0 %" -- "$eval_tool" "$run" --json "$run/figures.json"
cp "$work/out" "$work/run.txt"
for pattern in "correct / wrong +1 / 1" "revisited 100 m stretches detected +1 of 5" \
    "relative pose error, mean +0.400 m, 1.50 deg" "CAN stamp - QueryTime +1605.0 / 1704.0 / 1704.0 ms" \
    "CAN stamp - time of QueryFrame +1605.0 / 1704.0 / 1704.0 ms" "CAN stamp - last frame before it +5.0 / 6.0 / 6.0 ms" \
    "LoopDetection +16 accepted, 2 rejected \(CRC 1, alive counter 1" "2 complete, 1 incomplete" \
    "detection recall \(any label\) +75.0 %" "detection precision \(any label\) +60.0 %" \
    "classification accuracy +66.7 %" "longest loop time \(any cycle\) +12.50 ms" \
    "^Landmarks \(the ECU's" "on a marking of their label +50.0 % \(1\)" "on no marking +1" \
    "on no marking: landmark 2 \(ped\), frames 15\.\.19, at \(20\.0, 20\.0\) m; nearest marking 0 \(stop\), 34\.48 m" \
    "^Markings driven past" "passes +0 \(and 0 at the drive's start or end" \
    "^Revisit events \(frames within 6 m of a frame at least 30 s older" \
    "same direction +0 / 0 \(-\) +1 / 1 \(100.0 %\)" "closed at, median / p90 \(50 m or more\) +176.0 / 176.0 m" \
    "event at frame 394 \(to 799\): 405.0 m, same direction, closed at 176.0 m \(query frame 553\)"; do
  grep -qE -- "$pattern" "$work/run.txt" || { echo "FAIL table lacks '$pattern'"; failures=$((failures + 1)); }
done
for f in loops.svg loops.png figures.json; do
  [ -s "$run/$f" ] || { echo "FAIL $f not written"; failures=$((failures + 1)); }
done
grep -q '"correct":1,"wrong":1' "$run/figures.json" || { echo "FAIL json lacks the loop counts"; failures=$((failures + 1)); }
grep -q '"landmarks":{"count":2,"without_pose":0,"right_label":1,"wrong_label":0,"on_nothing":1' "$run/figures.json" ||
  { echo "FAIL json lacks the landmarks"; failures=$((failures + 1)); }
grep -q '"misplaced":\[{"landmark":2,"label":"ped","frames":\[15,19\],"at":\[20.000,20.000\],"judged":"on no marking","nearest":{"id":0,"class":"stop","distance_m":34.482}}\]' "$run/figures.json" ||
  { echo "FAIL json lacks the misplaced landmark"; failures=$((failures + 1)); }
grep -q '"revisits":{"radius_m":6,"min_age_s":30,"max_gap_s":3,"longer_m":50,"events":\[{"first_frame":394,"last_frame":799,"start_m":394.000,"length_m":405.000,"kind":"same","closed_at_m":176.000,"closing_query_frame":553,"shared_markings":0,"second_shared_m":null,"third_shared_m":null,"landmarked_markings":0,"second_landmarked_m":null,"third_landmarked_m":null}\]' "$run/figures.json" ||
  { echo "FAIL json lacks the revisit events"; failures=$((failures + 1)); }
grep -q '"passes":{"count":0,"cut_by_drive_ends":0,"named_right":0' "$run/figures.json" ||
  { echo "FAIL json lacks the passes"; failures=$((failures + 1)); }
if command -v python3 >/dev/null; then
  python3 -c 'import json,sys; json.load(open(sys.argv[1]))' "$run/figures.json" ||
    { echo "FAIL figures.json is not JSON"; failures=$((failures + 1)); }
fi

# --summary: the same drive twice, summed.
check "--summary" 0 "^markloop-eval --summary: 2 drives, 1.60 km driven" -- \
  "$eval_tool" --summary "$run/figures.json" "$run/figures.json" --json "$work/summary.json"
for pattern in "same direction +0 / 0 \(-\) +2 / 2 \(100.0 %\)" "closed at, median / p90 \(50 m or more\) +176.0 / 176.0 m \(2 closed\)" \
    "wrong LoopDetections +2" "relative pose error, mean +0.400 m \(2 correct" "wrong loops: $run/figures.json \(1\)"; do
  grep -qE -- "$pattern" "$work/out" || { echo "FAIL summary lacks '$pattern'"; failures=$((failures + 1)); }
done
grep -q '"drives":2,' "$work/summary.json" || { echo "FAIL summary json"; failures=$((failures + 1)); }
check "--summary without files" 2 "^markloop-eval: --summary needs eval.json files" -- "$eval_tool" --summary
check "--summary with --can" 2 "^markloop-eval: --can does not apply with --summary" -- "$eval_tool" --summary x --can y
check "--summary of a frames.csv" 2 "frames.csv: byte 1: " -- "$eval_tool" --summary "$run/frames.csv"

check "tolerance 2 m" 0 "correct / wrong +0 / 2" -- "$eval_tool" "$run" --tolerance 2 --svg "$work/t.svg" --png "$work/t.png"

run=$(fresh nodet) && rm "$run/ecu-detections.csv"
check "no detections file: note" 0 "ecu-detections.csv not found: marking detection not evaluated" -- "$eval_tool" "$run"
grep -qE "on no marking +1" "$work/out" || { echo "FAIL landmarks not judged without the detections"; failures=$((failures + 1)); }
grep -q "^Markings driven past: need the detections and the landmarks" "$work/out" ||
  { echo "FAIL no note on the markings driven past"; failures=$((failures + 1)); }
check "--detections missing" 2 "absent.csv: cannot open: No such file" -- "$eval_tool" "$run" --detections "$run/absent.csv"
run=$(fresh nolandmarks) && rm "$run/ecu-landmarks.csv"
check "no landmarks file: note" 0 "ecu-landmarks.csv not found: landmarks not evaluated" -- "$eval_tool" "$run"
check "--landmarks missing" 2 "absent.csv: cannot open: No such file" -- "$eval_tool" "$run" --landmarks "$run/absent.csv"
run=$(fresh badlandmark) && sed -i '3s/,15,19,/,25,19,/' "$run/ecu-landmarks.csv"
check "landmark frames reversed" 2 "^markloop-eval: $run/ecu-landmarks.csv:3: first_frame 25 is after last_frame 19" -- "$eval_tool" "$run"
run=$(fresh farlandmark) && sed -i '2s/,30,48,/,30,900,/' "$run/ecu-landmarks.csv"
check "landmark beyond the truth" 2 "^markloop-eval: $run/ecu-landmarks.csv:2: last_frame 900 is beyond the truth's 800 frames" -- "$eval_tool" "$run"

run=$(fresh badcan) && printf '(0000000080.000000) vcan0 2A0#00\n(0000000080.100000) vcan0 2A0#XY\n' >>"$run/ecu-can.log"
check "bad candump line" 2 "^markloop-eval: $run/ecu-can.log:36:" -- "$eval_tool" "$run"
# A CAN log that cannot be lined up with the drive is refused at its line; one
# that can, but holds frames the ECU does not send, is judged with a warning.
run=$(fresh wallclock) && sed -i 's/^(0000000/(1733130/' "$run/ecu-can.log"
check "CAN log on the wall clock" 2 "^markloop-eval: $run/ecu-can.log:1: stamp 1733130000.100000 s lies outside the drive \(0.000 to 79.900 s" -- \
  "$eval_tool" "$run"
run=$(fresh future) && sed -i '10s/^([0-9.]*)/(4102444800.000000)/' "$run/ecu-can.log"
check "CAN frame far in the future" 2 "^markloop-eval: $run/ecu-can.log:10: stamp 4102444800.000000 s lies outside the drive" -- \
  "$eval_tool" "$run"
run=$(fresh backwards) && sed -i '10s/^([0-9.]*)/(0000000001.000000)/' "$run/ecu-can.log"
check "CAN stamps going back" 2 "^markloop-eval: $run/ecu-can.log:10: stamp 1.000000 s is before the line above's 57.004002 s" -- \
  "$eval_tool" "$run"
run=$(fresh cut) && truncate -s -7 "$run/ecu-can.log"
check "CAN log cut in its last line" 2 "^markloop-eval: $run/ecu-can.log:34: the last line is cut short: no newline at its end, and its frame has 5 bytes where the ECU sends 8" -- \
  "$eval_tool" "$run"
run=$(fresh nonewline) && truncate -s -1 "$run/ecu-can.log"
check "CAN log without a final newline" 0 "precision +50.0 %" -- "$eval_tool" "$run"
run=$(fresh dlc) && sed -i -E '20,25s/(2A0#[0-9A-F]{10})[0-9A-F]*/\1/' "$run/ecu-can.log"
check "CAN frames of the wrong length" 0 "^markloop-eval: warning: $run/ecu-can.log:20: 6 of 33 LoopDetection and Status frames have the wrong length \(this one 5 bytes, the DBC's 8\)" -- \
  "$eval_tool" "$run"
grep -qE "LoopDetection +[0-9]+ accepted, [0-9]+ rejected \(.*length 6" "$work/out" ||
  { echo "FAIL the wrong lengths are not counted in the table"; failures=$((failures + 1)); }
run=$(fresh odometry) && sed -i 's/ 2[AB]0#/ 120#/' "$run/ecu-can.log"
check "not the ECU's CAN log" 0 "^markloop-eval: warning: $run/ecu-can.log: no LoopDetection or Status frame: is this the ECU's log\?" -- \
  "$eval_tool" "$run"
run=$(fresh quiet)
check "the ECU's CAN log: no warning" 0 "precision +50.0 %" -- "$eval_tool" "$run"
! grep -q "warning" "$work/out" || { echo "FAIL a warning on the ECU's own log"; failures=$((failures + 1)); }
run=$(fresh badvisible) && printf '12,9,stop,1,2,3,4,5,6,7\n' >>"$run/visible.csv"
check "short visible line" 2 "^markloop-eval: $run/visible.csv:6: expected 11 comma-separated fields" -- "$eval_tool" "$run"
run=$(fresh badframes) && sed -i '5s/.*/3,0.3,abc,0,0/' "$run/frames.csv"
check "bad frames.csv" 2 "^markloop-eval: $run/frames.csv:5: expected frame,t,x,y,yaw numbers" -- "$eval_tool" "$run"
run=$(fresh baddet) && sed -i '3s/leftturn/left-turn/' "$run/ecu-detections.csv"
check "unknown label" 2 "^markloop-eval: $run/ecu-detections.csv:3: label 'left-turn' is not a marking class" -- "$eval_tool" "$run"
run=$(fresh badpng)
check "unwritable picture" 1 "^markloop-eval: $work/nowhere/x.png: cannot write: No such file or directory" -- \
  "$eval_tool" "$run" --png "$work/nowhere/x.png"

# Inputs that are directories or endless are refused by name (status 2);
# outputs that cannot be written fail the run (status 1), naming them.
run=$(fresh limits)
check "directory as --can" 2 "^markloop-eval: $run: is a directory, not a CAN log" -- "$eval_tool" "$run" --can "$run"
check "directory as --detections" 2 "^markloop-eval: $run: is a directory, not a CSV file" -- \
  "$eval_tool" "$run" --detections "$run"
check "endless --landmarks" 2 "^markloop-eval: /dev/zero: larger than 256 MiB, the limit for a CSV file" -- \
  "$eval_tool" "$run" --landmarks /dev/zero
mv "$run/frames.csv" "$run/frames.tmp" && mkdir "$run/frames.csv"
check "directory as frames.csv" 2 "frames.csv: is a directory, not a frames.csv file" -- "$eval_tool" "$run"
rmdir "$run/frames.csv" && mv "$run/frames.tmp" "$run/frames.csv"
check "full disk (--json)" 1 "^markloop-eval: /dev/full: cannot write: No space left on device" -- \
  "$eval_tool" "$run" --json /dev/full
check "full disk (--png)" 1 "^markloop-eval: /dev/full: cannot write: No space left on device" -- \
  "$eval_tool" "$run" --png /dev/full
check "directory as --svg" 1 "^markloop-eval: $run: cannot write: Is a directory" -- "$eval_tool" "$run" --svg "$run"
cp "$run/frames.csv" "$work/frames.keep"
check "output is frames.csv" 2 "^markloop-eval: $run/frames.csv: is the input $run/frames.csv: an output may not overwrite it" -- \
  "$eval_tool" "$run" --json "$run/frames.csv"
cmp -s "$run/frames.csv" "$work/frames.keep" || { echo "FAIL frames.csv was overwritten"; failures=$((failures + 1)); }
printf '0 0 0 0 0 0 0 1\n' >"$run/after.tum"
cp "$run/after.tum" "$work/after.keep"
check "output is the corrected trajectory" 2 "^markloop-eval: $run/after.tum: is the input $run/after.tum: an output may not overwrite it" -- \
  "$eval_tool" "$run" --corrected "$run/after.tum" --svg "$run/after.tum"
cmp -s "$run/after.tum" "$work/after.keep" || { echo "FAIL the corrected trajectory was overwritten"; failures=$((failures + 1)); }
check "tolerance out of range" 2 "--tolerance must be in \(0, 10000\] metres" -- "$eval_tool" "$run" --tolerance 1e308
run=$(fresh hugeyaw) && sed -i '3s/,[^,]*$/,1e308/' "$run/frames.csv"
check "yaw out of range" 2 "^markloop-eval: $run/frames.csv:3: yaw is out of range" -- "$eval_tool" "$run"
run=$(fresh hugeheading) && sed -i '3s/,[^,]*$/,1e308/' "$run/markings.csv"
check "heading out of range" 2 "^markloop-eval: $run/markings.csv:3: heading 1e308 is out of range" -- "$eval_tool" "$run"
run=$(fresh hugecorner) && sed -i '3s/,[^,]*$/,1e308/' "$run/visible.csv"
check "corner out of range" 2 "^markloop-eval: $run/visible.csv:3: y4 1e308 is out of range" -- "$eval_tool" "$run"
run=$(fresh limits2)
check "full disk (standard output)" 1 "standard output: cannot write: No space left on device" -- \
  bash -c '"$1" "$2" >/dev/full' - "$eval_tool" "$run"

finish
