#!/usr/bin/env bash
# The ECU program from the outside: help, exit status and messages on bad
# options and configuration. Arguments: a scratch dir, then the command that
# runs markloop (a cross build puts its emulator in front).
set -euo pipefail
work=$1; shift
ecu=("$@")
rm -rf "$work" && mkdir -p "$work"
source "$(dirname "$0")/../cli_check.sh"

check "help" 0 "usage: markloop" -- "${ecu[@]}" --help
check "unknown option" 2 "^markloop: unknown option --frobnicate \(see --help\)" -- "${ecu[@]}" --frobnicate
check "unknown option with a value" 2 "unknown option --frobnicate" -- "${ecu[@]}" --frobnicate 1
check "no value" 2 "^markloop: --can-in needs a value" -- "${ecu[@]}" --can-in
check "argument without option" 2 "unexpected argument stray" -- "${ecu[@]}" stray
check "bad --set" 2 "--set needs KEY=VALUE, got 'engine.k'" -- "${ecu[@]}" --set engine.k
check "unknown key" 2 "--set: unknown key 'foo'" -- "${ecu[@]}" --set foo=1
check "bad number" 2 "engine.k: not a whole number: 'x'" -- "${ecu[@]}" --set engine.k=x
check "missing config" 2 "$work/none.conf" -- "${ecu[@]}" --config "$work/none.conf"
printf 'engine.k = 4\nbogus line\n' >"$work/bad.conf"
check "bad config line" 2 "bad.conf:2: expected 'key = value', got 'bogus line'" -- "${ecu[@]}" --config "$work/bad.conf"
check "file mode half given" 2 "needs both a frame file \(--camera-file\) and a CAN log \(--can-in\)" -- \
  "${ecu[@]}" --camera-file "$work/none.y4m"
check "print config" 0 "engine.k = 5" -- "${ecu[@]}" --set engine.k=5 --print-config
check "gate under the detector's threshold" 2 \
  "^markloop: observation.min_score 0.5 is below the detector's threshold 0.6 \(detector_min_score, the built-in default\)" -- \
  "${ecu[@]}" --set observation.min_score=0.5

finish
