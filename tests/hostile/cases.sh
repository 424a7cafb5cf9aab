# The cases. Sourced by run.sh, which calls define_cases; each `C` call
# writes one case file (see README.md, "Adding a case").
#
# Fields of C (key=value; values in single quotes are expanded when the case
# runs, with $W its scratch dir, $F the fixtures, $ECU $REPLAY $EVAL $DETECT
# $SIM the programs, $FMS/$FMF file-mode arguments of the small/full drive,
# $X the ECU's "no real-time" settings):
#   name     unique, [a-z0-9._-]; prog: ecu replay eval detect sim
#   cmd      the command (exec'd under the limits; shell=1: a bash script)
#   setup    bash run before, in $W, without limits (helpers in lib.sh);
#            exit 77 skips the case
#   expect   allowed outcomes, '|'-separated:
#              ok      exit 0 (and /phrase/ in stdout+stderr when given)
#              reject  exit 2, stderr names `mention` (and `line`)
#              fail    exit 1 or 2, stderr names `mention` (runtime failure)
#              okwarn  exit 0 with stderr naming `mention` (and `line`)
#              any     exit 0, or 1/2 naming `mention` (robustness only)
#   mention  text stderr must hold (a path, a key, an option)
#   line     line number: stderr holds "mention:line" (or "line N")
#   phrase   regex (grep -Ei) stdout+stderr must match on exit 0
#   guard    paths whose type and content must not change
#   mapok    map path that must stay a sound map and not shrink
#   mapsaved map path that must be saved (mtime moves), sound, not smaller
#   preserve path whose original bytes must survive there or as PATH.corrupt-*
#   linkkeep path that must still be a symbolic link afterwards
#   user     nobody: run as nobody (setpriv), for permission cases
#   term     signal mode: file:PATH (wait for it) or delay; the signal
#            (termsig, TERM) goes after termdelay s; termexit 0 (clean exit
#            0 wanted) or any (0, 1/2 naming `mention`, or death by it)
#   timeout  seconds (default --timeout); slow=1 runs the case early

# Numbers the generators need.
fixture_numbers() {
  HDR=$(head -1 "$F/small.y4m" | wc -c)             # header line, with its newline
  FB=$((6 + 1280 * 512))                            # "FRAME\n" + luma
  SMALL=$(stat -c %s "$F/small.y4m")
  SMALL420=$(stat -c %s "$F/small420.y4m")
  CANLINES=$(wc -l <"$F/drive/odometry.log")
  MAPBYTES=$(stat -c %s "$F/base.map")
  MKLINES=$(wc -l <"$F/drive/markings.txt")
  FRLINES=$(wc -l <"$F/drive/frames.csv")
  ECANLINES=$(wc -l <"$F/drive/ecu-can.log")
}

declare -A seen_case
C() {
  local kv name= prog= slow=0 k
  declare -A c=()
  for kv in "$@"; do c[${kv%%=*}]=${kv#*=}; done
  name=${c[name]}; prog=${c[prog]:-}
  [ -n "$name" ] && [ -n "$prog" ] && [ -n "${c[cmd]:-}" ] && [ -n "${c[expect]:-}${c[term]:-}" ] ||
    { echo "hostile: bad case definition: $*" >&2; exit 2; }
  [ -z "${seen_case[$name]:-}" ] || { echo "hostile: duplicate case name $name" >&2; exit 2; }
  seen_case[$name]=1
  [ -n "$filter" ] && ! [[ "$name" =~ $filter ]] && return 0
  slow=${c[slow]:-0}; unset 'c[slow]'
  [ -n "${c[term]:-}" ] && slow=1
  # Run order: signal and slow cases, then the slower programs, the ECU last.
  local order
  case "$slow:$prog" in 1:*) order=0 ;; *:sim) order=1 ;; *:eval) order=2 ;; *:detect) order=3 ;;
    *:replay) order=4 ;; *) order=5 ;; esac
  {
    for k in "${!c[@]}"; do printf '%s=%q\n' "$k" "${c[$k]}"; done
  } >"$OUT/cases/$order-$name.case"
  printf '%-44s %-7s %s%s%s\n' "$name" "$prog" "${c[expect]:-signal ${c[termsig]:-TERM}, exit ${c[termexit]:-0}}" \
    "${c[mention]:+ naming ${c[mention]}}${c[line]:+:${c[line]}}" "${c[phrase]:+ /${c[phrase]}/}" >>"$OUT/cases/.list"
}

# The usual bad files for one file argument. CMD holds @ where the path goes.
#   badfiles PREFIX PROG CMD VALID EMPTY_EXPECT [OK_PHRASE [all]]
# VALID: a good file for the symlink and FIFO cases; EMPTY_EXPECT: what an
# empty file (and /dev/null) should give; all: also /dev/full, a mknod'ed
# /dev/zero and a slow FIFO writer (the ECU's inputs). FIFO_EXPECT: what a
# fed FIFO should give (ok; ok|reject where a regular file is documented).
FIFO_EXPECT=ok
badfiles() {
  local pre=$1 prog=$2 cmd=$3 valid=$4 empty=$5 phrase=${6:-} all=${7:-}
  local p='$W/in'
  C name="$pre.missing" prog="$prog" expect=reject mention="$p" cmd="${cmd//@/$p}"
  C name="$pre.empty" prog="$prog" expect="$empty" mention="$p" setup=': >in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.directory" prog="$prog" expect=reject mention="$p" setup='mkdir in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.binary" prog="$prog" expect=reject mention="$p" setup='cp $F/random.bin in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.dev-zero" prog="$prog" expect=reject mention=/dev/zero cmd="${cmd//@//dev/zero}"
  C name="$pre.dev-null" prog="$prog" expect="$empty" mention=/dev/null cmd="${cmd//@//dev/null}"
  [ -n "$all" ] && C name="$pre.dev-full" prog="$prog" expect=reject mention=/dev/full cmd="${cmd//@//dev/full}"
  C name="$pre.mknod-nodev" prog="$prog" expect=reject mention="$p" setup='node in nodev' cmd="${cmd//@/$p}" guard="$p"
  [ -n "$all" ] && C name="$pre.mknod-zero" prog="$prog" expect=reject mention="$p" setup='node in zero' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.symlink" prog="$prog" expect=ok phrase="$phrase" setup="ln -s $valid in" cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.symlink-dangling" prog="$prog" expect=reject mention="$p" setup='ln -s $W/nowhere in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.symlink-loop" prog="$prog" expect=reject mention="$p" setup='ln -s in in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.unreadable" prog="$prog" expect=reject mention="$p" user=nobody \
    setup="open_scratch; cp $valid in; chmod 000 in" cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.fifo-fed" prog="$prog" expect="$FIFO_EXPECT" mention="$p" phrase="$phrase" setup="fifo_feed in $valid" cmd="${cmd//@/$p}"
  C name="$pre.fifo-no-writer" prog="$prog" term=delay termdelay=0.5 termexit=any mention="$p" \
    setup='mkfifo in' cmd="${cmd//@/$p}" guard="$p"
  C name="$pre.fifo-stalled" prog="$prog" term=file:'$W/mark' termdelay=0.5 termexit=any mention="$p" \
    setup="fifo_stall in $valid 100 \$W/mark" cmd="${cmd//@/$p}"
  [ -n "$all" ] && C name="$pre.fifo-slow-writer" prog="$prog" expect="$FIFO_EXPECT" mention="$p" phrase="$phrase" \
    setup="fifo_slow in $valid 999999999 1" cmd="${cmd//@/$p}"
  return 0
}

# Bit flips of a valid file: anything but a crash, a hang or an unnamed error.
# MENTION: what an error must name (default the file; A|B: either).
bitflips() {  # PREFIX PROG CMD VALID N NBITS [FROM TO [MENTION]]
  local pre=$1 prog=$2 cmd=$3 valid=$4 n=$5 nbits=$6 from=${7:-0} to=${8:-0} mention=${9:-'$W/in'} s
  for s in $(seq 1 "$n"); do
    C name="$pre.bitflip$s" prog="$prog" expect=any mention="$mention" \
      setup="gen bitflip $valid in $s $nbits $from $to" cmd="${cmd//@/\$W/in}"
  done
}

# ------------------------------------------------------------------ markloop
ecu_cases() {
  local k v e key
  # Controls: valid runs must pass, or nothing else means much.
  C name=ecu.control.help prog=ecu expect=ok phrase='usage: markloop' cmd='$ECU --help'
  C name=ecu.control.small prog=ecu expect=ok phrase='10 frames processed' cmd='$ECU $FMS $X'
  C name=ecu.control.full-new-map prog=ecu expect=ok mapsaved='$W/m.bin' cmd='$ECU $FMF --map $W/m.bin $X'
  C name=ecu.control.full-base-map prog=ecu expect=ok mapsaved='$W/m.bin' setup='cp $F/base.map m.bin' cmd='$ECU $FMF --map $W/m.bin $X'
  C name=ecu.control.big-map prog=ecu expect=ok mapsaved='$W/m.bin' setup='cp $F/big.map m.bin' cmd='$ECU $FMF --map $W/m.bin $X'
  C name=ecu.control.outputs prog=ecu expect=ok phrase='frames processed' \
    cmd='$ECU $FMS --can-out $W/c.log --summary $W/s.json --detections-out $W/d.csv --landmarks-out $W/l.csv $X'
  C name=ecu.control.sigterm-realtime prog=ecu term=delay termdelay=1.5 termexit=0 mapsaved='$W/m.bin' \
    setup='cp $F/base.map m.bin' cmd='$ECU $FMF --realtime --map $W/m.bin $X'

  # ---- options used wrongly
  C name=ecu.opt.unknown prog=ecu expect=reject mention=--frobnicate cmd='$ECU --frobnicate'
  C name=ecu.opt.stray prog=ecu expect=reject mention=stray cmd='$ECU $FMS stray $X'
  C name=ecu.opt.half-file-mode prog=ecu expect=reject mention=--can-in cmd='$ECU --camera-file $F/small.y4m $X'
  C name=ecu.opt.config-twice prog=ecu expect=reject mention='$W/none.conf' cmd='$ECU --config $F/file-mode.conf --config $W/none.conf $X'
  for k in --config --camera-device --camera-file --can-interface --can-in --can-out --calibration --map \
           --detections-out --landmarks-out --k --first-frame --frames --summary --set; do
    C name="ecu.opt.no-value${k}" prog=ecu expect=reject mention="$k" cmd="\$ECU \$FMS \$X $k"
  done
  C name=ecu.opt.value-is-option prog=ecu expect=reject mention=--map cmd='$ECU $FMS --map --quiet $X'
  C name=ecu.opt.set-no-equals prog=ecu expect=reject mention=engine.k cmd='$ECU --set engine.k --print-config'
  C name=ecu.opt.set-empty-key prog=ecu expect=reject mention=--set cmd='$ECU --set =4 --print-config'
  C name=ecu.opt.set-unknown-key prog=ecu expect=reject mention=nonesuch cmd='$ECU --set nonesuch=1 --print-config'
  C name=ecu.opt.set-empty-value prog=ecu expect=reject mention=engine.k cmd='$ECU --set engine.k= --print-config'
  C name=ecu.opt.set-two-equals prog=ecu expect=reject mention=engine.k cmd='$ECU --set engine.k=4=5 --print-config'
  C name=ecu.opt.format-rgb prog=ecu expect=reject mention=camera.format cmd='$ECU --set camera.format=rgb --print-config'
  for v in 0 1 99 -4 2147483648 nan 1e308 4.5; do
    C name="ecu.opt.k=$v" prog=ecu expect=reject mention=engine.k cmd="\$ECU \$FMS \$X --k $v"
  done
  for v in -1 nan 1e308 18446744073709551616 x; do
    C name="ecu.opt.frames=$v" prog=ecu expect=reject mention=frames cmd="\$ECU \$FMS \$X --frames $v"
    C name="ecu.opt.first-frame=$v" prog=ecu expect=reject mention=first_frame cmd="\$ECU \$FMS \$X --first-frame $v"
  done
  C name=ecu.opt.first-frame-beyond-end prog=ecu expect='okwarn|reject' mention='small.y4m' \
    cmd='$ECU $FMS $X --first-frame 1000000'
  # Every numeric key with absurd numbers (parsing and ranges; --print-config).
  local ints="camera.input camera.width camera.height camera.fps camera.max_rate camera.timeout_ms camera.blind_frames
    status.period_ms odometry.timeout_ms file.first_frame file.frames realtime.priority realtime.cpu engine.k
    engine.min_observations engine.max_skipped_rows engine.max_candidates database.landmark_capacity
    database.sequence_capacity"
  local reals="observation.min_score observation.min_range_m observation.max_range_m engine.association_radius_m
    engine.commit_after_s engine.release_lag_m engine.settled_lag_m engine.row_width_m engine.max_link_m engine.distance_tolerance_m
    engine.distance_tolerance_rel engine.min_separation_m engine.min_separation_s engine.max_residual_m
    engine.max_frame_distance_m engine.max_drift_rel engine.max_drift_m engine.max_drift_yaw_deg
    engine.max_drift_yaw_deg_per_m engine.confirm_min_gap_m engine.confirm_within_m"
  for key in $ints $reals; do
    local values="nan 18446744073709551616 -1"
    [[ " ${ints//$'\n'/ } " == *" $key "* ]] && values+=" 2147483648"
    for v in $values; do
      e=reject
      [ "$v" = -1 ] && [[ " camera.input realtime.cpu engine.settled_lag_m " == *" $key "* ]] && e=ok
      [ "$v" = 2147483648 ] && [[ " file.first_frame file.frames " == *" $key "* ]] && e=ok
      C name="ecu.key.$key=$v" prog=ecu expect=$e mention="$key" cmd="\$ECU --set $key=$v --print-config"
    done
  done
  for key in map.save_on_exit file.realtime realtime.mlockall engine.confirm_loaded_places; do
    for v in maybe 2 ''; do
      C name="ecu.key.$key=${v:-empty}" prog=ecu expect=reject mention="$key" cmd="\$ECU --set '$key=$v' --print-config"
    done
  done
  # Huge capacities: a clear refusal (or a run within the memory limit), never bad_alloc.
  C name=ecu.capacity.landmarks-2^30 prog=ecu expect='ok|reject' mention=landmark_capacity mapok='$W/m.bin' \
    setup='cp $F/base.map m.bin' cmd='$ECU $FMS --map $W/m.bin $X --set database.landmark_capacity=1073741824'
  C name=ecu.capacity.sequences-2^30 prog=ecu expect='ok|reject' mention=sequence_capacity mapok='$W/m.bin' \
    setup='cp $F/base.map m.bin' cmd='$ECU $FMS --map $W/m.bin $X --set database.sequence_capacity=1073741824'
  C name=ecu.capacity.both-2^30 prog=ecu expect='ok|reject' mention=capacity \
    cmd='$ECU $FMS $X --set database.sequence_capacity=1073741824 --set database.landmark_capacity=1073741824'
  C name=ecu.capacity.landmarks-2^30-print prog=ecu expect='ok|reject' mention=landmark_capacity \
    cmd='$ECU --set database.landmark_capacity=1073741824 --print-config'
  C name=ecu.capacity.k10-2^30 prog=ecu expect='ok|reject' mention=capacity \
    cmd='$ECU $FMS $X --k 10 --set database.sequence_capacity=1073741824'

  # ---- --config FILE
  badfiles ecu.config ecu '$ECU --config @ --print-config $X' '$F/file-mode.conf' ok 'camera.file = ' all
  bitflips ecu.config ecu '$ECU --config @ --print-config $X' '$F/markloop.conf' 6 8
  local cfg='$ECU --config $W/in --print-config $X'
  C name=ecu.config.huge-valid prog=ecu expect='ok|reject' mention='$W/in' phrase='engine.k = 4' \
    setup='for i in $(seq 200000); do echo "# comment line $i of a long configuration file ......................"; done >in; echo "engine.k = 4" >>in' cmd="$cfg"
  C name=ecu.config.long-line prog=ecu expect=reject mention='$W/in' line=2 \
    setup='echo "engine.k = 4" >in; head -c 500000 /dev/zero | tr "\0" a >>in; echo >>in' cmd="$cfg"
  C name=ecu.config.nul-byte prog=ecu expect=reject mention='$W/in' line=2 \
    setup='printf "engine.k = 4\nengine.min_observations = 3\0\n" >in' cmd="$cfg"
  C name=ecu.config.no-value prog=ecu expect=reject mention='$W/in' line=3 \
    setup='printf "# c\nengine.k = 4\nengine.max_link_m =\n" >in' cmd="$cfg"
  C name=ecu.config.no-key prog=ecu expect=reject mention='$W/in' line=2 setup='printf "engine.k = 4\n= 5\n" >in' cmd="$cfg"
  C name=ecu.config.unknown-key prog=ecu expect=reject mention='$W/in' line=2 setup='printf "engine.k = 4\nengine.kk = 5\n" >in' cmd="$cfg"
  C name=ecu.config.nan-value prog=ecu expect=reject mention='$W/in' line=1 setup='printf "engine.max_link_m = nan\n" >in' cmd="$cfg"
  C name=ecu.config.crlf prog=ecu expect='ok|reject' mention='$W/in' phrase='engine.k = 5' \
    setup='printf "engine.k = 5\r\nengine.min_observations = 3\r\n" >in' cmd="$cfg"
  C name=ecu.config.no-final-newline prog=ecu expect=ok phrase='engine.k = 5' setup='printf "engine.k = 5" >in' cmd="$cfg"
  C name=ecu.config.duplicate-key prog=ecu expect='ok|reject' mention='$W/in' phrase='engine.k = [56]' \
    setup='printf "engine.k = 5\nengine.k = 6\n" >in' cmd="$cfg"
  C name=ecu.config.utf8-bom prog=ecu expect='ok|reject' mention='$W/in' phrase='engine.k = 5' \
    setup='printf "\xef\xbb\xbfengine.k = 5\n" >in' cmd="$cfg"
  for v in 100 1000 3000 6000; do
    C name="ecu.config.truncated-$v" prog=ecu expect=any mention='$W/in' setup="head -c $v \$F/markloop.conf >in" cmd="$cfg"
  done
  C name=ecu.config.corpus-small prog=ecu expect=any mention=small.conf \
    cmd='$ECU --config $REPO/tests/fuzz/corpus/ecu_config/small.conf --print-config $X'

  # ---- --camera-file FILE (YUV4MPEG2)
  local cam='$ECU $FMS --camera-file @ $X'
  badfiles ecu.camera ecu "$cam" '$F/small.y4m' reject '10 frames processed' all
  cam='$ECU $FMS --camera-file $W/in --can-out $W/out.log $X'
  C name=ecu.camera.stalled-sigterm prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=0 mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; fifo_stall in \$F/drive/frames.y4m \$(($HDR + 30 * $FB)) \$W/mark" \
    cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  C name=ecu.camera.stalled-sigint prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=0 termsig=INT mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; fifo_stall in \$F/drive/frames.y4m \$(($HDR + 30 * $FB)) \$W/mark" \
    cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  C name=ecu.camera.stalled-mid-frame-sigterm prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=0 mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; fifo_stall in \$F/drive/frames.y4m \$(($HDR + 30 * $FB + 1000)) \$W/mark" \
    cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  C name=ecu.camera.stalled-header-sigterm prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=any mention='$W/in' mapok='$W/m.bin' \
    setup="cp \$F/base.map m.bin; fifo_stall in \$F/small.y4m 20 \$W/mark" \
    cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  C name=ecu.camera.no-writer-sigterm-map prog=ecu term=delay termdelay=0.5 termexit=any mention='$W/in' mapok='$W/m.bin' \
    setup='cp $F/base.map m.bin; mkfifo in' cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  C name=ecu.camera.420-file prog=ecu expect=ok phrase='10 frames processed' cmd='$ECU $FMS --camera-file $F/small420.y4m $X'
  C name=ecu.camera.420-fifo prog=ecu expect=ok phrase='10 frames processed' setup='fifo_feed in $F/small420.y4m' cmd="$cam"
  C name=ecu.camera.420-pipe prog=ecu expect=ok phrase='10 frames processed' shell=1 \
    cmd='cat $F/small420.y4m | $ECU $FMS --camera-file /dev/stdin $X'
  C name=ecu.camera.mono-pipe prog=ecu expect=ok phrase='10 frames processed' shell=1 \
    cmd='cat $F/small.y4m | $ECU $FMS --camera-file /dev/stdin $X'
  C name=ecu.camera.420-pipe-truncated prog=ecu expect=reject mention=/dev/stdin shell=1 \
    cmd="head -c \$(($SMALL420 - 5000)) \$F/small420.y4m | \$ECU \$FMS --camera-file /dev/stdin \$X"
  C name=ecu.camera.420-pipe-slow prog=ecu expect=ok phrase='10 frames processed' shell=1 \
    cmd='{ head -c 3000000 $F/small420.y4m; sleep 1; tail -c +3000001 $F/small420.y4m; } | $ECU $FMS --camera-file /dev/stdin $X'
  # Header lines (3 frames each).
  local h
  local -a headers=(
    "slow-rate|reject|W1280 H512 F1:99999999 Ip A1:1 Cmono"
    "rate-0|reject|W1280 H512 F0:1 Ip A1:1 Cmono"
    "rate-den-0|reject|W1280 H512 F1:0 Ip A1:1 Cmono"
    "fast-rate|reject|W1280 H512 F99999999:1 Ip A1:1 Cmono"
    "rate-negative|reject|W1280 H512 F-10:1 Ip A1:1 Cmono"
    "rate-den-negative|reject|W1280 H512 F10:-1 Ip A1:1 Cmono"
    "rate-word|reject|W1280 H512 Fx:y Ip A1:1 Cmono"
    "rate-no-colon|reject|W1280 H512 F10 Ip A1:1 Cmono"
    "rate-int-max|reject|W1280 H512 F2147483647:1 Ip A1:1 Cmono"
    "rate-int-overflow|reject|W1280 H512 F2147483648:1 Ip A1:1 Cmono"
    "rate-tiny|reject|W1280 H512 F1:2147483647 Ip A1:1 Cmono"
    "rate-ntsc|ok|W1280 H512 F30000:1001 Ip A1:1 Cmono"
    "width-off-by-one|reject|W1279 H512 F10:1 Ip A1:1 Cmono"
    "width-0|reject|W0 H512 F10:1 Ip A1:1 Cmono"
    "width-negative|reject|W-1280 H512 F10:1 Ip A1:1 Cmono"
    "width-huge|reject|W99999999 H512 F10:1 Ip A1:1 Cmono"
    "width-2^31|reject|W2147483648 H512 F10:1 Ip A1:1 Cmono"
    "height-0|reject|W1280 H0 F10:1 Ip A1:1 Cmono"
    "height-huge|reject|W1280 H99999999 F10:1 Ip A1:1 Cmono"
    "no-width|reject|H512 F10:1 Ip A1:1 Cmono"
    "no-height|reject|W1280 F10:1 Ip A1:1 Cmono"
    "magic-only|reject|"
    "chroma-411|reject|W1280 H512 F10:1 Ip A1:1 C411"
    "chroma-420-on-mono-data|reject|W1280 H512 F10:1 Ip A1:1 C420jpeg"
    "chroma-444-on-mono-data|reject|W1280 H512 F10:1 Ip A1:1 C444"
    "interlaced|reject|W1280 H512 F10:1 It A1:1 Cmono"
    "interlaced-mixed|reject|W1280 H512 F10:1 Im A1:1 Cmono"
    "extension|ok|W1280 H512 F10:1 Ip A1:1 Cmono XYSCSS=MONO XCOLORRANGE=FULL"
    "double-space|ok|W1280  H512 F10:1 Ip A1:1 Cmono"
    "duplicate-rate|any|W1280 H512 F10:1 F1:99999999 Ip A1:1 Cmono"
    "empty-tag|any|W1280 H512 F10:1 Ip A1:1 Cmono X"
  )
  for h in "${headers[@]}"; do
    IFS='|' read -r k e v <<<"$h"
    C name="ecu.camera.header.$k" prog=ecu expect="$e" mention='$W/in' phrase='3 frames processed' \
      setup="gen y4m-header \$F/small.y4m in 'YUV4MPEG2${v:+ $v}' 3" cmd="$cam"
  done
  C name=ecu.camera.header.slow-rate-realtime prog=ecu expect=reject mention='$W/in' \
    setup="gen y4m-header \$F/small.y4m in 'YUV4MPEG2 W1280 H512 F1:99999999 Ip A1:1 Cmono' 3" cmd="$cam --realtime"
  C name=ecu.camera.header.wrong-magic prog=ecu expect=reject mention='$W/in' \
    setup="gen y4m-header \$F/small.y4m in 'YUV4MPEG3 W1280 H512 F10:1 Ip A1:1 Cmono' 3" cmd="$cam"
  C name=ecu.camera.header.glued-magic prog=ecu expect=reject mention='$W/in' \
    setup="gen y4m-header \$F/small.y4m in 'YUV4MPEG2W1280 H512 F10:1 Ip A1:1 Cmono' 3" cmd="$cam"
  C name=ecu.camera.header.too-long prog=ecu expect=reject mention='$W/in' \
    setup="gen y4m-header \$F/small.y4m in \"YUV4MPEG2 W1280 H512 F10:1 Ip A1:1 Cmono X\$(head -c 5000 /dev/zero | tr '\\0' a)\" 3" cmd="$cam"
  C name=ecu.camera.header.no-newline prog=ecu expect=reject mention='$W/in' \
    setup='printf "YUV4MPEG2 W1280 H512 F10:1 Ip A1:1 Cmono" >in' cmd="$cam"
  C name=ecu.camera.header-only prog=ecu expect='ok|reject' mention='$W/in' phrase='0 frames processed' \
    setup="head -c $HDR \$F/small.y4m >in" cmd="$cam"
  # The last frame cut short, and damaged FRAME lines.
  for v in 1 1000 $((FB - 6)) $((FB - 3)); do
    C name="ecu.camera.truncated-last-frame-$v" prog=ecu expect=reject mention='$W/in' \
      setup="gen y4m-truncate \$F/small.y4m in $v" cmd="$cam"
  done
  C name=ecu.camera.whole-frames-only prog=ecu expect=ok phrase='9 frames processed' \
    setup="gen y4m-truncate \$F/small.y4m in $FB" cmd="$cam"
  C name=ecu.camera.truncated-last-frame-map prog=ecu expect=reject mention='$W/in' mapsaved='$W/m.bin' slow=1 \
    setup="cp \$F/base.map m.bin; gen y4m-truncate \$F/drive/frames.y4m in 1000" \
    cmd='$ECU $FMF --camera-file $W/in --map $W/m.bin $X'
  local -a tags=("framx|FRAMX" "empty||" "junk|#####" "long|FRAME X$(printf 'a%.0s' $(seq 1 3000))" "frame-lower|frame")
  for h in "${tags[@]}"; do
    IFS='|' read -r k v <<<"$h"
    C name="ecu.camera.frame-tag-$k" prog=ecu expect=reject mention='$W/in' setup="gen y4m-frametag \$F/small.y4m in 3 '$v'" cmd="$cam"
  done
  C name=ecu.camera.frame-tag-params prog=ecu expect=ok phrase='10 frames processed' \
    setup="gen y4m-frametag \$F/small.y4m in 3 'FRAME Ip XFOO=1'" cmd="$cam"
  bitflips ecu.camera.header ecu "$cam" '$F/small.y4m' 6 1 0 "$HDR"
  bitflips ecu.camera.frame-tags ecu "$cam" '$F/small.y4m' 4 1 $((HDR + 3 * FB)) $((HDR + 3 * FB + 6))
  bitflips ecu.camera.anywhere ecu "$cam" '$F/small.y4m' 3 64

  # ---- --can-in FILE (candump -l)
  local can='$ECU $FMF --can-in @ $X'
  badfiles ecu.can ecu "$can" '$F/drive/odometry.log' any 'odometry [1-9][0-9]* accepted' all
  can='$ECU $FMF --can-in $W/in --map $W/m.bin $X'
  local acc='odometry [1-9][0-9]* accepted'
  C name=ecu.can.stalled-sigterm prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=0 mapsaved='$W/m.bin' \
    setup='cp $F/base.map m.bin; mkfifo in; { head -n 200 $F/drive/odometry.log; : >$W/mark; exec sleep 600; } >in 2>/dev/null & bg_pid $!' cmd="$can"
  C name=ecu.can.stalled-mid-line-sigterm prog=ecu term=file:'$W/mark' termdelay=0.5 termexit=0 mapsaved='$W/m.bin' \
    setup='cp $F/base.map m.bin; mkfifo in; { head -n 200 $F/drive/odometry.log; printf "(0000000004.0"; : >$W/mark; exec sleep 600; } >in 2>/dev/null & bg_pid $!' cmd="$can"
  C name=ecu.can.epoch prog=ecu expect='ok|reject' phrase="$acc" mention='$W/in' \
    setup='gen can-shift $F/drive/odometry.log in 1733130000' cmd="$can"
  C name=ecu.can.epoch-after-first-line prog=ecu expect='ok|reject' phrase="$acc" mention='$W/in' \
    setup='gen can-shift $F/drive/odometry.log t 1733130000; head -n1 $F/drive/odometry.log >in; tail -n +2 t >>in' cmd="$can"
  C name=ecu.can.far-future-line-100 prog=ecu expect='okwarn|reject' mention='$W/in' line='100|101' \
    setup='gen can-stamp $F/drive/odometry.log in 100 4102444800' cmd="$can"
  C name=ecu.can.beyond-2262-line-100 prog=ecu expect=reject mention='$W/in' line='100|101' mapsaved='$W/m.bin' \
    setup='cp $F/base.map m.bin; gen can-stamp $F/drive/odometry.log in 100 9999999999' cmd="$can"
  C name=ecu.can.far-future-last-line prog=ecu expect='okwarn|reject' mention='$W/in' line="$CANLINES" \
    phrase='[1-9][0-9]* (log )?frames? after the last camera frame' \
    setup="gen can-stamp \$F/drive/odometry.log in $CANLINES 4102444800" cmd="$can"
  C name=ecu.can.backwards-line-200 prog=ecu expect='okwarn|reject' mention='$W/in' line='200|201' \
    setup='gen can-stamp $F/drive/odometry.log in 200 0000000001' cmd="$can"
  C name=ecu.can.malformed-last-line prog=ecu expect=reject mention='$W/in' line="$CANLINES" mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; gen can-edit \$F/drive/odometry.log in $CANLINES 'this is not candump'" cmd="$can"
  C name=ecu.can.cut-last-line prog=ecu expect=reject mention='$W/in' line="$CANLINES" mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; head -n $((CANLINES - 1)) \$F/drive/odometry.log >in; printf '(0000000014.9' >>in" cmd="$can"
  C name=ecu.can.binary-last-line prog=ecu expect=reject mention='$W/in' line="$CANLINES" mapsaved='$W/m.bin' \
    setup="cp \$F/base.map m.bin; head -n $((CANLINES - 1)) \$F/drive/odometry.log >in; head -c 40 \$F/random.bin | tr -d '\\n' >>in; echo >>in" cmd="$can"
  C name=ecu.can.no-final-newline prog=ecu expect=ok phrase="$acc" mapsaved='$W/m.bin' \
    setup='cp $F/base.map m.bin; head -c -1 $F/drive/odometry.log >in' cmd="$can"
  C name=ecu.can.long-line-50 prog=ecu expect=reject mention='$W/in' line=50 \
    setup='head -n 49 $F/drive/odometry.log >in; head -c 2000000 /dev/zero | tr "\0" 7 >>in; echo >>in; tail -n +51 $F/drive/odometry.log >>in' cmd="$can"
  C name=ecu.can.nul-line-50 prog=ecu expect=reject mention='$W/in' line=50 \
    setup='head -n 49 $F/drive/odometry.log >in; printf "(0000000000.980000) vcan0 120#00\0\n" >>in; tail -n +51 $F/drive/odometry.log >>in' cmd="$can"
  C name=ecu.can.crlf prog=ecu expect='ok|reject' mention='$W/in' line=1 phrase="$acc" \
    setup="sed 's/\$/\\r/' \$F/drive/odometry.log >in" cmd="$can"
  for v in 7 4 1 0; do
    C name="ecu.can.odometry-length-$v" prog=ecu expect=ok phrase='(wrong|bad)[ _-]?(length|dlc|size)' \
      setup="gen can-dlc \$F/drive/odometry.log in 120 $v" cmd="$can"
  done
  C name=ecu.can.odometry-length-4-every-10th prog=ecu expect=ok phrase='[1-9][0-9]* (odometry )?(frames )?(of the )?(wrong|bad)[ _-]?(length|dlc|size)|(wrong|bad)[ _-]?(length|dlc|size)[^0-9]*[1-9]' \
    setup='gen can-dlc $F/drive/odometry.log in 120 4 10' cmd="$can"
  C name=ecu.can.gap-4s prog=ecu expect=ok phrase='[1-9][0-9]* timeouts' \
    setup='sed "200,400d" $F/drive/odometry.log >in' cmd="$can"
  C name=ecu.can.every-line-twice prog=ecu expect=ok phrase='[1-9][0-9]* bad counter' \
    setup='sed p $F/drive/odometry.log >in' cmd="$can"
  C name=ecu.can.fd-frame-line-10 prog=ecu expect='ok|reject' mention='$W/in' line=10 phrase="$acc" \
    setup="gen can-edit \$F/drive/odometry.log in 10 '(0000000000.190000) vcan0 123##10011223344556677'" cmd="$can"
  C name=ecu.can.rtr-frame-line-10 prog=ecu expect='ok|reject' mention='$W/in' line=10 phrase="$acc" \
    setup="gen can-edit \$F/drive/odometry.log in 10 '(0000000000.190000) vcan0 123#R'" cmd="$can"
  C name=ecu.can.error-frame-line-10 prog=ecu expect='ok|reject' mention='$W/in' line=10 phrase="$acc" \
    setup="gen can-edit \$F/drive/odometry.log in 10 '(0000000000.190000) vcan0 20000080#0000000000000000'" cmd="$can"
  C name=ecu.can.foreign-frames prog=ecu expect=ok phrase='[1-9][0-9]* foreign frames' \
    setup="awk '{print; print substr(\$0, 1, 19) \" vcan0 321#00\"}' \$F/drive/odometry.log >in" cmd="$can"
  C name=ecu.can.other-interface prog=ecu expect=ok phrase="$acc" setup='sed "s/ vcan0 / can1 /" $F/drive/odometry.log >in' cmd="$can"
  bitflips ecu.can ecu '$ECU $FMF --can-in @ $X' '$F/drive/odometry.log' 5 4

  # ---- --calibration FILE (OpenCV YAML)
  local cal='$ECU $FMS --calibration @ $X'
  FIFO_EXPECT='ok|reject' badfiles ecu.calibration ecu "$cal" '$F/drive/camera.yaml' reject '10 frames processed' all
  cal='$ECU $FMS --calibration $W/in $X'
  for v in seq map block; do
    C name="ecu.calibration.nested-50000-$v" prog=ecu expect=reject mention='$W/in' setup="gen nested-yaml in 50000 $v" cmd="$cal"
  done
  C name=ecu.calibration.nested-20 prog=ecu expect=any mention='$W/in' setup='gen nested-yaml in 20 seq' cmd="$cal"
  for v in 40 120 250 330 420; do
    C name="ecu.calibration.truncated-$v" prog=ecu expect=any mention='$W/in' setup="head -c $v \$F/drive/camera.yaml >in" cmd="$cal"
  done
  bitflips ecu.calibration ecu '$ECU $FMS --calibration @ $X' '$F/drive/camera.yaml' 6 2 0 0 '$W/in|small.y4m'
  local -a edits=(
    "fx-nan|s/data: \\[ 900\\./data: [ .nan/"
    "fx-inf|s/data: \\[ 900\\./data: [ .inf/"
    "fx-0|s/data: \\[ 900\\./data: [ 0./"
    "fx-negative|s/data: \\[ 900\\./data: [ -900./"
    "fx-1e308|s/data: \\[ 900\\./data: [ 1e308/"
    "width-0|s/^image_width: .*/image_width: 0/"
    "width-negative|s/^image_width: .*/image_width: -1280/"
    "width-2^31|s/^image_width: .*/image_width: 2147483647/"
    "width-mismatch|s/^image_width: .*/image_width: 1281/"
    "height-huge|s/^image_height: .*/image_height: 99999999/"
    "width-text|s/^image_width: .*/image_width: wide/"
    "mount-height-nan|s/^mount_height: .*/mount_height: .nan/"
    "mount-height-negative|s/^mount_height: .*/mount_height: -1.5/"
    "mount-height-1e308|s/^mount_height: .*/mount_height: 1e308/"
    "mount-pitch-1e308|s/^mount_pitch_deg: .*/mount_pitch_deg: 1e308/"
    "mount-pitch-90|s/^mount_pitch_deg: .*/mount_pitch_deg: 90./"
    "mount-pitch-nan|s/^mount_pitch_deg: .*/mount_pitch_deg: .nan/"
    "distortion-nan|s/data: \\[ -5.0000000000000003e-02/data: [ .nan/"
    "distortion-huge|s/data: \\[ -5.0000000000000003e-02/data: [ 1e300/"
    "matrix-rows-2|0,/rows: 3/s/rows: 3/rows: 2/"
    "matrix-cols-99|0,/cols: 3/s/cols: 3/cols: 99/"
    "matrix-rows-huge|0,/rows: 3/s/rows: 3/rows: 2147483647/"
    "matrix-dt-text|0,/dt: d/s/dt: d/dt: s/"
    "no-matrix|s/^camera_matrix:.*/nothing: 1/"
    "detector-min-score-nan|\$a detector_min_score: .nan"
    "detector-min-score-2|\$a detector_min_score: 2."
    "detector-min-score-negative|\$a detector_min_score: -1."
    "detector-region-inverted|\$a detector_x_near_m: 30.\\ndetector_x_far_m: 3."
    "detector-step-0|\$a detector_x_step_m: 0."
    "detector-step-tiny|\$a detector_x_step_m: 1e-9\\ndetector_y_step_m: 1e-9"
    "duplicate-key|\$a image_width: 640"
  )
  for h in "${edits[@]}"; do
    k=${h%%|*}; v=${h#*|}
    e='$W/in'; [[ "$k" == width-mismatch || "$k" == duplicate-key ]] && e='$W/in|small.y4m'
    C name="ecu.calibration.value-$k" prog=ecu expect=reject mention="$e" setup="sed -e '$v' \$F/drive/camera.yaml >in" cmd="$cal"
  done
  for v in broken dashes-hang matrix-rows-damaged; do
    C name="ecu.calibration.corpus-$v" prog=ecu expect=any mention="$v.yaml" \
      cmd="\$ECU \$FMS --calibration \$REPO/tests/fuzz/corpus/calibration/$v.yaml \$X"
  done

  # ---- --map FILE
  local map='$ECU $FMS --map $W/m.bin $X'   # the small drive: loading and saving are the point
  local -a corrupt=(
    "empty|: >m.bin"
    "7-bytes|printf MLOOPMA >m.bin"
    "wrong-magic|gen bitflip \$F/base.map m.bin 1 1 0 8"
    "truncated-63|head -c 63 \$F/base.map >m.bin"
    "truncated-64|head -c 64 \$F/base.map >m.bin"
    "truncated-100|head -c 100 \$F/base.map >m.bin"
    "truncated-last-byte|head -c -1 \$F/base.map >m.bin"
    "extra-byte|cp \$F/base.map m.bin; printf x >>m.bin"
    "random|cp \$F/random.bin m.bin"
    "text|echo 'my notes, not a map' >m.bin"
    "landmarks-2^40|gen map-edit \$F/base.map m.bin landmarks 1099511627776"
    "sequences-2^33|gen map-edit \$F/base.map m.bin sequences 8589934592"
    "payload-1|gen map-edit \$F/base.map m.bin payload 1"
    "landmarks-0|gen map-edit \$F/base.map m.bin landmarks 0"
  )
  for h in "${corrupt[@]}"; do
    k=${h%%|*}; v=${h#*|}
    C name="ecu.map.corrupt-$k" prog=ecu expect='ok|reject' mention='$W/m.bin' preserve='$W/m.bin' setup="$v" cmd="$map"
  done
  for v in 1 2 3 4 5 6; do
    C name="ecu.map.bitflip-header$v" prog=ecu expect='ok|reject' mention='$W/m.bin' preserve='$W/m.bin' \
      setup="gen bitflip \$F/base.map m.bin $v 1 0 64" cmd="$map"
    C name="ecu.map.bitflip-payload$v" prog=ecu expect='ok|reject' mention='$W/m.bin' preserve='$W/m.bin' \
      setup="gen bitflip \$F/base.map m.bin $v 1 64 0" cmd="$map"
  done
  C name=ecu.map.newer-version prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' \
    setup='gen map-edit $F/base.map m.bin version 99' cmd="$map"
  C name=ecu.map.other-k prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd='$ECU $FMS --map $W/m.bin --k 5 $X'
  C name=ecu.map.directory prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' setup='mkdir m.bin; touch m.bin/keep' cmd="$map"
  C name=ecu.map.fifo-no-writer prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' timeout=5 setup='mkfifo m.bin' cmd="$map"
  C name=ecu.map.fifo-fed prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' setup='fifo_feed m.bin $F/base.map' cmd="$map"
  for v in null zero full nodev; do
    C name="ecu.map.mknod-$v" prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' setup="node m.bin $v" cmd="$map"
  done
  C name=ecu.map.symlink prog=ecu expect=ok linkkeep='$W/m.bin' mapsaved='$W/real.bin' \
    setup='cp $F/base.map real.bin; ln -s real.bin m.bin' cmd="$map"
  C name=ecu.map.symlink-dangling prog=ecu expect='ok|reject' mention='$W/m.bin' linkkeep='$W/m.bin' \
    setup='ln -s real.bin m.bin' cmd="$map"
  C name=ecu.map.symlink-to-calibration prog=ecu expect=reject mention='$W/m.bin' guard='$W/cam.yaml $W/m.bin' \
    setup='cp $F/drive/camera.yaml cam.yaml; ln -s cam.yaml m.bin' cmd="$map"
  C name=ecu.map.missing-directory prog=ecu expect=fail mention='$W/no/such/m.bin' cmd='$ECU $FMS --map $W/no/such/m.bin $X'
  C name=ecu.map.unreadable prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' user=nobody \
    setup='chmod 777 .; cp $F/big.map m.bin; chmod 000 m.bin' cmd="$map"
  C name=ecu.map.read-only-directory prog=ecu expect=fail mention='$W/ro/m.bin' guard='$W/ro/m.bin' user=nobody \
    setup='mkdir ro; cp $F/big.map ro/m.bin; chmod 644 ro/m.bin; chmod 555 ro' cmd='$ECU $FMS --map $W/ro/m.bin $X'
  C name=ecu.map.new-in-read-only-directory prog=ecu expect=fail mention='$W/ro/m.bin' user=nobody \
    setup='mkdir ro; chmod 555 ro' cmd='$ECU $FMS --map $W/ro/m.bin $X'
  C name=ecu.map.smaller-landmark-capacity prog=ecu expect='ok|reject' mention='$W/m.bin' mapok='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd="$map --set database.landmark_capacity=16"
  C name=ecu.map.smaller-sequence-capacity prog=ecu expect='ok|reject' mention='$W/m.bin' mapok='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd="$map --set database.sequence_capacity=16"
  C name=ecu.map.smaller-both-capacities prog=ecu expect='ok|reject' mention='$W/m.bin' mapok='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd="$map --set database.sequence_capacity=16 --set database.landmark_capacity=16"
  C name=ecu.map.no-save-on-exit prog=ecu expect=ok guard='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd="$map --set map.save_on_exit=false"
  C name=ecu.map.same-as-can-out prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd='$ECU $FMS --map $W/m.bin --can-out $W/m.bin $X'
  C name=ecu.map.same-as-camera-file prog=ecu expect=reject mention='$W/c.y4m' guard='$W/c.y4m' \
    setup='cp $F/small.y4m c.y4m' cmd='$ECU $FMS --camera-file $W/c.y4m --map $W/c.y4m $X'
  C name=ecu.map.same-as-can-in prog=ecu expect=reject mention='$W/o.log' guard='$W/o.log' \
    setup='cp $F/drive/odometry.log o.log' cmd='$ECU $FMS --can-in $W/o.log --map $W/o.log $X'
  C name=ecu.map.same-as-calibration prog=ecu expect=reject mention='$W/cam.yaml' guard='$W/cam.yaml' \
    setup='cp $F/drive/camera.yaml cam.yaml' cmd='$ECU $FMS --calibration $W/cam.yaml --map $W/cam.yaml $X'
  C name=ecu.map.same-as-config prog=ecu expect=reject mention='$W/m.conf' guard='$W/m.conf' \
    setup='cp $F/file-mode.conf m.conf' cmd='$ECU --config $W/m.conf --map $W/m.conf $X'
  # Two ECUs on one map: the first holds it (stalled camera FIFO) while the
  # second runs a whole drive; the second should be refused, the map stay sound.
  C name=ecu.map.two-processes prog=ecu expect=reject mention='$W/m.bin' mapok='$W/m.bin' shell=1 slow=1 \
    setup="cp \$F/base.map m.bin; fifo_stall cam1 \$F/drive/frames.y4m \$(($HDR + 20 * $FB)) \$W/mark" \
    cmd='$ECU $FMF --camera-file $W/cam1 --map $W/m.bin $X 2>$W/first.err & p=$!
         for i in $(seq 500); do [ -e $W/mark ] && break; sleep 0.01; done; sleep 0.5
         $ECU $FMS --map $W/m.bin $X; st=$?
         kill -TERM $p; wait $p; echo "first markloop: exit $?" >&2; sed "s/^/first: /" $W/first.err >&2; exit $st'
  C name=ecu.map.two-processes-at-once prog=ecu expect='ok|reject' mention='$W/m.bin' mapok='$W/m.bin' shell=1 \
    setup='cp $F/base.map m.bin' \
    cmd='$ECU $FMS --map $W/m.bin $X 2>$W/first.err & p=$!
         $ECU $FMS --map $W/m.bin $X; st=$?; wait $p; st1=$?
         echo "first markloop: exit $st1" >&2; sed "s/^/first: /" $W/first.err >&2
         [ $st1 = 0 ] || [ $st = 0 ] || exit 2; exit $st'

  # ---- outputs
  local o what
  for o in can-out summary detections-out landmarks-out; do
    what='$ECU $FMS --map $W/m.bin $X --'"$o"
    C name="ecu.out.$o.mknod-full" prog=ecu expect=fail mention='$W/o' guard='$W/o' mapsaved='$W/m.bin' \
      setup='cp $F/base.map m.bin; node o full' cmd="$what \$W/o"
    C name="ecu.out.$o.dev-full" prog=ecu expect=fail mention=/dev/full guard=/dev/full user=nobody \
      setup='chmod 777 .' cmd="\$ECU \$FMS \$X --$o /dev/full"
    C name="ecu.out.$o.dev-null" prog=ecu expect=ok guard=/dev/null user=nobody cmd="\$ECU \$FMS \$X --$o /dev/null"
    C name="ecu.out.$o.directory" prog=ecu expect=fail mention='$W/o' guard='$W/o' mapok='$W/m.bin' \
      setup='cp $F/base.map m.bin; mkdir o' cmd="$what \$W/o"
    C name="ecu.out.$o.missing-directory" prog=ecu expect=fail mention='$W/no/o' cmd="\$ECU \$FMS \$X --$o \$W/no/o"
    C name="ecu.out.$o.read-only-directory" prog=ecu expect=fail mention='$W/ro/o' user=nobody \
      setup='mkdir ro; chmod 555 ro' cmd="\$ECU \$FMS \$X --$o \$W/ro/o"
  done
  C name=ecu.out.can-out-is-can-in prog=ecu expect=reject mention='$W/o.log' guard='$W/o.log' \
    setup='cp $F/drive/odometry.log o.log' cmd='$ECU $FMS --can-in $W/o.log --can-out $W/o.log $X'
  C name=ecu.out.detections-out-is-calibration prog=ecu expect=reject mention='$W/c.yaml' guard='$W/c.yaml' \
    setup='cp $F/drive/camera.yaml c.yaml' cmd='$ECU $FMS --calibration $W/c.yaml --detections-out $W/c.yaml $X'
  C name=ecu.out.landmarks-out-is-camera-file prog=ecu expect=reject mention='$W/c.y4m' guard='$W/c.y4m' \
    setup='cp $F/small.y4m c.y4m' cmd='$ECU $FMS --camera-file $W/c.y4m --landmarks-out $W/c.y4m $X'
  C name=ecu.out.summary-is-map prog=ecu expect=reject mention='$W/m.bin' guard='$W/m.bin' \
    setup='cp $F/big.map m.bin' cmd='$ECU $FMS --map $W/m.bin --set map.save_on_exit=false --summary $W/m.bin $X'
  C name=ecu.out.summary-is-config prog=ecu expect=reject mention='$W/m.conf' guard='$W/m.conf' \
    setup='cp $F/file-mode.conf m.conf' cmd='$ECU --config $W/m.conf --summary $W/m.conf $X'

  # ---- live mode (no camera, no CAN here): a clear refusal or a clean stop on SIGTERM
  for h in "camera-dev-null|--camera-device /dev/null --can-interface lo|/dev/null" \
           "camera-regular-file|--camera-device \$F/small.y4m --can-interface lo|small.y4m" \
           "camera-directory|--camera-device \$F --can-interface lo|\$F" \
           "camera-missing|--camera-device \$W/video9 --can-interface lo|\$W/video9" \
           "can-missing|--camera-device /dev/null --can-interface nosuchcan0|nosuchcan0" \
           "can-name-too-long|--camera-device /dev/null --can-interface abcdefghijklmnopqrstuvwxyz|abcdefghijklmnopqrstuvwxyz"; do
    IFS='|' read -r k v e <<<"$h"
    C name="ecu.live.$k" prog=ecu term=delay termdelay=1 termexit=any mention="$e" cmd="\$ECU $v \$X"
  done
}

# ------------------------------------------------------------------ markloop-replay
replay_cases() {
  local k v e h
  local mk='$F/drive/markings.txt' ps='$F/drive/poses.txt'
  C name=replay.control.markings prog=replay expect=ok phrase='matches' cmd="\$REPLAY --markings $mk"
  C name=replay.control.poses-truth prog=replay expect=ok phrase='matches' cmd="\$REPLAY --markings $mk --poses $ps --truth \$F/drive/frames.csv"
  C name=replay.control.sweep prog=replay expect=ok cmd="\$REPLAY --markings $mk --poses $ps --sweep 3..5"
  C name=replay.control.compat prog=replay expect=ok cmd="\$REPLAY --markings $mk --compat"
  C name=replay.opt.no-markings prog=replay expect=reject mention=--markings cmd='$REPLAY'
  C name=replay.opt.unknown prog=replay expect=reject mention=--frobnicate cmd="\$REPLAY --markings $mk --frobnicate"
  C name=replay.opt.stray prog=replay expect=reject mention=stray cmd="\$REPLAY --markings $mk stray"
  for k in --markings --poses --fps --k --abs-tol --rel-tol --min-separation --min-separation-s --max-residual \
           --association-radius --commit-after --min-observations --skip-rows --sequence-capacity \
           --landmark-capacity --out --jsonl --truth --truth-radius --sweep; do
    C name="replay.opt.no-value$k" prog=replay expect=reject mention="$k" cmd="\$REPLAY --markings $mk $k"
  done
  for k in --fps --k --abs-tol --rel-tol --min-separation --min-separation-s --max-residual --association-radius \
           --commit-after --min-observations --skip-rows --sequence-capacity --landmark-capacity --truth-radius; do
    for v in nan inf -1 18446744073709551616 2147483648; do
      e=reject
      [ "$v" = 2147483648 ] && [[ " --min-separation --min-separation-s " == *" $k "* ]] && e='ok|reject'
      C name="replay.num$k=$v" prog=replay expect="$e" mention="$k" cmd="\$REPLAY --markings $mk --truth \$F/drive/frames.csv $k $v"
    done
  done
  C name=replay.capacity.landmarks-2^30 prog=replay expect='ok|reject' mention=--landmark-capacity \
    cmd="\$REPLAY --markings $mk --landmark-capacity 1073741824"
  C name=replay.capacity.sequences-2^30 prog=replay expect='ok|reject' mention=--sequence-capacity \
    cmd="\$REPLAY --markings $mk --sequence-capacity 1073741824"
  C name=replay.capacity.landmarks-2^40 prog=replay expect='ok|reject' mention=--landmark-capacity \
    cmd="\$REPLAY --markings $mk --landmark-capacity 1099511627776"
  for v in 2..1000000 5..2 a..b 2.. ..4 2147483648..2147483649 3-5 0..0; do
    C name="replay.sweep=$v" prog=replay expect=reject mention=--sweep cmd="\$REPLAY --markings $mk --sweep $v"
  done

  # The ECU's detections CSV, placed with the drive's poses.
  local ed='$F/drive/ecu-detections.csv'
  C name=replay.control.ecu-detections prog=replay expect=ok phrase='matches' cmd="\$REPLAY --ecu-detections $ed --poses $ps"
  C name=replay.opt.ecu-detections-no-poses prog=replay expect=reject mention=--poses cmd="\$REPLAY --ecu-detections $ed"
  badfiles replay.ecu-detections replay "\$REPLAY --ecu-detections @ --poses $ps" "$ed" reject 'matches'
  bitflips replay.ecu-detections replay "\$REPLAY --ecu-detections @ --poses $ps" "$ed" 3 3
  badfiles replay.markings replay '$REPLAY --markings @' "$mk" reject 'matches' all
  badfiles replay.poses replay "\$REPLAY --markings $mk --poses @" "$ps" reject 'matches'
  badfiles replay.truth replay "\$REPLAY --markings $mk --truth @" '$F/drive/frames.csv' reject 'matches'
  bitflips replay.markings replay '$REPLAY --markings @' "$mk" 5 3
  bitflips replay.poses replay "\$REPLAY --markings $mk --poses @" "$ps" 3 3
  local r='$REPLAY --markings $W/in'
  local -a marks=(
    "count-zero|ok||printf '0\\n' >in"
    "count-too-big|reject|3/4|printf '5\\n0 1 1.5 2 stop\\n1 1 1.5 3 stop\\n' >in"
    "count-too-small|reject|3|printf '1\\n0 1 1.5 2 stop\\n1 1 1.5 3 stop\\n' >in"
    "count-negative|reject|1|printf -- '-1\\n0 1 1.5 2 stop\\n' >in"
    "count-2^64|reject|1|printf '18446744073709551616\\n0 1 1.5 2 stop\\n' >in"
    "count-2^62|reject|3/4|printf '4611686018427387904\\n0 1 1.5 2 stop\\n1 1 1.5 2 stop\\n' >in"
    "count-1e308|reject|1|printf '1e308\\n0 1 1.5 2 stop\\n' >in"
    "count-nan|reject|1|printf 'nan\\n0 1 1.5 2 stop\\n' >in"
    "frame-int-max|any|3|printf '2\\n0 1 1.5 2 stop\\n2147483647 1 1.5 3 stop\\n' >in"
    "frame-2^31|any|3|printf '2\\n0 1 1.5 2 stop\\n2147483648 1 1.5 3 stop\\n' >in"
    "frame-2^64|reject|3|printf '2\\n0 1 1.5 2 stop\\n18446744073709551616 1 1.5 3 stop\\n' >in"
    "frame-negative|reject|3|printf '2\\n0 1 1.5 2 stop\\n-5 1 1.5 3 stop\\n' >in"
    "frame-fraction|reject|3|printf '2\\n0 1 1.5 2 stop\\n1.5 1 1.5 3 stop\\n' >in"
    "frame-1e308|reject|3|printf '2\\n0 1 1.5 2 stop\\n1e308 1 1.5 3 stop\\n' >in"
    "frames-backwards|okwarn|3|printf '2\\n5 1 1.5 2 stop\\n1 1 1.5 3 stop\\n' >in"
    "x-nan|reject|3|printf '2\\n0 1 1.5 2 stop\\n1 nan 1.5 3 stop\\n' >in"
    "x-inf|reject|3|printf '2\\n0 1 1.5 2 stop\\n1 inf 1.5 3 stop\\n' >in"
    "x-1e308|reject|3|printf '2\\n0 1 1.5 2 stop\\n1 1e308 1.5 3 stop\\n' >in"
    "z-nan|reject|3|printf '2\\n0 1 1.5 2 stop\\n1 1 1.5 nan stop\\n' >in"
    "z-1e12|any|3|printf '2\\n0 1 1.5 2 stop\\n1 1 1.5 1e12 stop\\n' >in"
    "label-unknown|any|3|printf '2\\n0 1 1.5 2 stop\\n1 1 1.5 3 zebra\\n' >in"
    "label-missing|reject|3/4|printf '2\\n0 1 1.5 2 stop\\n1 1 1.5 3\\n' >in"
    "extra-field|reject|3|printf '2\\n0 1 1.5 2 stop\\n1 1 1.5 3 stop extra\\n' >in"
    "text-count|reject|1|printf 'many\\n0 1 1.5 2 stop\\n' >in"
    "crlf|any|1|sed 's/\$/\\r/' \$F/drive/markings.txt >in"
    "cut-mid-record|reject|$MKLINES/$((MKLINES + 1))|sed '\$s/ [^ ]* [^ ]*\$//' \$F/drive/markings.txt >in"
    "no-final-newline|ok||head -c -1 \$F/drive/markings.txt >in"
    "long-line|reject|2|printf '2\\n0 1 1.5 2 ' >in; head -c 3000000 /dev/zero | tr '\\0' a >>in; printf '\\n1 1 1.5 3 stop\\n' >>in"
    "nul-byte|reject|2|printf '2\\n0 1 1.5\\0 2 stop\\n1 1 1.5 3 stop\\n' >in"
  )
  for h in "${marks[@]}"; do
    IFS='|' read -r k e v h <<<"$h"
    C name="replay.markings.$k" prog=replay expect="$e" mention='$W/in' line="${v//\//|}" setup="$h" cmd="$r"
  done
  C name=replay.markings.frame-int-max-with-poses prog=replay expect=reject mention='$W/in|poses.txt' \
    setup="printf '2\\n0 1 1.5 2 stop\\n2147483647 1 1.5 3 stop\\n' >in" cmd="$r --poses $ps"
  C name=replay.markings.frame-int-max-fps prog=replay expect=any mention='$W/in' \
    setup="printf '2\\n0 1 1.5 2 stop\\n2147483647 1 1.5 3 stop\\n' >in" cmd="$r --fps 1000000"
  C name=replay.markings.frame-int-max-truth prog=replay expect=reject mention='$W/in' \
    setup="printf '2\\n0 1 1.5 2 stop\\n2147483647 1 1.5 3 stop\\n' >in" cmd="$r --truth \$F/drive/frames.csv"
  C name=replay.markings.frame-int-max-compat prog=replay expect=any mention='$W/in' \
    setup="printf '2\\n0 1 1.5 2 stop\\n2147483647 1 1.5 3 stop\\n' >in" cmd="$r --compat"
  local p="\$REPLAY --markings $mk --poses \$W/in"
  C name=replay.poses.11-numbers prog=replay expect=reject mention='$W/in' line=2 \
    setup='head -n1 $F/drive/poses.txt >in; echo "1 0 0 5 0 1 0 0 0 0 1" >>in; tail -n +3 $F/drive/poses.txt >>in' cmd="$p"
  C name=replay.poses.nan prog=replay expect=reject mention='$W/in' line=3 \
    setup='sed "3s/^[^ ]*/nan/" $F/drive/poses.txt >in' cmd="$p"
  C name=replay.poses.too-few prog=replay expect=reject mention='$W/in' setup='head -n 20 $F/drive/poses.txt >in' cmd="$p"
  C name=replay.poses.jump-1e7 prog=replay expect='ok|reject' mention='$W/in' \
    setup='awk "NR>75{\$4+=1e7} {print}" $F/drive/poses.txt >in' cmd="$p"
  C name=replay.poses.jump-1e12 prog=replay expect='ok|reject' mention='$W/in' \
    setup='awk "NR>75{\$4+=1e12} {print}" $F/drive/poses.txt >in' cmd="$p"
  C name=replay.poses.far-1e12-all prog=replay expect='ok|reject' mention='$W/in' \
    setup='awk "{\$4+=1e12; \$12+=1e12} {print}" $F/drive/poses.txt >in' cmd="$p"
  C name=replay.poses.tum-instead prog=replay expect=reject mention='$W/in' line=1 \
    setup='awk "{print NR/10, \$4, \$8, \$12, 0, 0, 0, 1}" $F/drive/poses.txt >in' cmd="$p"
  C name=replay.truth.wrong-frame prog=replay expect=reject mention='$W/in' line=3 \
    setup='sed "3s/^1,/7,/" $F/drive/frames.csv >in' cmd="\$REPLAY --markings $mk --truth \$W/in"
  C name=replay.truth.too-few prog=replay expect=reject mention='$W/in' \
    setup='head -n 20 $F/drive/frames.csv >in' cmd="\$REPLAY --markings $mk --truth \$W/in"
  C name=replay.truth.radius-nan prog=replay expect=reject mention=--truth-radius \
    cmd="\$REPLAY --markings $mk --truth \$F/drive/frames.csv --truth-radius nan"
  local o
  for o in out jsonl; do
    # m.txt: the drive's markings driven twice (the second lap 200 frames later): 5 matches to write.
    C name="replay.out.$o.mknod-full" prog=replay expect=fail mention='$W/o' guard='$W/o' \
      setup='node o full; { echo $((2 * $(head -n1 $F/drive/markings.txt))); tail -n +2 $F/drive/markings.txt; awk "NR>1{\$1+=200; print}" $F/drive/markings.txt; } >m.txt' \
      cmd="\$REPLAY --markings \$W/m.txt --$o \$W/o"
    C name="replay.out.$o.dev-full" prog=replay expect=fail mention=/dev/full guard=/dev/full user=nobody \
      setup='{ echo $((2 * $(head -n1 $F/drive/markings.txt))); tail -n +2 $F/drive/markings.txt; awk "NR>1{\$1+=200; print}" $F/drive/markings.txt; } >m.txt' \
      cmd="\$REPLAY --markings \$W/m.txt --$o /dev/full"
    C name="replay.out.$o.directory" prog=replay expect=fail mention='$W/o' guard='$W/o' setup='mkdir o' cmd="\$REPLAY --markings $mk --$o \$W/o"
    C name="replay.out.$o.missing-directory" prog=replay expect=fail mention='$W/no/o' cmd="\$REPLAY --markings $mk --$o \$W/no/o"
    C name="replay.out.$o.read-only-directory" prog=replay expect=fail mention='$W/ro/o' user=nobody \
      setup='mkdir ro; chmod 555 ro' cmd="\$REPLAY --markings $mk --$o \$W/ro/o"
  done
  C name=replay.out.out-is-markings prog=replay expect=reject mention='$W/m.txt' guard='$W/m.txt' \
    setup='cp $F/drive/markings.txt m.txt' cmd='$REPLAY --markings $W/m.txt --out $W/m.txt'
  C name=replay.out.jsonl-is-poses prog=replay expect=reject mention='$W/p.txt' guard='$W/p.txt' \
    setup='cp $F/drive/poses.txt p.txt' cmd="\$REPLAY --markings $mk --poses \$W/p.txt --jsonl \$W/p.txt"
  C name=replay.out.out-is-truth prog=replay expect=reject mention='$W/t.csv' guard='$W/t.csv' \
    setup='cp $F/drive/frames.csv t.csv' cmd="\$REPLAY --markings $mk --truth \$W/t.csv --out \$W/t.csv"
}

# ------------------------------------------------------------------ markloop-eval
eval_cases() {
  local f k v e h
  local ev='$EVAL $W/d --svg $W/o.svg --png $W/o.png'
  local cp='cp -r $F/eval d'
  C name=eval.control prog=eval expect=ok phrase='precision' setup="$cp" cmd="$ev"
  C name=eval.control.json prog=eval expect=ok setup="$cp" cmd="$ev --json \$W/o.json"
  C name=eval.opt.no-dir prog=eval expect=reject mention=DIR cmd='$EVAL'
  C name=eval.opt.unknown prog=eval expect=reject mention=--frobnicate setup="$cp" cmd="$ev --frobnicate"
  C name=eval.opt.two-dirs prog=eval expect=reject mention='$W/d' setup="$cp" cmd="$ev \$W/d"
  for k in --can --detections --landmarks --tolerance --svg --png --json; do
    C name="eval.opt.no-value$k" prog=eval expect=reject mention="$k" setup="$cp" cmd="$ev $k"
  done
  for v in nan inf -1 0 1e308 x; do
    C name="eval.tolerance=$v" prog=eval expect=reject mention=--tolerance setup="$cp" cmd="$ev --tolerance $v"
  done
  C name=eval.dir.missing prog=eval expect=reject mention='$W/d' cmd="$ev"
  C name=eval.dir.is-file prog=eval expect=reject mention='$W/d' setup='echo x >d' cmd="$ev"
  C name=eval.dir.empty prog=eval expect=reject mention='$W/d' setup='mkdir d' cmd="$ev"
  C name=eval.dir.dev-null prog=eval expect=reject mention=/dev/null cmd='$EVAL /dev/null --svg $W/o.svg --png $W/o.png'
  C name=eval.dir.unreadable prog=eval expect=reject mention='$W/d' user=nobody \
    setup="open_scratch; $cp; chmod 000 d" cmd="$ev"
  C name=eval.dir.outputs-default prog=eval expect=ok guard='$W/d/frames.csv' setup="$cp" cmd='$EVAL $W/d'
  local -A valid=([frames.csv]='$F/eval/frames.csv' [markings.csv]='$F/eval/markings.csv' [visible.csv]='$F/eval/visible.csv')
  for f in frames.csv markings.csv visible.csv; do
    local t="\$W/d/$f"
    C name="eval.$f.missing" prog=eval expect=reject mention="$t" setup="$cp; rm d/$f" cmd="$ev"
    C name="eval.$f.empty" prog=eval expect=reject mention="$t" setup="$cp; : >d/$f" cmd="$ev"
    C name="eval.$f.header-only" prog=eval expect='ok|reject' mention="$t" setup="$cp; head -n1 ${valid[$f]} >d/$f" cmd="$ev"
    C name="eval.$f.binary" prog=eval expect=reject mention="$t" line=1 setup="$cp; cp \$F/random.bin d/$f" cmd="$ev"
    C name="eval.$f.directory" prog=eval expect=reject mention="$t" setup="$cp; rm d/$f; mkdir d/$f" cmd="$ev"
    C name="eval.$f.dev-zero" prog=eval expect=reject mention="$t" setup="$cp; rm d/$f; ln -s /dev/zero d/$f" cmd="$ev"
    C name="eval.$f.fifo-fed" prog=eval expect=ok phrase='precision' setup="$cp; rm d/$f; fifo_feed d/$f ${valid[$f]}" cmd="$ev"
    C name="eval.$f.fifo-no-writer" prog=eval term=delay termdelay=0.5 termexit=any mention="$t" setup="$cp; rm d/$f; mkfifo d/$f" cmd="$ev"
    C name="eval.$f.unreadable" prog=eval expect=reject mention="$t" user=nobody setup="open_scratch; $cp; chmod 000 d/$f" cmd="$ev"
    C name="eval.$f.cut-mid-line" prog=eval expect=reject mention="$t" setup="$cp; head -c -9 ${valid[$f]} >d/$f" cmd="$ev"
    C name="eval.$f.nan" prog=eval expect=reject mention="$t" line=3 setup="$cp; sed '3s/,[^,]*\$/,nan/' ${valid[$f]} >d/$f" cmd="$ev"
    C name="eval.$f.1e308" prog=eval expect=reject mention="$t" line=3 setup="$cp; sed '3s/,[^,]*\$/,1e308/' ${valid[$f]} >d/$f" cmd="$ev"
    C name="eval.$f.extra-column" prog=eval expect=reject mention="$t" line=4 setup="$cp; sed '4s/\$/,7/' ${valid[$f]} >d/$f" cmd="$ev"
    C name="eval.$f.long-line" prog=eval expect=reject mention="$t" line=3 \
      setup="$cp; { head -n2 ${valid[$f]}; head -c 3000000 /dev/zero | tr '\\0' 7; echo; tail -n +4 ${valid[$f]}; } >d/$f" cmd="$ev"
    C name="eval.$f.crlf" prog=eval expect='ok|reject' mention="$t" setup="$cp; sed 's/\$/\\r/' ${valid[$f]} >d/$f" cmd="$ev"
    for v in 1 2 3; do
      C name="eval.$f.bitflip$v" prog=eval expect=any mention="$t" setup="$cp; gen bitflip ${valid[$f]} d/$f $v 3" cmd="$ev"
    done
  done
  C name=eval.frames.csv.jump-1e7 prog=eval expect='ok|reject' mention='$W/d/frames.csv' \
    setup="$cp; awk -F, -v OFS=, 'NR>75{\$3+=1e7} {print}' \$F/eval/frames.csv >d/frames.csv" cmd="$ev"
  C name=eval.frames.csv.jump-1e12 prog=eval expect='ok|reject' mention='$W/d/frames.csv' \
    setup="$cp; awk -F, -v OFS=, 'NR>75{\$3+=1e12} {print}' \$F/eval/frames.csv >d/frames.csv" cmd="$ev"
  C name=eval.frames.csv.frame-int-max prog=eval expect='ok|reject' mention='$W/d/frames.csv' \
    setup="$cp; sed '\$s/^[0-9]*,/2147483647,/' \$F/eval/frames.csv >d/frames.csv" cmd="$ev"
  C name=eval.markings.csv.far-away-1e12 prog=eval expect='ok|reject' mention='$W/d/markings.csv' \
    setup="$cp; awk -F, -v OFS=, 'NR==5{\$3=1e12} {print}' \$F/eval/markings.csv >d/markings.csv" cmd="$ev"
  # The ECU's outputs.
  local c='$W/d/ecu-can.log'
  C name=eval.can.missing-explicit prog=eval expect=reject mention='$W/none.log' setup="$cp" cmd="$ev --can \$W/none.log"
  C name=eval.can.missing-default prog=eval expect=reject mention="$c" setup="$cp; rm d/ecu-can.log" cmd="$ev"
  C name=eval.can.empty prog=eval expect='ok|reject' mention="$c" setup="$cp; : >d/ecu-can.log" cmd="$ev"
  C name=eval.can.binary prog=eval expect=reject mention="$c" line=1 setup="$cp; cp \$F/random.bin d/ecu-can.log" cmd="$ev"
  C name=eval.can.dev-zero prog=eval expect=reject mention=/dev/zero setup="$cp" cmd="$ev --can /dev/zero"
  C name=eval.can.directory prog=eval expect=reject mention="$c" setup="$cp; rm d/ecu-can.log; mkdir d/ecu-can.log" cmd="$ev"
  C name=eval.can.fifo-no-writer prog=eval term=delay termdelay=0.5 termexit=any mention="$c" setup="$cp; rm d/ecu-can.log; mkfifo d/ecu-can.log" cmd="$ev"
  C name=eval.can.epoch prog=eval expect='okwarn|reject' mention="$c" \
    setup="$cp; gen can-shift \$F/eval/ecu-can.log d/ecu-can.log 1733130000" cmd="$ev"
  C name=eval.can.far-future-line-100 prog=eval expect='okwarn|reject' mention="$c" line='100|101' \
    setup="$cp; gen can-stamp \$F/eval/ecu-can.log d/ecu-can.log 100 4102444800" cmd="$ev"
  C name=eval.can.malformed-last-line prog=eval expect=reject mention="$c" line="$ECANLINES" \
    setup="$cp; gen can-edit \$F/eval/ecu-can.log d/ecu-can.log $ECANLINES 'not candump'" cmd="$ev"
  C name=eval.can.cut-last-line prog=eval expect='okwarn|reject' mention="$c" line="$ECANLINES" \
    setup="$cp; head -c -7 \$F/eval/ecu-can.log >d/ecu-can.log" cmd="$ev"
  C name=eval.can.wrong-length prog=eval expect='okwarn|reject' mention="$c" \
    setup="$cp; gen can-dlc \$F/eval/ecu-can.log d/ecu-can.log 2B0 5" cmd="$ev"
  C name=eval.can.odometry-log-instead prog=eval expect='okwarn|reject' mention="$c" \
    setup="$cp; cp \$F/drive/odometry.log d/ecu-can.log" cmd="$ev"
  for v in 1 2 3 4; do
    C name="eval.can.bitflip$v" prog=eval expect=any mention="$c" setup="$cp; gen bitflip \$F/eval/ecu-can.log d/ecu-can.log $v 3" cmd="$ev"
  done
  for f in detections landmarks; do
    local t="\$W/d/ecu-$f.csv"
    C name="eval.$f.missing-explicit" prog=eval expect=reject mention='$W/none.csv' setup="$cp" cmd="$ev --$f \$W/none.csv"
    C name="eval.$f.binary" prog=eval expect=reject mention="$t" line=1 setup="$cp; cp \$F/random.bin d/ecu-$f.csv" cmd="$ev"
    C name="eval.$f.nan" prog=eval expect=reject mention="$t" line=3 setup="$cp; sed '3s/,[^,]*,/,nan,/' \$F/eval/ecu-$f.csv >d/ecu-$f.csv" cmd="$ev"
    C name="eval.$f.label-unknown" prog=eval expect=reject mention="$t" line=2 setup="$cp; sed '2s/^[^,]*,[^,]*,/0,zebra,/' \$F/eval/ecu-$f.csv >d/ecu-$f.csv" cmd="$ev"
    C name="eval.$f.directory" prog=eval expect=reject mention="$t" setup="$cp; rm d/ecu-$f.csv; mkdir d/ecu-$f.csv" cmd="$ev"
    C name="eval.$f.dev-zero" prog=eval expect=reject mention=/dev/zero setup="$cp" cmd="$ev --$f /dev/zero"
  done
  local o
  for o in svg png json; do
    local base='$EVAL $W/d --svg $W/o.svg --png $W/o.png'
    C name="eval.out.$o.mknod-full" prog=eval expect=fail mention='$W/o' guard='$W/o' setup="$cp; node o full" cmd="$base --$o \$W/o"
    C name="eval.out.$o.dev-full" prog=eval expect=fail mention=/dev/full guard=/dev/full user=nobody \
      setup="open_scratch; $cp; chmod -R a+rwX d; chmod 777 ." cmd="$base --$o /dev/full"
    C name="eval.out.$o.directory" prog=eval expect=fail mention='$W/o' guard='$W/o' setup="$cp; mkdir o" cmd="$base --$o \$W/o"
    C name="eval.out.$o.missing-directory" prog=eval expect=fail mention='$W/no/o' setup="$cp" cmd="$base --$o \$W/no/o"
    C name="eval.out.$o.is-frames-csv" prog=eval expect=reject mention='$W/d/frames.csv' guard='$W/d/frames.csv' \
      setup="$cp" cmd="$base --$o \$W/d/frames.csv"
  done
  C name=eval.out.default-dir-read-only prog=eval expect=fail mention='$W/d' user=nobody \
    setup="open_scratch; $cp; chmod 555 d" cmd='$EVAL $W/d'
}

# ------------------------------------------------------------------ markloop-detect
detect_cases() {
  local k v e h
  local img='$F/ts/images/000000.png' cam='$F/ts/camera.yaml'
  C name=detect.control prog=detect expect=ok phrase='"label"' cmd="\$DETECT --camera $cam $img"
  C name=detect.control.two prog=detect expect=ok phrase='000001' cmd="\$DETECT --camera $cam $img \$F/ts/images/000001.png"
  C name=detect.control.view prog=detect expect=ok phrase='"label"' setup='mkdir v' cmd="\$DETECT --camera $cam --view \$W/v $img"
  C name=detect.control.jpeg prog=detect expect=ok cmd='$DETECT --camera $F/tiny.yaml $F/grey.jpg'
  C name=detect.opt.no-camera prog=detect expect=reject mention=--camera cmd="\$DETECT $img"
  C name=detect.opt.no-images prog=detect expect=reject mention=image cmd="\$DETECT --camera $cam"
  C name=detect.opt.unknown prog=detect expect=reject mention=--frobnicate cmd="\$DETECT --camera $cam --frobnicate $img"
  for k in --camera --min-score --view; do
    C name="detect.opt.no-value$k" prog=detect expect=reject mention="$k" cmd="\$DETECT $img $k"
  done
  for v in nan inf -1 2 1e308 x; do
    C name="detect.min-score=$v" prog=detect expect=reject mention=--min-score cmd="\$DETECT --camera $cam --min-score $v $img"
  done
  FIFO_EXPECT='ok|reject' badfiles detect.camera detect "\$DETECT --camera @ $img" "$cam" reject '"label"'
  badfiles detect.image detect "\$DETECT --camera $cam @" "$img" reject '"label"'
  for v in seq map block; do
    C name="detect.camera.nested-50000-$v" prog=detect expect=reject mention='$W/in' setup="gen nested-yaml in 50000 $v" cmd="\$DETECT --camera \$W/in $img"
  done
  C name=detect.camera.honda-on-sim-image prog=detect expect=reject mention="$img" cmd="\$DETECT --camera \$REPO/app/cameras/honda.yaml $img"
  bitflips detect.camera detect "\$DETECT --camera @ $img" "$cam" 4 2 0 0 '$W/in|000000.png'
  local d="\$DETECT --camera $cam \$W/in.png"
  C name=detect.image.text-named-png prog=detect expect=reject mention='$W/in.png' setup='echo "not an image" >in.png' cmd="$d"
  C name=detect.image.png-bomb prog=detect expect=reject mention='$W/in.png' setup='gen png-bomb in.png 60000 60000' cmd="$d"
  C name=detect.image.png-bomb-wide prog=detect expect=reject mention='$W/in.png' setup='gen png-bomb in.png 2147483647 1' cmd="$d"
  C name=detect.image.png-1x1 prog=detect expect=reject mention='$W/in.png' setup='gen png-bomb in.png 1 1' cmd="$d"
  C name=detect.image.png-camera-size-no-data prog=detect expect=reject mention='$W/in.png' setup='gen png-bomb in.png 1280 512' cmd="$d"
  for v in 100 5000 100000 300000; do
    C name="detect.image.png-truncated-$v" prog=detect expect=reject mention='$W/in.png' setup="head -c $v $img >in.png" cmd="$d"
  done
  bitflips detect.image detect "\$DETECT --camera $cam @" "$img" 4 4
  bitflips detect.image.png-header detect "\$DETECT --camera $cam @" "$img" 4 1 0 64
  C name=detect.image.corpus-truncated-jpeg prog=detect expect=reject mention=truncated.jpg \
    cmd='$DETECT --camera $F/tiny.yaml $REPO/tests/fuzz/corpus/still_image/truncated.jpg'
  C name=detect.image.corpus-wrong-size prog=detect expect=reject mention=wrong-size.png \
    cmd='$DETECT --camera $F/tiny.yaml $REPO/tests/fuzz/corpus/still_image/wrong-size.png'
  C name=detect.image.jpeg-wrong-size prog=detect expect=reject mention=grey.jpg cmd="\$DETECT --camera $cam \$F/grey.jpg"
  for v in 1 2 3 4; do
    C name="detect.image.jpeg-bitflip$v" prog=detect expect=any mention='$W/in' setup="gen bitflip \$F/grey.jpg in $v 3" cmd='$DETECT --camera $F/tiny.yaml $W/in'
  done
  for v in 50 200 half; do  # grey.jpg is 367 bytes: half of it, not 400 (the whole file)
    local n=$v; [ "$v" = half ] && n='$(($(stat -c %s $F/grey.jpg) / 2))'
    C name="detect.image.jpeg-truncated-$v" prog=detect expect=reject mention='$W/in' setup="head -c $n \$F/grey.jpg >in" cmd='$DETECT --camera $F/tiny.yaml $W/in'
  done
  C name=detect.image.bad-one-among-good prog=detect expect=reject mention='$W/in.png' phrase='000001' \
    setup='echo junk >in.png' cmd="\$DETECT --camera $cam $img \$W/in.png \$F/ts/images/000001.png"
  C name=detect.image.same-twice prog=detect expect=ok cmd="\$DETECT --camera $cam $img $img"
  local vw="\$DETECT --camera $cam --view"
  C name=detect.view.is-file prog=detect expect=fail mention='$W/v' guard='$W/v' setup='echo keep >v' cmd="$vw \$W/v $img"
  C name=detect.view.mknod-full prog=detect expect=fail mention='$W/v' guard='$W/v' setup='node v full' cmd="$vw \$W/v $img"
  C name=detect.view.missing-parent prog=detect expect='ok|fail' mention='$W/no/v' cmd="$vw \$W/no/v $img"
  C name=detect.view.read-only prog=detect expect=fail mention='$W/v' user=nobody setup='open_scratch; mkdir v; chmod 555 v' cmd="$vw \$W/v $img"
  C name=detect.view.dev-full prog=detect expect=fail mention=/dev/full guard=/dev/full user=nobody cmd="$vw /dev/full $img"
  C name=detect.view.overwrites-input prog=detect expect=fail mention='$W/v' guard='$W/v/000000.png' \
    setup="mkdir v; cp $img v/000000.png" cmd="$vw \$W/v \$W/v/000000.png"
}

# ------------------------------------------------------------------ markloop-sim
sim_cases() {
  local k v e h
  local d='$SIM drive --scenario loop --no-render --max-frames 20 --out $W/o'
  C name=sim.control.list prog=sim expect=ok phrase='loop' cmd='$SIM list'
  C name=sim.control.drive prog=sim expect=ok phrase='20 frames' cmd="$d"
  C name=sim.control.render prog=sim expect=ok phrase='5 frames' cmd='$SIM drive --scenario loop --max-frames 5 --out $W/o'
  C name=sim.control.route prog=sim expect=ok cmd='$SIM drive --route $REPO/sim/routes/block-and-a-half.kitti.txt --no-render --max-frames 20 --out $W/o'
  C name=sim.opt.none prog=sim expect=reject mention=usage cmd='$SIM'
  C name=sim.opt.unknown-command prog=sim expect=reject mention=fly cmd='$SIM fly'
  C name=sim.opt.no-out prog=sim expect=reject mention=--out cmd='$SIM drive --scenario loop'
  C name=sim.opt.unknown-scenario prog=sim expect=reject mention=nowhere cmd='$SIM drive --scenario nowhere --out $W/o'
  C name=sim.opt.scenario-and-route prog=sim expect=reject mention=--route cmd='$SIM drive --scenario loop --route $REPO/sim/routes/block-and-a-half.kitti.txt --out $W/o'
  C name=sim.opt.unknown prog=sim expect=reject mention=--frobnicate cmd="$d --frobnicate"
  for k in --scenario --route --out --seed --speed --fps --laps --camera --light --wear --occluders --noise --drift \
           --class-weights --max-frames --cover-lens; do
    C name="sim.opt.no-value$k" prog=sim expect=reject mention="$k" cmd="\$SIM drive --no-render $k"
  done
  local -A vals=(
    [--seed]="nan -1 18446744073709551616 x"
    [--speed]="nan inf 0 -1 1e308 1e-300"
    [--fps]="nan inf 0 -1 1e308 1e-300"
    [--laps]="0 -1 2147483648 nan"
    [--max-frames]="-1 18446744073709551616 nan"
    [--wear]="nan -1 2 inf"
    [--occluders]="nan -1 2"
    [--noise]="nan -1 1e308 inf"
    [--drift]="nan -1 inf 1e308"
    [--light]="noon ''"
    [--class-weights]="junk stop=nan stop=-1 nonesuch=1 stop=1e308 ="
    [--cover-lens]="5:2 nan:1 1e308:2e308 x 1: -5:-1"
  )
  for k in "${!vals[@]}"; do
    for v in ${vals[$k]}; do
      C name="sim.num$k=${v//\'/}" prog=sim expect=reject mention="$k" cmd="$d $k $v"
    done
  done
  C name=sim.laps-huge-bounded prog=sim expect='ok|reject' mention=--laps phrase='20 frames' cmd="$d --laps 1000000"
  # --route FILE
  local r='$SIM drive --route @ --no-render --max-frames 50 --out $W/o'
  badfiles sim.route sim "$r" '$REPO/sim/routes/block-and-a-half.kitti.txt' reject 'frames'
  r='$SIM drive --route $W/in --no-render --max-frames 50 --out $W/o'
  C name=sim.route.one-pose prog=sim expect=reject mention='$W/in' setup='gen route in line 1 0' cmd="$r"
  C name=sim.route.standing-still prog=sim expect=reject mention='$W/in' setup='gen route in same 100 0' cmd="$r"
  C name=sim.route.nan prog=sim expect=reject mention='$W/in' line=51 setup='gen route in nan 100 0' cmd="$r"
  C name=sim.route.jump-1e7 prog=sim expect='ok|reject' mention='$W/in' line=51 setup='gen route in jump 100 1e7' cmd="$r"
  C name=sim.route.jump-1e12 prog=sim expect='ok|reject' mention='$W/in' line=51 setup='gen route in jump 100 1e12' cmd="$r"
  C name=sim.route.jump-1e7-rendered prog=sim expect='ok|reject' mention='$W/in' line=51 \
    setup='gen route in jump 100 1e7' cmd='$SIM drive --route $W/in --max-frames 5 --out $W/o'
  C name=sim.route.jump-1e12-full prog=sim expect='ok|reject' mention='$W/in' line=51 setup='gen route in jump 100 1e12' \
    cmd='$SIM drive --route $W/in --no-render --out $W/o'
  C name=sim.route.far-1e12 prog=sim expect='ok|reject' mention='$W/in' \
    setup="awk '{\$4+=1e12} {print}' \$REPO/sim/routes/block-and-a-half.kitti.txt >in" cmd="$r"
  C name=sim.route.1e308 prog=sim expect=reject mention='$W/in' setup="sed '10s/^\\([^ ]* [^ ]* [^ ]*\\) [^ ]*/\\1 1e308/' \$REPO/sim/routes/block-and-a-half.kitti.txt >in" cmd="$r"
  C name=sim.route.tum-then-kitti prog=sim expect=reject mention='$W/in' line=2 \
    setup="printf '0 0 0 0 0 0 0 1\\n' >in; tail -n +2 \$REPO/sim/routes/block-and-a-half.kitti.txt >>in" cmd="$r"
  C name=sim.route.tum-time-backwards prog=sim expect=reject mention='$W/in' line=3 \
    setup="printf '0 0 0 0 0 0 0 1\\n1 10 0 0 0 0 0 1\\n0.5 20 0 0 0 0 0 1\\n3 30 0 0 0 0 0 1\\n' >in" cmd="$r"
  C name=sim.route.tum-quaternion-zero prog=sim expect=reject mention='$W/in' \
    setup="printf '0 0 0 0 0 0 0 0\\n1 10 0 0 0 0 0 0\\n2 20 0 0 0 0 0 0\\n' >in" cmd="$r"
  C name=sim.route.crlf prog=sim expect='ok|reject' mention='$W/in' phrase=frames \
    setup="sed 's/\$/\\r/' \$REPO/sim/routes/block-and-a-half.kitti.txt >in" cmd="$r"
  bitflips sim.route sim '$SIM drive --route @ --no-render --max-frames 50 --out $W/o' '$REPO/sim/routes/block-and-a-half.kitti.txt' 4 3
  # --camera FILE
  local c='$SIM drive --scenario loop --max-frames 3 --out $W/o --camera $W/in'
  C name=sim.camera.missing prog=sim expect=reject mention='$W/in' cmd="$c"
  C name=sim.camera.binary prog=sim expect=reject mention='$W/in' setup='cp $F/random.bin in' cmd="$c"
  C name=sim.camera.dev-zero prog=sim expect=reject mention=/dev/zero cmd='$SIM drive --scenario loop --max-frames 3 --out $W/o --camera /dev/zero'
  C name=sim.camera.nested-50000 prog=sim expect=reject mention='$W/in' setup='gen nested-yaml in 50000 seq' cmd="$c"
  C name=sim.camera.huge-image prog=sim expect=reject mention='$W/in' \
    setup="sed -e 's/^image_width: .*/image_width: 100000/' -e 's/^image_height: .*/image_height: 100000/' \$F/drive/camera.yaml >in" cmd="$c"
  C name=sim.camera.fx-nan prog=sim expect=reject mention='$W/in' setup="sed 's/data: \\[ 900\\./data: [ .nan/' \$F/drive/camera.yaml >in" cmd="$c"
  C name=sim.camera.fifo-no-writer prog=sim term=delay termdelay=0.5 termexit=any mention='$W/in' setup='mkfifo in' cmd="$c"
  # --out DIR
  C name=sim.out.mknod-full prog=sim expect=reject mention='$W/o' guard='$W/o' setup='node o full' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/o'
  C name=sim.out.regular-file prog=sim expect=reject mention='$W/o' guard='$W/o' setup='echo keep >o' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/o'
  C name=sim.out.dev-null prog=sim expect=reject mention=/dev/null guard=/dev/null user=nobody cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out /dev/null'
  C name=sim.out.read-only prog=sim expect=fail mention='$W/o' user=nobody setup='open_scratch; mkdir o; chmod 555 o' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/o'
  C name=sim.out.missing-parents prog=sim expect='ok|fail' mention='$W/a/b/o' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/a/b/o'
  C name=sim.out.full-file-in-out prog=sim expect=fail mention='frames.csv' guard='$W/o/frames.csv' \
    setup='mkdir o; node o/frames.csv full' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/o'
  C name=sim.out.overwrites-a-drive-in-use prog=sim expect='ok|fail' mention='$W/o' \
    setup='mkdir o; echo mine >o/notes.txt' guard='$W/o/notes.txt' cmd='$SIM drive --scenario loop --no-render --max-frames 5 --out $W/o'
  # training-set
  C name=sim.training.frames-negative prog=sim expect=reject mention=--frames cmd='$SIM training-set --out $W/o --frames -1'
  C name=sim.training.frames-nan prog=sim expect=reject mention=--frames cmd='$SIM training-set --out $W/o --frames nan'
  C name=sim.training.frames-0 prog=sim expect='ok|reject' mention=--frames cmd='$SIM training-set --out $W/o --frames 0'
  C name=sim.training.out-file prog=sim expect=reject mention='$W/o' guard='$W/o' setup='echo keep >o' cmd='$SIM training-set --out $W/o --frames 1'
  C name=sim.training.camera-nested prog=sim expect=reject mention='$W/in' setup='gen nested-yaml in 50000 map' cmd='$SIM training-set --out $W/o --frames 1 --camera $W/in'
  # live (no video output device here: a clear refusal)
  C name=sim.live.no-from prog=sim expect=reject mention=--from cmd='$SIM live --video /dev/null'
  C name=sim.live.from-missing prog=sim expect=reject mention='$W/none' cmd='$SIM live --from $W/none --video /dev/null'
  C name=sim.live.video-dev-null prog=sim expect=reject mention=/dev/null cmd='$SIM live --from $F/drive --video /dev/null --max-frames 5'
  C name=sim.live.video-regular-file prog=sim expect=reject mention='$W/v' guard='$W/v' setup='echo keep >v' cmd='$SIM live --from $F/drive --video $W/v --max-frames 5'
  C name=sim.live.video-nodev prog=sim expect=reject mention='$W/v' setup='node v nodev' cmd='$SIM live --from $F/drive --video $W/v --max-frames 5'
  C name=sim.live.from-without-frames prog=sim expect=reject mention=frames.y4m setup='mkdir d; cp $F/drive/odometry.log d/' cmd='$SIM live --from $W/d --video /dev/null --max-frames 5'
}

define_cases() {
  fixture_numbers
  : >"$OUT/cases/.list"
  ecu_cases
  replay_cases
  eval_cases
  detect_cases
  sim_cases
}
