#!/usr/bin/env bash
# Build SurfMesh's Debian package for one Debian release, with CMake and CPack:
#
#   scripts/package.sh              # for the release this machine runs (bookworm: FreeCAD 0.20)
#   sudo scripts/package.sh trixie  # for another release (FreeCAD 1.0), built inside its root
#   sudo scripts/package.sh sid     #   (scripts/debian-root.sh: a cached debootstrap root)
#
# Result: build-package-<release>/surfmesh_<version>-1~<release>_<arch>.deb, which installs
# the workbench into FreeCAD's system Mod folder (/usr/share/freecad/Mod/SurfMesh) and the
# `surfmesh` command (/usr/bin/surfmesh). Install it with `apt install ./surfmesh_….deb`;
# tests/package/test_package.sh installs it in a clean root of the release and runs the demo.
# A package only fits the release it was built on (its Python, OpenCASCADE and FreeCAD).
#
# Environment:
#   JOBS                  parallel build jobs (default: 2)
#   SURFMESH_SKIP_APT=1   do not check or install the Debian packages the build needs
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
say() { printf '[package] %s\n' "$*"; }

host_codename() {
  # scripts/debian-root.sh sets SURFMESH_LANE to the root's suite (sid's os-release names
  # the next release, not "sid")
  if [ -n "${SURFMESH_LANE:-}" ] && [ "${SURFMESH_LANE}" != "host" ]; then
    echo "$SURFMESH_LANE"; return
  fi
  (. /etc/os-release && echo "${VERSION_CODENAME:-unknown}")
}

HOST="$(host_codename)"
SUITE="${1:-$HOST}"
if [ "$SUITE" != "$HOST" ]; then
  # another release: build inside its root (made and cached by scripts/debian-root.sh)
  say "building the $SUITE package inside the $SUITE root"
  exec bash "$REPO/scripts/debian-root.sh" "$SUITE" scripts/package.sh
fi

JOBS="${JOBS:-2}"
BUILD_DIR="$REPO/build-package-$SUITE"
PYTHON=/usr/bin/python3  # the interpreter FreeCAD embeds

# ---- 1. what the build needs ---------------------------------------------------------------
PACKAGES=(
  build-essential dpkg-dev cmake ninja-build pkg-config file
  libeigen3-dev libtbb-dev pybind11-dev python3-dev
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
  libocct-data-exchange-dev
)
if [ "${SURFMESH_SKIP_APT:-0}" != "1" ]; then
  missing=()
  for p in "${PACKAGES[@]}"; do
    [ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)" = "install ok installed" ] \
      || missing+=("$p")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    SUDO=()
    if [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1; then SUDO=(sudo); fi
    say "installing the build's Debian packages: ${missing[*]}"
    "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
    "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
      --no-install-recommends "${missing[@]}"
  fi
fi

# ---- 2. build (the module only: no tests, no benchmarks) ------------------------------------
t0=$(date +%s)
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  say "configuring $BUILD_DIR (Release, Python $PYTHON, release $SUITE)"
  cmake -S "$REPO" -B "$BUILD_DIR" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release \
    -DPython3_EXECUTABLE="$PYTHON" \
    -DSURFMESH_BUILD_TESTS=OFF -DSURFMESH_BUILD_BENCH=OFF \
    -DSURFMESH_DEB_CODENAME="$SUITE" >/dev/null
fi
say "building in $BUILD_DIR (-j$JOBS)"
cmake --build "$BUILD_DIR" -j "$JOBS"

# ---- 3. package -----------------------------------------------------------------------------
rm -f "$BUILD_DIR"/surfmesh_*.deb
(cd "$BUILD_DIR" && cpack -G DEB >cpack.log 2>&1) || {
  cat "$BUILD_DIR/cpack.log" >&2; say "ERROR: cpack failed"; exit 1; }
deb="$(ls "$BUILD_DIR"/surfmesh_*.deb)"
say "built $deb in $(( $(date +%s) - t0 )) s"
dpkg-deb -f "$deb" Package Version Architecture Depends Recommends | sed 's/^/  /'
