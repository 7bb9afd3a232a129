"""SurfMesh on the meshes FreeCAD's own mesh workbench makes of every CAD part, unperturbed.

For each part of SURFMESH_MP_CAD_DIR (default ../shared/data/cad), two MeshPart meshes:
"standard" (BRepMesh, linear deflection diagonal / 500, angular 0.35) and "mefisto" (maximum
edge length diagonal / 30). Each goes through ``SurfMesh.optimize`` with its defaults, with
``boundary="fixed"`` and ``boundary="slide"``. One Markdown table row per run: triangles,
nodes glued (twins at the same position: the standard mesher's cracks along CAD edges),
tangled elements before → after (how many of those left have a movable node), min / mean
quality before → after, sweeps, time, and the largest distance to the part of a node the run
moved (FreeCAD's ``Shape.distToShape``, on up to 150 moved nodes; ``Mesh.Mesh`` stores float32
points, so about 1e-7 × diagonal is its rounding). A mesh SurfMesh refuses gets a row with the
start of the message.

    freecadcmd bench/python/meshpart_parts.py

Options by environment (freecadcmd takes no script options): SURFMESH_MP_PARTS (comma list
of files in SURFMESH_MP_CAD_DIR).
"""

import os
import time

import numpy as np

import FreeCAD
import MeshPart
import Part
import SurfMesh

HERE = os.path.dirname(os.path.abspath(__file__))
CAD = os.environ.get(
    "SURFMESH_MP_CAD_DIR", os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared",
                                                         "data", "cad")))


def points(mesh):
    return np.array([[p.x, p.y, p.z] for p in mesh.Points])


def max_moved_distance(shape, before, after, limit=150):
    moved = np.nonzero(np.any(after != before, axis=1))[0]
    if moved.size == 0:
        return 0.0, 0
    sample = moved[:: max(1, moved.size // limit)]
    d = max(shape.distToShape(Part.Vertex(FreeCAD.Vector(*map(float, after[i]))))[0]
            for i in sample)
    return d, moved.size


def main():
    default = sorted(f for f in os.listdir(CAD) if f.endswith((".step", ".stp", ".brep")))
    parts = [p for p in os.environ.get("SURFMESH_MP_PARTS", ",".join(default)).split(",") if p]
    print("| part | mesher | triangles | glued nodes | boundary | tangled before → after "
          "(movable) | min q before → after | mean q before → after | sweeps | s | "
          "max distance of moved nodes to the part |")
    print("|---|---|---:|---:|---|---|---|---|---:|---:|---:|")
    for name in parts:
        shape = Part.read(os.path.join(CAD, name))
        diag = shape.BoundBox.DiagonalLength
        for mesher in ("standard", "mefisto"):
            if mesher == "standard":
                mesh = MeshPart.meshFromShape(Shape=shape, LinearDeflection=diag / 500,
                                              AngularDeflection=0.35, Relative=False)
            else:
                mesh = MeshPart.meshFromShape(Shape=shape, MaxLength=diag / 30)
            p0 = points(mesh)
            for boundary in ("fixed", "slide"):
                head = f"| {name} | {mesher} | {mesh.CountFacets} |"
                try:
                    t = time.perf_counter()
                    r = SurfMesh.optimize(mesh, shape, boundary=boundary)
                    dt = time.perf_counter() - t
                except ValueError as e:
                    print(f"{head} | {boundary} | refused: {str(e)[:160]} | | | | | |",
                          flush=True)
                    continue
                b, a = r.before.stats, r.after.stats
                d, n_moved = max_moved_distance(shape, p0, points(r.mesh))
                print(f"{head} {r.bridge.get('glued_nodes', 0)} | {boundary} | "
                      f"{b['tangled']} → {a['tangled']} ({len(r.tangled_movable)}) | "
                      f"{b['min']:.3f} → {a['min']:.3f} | {b['mean']:.3f} → {a['mean']:.3f} | "
                      f"{r.sweeps} | {dt:.1f} | {d / diag:.1e} × diag ({n_moved} moved) |",
                      flush=True)


main()
