"""GUI test: the SurfMesh_SelectTangled command ("Select tangled elements").

On a FEM mesh (Gmsh, tria3) and a Mesh feature (MeshPart) of the torus, both tangled by moving
nodes in (u,v) as the other GUI tests do, the command run through FreeCADGui.runCommand:
- selects exactly the elements SurfMesh's API measures as tangled (reference: SurfMesh.measure
  with the measure of the preferences, and FreeCAD's own face normal for the sign of each
  triangle): FEM elements as "Elem<id>F1" (what a click on the element selects in FreeCAD
  0.20), Mesh facets as "Facet<index>" (0-based, as FreeCAD's Face info numbers facets);
- says in the report view how many, their ids, and where the first one is (its centroid from
  FreeCAD's own node positions, and its CAD face);
- outlines them in the 3D view (screenshot pixels) until the selection changes;
- leaves the document unchanged (objects, properties, nodes, undo stack, modified flag);
- on a mesh without tangled elements, selects its WORST_ELEMENTS worst elements and says so;
- on bad input (nothing selected, a mesh without a known shape) gives the same clear messages
  as the other commands, no traceback, and changes nothing.
Exit code 0 = pass (tests/gui/README.md).
"""

import os
import re
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, MessageBoxCloser, pixels, report_text  # noqa: E402

code = 1


def outline_pixels(img):
    """Number of pixels in the color of the outlines of selected elements (bright cyan: no
    quality color, background, edge or shading of the mesh comes near it)."""
    import numpy as np

    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return int(np.count_nonzero((b > 0.8) & (g > 0.6) & (r < 0.25)))


try:
    import FreeCAD
    import FreeCADGui
    import numpy as np
    from PySide import QtGui

    assert FreeCAD.GuiUp
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    mw = FreeCADGui.getMainWindow()

    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    check("SurfMesh_SelectTangled" in FreeCADGui.listCommands(), "command registered")
    bars = [b for b in mw.findChildren(QtGui.QToolBar) if b.windowTitle() == "SurfMesh"]
    menus = [m for m in mw.menuBar().actions() if m.text().replace("&", "") == "SurfMesh"]
    check(any("Select tangled elements" in [a.text() for a in b.actions()] for b in bars)
          and any("Select tangled elements" in [a.text() for a in m.menu().actions()]
                  for m in menus), "in the SurfMesh toolbar and menu")
    import MeshPart

    import SurfMesh
    from SurfMesh.app import compat, examples
    from SurfMesh.app.document import WORST_ELEMENTS
    from SurfMesh.gui import preferences, selection

    sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()),
                                    "tests", "python"))
    import surfmesh_testing as T

    measure = preferences.measure()

    # ---- the document: a tangled FEM mesh, a tangled Mesh feature, a clean FEM mesh ----------
    doc = FreeCAD.newDocument("SurfMeshSelectTangled")
    doc.UndoMode = 1
    tor = examples.make_torus(doc)
    fem = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    _, fem_tangled = examples.tangle_to(fem, tor.Shape, target=25, seed=1)
    tri = doc.addObject("Mesh::Feature", "TorusTri")
    tri.Mesh = MeshPart.meshFromShape(Shape=tor.Shape, LinearDeflection=0.2)
    _, tri_tangled = examples.tangle_to(tri, tor.Shape, target=15, seed=2)
    clean = examples.make_gmsh_mesh(doc, tor, 3.0, name="CleanMesh")
    check(fem_tangled > 0 and tri_tangled > 0, f"tangled inputs ({fem_tangled} FEM elements, "
                                                f"{tri_tangled} Mesh facets)")
    for o in (tor, tri, clean):
        o.ViewObject.Visibility = False
    doc.recompute()
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()
    # The FEM mesh is measured (colored) first, as a user would; the Mesh feature is not.
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(fem)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    check("SurfMeshColors" in fem.PropertiesList, "FEM mesh measured and colored")
    doc.recompute()
    doc.saveAs(os.path.join(out, "select_tangled.FCStd"))
    FreeCADGui.runCommand("Std_Save")  # clears the GUI's modified flag (doc.save() does not)
    FreeCADGui.updateGui()
    doc.clearUndos()
    gdoc = FreeCADGui.getDocument(doc.Name)

    def fem_state(obj):
        return T.fem_snapshot(obj.FemMesh)

    def snapshot():
        objs = {}
        for o in doc.Objects:
            props = {}
            for p in o.PropertiesList:
                if p in ("FemMesh", "Mesh", "Shape"):
                    continue
                try:
                    props[p] = repr(getattr(o, p))
                except Exception:
                    props[p] = "?"
            vo = o.ViewObject
            vprops = {p: repr(getattr(vo, p)) for p in vo.PropertiesList if p != "Proxy"}
            # a value whose repr is its address (1.x's ShapeMaterial) says nothing of a change
            props = {k: v for k, v in props.items() if " at 0x" not in v}
            vprops = {k: v for k, v in vprops.items() if " at 0x" not in v}
            objs[o.Name] = (props, vprops, list(o.State))
        return {
            "objects": objs,
            "undo": (doc.UndoCount, list(doc.UndoNames)),
            "redo": doc.RedoCount,
            "pending": bool(getattr(doc, "HasPendingTransaction", False)),
            "modified": gdoc.Modified,
            "fem": fem_state(fem),
            "clean": fem_state(clean),
            "tri": T.mesh_snapshot(tri.Mesh),
        }

    def snapshot_diff(a, b):
        """What differs between two snapshots (for the message of a failed check)."""
        out = [k for k in a if k != "objects" and a[k] != b.get(k)]
        for name, (props, vprops, state) in a["objects"].items():
            p2, v2, s2 = b["objects"].get(name, ({}, {}, []))
            out += [f"{name}.{k}" for k in props if props[k] != p2.get(k)]
            out += [f"{name}.ViewObject.{k}" for k in vprops if vprops[k] != v2.get(k)]
            if state != s2:
                out.append(f"{name}.State {state} -> {s2}")
        return out

    def baseline():
        """The state the command must leave as it is, after the test's own changes (which
        mesh is shown) are saved."""
        FreeCADGui.runCommand("Std_Save")
        FreeCADGui.updateGui()
        if gdoc.Modified and compat.freecad_version() >= (1, 1, 0):
            gdoc.Modified = False  # 1.1's Std_Save leaves the flag set on a document just saved
        state = snapshot()
        check(state["modified"] is False, "saved document unmodified before the command")
        return state

    before = baseline()

    def run_on(objs):
        FreeCADGui.Selection.clearSelection()
        for o in objs:
            FreeCADGui.Selection.addSelection(o)
        start = len(report_text(mw))
        FreeCADGui.runCommand("SurfMesh_SelectTangled")
        FreeCADGui.updateGui()
        return report_text(mw)[start:]

    def selected_subs(obj):
        subs = []
        from SurfMesh.app import compat

        for s in compat.selection_with_subelements(FreeCADGui, doc.Name):
            check(s.ObjectName == obj.Name, f"only {obj.Name} selected (found {s.ObjectName})")
            subs.extend(s.SubElementNames)
        return subs

    def parse(message, noun):
        """(count, ids, (x, y, z), face) of the command's line in the report view."""
        m = re.search(r"SurfMesh: [^\n]*?: (\d+) tangled " + noun + r"s? \([a-z]+ measure\): "
                      + noun + r"s? ([0-9, …]+); (?:the first|it), " + noun
                      + r" (\d+), lies near \(([-0-9.e+]+), ([-0-9.e+]+), ([-0-9.e+]+)\) on "
                      r"(Face\d+)", message)
        check(m is not None, f"report view names the tangled {noun}s ({message[-300:]!r})")
        ids = [int(t) for t in m.group(2).replace("…", "").split(",") if t.strip()]
        first = int(m.group(3))
        return (int(m.group(1)), ids, first,
                tuple(float(m.group(k)) for k in (4, 5, 6)), m.group(7))

    def shot(name):
        path = os.path.join(out, name)
        view.saveImage(path, 800, 600, "White")
        return pixels(path)

    def tangled_reference(nodes, tris):
        """Tangled triangles by FreeCAD's face normal (surfmesh_testing's planar reference)."""
        _, tangled = T.reference_tri_quality(np.asarray(nodes), np.asarray(tris),
                                             tor.Shape.Faces[0])
        return set(np.nonzero(tangled)[0].tolist())

    img0 = shot("select_tangled_before.png")
    check(outline_pixels(img0) == 0, "no outline color in the view before the command")

    # ---- FEM mesh: tangled elements selected ---------------------------------------------
    message = run_on([fem])
    rep = SurfMesh.measure(fem, tor, measure=measure)
    expected = sorted(int(i) for i in rep.element_ids[rep.tangled])
    check(len(expected) == fem_tangled, f"API reference: {len(expected)} tangled elements")
    subs = selected_subs(fem)
    check(sorted(subs) == sorted(f"Elem{i}F1" for i in expected),
          f"FEM: the selection is exactly the {len(expected)} tangled elements (Elem<id>F1)")
    fm = fem.FemMesh
    faces = sorted(fm.Faces)
    node_pos = {k: (v.x, v.y, v.z) for k, v in fm.Nodes.items()}
    node_ids = sorted(node_pos)
    row = {n: i for i, n in enumerate(node_ids)}
    nodes = [node_pos[n] for n in node_ids]
    tris = [[row[n] for n in fm.getElementNodes(e)] for e in faces]
    ref = sorted(faces[k] for k in tangled_reference(nodes, tris))
    check(ref == expected, "FEM: FreeCAD's face normal finds the same tangled elements")
    count, ids, first, where, face = parse(message, "element")
    check(count == len(expected) and ids == expected and first == expected[0],
          f"FEM: report view gives the count ({count}) and the ids, first element {first}")
    centroid = np.mean([node_pos[n] for n in fm.getElementNodes(first)], axis=0)
    check(np.allclose(where, centroid, rtol=1e-5, atol=1e-5) and face == "Face1",
          f"FEM: location of the first element ({where} on {face}; centroid {centroid})")
    check("Elem" in message and "outlined" in message, "message says how they are selected")
    check(sorted(selection.marked(fem)) == sorted(subs), "FEM: selected elements outlined")
    img1 = shot("select_tangled_fem.png")
    n1 = outline_pixels(img1)
    check(n1 > 50, f"FEM: outlines visible in the view ({n1} pixels)")
    now = snapshot()
    check(now == before, "FEM: document unchanged (objects, properties, nodes, undo, "
                         f"modified flag): {snapshot_diff(before, now)}")
    fem.ViewObject.Visibility = False  # the outlines are drawn with the mesh only
    FreeCADGui.updateGui()
    n_hidden = outline_pixels(shot("select_tangled_fem_hidden.png"))
    check(n_hidden == 0, f"FEM: outlines hidden with the mesh ({n_hidden} pixels)")
    fem.ViewObject.Visibility = True
    FreeCADGui.updateGui()
    check(outline_pixels(shot("select_tangled_fem.png")) == n1, "FEM: and shown with it again")
    # The outlines go with the selection.
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.updateGui()
    check(selection.marked(fem) == [], "FEM: outlines removed once the selection is cleared")
    n2 = outline_pixels(shot("select_tangled_fem_cleared.png"))
    check(n2 == 0, f"FEM: no outline left in the view ({n2} pixels)")

    # ---- Mesh feature (no link to its shape): selected together with the shape ------------
    fem.ViewObject.Visibility = False
    tri.ViewObject.Visibility = True
    view.fitAll()
    before = baseline()
    message = run_on([tri, tor])
    rep = SurfMesh.measure(tri, tor, measure=measure)
    expected = sorted(int(i) for i in np.nonzero(rep.tangled)[0])
    check(len(expected) == tri_tangled, f"API reference: {len(expected)} tangled facets")
    subs = selected_subs(tri)
    check(sorted(subs) == sorted(f"Facet{i}" for i in expected),
          f"Mesh: the selection is exactly the {len(expected)} tangled facets (Facet<index>)")
    pts, tris = tri.Mesh.Topology
    ref = sorted(tangled_reference([(p.x, p.y, p.z) for p in pts], tris))
    check(ref == expected, "Mesh: FreeCAD's face normal finds the same tangled facets")
    count, ids, first, where, face = parse(message, "facet")
    check(count == len(expected) and ids == expected and first == expected[0],
          f"Mesh: report view gives the count ({count}) and the indices, first facet {first}")
    facet = tri.Mesh.Facets[first]
    check(facet.Index == first, "Mesh: ids are FreeCAD's facet indices")
    centroid = np.mean([tuple(p) for p in facet.Points], axis=0)
    check(np.allclose(where, centroid, rtol=1e-5, atol=1e-5) and face == "Face1",
          f"Mesh: location of the first facet ({where} on {face})")
    img3 = shot("select_tangled_mesh.png")
    n3 = outline_pixels(img3)
    check(n3 > 50, f"Mesh: outlines visible in the view ({n3} pixels)")
    check(snapshot() == before, "Mesh: document unchanged")
    # Selecting the whole object (a click in the tree) replaces the elements: outlines go.
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(tri)
    FreeCADGui.updateGui()
    check(selection.marked(tri) == [], "Mesh: outlines removed when the selection changes")

    # ---- a mesh without tangled elements: its worst elements ------------------------------
    tri.ViewObject.Visibility = False
    clean.ViewObject.Visibility = True
    before = baseline()
    message = run_on([clean])
    rep = SurfMesh.measure(clean, tor, measure=measure)
    check(rep.stats["tangled"] == 0, "clean mesh has no tangled element")
    subs = selected_subs(clean)
    by_name = {f"Elem{int(i)}F1": k for k, i in enumerate(rep.element_ids)}
    picked = np.zeros(len(rep.quality), dtype=bool)
    picked[[by_name[n] for n in subs if n in by_name]] = True
    others = ~picked & ~rep.skipped
    check(len(subs) == WORST_ELEMENTS and picked.sum() == WORST_ELEMENTS
          and not (picked & rep.skipped).any(),
          f"no tangled element: {WORST_ELEMENTS} measured elements selected")
    check(rep.quality[picked].max() <= rep.quality[others].min(),
          f"they are the worst: quality ≤ {rep.quality[picked].max():.4f} ≤ every other "
          f"element's ({rep.quality[others].min():.4f})")
    m = re.search(r"no tangled element \([a-z]+ measure\); the (\d+) worst, quality "
                  r"[0-9.e-]+ to [0-9.e-]+: elements ([0-9, ]+); the worst, element (\d+)",
                  message)
    check(m is not None, f"report view says none is tangled ({message[-250:]!r})")
    listed = [int(t) for t in m.group(2).split(",")]
    q_listed = [float(rep.quality[by_name[f"Elem{i}F1"]]) for i in listed]
    check(int(m.group(1)) == WORST_ELEMENTS and sorted(f"Elem{i}F1" for i in listed)
          == sorted(subs) and int(m.group(3)) == listed[0] and q_listed == sorted(q_listed),
          "report view names the worst elements, worst first")
    check(snapshot() == before, "worst elements: document unchanged")

    # ---- bad input ----------------------------------------------------------------------------
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.updateGui()
    cmd = FreeCADGui.Command.get("SurfMesh_SelectTangled") if hasattr(FreeCADGui, "Command") \
        else None
    if cmd is not None:
        check(not cmd.isActive(), "nothing selected: the command is disabled, like the others")
    start = len(report_text(mw))
    FreeCADGui.runCommand("SurfMesh_SelectTangled")  # disabled: does nothing
    FreeCADGui.updateGui()
    check(FreeCADGui.Selection.getSelectionEx() == [] and "Traceback" not in
          report_text(mw)[start:], "nothing selected: runCommand does nothing, no traceback")
    from SurfMesh.gui.commands.select_tangled import SelectTangledCommand

    boxes = MessageBoxCloser()
    start = len(report_text(mw))
    SelectTangledCommand().Activated()  # as the menu would if it were enabled
    boxes.stop()
    text = report_text(mw)[start:]
    check(any("select one mesh object" in t for t in boxes.texts)
          and "select one mesh object" in text and "Traceback" not in text,
          f"nothing selected: the clear message ({boxes.texts}, {text.strip()!r})")
    # A Mesh feature alone: no shape known for it (no link, no "(Meshed)" label).
    boxes = MessageBoxCloser()
    message = run_on([tri])
    boxes.stop()
    check(any("no shape known for mesh 'TorusTri'" in t for t in boxes.texts)
          and "no shape known" in message and "Traceback" not in message,
          f"mesh without shape: the clear message ({boxes.texts})")
    check([s.ObjectName for s in FreeCADGui.Selection.getSelectionEx()] == ["TorusTri"]
          and selected_subs(tri) == [], "error: the selection is left as it was")
    # Optimize on it: the same message before any panel opens (OK could only fail there).
    from SurfMesh.gui.commands.optimize import OptimizeCommand

    boxes = MessageBoxCloser()
    OptimizeCommand().Activated()
    boxes.stop()
    FreeCADGui.updateGui()
    check(any("no shape known for mesh 'TorusTri'" in t for t in boxes.texts)
          and not FreeCADGui.Control.activeDialog(),
          f"Optimize on a mesh without shape: the message, no panel ({boxes.texts})")
    check(snapshot() == before, "bad input: document unchanged")

    FreeCAD.closeDocument(doc.Name)
    FreeCADGui.updateGui()
    check(selection._marks == {}, "no outline kept for a closed document")
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_select_tangled", code)
