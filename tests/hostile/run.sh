#!/usr/bin/env bash
# Hostile and careless inputs for every markloop program.
#
#   bash tests/hostile/run.sh --bin build/host [--out DIR] [--filter REGEX] [--jobs N]
#                             [--timeout S] [--mem-mb N] [--keep] [--list]
#
#   --bin DIR       build tree holding bin/markloop, bin/markloop-replay,
#                   bin/markloop-eval, bin/markloop-detect, bin/markloop-sim
#   --out DIR       scratch, fixtures, logs and results; default build/hostile
#   --filter REGEX  run only the cases whose name matches (grep -E)
#   --jobs N        cases run in parallel; default 2
#   --timeout S     time limit of one case (timeout -s KILL); default 10
#   --mem-mb N      address-space limit of one case (ulimit -v); default 4096
#   --keep          keep each case's scratch dir (OUT/work/NAME)
#   --list          print the case names and expectations, run nothing
#
# Makes a short simulated drive once (OUT/fixtures), derives the hostile
# inputs from it case by case, runs each case under limits and classifies it:
# crash, hang, dataloss, silent_accept, unnamed, wrong_status (or pass, skip).
# Prints a table; failing cases' logs are in OUT/logs/NAME.log. Exit status 0
# when every case passed, 1 when any failed, 2 on a usage or fixture error.
set -uo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
bin=
out=build/hostile
filter=
jobs=2
case_timeout=10
mem_mb=4096
keep=0
list=0

usage() { sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "hostile: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin=${2:?}; shift 2 ;;
    --out) out=${2:?}; shift 2 ;;
    --filter) filter=${2:?}; shift 2 ;;
    --jobs) jobs=${2:?}; shift 2 ;;
    --timeout) case_timeout=${2:?}; shift 2 ;;
    --mem-mb) mem_mb=${2:?}; shift 2 ;;
    --keep) keep=1; shift ;;
    --list) list=1; shift ;;
    --help|-h) usage; exit 0 ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
[ -n "$bin" ] || die "--bin BUILD_DIR is required (see --help)"
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || die "--jobs wants a positive whole number, got '$jobs'"
[[ "$case_timeout" =~ ^[1-9][0-9]*$ ]] || die "--timeout wants whole seconds, got '$case_timeout'"
[[ "$mem_mb" =~ ^[1-9][0-9]*$ ]] || die "--mem-mb wants a positive whole number, got '$mem_mb'"
bin=$(cd "$bin" 2>/dev/null && pwd) || die "--bin: no such directory"
for tool in bin/markloop bin/markloop-replay bin/markloop-eval \
            bin/markloop-detect bin/markloop-sim; do
  [ -x "$bin/$tool" ] || die "$bin/$tool is missing: build first (cmake --build --preset host)"
done
for tool in timeout setpriv mkfifo mknod sha256sum stat xargs; do
  command -v "$tool" >/dev/null || die "needs $tool"
done
PY=$(command -v /usr/bin/python3 || command -v python3) || die "needs python3"

mkdir -p "$out" && out=$(cd "$out" && pwd)
chmod 755 "$out"
export OUT=$out H=$here PY KEEP=$keep CASE_TIMEOUT=$case_timeout
export MEM_KB=$((mem_mb * 1024)) FSIZE_KB=$((64 * 1024))
export STOP_MS=100 STOP_SLACK_MS=300 STOP_LIMIT_S=3
export ECU=$bin/bin/markloop REPLAY=$bin/bin/markloop-replay EVAL=$bin/bin/markloop-eval
export DETECT=$bin/bin/markloop-detect SIM=$bin/bin/markloop-sim
export F=$out/fixtures
# What the ECU cases share: no real-time scheduling or locked memory (this
# runs as root), and file mode on the small (10 frames) or full drive.
export X="--set realtime.mlockall=false --set realtime.priority=0"
export FMS="--camera-file $F/small.y4m --can-in $F/drive/odometry.log --calibration $F/drive/camera.yaml"
export FMF="--camera-file $F/drive/frames.y4m --can-in $F/drive/odometry.log --calibration $F/drive/camera.yaml"
export REPO=$(cd "$here/../.." && pwd)
start=$(date +%s.%N)

# ---------------------------------------------------------------- fixtures
# Once per run, reused while the binaries and this folder are unchanged.
stamp=$( (ls -l --time-style=+%s "$ECU" "$SIM"; cat "$here/gen.py" "$here/run.sh") | sha256sum | cut -c1-16)
if [ "$(cat "$F/.stamp" 2>/dev/null)" != "$stamp" ]; then
  echo "hostile: making fixtures in $F"
  rm -rf "$F" && mkdir -p "$F"
  (
    set -e
    cd "$F"
    "$SIM" drive --scenario loop --seed 1 --max-frames 120 --out drive >sim.log 2>&1
    "$ECU" --camera-file drive/frames.y4m --can-in drive/odometry.log --calibration drive/camera.yaml \
      --can-out drive/ecu-can.log --detections-out drive/ecu-detections.csv \
      --landmarks-out drive/ecu-landmarks.csv --summary drive/ecu-summary.json --map base.map \
      --set realtime.mlockall=false --set realtime.priority=0 >ecu.log 2>&1
    "$PY" "$here/gen.py" map-info base.map | grep -q '^ok [1-9]'
    "$PY" "$here/gen.py" map-make big.map 4 100 base.map
    "$PY" "$here/gen.py" y4m-frames drive/frames.y4m small.y4m 10
    "$PY" "$here/gen.py" y4m-420 small.y4m small420.y4m
    mkdir eval
    cp drive/frames.csv drive/markings.csv drive/visible.csv drive/ecu-can.log \
      drive/ecu-detections.csv drive/ecu-landmarks.csv eval/
    "$SIM" training-set --out ts --frames 2 --seed 7 >ts.log 2>&1
    cp "$REPO/tests/fuzz/corpus/still_image/grey.jpg" "$REPO/tests/fuzz/corpus/still_image/grey.png" .
    # A camera for the 64x48 corpus images (the sim camera scaled down 20 times).
    sed -e 's/^image_width: .*/image_width: 64/' -e 's/^image_height: .*/image_height: 48/' \
        -e 's/data: \[ 900\., 0\., 6\.3950000000000000e+02, 0\., 900\.,/data: [ 45., 0., 31.5, 0., 45.,/' \
        -e 's/^       2\.5550000000000000e+02, 0\., 0\., 1\. \]/       23.5, 0., 0., 1. ]/' drive/camera.yaml >tiny.yaml
    "$PY" -c 'import random, sys; r = random.Random(63); sys.stdout.buffer.write(b"\xff" + bytes(r.randrange(256) for _ in range(65535)))' >random.bin
    cp "$REPO/app/ecu/markloop.conf" markloop.conf
    printf 'camera.file = %s\ncan.in_log = %s\ncalibration = %s\nrealtime.mlockall = false\n' \
      "$F/small.y4m" "$F/drive/odometry.log" "$F/drive/camera.yaml" >file-mode.conf
    rm -f drive/*.png drive/*.svg
    chmod -R a+rX "$F"
  ) || { cat "$F"/*.log >&2 2>/dev/null; die "could not make the fixtures (see above)"; }
  echo "$stamp" >"$F/.stamp"
fi

# ---------------------------------------------------------------- cases
rm -rf "$out/cases" "$out/results" "$out/logs" "$out/work"
mkdir -p "$out/cases" "$out/results" "$out/logs" "$out/work"
# shellcheck source=tests/hostile/cases.sh
source "$here/cases.sh"
define_cases
[ "$list" = 1 ] && { cat "$out/cases/.list"; exit 0; }
ncases=$(find "$out/cases" -name '*.case' | wc -l)
[ "$ncases" -gt 0 ] || die "no case matches --filter '$filter'"
echo "hostile: $ncases cases, $jobs at a time, ${case_timeout}s and ${mem_mb} MiB each (failures as they come)"

# Signal cases (which mostly wait for a FIFO writer or the signal) run one at
# a time beside the others (--jobs at a time, slow programs first, so that the
# tail is short).
find "$out/cases" -name '0-*.case' | sort | xargs -r -P 1 -n 1 bash "$here/lib.sh" run-case &
signals=$!
find "$out/cases" -name '[1-9]-*.case' | sort | xargs -r -P "$jobs" -n 8 bash "$here/lib.sh" run-case
wait "$signals"

# ---------------------------------------------------------------- table
end=$(date +%s.%N)
wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.0f", b - a }')
cat "$out"/results/*.res >"$out/results.tsv" 2>/dev/null
# Stop times after our SIGTERM/SIGINT (cases still running when it was sent).
stops=$(awk -F'\t' '$7 == "signal" { print $5 "\t" $1 }' "$out/results.tsv" | sort -n |
  awk -F'\t' -v limit="$STOP_MS" -v slack="$STOP_SLACK_MS" '{ t[NR] = $1; n[NR] = $2 }
    END { if (NR) printf "stop after SIGTERM/SIGINT, %d cases: median %d ms, max %d ms (%s); limit %d ms, %d with slack",
                         NR, t[int((NR + 1) / 2)], t[NR], n[NR], limit, slack }')
awk -F'\t' -v wall="$wall" -v out="$out" -v stops="$stops" '
  { total++; prog[$2]++; split($3, cl, ",")
    if ($3 == "pass") { pass++; pp[$2]++ } else if ($3 == "skip") { skip++ }
    else { failed++; pf[$2]++; for (i in cl) { n[cl[i]]++; names[cl[i]] = names[cl[i]] " " $1 } } }
  END {
    printf "\n%-10s %6s %6s %6s\n", "program", "cases", "passed", "failed"
    split("ecu replay eval detect sim", order, " ")
    for (i = 1; i <= 5; i++) { p = order[i]; printf "%-10s %6d %6d %6d\n", p, prog[p], pp[p], pf[p] }
    printf "%-10s %6d %6d %6d   (%d skipped)\n\n", "all", total, pass, failed, skip
    split("crash hang dataloss silent_accept unnamed wrong_status harness", cls, " ")
    label["crash"] = "crashes"; label["hang"] = "hangs"; label["dataloss"] = "silent data loss"
    label["silent_accept"] = "silent acceptance"; label["unnamed"] = "unnamed rejections"
    label["wrong_status"] = "wrong exit status"; label["harness"] = "harness errors"
    for (i = 1; i <= 7; i++) printf "%-20s %5d\n", label[cls[i]], n[cls[i]]
    if (stops != "") printf "\n%s\n", stops
    printf "\nwall time %s s; logs of failing cases in %s/logs/\n", wall, out
    for (i = 1; i <= 7; i++) if (n[cls[i]] > 0) {
      printf "\n%s (%d):\n", label[cls[i]], n[cls[i]]
      m = split(names[cls[i]], list, " "); line = " "
      for (j = 1; j <= m; j++) { if (length(line) + length(list[j]) > 100) { print line; line = " " } line = line " " list[j] }
      print line
    }
    exit (failed > 0 ? 1 : 0)
  }' "$out/results.tsv"
