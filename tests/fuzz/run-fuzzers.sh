#!/usr/bin/env bash
# Runs every fuzz target of the `fuzz` preset (libFuzzer, ASan, UBSan) for a
# while, each from its committed corpus and the project's own files of its
# kind, and prints a table. An input that crashes a target is kept in
# build/fuzz/crashes/NAME/ and fails the run; copy it into
# tests/fuzz/corpus/NAME/ with the fix, so that ctest replays it for good.
#
#   tests/fuzz/run-fuzzers.sh [--seconds S] [TARGET...]
#
# Needs clang (apt install clang). Builds the preset first.
set -euo pipefail
case "${1:-}" in
  -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
esac
cd "$(dirname "$0")/../.."
seconds=60
if [ "${1:-}" = --seconds ]; then seconds=$2; shift 2; fi
targets=("$@")
command -v clang++ >/dev/null || { echo "run-fuzzers: clang++ not found (apt install clang)" >&2; exit 1; }
cmake --preset fuzz >/dev/null
cmake --build --preset fuzz
bin_dir=build/fuzz/bin
# Each target's build writes NAME.seeds (the project's own files of its kind)
# and NAME.max_len (tests/fuzz/CMakeLists.txt, the one list of targets).
if [ "${#targets[@]}" -eq 0 ]; then
  for seeds in "$bin_dir"/markloop-fuzz-*.seeds; do
    name=${seeds##*/markloop-fuzz-}
    targets+=("${name%.seeds}")
  done
fi

status=0
printf '%-14s %10s %8s %8s %s\n' target runs coverage corpus result
for t in "${targets[@]}"; do
  bin=$bin_dir/markloop-fuzz-$t
  if [ ! -x "$bin" ] || [ ! -f "$bin.seeds" ] || [ ! -f "$bin.max_len" ]; then echo "run-fuzzers: no target '$t'" >&2; exit 2; fi
  work=build/fuzz/corpus/$t
  crashes=build/fuzz/crashes/$t
  mkdir -p "$work" "$crashes"
  # libFuzzer reads corpus directories only: the project's files are copied in.
  while IFS= read -r seed; do
    [ -n "$seed" ] || continue
    if [ -d "$seed" ]; then cp -r "$seed"/. "$work"/; else cp "$seed" "$work"/; fi
  done <"$bin.seeds"
  log=build/fuzz/$t.log
  result=ok
  "$bin" -max_total_time="$seconds" -max_len="$(cat "$bin.max_len")" -rss_limit_mb=2048 -timeout=10 \
    -artifact_prefix="$crashes/" -print_final_stats=1 "$work" "tests/fuzz/corpus/$t" \
    >"$log" 2>&1 || { result="FAILED: $(ls "$crashes" | head -1) (log $log)"; status=1; }
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$( (grep -o 'cov: [0-9]*' "$log" || true) | tail -1 | cut -d' ' -f2)
  corp=$(find "$work" -type f | wc -l)
  printf '%-14s %10s %8s %8s %s\n' "$t" "${runs:-?}" "${cov:-?}" "$corp" "$result"
done
exit $status
