#!/usr/bin/env bash
# Run a command (default: scripts/test.sh) inside a Debian root of another release, to check
# SurfMesh with the FreeCAD, OpenCASCADE, Python and Gmsh of that release:
#
#   sudo scripts/debian-root.sh trixie                  # FreeCAD 1.0, OCCT 7.8, Python 3.13
#   sudo scripts/debian-root.sh sid                     # FreeCAD 1.1, OCCT 7.9, Eigen 5
#   sudo scripts/debian-root.sh trixie scripts/demo.sh  # any command, run from the repository
#
# As root (debootstrap, chroot and bind mounts need it). The root is made once with
# `debootstrap --variant=minbase` from Debian's own archive and kept in
# $SURFMESH_ROOTS_DIR/<suite> (default /var/cache/surfmesh-roots), outside the repository, so a
# later run reuses it (and the packages scripts/install.sh installed there). Inside, the
# repository's parent folder is mounted at the same path (the shared CAD data beside the
# repository stays reachable), the build goes to build-<suite>/ (the host's build/ is left
# alone) and the workbench to the root's own home. The sanitizer build and the clang-format
# check belong to the host's run (SURFMESH_LANE tells scripts/test.sh so).
#
# Environment:
#   SURFMESH_ROOTS_DIR   where the roots are kept (default: /var/cache/surfmesh-roots)
#   SURFMESH_MIRROR      Debian mirror for debootstrap (default: http://deb.debian.org/debian)
set -euo pipefail

SUITE="${1:?usage: scripts/debian-root.sh <trixie|sid|…> [command …]}"
shift
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PARENT="$(dirname "$REPO")"
ROOTS="${SURFMESH_ROOTS_DIR:-/var/cache/surfmesh-roots}"
MIRROR="${SURFMESH_MIRROR:-http://deb.debian.org/debian}"
ROOT="$ROOTS/$SUITE"
say() { printf '[debian-root %s] %s\n' "$SUITE" "$*"; }

if [ "$(id -u)" -ne 0 ]; then
  echo "scripts/debian-root.sh: run as root (debootstrap, chroot and mounts need it)" >&2
  exit 2
fi
case "$ROOT/" in
  "$REPO"/*) echo "scripts/debian-root.sh: $ROOTS is inside the repository; choose another SURFMESH_ROOTS_DIR" >&2; exit 2 ;;
esac

# One run per root at a time (two would stack their mounts and race on the packages).
mkdir -p "$ROOTS"
exec 9>"$ROOTS/.$SUITE.lock"
if ! flock -n 9; then
  say "another run uses this root: waiting for it"
  flock 9
fi

# ---- 1. the root -------------------------------------------------------------------------
if [ ! -x "$ROOT/usr/bin/apt-get" ] || [ ! -f "$ROOT/.surfmesh-root-ok" ]; then
  command -v debootstrap >/dev/null 2>&1 || {
    say "installing debootstrap"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap
  }
  say "making the root in $ROOT (debootstrap --variant=minbase $SUITE $MIRROR)"
  # Never remove a root with something still mounted in it (a bind mount of the repository
  # would go with it): undo mounts a killed earlier run left, and stay on the root's own
  # file system.
  if grep -q " $ROOT/" /proc/mounts; then
    grep " $ROOT/" /proc/mounts | awk '{print $2}' | sort -r | xargs -r -n1 umount -l
  fi
  if grep -q " $ROOT/" /proc/mounts; then
    echo "scripts/debian-root.sh: $ROOT still has mounts; not removing it" >&2
    exit 1
  fi
  rm -rf --one-file-system "$ROOT"
  mkdir -p "$ROOTS"
  t0=$(date +%s)
  debootstrap --variant=minbase "$SUITE" "$ROOT" "$MIRROR"
  # No recommends (scripts/install.sh lists what is needed); a mirror's Release file past its
  # Valid-Until date (sid's, on a snapshot) is still taken.
  printf 'APT::Install-Recommends "false";\nAcquire::Check-Valid-Until "false";\n' \
    > "$ROOT/etc/apt/apt.conf.d/99surfmesh"
  touch "$ROOT/.surfmesh-root-ok"
  say "root made in $(( $(date +%s) - t0 )) s"
else
  say "reusing $ROOT"
fi

# ---- 2. mounts (undone on exit) ----------------------------------------------------------
MOUNTS=()
cleanup() {
  local i
  for (( i=${#MOUNTS[@]}-1; i>=0; i-- )); do umount -l "${MOUNTS[$i]}" 2>/dev/null || true; done
}
trap cleanup EXIT
bind() {  # bind SRC DEST-inside-root
  mkdir -p "$ROOT$2"
  mount --bind "$1" "$ROOT$2"
  MOUNTS+=("$ROOT$2")
}
mkdir -p "$ROOT/proc" "$ROOT/sys" "$ROOT/dev/shm"
mount -t proc proc "$ROOT/proc" && MOUNTS+=("$ROOT/proc")
bind /sys /sys
bind /dev /dev
bind /dev/pts /dev/pts
mount -t tmpfs tmpfs "$ROOT/dev/shm" && MOUNTS+=("$ROOT/dev/shm")
bind "$PARENT" "$PARENT"
cp /etc/resolv.conf "$ROOT/etc/resolv.conf" 2>/dev/null || true

# ---- 3. the command ----------------------------------------------------------------------
if [ "$#" -eq 0 ]; then set -- scripts/test.sh; fi
say "running: $* (in $REPO, build-$SUITE/)"
rc=0
chroot "$ROOT" /usr/bin/env -i \
  HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  LANG=C.UTF-8 TERM="${TERM:-dumb}" CI="${CI:-false}" DEBIAN_FRONTEND=noninteractive \
  SURFMESH_LANE="$SUITE" BUILD_DIR="$REPO/build-$SUITE" JOBS="${JOBS:-2}" \
  ${SURFMESH_PY_TIMEOUT:+SURFMESH_PY_TIMEOUT=$SURFMESH_PY_TIMEOUT} \
  ${SURFMESH_GUI_TIMEOUT:+SURFMESH_GUI_TIMEOUT=$SURFMESH_GUI_TIMEOUT} \
  /bin/bash -c 'cd "$1" && shift && exec bash "$@"' _ "$REPO" "$@" || rc=$?
say "exit $rc"
exit "$rc"
