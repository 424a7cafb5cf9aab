# Shared by the command-line tests (sourced, not run): `check` runs a
# command and compares its exit status and output with what is expected;
# `finish` fails the test when any check failed. Needs $work (scratch dir).
failures=0
check() {  # check NAME EXPECTED_STATUS PATTERN -- COMMAND...
  local name=$1 want=$2 pattern=$3; shift 4
  local status=0
  "$@" >"$work/out" 2>&1 || status=$?
  if [ "$status" != "$want" ] || ! grep -qE -- "$pattern" "$work/out"; then
    echo "FAIL $name: status $status (want $want), output:"; sed 's/^/  /' "$work/out"
    failures=$((failures + 1))
  else
    echo "ok   $name"
  fi
}
finish() {
  [ "$failures" = 0 ] || { echo "$failures check(s) failed"; exit 1; }
}
