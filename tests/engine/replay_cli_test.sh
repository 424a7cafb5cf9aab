#!/usr/bin/env bash
# The replay and simulator programs from the outside: help, exit status and
# messages on bad input, and an end-to-end drive judged against its truth.
set -euo pipefail
replay=$1 sim=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

check "replay --help" 0 "usage: markloop-replay" -- "$replay" --help
check "sim --help" 0 "usage: markloop-sim" -- "$sim" --help
check "missing option" 2 "one of --markings FILE and --ecu-detections FILE is required" -- "$replay"
check "unknown option" 2 "unknown option --frobnicate" -- "$replay" --markings x --frobnicate
check "missing file" 2 "^markloop-replay: $work/none.txt: cannot open" -- "$replay" --markings "$work/none.txt"

printf '2\n0 1 1.5 10 A\n' >"$work/short.txt"
check "wrong count" 2 "short.txt:3: the file declares 2 records" -- "$replay" --markings "$work/short.txt"
printf '1\n0 1 x 10 A\n' >"$work/nan.txt"
check "not a number" 2 "nan.txt:2: record 1: y is not a finite number: 'x'" -- "$replay" --markings "$work/nan.txt"
printf '1\n0 1 1.5 10 A\n' >"$work/one.txt"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0\n' >"$work/poses.txt"
check "short pose line" 2 "poses.txt:2: expected 12 numbers" -- "$replay" --markings "$work/one.txt" --poses "$work/poses.txt"
check "bad k" 2 "^markloop-replay: --k: 11 is outside 2 to 10$" -- "$replay" --markings "$work/one.txt" --k 11
# Every numeric option has a range, checked where it is parsed: the message
# names the option and the range (absurd values were accepted, or refused by
# the engine's validate() without naming the option).
for h in "--abs-tol|-1|0.001 to 100 \(metres\)" "--abs-tol|2147483648|0.001 to 100 \(metres\)" \
         "--abs-tol|18446744073709551616|0.001 to 100 \(metres\)" "--rel-tol|2147483648|0 to 0.1" \
         "--rel-tol|18446744073709551616|0 to 0.1" "--association-radius|2147483648|0.01 to 100 \(metres\)" \
         "--commit-after|18446744073709551616|0.01 to 100 \(seconds\)" "--max-residual|2147483648|0.001 to 100 \(metres\)" \
         "--min-separation|18446744073709551616|0 to 10000 \(metres\)" "--min-separation-s|18446744073709551616|0 to 86400 \(seconds\)" \
         "--min-observations|2147483648|1 to 1000" "--k|2147483648|2 to 10" "--skip-rows|2147483648|0 to 1" \
         "--landmark-capacity|2147483648|16 to 1073741824" "--sequence-capacity|2147483648|16 to 1073741824" \
         "--fps|0|0.001 to 1000000 \(Hz\)" "--truth-radius|1e999|0.01 to 10000 \(metres\)"; do
  IFS='|' read -r option value range <<<"$h"
  check "$option $value" 2 "^markloop-replay: $option: $value is outside $range$" -- "$replay" --markings "$work/one.txt" "$option" "$value"
done
check "not a number" 2 "^markloop-replay: --abs-tol: not a number: 'nan'; expected 0.001 to 100 \(metres\)$" -- \
  "$replay" --markings "$work/one.txt" --abs-tol nan
check "not a whole number" 2 "^markloop-replay: --min-observations: not a whole number: '2.5'; expected 1 to 1000$" -- \
  "$replay" --markings "$work/one.txt" --min-observations 2.5
check "ranges in --help" 0 "--abs-tol M +distance tolerance, absolute part, 0.001 to 100 m" -- "$replay" --help
check "range ends accepted" 0 "^matches: 0" -- "$replay" --markings "$work/one.txt" --k 10 --abs-tol 100 --rel-tol 0 \
  --min-separation 10000 --min-separation-s 86400 --max-residual 0.001 --association-radius 0.01 --commit-after 100 \
  --min-observations 1000 --skip-rows 0 --landmark-capacity 16 --sequence-capacity 16
check "bad sweep" 2 "--sweep: expected" -- "$replay" --markings "$work/one.txt" --sweep 5
# Options before --help are checked as given; after it, not read.
check "bad value before --help" 2 "^markloop-replay: --k: 11 is outside 2 to 10$" -- "$replay" --k 11 --help
check "bad value after --help" 0 "usage: markloop-replay" -- "$replay" --help --k 11
check "stray argument" 2 "^markloop-replay: unexpected argument stray \(see --help\)$" -- \
  "$replay" --markings "$work/one.txt" stray

# The ECU's detections: placed with the poses and gated as the ECU gates
# them (score 0.6, 5.5 to 16 m ahead).
header=frame,label,score,x1,y1,x2,y2,x3,y3,x4,y4,ground_x,ground_y
printf '%s\n0,forward,0.9,1,2,3,4,5,6,7,8,10,0\n1,forward,0.3,1,2,3,4,5,6,7,8,9,0\n1,stopline,0.9,1,2,3,4,5,6,7,8,20,0\n' \
  "$header" >"$work/ecu.csv"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1\n' >"$work/two-poses.txt"
check "ECU detections gated" 0 "ecu.csv: 3 detections, 2 of them refused by the ECU's observation gate" -- \
  "$replay" --ecu-detections "$work/ecu.csv" --poses "$work/two-poses.txt"
check "ECU detections need poses" 2 "^markloop-replay: --ecu-detections needs --poses" -- \
  "$replay" --ecu-detections "$work/ecu.csv"
check "markings and ECU detections" 2 "one of --markings FILE and --ecu-detections FILE is required" -- \
  "$replay" --ecu-detections "$work/ecu.csv" --markings "$work/one.txt" --poses "$work/two-poses.txt"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n' >"$work/poses1.txt"
check "ECU detection without a pose" 2 "ecu.csv: frame 1 has no pose \(the poses hold 1 frames\)" -- \
  "$replay" --ecu-detections "$work/ecu.csv" --poses "$work/poses1.txt"
printf '%s\n0,forward,0.9,1,2,3,4,5,6,7,8,nan,0\n' "$header" >"$work/ecu-nan.csv"
check "ECU detection not a number" 2 "ecu-nan.csv:2: ground_x is not a finite number" -- \
  "$replay" --ecu-detections "$work/ecu-nan.csv" --poses "$work/two-poses.txt"

# Inputs: a directory, an endless device and poses that stop short are
# refused by name; a record at the largest frame takes no longer than others.
check "directory as markings" 2 "^markloop-replay: $work: is a directory, not a markings file" -- "$replay" --markings "$work"
check "directory as truth" 2 "$work: is a directory, not a ground truth file" -- "$replay" --markings "$work/one.txt" --truth "$work"
check "endless markings" 2 "/dev/zero: larger than 256 MiB, the limit for a markings file" -- "$replay" --markings /dev/zero
printf '2\n0 1 1.5 10 A\n2147483647 1 1.5 10 A\n' >"$work/far.txt"
check "largest frame number" 0 "2 detections in 2147483648 frames" -- timeout 10 "$replay" --markings "$work/far.txt"
: >"$work/no-poses.txt"
check "empty poses" 2 "no-poses.txt: has 0 poses, the markings reach frame 2147483647" -- \
  "$replay" --markings "$work/far.txt" --poses "$work/no-poses.txt"
printf '2\n0 1 1.5 10 A\n2 1 1.5 10 A\n' >"$work/three-frames.txt"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n' >"$work/one-pose.txt"
check "poses short of the markings" 2 "one-pose.txt: has 1 pose, the markings reach frame 2" -- \
  "$replay" --markings "$work/three-frames.txt" --poses "$work/one-pose.txt"
check "database beyond memory" 2 "^markloop-replay: --landmark-capacity = 1073741824 and --sequence-capacity = 1073741824 .* more than .* of memory available" -- \
  "$replay" --markings "$work/one.txt" --landmark-capacity 1073741824 --sequence-capacity 1073741824
check "directory as output" 1 "^markloop-replay: $work: cannot write: Is a directory" -- "$replay" --markings "$work/one.txt" --out "$work"
cp "$work/one.txt" "$work/keep.txt"
check "output is the markings" 2 "keep.txt: is the --markings input: an output may not overwrite it" -- \
  "$replay" --markings "$work/keep.txt" --out "$work/keep.txt"
cmp -s "$work/one.txt" "$work/keep.txt" || { echo "FAIL the markings were overwritten"; failures=$((failures + 1)); }
printf 'frame,t,x,y,yaw\n0,0,0,0,0\n' >"$work/truth-one.csv"
check "truth short of the markings" 2 "truth-one.csv: has 1 true pose, the markings reach frame 2 \($work/three-frames.txt:3;" -- \
  "$replay" --markings "$work/three-frames.txt" --truth "$work/truth-one.csv"
printf '1\n0 1 1.5 10 %s\n' "$(head -c 100 /dev/zero | tr '\0' a)" >"$work/long-label.txt"
check "label too long" 2 "long-label.txt:2: record 1: label is longer than 64 characters" -- "$replay" --markings "$work/long-label.txt"
printf '2\n5 1 1.5 10 A\n1 1 1.5 12 A\n' >"$work/backwards.txt"
check "frames out of order" 0 "backwards.txt:3: frame 1 after frame 5: the records are taken in frame order" -- \
  "$replay" --markings "$work/backwards.txt"
check "frame rate out of range" 2 "^markloop-replay: --fps: 2147483648 is outside 0.001 to 1000000 \(Hz\)$" -- \
  "$replay" --markings "$work/one.txt" --fps 2147483648

printf '0\n' >"$work/empty.txt"
check "empty input (engine)" 0 "^matches: 0" -- "$replay" --markings "$work/empty.txt"
check "empty input (compat)" 0 "0 matches" -- "$replay" --markings "$work/empty.txt" --compat --out "$work/empty-matches.txt"
[ ! -s "$work/empty-matches.txt" ] || { echo "FAIL compat wrote matches for empty input"; failures=$((failures + 1)); }

check "simulated drive" 0 "1.2 km city block" -- "$sim" drive --scenario loop --seed 2 --no-render --out "$work/drive"
check "replay of the drive" 0 "precision 100.0%" -- "$replay" --markings "$work/drive/markings.txt" \
  --poses "$work/drive/poses.txt" --truth "$work/drive/frames.csv" \
  --out "$work/matches.txt" --jsonl "$work/matches.jsonl"
# Two laps of the block: lap 2 is one revisit event the same way, closed.
grep -qE "same direction +0 / 0 \(-\) +1 / 1 \(100.0 %\)" "$work/out" &&
  grep -qE "event at frame [0-9]+ \(to [0-9]+\): [0-9.]+ m, same direction, closed at [0-9.]+ m" "$work/out" ||
  { echo "FAIL replay lacks the revisit events"; failures=$((failures + 1)); }
lines=$(wc -l <"$work/matches.txt") records=$(wc -l <"$work/matches.jsonl")
if [ "$records" -lt 10 ] || [ "$lines" != $((2 * records)) ]; then
  echo "FAIL outputs: $lines lines in matches.txt for $records JSON records"; failures=$((failures + 1))
fi
grep -q '"residual_m"' "$work/matches.jsonl" || { echo "FAIL jsonl lacks residuals"; failures=$((failures + 1)); }
# The simulator's wheel speed reads 0.5 % high (drift 1): the markings tell.
scale=$(sed -n 's/.*odometry scale by the markings \([0-9.]*\) .*/\1/p' "$work/out")
awk -v s="$scale" 'BEGIN { exit !(s > 1.000 && s < 1.012) }' ||
  { echo "FAIL odometry scale '$scale' not near 1.005"; failures=$((failures + 1)); }
check "sweep" 0 "Correct matches \(%\)" -- "$replay" --markings "$work/drive/markings.txt" \
  --poses "$work/drive/poses.txt" --truth "$work/drive/frames.csv" --sweep 2..6
check "compat on the drive" 0 "matches \(k=4\)" -- "$replay" --markings "$work/drive/markings.txt" --compat
# Outputs that cannot be written fail the run (status 1), naming them.
check "full disk (--out)" 1 "^markloop-replay: /dev/full: cannot write: No space left on device" -- \
  "$replay" --markings "$work/drive/markings.txt" --poses "$work/drive/poses.txt" --out /dev/full
check "full disk (--jsonl)" 1 "/dev/full: cannot write: No space left on device" -- \
  "$replay" --markings "$work/drive/markings.txt" --poses "$work/drive/poses.txt" --jsonl /dev/full
check "full disk (standard output)" 1 "standard output: cannot write: No space left on device" -- \
  bash -c '"$1" --markings "$2" >/dev/full' - "$replay" "$work/drive/markings.txt"

finish
