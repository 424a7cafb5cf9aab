#!/usr/bin/env bash
# Per-frame instruction counts of the pipeline stages on aarch64 and x86-64,
# the portable stand-in for timing on the target: both binaries run under
# qemu-user (qemu-aarch64, qemu-x86_64) with a small instruction-counting
# plugin (insn_count_plugin.c, compiled here with the host's cc), once with
# FEW and once with MANY frames; (count(MANY) - count(FEW)) / (MANY - FEW) is
# the cost of one frame, start-up and preparation cancelled out.
#
#   instruction-counts.sh [--host BUILD] [--aarch64 BUILD] [--few N] [--many N]
#
# Defaults: build/host, build/aarch64; FEW and MANY per stage (the engine:
# 2000 and 12000 frames of the ring drive and its repeats). Prints a
# Markdown table. Adding a stage is one line in `stages` below.
set -euo pipefail
cd "$(dirname "$0")/../.."

die() { echo "instruction-counts: ERROR: $*" >&2; exit 2; }
host_build=build/host aarch64_build=build/aarch64 few=2000 many=12000
while [ $# -gt 0 ]; do
  case "$1" in
    --host) host_build=$2; shift 2 ;;
    --aarch64) aarch64_build=$2; shift 2 ;;
    --few) few=$2; shift 2 ;;
    --many) many=$2; shift 2 ;;
    -h|--help) sed -n '2,14s/^# \{0,1\}//p' "$0"; exit 0 ;;
    *) die "unknown argument $1 (see --help)" ;;
  esac
done
[[ "$few" =~ ^[0-9]+$ && "$many" =~ ^[0-9]+$ && "$many" -gt "$few" ]] || die "--few and --many: whole numbers, many > few"
default_few=$few default_many=$many

# stage name | program (relative to a build tree) | arguments before the frame
# count | FEW | MANY (empty: --few/--many)
stages=(
  "engine (sequence engine, ring drive)|bin/markloop-pipeline-frames|--stage engine --frames|2000|12000"
  "perception (marking detector, 1280x512 grey)|bin/markloop-pipeline-frames|--stage perception --frames|4|12"
)

for tool in qemu-x86_64 qemu-aarch64 cc; do
  command -v "$tool" >/dev/null || die "$tool not found (packages qemu-user, build-essential)"
done
work=$(mktemp -d "${TMPDIR:-/tmp}/markloop-insn.XXXXXX")
trap 'rm -rf "$work"' EXIT
plugin=$work/insn_count_plugin.so
cc -O2 -shared -fPIC -fvisibility=hidden -o "$plugin" tests/perf/insn_count_plugin.c ||
  die "cannot compile the plugin"

count() {  # $1 = qemu, $2... = program and arguments; prints the instruction count
  local qemu=$1 out=$work/count
  shift
  rm -f "$out"
  local prefix=()
  [ "$qemu" = qemu-aarch64 ] && prefix=(-L /)  # Debian multiarch: the :arm64 libraries
  "$qemu" "${prefix[@]}" -plugin "$plugin,out=$out" "$@" >/dev/null ||
    die "$* failed under $qemu"
  [ -s "$out" ] || die "the plugin wrote no count for $*"
  sed -n 's/^instructions: //p' "$out"
}

per_frame() {  # $1 = qemu, $2 = program, $3 = arguments
  local a b
  [ -x "$2" ] || die "$2 missing: build it first (cmake --build --preset ...)"
  # shellcheck disable=SC2086
  a=$(count "$1" "$2" $3 "$few")
  # shellcheck disable=SC2086
  b=$(count "$1" "$2" $3 "$many")
  echo $(((b - a) / (many - few)))
}

echo "| stage | x86-64 instructions/frame | aarch64 instructions/frame | aarch64 / x86-64 |"
echo "|---|---:|---:|---:|"
for entry in "${stages[@]}"; do
  IFS='|' read -r name program args stage_few stage_many <<<"$entry"
  few=${stage_few:-$default_few} many=${stage_many:-$default_many}
  x86=$(per_frame qemu-x86_64 "$host_build/$program" "$args")
  arm=$(per_frame qemu-aarch64 "$aarch64_build/$program" "$args")
  ratio=$(awk -v a="$arm" -v x="$x86" 'BEGIN { printf "%.2f", a / x }')
  echo "| $name (frames $few..$many) | $x86 | $arm | $ratio |"
done
echo
echo "(x86-64 binary from $host_build, aarch64 from $aarch64_build; qemu $(qemu-aarch64 --version | head -n1 | awk '{print $3}'))"
