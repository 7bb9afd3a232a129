"""SurfMesh on the meshes FreeCAD's own mesh workbench makes of every CAD part, unperturbed.

For each part of SURFMESH_MP_CAD_DIR (default ../shared/data/cad), two MeshPart meshes:
"standard" (BRepMesh, linear deflection diagonal / 500, angular 0.35) and "mefisto" (maximum
edge length diagonal / 30). Each goes through ``SurfMesh.optimize`` with its defaults, with
``boundary="fixed"`` and ``boundary="slide"``. One Markdown table row per run: triangles,
nodes glued (twins at the same position: the standard mesher's cracks along CAD edges),
tangled elements before → after (how many of those left have a movable node), min / mean
quality before → after, sweeps, time, and the largest distance to the part of a node the run
moved (FreeCAD's ``Shape.distToShape``, on up to 150 moved nodes; ``Mesh.Mesh`` stores float32
points, so about 1e-7 × diagonal is its rounding). ``distToShape`` misses the foot point of
some points on the OCC bottle's thread surfaces (it reports 0.033 for a point that is φ(u,v)
of Face4 at a (u,v) inside the face; ``Surface.parameter`` gives that (u,v) back): where it
reports more than 1e-6 × diagonal, the node is also projected on every face surface
(``Surface.parameter``, kept when ``isPartOfDomain``) and the smaller distance is kept; the row
says how many such nodes the projection put on a face. A mesh SurfMesh refuses gets a row with
the start of the message.

    freecadcmd bench/python/meshpart_parts.py

Options by environment (freecadcmd takes no script options): SURFMESH_MP_CAD_DIR ("built":
the shapes of built_shapes.py — a helical sweep, a loft, a revolved profile, poles —, written to
a temporary directory); SURFMESH_MP_PARTS (comma list of files in SURFMESH_MP_CAD_DIR);
SURFMESH_MP_AMPS (e.g. "0.3,0.6": also runs each mesh SurfMesh takes with its Face nodes moved
in (u,v) by that many × their element size, as perturbed_fem.py does, none of them onto
another CAD entity; default none) and
SURFMESH_MP_SEEDS (default "1,2").
"""

import os
import sys
import time

import numpy as np

import FreeCAD
import MeshPart
import Part
import SurfMesh
from SurfMesh.app import api, conversion

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from perturb import kept_classified, local_sizes, perturbed  # noqa: E402
CAD = os.environ.get(
    "SURFMESH_MP_CAD_DIR", os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared",
                                                         "data", "cad")))
if CAD == "built":
    import tempfile

    import built_shapes

    CAD = built_shapes.write(tempfile.mkdtemp(prefix="surfmesh_built_"))


def points(mesh):
    return np.array([[p.x, p.y, p.z] for p in mesh.Points])


def on_a_face(shape, p):
    """Distance from p to its projection on the nearest face surface whose trimmed domain
    holds that projection (Surface.parameter, isPartOfDomain)."""
    v = FreeCAD.Vector(*map(float, p))
    best = float("inf")
    for f in shape.Faces:
        u, w = f.Surface.parameter(v)
        if f.isPartOfDomain(u, w):
            best = min(best, (f.Surface.value(u, w) - v).Length)
    return best


def max_moved_distance(shape, before, after, limit=150):
    """Largest distance to the part over up to ``limit`` moved nodes, the number of moved
    nodes, and how many of the sample ``distToShape`` put farther than 1e-6 × diagonal and the
    projection on their face did not (see the module doc)."""
    moved = np.nonzero(np.any(after != before, axis=1))[0]
    if moved.size == 0:
        return 0.0, 0, 0
    sample = moved[:: max(1, moved.size // limit)]
    far = 1e-6 * shape.BoundBox.DiagonalLength
    worst, rechecked = 0.0, 0
    for i in sample:
        d = shape.distToShape(Part.Vertex(FreeCAD.Vector(*map(float, after[i]))))[0]
        if d > far:
            d2 = on_a_face(shape, after[i])
            if d2 < d:
                rechecked += d2 <= far
                d = d2
        worst = max(worst, d)
    return worst, moved.size, rechecked


def main():
    default = sorted(f for f in os.listdir(CAD) if f.endswith((".step", ".stp", ".brep")))
    parts = [p for p in os.environ.get("SURFMESH_MP_PARTS", ",".join(default)).split(",") if p]
    amps = [float(x) for x in os.environ.get("SURFMESH_MP_AMPS", "").split(",") if x]
    seeds = [int(x) for x in os.environ.get("SURFMESH_MP_SEEDS", "1,2").split(",") if x]
    perturbations = [(amp, seed) for amp in amps for seed in seeds]
    print("| part | mesher | triangles | glued nodes | boundary | tangled before → after "
          "(movable) | min q before → after | mean q before → after | sweeps | s (of it CAD "
          "recovery) | max distance of moved nodes to the part |")
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
            runs = [("", mesh, points(mesh))]
            for amp, seed in perturbations:
                trial = perturbed_mesh(mesh, shape, amp, seed)
                if trial is None:
                    break  # refused: its unperturbed rows say why
                label = f", Face nodes moved {amp:g} × size (seed {seed})"
                runs.append((label, trial, trial.nodes.astype(np.float32).astype(np.float64)))
            for label, m, p0 in runs:
                for boundary in ("fixed", "slide"):
                    head = f"| {name} | {mesher}{label} | {mesh.CountFacets} |"
                    try:
                        t = time.perf_counter()
                        r = SurfMesh.optimize(m, shape, boundary=boundary)
                        dt = time.perf_counter() - t
                    except ValueError as e:
                        print(f"{head} | {boundary} | refused: {str(e)[:160]} | | | | | |",
                              flush=True)
                        continue
                    b, a = r.before.stats, r.after.stats
                    d, n_moved, rechecked = max_moved_distance(shape, p0, points(r.mesh))
                    note = f", {rechecked} by projection" if rechecked else ""
                    print(f"{head} {r.bridge.get('glued_nodes', 0)} | {boundary} | "
                          f"{b['tangled']} → {a['tangled']} ({len(r.tangled_movable)}) | "
                          f"{b['min']:.3f} → {a['min']:.3f} | {b['mean']:.3f} → "
                          f"{a['mean']:.3f} | {r.sweeps} | {dt:.1f} ({r.bridge['seconds']:.1f}) | "
                          f"{d / diag:.1e} × diag "
                          f"({n_moved} moved{note}) |", flush=True)


def perturbed_mesh(mesh, shape, amp, seed):
    """``mesh`` as arrays with its Face nodes moved (see perturb.py); glued twins move with
    their node. None when SurfMesh refuses the mesh."""
    try:
        data, handle = api.prepare(mesh, shape)
    except ValueError:
        return None
    w = data if data.kept is None else data.subset(data.kept)
    kinds = np.asarray(handle.node_kinds())
    faces = np.asarray(handle.node_faces())
    nodes, moved = perturbed(data, shape, kinds, faces, np.asarray(handle.uv()),
                             local_sizes(data, w), amp, seed)
    nodes, _ = kept_classified(data, shape, nodes, moved, kinds, faces)
    if data.glued is not None:
        nodes = nodes[data.glued]
    raw = conversion.read_mesh(mesh)  # the input's own elements (twins not glued)
    return conversion.MeshData(**{**raw.__dict__, "nodes": nodes})

main()
