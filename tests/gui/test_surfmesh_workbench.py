"""GUI test: the SurfMesh workbench loads, every command runs on a sample document (FEM tria3
and Mesh), colors are applied (color property + screenshot pixels), the optimize task panel
applies and cancels, the report dialog opens. Exit code 0 = pass (tests/gui/README.md)."""

import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, pixels, reopen  # noqa: E402

code = 1


def shares(img):
    """Shares of green (good quality), yellow/orange (fair/poor) and purple (tangled) among the
    colored pixels of a screenshot (white background and dark edges excluded); hue classes
    survive the view's shading. The color scale at the left of the view is left out."""
    import numpy as np

    img = img[:, int(0.22 * img.shape[1]):]  # without the color scale at the left
    a = img.reshape(-1, 3)
    a = a[(a.sum(axis=1) < 2.85) & (a.max(axis=1) > 0.15)]
    if len(a) == 0:
        return 0.0, 0.0, 0.0
    r, g, b = a.T
    green = float(np.mean((g > 1.25 * r) & (g > 1.25 * b)))
    yellow = float(np.mean((r > 0.8 * g) & (g > 1.5 * b)))
    purple = float(np.mean((b > 1.2 * g) & (r > 1.2 * g)))
    return green, yellow, purple


try:
    import FreeCAD
    import FreeCADGui
    import numpy as np

    assert FreeCAD.GuiUp
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)

    # ---- workbench ----------------------------------------------------------------------
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    wb = FreeCADGui.activeWorkbench()
    check(wb.MenuText == "SurfMesh", "workbench active")
    cmds = FreeCADGui.listCommands()
    for name in ("SurfMesh_Measure", "SurfMesh_SelectTangled", "SurfMesh_Optimize",
                 "SurfMesh_Report", "SurfMesh_ClearColors"):
        check(name in cmds, f"{name} registered")
        res = FreeCADGui.Command.get(name).getInfo() if hasattr(FreeCADGui, "Command") else None
        if res:
            check(os.path.exists(res["pixmap"]) or res["pixmap"], f"{name} icon")
    import SurfMesh
    from SurfMesh import paths
    from SurfMesh.app import coloring, examples

    for name in ("SurfMesh", "SurfMesh_Measure", "SurfMesh_SelectTangled", "SurfMesh_Optimize",
                 "SurfMesh_Report", "SurfMesh_ClearColors"):
        check(os.path.exists(paths.icon(name)), f"icon {name}.svg installed")

    # ---- Edit > Preferences > SurfMesh: the measure of Measure and Select tangled ----------
    from PySide import QtCore as _QtCore
    from PySide import QtGui as _QtGui

    from SurfMesh.gui import preferences as _prefs

    _prefs.set_measure("shape")
    seen = []

    def _pick_oddy():
        w = _QtGui.QApplication.activeModalWidget()
        if w is None:
            return
        pages = w.findChildren(_QtGui.QWidget, "SurfMeshPreferences")
        if pages:
            combo = pages[0].findChild(_QtGui.QComboBox, "measure")
            seen.append(combo.currentText())
            combo.setCurrentIndex(combo.findText("oddy"))
        w.accept()

    poke = _QtCore.QTimer()
    poke.setInterval(200)
    poke.timeout.connect(_pick_oddy)
    poke.start()
    FreeCADGui.runCommand("Std_DlgPreferences")
    poke.stop()
    check(seen == ["shape"] and _prefs.measure() == "oddy",
          f"the preference page shows the measure and stores the one chosen ({seen})")
    _prefs.set_measure("shape")

    # ---- sample document: tangled FEM tria3 torus -----------------------------------------
    doc = FreeCAD.newDocument("SurfMeshGuiTest")
    doc.UndoMode = 1
    tor = examples.make_torus(doc)
    mesh = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    amp, tangled = examples.tangle_to(mesh, tor.Shape, target=25, seed=1)
    tor.ViewObject.Visibility = False
    doc.recompute()
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(mesh)
    check(FreeCADGui.Command.get("SurfMesh_Measure").isActive()
          if hasattr(FreeCADGui, "Command") else True, "Measure active on selection")
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    check("SurfMeshColors" in mesh.PropertiesList, "FEM mesh got its colors")
    from SurfMesh.gui import legend

    check(legend.shown(doc) == "SurfMesh quality (shape)",
          f"the color scale is shown with the measure ({legend.shown(doc)!r})")
    stats = SurfMesh.stats_of(mesh)
    check(stats["tangled"] == tangled and tangled > 0, "stats stored, tangled counted")
    q = np.array(mesh.SurfMeshQuality)
    expected = coloring.quality_rgb(q, q <= 0)
    got = np.array([c[:3] for c in mesh.SurfMeshColors])
    check(np.allclose(got, expected, atol=1e-6), "color property matches the quality")
    # The measured mesh is still selected: FreeCAD's "Shape" selection style would draw it in
    # the selection color over its quality colors; while colored, it draws a bounding box.
    check(mesh.ViewObject.SelectionStyle == "BoundBox", "colored mesh selected as a box")
    check(len(FreeCADGui.Selection.getSelection()) == 1, "the mesh is still selected")
    shot1 = os.path.join(out, "gui_measure.png")
    view.saveImage(shot1, 800, 600, "White")
    img1 = pixels(shot1)
    frac_green, frac_yellow, frac_tangled = shares(img1)
    check(frac_green > 0.3, f"screenshot shows good (green) elements ({frac_green:.3f})")
    check(frac_yellow > 0.03, f"screenshot shows poor (yellow/red) elements ({frac_yellow:.3f})")
    # A tangled element is wound against its neighbours: the view sees its back face, which a
    # FEM view culls by default. Its purple must reach the screen all the same.
    check(mesh.ViewObject.BackfaceCulling is False, "back faces drawn while tangled are shown")
    check(frac_tangled > 0.0, f"screenshot shows the tangled (purple) elements ({frac_tangled:.5f})")

    # ---- optimize through the task panel: cancel, then apply --------------------------------
    from SurfMesh.gui.taskpanels.optimize_panel import OptimizePanel

    from SurfMesh.gui import preferences

    # The panel opens with the last run's settings: start from the optimizer's defaults.
    preferences.set_optimize_settings(dict(SurfMesh.OPTIMIZE_DEFAULTS, boundary="fixed"))
    n_objects = len(doc.Objects)
    undo0 = doc.UndoCount
    panel = OptimizePanel(mesh, tor)
    FreeCADGui.Control.showDialog(panel)
    FreeCADGui.updateGui()
    panel.stop_requested = False
    orig_hook = panel._hook

    def cancelling_hook(info):
        orig_hook(info)
        panel.request_stop()  # the Stop button, pressed during the first sweep
        return False

    panel._hook = cancelling_hook
    check(panel.accept() is False, "cancelled run keeps the panel open")
    check(len(doc.Objects) == n_objects and doc.UndoCount == undo0,
          "cancel leaves the document unchanged")
    check("cancelled" in panel.status.text(), "panel says cancelled")
    panel._hook = orig_hook
    panel.max_sweeps.setValue(200)
    check(panel.monotone.isChecked() is SurfMesh.OPTIMIZE_DEFAULTS["monotone"]
          and panel.over_relaxation.value() == SurfMesh.OPTIMIZE_DEFAULTS["over_relaxation"],
          "panel starts from the optimizer's defaults")
    panel.over_relaxation.setValue(1.5)
    check("over_relaxation=1.5" in panel.command() and "monotone" not in panel.command()
          and "topology" not in panel.command(),
          f"panel passes the options changed, only those ({panel.command()})")
    flip_box = panel.form.findChild(_QtGui.QCheckBox, "topology")
    check(flip_box is panel.topology and flip_box.text() == "Flip edges"
          and not flip_box.isChecked() and panel.options()["topology"] == "none"
          and flip_box in panel.inputs,
          "\"Flip edges\" shown, off by default, disabled with the other inputs during a run")
    from SurfMesh.app import progress as _progress

    stages = []
    with _progress.stage_hook(stages.append):
        check(panel.accept() is False and panel.result is not None,
              "OK runs, the panel stays open with the outcome")
    check(panel.accept() is True and not FreeCADGui.Control.activeDialog(),
          "then OK (Close) closes it")
    check(stages == ["reading the mesh", "placing the nodes on the shape's faces and edges",
                     "optimizing", "measuring the result"],
          f"the run names its stages ({stages})")
    FreeCADGui.updateGui()
    new = doc.getObject("TorusMesh_optimized")
    check(new is not None, "TorusMesh_optimized created")
    check(doc.UndoCount == undo0 + 1, "one undo transaction")
    # The result takes the original's place: the original hidden, the result selected; undo
    # shows the original again, redo hides it again.
    check(mesh.ViewObject.Visibility is False and new.ViewObject.Visibility is True,
          "the original is hidden, the result shown")
    check(FreeCADGui.Selection.getSelection() == [new], "the result is selected")
    doc.undo()
    FreeCADGui.updateGui()
    check(doc.getObject("TorusMesh_optimized") is None and mesh.ViewObject.Visibility is True,
          "undo removes the result and shows the original")
    doc.redo()
    FreeCADGui.updateGui()
    new = doc.getObject("TorusMesh_optimized")
    check(new is not None and mesh.ViewObject.Visibility is False,
          "redo brings the result back and hides the original")
    check(SurfMesh.stats_of(new)["tangled"] == 0, "optimized mesh untangled")
    check("over_relaxation=1.5" in new.SurfMeshRun.get("options", "")
          and "max_sweeps=200" in new.SurfMeshRun.get("options", ""),
          f"the run's options stored on the result ({dict(new.SurfMeshRun)})")
    check(new.SurfMeshRun.get("topology") == "none" and "flips" not in new.SurfMeshRun,
          f"a run without \"Flip edges\" records topology none ({dict(new.SurfMeshRun)})")
    again = OptimizePanel(mesh, tor)
    check(again.over_relaxation.value() == 1.5 and again.max_sweeps.value() == 200
          and again.boundary.currentData() == "fixed" and again.monotone.isChecked(),
          "the panel opens with the settings of the last run")
    preferences.set_optimize_settings(dict(SurfMesh.OPTIMIZE_DEFAULTS, boundary="fixed"))
    fresh = OptimizePanel(mesh, tor)
    check(fresh.over_relaxation.value() == SurfMesh.OPTIMIZE_DEFAULTS["over_relaxation"],
          "settings stored back")
    check(len(new.SurfMeshColors) == len(new.FemMesh.Faces), "optimized mesh colored")
    mesh.ViewObject.Visibility = False
    FreeCADGui.updateGui()
    shot2 = os.path.join(out, "gui_optimized.png")
    view.saveImage(shot2, 800, 600, "White")
    img2 = pixels(shot2)
    frac_green2, frac_yellow2, frac_tangled2 = shares(img2)
    check(frac_green2 > frac_green, f"optimized view is greener ({frac_green2:.3f} > "
                                    f"{frac_green:.3f})")
    check(frac_yellow2 < frac_yellow, "fewer poor elements in the view")
    check(frac_tangled2 < 0.1 * frac_tangled, f"no tangled color left ({frac_tangled2:.5f})")
    check(new.ViewObject.BackfaceCulling is True, "untangled mesh keeps the view's culling")

    # ---- optimize only the faces selected with the mesh ------------------------------------
    # A cylinder's Gmsh mesh with nodes of its side (Face1) moved on the surface: the mesh and
    # Face1 selected, the command's panel lists Face1 and passes it on; the disks' nodes
    # (z = 0 and z = height, FreeCAD's own coordinates) stay, the side is smoothed.
    import types

    from SurfMesh.app import api, conversion
    from SurfMesh.gui import selection
    from SurfMesh.gui.commands import optimize as optimize_command

    cyl = doc.addObject("Part::Cylinder", "Cyl")
    cyl.Radius, cyl.Height = 5.0, 12.0
    doc.recompute()
    cmesh = examples.make_gmsh_mesh(doc, cyl, 1.5, name="CylMesh")
    cdata, chandle = api.prepare(cmesh, cyl)
    side = ((np.asarray(chandle.node_kinds()) == 1) & (np.asarray(chandle.node_faces()) == 0)
            & (cdata.nodes[:, 2] > 2.0) & (cdata.nodes[:, 2] < 10.0))
    moved_in = examples.perturb_on_surface(cdata, cyl.Shape.Faces[0], 0.6, seed=3,
                                           movable=side)
    cmesh.FemMesh = conversion.rebuild(cdata, moved_in)
    doc.recompute()
    q_in = SurfMesh.measure(cmesh, cyl).stats
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(cmesh)
    FreeCADGui.Selection.addSelection(cyl, "Face1")
    check(selection.selected_mesh_and_shape() == (cmesh, cyl)
          and selection.selected_faces(cyl) == ["Face1"], "mesh and a face of its shape selected")
    shown = []
    real_gui = optimize_command.FreeCADGui
    optimize_command.FreeCADGui = types.SimpleNamespace(
        Control=types.SimpleNamespace(showDialog=shown.append))
    try:
        optimize_command.OptimizeCommand().Activated()
    finally:
        optimize_command.FreeCADGui = real_gui
    check(len(shown) == 1 and shown[0].faces.text() == "Face1",
          "the panel lists the selected face")
    fpanel = shown[0]
    check("faces=['Face1']" in fpanel.command(), f"the run is limited to it ({fpanel.command()})")
    FreeCADGui.Control.showDialog(fpanel)
    check(fpanel.accept() is False and fpanel.result is not None, "the run on Face1 applies")
    fpanel.accept()
    FreeCADGui.updateGui()
    cnew = doc.getObject("CylMesh_optimized")
    check(cnew is not None, "CylMesh_optimized created")
    ids = sorted(cnew.FemMesh.Nodes)
    after = np.array([tuple(cnew.FemMesh.Nodes[i]) for i in ids])
    before = np.array([tuple(cmesh.FemMesh.Nodes[i]) for i in ids])
    disks = (np.abs(before[:, 2]) < 1e-9) | (np.abs(before[:, 2] - 12.0) < 1e-9)
    moved = np.linalg.norm(after - before, axis=1) > 0
    check(disks.sum() > 50 and not moved[disks].any(),
          f"the disks' {int(disks.sum())} nodes stay ({int(moved[disks].sum())} moved)")
    check(moved[~disks].sum() > 0.5 * side.sum(),
          f"the side's nodes move ({int(moved[~disks].sum())} of {int((~disks).sum())})")
    q_out = SurfMesh.stats_of(cnew)
    check(q_out["tangled"] == 0 and q_out["mean"] > q_in["mean"],
          f"the side is smoothed (mean {q_in['mean']:.3f} -> {q_out['mean']:.3f}, tangled "
          f"{q_in['tangled']} -> {q_out['tangled']})")
    r_side = np.hypot(after[~disks, 0], after[~disks, 1])
    check(np.abs(r_side - 5.0).max() < 1e-9, "the side's nodes stay on the cylinder")
    for o in (cnew, cmesh, cyl):
        o.ViewObject.Visibility = False

    # ---- report ---------------------------------------------------------------------------
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(new)
    FreeCADGui.runCommand("SurfMesh_Report")
    FreeCADGui.updateGui()
    from SurfMesh.gui import report_dialog

    check(len(report_dialog._open_dialogs) == 1, "report dialog open")
    dlg = report_dialog._open_dialogs[0]
    from PySide import QtGui

    html = dlg.findChild(QtGui.QTextBrowser, "SurfMeshReportTable").toPlainText()
    check("Optimized" in html and "Initial" in html and "Oddy" in html, "report table rows")
    check(dlg.findChild(QtGui.QLabel, "SurfMeshReportHistogram") is not None,
          "histogram shown")
    dlg.close()

    # ---- clear colors -----------------------------------------------------------------------
    FreeCADGui.runCommand("SurfMesh_ClearColors")
    check("SurfMeshColors" not in new.PropertiesList, "colors cleared")
    shot3 = os.path.join(out, "gui_cleared.png")
    view.saveImage(shot3, 800, 600, "White")
    frac_green3 = shares(pixels(shot3))[0]
    check(frac_green3 < 0.5 * frac_green2, f"view no longer green ({frac_green3:.3f})")
    # Clearing is an undo step: undo shows the colors again (FreeCAD restores the properties
    # but not a FEM view's element colors), redo clears them again.
    check(doc.UndoNames[0] == "SurfMesh clear colors",
          f"clearing is an undo step ({doc.UndoNames[:2]})")

    def settled_shot(name):
        for _ in range(3):  # the view follows the document on the next event loop turns
            FreeCADGui.updateGui()
        path = os.path.join(out, name)
        view.saveImage(path, 800, 600, "White")
        return shares(pixels(path))[0]

    FreeCADGui.Selection.clearSelection()
    doc.undo()
    green_undone = settled_shot("gui_clear_undone.png")
    check("SurfMeshColors" in new.PropertiesList and green_undone > 0.8 * frac_green2,
          f"undo of the clearing shows the colors again ({green_undone:.3f}, before "
          f"{frac_green2:.3f})")
    doc.redo()
    green_redone = settled_shot("gui_clear_redone.png")
    check("SurfMeshColors" not in new.PropertiesList and green_redone < 0.5 * frac_green2,
          f"redo clears them again ({green_redone:.3f})")
    FreeCADGui.Selection.addSelection(new)

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(mesh)
    FreeCADGui.runCommand("SurfMesh_ClearColors")
    check("SurfMeshColors" not in mesh.PropertiesList, "tangled mesh's colors cleared")
    check(mesh.ViewObject.BackfaceCulling is True, "clearing gives the view its culling back")
    check(mesh.ViewObject.SelectionStyle == "Shape", "clearing gives the view its selection style")
    FreeCADGui.updateGui()
    check(legend.shown(doc) is None, "no visible colored mesh: no color scale")

    # ---- Mesh object: measure colors through Coloring -----------------------------------------
    import MeshPart

    m = doc.addObject("Mesh::Feature", "TorusTri")
    m.Mesh = MeshPart.meshFromShape(Shape=tor.Shape, LinearDeflection=0.2)
    new.ViewObject.Visibility = False
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(m)
    FreeCADGui.Selection.addSelection(tor)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    check(m.ViewObject.Coloring is True, "Mesh Coloring on")
    check(len(m.SurfMeshColors) == m.Mesh.CountFacets, "Mesh colors per facet")
    shot4 = os.path.join(out, "gui_mesh.png")
    view.fitAll()
    view.saveImage(shot4, 800, 600, "White")
    frac4, frac4y, _ = shares(pixels(shot4))
    check(frac4 + frac4y > 0.5, f"Mesh screenshot shows quality colors ({frac4:.3f}, "
                                f"{frac4y:.3f})")
    # Undo of the measure takes its colors away with its properties (a FEM view's colors too,
    # above: undoing the clearing); redo brings them back.
    FreeCADGui.Selection.clearSelection()
    doc.undo()
    frac4u = settled_shot("gui_mesh_undone.png")
    # (the view's Coloring flag is a view property: 1.1's undo leaves it set, with no colors
    # left to show)
    check("SurfMeshColors" not in m.PropertiesList and frac4u < 0.2 * (frac4 + frac4y),
          f"undo of Measure clears the Mesh colors ({frac4u:.3f}, properties "
          f"{'with' if 'SurfMeshColors' in m.PropertiesList else 'without'} SurfMeshColors, "
          f"Coloring {m.ViewObject.Coloring})")
    doc.redo()
    frac4r = settled_shot("gui_mesh_redone.png")
    check("SurfMeshColors" in m.PropertiesList and abs(frac4r - frac4) < 0.05,
          f"redo shows them again ({frac4r:.3f} vs {frac4:.3f})")

    check(m.ViewObject.Lighting == "One side", "untangled Mesh keeps one-sided lighting")
    # A Mesh view leaves back faces unlit: colors marking a tangled facet light both sides,
    # and clearing them gives the view its own lighting back.
    from types import SimpleNamespace

    marked = np.array(m.SurfMeshQuality)
    marked[:3] = 0.0
    SurfMesh.apply_colors(m, SimpleNamespace(quality=marked, tangled=marked <= 0.0))
    check(m.ViewObject.Lighting == "Two side", "Mesh with tangled facets lit on both sides")
    SurfMesh.clear_colors(m)
    check(m.ViewObject.Lighting == "One side", "clearing gives the Mesh view its lighting back")

    # ---- FEM tria6: node colors (ElementColor draws wrong colors on tria6 in 0.20) ----------
    m.ViewObject.Visibility = False
    m6 = examples.make_gmsh_mesh(doc, tor, 2.5, name="Torus6", order="2nd")
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(m6)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    check(len(m6.SurfMeshColors) == len(m6.FemMesh.Faces), "tria6 colors per element")
    shot5 = os.path.join(out, "gui_tria6.png")
    view.fitAll()
    view.saveImage(shot5, 800, 600, "White")
    g5, y5, _ = shares(pixels(shot5))
    check(g5 + y5 > 0.5, f"tria6 screenshot shows quality colors ({g5:.3f}, {y5:.3f})")

    FreeCAD.closeDocument(doc.Name)

    # ---- colors of a FEM mesh after the document is saved and opened again ----------------
    # FreeCAD saves no FEM view colors: the workbench shows the stored ones again on opening.
    doc = FreeCAD.newDocument("SurfMeshReopen")
    tor = examples.make_torus(doc)
    fem = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    examples.tangle_to(fem, tor.Shape, target=25, seed=1)
    tor.ViewObject.Visibility = False
    doc.recompute()
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    def framing(cam):  # where fit all puts the camera (not its clipping planes)
        return [ln for ln in cam.splitlines() if ln.split()[:1] in (["position"],
                                                                     ["orientation"],
                                                                     ["height"])]

    camera = framing(view.getCamera())
    SurfMesh.measure_object(fem)
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.updateGui()
    view.fitAll()
    from pivy import coin

    boxing = coin.SoGetBoundingBoxAction(coin.SbViewportRegion(800, 600))
    boxing.apply(legend._nodes[doc.Name][0])
    check(boxing.getBoundingBox().isEmpty(), "the color scale has no bounding box")
    check(legend.shown(doc) is not None and framing(view.getCamera()) == camera,
          f"the color scale takes no part in fit all ({camera} {framing(view.getCamera())})")
    shot6 = os.path.join(out, "gui_before_save.png")
    view.saveImage(shot6, 800, 600, "White")
    g6, y6, p6 = shares(pixels(shot6))
    path = os.path.join(out, "surfmesh_reopen.FCStd")
    doc = reopen(doc, path)
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    shot7 = os.path.join(out, "gui_after_reopen.png")
    view.saveImage(shot7, 800, 600, "White")
    g7, y7, p7 = shares(pixels(shot7))
    check(g6 > 0.3 and p6 > 0.0, f"colored before saving ({g6:.3f} green, {p6:.5f} tangled)")
    check(abs(g7 - g6) < 0.05 and abs(y7 - y6) < 0.05 and p7 > 0.5 * p6,
          f"the same colors after opening it again ({g7:.3f} green, {y7:.3f} poor, "
          f"{p7:.5f} tangled)")
    check(not FreeCADGui.getDocument(doc.Name).Modified, "showing them changes nothing")
    check(legend.shown(doc) == "SurfMesh quality (shape)", "and the color scale")
    left = pixels(shot7)[150:450, 5:30]  # the scale's bar, left of the mesh
    check(float(np.mean((left[..., 0] > 0.6) & (left[..., 2] < 0.3))) > 0.3,
          "the scale is drawn (red to green bar at the left)")
    FreeCAD.closeDocument(doc.Name)

    # ---- optimize with "Flip edges" ticked --------------------------------------------------
    doc = FreeCAD.newDocument("SurfMeshFlips")
    tor = examples.make_torus(doc)
    fem = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    examples.tangle_to(fem, tor.Shape, target=25, seed=1)
    doc.recompute()
    preferences.set_optimize_settings(dict(SurfMesh.OPTIMIZE_DEFAULTS, boundary="fixed"))
    panel = OptimizePanel(fem, tor)
    FreeCADGui.Control.showDialog(panel)
    FreeCADGui.updateGui()
    check(not panel.topology.isChecked(), "\"Flip edges\" starts off (the default)")
    panel.topology.setChecked(True)
    check(panel.options()["topology"] == "flip" and "topology='flip'" in panel.command(),
          f"ticked, the panel passes topology='flip' ({panel.command()})")
    check(panel.accept() is False and panel.result is not None, "the run with flips made")
    flipped = panel.result
    run = dict(flipped.SurfMeshRun)
    check(run.get("topology") == "flip", f"the result records topology flip ({run})")
    check(("flips" in run) == ("rewired_elements" in run)
          and ("flips" not in run or (int(run["flips"]) > 0 and run["rewired_elements"])),
          f"and the flips made, with the elements they rewired ({run})")
    check(SurfMesh.stats_of(flipped)["tangled"] == 0, "the mesh with flips untangled")
    check(panel.accept() is True and not FreeCADGui.Control.activeDialog(), "closed")
    remembered = OptimizePanel(fem, tor)
    check(remembered.topology.isChecked(), "the panel remembers \"Flip edges\"")
    preferences.params().SetString("OptimizeTopology", "bogus")
    check(preferences.optimize_settings()["topology"] == "none",
          "an unknown stored value reads as the default")
    preferences.set_optimize_settings(dict(SurfMesh.OPTIMIZE_DEFAULTS, boundary="fixed"))
    reset = OptimizePanel(fem, tor)
    check(not reset.topology.isChecked(), "reset to the default: off")
    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_workbench", code)
