"""GUI test: what the GUI tells a user, and how the Optimize panel reads.

Checks, in the real FreeCAD GUI on a tangled Gmsh FEM mesh of a torus:
- the Optimize tooltip shows "_optimized" as text (no "<name>" swallowed as rich text);
- the preference dialog's SurfMesh group has SurfMesh's icon (not FreeCAD's missing-icon cross):
  its pixels equal those of resources/icons/preferences-surfmesh.svg;
- the Optimize panel names measures and edge modes in words (no raw "oddy"/"slide"), gives the
  distance to the part in mm, keeps its expert settings in an "Advanced" group, disables its
  inputs while a run lasts, and its progress bar ends near 100 % when the run converges long
  before the sweep limit;
- after the run the panel stays open with its outcome: a "Result" table whose before and after
  cells are the counts and qualities measured independently of the run (the invalid count
  green at 0), sweeps and time; the result selected; OK reads "Close", Cancel is gone, the
  inputs keep the run's settings, disabled; a screenshot of the panel shows the green cell;
  "Close" closes it;
- the report view and the status bar say "tangled N → 0, …" with the same counts;
- a run that leaves tangled elements (one sweep) opens a warning dialog that says so, with the
  outcome and the run's warnings as details;
- the color scale stands on a light panel: on a black screenshot the legend's area is mostly
  light (it was black around the labels before).
"""

import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, pixels, report_text  # noqa: E402

code = 1
try:
    import FreeCAD
    import FreeCADGui
    import numpy as np
    from PySide import QtCore, QtGui

    assert FreeCAD.GuiUp
    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/View").SetBool(
        "UseNavigationAnimations", False)
    out = os.environ.get("SURFMESH_TEST_OUTPUT_DIR") or os.path.abspath("build/test-output")
    os.makedirs(out, exist_ok=True)
    os.makedirs(out, exist_ok=True)
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    mw = FreeCADGui.getMainWindow()

    import SurfMesh
    from SurfMesh import paths
    from SurfMesh.app import examples, reports

    # ---- the Optimize tooltip -------------------------------------------------------------
    actions = [a for a in mw.findChildren(QtGui.QAction) if a.objectName() == "SurfMesh_Optimize"]
    check(actions, "the Optimize action exists")
    tip = actions[0].toolTip()
    if tip.lstrip().startswith("<"):  # FreeCAD 1.x gives its tooltips as rich text
        rich = QtGui.QTextDocument()
        rich.setHtml(tip)
        tip = rich.toPlainText()
    check("<name>" not in tip and '"_optimized"' in tip,
          f"the tooltip names the new mesh in words ({tip[:120]!r})")

    # ---- the preference group's icon --------------------------------------------------------
    seen = {}

    def _look():
        w = QtGui.QApplication.activeModalWidget()
        if w is None:
            return
        # the groups' list: a QListWidget in 0.20, a tree view in 1.x
        for view in w.findChildren(QtGui.QAbstractItemView):
            model = view.model()
            if model is None:
                continue
            todo = [QtCore.QModelIndex()]
            while todo:
                parent = todo.pop()
                for row in range(model.rowCount(parent)):
                    index = model.index(row, 0, parent)
                    todo.append(index)
                    if model.data(index, QtCore.Qt.DisplayRole) == "SurfMesh":
                        icon = model.data(index, QtCore.Qt.DecorationRole)
                        if isinstance(icon, QtGui.QIcon):
                            seen["icon"] = icon.pixmap(48, 48).toImage()
        w.reject()

    poke = QtCore.QTimer()
    poke.setInterval(200)
    poke.timeout.connect(_look)
    poke.start()
    FreeCADGui.runCommand("Std_DlgPreferences")
    poke.stop()
    check("icon" in seen, "the preference dialog lists the SurfMesh group")
    ours = QtGui.QIcon(paths.icon("preferences-surfmesh")).pixmap(48, 48).toImage()

    def rgba(img):
        img = img.scaled(32, 32, QtCore.Qt.IgnoreAspectRatio, QtCore.Qt.SmoothTransformation)
        img = img.convertToFormat(QtGui.QImage.Format_RGBA8888)
        ptr = img.constBits()
        return np.frombuffer(bytes(ptr), dtype=np.uint8)[: img.width() * img.height() * 4] \
            .reshape(img.height(), img.width(), 4).astype(float)

    a, b = rgba(seen["icon"]), rgba(ours)
    check(np.abs(a - b).mean() < 12.0,
          f"the group's icon is SurfMesh's (mean difference {np.abs(a - b).mean():.1f})")

    # ---- a tangled FEM mesh ----------------------------------------------------------------
    doc = FreeCAD.newDocument("SurfMeshOutcome")
    doc.UndoMode = 1
    tor = examples.make_torus(doc)
    mesh = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    amp, tangled = examples.tangle_to(mesh, tor.Shape, target=25, seed=1)
    tor.ViewObject.Visibility = False
    doc.recompute()
    view = FreeCADGui.ActiveDocument.ActiveView
    view.viewIsometric()
    view.fitAll()
    before = SurfMesh.measure(mesh, tor)  # measured here, independently of the panel's run
    check(before.stats["tangled"] == tangled > 0, f"{tangled} tangled elements to start with")

    from SurfMesh.gui import preferences
    from SurfMesh.gui.taskpanels.optimize_panel import OptimizePanel

    preferences.set_optimize_settings(dict(SurfMesh.OPTIMIZE_DEFAULTS, boundary="fixed"))
    preferences.set_measure("shape")
    panel = OptimizePanel(mesh, tor)
    FreeCADGui.Control.showDialog(panel)
    FreeCADGui.updateGui()
    m_items = [panel.measure.itemText(i) for i in range(panel.measure.count())]
    b_items = [panel.boundary.itemText(i) for i in range(panel.boundary.count())]
    check(not set(m_items) & set(SurfMesh.measure_names()) and panel.measure.currentData()
          == "shape", f"measures in words ({m_items})")
    check(not set(b_items) & {"fixed", "slide"} and panel.boundary.currentData() == "fixed",
          f"edge modes in words ({b_items})")
    check(panel.tolerance.suffix().strip() == "mm", "the distance to the part has its unit")
    groups = [g for g in panel.form.findChildren(QtGui.QGroupBox) if g.title() == "Advanced"]
    check(len(groups) == 1 and all(groups[0].isAncestorOf(w) for w in (
        panel.rel_tol, panel.over_relaxation, panel.threads, panel.tolerance)),
        "expert settings in an Advanced group")
    check("'shape'" in panel.command() or "measure='shape'" in panel.command(),
          f"the command still passes the API's names ({panel.command()})")

    during = []
    orig_hook = panel._hook

    def watching_hook(info):
        go = orig_hook(info)
        during.append((all(not w.isEnabled() for w in panel.inputs), panel.bar.value(),
                       int(info.get("sweep", 0)), int(info.get("max_sweeps", 1))))
        return go

    panel._hook = watching_hook
    check(panel.accept() is False and FreeCADGui.Control.activeDialog(),
          "the run applies and the panel stays open")
    new = doc.getObject("TorusMesh_optimized")
    check(new is not None and panel.result is new, "the optimized mesh exists")
    check(during and all(d[0] for d in during), "inputs disabled while the run lasts")
    check(not any(w.isEnabled() for w in panel.inputs) and panel.measure.currentData() ==
          "shape", "after it the inputs keep the run's settings, disabled")
    FreeCADGui.updateGui()
    box = panel.form.findChild(QtGui.QGroupBox, "result")
    check(box is not None and box.isVisible(), "the panel shows a Result table")

    def cell(name):
        w = panel.form.findChild(QtGui.QLabel, name)
        return w.text() if w is not None else None

    after_m = SurfMesh.measure(new, tor)  # measured here, independently of the run
    counts = {k: (cell("before_" + k), cell("after_" + k)) for k in
              ("invalid", "tangled", "across")}
    check(counts["invalid"] == (str(before.stats["invalid"]), "0")
          and counts["tangled"] == (str(before.stats["tangled"]),
                                    str(after_m.stats["tangled"]))
          and counts["across"] == (str(before.stats["across"]), str(after_m.stats["across"]))
          and after_m.stats["invalid"] == 0,
          f"its counts are the measured ones (invalid, tangled, across: {counts})")
    check(cell("before_mean") == reports.format_value(before.stats["mean"])
          and cell("after_mean") == reports.format_value(after_m.stats["mean"]),
          f"mean quality {cell('before_mean')} → {cell('after_mean')}")
    check(cell("after_min") == reports.format_value(after_m.stats["min"]),
          f"min quality {cell('before_min')} → {cell('after_min')}")
    check(cell("resultObject") == new.Label and "sweep" in (cell("resultRun") or "")
          and " s (" in cell("resultRun"), f"with the result's name and {cell('resultRun')!r}")
    sel = FreeCADGui.Selection.getSelection()
    check(sel == [new], "the result is selected")
    check(panel.buttons is not None, "FreeCAD handed the panel its buttons")
    ok = panel.buttons.button(QtGui.QDialogButtonBox.Ok)
    cancel = panel.buttons.button(QtGui.QDialogButtonBox.Cancel)
    check(ok is not None and ok.text() == "Close" and ok.isVisible(), "OK reads Close")
    check(cancel is None or not cancel.isVisible(), "Cancel is gone (Undo takes the run back)")
    panel.form.grab().save(os.path.join(out, "gui_outcome_panel_whole.png"))  # (to look at)
    green = panel.form.findChild(QtGui.QLabel, "after_invalid")
    shot = os.path.join(out, "gui_outcome_panel.png")
    green.grab().save(shot)  # the cell as drawn: its text pixels are green
    img = pixels(shot)
    ink = img[img.sum(axis=2) < 2.4]  # not the background
    greenish = ((ink[:, 1] > ink[:, 0] + 0.15) & (ink[:, 1] > ink[:, 2] + 0.15)).mean() \
        if len(ink) else 0.0
    check(len(ink) > 20 and greenish > 0.5,
          f"the 0-invalid cell is drawn green ({greenish:.2f} of {len(ink)} text pixels)")
    status_text = panel.status.text()
    check(status_text == f"Done: {new.Label} (below)", f"the status line ({status_text!r})")
    last_sweep, total = during[-1][2], during[-1][3]
    check(last_sweep < total / 2 and during[-1][1] >= 90,
          f"progress ends near 100 % at sweep {last_sweep} of {total} ({during[-1][1]} %; the "
          f"sweep count alone would give {100 * last_sweep // total} %)")
    check([d[1] for d in during] == sorted(d[1] for d in during), "progress never drops")
    after = SurfMesh.measure(new, tor)
    text = report_text(mw)
    run = dict(new.SurfMeshRun)
    line = f"SurfMesh: {new.Label}: " + reports.outcome_text(
        before.stats, after.stats, int(run["sweeps"]), float(run["seconds"]), run["reason"])
    check(f"{before.stats['tangled']} tangled" in line and "0 tangled" in line, line)
    check(line in text, f"the report view says what the run did ({line!r})")
    # (FreeCAD's status bar elides a long message in its middle: its start is kept)
    check(mw.statusBar().currentMessage().startswith(line[:50]),
          f"so does the status bar ({mw.statusBar().currentMessage()[:100]!r})")
    check(panel.accept() is True and not FreeCADGui.Control.activeDialog(),
          "Close closes the panel")
    check(doc.getObject("TorusMesh_optimized") is new, "and the result stays")

    # ---- a run that leaves tangled elements: a warning dialog -------------------------------
    boxes = []

    def _catch():
        w = QtGui.QApplication.activeModalWidget()
        if isinstance(w, QtGui.QMessageBox):
            boxes.append((w.objectName(), w.text(), w.informativeText(), w.detailedText()))
            w.accept()

    catcher = QtCore.QTimer()
    catcher.setInterval(50)
    catcher.timeout.connect(_catch)
    catcher.start()
    panel2 = OptimizePanel(mesh, tor)
    FreeCADGui.Control.showDialog(panel2)
    panel2.max_sweeps.setValue(1)
    panel2.monotone.setChecked(True)
    check(panel2.accept() is False and panel2.result is not None, "a one-sweep run applies")
    catcher.stop()
    short = doc.Objects[-1]
    red = panel2.form.findChild(QtGui.QLabel, "after_invalid")
    check(red is not None and "c00000" in red.styleSheet() and red.text() != "0",
          f"the panel's invalid count stays red ({red.text() if red else None})")
    check(panel2.accept() is True, "and Close closes it")
    left = SurfMesh.measure(short, tor).stats["tangled"]
    check(left > 0, f"one sweep leaves {left} tangled elements")
    check(len(boxes) == 1 and boxes[0][0] == "SurfMeshTangledLeft"
          and f"{left} element" in boxes[0][1] and "still tangled" in boxes[0][1],
          f"a warning dialog says how many stay tangled ({boxes[:1]})")
    check("→" in boxes[0][2] and "tangled element" in boxes[0][3].lower()
          or "stay tangled" in boxes[0][3], "with the outcome, and the warnings as details")

    # ---- the legend's panel -----------------------------------------------------------------
    short.ViewObject.Visibility = False
    new.ViewObject.Visibility = True
    FreeCADGui.updateGui()
    from SurfMesh.gui import legend

    check(legend.shown(doc), "the color scale is shown")
    shot = os.path.join(out, "gui_outcome_legend.png")
    W, H = 800, 600
    view.saveImage(shot, W, H, "Black")
    img = pixels(shot)
    x0, y0, x1, y1 = legend._PANEL
    cols = slice(int((x0 + 1) / 2 * W) + 3, int((x1 + 1) / 2 * W) - 3)
    rows = slice(int((1 - y1) / 2 * H) + 3, int((1 - y0) / 2 * H) - 3)
    region = img[rows, cols]
    light = (region.mean(axis=2) > 0.75).mean()
    check(light > 0.6, f"the legend stands on a light panel ({light:.2f} of its area light, on "
          "a black background)")
    outside = img[rows, int((x1 + 1) / 2 * W) + 10: int((x1 + 1) / 2 * W) + 40]
    check((outside.mean(axis=2) > 0.75).mean() < 0.5, "and the panel ends where it should")

    # ---- a FEM mesh in an analysis: replaced there, in one undo step -------------------------
    import ObjectsFem

    mesh2 = examples.make_gmsh_mesh(doc, tor, 2.0, name="AnalysisMesh")
    examples.tangle_to(mesh2, tor.Shape, target=10, seed=3)
    analysis = ObjectsFem.makeAnalysis(doc, "Analysis")
    analysis.addObject(mesh2)
    doc.recompute()
    panel3 = OptimizePanel(mesh2, tor)
    FreeCADGui.Control.showDialog(panel3)
    FreeCADGui.updateGui()
    box = panel3.form.findChild(QtGui.QCheckBox, "replaceInAnalysis")
    check(box is not None and box.isVisible() and box.isChecked(),
          "the panel offers to replace the mesh in its analysis, checked")
    check("replace_in_analysis" not in panel3.command(), "(the default of the call)")
    box.setChecked(False)
    check("replace_in_analysis=False" in panel3.command(), "unchecked, the call says so")
    box.setChecked(True)
    undo0 = doc.UndoCount
    check(panel3.accept() is False and panel3.result is not None,
          "the run in the analysis applies")
    panel3.accept()
    result = doc.getObject("AnalysisMesh_optimized")
    check(analysis.Group == [result] and result.Part == tor,
          "the result is the analysis' mesh, linked to the shape")
    check(doc.UndoCount == undo0 + 1, "in one undo step")
    doc.undo()
    FreeCADGui.updateGui()
    check(analysis.Group == [mesh2] and doc.getObject("AnalysisMesh_optimized") is None,
          "undo puts the original back")
    panel4 = OptimizePanel(mesh, tor)  # a mesh in no analysis: no such option shown
    check(not panel4.replace.isVisible() and panel4.analysis is None,
          "no replace option for a mesh in no analysis")

    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_outcome", code, last=None)
