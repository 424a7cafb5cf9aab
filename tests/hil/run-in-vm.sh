#!/usr/bin/env bash
# Hardware-in-the-loop runner: runs shell commands where a real vcan0 exists.
#
#   run-in-vm.sh [options] [--] 'command 1' ['command 2' ...]
#
# Natively when the host kernel can create vcan interfaces; otherwise inside a
# qemu VM booted from Debian's own kernel package (see
# /work/shared/reference/hil-vm-notes.md):
#   1. `apt-get download` the linux-image package that linux-image-amd64
#      depends on, `dpkg -x` it, keep vmlinuz + the modules we need (CAN,
#      9p/virtio, vivid and its media deps), `depmod -b`; cached in the cache
#      dir (default ~/.cache/markloop-hil), so only the first run downloads.
#   2. Build a busybox-static initramfs whose /init loads the modules in
#      modules.dep order, mounts the host root read-only over 9p, a writable
#      9p share for results, chroots into the host root, creates vcan0, runs
#      each command (output + exit status to the results share), powers off.
#   3. Boot qemu (-accel tcg unless KVM was probed to work), then check that
#      every command left an exit status. Anything missing is a FAILURE: this
#      script never skips silently.
#
# Each command runs under /bin/sh -c in the directory this script was called
# from, as root, with HIL_RESULTS (a writable directory whose files are kept
# in <results>/out on the host), TMPDIR (writable scratch) and HIL_IN_VM=1|0
# set. In the VM everything of the host, /tmp included, is read-only; scratch
# space and results live under /run.
#
# Options:
#   --cache DIR      download/kernel cache (env MARKLOOP_HIL_CACHE)
#   --results DIR    where to put logs (default: a fresh temp dir)
#   --mode M         auto | native | vm  (env MARKLOOP_HIL_MODE; default auto)
#   --accel A        auto | tcg | kvm    (env MARKLOOP_HIL_ACCEL; default auto:
#                    KVM only when /dev/kvm is usable and a cached probe boot
#                    with KVM succeeded, else tcg)
#   --timeout SEC    wall-clock limit for the VM (default 600)
#   --require FILE   fail unless FILE exists (e.g. a test binary); repeatable
#   --with-vivid     also load vivid (virtual V4L2 camera) in the VM
#   --arch A         x86_64 | aarch64 (env MARKLOOP_HIL_ARCH; default: this
#                    machine's). aarch64 boots Debian's arm64 kernel in
#                    qemu-system-aarch64 -M virt -cpu cortex-a72 (always tcg)
#                    with busybox-static:arm64 in the initramfs. The host root
#                    holds no arm64 shell, so the guest does not chroot: it
#                    runs the commands with busybox sh in the initramfs, with
#                    the host's directories (/usr, /lib, /etc, /work, ...)
#                    linked in read-only, so aarch64 binaries find their
#                    loader and libraries in Debian's multiarch directories
#                    (the :arm64 packages). Host (x86) programs cannot run
#                    there: commands run under the guest's dash, with its
#                    busybox, can-utils and iproute2 first on PATH.
#   --prepare-only   download/cache the kernel and exit
set -euo pipefail

die() {
  echo "run-in-vm: ERROR: $*" >&2
  exit 1
}
log() { echo "run-in-vm: $*" >&2; }

cache=${MARKLOOP_HIL_CACHE:-${HOME:-/root}/.cache/markloop-hil}
results=
mode=${MARKLOOP_HIL_MODE:-auto}
accel=${MARKLOOP_HIL_ACCEL:-auto}
timeout_s=600
with_vivid=0
prepare_only=0
arch=${MARKLOOP_HIL_ARCH:-$(uname -m)}
requires=()
commands=()

while [ $# -gt 0 ]; do
  case "$1" in
    --cache) cache=$2; shift 2 ;;
    --results) results=$2; shift 2 ;;
    --mode) mode=$2; shift 2 ;;
    --accel) accel=$2; shift 2 ;;
    --timeout) timeout_s=$2; shift 2 ;;
    --require) requires+=("$2"); shift 2 ;;
    --with-vivid) with_vivid=1; shift ;;
    --arch) arch=$2; shift 2 ;;
    --prepare-only) prepare_only=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;;
    --) shift; commands+=("$@"); break ;;
    -*) die "unknown option $1" ;;
    *) commands+=("$1"); shift ;;
  esac
done

[ "$prepare_only" = 1 ] || [ "${#commands[@]}" -gt 0 ] || die "no command given"
for f in "${requires[@]}"; do
  [ -e "$f" ] || die "required file $f does not exist (build the project first: cmake --build --preset host)"
done
case "$mode" in auto|native|vm) ;; *) die "bad --mode $mode" ;; esac
case "$accel" in auto|tcg|kvm) ;; *) die "bad --accel $accel" ;; esac
case "$arch" in
  x86_64) deb_arch=amd64 qemu_system=qemu-system-x86_64 qemu_package=qemu-system-x86 ;;
  aarch64) deb_arch=arm64 qemu_system=qemu-system-aarch64 qemu_package=qemu-system-arm ;;
  *) die "bad --arch $arch (x86_64 or aarch64)" ;;
esac
# A guest of another architecture cannot run the host's programs: no chroot.
foreign=0
[ "$arch" = "$(uname -m)" ] || foreign=1

if [ -z "$results" ]; then
  results=$(mktemp -d "${TMPDIR:-/tmp}/markloop-hil.XXXXXX")
fi
mkdir -p "$results"
results=$(cd "$results" && pwd)
rm -rf "$results/out" "$results/cmds" "$results/console.log"
mkdir -p "$results/out" "$results/cmds"
workdir=$(pwd)

# ------------------------------------------------------------------ helpers

summarize() {
  # Prints every command's log and status; fails unless all ran and passed.
  local i rc status=0 n=${#commands[@]}
  for ((i = 0; i < n; i++)); do
    local id
    id=$(printf '%02d' "$i")
    echo "===== [$id] ${commands[$i]}"
    if [ -f "$results/out/$id.log" ]; then cat "$results/out/$id.log"; else echo "(no output file)"; fi
    if [ ! -f "$results/out/$id.rc" ]; then
      echo "===== [$id] FAILED: no exit status (the command did not run or did not finish)"
      status=1
      continue
    fi
    rc=$(cat "$results/out/$id.rc")
    if [ "$rc" = 0 ]; then
      echo "===== [$id] passed"
    else
      echo "===== [$id] FAILED with exit status $rc"
      status=1
    fi
  done
  if [ -f "$results/out/fatal" ]; then
    echo "run-in-vm: guest reported a fatal error: $(cat "$results/out/fatal")"
    status=1
  fi
  return $status
}

# ------------------------------------------------------------------ native

native_vcan_possible() {
  [ "$(id -u)" = 0 ] || return 1
  if ip link show vcan0 >/dev/null 2>&1; then
    ip -details link show vcan0 2>/dev/null | grep -q vcan || return 1
    return 0
  fi
  ip link add dev vcan0 type vcan >/dev/null 2>&1 || return 1
  return 0
}

run_native() {
  log "host kernel has vcan: running natively"
  ip link set vcan0 up
  local i n=${#commands[@]}
  for ((i = 0; i < n; i++)); do
    local id
    id=$(printf '%02d' "$i")
    set +e
    (cd "$workdir" && HIL_RESULTS="$results/out" HIL_IN_VM=0 /bin/sh -c "${commands[$i]}") \
      >"$results/out/$id.log" 2>&1
    echo $? >"$results/out/$id.rc"
    set -e
  done
  summarize
}

if [ "$mode" != vm ] && [ "$prepare_only" = 0 ] && [ "$foreign" = 0 ]; then
  if native_vcan_possible; then
    run_native
    exit $?
  fi
  [ "$mode" = native ] && die "--mode native: this kernel cannot create vcan interfaces"
  log "host kernel has no vcan ($(uname -r)): using a qemu VM"
fi

# ------------------------------------------------------------------ VM: tools

[ "$mode" = native ] && [ "$foreign" = 1 ] && die "--mode native: cannot run $arch natively on $(uname -m)"
for tool in "$qemu_system" cpio depmod modprobe dpkg apt-get apt-cache gzip flock timeout; do
  command -v "$tool" >/dev/null || die "$tool not found: run .ci/setup (packages $qemu_package, cpio, kmod, ...)"
done
busybox=/bin/busybox
if [ "$foreign" = 0 ]; then
  [ -x "$busybox" ] || die "$busybox missing: install busybox-static"
  file_out=$(LC_ALL=C readelf -d "$busybox" 2>/dev/null | grep -c NEEDED || true)
  [ "$file_out" = 0 ] || die "$busybox is dynamically linked: install busybox-static"
fi

# ------------------------------------------------------------------ VM: kernel cache

mkdir -p "$cache"
exec 9>"$cache/lock"
flock 9

kpkg=${MARKLOOP_HIL_KERNEL_PACKAGE:-}
if [ -z "$kpkg" ]; then
  kpkg=$(apt-cache depends "linux-image-$deb_arch:$deb_arch" 2>/dev/null |
    awk '/Depends: linux-image-[0-9]/{print $2; exit}')
  kpkg=${kpkg%:*}
fi
if [ -z "$kpkg" ]; then
  # No apt lists: use whatever kernel is cached already.
  kpkg=$(ls -d "$cache"/linux-image-*-"$deb_arch" 2>/dev/null | tail -n1 | xargs -r -n1 basename || true)
  [ -n "$kpkg" ] || die "cannot determine the kernel package (apt-cache depends linux-image-$deb_arch:$deb_arch gave nothing; run apt-get update$([ "$foreign" = 1 ] && echo ", after dpkg --add-architecture $deb_arch"))"
fi
kver=${kpkg#linux-image-}
kdir=$cache/$kpkg

# Modules to load (and their dependencies, resolved by modprobe).
base_modules=(virtio_pci 9pnet_virtio 9p can can_raw can_dev vcan sch_tbf)
media_modules=(vivid)
# The cache is rebuilt when the module selection changes.
cache_key="modules: ${base_modules[*]} / ${media_modules[*]}"
# A foreign guest gets its own shell and CAN tools (the host's are x86).
# Their shared libraries come from the host's multiarch directories (.ci/setup
# installs the :arm64 runtime libraries of can-utils and iproute2).
# dash is the commands' /bin/sh: Debian's busybox sh prefers its own applets
# (its tc lacks tbf) to the programs on PATH.
guest_packages=(busybox-static can-utils iproute2 dash)
[ "$foreign" = 0 ] || cache_key="$cache_key / ${guest_packages[*]}:$deb_arch + stdbuf"

if [ ! -f "$kdir/ready" ] || [ "$(cat "$kdir/ready")" != "$cache_key" ]; then
  log "preparing kernel $kver in $kdir (one-time download of $kpkg, ~70 MB)"
  rm -rf "$kdir" "$cache/extract"
  mkdir -p "$cache/debs" "$cache/extract"
  (cd "$cache/debs" && rm -f "$kpkg"_*.deb && apt-get download -q "$kpkg:$deb_arch") ||
    die "apt-get download $kpkg:$deb_arch failed (is the Debian archive reachable? try apt-get update)"
  deb=$(ls "$cache/debs/$kpkg"_*.deb | head -n1)
  dpkg -x "$deb" "$cache/extract" || die "dpkg -x $deb failed"
  src=$cache/extract
  [ -f "$src/boot/vmlinuz-$kver" ] || die "no boot/vmlinuz-$kver in $deb"
  depmod -b "$src" "$kver" || die "depmod -b $src $kver failed"

  mkdir -p "$kdir/modules"
  cp "$src/boot/vmlinuz-$kver" "$kdir/vmlinuz"
  resolve() {  # prints module paths (relative to the extract) in load order
    local m
    for m in "$@"; do
      modprobe -d "$src" -S "$kver" --show-depends "$m" ||
        die "module $m not found in $kpkg"
    done | awk '$1 == "insmod" {print $2}' | awk '!seen[$0]++'
  }
  copy_list() {  # $1 = list file; copies modules flat, writes names in load order
    local p name
    : >"$1"
    while read -r p; do
      name=$(basename "$p")
      case "$name" in
        *.ko.xz) xz -dc "$p" >"$kdir/modules/${name%.xz}"; name=${name%.xz} ;;
        *.ko.zst) zstd -qdc "$p" >"$kdir/modules/${name%.zst}"; name=${name%.zst} ;;
        *.ko) cp "$p" "$kdir/modules/$name" ;;
        *) die "unexpected module file $p" ;;
      esac
      echo "$name" >>"$1"
    done
  }
  resolve "${base_modules[@]}" | copy_list "$kdir/base.load"
  resolve "${media_modules[@]}" | grep -vxF -f <(resolve "${base_modules[@]}") |
    copy_list "$kdir/media.load" || true
  [ -s "$kdir/base.load" ] || die "no modules resolved for ${base_modules[*]}"
  if [ "$foreign" = 1 ]; then
    # The initramfs shell and CAN tools must be the guest's ($deb_arch).
    mkdir -p "$kdir/bin" "$cache/extract-guest"
    for p in "${guest_packages[@]}"; do
      (cd "$cache/debs" && apt-get download -q "$p:$deb_arch") || die "apt-get download $p:$deb_arch failed"
    done
    for p in "${guest_packages[@]}"; do dpkg -x "$cache/debs/$p"_*.deb "$cache/extract-guest"; done
    cp "$cache/extract-guest/bin/busybox" "$kdir/busybox"
    cp "$cache/extract-guest/usr/bin"/* "$kdir/bin/"
    for d in bin sbin; do
      [ -d "$cache/extract-guest/$d" ] && find "$cache/extract-guest/$d" -type f -exec cp {} "$kdir/bin/" \;
    done
    # The tests wrap candump in `stdbuf -oL` (coreutils, an LD_PRELOAD
    # library of the host's architecture); candump flushes every frame it
    # prints, so in the guest the wrapper just runs the command.
    printf '%s\n' '#!/bin/sh' 'while [ $# -gt 0 ]; do case "$1" in -i|-o|-e) shift 2 ;; -*) shift ;; *) break ;; esac; done' \
      'exec "$@"' >"$kdir/bin/stdbuf"
    chmod 755 "$kdir/bin/stdbuf"
    rm -rf "$cache/extract-guest"
  fi
  echo "$kver" >"$kdir/version"
  rm -rf "$cache/extract" "$cache/debs"
  echo "$cache_key" >"$kdir/ready"
  log "kernel ready: $(wc -l <"$kdir/base.load") base modules, $(wc -l <"$kdir/media.load") media modules"
fi

if [ "$prepare_only" = 1 ]; then
  log "prepared $kdir"
  exit 0
fi

# ------------------------------------------------------------------ VM: initramfs

build_initramfs() {  # $1 = output file, $2 = init script text
  local root
  root=$(mktemp -d "$results/initramfs.XXXXXX")
  mkdir -p "$root/bin" "$root/lib/modules" "$root/proc" "$root/sys" "$root/dev" \
    "$root/newroot" "$root/results"
  if [ "$foreign" = 1 ]; then
    cp "$kdir/busybox" "$root/bin/busybox"
    # Not in /bin: busybox --install would replace them with its applets.
    mkdir -p "$root/guest/bin"
    cp "$kdir/bin"/* "$root/guest/bin/"
  else
    cp "$busybox" "$root/bin/busybox"
  fi
  echo "$foreign" >"$root/foreign"
  cp "$kdir"/modules/*.ko "$root/lib/modules/"
  cp "$kdir/base.load" "$root/base.load"
  if [ "$with_vivid" = 1 ]; then cp "$kdir/media.load" "$root/media.load"; else : >"$root/media.load"; fi
  printf '%s\n' "$2" >"$root/init"
  chmod 755 "$root/init"
  (cd "$root" && find . -print0 | cpio --null -o -H newc --quiet | gzip -1) >"$1"
  rm -rf "$root"
}

read -r -d '' init_script <<'INIT' || true
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
say() { echo "MARKLOOP-HIL: $*"; }
say "init started"
fatal() {
  say "FATAL: $*"
  [ -d /results/out ] && echo "$*" >/results/out/fatal
  sync
  poweroff -f
}
for list in /base.load /media.load; do
  while read -r m; do
    [ -n "$m" ] || continue
    args=
    [ "$m" = vivid.ko ] && args="n_devs=1 node_types=0x101"
    insmod "/lib/modules/$m" $args || say "insmod $m failed"
  done <"$list"
done
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 results /results || fatal "cannot mount the results share"
[ -f /results/probe ] && { say "probe ok"; echo ok >/results/out/probe; sync; poweroff -f; }
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144,cache=loose,ro hostroot /newroot ||
  fatal "cannot mount the host root over 9p"
if [ "$(cat /foreign)" = 1 ]; then
  # Guest of another architecture: stay in the initramfs (busybox sh) and
  # link the host's directories in, so that /lib/ld-linux-*.so.1, the
  # multiarch libraries, /etc and the checkout resolve as on the host.
  rm -rf /lib
  for d in /newroot/* /newroot/.[!.]*; do
    n=${d#/newroot}
    [ -e "$d" ] || [ -L "$d" ] || continue
    # /tmp stays the host's (read-only): a checkout may live there.
    case "$n" in /bin|/sbin|/guest|/proc|/sys|/dev|/run|/results|/newroot|/init|/foreign|/base.load|/media.load) continue ;; esac
    [ -e "$n" ] || ln -s "$d" "$n"
  done
  mkdir -p /sbin /run /dev/pts /dev/shm
  mount -t devpts devpts /dev/pts
  mount -t tmpfs tmpfs /dev/shm
  mount -t tmpfs -o mode=1777 tmpfs /run || fatal "cannot mount tmpfs on /run"
  mkdir -p /run/hil-tmp /run/hil-share
  chmod 1777 /run/hil-tmp
  mount -o bind /results /run/hil-share || fatal "cannot bind the results share"
  ln -sf /guest/bin/dash /bin/sh
  export PATH=/guest/bin:/bin:/sbin HOME=/run/hil-tmp TMPDIR=/run/hil-tmp LANG=C.UTF-8 HIL_RESULTS=/run/hil-share/out HIL_IN_VM=1
  { ip link set lo up && ip link add dev vcan0 type vcan && ip link set vcan0 up; } || fatal "cannot create vcan0"
  say "vcan0 up, running commands (no chroot: $(uname -m) guest)"
  cwd=$(cat /results/cwd)
  for f in /results/cmds/*; do
    id=${f##*/}
    say "command $id start"
    (cd "$cwd" && exec /bin/sh "/run/hil-share/cmds/$id") >/results/out/$id.log 2>&1 </dev/null
    rc=$?
    echo $rc >/results/out/$id.rc
    sync
    say "command $id exit $rc"
  done
  echo done >/results/out/done
  sync
  umount /run/hil-share 2>/dev/null
  umount /results 2>/dev/null
  say "powering off"
  poweroff -f
fi
R=/newroot
mount -t proc proc $R/proc
mount -t sysfs sys $R/sys
mount -t devtmpfs dev $R/dev
mkdir -p $R/dev/pts $R/dev/shm
mount -t devpts devpts $R/dev/pts
mount -t tmpfs tmpfs $R/dev/shm
# Scratch space lives under /run: a tmpfs over /tmp would hide a checkout or
# build tree that lives under the host's /tmp (CI may clone there).
mount -t tmpfs -o mode=1777 tmpfs $R/run || fatal "cannot mount tmpfs on /run"
mkdir -p $R/run/hil-tmp $R/run/hil-share
chmod 1777 $R/run/hil-tmp
mount -o bind /results $R/run/hil-share || fatal "cannot bind the results share"
ENV="PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/run/hil-tmp TMPDIR=/run/hil-tmp LANG=C.UTF-8 HIL_RESULTS=/run/hil-share/out HIL_IN_VM=1"
chroot $R /usr/bin/env -i $ENV /bin/sh -c 'ip link set lo up && ip link add dev vcan0 type vcan && ip link set vcan0 up' ||
  fatal "cannot create vcan0"
say "vcan0 up, running commands"
cwd=$(cat /results/cwd)
for f in /results/cmds/*; do
  id=${f##*/}
  say "command $id start"
  chroot $R /usr/bin/env -i $ENV HIL_CWD="$cwd" /bin/sh -c 'cd "$HIL_CWD" && exec /bin/sh "$0"' "/run/hil-share/cmds/$id" \
    >/results/out/$id.log 2>&1 </dev/null
  rc=$?
  echo $rc >/results/out/$id.rc
  sync
  say "command $id exit $rc"
done
echo done >/results/out/done
sync
umount $R/run/hil-share 2>/dev/null
umount /results 2>/dev/null
say "powering off"
poweroff -f
INIT

# Commands travel through the results share (/run/hil-share/cmds in the guest).
i=0
for c in "${commands[@]}"; do
  printf '%s\n' "$c" >"$results/cmds/$(printf '%02d' "$i")"
  i=$((i + 1))
done
echo "$workdir" >"$results/cwd"

initrd=$results/initrd.gz
rm -f "$results/probe"
build_initramfs "$initrd" "$init_script"

# ------------------------------------------------------------------ VM: boot

qemu_boot() {  # $1 = accel, $2 = timeout seconds, $3 = console log
  local rc=0
  local machine
  if [ "$arch" = aarch64 ]; then
    machine=(-M virt -cpu cortex-a72 -accel "$1")
    console=ttyAMA0
  else
    machine=(-accel "$1" -cpu "$([ "$1" = kvm ] && echo host || echo max)")
    console=ttyS0
  fi
  timeout -k 10 "$2" "$qemu_system" \
    "${machine[@]}" -m 1024 -smp 2 \
    -display none -no-reboot -monitor none -serial "file:$3" \
    -kernel "$kdir/vmlinuz" -initrd "$initrd" \
    -append "console=$console quiet panic=-1" \
    -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
    -virtfs "local,path=$results,mount_tag=results,security_model=none,multidevs=remap" \
    </dev/null >"$3.qemu" 2>&1 || rc=$?
  return $rc
}

choose_accel() {
  if [ "$accel" != auto ]; then echo "$accel"; return; fi
  if [ "$foreign" = 1 ]; then echo tcg; return; fi
  if [ ! -r /dev/kvm ] || [ ! -w /dev/kvm ]; then echo tcg; return; fi
  local probe_file=$cache/kvm-probe-$(uname -r)-$kver
  if [ ! -f "$probe_file" ]; then
    log "probing whether KVM boots a guest here (once; cached in $probe_file)"
    touch "$results/probe"
    if qemu_boot kvm 30 "$results/probe-console.log" && [ -f "$results/out/probe" ]; then
      echo kvm >"$probe_file"
    else
      echo tcg >"$probe_file"
    fi
    rm -f "$results/probe" "$results/out/probe"
  fi
  cat "$probe_file"
}

chosen=$(choose_accel)
log "booting $kpkg with -accel $chosen (timeout ${timeout_s}s), ${#commands[@]} command(s); logs in $results"
start=$(date +%s)
boot_rc=0
qemu_boot "$chosen" "$timeout_s" "$results/console.log" || boot_rc=$?
elapsed=$(($(date +%s) - start))
log "VM finished after ${elapsed}s (qemu status $boot_rc)"

if [ "$boot_rc" = 124 ] || [ "$boot_rc" = 137 ]; then
  echo "run-in-vm: ERROR: the VM did not finish within ${timeout_s}s" >&2
fi
if ! grep -q "MARKLOOP-HIL: init started" "$results/console.log" 2>/dev/null; then
  echo "run-in-vm: ERROR: the VM did not start (no init marker on the console)" >&2
  echo "---- qemu output:" >&2; cat "$results/console.log.qemu" >&2 || true
  echo "---- console:" >&2; tail -n 50 "$results/console.log" >&2 || true
  exit 1
fi
status=0
summarize || status=1
if [ ! -f "$results/out/done" ]; then
  echo "run-in-vm: ERROR: the guest did not finish all commands" >&2
  status=1
fi
if [ "$status" != 0 ]; then
  echo "---- guest console (last 60 lines):"
  tail -n 60 "$results/console.log" || true
fi
exit $status
