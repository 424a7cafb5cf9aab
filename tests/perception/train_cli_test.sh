#!/usr/bin/env bash
# markloop-train from the outside: help, refusals with the reason, and the
# compiled-in model judged on a small simulator set (no training).
set -euo pipefail
train=$1 sim=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

check "help" 0 "usage: markloop-train" -- "$train" --help
check "no data" 2 "no training data" -- "$train" --folds 0
check "bad members" 2 "--members must be 1..4" -- "$train" --sim "$work/none" --members 9
check "bad weight average" 2 "--weight-average must be at least 0 and below 1" -- \
  "$train" --sim "$work/none" --weight-average 1
check "evaluate nothing" 2 "nothing to judge" -- "$train" --evaluate-builtin
check "evaluate trains nothing" 2 "trains nothing" -- "$train" --evaluate-builtin --sim "$work/none"
check "unknown option" 2 "unknown option --frobnicate" -- "$train" --frobnicate 1
check "no value" 2 "^markloop-train: --real needs a value" -- "$train" --real
check "missing set" 2 "$work/none" -- "$train" --evaluate-builtin --sim-test "$work/none"
scripts="$(dirname "$0")/../../app/perception/train"
check "train-model.sh help" 0 "Regenerates the marking classifier" -- sh "$scripts/train-model.sh" --help
check "train-model.sh no real images" 2 "$work/none/annotations.csv: no such file" -- \
  sh "$scripts/train-model.sh" "$work/none"
check "short-cv.sh help" 0 "short cross-validation" -- sh "$scripts/short-cv.sh" --help

"$sim" training-set --out "$work/set" --seed 9002 --frames 6 >/dev/null 2>&1
check "evaluate builtin" 0 "Simulator test set $work/set \(never trained on\)" -- \
  "$train" --evaluate-builtin --sim-test "$work/set"
# The table's last row: every class, with recall and precision.
grep -qE "^all +[0-9]+ +[0-9]+ +[0-9.]+% +[0-9]+ +[0-9]+ +[0-9.]+%" "$work/out" ||
  { echo "FAIL evaluate builtin: no 'all' row"; failures=$((failures + 1)); }
finish
