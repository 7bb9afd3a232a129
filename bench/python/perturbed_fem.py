"""SurfMesh on perturbed FreeCAD Gmsh FEM meshes (second order by default).

Meshes each part with FreeCAD's Gmsh mesher (``examples.make_gmsh_mesh``, the mesh FreeCAD's
FEM users get), moves every node SurfMesh classifies as a Face node to a random (u,v) on its
face, ``amp`` × its local element size away (kept only when inside the face's trimmed domain,
``Face.isPartOfDomain``, and when SurfMesh still classifies it as a node of that face: a node
moved within a CAD edge's own tolerance of that edge would be an Edge node by FreeCAD's rule,
held there), then runs ``SurfMesh.optimize`` with its defaults and prints one
Markdown table row per run: tangled elements before → after (how many of those left have a
movable node), min / mean quality, sweeps, time, and the largest distance to its CAD face of
a node the optimization moved, measured by FreeCAD (``Face.distToShape``, every such node), and
to the face's whole surface (``Face.Surface.toShape().distToShape``, or the distance to the
point ``Surface.parameter`` projects it to when that is smaller). The two differ for a node
inside its face but within the face's tolerance of a trimming loop: ``distToShape`` (OCC's
BRepExtrema) counts a point within the face's 3D tolerance, taken in (u,v), of a loop as ON,
not IN, and measures it to the loop's 3D edge.

    freecadcmd bench/python/perturbed_fem.py

Options by environment (freecadcmd takes no script options): SURFMESH_PF_PARTS (comma list of
files in SURFMESH_PF_CAD_DIR, default ../shared/data/cad), SURFMESH_PF_DIV (element size =
diagonal / DIV, 25), SURFMESH_PF_ORDER (2nd or 1st), SURFMESH_PF_AMPS (0,0.3,0.6; 0: the mesher's mesh as it is),
SURFMESH_PF_SEEDS (1,2), SURFMESH_PF_RECOMBINE (1: Gmsh's quadrilaterals, RecombineAll; with the
1st order), SURFMESH_PF_MESH_DIR (a directory: each mesh is read from there when it holds one
of the same part, size, order and recombination, else made and written there as .unv —
FreeCAD's Gmsh does not always give the same mesh twice, so comparing two revisions needs the
same file).
"""

import argparse  # Namespace only
import os
import sys
import time

import numpy as np

import FreeCAD
import Fem
import Part
import SurfMesh
from SurfMesh.app import api, conversion, examples

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from perturb import kept_classified, local_sizes, perturbed  # noqa: E402


def main():
    env = os.environ.get
    a = argparse.Namespace(
        parts=env("SURFMESH_PF_PARTS",
                  "occt_crankarm.brep,nist_pmi_1.step,occt_screw.step,gmsh_rod_revolution.brep"),
        div=float(env("SURFMESH_PF_DIV", "25")),
        order=env("SURFMESH_PF_ORDER", "2nd"),
        amps=env("SURFMESH_PF_AMPS", "0,0.3,0.6"),
        seeds=env("SURFMESH_PF_SEEDS", "1,2"),
        recombine=env("SURFMESH_PF_RECOMBINE", "0") == "1",
        cad_dir=env("SURFMESH_PF_CAD_DIR",
                    os.path.join(HERE, "..", "..", "..", "shared", "data", "cad")),
        mesh_dir=env("SURFMESH_PF_MESH_DIR", ""),
    )
    print("| part | mesh | amp | seed | Face nodes moved | tangled before → after (movable) "
          "| min q after | mean q after | sweeps | optimize s | max distance to the face "
          "| max distance to its surface |")
    print("|---|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    for name in a.parts.split(","):
        doc = FreeCAD.newDocument("perturbed_fem")
        part = doc.addObject("Part::Feature", "Part")
        part.Shape = Part.read(os.path.join(a.cad_dir, name))
        doc.recompute()
        shape = part.Shape
        diag = shape.BoundBox.DiagonalLength
        stored = ""
        if a.mesh_dir:
            stem = os.path.splitext(name)[0]
            stored = os.path.join(a.mesh_dir, f"{stem}_div{a.div:g}_{a.order}"
                                  f"{'_quads' if a.recombine else ''}.unv")
        if stored and os.path.exists(stored):
            mesh = Fem.read(stored)
            made = "read"
        else:
            t = time.perf_counter()
            mesh = examples.make_gmsh_mesh(doc, part, diag / a.div, order=a.order,
                                           recombine=a.recombine)
            made = f"Gmsh {time.perf_counter() - t:.0f} s"
            if stored:
                os.makedirs(a.mesh_dir, exist_ok=True)
                mesh.FemMesh.write(stored)
        data, handle = api.prepare(mesh, shape)
        w = data if data.kept is None else data.subset(data.kept)
        kinds = np.asarray(handle.node_kinds())
        faces = np.asarray(handle.node_faces())
        uv = np.asarray(handle.uv())
        size = local_sizes(data, w)
        kind = {(False, "1st"): "tria3", (False, "2nd"): "tria6", (True, "1st"): "quad4",
                (True, "2nd"): "quad8"}[(a.recombine, a.order)]
        label = f"{kind} diag/{a.div:g} ({w.element_count} el., {made})"
        amps = [float(x) for x in a.amps.split(",")]
        runs = [(amp, seed) for amp in amps if amp > 0 for seed in a.seeds.split(",")]
        if 0.0 in amps:
            runs.insert(0, (0.0, "-"))  # the mesher's own mesh
        face_nodes = np.nonzero(kinds == 1)[0]
        for amp, seed in runs:
            if amp == 0.0:
                nodes, moved = data.nodes, face_nodes[:0]
            else:
                nodes, moved = perturbed(data, shape, kinds, faces, uv, size, amp, int(seed))
                # Not into a CAD edge's tolerance band: the rule below would hold it there.
                nodes, moved = kept_classified(data, shape, nodes, moved, kinds, faces,
                                               hints="tolerance")
            trial = conversion.MeshData(**{**data.__dict__, "nodes": nodes})
            try:
                # FreeCAD's node-on-entity rule, as for the FEM object itself (its
                # Face nodes moved, the others where the mesher put them).
                r = SurfMesh.optimize(trial, shape, hints="tolerance")
            except Exception as err:  # one failing run must not hide the others
                print(f"| {name} | {label} | {amp} | {seed} | {len(moved)} | error: "
                      f"{str(err)[:200]} | | | | | | |", flush=True)
                continue
            # The nodes the optimization moved (after the perturbation).
            shifted = face_nodes[np.linalg.norm(r.nodes[face_nodes] - nodes[face_nodes],
                                                axis=1) > 0.0]
            dist = surf_dist = 0.0
            surfaces = {}
            for i in shifted:
                q = FreeCAD.Vector(*map(float, r.nodes[i]))
                p = Part.Vertex(q)
                f = shape.Faces[int(faces[i])]
                dist = max(dist, f.distToShape(p)[0])
                if int(faces[i]) not in surfaces:
                    surfaces[int(faces[i])] = f.Surface.toShape()
                # OCC's extrema miss the foot point of some points on B-spline surfaces (1.9e-5
                # for a point 1.6e-14 from its surface on nist_pmi_1): the smaller of that and
                # the distance to the surface's own projection (Surface.parameter).
                u, v = f.Surface.parameter(q)
                surf_dist = max(surf_dist, min(surfaces[int(faces[i])].distToShape(p)[0],
                                               (f.Surface.value(u, v) - q).Length))
            movable = len(r.tangled_movable)
            print(f"| {name} | {label} | {amp} | {seed} | {len(moved)} | "
                  f"{r.before.stats['tangled']} → {r.after.stats['tangled']} ({movable}) | "
                  f"{r.after.stats['min']:.4f} | {r.after.stats['mean']:.4f} | {r.sweeps} | "
                  f"{r.seconds:.1f} | {dist / diag:.1e} × diag | {surf_dist / diag:.1e} × diag |",
                  flush=True)
        FreeCAD.closeDocument(doc.Name)


main()
