"""GUI test: faults through the Optimize command and its task panel.

1. Cancel in the middle of a run, for real: the panel's OK button starts the optimization, and
   a timer (firing from the event processing the panel does after each sweep) presses the
   panel's Stop button, or the task dialog's Cancel button, once the first sweep is reported.
   The run stops after that sweep (a full run needs more), the document is unchanged (objects,
   undo stack, no open transaction, node coordinates of the mesh, its properties) and the
   panel stays open; OK in the same panel then completes the run.
2. An error in a run (the mesh of another shape): the error is reported (panel status and a
   message box, closed here by a timer), the document is unchanged, the panel stays usable;
   Cancel closes it, and the same command with the right shape then succeeds.
3. An exception raised inside the core's sweep loop (through its progress callback) while the
   panel runs: reported, document unchanged; the next OK in the same panel succeeds.

Exit code 0 = pass (tests/gui/README.md).
"""

import os
import sys
import traceback

sys.path.insert(0, os.path.join(os.environ.get("SURFMESH_REPO", os.getcwd()), "tests", "gui"))
from gui_testing import check, finish, MessageBoxCloser, show_task_panel  # noqa: E402

code = 1


try:
    import FreeCAD
    import FreeCADGui
    from PySide import QtCore, QtGui

    assert FreeCAD.GuiUp
    FreeCADGui.activateWorkbench("SurfMeshWorkbench")
    import SurfMesh
    from SurfMesh.app import examples, progress

    mw = FreeCADGui.getMainWindow()
    doc = FreeCAD.newDocument("SurfMeshGuiFaults")
    doc.UndoMode = 1
    tor = examples.make_torus(doc)
    mesh = examples.make_gmsh_mesh(doc, tor, 2.0, name="TorusMesh")
    amp, tangled = examples.tangle_to(mesh, tor.Shape, target=25, seed=1)
    check(tangled > 0, f"tangled input mesh ({tangled} tangled)")
    far = doc.addObject("Part::Feature", "FarCylinder")
    import Part

    far.Shape = Part.makeCylinder(3, 8, FreeCAD.Vector(100, 0, 0))
    doc.recompute()
    doc.clearUndos()
    FreeCADGui.updateGui()

    def nodes_of(obj):
        fem = obj.FemMesh
        return sorted((i, v.x, v.y, v.z) for i, v in fem.Nodes.items())

    def snapshot():
        return {
            "objects": sorted(o.Name for o in doc.Objects),
            "undo": (doc.UndoCount, list(doc.UndoNames)),
            "redo": doc.RedoCount,
            "pending": bool(getattr(doc, "HasPendingTransaction", False)),
            "nodes": nodes_of(mesh),
            "props": sorted(mesh.PropertiesList),
        }

    def panel_form():
        forms = [w for w in mw.findChildren(QtGui.QWidget, "SurfMeshOptimizePanel")
                 if w.isVisible()]
        return forms[0] if len(forms) == 1 else None

    def task_button(which):
        """The task dialog's OK / Cancel button (the visible QDialogButtonBox that has it)."""
        for box in mw.findChildren(QtGui.QDialogButtonBox):
            b = box.button(which)
            if b is not None and b.isVisible():
                return b
        return None

    def open_panel(shape_obj):
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(mesh)
        if shape_obj is not None:
            FreeCADGui.Selection.addSelection(shape_obj)
        FreeCADGui.runCommand("SurfMesh_Optimize")
        FreeCADGui.updateGui()
        show_task_panel(mw)
        FreeCADGui.updateGui()
        form = panel_form()
        check(form is not None and FreeCADGui.Control.activeDialog(),
              "Optimize command opens its task panel")
        return form

    class Presser:
        """Polls (every 10 ms, also during the panel's event processing between sweeps) until
        `ready()` holds, then clicks `button()` once."""

        def __init__(self, ready, button):
            self.ready, self.button = ready, button
            self.clicked_at = None
            self.timer = QtCore.QTimer()
            self.timer.setInterval(10)
            self.timer.timeout.connect(self.tick)
            self.timer.start()

        def tick(self):
            if self.clicked_at is None and self.ready():
                b = self.button()
                if b is not None and b.isEnabled():
                    self.clicked_at = status.text()
                    self.timer.stop()
                    b.click()

        def stop(self):
            self.timer.stop()

    def sweep_reported():
        return status.text().startswith("sweep ")

    # ---- 1a. Stop button in the middle of a run ----------------------------------------------
    before = snapshot()
    form = open_panel(tor)
    status = form.findChild(QtGui.QLabel, "status")
    stop_button = form.findChild(QtGui.QPushButton, "stop")
    ok = task_button(QtGui.QDialogButtonBox.Ok)
    check(ok is not None and stop_button is not None, "panel has OK and Stop buttons")
    check(not stop_button.isEnabled(), "Stop disabled while idle")
    form.findChild(QtGui.QSpinBox, "max_sweeps").setValue(200)
    presser = Presser(sweep_reported, lambda: stop_button)
    ok.click()  # runs the optimization (returns once it ends)
    presser.stop()
    FreeCADGui.updateGui()
    # (pressed at the first event check after a sweep was reported: sweep 1, or a later one
    # when a sweep takes less than the presser's 10 ms poll)
    check(presser.clicked_at is not None and presser.clicked_at.startswith("sweep "),
          f"Stop pressed during the run, after a sweep ({presser.clicked_at!r})")
    check("cancelled" in status.text(), f"panel says cancelled ({status.text()!r})")
    check(snapshot() == before, "Stop mid-run: document, undo stack and nodes unchanged")
    check(doc.getObject("TorusMesh_optimized") is None, "Stop mid-run: no result object")
    check(panel_form() is form and FreeCADGui.Control.activeDialog(),
          "panel still open after Stop")
    check(not stop_button.isEnabled(), "Stop disabled again after the run")

    # ---- 1b. the task dialog's Cancel button in the middle of a run --------------------------
    cancel = task_button(QtGui.QDialogButtonBox.Cancel)
    check(cancel is not None, "task dialog has a Cancel button")
    presser = Presser(sweep_reported, lambda: task_button(QtGui.QDialogButtonBox.Cancel))
    ok.click()
    presser.stop()
    FreeCADGui.updateGui()
    check(presser.clicked_at is not None and presser.clicked_at.startswith("sweep "),
          f"Cancel pressed during the run, after a sweep ({presser.clicked_at!r})")
    check("cancelled" in status.text(), "panel says cancelled after Cancel")
    check(snapshot() == before, "Cancel mid-run: document, undo stack and nodes unchanged")
    check(panel_form() is form and FreeCADGui.Control.activeDialog(),
          "Cancel during a run stops the run, not the panel")

    # ---- 1c. the same panel then completes a run ---------------------------------------------
    ok.click()
    FreeCADGui.updateGui()
    new = doc.getObject("TorusMesh_optimized")
    check(new is not None, "OK after the cancellations creates TorusMesh_optimized")
    check(panel_form() is form and FreeCADGui.Control.activeDialog(),
          "the panel stays open after a successful run, with its outcome")
    check(form.findChild(QtGui.QGroupBox, "result").isVisible(), "its Result table shown")
    check(ok.text() == "Close" and ok.isVisible(), f"OK now reads Close ({ok.text()!r})")
    cancel_after = task_button(QtGui.QDialogButtonBox.Cancel)
    check(cancel_after is None or not cancel_after.isVisible(), "Cancel gone after the run")
    ok.click()  # Close
    FreeCADGui.updateGui()
    check(not FreeCADGui.Control.activeDialog(), "Close closes the panel")
    check(doc.getObject("TorusMesh_optimized") is new, "the result stays")
    check(doc.UndoCount == before["undo"][0] + 1 and doc.UndoNames[0] == "SurfMesh optimize",
          "one undo step 'SurfMesh optimize'")
    sweeps = int(new.SurfMeshRun["sweeps"])
    check(sweeps > 1, f"a full run takes more than the 1 sweep the cancelled ones did ({sweeps})")
    check(SurfMesh.stats_of(new)["tangled"] == 0, "the completed run untangled the mesh")
    check(nodes_of(mesh) == before["nodes"], "the input mesh is kept as it was")
    doc.undo()
    FreeCADGui.updateGui()
    check(doc.getObject("TorusMesh_optimized") is None and snapshot()["objects"] ==
          before["objects"], "undo removes the result")
    doc.clearUndos()
    before = snapshot()

    # ---- 2. an error, then the GUI is still usable -------------------------------------------
    boxes = MessageBoxCloser()
    form = open_panel(far)  # the mesh does not lie on this shape
    status = form.findChild(QtGui.QLabel, "status")
    ok = task_button(QtGui.QDialogButtonBox.Ok)
    ok.click()
    FreeCADGui.updateGui()
    boxes.stop()
    check(status.text().startswith("error:") and "does not lie on this shape" in status.text(),
          f"panel shows the error ({status.text()[:120]!r})")
    check(any("does not lie on this shape" in t for t in boxes.texts),
          f"a message box named the problem ({[t[:80] for t in boxes.texts]})")
    check(snapshot() == before, "error: document, undo stack and nodes unchanged")
    check(panel_form() is form and FreeCADGui.Control.activeDialog(),
          "panel still open after the error")
    check(not form.findChild(QtGui.QPushButton, "stop").isEnabled(), "no run left active")
    task_button(QtGui.QDialogButtonBox.Cancel).click()  # idle: closes the panel
    FreeCADGui.updateGui()
    check(not FreeCADGui.Control.activeDialog(), "Cancel closes the idle panel")
    check(snapshot() == before, "closing the panel changes nothing")

    # ---- 3. an exception inside the core's sweep loop, then a good run in the same panel ------
    form = open_panel(tor)
    status = form.findChild(QtGui.QLabel, "status")
    ok = task_button(QtGui.QDialogButtonBox.Ok)
    calls = []

    def failing(info):
        calls.append(info["sweep"])
        if info["sweep"] >= 2:
            raise RuntimeError("injected fault in sweep 2")
        return True

    boxes = MessageBoxCloser()
    with progress.hook(failing):
        ok.click()
    FreeCADGui.updateGui()
    boxes.stop()
    check(calls[-1] == 2, f"the fault struck in the middle of the run (sweeps {calls})")
    check("injected fault" in status.text(), f"panel shows the fault ({status.text()[:120]!r})")
    check(any("injected fault" in t for t in boxes.texts), "a message box reported the fault")
    check(snapshot() == before, "fault: document, undo stack and nodes unchanged")
    check(panel_form() is form, "panel still open after the fault")
    ok.click()
    FreeCADGui.updateGui()
    new = doc.getObject("TorusMesh_optimized")
    check(new is not None and SurfMesh.stats_of(new)["tangled"] == 0,
          "OK after the fault completes the run in the same panel")
    check(doc.UndoCount == 1, "exactly one undo step after the faults and the good run")
    check(ok.text() == "Close", "OK reads Close after the good run")
    ok.click()
    FreeCADGui.updateGui()
    check(not FreeCADGui.Control.activeDialog(), "panel closed")

    # The other commands still work after all this.
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(new)
    FreeCADGui.runCommand("SurfMesh_Measure")
    FreeCADGui.updateGui()
    check("SurfMeshColors" in new.PropertiesList, "Measure works afterwards")

    FreeCAD.closeDocument(doc.Name)
    code = 0
except BaseException:
    traceback.print_exc()
finish("test_surfmesh_gui_faults", code, last=4)
