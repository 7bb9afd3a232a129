#!/usr/bin/env bash
# SurfMesh demo: the paper's torus (section 6.2, Table 2). Installs and builds SurfMesh
# (scripts/install.sh), builds a Part torus (R=10, r=4) with a Gmsh FEM mesh (~1600 nodes),
# tangles 73 of its elements by moving nodes in (u,v) on the torus (fixed seed), optimizes it
# with the shape and the Oddy measures and prints the paper-style table. Writes demo-output/:
#   torus.FCStd        the torus, the tangled mesh and the two optimized meshes, colored
#   table.txt          the statistics table;  report.json  the same, with the runs' details
#   histogram_*.png    quality histograms, tangled vs. smoothed, per measure
#   screenshot.png     the colored 3D views (tangled, smoothed with shape, with Oddy)
#
#   scripts/demo.sh [OUTDIR]
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$REPO/demo-output}" && cd "${1:-$REPO/demo-output}" && pwd)"
bash "$REPO/scripts/install.sh"
MOD_DIR="${SURFMESH_MOD_DIR:-$(bash "$REPO/scripts/freecad-user-mod.sh")/SurfMesh}"

echo "[demo] torus example (freecadcmd)"
freecadcmd "$MOD_DIR/SurfMesh/cli/demo.py" -- "$OUT" 2>&1 \
  | grep -vE '^\s*\(?[0-9]+ %\)|^\s*$|^  [# ]|^  [A-Z/]|Recompute|FreeCAD|Juergen|free and open|wouldn.t be|Tangled|^Measure|^---|Table 2' \
  || true
[ -f "$OUT/torus.FCStd" ] || { echo "[demo] ERROR: the torus example failed"; exit 1; }
echo
cat "$OUT/table.txt"
echo

echo "[demo] screenshot of the colored meshes (freecad under xvfb-run)"
SURFMESH_DEMO_OUTPUT="$OUT" QTWEBENGINE_DISABLE_SANDBOX=1 timeout 600 \
  xvfb-run -a -s "-screen 0 1280x1024x24" freecad "$MOD_DIR/SurfMesh/cli/demo_gui.py" \
  >"$OUT/gui.log" 2>&1 || { echo "[demo] ERROR: screenshot failed, see $OUT/gui.log"; exit 1; }
grep -E "^wrote" "$OUT/gui.log" || true
echo "[demo] done: $OUT"
ls -1 "$OUT"
