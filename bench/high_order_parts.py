#!/usr/bin/python3
"""SurfMesh on Gmsh's own high-order meshes of CAD parts, orders 2…5 (no perturbation).

    /usr/bin/python3 bench/high_order_parts.py [--parts gmsh_u_joint.step,occt_screw.step]
        [--orders 2,3,4,5] [--div 21] [--threads 1] [--boundary fixed] [--over-relaxation W]

Gmsh 4.8.4 meshes each part (element size = bounding-box diagonal / div) and raises the mesh to
each order (its high-order nodes projected on the CAD surfaces, as Gmsh does), then the
installed workbench's command line (`freecadcmd surfmesh_cli.py -- optimize`, run after
scripts/install.sh; SURFMESH_CLI=path runs another script instead, e.g. one that imports a copy
of the package built from a branch) optimizes it; one Markdown row per run from its JSON report: elements,
the side nodes the recovery put on their element's face (a side node that Gmsh placed off it,
see README: meshes with any were refused before), tangled before → after (of those left: folded
where no node may move / with a movable node), min and mean quality after, elements standing
across their surface before → after (a corner's tangent plane wound against the surface's
normal there), sweeps, the optimizer's seconds and why it stopped. Gmsh's curved
elements are often already folded at a CAD vertex, between two element sides on fixed CAD
edges: no node motion repairs those. The parts are read from ../shared/data/cad, never copied
into this repository.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "cad"))
# SURFMESH_CLI: another copy's command line (e.g. a private package built from a branch; run it
# with PYTHONPATH set to the folder holding that SurfMesh package).
CLI = os.environ.get("SURFMESH_CLI") or os.path.expanduser(
    "~/.local/share/FreeCAD/Mod/SurfMesh/SurfMesh/cli/surfmesh_cli.py")


def make_mesh(part, order, div, out):
    gmsh.clear()
    gmsh.model.occ.importShapes(part)
    gmsh.model.occ.synchronize()
    box = gmsh.model.getBoundingBox(-1, -1)
    diag = sum((box[i + 3] - box[i]) ** 2 for i in range(3)) ** 0.5
    gmsh.option.setNumber("Mesh.MeshSizeMax", diag / div)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", default="gmsh_u_joint.step,occt_screw.step")
    ap.add_argument("--orders", default="2,3,4,5")
    ap.add_argument("--div", type=float, default=21)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--boundary", default="fixed")
    ap.add_argument("--over-relaxation", default=None, help="passed to the command line")
    a = ap.parse_args()
    if not os.path.exists(CLI):
        raise SystemExit(f"{CLI} not found: run scripts/install.sh first")
    work = tempfile.mkdtemp(prefix="surfmesh_ho_")
    print(f"meshes and reports in {work}", file=sys.stderr)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    print(f"| part | order | elements | side nodes placed | tangled (held / movable left) | min q "
          f"| mean q | standing across | sweeps "
          f"| optimize s ({a.threads} thread{'s' if a.threads > 1 else ''}) | stop |")
    print("|---|---:|---:|---:|---|---:|---:|---|---:|---:|---|")
    for part in a.parts.split(","):
        path = part if os.path.isabs(part) else os.path.join(SHARED, part)
        name = os.path.splitext(os.path.basename(path))[0]
        for order in (int(o) for o in a.orders.split(",")):
            mesh = os.path.join(work, f"{name}_{order}.msh")
            make_mesh(path, order, a.div, mesh)
            report = os.path.join(work, f"{name}_{order}.json")
            run = subprocess.run(
                ["freecadcmd", CLI, "--", "optimize", path, mesh, "-o",
                 os.path.join(work, f"{name}_{order}_out.msh"), "--report", report,
                 "--threads", str(a.threads), "--boundary", a.boundary]
                + (["--over-relaxation", a.over_relaxation] if a.over_relaxation else []),
                capture_output=True, text=True)
            if run.returncode != 0 or not os.path.exists(report):
                last = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["?"]
                print(f"| {name} | {order} | - | - | error: {last[0]} | | | | | | |", flush=True)
                continue
            r = json.load(open(report))
            b, s = r["before"], r["after"]
            placed = len(r.get("bridge", {}).get("placed_nodes", []))
            print(f"| {name} | {order} | {b['elements']} | {placed} "
                  f"| {b['tangled']} → {s['tangled']} "
                  f"({len(r['tangled_unmovable'])} / {len(r['tangled_movable'])}) "
                  f"| {s['min']:.3f} | {s['mean']:.4f} | {b.get('across', '-')} → {s.get('across', '-')} "
                  f"| {r['sweeps']} | {r['seconds']:.2f} "
                  f"| {r['reason']} |", flush=True)
    gmsh.finalize()


if __name__ == "__main__":
    main()
