"""GUI test: *Select tangled elements* names every face the tangled elements lie on.

A Gmsh FEM mesh of a box, with one node near the middle of each of two faces pushed across its
neighbours in the face's plane (so both faces get tangled elements). The report view's line
must list the faces with their counts, checked against the faces found here for each tangled
element's centroid with Part's distToShape (the nearest face of the box).
"""

import os
import re
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, report_text  # noqa: E402

code = 1
try:
    import FreeCAD
    import FreeCADGui
    import numpy as np
    import Part

    assert FreeCAD.GuiUp
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    mw = FreeCADGui.getMainWindow()
    import SurfMesh
    from SurfMesh.app import api, conversion, examples
    from SurfMesh.gui import preferences

    preferences.set_measure("shape")
    doc = FreeCAD.newDocument("SurfMeshSelectFaces")
    box = doc.addObject("Part::Box", "Box")
    box.Length, box.Width, box.Height = 10.0, 10.0, 10.0
    doc.recompute()
    mesh = examples.make_gmsh_mesh(doc, box, 2.0, name="BoxMesh")
    doc.recompute()
    data = conversion.read_mesh(mesh)
    _, handle = api.prepare(mesh, box.Shape)
    node_faces = np.asarray(handle.node_faces())
    nodes = data.nodes.copy()
    for f in (0, 3):  # Face1 and Face4
        face = box.Shape.Faces[f]
        c = np.array(tuple(face.CenterOfMass))
        on = np.nonzero(node_faces == f)[0]
        k = on[np.argmin(np.linalg.norm(nodes[on] - c, axis=1))]
        u, v = face.Surface.parameter(FreeCAD.Vector(*nodes[k]))
        du = face.derivative1At(u, v)[0]
        step = 2.6 * np.array(tuple(du)) / du.Length  # across its neighbours, in the plane
        nodes[k] = nodes[k] + step
    mesh.FemMesh = conversion.rebuild(data, nodes)
    doc.recompute()
    rep = SurfMesh.measure(mesh, box)
    tangled = np.nonzero(rep.tangled)[0]
    check(len(tangled) > 1, f"{len(tangled)} tangled elements")
    # the face of each tangled element, found here: the box face nearest its centroid
    data = conversion.read_mesh(mesh)
    expected = {}
    for e in tangled:
        c = FreeCAD.Vector(*data.nodes[data.element(int(e))].mean(axis=0))
        d = [f.distToShape(Part.Vertex(c))[0] for f in box.Shape.Faces]
        name = f"Face{int(np.argmin(d)) + 1}"
        expected[name] = expected.get(name, 0) + 1
    check(len(expected) == 2, f"they lie on two faces ({expected})")

    start = len(report_text(mw))
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(mesh)
    FreeCADGui.Selection.addSelection(box)
    FreeCADGui.runCommand("SurfMesh_SelectTangled")
    FreeCADGui.updateGui()
    text = report_text(mw)[start:]
    m = re.search(r"they lie on (\d+) faces: ((?:Face\d+ \(\d+\)(?:, )?)+)", text)
    check(m is not None, f"the report view lists the faces ({text[-300:]!r})")
    listed = {f: int(n) for f, n in re.findall(r"(Face\d+) \((\d+)\)", m.group(2))}
    check(listed == expected, f"every face with its count ({listed} == {expected})")
    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_select_faces", code, last=None)
