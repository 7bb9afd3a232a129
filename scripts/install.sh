#!/usr/bin/env bash
# Install SurfMesh's dependencies (Debian packages), build it, and install the workbench for
# the current user. Idempotent and cheap to re-run: apt runs only when a package is missing,
# CMake configures only once per build directory and Ninja rebuilds only what changed.
#
#   scripts/install.sh
#
# Environment:
#   BUILD_DIR             build directory (default: <repo>/build)
#   JOBS                  parallel build jobs (default: 2)
#   CMAKE_BUILD_TYPE      default: Release
#   SURFMESH_SKIP_APT=1   do not check or install Debian packages
#   SURFMESH_MOD_DIR      where the workbench goes (default: <FreeCAD's user Mod folder>/SurfMesh,
#                         as FreeCAD says: ~/.local/share/FreeCAD/Mod for 0.20 and 1.0,
#                         ~/.local/share/FreeCAD/v1-1/Mod for 1.1; scripts/freecad-user-mod.sh)
#   SURFMESH_BIN_DIR      where the `surfmesh` command goes (a symbolic link into the workbench;
#                         default: /usr/local/bin as root, else $HOME/.local/bin)
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$REPO/build}"
case "$BUILD_DIR" in /*) ;; *) BUILD_DIR="$REPO/$BUILD_DIR" ;; esac
JOBS="${JOBS:-2}"
BUILD_TYPE="${CMAKE_BUILD_TYPE:-Release}"
HOME="${HOME:-$(getent passwd "$(id -u)" | cut -d: -f6)}"
export HOME
PYTHON=/usr/bin/python3  # the interpreter FreeCAD embeds

say() { printf '[install] %s\n' "$*"; }

# ---- 1. Debian packages ------------------------------------------------------------------
PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libtbb-dev pybind11-dev libgtest-dev
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
  libocct-data-exchange-dev
  python3-dev python3-numpy python3-matplotlib python3-meshio
  freecad gmsh python3-gmsh
  python3-distributed
  xvfb xauth clang-format
)

SUDO=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO=(sudo); fi
fi

is_installed() {
  [ "$(dpkg-query -W -f='${Status}' "$1" 2>/dev/null || true)" = "install ok installed" ]
}

freecad_works() {
  freecadcmd -c "import FreeCAD, Part, Mesh, MeshPart, Fem" >/dev/null 2>&1
}

apt_install() {  # apt_install [--no-install-recommends] pkg...
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "$@"
}

if [ "${SURFMESH_SKIP_APT:-0}" = "1" ]; then
  say "SURFMESH_SKIP_APT=1: not checking Debian packages"
else
  missing=()
  for p in "${PACKAGES[@]}"; do
    is_installed "$p" || missing+=("$p")
  done
  if [ "${#missing[@]}" -eq 0 ]; then
    say "all ${#PACKAGES[@]} Debian packages present"
  else
    say "installing missing Debian packages: ${missing[*]}"
    "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
    # Recommends are not needed (freecadcmd, the GUI under xvfb, gmsh and the build all
    # work without them); if FreeCAD turns out broken without them, install them below.
    apt_install --no-install-recommends "${missing[@]}"
  fi
  # FreeCAD built with Qt 6 (Debian sid) draws SVG icons, SurfMesh's included, only with
  # Qt 6's SVG plugins, which are a recommendation of its packages, not a dependency.
  if is_installed libqt6core6t64 && ! is_installed qt6-svg-plugins; then
    say "installing qt6-svg-plugins (SVG icons in a Qt 6 FreeCAD)"
    apt_install --no-install-recommends qt6-svg-plugins || say "  (not available here)"
  fi
  if ! freecad_works; then
    say "freecadcmd cannot import FreeCAD/Part/Mesh/Fem: reinstalling freecad with recommends"
    "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
    apt_install freecad freecad-python3
    freecad_works || { say "ERROR: freecadcmd still broken"; exit 1; }
  fi
fi

# ---- 2. Build ----------------------------------------------------------------------------
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  say "configuring $BUILD_DIR ($BUILD_TYPE, Ninja, Python $PYTHON)"
  cmake -S "$REPO" -B "$BUILD_DIR" -G Ninja \
    -DCMAKE_BUILD_TYPE="$BUILD_TYPE" \
    -DPython3_EXECUTABLE="$PYTHON"
else
  say "using existing configuration in $BUILD_DIR (delete it to reconfigure from scratch)"
fi
say "building in $BUILD_DIR (-j$JOBS)"
cmake --build "$BUILD_DIR" -j "$JOBS"

# ---- 3. Workbench for the current user ---------------------------------------------------
MOD_DIR="${SURFMESH_MOD_DIR:-$(bash "$REPO/scripts/freecad-user-mod.sh")/SurfMesh}"
# Layout:  $MOD_DIR/package.xml Init.py InitGui.py LICENSE resources/
#          $MOD_DIR/SurfMesh/            the Python package (src/SurfMesh)
#          $MOD_DIR/SurfMesh/_surfmesh.cpython-311-x86_64-linux-gnu.so  (from build/src/bindings)
# The copy is rebuilt from scratch each time so that no deleted file survives in it.
say "installing the workbench into $MOD_DIR"
MOD_DIR="${MOD_DIR%/}"
mkdir -p "$(dirname "$MOD_DIR")"
stage="$(mktemp -d "$MOD_DIR.stage.XXXXXX")"
trap 'rm -rf "$stage"' EXIT

copy_tree() {  # copy_tree SRC DEST (without caches)
  mkdir -p "$2"
  tar -C "$1" --exclude='__pycache__' --exclude='*.pyc' -cf - . | tar -C "$2" -xf -
}

for f in package.xml Init.py InitGui.py LICENSE; do
  if [ -f "$REPO/$f" ]; then cp "$REPO/$f" "$stage/"; else say "  (no $f yet, skipped)"; fi
done
if [ -d "$REPO/resources" ]; then
  copy_tree "$REPO/resources" "$stage/resources"
else
  say "  (no resources/ yet, skipped)"
fi
if [ -d "$REPO/src/SurfMesh" ]; then
  copy_tree "$REPO/src/SurfMesh" "$stage/SurfMesh"
else
  say "  (no src/SurfMesh/ yet, skipped)"
fi
sos=()
if [ -d "$BUILD_DIR/src/bindings" ]; then
  while IFS= read -r so; do sos+=("$so"); done \
    < <(find "$BUILD_DIR/src/bindings" -maxdepth 2 -name '*.so' -type f | sort)
fi
if [ "${#sos[@]}" -gt 0 ]; then
  mkdir -p "$stage/SurfMesh"
  for so in "${sos[@]}"; do
    cp "$so" "$stage/SurfMesh/"
    say "  module $(basename "$so")"
  done
else
  say "  (no compiled module in $BUILD_DIR/src/bindings yet, skipped)"
fi

rm -rf "$MOD_DIR"
mv "$stage" "$MOD_DIR"
chmod 755 "$MOD_DIR"
trap - EXIT
say "done: $(find "$MOD_DIR" -type f | wc -l) files in $MOD_DIR"

# ---- 4. The `surfmesh` command -----------------------------------------------------------
if [ "$(id -u)" -eq 0 ]; then default_bin=/usr/local/bin; else default_bin="$HOME/.local/bin"; fi
BIN_DIR="${SURFMESH_BIN_DIR:-$default_bin}"
mkdir -p "$BIN_DIR"
launcher="$MOD_DIR/SurfMesh/cli/launcher.py"
chmod 755 "$launcher"
ln -sfn "$launcher" "$BIN_DIR/surfmesh"
say "command: $BIN_DIR/surfmesh -> $launcher"
case ":$PATH:" in
  *":$BIN_DIR:"*) ;;
  *) say "  note: $BIN_DIR is not on your PATH: run $BIN_DIR/surfmesh, or add it to PATH" ;;
esac
