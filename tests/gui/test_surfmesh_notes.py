"""GUI test: the notes on reading a mesh are told once per mesh, in a user's words, with the
details in the Quality report.

Gmsh's second-order FEM mesh of the crank arm (read from tests/data) on its part: *Measure
quality* twice, then *Select tangled elements*; the report view must show each note once
(the three kinds the bridge warns about on this mesh: nodes of no element, elements left
out, side nodes far from their sides), never the bridge's question on the node order; the
Quality report lists the three full texts as details.
"""

import gzip
import os
import shutil
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, report_text  # noqa: E402

code = 1
try:
    import Fem
    import FreeCAD
    import FreeCADGui
    import Part
    from PySide import QtGui

    assert FreeCAD.GuiUp
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR", ".")
    os.makedirs(out, exist_ok=True)
    data = os.environ.get("SURFMESH_TEST_DATA_DIR", os.path.join(os.getcwd(), "tests", "data"))
    inp = os.path.join(out, "gui_notes_crankarm.inp")
    with gzip.open(os.path.join(data, "occt_crankarm_gmsh_order2.inp.gz")) as src, \
            open(inp, "wb") as dst:
        shutil.copyfileobj(src, dst)
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    mw = FreeCADGui.getMainWindow()
    from SurfMesh.gui import preferences

    preferences.set_color_by("quality")
    doc = FreeCAD.newDocument("SurfMeshNotesGui")
    part = doc.addObject("Part::Feature", "CrankArm")
    part.Shape = Part.read(os.path.join(data, "occt_crankarm.brep"))
    mesh = doc.addObject("Fem::FemMeshObject", "Mesh2nd")
    mesh.FemMesh = Fem.read(inp)
    doc.recompute()
    start = len(report_text(mw))
    for command in ("SurfMesh_Measure", "SurfMesh_Measure", "SurfMesh_SelectTangled"):
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(mesh)
        FreeCADGui.Selection.addSelection(part)
        FreeCADGui.runCommand(command)
        FreeCADGui.updateGui()
    text = report_text(mw)[start:]
    for words in ("nodes are used by no face element", "elements are left out",
                  "curved elements have a side node far from their side"):
        n = text.count(words)
        check(n == 1, f"'{words}' told once ({n} times)")
    check("is the node order corners first" not in text and "belong to no element" not in text,
          "not in the bridge's words")
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(mesh)
    FreeCADGui.Selection.addSelection(part)
    FreeCADGui.runCommand("SurfMesh_Report")
    FreeCADGui.updateGui()
    dlg = [w for w in mw.findChildren(QtGui.QDialog, "SurfMeshReport") if w.isVisible()][0]
    items = dlg.findChild(QtGui.QListWidget, "SurfMeshNotesList")
    texts = [items.item(i).text() for i in range(items.count())] if items else []
    check(len(texts) == 3 and any("node order" in t for t in texts),
          f"the report lists the details ({len(texts)})")
    dlg.close()
    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_notes", code, last=None)
