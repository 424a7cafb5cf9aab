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
scripts="$(dirname "$0")/../../app/tools/train"
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

# Inputs read whole are refused by name when they are directories or too
# big (status 2); outputs that cannot be written fail the run (status 1).
mkdir -p "$work/dir-set/images" "$work/dir-set/annotations.csv"
check "annotations are a directory" 2 "dir-set/annotations.csv: is a directory, not an annotation file" -- \
  "$train" --evaluate-builtin --sim-test "$work/dir-set"
mkdir -p "$work/endless-set/images" && ln -sf /dev/zero "$work/endless-set/annotations.csv"
check "endless annotations" 2 "annotations.csv: larger than 64 MiB, the limit for an annotation file" -- \
  "$train" --evaluate-builtin --sim-test "$work/endless-set"
cp -r "$work/set" "$work/dir-image" && mkdir "$work/dir-image/images/999999.png"
check "image is a directory" 2 "999999.png: is a directory, not an image" -- \
  "$train" --evaluate-builtin --sim-test "$work/dir-image"
"$sim" drive --scenario loop --max-frames 10 --out "$work/drive" >/dev/null 2>&1
printf '50000000,0,stop,1,2,3,4,5,6,7,8\n' >>"$work/drive/visible.csv"
check "drive frame beyond the drive" 2 "visible.csv:[0-9]+: frame 50000000 is beyond the drive's 10 frames \(frames.csv\)" -- \
  timeout 20 "$train" --evaluate-builtin --sim-drive "$work/drive"
# The model file and its notes, and the build's check accepts the file.
check "model file written" 0 "wrote $work/model.bin" -- \
  "$train" --sim "$work/set" --folds 0 --epochs 1 --members 1 --hidden 4 --out "$work/model.bin"
check "model notes" 0 "^Payload CRC-32 0x[0-9a-f]{8}\.$" -- cat "$work/model.txt"
generator="$scripts/../../perception/model/model_file.py"
check "model file checked as the build does" 0 "^// GENERATED from .*model.bin" -- \
  sh -c 'python3 "$1" --kind mlp "$2/model.bin" "$2/model.cpp" && head -1 "$2/model.cpp"' - "$generator" "$work"
printf 'X' | dd of="$work/model.bin" bs=1 seek=100 conv=notrunc 2>/dev/null
check "damaged model file refused" 1 "model.bin: payload CRC-32 0x[0-9a-f]{8} does not match" -- \
  python3 "$generator" --kind mlp "$work/model.bin" "$work/model.cpp"
check "model on a full disk" 1 "^markloop-train: /dev/full: cannot write: No space left on device" -- \
  "$train" --sim "$work/set" --folds 0 --epochs 1 --members 1 --hidden 4 --out /dev/full
check "dump into a file" 1 "^markloop-train: $work/file/mlp: cannot create the directory" -- \
  bash -c ': >"$1/file" && "$2" --sim "$1/set" --folds 0 --epochs 1 --members 1 --hidden 4 --dump "$1/file"' - "$work" "$train"
finish
