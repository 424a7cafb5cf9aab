# Hostile-input harness: helpers for case setup, and the runner of cases.
# Sourced by run.sh (case generation); run as
#   bash lib.sh run-case CASEFILE...   (by run.sh through xargs)
# A case file holds bash variables (see cases.sh and README.md).
# Process start-up is slow on a loaded machine: the runner forks little.

# ---------------------------------------------------------------- setup helpers
# (called from a case's `setup`, which runs as the caller, cwd $W, no limits)

# Remember a background helper's pid; the runner kills it (by pid) at the end.
bg_pid() { echo "$1" >>"$W/.bg"; }
# FIFO fed with SRC (the first BYTES bytes when given), then closed.
fifo_feed() {  # FIFO SRC [BYTES]
  mkfifo "$1"
  if [ -n "${3:-}" ]; then (exec head -c "$3" "$2" >"$1") & else (exec cat "$2" >"$1") & fi
  bg_pid $!
}
# FIFO fed with SRC's first BYTES bytes; then MARK is made and the writer
# stalls, holding the FIFO open.
fifo_stall() {  # FIFO SRC BYTES MARK
  mkfifo "$1"
  { head -c "$3" "$2"; : >"$4"; exec sleep 600; } >"$1" 2>/dev/null &
  bg_pid $!
}
# FIFO fed with SRC's first BYTES bytes by a writer that then waits SECONDS
# before it closes (a slow producer).
fifo_slow() {  # FIFO SRC BYTES SECONDS
  mkfifo "$1"
  { head -c "$3" "$2"; exec sleep "$4"; } >"$1" 2>/dev/null &
  bg_pid $!
}
# Device nodes in the scratch dir (never the system's own: a program that
# renames or replaces its map or output would do it to /dev/null as root).
node() {  # PATH null|zero|full|nodev
  [ "$(id -u)" = 0 ] || exit 77
  case "$2" in
    null) mknod "$1" c 1 3 ;; zero) mknod "$1" c 1 5 ;; full) mknod "$1" c 1 7 ;;
    nodev) mknod "$1" c 240 0 ;;  # an unassigned major: open() fails with ENXIO
  esac
  chmod 666 "$1"
}
gen() { "$PY" "$H/gen.py" "$@"; }
# An old modification time, so that a later save shows.
age() { touch -h -d @946684800 "$@"; }
# The scratch dir open to nobody (cases with user=nobody).
open_scratch() { chmod 755 "$W"; }

# ---------------------------------------------------------------- checks
fingerprint() {  # PATH -> type and content of a path (a link itself, not followed)
  local p=$1 t
  if [ ! -e "$p" ] && [ ! -L "$p" ]; then echo "missing"; return; fi
  if [ -L "$p" ]; then echo "link:$(readlink "$p"):$(fingerprint_target "$p")"
  elif [ -f "$p" ]; then echo "file:$(stat -c %a "$p"):$(sha256sum <"$p" | cut -c1-16)"
  elif [ -d "$p" ]; then echo "dir:$(stat -c %a "$p"):$(ls -A "$p" | cksum)"
  else stat -c '%F:%t:%T:%a' "$p" | tr ' ' _; fi
}
fingerprint_target() { if [ -f "$1" ]; then sha256sum <"$1" | cut -c1-16; else echo -; fi; }
map_info() { "$PY" "$H/gen.py" map-info "$1"; }
landmarks_of() { case "$1" in ok*) local a=($1); echo "${a[1]}" ;; *) echo -1 ;; esac; }
# Expands $W, $F... in a field.
expand() { eval "printf -v \"\$1\" '%s' \"$2\""; }
# Microseconds since the epoch, into the named variable.
now() { printf -v "$1" '%s' "${EPOCHREALTIME/./}"; }
alive() { local s; s=$(ps -o stat= -p "$1" 2>/dev/null); [ -n "$s" ] && [[ "$s" != Z* ]]; }
CRASH_RE='AddressSanitizer|LeakSanitizer|ThreadSanitizer|UndefinedBehaviorSanitizer|runtime error:|terminate called|bad_alloc|Segmentation fault|stack smashing|double free|malloc\(\): |free\(\): |Assertion .* failed'

# ---------------------------------------------------------------- one case
run_case() {
  local casefile=$1
  local name= prog= expect= mention= line= phrase= setup= cmd= guard= mapok= mapsaved= preserve=
  local user= timeout= term= termsig=TERM termdelay=0.5 termexit=0 shell=0 note= linkkeep=
  # shellcheck disable=SC1090
  source "$casefile"
  [ -n "$timeout" ] || timeout=$CASE_TIMEOUT
  export W="$OUT/work/$name"
  mkdir -p "$W" && cd "$W" || return
  [ "$user" = nobody ] && chmod 755 "$W"   # before setup, which may open it further
  local res="$OUT/results/$name.res" log="$OUT/logs/$name.log"
  local classes=() details=() has=" "
  add() { [[ "$has" == *" $1 "* ]] || has+="$1 "; classes+=("$1"); details+=("$2"); }

  # Setup (no limits). 77: not possible here (skip); anything else: harness error.
  if [ -n "$setup" ]; then
    local sst=0
    (set -e; eval "$setup") >"$W/.setup.out" 2>&1 || sst=$?
    if [ "$sst" = 77 ]; then
      printf '%s\t%s\tskip\t-\t0\tneeds root\trun\n' "$name" "$prog" >"$res"; cleanup_case; return
    elif [ "$sst" != 0 ]; then
      local so; read -r -N 300 so <"$W/.setup.out"
      printf '%s\t%s\tharness\t-\t0\tsetup failed (%s): %s\trun\n' "$name" "$prog" "$sst" "${so//$'\n'/ }" >"$res"
      echo "  HARNESS $name: setup failed ($sst): ${so//$'\n'/ }"
      cleanup_case; return
    fi
  fi

  # Before: what must survive.
  expand mention "$mention"
  local p g_paths=() g_before=() m_before=-1 ms_before=-1 ms_mtime= pv_sum=
  for p in $guard; do expand p "$p"; g_paths+=("$p"); g_before+=("$(fingerprint "$p")"); done
  if [ -n "$mapok" ]; then expand mapok "$mapok"; m_before=$(landmarks_of "$(map_info "$mapok")"); fi
  if [ -n "$mapsaved" ]; then
    expand mapsaved "$mapsaved"
    if [ -f "$mapsaved" ]; then age "$mapsaved"; ms_before=$(landmarks_of "$(map_info "$mapsaved")"); fi
    ms_mtime=$(stat -c %Y "$mapsaved" 2>/dev/null || echo none)
  fi
  if [ -n "$preserve" ]; then expand preserve "$preserve"; pv_sum=$(sha256sum <"$preserve" | cut -c1-16); fi
  [ -n "$linkkeep" ] && expand linkkeep "$linkkeep"

  # Limits: time (timeout -s KILL), address space, file size; as nobody if asked.
  local limits="ulimit -v $MEM_KB; ulimit -f $FSIZE_KB; ulimit -c 0;"
  local body runner
  if [ "$shell" = 1 ]; then body="$limits $cmd"; else body="$limits exec $cmd"; fi
  runner=(bash -c "$body")
  if [ "$user" = nobody ]; then
    runner=(setpriv --reuid=nobody --regid=nogroup --clear-groups bash -c "$body")
  fi

  local st t0 t1 elapsed_ms sent=
  if [ -z "$term" ]; then
    now t0
    timeout -s KILL "$timeout" "${runner[@]}" </dev/null >"$W/.out" 2>"$W/.err"
    st=$?
    now t1
  else
    # Signal mode: start; wait until the case is where it should be (a file
    # appears) and termdelay more; send the signal; time the exit.
    "${runner[@]}" </dev/null >"$W/.out" 2>"$W/.err" &
    local pid=$! waited=0
    if [[ "$term" == file:* ]]; then
      local mark; expand mark "${term#file:}"
      while [ ! -e "$mark" ] && [ $waited -lt $((timeout * 100)) ] && alive $pid; do
        sleep 0.01; waited=$((waited + 1)); done
    fi
    sleep "$termdelay"
    if ! alive $pid; then
      sent=0; now t0; wait $pid; st=$?; now t1
    else
      sent=1
      now t0
      kill -s "$termsig" $pid 2>/dev/null
      # Polled, not `wait -n` on the case and a watchdog: a case that ends
      # before the watchdog starts is not reported until the watchdog ends.
      # kill -0 fails once bash has reaped the case; wait still has its status.
      local deadline=$((t0 + STOP_LIMIT_S * 1000000)) t
      while kill -0 $pid 2>/dev/null; do
        now t
        [ "$t" -lt "$deadline" ] || break
        sleep 0.002
      done
      if kill -0 $pid 2>/dev/null; then
        kill -KILL $pid 2>/dev/null; wait $pid 2>/dev/null; now t1
        add hang "still running ${STOP_LIMIT_S} s after SIG$termsig (killed)"
        st=137
      else
        now t1; wait $pid; st=$?
      fi
    fi
  fi
  elapsed_ms=$(((t1 - t0) / 1000))

  # ---------------------------------------------------------------- classify
  local err out sig=0 sigok=0
  read -r -d '' -N 2000000 err <"$W/.err" 2>/dev/null
  read -r -d '' -N 200000 out <"$W/.out" 2>/dev/null
  [ "$st" -gt 128 ] && sig=$((st - 128))
  [ -n "$term" ] && [ "$sig" = "$(kill -l "$termsig")" ] && sigok=1

  # crash
  if [[ "$err" =~ $CRASH_RE ]]; then add crash "stderr: ${BASH_REMATCH[0]}"; fi
  if [ -z "$term" ] && [ "$st" = 137 ] && [ "$elapsed_ms" -ge $((timeout * 1000 - 200)) ]; then
    add hang "hit the ${timeout} s time limit"
  elif [ "$sig" -gt 0 ] && [ "$sigok" = 0 ] && [[ "$has" != *" hang "* ]]; then
    local sn; sn=$(kill -l "$sig" 2>/dev/null || echo "$sig")
    if [ "$sn" = XFSZ ]; then add crash "killed by SIGXFSZ: wrote past the $((FSIZE_KB / 1024)) MiB file-size limit"
    else add crash "killed by SIG$sn"; fi
  elif [ "$sig" = 0 ] && [ "$st" -gt 2 ]; then
    add crash "exit status $st"
  fi
  # stop time after our signal
  if [ -n "$term" ] && [ "$sent" = 1 ] && [[ "$has" != *" hang "* ]] && [ "$elapsed_ms" -gt "$STOP_SLACK_MS" ]; then
    add hang "stopped ${elapsed_ms} ms after SIG$termsig (limit ${STOP_MS} ms, ${STOP_SLACK_MS} with slack)"
  fi

  # data loss
  local i after
  for i in "${!g_paths[@]}"; do
    after=$(fingerprint "${g_paths[$i]}")
    [ "$after" = "${g_before[$i]}" ] || add dataloss "${g_paths[$i]#$W/} changed: ${g_before[$i]} -> $after"
  done
  if [ -n "$mapok" ] && [ "$m_before" -ge 0 ]; then
    local mi ma; mi=$(map_info "$mapok"); ma=$(landmarks_of "$mi")
    if [ "$ma" -lt 0 ]; then add dataloss "the map held $m_before landmarks, now: $mi"
    elif [ "$ma" -lt "$m_before" ]; then add dataloss "the map shrank: $m_before -> $ma landmarks"; fi
  fi
  if [ -n "$mapsaved" ]; then
    local mi2 ma2 mt2; mi2=$(map_info "$mapsaved"); ma2=$(landmarks_of "$mi2")
    mt2=$(stat -c %Y "$mapsaved" 2>/dev/null || echo none)
    if [ "$ma2" -lt 0 ]; then add dataloss "map not saved: $mi2"
    elif [ "$mt2" = "$ms_mtime" ]; then add dataloss "map not saved (this run's places lost)"
    elif [ "$ma2" -lt "$ms_before" ]; then add dataloss "the map shrank: $ms_before -> $ma2 landmarks"; fi
  fi
  if [ -n "$linkkeep" ] && [ ! -L "$linkkeep" ]; then
    add dataloss "the symbolic link ${linkkeep#$W/} was replaced ($(fingerprint "$linkkeep"))"
  fi
  if [ -n "$preserve" ]; then
    local found=0 f
    for f in "$preserve" "$preserve".corrupt-*; do
      [ -f "$f" ] && [ "$(sha256sum <"$f" | cut -c1-16)" = "$pv_sum" ] && found=1
    done
    [ $found = 1 ] || add dataloss "the original ${preserve#$W/} is gone (not kept, not set aside)"
  fi

  # exit status and messages
  local allowed=" ${expect//|/ } " named=1 status_ok=0 first=${err%%$'\n'*}
  first=${first:0:160}
  # mention and line may list alternatives: A|B
  if [ -n "$mention" ]; then
    local m l hit=0 ms ls
    IFS='|' read -r -a ms <<<"$mention"
    IFS='|' read -r -a ls <<<"${line:-}"
    for m in "${ms[@]}"; do
      [[ "$err" == *"$m"* ]] || continue
      if [ -z "$line" ]; then hit=1; break; fi
      for l in "${ls[@]}"; do
        [[ "$err" == *"$m:$l"* || "$err" =~ (^|[^a-z])line\ $l([^0-9]|$) ]] && hit=1
      done
    done
    named=$hit
  fi
  local phrase_ok=1
  if [ -n "$phrase" ]; then
    shopt -s nocasematch
    [[ "$out$err" =~ $phrase ]] || phrase_ok=0
    shopt -u nocasematch
  fi
  local what="${mention#$W/}${line:+:$line}"
  if [ -n "$term" ]; then
    if [ "$termexit" = 0 ]; then
      if [ "$sent" = 0 ]; then add wrong_status "exited (status $st) before the signal was sent: $first"
      elif [ "$st" != 0 ] && [ "$st" != 137 ]; then add wrong_status "exit status $st after SIG$termsig (want 0: a clean stop)"; fi
    else
      case "$st" in 0|1|2|137) ;; *) [ $sigok = 1 ] || add wrong_status "exit status $st";; esac
      if { [ "$st" = 1 ] || [ "$st" = 2 ]; } && [ $named = 0 ]; then add unnamed "exit $st, stderr does not name '$what': $first"; fi
    fi
  elif [ "$st" = 0 ]; then
    if [[ "$allowed" == *" ok "* || "$allowed" == *" any "* ]]; then
      [ $phrase_ok = 1 ] || add silent_accept "exit 0 without /$phrase/ in its output"
    elif [[ "$allowed" == *" okwarn "* ]]; then
      # named (file, line), or the counter in /phrase/ when the case gives one
      [ $named = 1 ] || { [ -n "$phrase" ] && [ $phrase_ok = 1 ]; } ||
        add silent_accept "exit 0 and no word of '$what'${phrase:+ nor /$phrase/}"
    else
      add silent_accept "exit 0 (want ${expect//|/ or })"
    fi
  elif [ "$st" = 1 ] || [ "$st" = 2 ]; then
    if [[ "$allowed" == *" reject "* && "$st" = 2 ]] || [[ "$allowed" == *" fail "* || "$allowed" == *" any "* ]]; then
      status_ok=1
    elif [[ "$allowed" == *" reject "* ]]; then
      add wrong_status "exit 1 (runtime failure) for bad input (want 2)"; status_ok=1
    else
      add wrong_status "exit $st (want ${expect//|/ or }): $first"
    fi
    [ $status_ok = 1 ] && [ $named = 0 ] && add unnamed "exit $st, stderr does not name '$what': $first"
  fi

  # ---------------------------------------------------------------- report
  local class=pass detail= c
  if [ ${#classes[@]} -gt 0 ]; then
    class=; for c in $has; do class+="${class:+,}$c"; done
    detail=$(printf '%s; ' "${details[@]}"); detail=${detail%; }
  fi
  local kind=run; [ -n "$term" ] && { [ "$sent" = 1 ] && kind=signal || kind=early; }
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$prog" "$class" "$st" "$elapsed_ms" "${detail//$'\t'/ }" "$kind" >"$res"
  if [ "$class" != pass ]; then
    {
      echo "case:    $name ($prog)${note:+ -- $note}"
      echo "expect:  ${expect:-signal $termsig, exit $termexit}${mention:+, naming $mention}${line:+:$line}${phrase:+, /$phrase/}"
      echo "setup:   $setup"
      echo "command: $cmd"
      echo "result:  $class: status $st, $elapsed_ms ms; $detail"
      echo "--- stderr:"
      if [ ${#err} -gt 4000 ]; then echo "${err:0:2000}"; echo "[...]"; echo "${err: -2000}"; else echo "$err"; fi
      echo "--- stdout (head):"; echo "${out:0:1000}"
    } >"$log" 2>/dev/null
    local msg="  FAIL $name: $class (status $st, $elapsed_ms ms) $detail"
    echo "${msg:0:220}"
  fi
  cleanup_case
}

cleanup_case() {
  local p
  if [ -f "$W/.bg" ]; then
    while read -r p; do kill -KILL "$p" 2>/dev/null; done <"$W/.bg"
  fi
  cd "$OUT" || return
  if [ "$KEEP" != 1 ]; then rm -rf "$W" 2>/dev/null || { chmod -R u+rwX "$W"; rm -rf "$W"; }; fi
}

if [ "${1:-}" = run-case ]; then
  shift
  for c in "$@"; do run_case "$c"; done
fi
