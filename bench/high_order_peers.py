#!/usr/bin/python3
"""Curved meshes: SurfMesh's two modes for curved elements against Gmsh's high-order
optimizers, on the same raw Gmsh meshes, judged by one judge.

    /usr/bin/python3 bench/high_order_peers.py [--parts occt_bottle.brep,occt_screw.step]
        [--orders 2,3] [--div 21] [--threads 1] [--gmsh HighOrder,HighOrderElastic]

For each part (read from ../shared/data/cad, never copied here) Gmsh meshes the surfaces of
the model with its volumes removed (with a solid in the model Gmsh's optimize("HighOrder")
silently does nothing), element size = bounding-box diagonal / div, and raises the mesh to
each order with setOrder(p) and no high-order optimization: the raw mesh. Then, each from the
raw mesh:
  * SurfMesh, --high-order reference and --high-order integral (the installed command line,
    boundary fixed);
  * Gmsh's optimize(method) for each method of --gmsh (its own defaults), timed in this
    process.
The judge is the same for all: `surfmesh measure` on each result, with the metrics
jacobian_ratio (min J / max J over the element, Gmsh's convention; ≤ 0: folded) and
side_node_offset, and its invalid count (tangled, or not proven valid against the face's
normals: see docs/method.md). One Markdown row per part, order and tool: elements, invalid,
min / mean Jacobian ratio, min / mean quality (the paper's shape measure), largest side-node
offset, seconds. SURFMESH_CLI=path runs another copy's command line.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "cad"))
CLI = os.environ.get("SURFMESH_CLI") or os.path.expanduser(
    "~/.local/share/FreeCAD/Mod/SurfMesh/SurfMesh/cli/surfmesh_cli.py")


def raw_mesh(part, order, div):
    gmsh.clear()
    gmsh.model.occ.importShapes(part)
    gmsh.model.occ.synchronize()
    vols = gmsh.model.getEntities(3)
    if vols:
        gmsh.model.occ.remove(vols)
        gmsh.model.occ.synchronize()
    box = gmsh.model.getBoundingBox(-1, -1)
    diag = math.sqrt(sum((box[i + 3] - box[i]) ** 2 for i in range(3)))
    gmsh.option.setNumber("Mesh.MeshSizeMax", diag / div)
    gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(order)


def cli(*args):
    run = subprocess.run(["freecadcmd", CLI, "--", *args], capture_output=True, text=True)
    if run.returncode != 0:
        last = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["?"]
        raise RuntimeError(last[0])


def judge(part, mesh, work, tag):
    report = os.path.join(work, tag + "_judge.json")
    cli("measure", part, mesh, "--metrics", "jacobian_ratio,side_node_offset", "--report",
        report)
    r = json.load(open(report))
    return r["stats"], r["metrics"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", default="occt_bottle.brep,occt_screw.step,occt_propeller.brep")
    ap.add_argument("--orders", default="2,3")
    ap.add_argument("--div", type=float, default=21)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--gmsh", default="HighOrder")
    a = ap.parse_args()
    if not os.path.exists(CLI):
        raise SystemExit(f"{CLI} not found: run scripts/install.sh first")
    work = tempfile.mkdtemp(prefix="surfmesh_hopeers_")
    print(f"meshes and reports in {work}; Gmsh {gmsh.__version__}", file=sys.stderr)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    print("| part | order | tool | elements | invalid | min / mean Jacobian ratio "
          "| min / mean quality | max side-node offset | seconds |")
    print("|---|---:|---|---:|---:|---|---|---:|---:|")
    for part in a.parts.split(","):
        path = part if os.path.isabs(part) else os.path.join(SHARED, part)
        name = os.path.splitext(os.path.basename(path))[0]
        for order in (int(o) for o in a.orders.split(",")):
            raw = os.path.join(work, f"{name}_{order}_raw.msh")
            raw_mesh(path, order, a.div)
            gmsh.write(raw)
            runs = [("input (Gmsh raw)", raw, None)]
            for mode in ("reference", "integral"):
                out = os.path.join(work, f"{name}_{order}_{mode}.msh")
                rep = os.path.join(work, f"{name}_{order}_{mode}.json")
                try:
                    cli("optimize", path, raw, "-o", out, "--report", rep, "--threads",
                        str(a.threads), "--high-order", mode)
                    runs.append((f"SurfMesh {mode}", out,
                                 json.load(open(rep))["seconds"]))
                except RuntimeError as exc:
                    runs.append((f"SurfMesh {mode}: {exc}", None, None))
            for method in a.gmsh.split(","):
                gmsh.clear()
                gmsh.open(raw)
                out = os.path.join(work, f"{name}_{order}_{method}.msh")
                gmsh.option.setNumber("General.NumThreads", a.threads)
                t = time.perf_counter()
                try:
                    gmsh.model.mesh.optimize(method)
                    dt = time.perf_counter() - t
                    gmsh.write(out)
                    runs.append((f"Gmsh {method}", out, dt))
                except Exception as exc:  # Gmsh aborts some runs ("Failed to reach ...")
                    runs.append((f"Gmsh {method}: {str(exc).splitlines()[0]}", None, None))
            for tool, mesh, seconds in runs:
                if mesh is None:
                    print(f"| {name} | {order} | {tool} | | | | | | |", flush=True)
                    continue
                try:
                    s, m = judge(path, mesh, work, os.path.basename(mesh)[:-4])
                except RuntimeError as exc:
                    print(f"| {name} | {order} | {tool} | judge: {exc} | | | | | |", flush=True)
                    continue
                jr, off = m["jacobian_ratio"], m["side_node_offset"]
                sec = "" if seconds is None else f"{seconds:.2f}"
                print(f"| {name} | {order} | {tool} | {s['elements']} | {s['invalid']} "
                      f"| {jr['min']:.3f} / {jr['mean']:.3f} | {s['min']:.3f} / {s['mean']:.3f} "
                      f"| {off['max']:.3f} | {sec} |", flush=True)
    gmsh.finalize()


if __name__ == "__main__":
    main()
