"""FreeCAD's own FEM examples with a surface mesh, written as case files for bench/peers.py.

    SURFMESH_FEM_OUT=DIR [SURFMESH_FEM_EXAMPLES=name,name] freecadcmd bench/python/fem_examples.py

Builds each example of FreeCAD's ``femexamples`` (shipped with FreeCAD's FEM workbench) whose
mesh holds 2D elements only, headless (``setup()``, then a recompute), and writes into DIR:

* ``fem_NAME.brep``: the Part shape the mesh object is made on (its ``Part`` link);
* ``fem_NAME.unv``: the FEM mesh as FreeCAD writes it (``FemMesh.write``), 2D elements only
  (edge and volume elements dropped; none of these examples has any);
* ``fem_NAME.json``: the same mesh for the Gmsh side of the suite: {"nodes": {id: [x, y, z]},
  "elements": [[id, [node ids in FreeCAD's (SMESH) order]]], "example", "part", "types"}.

The perturbed variants are made from these files by bench/fem_cases.py (in (u, v) of the
shape's faces, with Gmsh's OCC kernel, as the suite's other perturbed cases). A list of the
examples written, {"cases": [{"name", "example", "brep", "unv", "json", "elements", "types"}]},
goes to DIR/fem_examples.json; an example that fails to build is listed with its "error".
"""

import json
import os

import FreeCAD
import Fem
import Part

# The femexamples whose mesh is a surface mesh on a Part shape (FreeCAD 0.20's examples: the
# two square_pipe_end_twisted examples share one mesh, so one of them is enough).
EXAMPLES = [
    "ccx_cantilever_ele_quad4",
    "ccx_cantilever_ele_quad8",
    "ccx_cantilever_ele_tria3",
    "ccx_cantilever_ele_tria6",
    "mystran_plate",
    "rc_wall_2d",
    "buckling_platebuckling",
    "material_multiple_bendingbeam_fivefaces",
    "square_pipe_end_twisted_nodeforces",
    "buckling_lateraltorsionalbuckling",
    "constraint_contact_shell_shell",
]
TYPES = {3: "tria3", 4: "quad4", 6: "tria6", 8: "quad8"}


def surface_only(fem):
    """A FemMesh of the 2D elements of ``fem`` (ids kept) and the nodes they use."""
    out = Fem.FemMesh()
    used = sorted({n for f in fem.Faces for n in fem.getElementNodes(f)})
    for n in used:
        p = fem.getNodeById(n)
        out.addNode(p.x, p.y, p.z, n)
    for f in sorted(fem.Faces):
        out.addFace(list(fem.getElementNodes(f)), f)
    return out


def export(name, out_dir):
    import importlib

    mod = importlib.import_module("femexamples." + name)
    doc = mod.setup()
    try:
        doc.recompute()
        meshes = [o for o in doc.Objects if o.isDerivedFrom("Fem::FemMeshObject")]
        if len(meshes) != 1:
            raise RuntimeError(f"{len(meshes)} mesh objects")
        obj = meshes[0]
        part = getattr(obj, "Part", None)
        if part is None or not isinstance(getattr(part, "Shape", None), Part.Shape):
            raise RuntimeError("the mesh object links no Part shape")
        fem = obj.FemMesh
        if fem.VolumeCount or not fem.FaceCount:
            raise RuntimeError(f"not a surface mesh ({fem.FaceCount} faces, "
                               f"{fem.VolumeCount} volumes)")
        fem = surface_only(fem)
        stem = os.path.join(out_dir, "fem_" + name)
        part.Shape.exportBrep(stem + ".brep")
        fem.write(stem + ".unv")
        elements = [[f, list(fem.getElementNodes(f))] for f in sorted(fem.Faces)]
        types = sorted({TYPES.get(len(n), str(len(n))) for _, n in elements})
        nodes = {n: list(fem.getNodeById(n)) for n in fem.Nodes}
        with open(stem + ".json", "w") as f:
            json.dump({"example": name, "part": part.Name, "types": types, "nodes": nodes,
                       "elements": elements}, f)
        return {"name": name, "example": name, "brep": stem + ".brep", "unv": stem + ".unv",
                "json": stem + ".json", "elements": len(elements), "types": types,
                "faces": len(part.Shape.Faces)}
    finally:
        FreeCAD.closeDocument(doc.Name)


def main():
    out_dir = os.environ["SURFMESH_FEM_OUT"]
    names = [n for n in os.environ.get("SURFMESH_FEM_EXAMPLES", "").split(",") if n] or EXAMPLES
    os.makedirs(out_dir, exist_ok=True)
    cases = []
    for name in names:
        try:
            cases.append(export(name, out_dir))
        except Exception as err:  # noqa: BLE001 - one example's failure is its entry
            cases.append({"name": name, "error": f"{type(err).__name__}: {str(err)[:300]}"})
    with open(os.path.join(out_dir, "fem_examples.json"), "w") as f:
        json.dump({"freecad": ".".join(FreeCAD.Version()[:3]), "cases": cases}, f, indent=1)


main()
