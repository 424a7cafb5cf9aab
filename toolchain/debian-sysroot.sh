#!/usr/bin/env bash
# Builds a target root from Debian packages without installing them on this
# machine: a private apt state (lists, cache, an empty dpkg status) for one
# architecture, the same sources as this machine's apt, `apt-get install
# --download-only` to resolve the dependency closure, then `dpkg-deb -x` of
# every package into the root. Maintainer scripts do not run; the root is for
# compiling, linking and running under qemu-user, not for booting.
#
#   debian-sysroot.sh --arch ARCH --out DIR [--no-deps] PACKAGE...
#
#   --arch ARCH   Debian architecture (arm64, armhf, ...)
#   --out DIR     the root to (re)create; apt state is kept in DIR.apt
#   --no-deps     unpack only the named packages (an extra root next to a
#                 multiarch installation, e.g. libcatch2-dev, which is not
#                 Multi-Arch co-installable)
#
# The root is rebuilt only when the package list changes (DIR/.packages).
# Index files that fail to download (a mirror in the middle of a sync) are
# reported and skipped: packages then come from the remaining suites, and a
# package that cannot be resolved is an error.
set -euo pipefail

die() { echo "debian-sysroot: ERROR: $*" >&2; exit 2; }
log() { echo "debian-sysroot: $*" >&2; }

usage() { sed -n '2,20s/^# \{0,1\}//p' "$0"; }

arch= out= with_deps=1 packages=()
while [ $# -gt 0 ]; do
  case "$1" in
    --arch) [ $# -ge 2 ] || die "--arch needs a value"; arch=$2; shift 2 ;;
    --out) [ $# -ge 2 ] || die "--out needs a value"; out=$2; shift 2 ;;
    --no-deps) with_deps=0; shift ;;
    -h|--help) usage; exit 0 ;;
    -*) die "unknown option $1 (see --help)" ;;
    *) packages+=("$1"); shift ;;
  esac
done
[ -n "$arch" ] || die "--arch is required (see --help)"
[ -n "$out" ] || die "--out is required (see --help)"
[ "${#packages[@]}" -gt 0 ] || die "no package given (see --help)"
[[ "$arch" =~ ^[a-z0-9]+$ ]] || die "bad architecture '$arch'"
for tool in apt-get dpkg-deb; do command -v "$tool" >/dev/null || die "$tool not found"; done

mkdir -p "$out"
out=$(cd "$out" && pwd)
stamp="$arch deps=$with_deps ${packages[*]} (alternatives linked)"
if [ -f "$out/.packages" ] && [ "$(cat "$out/.packages")" = "$stamp" ]; then
  log "$out is up to date"
  exit 0
fi

state=$out.apt
mkdir -p "$state/lists/partial" "$state/cache/archives/partial"
: >"$state/status"
apt_opts=(
  -o "APT::Architecture=$arch" -o "APT::Architectures::=$arch"
  -o "Dir::State=$state" -o "Dir::State::Lists=$state/lists"
  -o "Dir::State::status=$state/status" -o "Dir::Cache=$state/cache"
  -o "Dir::Cache::archives=$state/cache/archives"
  -o "APT::Install-Recommends=false" -o "Debug::NoLocking=true"
  -o "APT::Get::AllowUnauthenticated=false" -q
)

log "updating the $arch package lists in $state/lists"
if ! apt-get "${apt_opts[@]}" update >"$state/update.log" 2>&1; then
  grep -E '^(E|W|Err):' "$state/update.log" >&2 || true
  log "some index files failed; continuing with the others"
fi

rm -f "$state/cache/archives"/*.deb
if [ "$with_deps" = 1 ]; then
  log "resolving and downloading ${packages[*]} with their dependencies"
  apt-get "${apt_opts[@]}" install -y --download-only "${packages[@]}" >"$state/install.log" 2>&1 ||
    { cat "$state/install.log" >&2; die "cannot resolve ${packages[*]} for $arch"; }
else
  log "downloading ${packages[*]}"
  (cd "$state/cache/archives" && apt-get "${apt_opts[@]}" download "${packages[@]}") >"$state/install.log" 2>&1 ||
    { cat "$state/install.log" >&2; die "cannot download ${packages[*]} for $arch"; }
fi

debs=("$state/cache/archives"/*.deb)
[ -e "${debs[0]}" ] || die "nothing was downloaded"
rm -rf "$out"
mkdir -p "$out"
for deb in "${debs[@]}"; do
  deb_arch=$(dpkg-deb -f "$deb" Architecture)
  [ "$deb_arch" = "$arch" ] || [ "$deb_arch" = all ] || die "$deb is for $deb_arch, not $arch"
  dpkg-deb -x "$deb" "$out"
done
# Absolute symlinks (e.g. libfoo.so -> /lib/<triple>/libfoo.so.1) would
# point into the build machine: make them relative to the root.
find "$out" -type l -lname '/*' -print0 | while IFS= read -r -d '' link; do
  target=$(readlink "$link")
  ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "$out$target")" "$link"
done
# Maintainer scripts do not run, so the update-alternatives links that
# libblas3/liblapack3 (OpenCV's BLAS/LAPACK) make in postinst are missing:
# link each library in a multiarch alternatives directory into its parent.
for lib in "$out"/usr/lib/*-linux-gnu*/{blas,lapack,openblas*,atlas}/lib*.so*; do
  [ -e "$lib" ] || continue
  parent=$(dirname "$(dirname "$lib")")
  [ -e "$parent/$(basename "$lib")" ] || ln -s "$(basename "$(dirname "$lib")")/$(basename "$lib")" "$parent/$(basename "$lib")"
done
rm -f "$state/cache/archives"/*.deb
echo "$stamp" >"$out/.packages"
log "unpacked ${#debs[@]} packages into $out ($(du -sh "$out" | cut -f1))"
