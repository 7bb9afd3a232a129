"""The paper's torus example (section 6.2, Table 2), headless part of scripts/demo.sh:

    freecadcmd <Mod>/SurfMesh/SurfMesh/cli/demo.py -- OUTDIR

Builds a Part torus (R = 10, r = 4), a first-order Gmsh FEM mesh of it (about 1600 nodes and
3300 triangles), perturbs its nodes in (u, v) on the torus with a fixed seed until 73 elements
are tangled, optimizes it with the shape and the Oddy measures, prints the paper-style table
and writes OUTDIR/torus.FCStd, OUTDIR/table.txt, OUTDIR/report.json and the histograms
OUTDIR/histogram_shape.png, OUTDIR/histogram_oddy.png.
"""

from __future__ import annotations

import os
import sys
import time
import traceback


def main(outdir):
    import FreeCAD

    import SurfMesh
    from SurfMesh.app import examples, reports

    os.makedirs(outdir, exist_ok=True)
    doc = FreeCAD.newDocument("SurfMeshTorus")
    t0 = time.perf_counter()
    ex = examples.make_torus_example(doc)
    mesh, tor = ex["mesh"], ex["shape"]
    fem = mesh.FemMesh
    print(f"torus R=10 r=4: Gmsh mesh with {fem.NodeCount} nodes, {fem.TriangleCount} triangles; "
          f"perturbed in (u,v) by {ex['amplitude']:.4f} (seed 1): {ex['tangled']} tangled",
          flush=True)
    rows, out = [], {"nodes": fem.NodeCount, "elements": fem.TriangleCount,
                     "amplitude": ex["amplitude"], "runs": {}}
    for measure in SurfMesh.measure_names():
        new = SurfMesh.optimize_object(mesh, shape=tor, measure=measure,
                                       name=f"TorusMesh_{measure}_optimized")
        new.Label = f"Torus mesh optimized ({measure})"
        before = SurfMesh.stats_of(new, before=True)
        after = SurfMesh.stats_of(new)
        rows += [(measure, "Tangled", before), (measure, "Smoothed", after)]
        run = dict(new.SurfMeshRun)
        out["runs"][measure] = {"before": before, "after": after, **run}
        print(f"{measure}: {run['sweeps']} sweeps, {run['seconds']} s ({run['reason']})",
              flush=True)
        reports.save_histogram(
            os.path.join(outdir, f"histogram_{measure}.png"),
            [("tangled", new.SurfMeshQualityBefore, before["tangled"]),
             ("smoothed", new.SurfMeshQuality, after["tangled"])],
            title=f"Torus: {measure} quality, tangled vs. smoothed",
        )
    SurfMesh.measure_object(mesh, shape=tor, measure="shape")  # colors the tangled mesh
    table = reports.format_table(rows, title="Shape and Oddy quality statistics of the meshes "
                                             "on the torus (paper Table 2)")
    print()
    print(table, flush=True)
    with open(os.path.join(outdir, "table.txt"), "w", encoding="utf-8") as fh:
        fh.write(table + "\n")
    reports.write_json(os.path.join(outdir, "report.json"), out)
    tor.Visibility = False
    doc.recompute()
    doc.saveAs(os.path.join(outdir, "torus.FCStd"))
    print(f"\nwrote {outdir}/torus.FCStd, table.txt, report.json, histogram_*.png "
          f"({time.perf_counter() - t0:.1f} s)", flush=True)
    return 0


def _run():
    from SurfMesh.app.compat import script_args

    args = script_args()  # freecadcmd demo.py -- DIR
    outdir = os.path.abspath(args[0] if args else "demo-output")
    try:
        return main(outdir)
    except Exception:
        traceback.print_exc()
        return 1


if __name__ in ("__main__", "demo"):  # freecadcmd runs scripts under their file name
    sys.exit(_run())
