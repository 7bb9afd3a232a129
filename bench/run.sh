#!/bin/sh
# SurfMesh benchmarks: builds what is needed, then prints the tables of bench/RESULTS.md.
#
#   bench/run.sh [quick]        (from the repository root; BUILD=dir to choose the build dir)
#
# 1. scaling: time per sweep, sweeps, floor ratio and peak memory vs element count (torus grid,
#    10³…10⁶ triangles, 1 and 2 threads) and the floor ratio on OCC faces;
# 2. SurfMesh vs Gmsh Laplace2D / Relocate2D on the same perturbed meshes (paper's torus, the
#    engine block of ../shared/data/cad at 1×, 10×, 100× the elements);
# 3. every CAD part of ../shared/data/cad, two perturbations each (bench/parts_compare.py) and
#    the paper's Table 3 on a crank shaft and a gear-box housing (bench/paper_table3.py), and
#    edge flips against node motion alone, Laplace2D and Netgen (bench/flips_compare.py), and
#    the sweeps' escapes turned off one by one (bench/escapes_ablation.py);
# 4. FreeCAD conversion cost vs optimization (bench/python/bench_conversion.py, freecadcmd);
# 5. (not in quick) FreeCAD's Gmsh second-order meshes of four parts, Face nodes perturbed in
#    (u,v), through SurfMesh.optimize (bench/python/perturbed_fem.py, freecadcmd);
# 6. (not in quick) FreeCAD's MeshPart meshes (standard and Mefisto) of every CAD part, as
#    they come, fixed and sliding boundary (bench/python/meshpart_parts.py, freecadcmd);
# 7. (not in quick) Gmsh's own high-order meshes (orders 2-5) of two parts through the
#    installed workbench's command line (bench/high_order_parts.py);
# 8. (not in quick) shapes built with FreeCAD (bench/python/built_shapes.py): the Gmsh
#    comparison of 3. and Gmsh's order-2 and order-3 meshes of them.
set -e
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${BUILD:-$ROOT/build-bench}
if [ ! -x "$BUILD/bench/bench_sweep" ] || [ ! -x "$BUILD/bench/bench_cad" ]; then
  cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DPython3_EXECUTABLE=/usr/bin/python3 -DSURFMESH_BUILD_TESTS=OFF >/dev/null
fi
cmake --build "$BUILD" -j2 --target bench_sweep bench_cad >/dev/null
B=$BUILD/bench
SIZES="1000 10000 100000 1000000"
CASES="torus,part,part10,part100"
if [ "$1" = "quick" ]; then SIZES="1000 10000 100000"; CASES="torus,part"; fi

echo "## Scaling (torus R=10 r=4 grid, ~2% of the nodes moved by 1.3 cells, analytic surface)"
"$B/bench_sweep" --header
for n in $SIZES; do
  for t in 1 2; do "$B/bench_sweep" --surface torus --elements "$n" --threads "$t"; done
done
echo
echo "## Floor ratio on OCC faces (100k triangles, 1 thread)"
"$B/bench_sweep" --header
for s in torus occ-torus occ-bspline; do
  "$B/bench_sweep" --surface "$s" --elements 100000 --threads 1
done
echo
echo "## SurfMesh vs Gmsh"
/usr/bin/python3 "$ROOT/bench/gmsh_compare.py" --bench-dir "$B" --cases "$CASES" --threads 2 \
  2>&1 | grep -v '^Info'
echo
if [ "$1" != "quick" ]; then
  echo "## Every CAD part, two perturbations each"
  /usr/bin/python3 "$ROOT/bench/parts_compare.py" --bench-dir "$B" 2>&1 | grep -v '^Info'
  echo
fi
echo "## The paper's Table 3"
/usr/bin/python3 "$ROOT/bench/paper_table3.py" --bench-dir "$B" 2>&1 | grep -v '^Info'
echo
echo "## Edge flips (topology flip) against node motion alone, Laplace2D and Netgen"
if [ "$1" = "quick" ]; then
  /usr/bin/python3 "$ROOT/bench/flips_compare.py" --bench-dir "$B" --parts occt_crankarm.brep \
    --sizes 21 2>&1 | grep -E '^\||rror'
else
  /usr/bin/python3 "$ROOT/bench/flips_compare.py" --bench-dir "$B" 2>&1 | grep -E '^\||rror'
  BENCH_BOUNDARY=slide /usr/bin/python3 "$ROOT/bench/flips_compare.py" --bench-dir "$B" \
    2>&1 | grep -E '^\||rror'
fi
echo
echo "## The escapes one by one (ablation)"
if [ "$1" = "quick" ]; then
  /usr/bin/python3 "$ROOT/bench/escapes_ablation.py" --bench-dir "$B" --parts occt_crankarm.brep \
    --seeds 1 2>&1 | grep -E '^\||rror'
else
  /usr/bin/python3 "$ROOT/bench/escapes_ablation.py" --bench-dir "$B" 2>&1 | grep -E '^\||rror'
fi
echo
echo "## FreeCAD conversion vs optimization"
if [ -f "$ROOT/bench/python/bench_conversion.py" ]; then
  freecadcmd "$ROOT/bench/python/bench_conversion.py" 2>&1 | grep -E '^\||^#|rror' || true
fi
if [ "$1" != "quick" ]; then
  echo
  echo "## Perturbed FreeCAD Gmsh second-order meshes"
  freecadcmd "$ROOT/bench/python/perturbed_fem.py" 2>&1 | grep -E '^\||rror' || true
fi
if [ "$1" != "quick" ]; then
  echo
  echo "## FreeCAD MeshPart meshes of every CAD part"
  freecadcmd "$ROOT/bench/python/meshpart_parts.py" 2>&1 | grep -E '^\||rror' || true
fi
if [ "$1" != "quick" ]; then
  echo
  echo "## Gmsh's high-order meshes, orders 2-5 (installed workbench's command line)"
  /usr/bin/python3 "$ROOT/bench/high_order_parts.py" 2>&1 | grep -E '^\||rror' || true
fi
if [ "$1" != "quick" ]; then
  echo
  echo "## Shapes built with FreeCAD: SurfMesh vs Gmsh, and Gmsh's order-2 and order-3 meshes"
  BUILT=$(mktemp -d)
  SURFMESH_BUILT_DIR="$BUILT" freecadcmd "$ROOT/bench/python/write_built_shapes.py" >/dev/null 2>&1
  PARTS=$(ls "$BUILT"/*.brep | paste -sd, -)
  /usr/bin/python3 "$ROOT/bench/parts_compare.py" --bench-dir "$B" --parts "$PARTS" 2>&1 \
    | grep -v '^Info'
  /usr/bin/python3 "$ROOT/bench/high_order_parts.py" --parts "$PARTS" --orders 2,3 --div 17 \
    2>&1 | grep -E '^\||rror' || true
  rm -rf "$BUILT"
fi
