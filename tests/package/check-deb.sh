#!/usr/bin/env bash
# Builds the Debian package of a build tree (CPack) and installs it into a
# scratch root of the package's architecture, then checks it:
#   - the .deb's Architecture is the build's target (arm64 for aarch64, ...);
#   - dpkg installs it into an empty root (--root, no maintainer scripts run
#     on this machine; dependencies are not installed there, so they are
#     forced, but they are listed and must be non-empty);
#   - every file the build's install() rules produce is in the root, with
#     the same size for non-ELF files;
#   - every ELF file is for the target's machine;
#   - every file under /etc is a conffile; the DBC is in /usr/share/markloop.
#
#   check-deb.sh BUILD_DIR
set -euo pipefail

die() { echo "check-deb: FAILED: $*" >&2; exit 1; }
[ "${1:-}" = --help ] || [ "${1:-}" = -h ] && { sed -n '2,14s/^# \{0,1\}//p' "$0"; exit 0; }
[ $# -eq 1 ] || { echo "usage: check-deb.sh BUILD_DIR (see --help)" >&2; exit 2; }
build=$(cd "$1" && pwd) || { echo "check-deb: $1: no such build directory" >&2; exit 2; }
[ -f "$build/CPackConfig.cmake" ] || { echo "check-deb: $build/CPackConfig.cmake missing: configure the build first" >&2; exit 2; }

# The target processor as CMake recorded it (CMakeSystem.cmake).
processor=$(grep -h 'set(CMAKE_SYSTEM_PROCESSOR ' "$build"/CMakeFiles/*/CMakeSystem.cmake 2>/dev/null |
  head -n1 | sed 's/.*"\(.*\)".*/\1/')
case "$processor" in
  aarch64) deb_arch=arm64 machine=AArch64 ;;
  arm*) deb_arch=armhf machine=ARM ;;
  x86_64) deb_arch=amd64 machine="Advanced Micro Devices X86-64" ;;
  *) die "unknown target processor '$processor'" ;;
esac

work=$build/package-check
rm -rf "$work"
mkdir -p "$work/out" "$work/stage" "$work/root/var/lib/dpkg/info" "$work/root/var/lib/dpkg/updates"
: >"$work/root/var/lib/dpkg/status"

echo "check-deb: packaging $build ($processor -> $deb_arch)"
(cd "$work/out" && cpack --config "$build/CPackConfig.cmake" -B "$work/out" >"$work/cpack.log" 2>&1) ||
  { cat "$work/cpack.log"; die "cpack failed"; }
debs=("$work/out"/*.deb)
[ "${#debs[@]}" = 1 ] && [ -f "${debs[0]}" ] || die "expected one .deb in $work/out, found ${#debs[@]}"
deb=${debs[0]}
echo "check-deb: $(basename "$deb") ($(stat -c %s "$deb") bytes)"

[ "$(dpkg-deb -f "$deb" Architecture)" = "$deb_arch" ] || die "Architecture is $(dpkg-deb -f "$deb" Architecture), not $deb_arch"
depends=$(dpkg-deb -f "$deb" Depends)
[ -n "$depends" ] || die "the package declares no dependencies"
echo "check-deb: Depends: $depends"

dpkg --root="$work/root" --force-architecture --force-depends --force-script-chrootless \
  --log=/dev/null -i "$deb" >"$work/dpkg.log" 2>&1 || { cat "$work/dpkg.log"; die "dpkg -i into $work/root failed"; }
status=$(dpkg --root="$work/root" -s markloop 2>/dev/null | sed -n 's/^Status: //p')
[ "$status" = "install ok installed" ] || die "dpkg status of markloop in the scratch root: '$status'"

# What the install() rules produce, staged independently of CPack.
DESTDIR="$work/stage" cmake --install "$build" --prefix /usr >"$work/install.log" 2>&1 ||
  { cat "$work/install.log"; die "cmake --install failed"; }
count=0
while IFS= read -r -d '' staged; do
  rel=${staged#"$work/stage"}
  installed=$work/root$rel
  [ -e "$installed" ] || die "$rel is installed by the build but missing from the package"
  if LC_ALL=C readelf -h "$installed" >/dev/null 2>&1; then
    m=$(LC_ALL=C readelf -h "$installed" | sed -n 's/^ *Machine: *//p')
    [ "$m" = "$machine" ] || die "$rel is for '$m', not '$machine'"
  elif [ "$(stat -c %s "$staged")" != "$(stat -c %s "$installed")" ]; then
    die "$rel differs in size between the build and the package"
  fi
  count=$((count + 1))
done < <(find "$work/stage" \( -type f -o -type l \) -print0)
[ "$count" -gt 0 ] || die "the build installs nothing"

[ -f "$work/root/usr/share/markloop/markloop.dbc" ] || die "/usr/share/markloop/markloop.dbc is not in the package"
conffiles=$(dpkg-deb --ctrl-tarfile "$deb" | tar -xOf - ./conffiles 2>/dev/null || true)
while IFS= read -r -d '' etc_file; do
  rel=${etc_file#"$work/root"}
  grep -qx "$rel" <<<"$conffiles" || die "$rel is under /etc but not a conffile"
done < <(find "$work/root/etc" -type f -print0 2>/dev/null)

echo "check-deb: installed into $work/root: $count files as built, ELF machine $machine, $(grep -c . <<<"$conffiles" || true) conffile(s)"
dpkg --root="$work/root" -L markloop | grep -v '/\.$' | sed 's/^/check-deb:   /'
echo "check-deb: passed"
