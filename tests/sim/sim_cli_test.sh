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
# Routes that imply no real drive, or are no file, are refused before a
# world is laid along them.
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 10000000\n' >"$work/jump.txt"
check "route jump" 2 "^markloop-sim: $work/jump.txt:2: 10000 km from the pose before: more than the 1000 m a route may step" -- \
  timeout 20 "$sim" drive --route "$work/jump.txt" --no-render --out "$work/x"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1e12\n' >"$work/far.txt"
check "route far away" 2 "far.txt:2: position \(1000000000 km, 0 m\) lies beyond 100000 km of the origin" -- \
  timeout 20 "$sim" drive --route "$work/far.txt" --no-render --out "$work/x"
check "route is a directory" 2 "^markloop-sim: $work: is a directory, not a route file" -- \
  "$sim" drive --route "$work" --out "$work/x"
printf '0 0 0 0 0 0 0 0\n1 10 0 0 0 0 0 0\n2 20 0 0 0 0 0 0\n' >"$work/tum-zero.txt"
check "route with a zero quaternion" 2 "tum-zero.txt:1: quaternion qx qy qz qw is zero" -- \
  "$sim" drive --route "$work/tum-zero.txt" --no-render --out "$work/x"
check "speed out of range" 2 "--speed must be in 0.1..100 m/s" -- "$sim" drive --speed 1e308 --out "$work/x"
check "frame rate out of range" 2 "--fps must be in 1..1000" -- "$sim" drive --fps 1e-300 --out "$work/x"
check "laps out of range" 2 "--laps must be in 1..1000" -- "$sim" drive --laps 2147483648 --out "$work/x"
check "class weight out of range" 2 "weight must be a number in 0..1e6" -- "$sim" drive --class-weights stop=1e308 --out "$work/x"
check "unknown command" 2 "^markloop-sim: unknown command 'fly'" -- "$sim" fly
check "endless route" 2 "/dev/zero: larger than 64 MiB, the limit for a route file" -- \
  "$sim" drive --route /dev/zero --out "$work/x"

check "route drive" 0 "block-and-a-half.kitti.txt .* frames" -- \
  "$sim" drive --route "$routes/block-and-a-half.kitti.txt" --max-frames 20 --out "$work/route"
for f in frames.y4m odometry.log frames.csv markings.csv visible.csv camera.yaml markings.txt poses.txt; do
  [ -s "$work/route/$f" ] || { echo "FAIL route drive: $f missing or empty"; failures=$((failures + 1)); }
done
[ "$(wc -l <"$work/route/frames.csv")" = 21 ] || { echo "FAIL route drive: frames.csv rows"; failures=$((failures + 1)); }
check "training set" 0 "2 images" -- "$sim" training-set --frames 2 --out "$work/train"

# Outputs that cannot be written fail the run (status 1), naming them.
echo keep >"$work/file"
check "out is a file" 2 "^markloop-sim: $work/file: not a directory \(--out DIR" -- \
  "$sim" drive --scenario loop --no-render --max-frames 5 --out "$work/file"
check "training set out is a file" 2 "^markloop-sim: $work/file: not a directory" -- \
  "$sim" training-set --frames 1 --out "$work/file"
[ "$(cat "$work/file")" = keep ] || { echo "FAIL --out file overwritten"; failures=$((failures + 1)); }
mkdir -p "$work/ro" && chmod 555 "$work/ro"
if [ ! -w "$work/ro" ]; then  # root writes anywhere
  check "out not writable" 1 "^markloop-sim: $work/ro/x: cannot create the directory" -- \
    "$sim" drive --scenario loop --no-render --max-frames 5 --out "$work/ro/x"
fi
mkdir -p "$work/full" && ln -sf /dev/full "$work/full/frames.csv"
check "full disk" 1 "^markloop-sim: $work/full/frames.csv: cannot write: No space left on device" -- \
  "$sim" drive --scenario loop --no-render --max-frames 5 --out "$work/full"
mkdir -p "$work/full-set/images" && ln -sf /dev/full "$work/full-set/images/000000.png"
check "full disk (training set)" 1 "000000.png: cannot write: No space left on device" -- \
  "$sim" training-set --frames 1 --out "$work/full-set"
check "full disk (standard output)" 1 "standard output: cannot write: No space left on device" -- \
  bash -c '"$1" list >/dev/full' - "$sim"
# live reads the drive whole before it opens a device.
rm -f "$work/route/odometry.log" && mkdir "$work/route/odometry.log"
check "live: odometry log is a directory" 2 "odometry.log: is a directory, not an odometry log" -- \
  "$sim" live --from "$work/route" --video /dev/null --can vcan-none

finish
