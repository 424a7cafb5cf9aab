#!/bin/sh
# The short cross-validation that ideas are screened with (docs/decisions.md;
# about 5 minutes on two cores): markloop-train as
# train-model.sh runs it, but one network instead of three and fewer
# simulator sets (training sets 101..105 and 201..203, the `figure8`
# drive), judged on the same held-apart sets. It writes no model. Run from
# the repository root after train-model.sh has rendered build/train-data.
#
#   app/tools/train/short-cv.sh [REAL_DIR] [markloop-train options...]
#
# Options given after REAL_DIR are appended (a later one wins: --seed 2,
# --weight-decay 1e-3, ...); MARKLOOP_TRAIN_LIST_MISSED=1 and the other
# diagnostics of markloop-train --help work as there. It runs build/train's
# markloop-train, as train-model.sh does (MARKLOOP_BUILD=build/host: the host
# preset's). MARKLOOP_TRAIN_DATA=DIR reads the rendered sets from DIR instead
# of build/train-data (sets rendered another way, for an experiment).
set -eu
case "${1:-}" in
  -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
esac
REAL=../shared/data/roadmarks-honda
case "${1:-}" in
  ''|-*) ;;
  *) REAL=$1; shift ;;
esac
DATA=${MARKLOOP_TRAIN_DATA:-build/train-data}
# shellcheck source=app/tools/train/recipe.sh
. "$(dirname "$0")/recipe.sh"
TRAIN=$BUILD/bin/markloop-train
[ -x "$TRAIN" ] || { echo "short-cv.sh: $TRAIN missing: build the preset first (see train-model.sh --help)" >&2; exit 2; }
for set in sim101 sim102 sim103 sim104 sim105 honda201 honda202 honda203 simtest9001 hondatest9002; do
  [ -f "$DATA/$set/annotations.csv" ] ||
    { echo "short-cv.sh: $DATA/$set missing: run app/tools/train/train-model.sh first" >&2; exit 2; }
done
# shellcheck disable=SC2086  # $RECIPE is a list of options
exec "$TRAIN" --real "$REAL" --real-camera app/cameras/honda.yaml \
  --sim "$DATA/sim101" --sim "$DATA/sim102" --sim "$DATA/sim103" --sim "$DATA/sim104" \
  --sim "$DATA/sim105" --sim "$DATA/honda201" --sim "$DATA/honda202" --sim "$DATA/honda203" \
  --sim-drive-train "$DATA/drive-figure8-21" \
  --sim-test "$DATA/simtest9001" --sim-test "$DATA/hondatest9002" --sim-drive "$DATA/drive-loop-7" \
  $RECIPE --members 1 "$@"
