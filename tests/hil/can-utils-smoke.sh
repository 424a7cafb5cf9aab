#!/bin/sh
# Shell-level HIL step in the guest: the bus itself works with can-utils
# alone (candump sees cansend), so failures in the C++ tests point at the
# driver, not at the VM.
set -eu
IF=${HIL_CAN_IF:-vcan0}
OUT=${HIL_RESULTS:-/tmp}/can-utils-smoke.log
ip -details link show "$IF"
candump -L -n 3 "$IF" >"$OUT" &
pid=$!
sleep 0.5
cansend "$IF" 123#DEADBEEF
cansend "$IF" 18FF0001#0102030405060708
cansend "$IF" 7FF#
wait $pid
cat "$OUT"
sed 's/^([0-9]*\.[0-9]*) //' "$OUT" >"$OUT.body"
printf '%s\n' "$IF 123#DEADBEEF" "$IF 18FF0001#0102030405060708" "$IF 7FF#" | cmp - "$OUT.body"
echo "can-utils smoke: ok"
