#!/bin/sh
# Regenerates the marking classifier, app/perception/model/marking_mlp.bin
# (the MLPs, markloop-train) and app/perception/model/marking_cnn.bin (the
# convolutional networks, train_cnn.py: needs python3-torch), each with a
# .txt beside it saying how it was trained (format:
# app/perception/model/README.md; the build compiles them in), and prints
# their evaluation, then the blend's (the detector's). Run from the repository
# root after `bash .ci/setup train` (PyTorch, and the preset train: markloop-train
# with AVX2 and FMA, x86-64-v3: the model in the repository came from that
# build; MARKLOOP_BUILD=build/host runs the host preset's build instead, on
# any x86-64 host, and gives a model that differs in the last bits).
#
#   app/tools/train/train-model.sh [REAL_DIR]
#
# REAL_DIR: the real images (roadmarks-honda layout; default
# ../shared/data/roadmarks-honda). They are read, never copied. The simulator
# data is rendered into build/train-data with fixed seeds: training sets
# 101..110 (600 images each) through the simulator's camera, 201..206 through
# the real images' camera (app/cameras/honda.yaml: its homography, bird's-eye
# region and bonnet), and a drive of the `figure8` scenario with seed 21
# (curves, lane changes, off-road clutter) to train on; held apart for
# evaluation only, the training-set seeds 9001 (simulator's camera) and 9002
# (real camera), 1,200 images each (one seed's 300 moved recall in range by
# 1.5 points either way), and a drive of the `loop` scenario with seed 7.
# markloop-train trains its default ensemble of 3 networks (seeds 1, 101, 201)
# and writes the candidates to build/train-data/candidates; train_cnn.py
# trains the convolutional networks on them (seeds 1 and 2), the
# cross-validation folds two at a time (one thread each), the final ones on
# two threads. Same inputs, same model: every
# random choice is seeded.
set -eu
case "${1:-}" in
  -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
  -*) echo "train-model.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
esac
REAL=${1:-../shared/data/roadmarks-honda}
DATA=build/train-data
# shellcheck source=app/tools/train/recipe.sh
. "$(dirname "$0")/recipe.sh"
SIM=$BUILD/bin/markloop-sim
TRAIN=$BUILD/bin/markloop-train
[ -f "$REAL/annotations.csv" ] ||
  { echo "train-model.sh: $REAL/annotations.csv: no such file (REAL_DIR: the real images)" >&2; exit 2; }
for tool in "$SIM" "$TRAIN"; do
  [ -x "$tool" ] || { echo "train-model.sh: $tool missing: bash .ci/setup train first (see --help)" >&2; exit 2; }
done
PYTHON=${PYTHON:-/usr/bin/python3}
"$PYTHON" -c "import torch, numpy" 2>/dev/null ||
  { echo "train-model.sh: $PYTHON cannot import torch and numpy: bash .ci/setup train" >&2; exit 2; }
mkdir -p "$DATA"
# training_set SEED DIR FRAMES [CAMERA]: rendered once, through CAMERA when
# given (default the simulator's). The simulator writes the calibration it
# used but not the detector_* keys (region, bonnet), so CAMERA's file then
# replaces the set's camera.yaml.
training_set() {
  [ -f "$2/annotations.csv" ] && return
  "$SIM" training-set --out "$2" --seed "$1" --frames "$3" ${4:+--camera "$4"}
  [ -z "${4:-}" ] || cp "$4" "$2/camera.yaml"
}
sims=""
for seed in 101 102 103 104 105 106 107 108 109 110; do
  training_set "$seed" "$DATA/sim$seed" 600
  sims="$sims --sim $DATA/sim$seed"
done
# The same kind of scenes seen through the real images' camera: the
# classifier learns markings at that camera's bird's-eye resolution and smear
# too, not at one camera's only.
for seed in 201 202 203 204 205 206; do
  training_set "$seed" "$DATA/honda$seed" 600 app/cameras/honda.yaml
  sims="$sims --sim $DATA/honda$seed"
done
training_set 9001 "$DATA/simtest9001" 1200
training_set 9002 "$DATA/hondatest9002" 1200 app/cameras/honda.yaml
[ -f "$DATA/drive-figure8-21/visible.csv" ] ||
  "$SIM" drive --scenario figure8 --seed 21 --out "$DATA/drive-figure8-21"
[ -f "$DATA/drive-loop-7/visible.csv" ] ||
  "$SIM" drive --scenario loop --seed 7 --out "$DATA/drive-loop-7"
TESTS="--sim-test $DATA/simtest9001 --sim-test $DATA/hondatest9002 --sim-drive $DATA/drive-loop-7"
DUMP=$DATA/candidates
# shellcheck disable=SC2086  # $sims, $TESTS and $RECIPE are lists of options
"$TRAIN" --real "$REAL" --real-camera app/cameras/honda.yaml $sims \
  --sim-drive-train "$DATA/drive-figure8-21" $TESTS $RECIPE \
  --out app/perception/model/marking_mlp.bin --dump "$DUMP"
CNN="$PYTHON app/tools/train/train_cnn.py $DUMP --seeds $CNN_SEEDS"
rm -rf "$DUMP"/cnn
$CNN --folds 0,1 & first=$!
$CNN --folds 2,3 & second=$!
wait $first && wait $second
$CNN --folds all --threads 2 --out app/perception/model/marking_cnn.bin
echo "The MLPs blended with the networks (their geometric mean, as the detector classifies):"
scores="--scores $DUMP/mlp"
for seed in $(echo "$CNN_SEEDS" | tr , ' '); do scores="$scores --scores $DUMP/cnn/seed$seed"; done
# shellcheck disable=SC2086
"$TRAIN" --real "$REAL" --real-camera app/cameras/honda.yaml $TESTS $scores
