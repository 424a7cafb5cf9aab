#!/usr/bin/env bash
# The replay and simulator programs from the outside: help, exit status and
# messages on bad input, and an end-to-end drive judged against its truth.
set -euo pipefail
replay=$1 sim=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

check "replay --help" 0 "usage: markloop-replay" -- "$replay" --help
check "sim --help" 0 "usage: markloop-sim" -- "$sim" --help
check "missing option" 2 "--markings FILE is required" -- "$replay"
check "unknown option" 2 "unknown option --frobnicate" -- "$replay" --markings x --frobnicate
check "missing file" 2 "^markloop-replay: $work/none.txt: cannot open" -- "$replay" --markings "$work/none.txt"

printf '2\n0 1 1.5 10 A\n' >"$work/short.txt"
check "wrong count" 2 "short.txt:3: the file declares 2 records" -- "$replay" --markings "$work/short.txt"
printf '1\n0 1 x 10 A\n' >"$work/nan.txt"
check "not a number" 2 "nan.txt:2: record 1: y is not a finite number: 'x'" -- "$replay" --markings "$work/nan.txt"
printf '1\n0 1 1.5 10 A\n' >"$work/one.txt"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0\n' >"$work/poses.txt"
check "short pose line" 2 "poses.txt:2: expected 12 numbers" -- "$replay" --markings "$work/one.txt" --poses "$work/poses.txt"
check "bad k" 2 "k must be between 2 and 10" -- "$replay" --markings "$work/one.txt" --k 11
check "bad sweep" 2 "--sweep: expected" -- "$replay" --markings "$work/one.txt" --sweep 5

printf '0\n' >"$work/empty.txt"
check "empty input (engine)" 0 "^matches: 0" -- "$replay" --markings "$work/empty.txt"
check "empty input (compat)" 0 "0 matches" -- "$replay" --markings "$work/empty.txt" --compat --out "$work/empty-matches.txt"
[ ! -s "$work/empty-matches.txt" ] || { echo "FAIL compat wrote matches for empty input"; failures=$((failures + 1)); }

check "simulated drive" 0 "1.2 km city block" -- "$sim" drive --scenario loop --seed 2 --no-render --out "$work/drive"
check "replay of the drive" 0 "precision 100.0%" -- "$replay" --markings "$work/drive/markings.txt" \
  --poses "$work/drive/poses.txt" --truth "$work/drive/frames.csv" \
  --out "$work/matches.txt" --jsonl "$work/matches.jsonl"
lines=$(wc -l <"$work/matches.txt") records=$(wc -l <"$work/matches.jsonl")
if [ "$records" -lt 10 ] || [ "$lines" != $((2 * records)) ]; then
  echo "FAIL outputs: $lines lines in matches.txt for $records JSON records"; failures=$((failures + 1))
fi
grep -q '"residual_m"' "$work/matches.jsonl" || { echo "FAIL jsonl lacks residuals"; failures=$((failures + 1)); }
check "sweep" 0 "Correct matches \(%\)" -- "$replay" --markings "$work/drive/markings.txt" \
  --poses "$work/drive/poses.txt" --truth "$work/drive/frames.csv" --sweep 2..6
check "compat on the drive" 0 "matches \(k=4\)" -- "$replay" --markings "$work/drive/markings.txt" --compat

finish
