#!/usr/bin/env bash
# markloop-sim from the outside: help, exit status and FILE:LINE messages on
# bad input, and a route file driven end to end.
set -euo pipefail
sim=$1 routes=$2 work=$3
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

check "help" 0 "usage: markloop-sim drive" -- "$sim" --help
check "drive help" 0 "odometry.log" -- "$sim" drive --help
check "no command" 2 "usage" -- "$sim"
check "list" 0 "two-days" -- "$sim" list
check "unknown drive option" 2 "unknown option --frobnicate" -- "$sim" drive --frobnicate 1 --out "$work/x"
check "no value" 2 "^markloop-sim: --out needs a value" -- "$sim" drive --out
check "unknown training-set option" 2 "unknown option --frobnicate" -- "$sim" training-set --frobnicate
check "unknown live option" 2 "unknown option --frobnicate" -- "$sim" live --frobnicate
check "no out" 2 "--out DIR is required" -- "$sim" drive --scenario loop
check "unknown scenario" 2 "unknown scenario 'moon'" -- "$sim" drive --scenario moon --out "$work/x"
check "both" 2 "not both" -- "$sim" drive --scenario loop --route r --out "$work/x"
check "bad light" 2 "--light: unknown 'noon'" -- "$sim" drive --light noon --out "$work/x"
check "bad weights" 2 "--class-weights: unknown marking class 'cat'" -- "$sim" drive --class-weights cat=1 --out "$work/x"
check "bad drift" 2 "--drift must be in 0..100" -- "$sim" drive --drift -1 --out "$work/x"
check "bad seed" 2 "--seed: not a whole number" -- "$sim" drive --seed 1.5 --out "$work/x"
check "cover-lens without a colon" 2 "--cover-lens: expected FROM:TO \(seconds\), got '5'" -- "$sim" drive --cover-lens 5 --out "$work/x"
check "cover-lens backwards" 2 "--cover-lens: expected 0 <= FROM < TO, got '5:3'" -- "$sim" drive --cover-lens 5:3 --out "$work/x"
check "cover-lens not a number" 2 "--cover-lens: not a number" -- "$sim" drive --cover-lens a:3 --out "$work/x"
check "missing route" 2 "$work/none.txt: cannot open" -- "$sim" drive --route "$work/none.txt" --out "$work/x"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 oops\n' >"$work/bad.txt"
check "bad route line" 2 "bad.txt:2: 'oops' is not a number" -- "$sim" drive --route "$work/bad.txt" --out "$work/x"
check "missing camera" 2 "$work/none.yaml" -- "$sim" drive --camera "$work/none.yaml" --out "$work/x"

check "route drive" 0 "block-and-a-half.kitti.txt .* frames" -- \
  "$sim" drive --route "$routes/block-and-a-half.kitti.txt" --max-frames 20 --out "$work/route"
for f in frames.y4m odometry.log frames.csv markings.csv visible.csv camera.yaml markings.txt poses.txt; do
  [ -s "$work/route/$f" ] || { echo "FAIL route drive: $f missing or empty"; failures=$((failures + 1)); }
done
[ "$(wc -l <"$work/route/frames.csv")" = 21 ] || { echo "FAIL route drive: frames.csv rows"; failures=$((failures + 1)); }
check "training set" 0 "2 images" -- "$sim" training-set --frames 2 --out "$work/train"

finish
