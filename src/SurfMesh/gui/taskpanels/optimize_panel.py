"""Task panel of SurfMesh_Optimize: the quality measure, what the nodes on CAD edges do, the
faces whose elements to optimize (those selected with the mesh; empty: the whole mesh), the
sweep limit, the monotone mode and edge flips; for a FEM mesh in an analysis, whether the
result replaces it there; in an "Advanced" group the distance to the part, the stopping
tolerance, over-relaxation and threads (the panel opens with the settings of the last run
applied).

OK runs SurfMesh.optimize_object through FreeCADGui.doCommand with a progress hook that
drives the panel's progress bar (against the run's stopping rule) while its inputs are
disabled; Cancel (or Stop) during a run stops it and leaves the document unchanged; Cancel
when idle closes the panel. After a run the panel stays open with its outcome: a "Result"
table (before → after: invalid elements, minimum and mean quality; sweeps and time), the
result selected, OK renamed "Close" and Cancel gone (Edit → Undo takes the run back). The
report view and the status bar say the same, and a dialog warns when elements stay tangled.
"""

from __future__ import annotations

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from SurfMesh import paths
from SurfMesh.app import api, compat, document, options, progress, reports
from SurfMesh.gui import preferences, runner, selection


class OptimizePanel:
    def __init__(self, mesh, shape, faces=None):
        self.mesh = mesh
        self.shape = shape
        self.initial_faces = list(faces or [])
        self.running = False
        self.stop_requested = False
        self.result = None
        self.outcome = None
        self.buttons = None  # the task dialog's button box (modifyStandardButtons)
        self.form = self._build_form()

    # ---- form ------------------------------------------------------------------------------
    def _build_form(self):
        w = QtGui.QWidget()
        w.setObjectName("SurfMeshOptimizePanel")
        w.setWindowTitle("Optimize surface mesh")
        w.setWindowIcon(QtGui.QIcon(paths.icon("SurfMesh_Optimize")))
        lay = QtGui.QFormLayout(w)
        info = QtGui.QLabel(
            f"Mesh: <b>{self.mesh.Label}</b><br>Shape: <b>"
            f"{self.shape.Label if self.shape is not None else '(none: select one)'}</b>"
        )
        lay.addRow(info)
        self.measure = QtGui.QComboBox()
        self.measure.setObjectName("measure")
        names = api.measure_names()
        for name in names:
            self.measure.addItem(reports.measure_label(name), name)
        cur = preferences.measure()
        if cur in names:
            self.measure.setCurrentIndex(names.index(cur))
        self.measure.setToolTip("The element quality the run improves")
        lay.addRow("Quality measure", self.measure)
        last = preferences.optimize_settings()  # the settings of the last run applied
        self.boundary = QtGui.QComboBox()
        self.boundary.setObjectName("boundary")
        for mode in api.BOUNDARY_MODES:
            self.boundary.addItem(reports.BOUNDARY_LABELS.get(mode, mode), mode)
        self.boundary.setCurrentIndex(list(api.BOUNDARY_MODES).index(last["boundary"]))
        self.boundary.setToolTip("Whether the nodes on the part's edges stay where they are, "
                                 "or slide along the edges (the nodes on corners always stay)")
        lay.addRow("Edges", self.boundary)
        self.high_order = QtGui.QComboBox()
        self.high_order.setObjectName("high_order")
        for mode in options.HIGH_ORDER_MODES:
            self.high_order.addItem(reports.HIGH_ORDER_LABELS.get(mode, mode), mode)
        self.high_order.setCurrentIndex(list(options.HIGH_ORDER_MODES).index(last["high_order"]))
        self.high_order.setToolTip(
            "Second- and higher-order elements: measured against their straight-sided "
            "counterpart on the surface (corners smoothed, side nodes where interpolating the "
            "face puts them: affine on a plane), or by the paper's integral measure, which may "
            "curve straight sides. Linear meshes are the same either way")
        lay.addRow("Curved elements", self.high_order)
        self.topology = QtGui.QCheckBox("Flip edges")
        self.topology.setObjectName("topology")
        self.topology.setChecked(last["topology"] == "flip")
        self.topology.setToolTip(
            "Edge flips between the smoothing runs: two triangles of one face swap their "
            "diagonal when that raises the pair's smaller quality or makes an invalid pair "
            "valid. Node ids and element ids are kept; quads and triangles of order 3 and "
            "higher are not flipped (off: the nodes move, the elements keep their nodes)")
        lay.addRow(self.topology)
        self.faces = QtGui.QLineEdit(", ".join(self.initial_faces))
        self.faces.setObjectName("faces")
        self.faces.setPlaceholderText("all")
        self.faces.setToolTip(
            "Optimize only the elements on these faces of the shape (e.g. Face3, Face7; the "
            "faces selected with the mesh): the nodes of the other elements stay. Empty: the "
            "whole mesh"
        )
        lay.addRow("Only faces", self.faces)
        self.max_sweeps = QtGui.QSpinBox()
        self.max_sweeps.setObjectName("max_sweeps")
        self.max_sweeps.setRange(1, 100000)
        self.max_sweeps.setValue(last["max_sweeps"])
        self.max_sweeps.setToolTip("The run stops after this many passes over the nodes at "
                                   "the latest")
        lay.addRow("Max. sweeps", self.max_sweeps)
        self.monotone = QtGui.QCheckBox("Never lower the minimum quality")
        self.monotone.setObjectName("monotone")
        self.monotone.setChecked(bool(last["monotone"]))
        self.monotone.setToolTip(
            "Once the mesh is untangled, reject node moves that would lower its minimum quality "
            "(off: improve the quality of the mesh as a whole alone)"
        )
        lay.addRow(self.monotone)
        self.analysis = document.analysis_of(self.mesh) if "FemMesh" in getattr(
            self.mesh, "PropertiesList", []) else None
        self.replace = QtGui.QCheckBox("Replace the mesh in its analysis")
        self.replace.setObjectName("replaceInAnalysis")
        self.replace.setChecked(self.analysis is not None)
        self.replace.setVisible(self.analysis is not None)
        self.replace.setToolTip(
            "The optimized mesh takes this mesh's place in "
            f"{self.analysis.Label if self.analysis is not None else 'its analysis'}, linked to "
            "the same shape; this mesh leaves the analysis and stays in the document. Undo "
            "brings it back")
        if self.analysis is not None:
            lay.addRow(self.replace)
        lay.addRow(self._build_advanced(last))
        # what a run disables while it lasts
        self.inputs = [self.measure, self.boundary, self.high_order, self.topology, self.faces,
                       self.max_sweeps, self.monotone, self.replace, self.tolerance,
                       self.rel_tol, self.over_relaxation, self.threads]
        self._add_run_controls(lay)
        return w

    def _build_advanced(self, last):
        """The "Advanced" group: distance to the part, stopping tolerance, over-relaxation,
        threads (``last``: the settings of the last run applied)."""
        advanced = QtGui.QGroupBox("Advanced")
        advanced.setObjectName("advanced")
        adv = QtGui.QFormLayout(advanced)
        self.tolerance = QtGui.QDoubleSpinBox()
        self.tolerance.setObjectName("tolerance")
        self.tolerance.setDecimals(6)
        self.tolerance.setRange(0.0, 1e6)
        self.tolerance.setSuffix(" mm")
        self.tolerance.setSpecialValueText("automatic")
        self.tolerance.setToolTip("Largest distance of a node from the part for it to count as "
                                  "lying on it (0: chosen from the part's size and tolerances)")
        adv.addRow("Distance to the part", self.tolerance)
        self.rel_tol = QtGui.QDoubleSpinBox()
        self.rel_tol.setObjectName("rel_tol")
        self.rel_tol.setDecimals(8)
        self.rel_tol.setRange(1e-8, 1.0)
        self.rel_tol.setSingleStep(1e-5)
        self.rel_tol.setValue(last["rel_tol"])
        self.rel_tol.setToolTip("Once untangled, the run stops when a sweep improves the mesh by "
                                "less than this fraction")
        adv.addRow("Stop below an improvement of", self.rel_tol)
        self.over_relaxation = QtGui.QDoubleSpinBox()
        self.over_relaxation.setObjectName("over_relaxation")
        self.over_relaxation.setDecimals(2)
        self.over_relaxation.setRange(1.0, 1.99)
        self.over_relaxation.setSingleStep(0.1)
        self.over_relaxation.setValue(last["over_relaxation"])
        self.over_relaxation.setToolTip(
            "Once untangled, a node first tries this multiple of its Newton step (kept only when "
            "it lowers the objective); 1 = plain Gauss-Seidel"
        )
        adv.addRow("Over-relaxation", self.over_relaxation)
        self.threads = QtGui.QSpinBox()
        self.threads.setObjectName("threads")
        self.threads.setRange(0, 256)
        self.threads.setSpecialValueText("all")
        self.threads.setValue(last["threads"])
        self.threads.setToolTip("Processor threads the run uses (the result does not depend on "
                                "it)")
        adv.addRow("Threads", self.threads)
        return advanced

    def _add_run_controls(self, lay):
        """The progress bar, the status line, the Stop button and the (hidden) result table."""
        self.bar = QtGui.QProgressBar()
        self.bar.setObjectName("progress")
        self.bar.setRange(0, 100)
        self.bar.setValue(0)
        lay.addRow(self.bar)
        self.status = QtGui.QLabel("")
        self.status.setObjectName("status")
        self.status.setWordWrap(True)
        lay.addRow(self.status)
        self.stop = QtGui.QPushButton("Stop")
        self.stop.setObjectName("stop")
        self.stop.setEnabled(False)
        self.stop.clicked.connect(self.request_stop)
        lay.addRow(self.stop)
        self.result_box = QtGui.QGroupBox("Result")
        self.result_box.setObjectName("result")
        self.result_grid = QtGui.QGridLayout(self.result_box)
        self.result_box.setVisible(False)
        lay.addRow(self.result_box)

    def _show_result(self, new):
        """Fills the "Result" table (once: the panel closes after its run) with what the run
        that made ``new`` did: before → after for the validity counts and the quality, the
        sweeps and the time; the "After" of the validity row in red when invalid elements
        remain, in green when none do."""
        before, after = document.stats_of(new, before=True), document.stats_of(new)
        run = dict(new.SurfMeshRun)
        grid = self.result_grid

        def cell(text, row, col, name=None, bold=False):
            label = QtGui.QLabel(text)
            label.setWordWrap(True)
            if name:
                label.setObjectName(name)
            if bold:
                label.setStyleSheet("font-weight: bold")
            grid.addWidget(label, row, col)
            return label

        head = cell(f"{new.Label}", 0, 0, "resultObject", bold=True)
        head.setToolTip("The optimized mesh (selected); the original stays unchanged")
        cell("Before", 0, 1, bold=True)
        cell("After", 0, 2, bold=True)
        rows = reports.outcome_rows(before, after)
        for i, (key, label, b, a) in enumerate(rows, start=1):
            cell(label, i, 0)
            cell(b, i, 1, f"before_{key}")
            done = cell(a, i, 2, f"after_{key}")
            if key == "invalid":
                done.setStyleSheet("color: #008000; font-weight: bold" if a == "0"
                                   else "color: #c00000; font-weight: bold")
        run_label = QtGui.QLabel(reports.run_text(int(run.get("sweeps", 0)),
                                                  float(run.get("seconds", 0.0)),
                                                  run.get("reason", "")))
        run_label.setObjectName("resultRun")
        run_label.setToolTip("Sweeps over the nodes, the run's time and why it stopped")
        grid.addWidget(run_label, len(rows) + 1, 0, 1, 3)
        undo = QtGui.QLabel("Edit → Undo takes the run back.")
        undo.setObjectName("resultUndo")
        grid.addWidget(undo, len(rows) + 2, 0, 1, 3)
        self.result_box.setVisible(True)

    def face_names(self):
        """The faces of the "Only faces" field ("Face3, 7" → ["Face3", "Face7"]); empty: all."""
        return api.face_list(self.faces.text())

    def options(self):
        return {
            "measure": self.measure.currentData(),
            "boundary": self.boundary.currentData(),
            "tolerance": self.tolerance.value() or None,
            "rel_tol": self.rel_tol.value(),
            "max_sweeps": self.max_sweeps.value(),
            "monotone": self.monotone.isChecked(),
            "over_relaxation": self.over_relaxation.value(),
            "threads": self.threads.value(),
            "high_order": self.high_order.currentData(),
            "topology": "flip" if self.topology.isChecked() else "none",
        }

    def command(self):
        o = self.options()
        args = [selection.object_ref(self.mesh)]
        if self.shape is not None:
            args.append("shape=" + selection.object_ref(self.shape))
        args.append(f"measure={o['measure']!r}")
        args.append(f"boundary={o['boundary']!r}")
        if o["tolerance"] is not None:
            args.append(f"tolerance={o['tolerance']!r}")
        defaults = options.optimize_defaults()  # (the core's)
        for k in ("rel_tol", "max_sweeps", "monotone", "over_relaxation", "threads",
                  "high_order", "topology"):
            if o[k] != defaults[k]:
                args.append(f"{k}={o[k]!r}")
        faces = self.face_names()
        if faces:
            args.append(f"faces={faces!r}")
        if self.analysis is not None and not self.replace.isChecked():
            args.append("replace_in_analysis=False")  # (the default for a mesh in an analysis)
        return "SurfMesh.optimize_object(" + ", ".join(args) + ")"

    # ---- running ---------------------------------------------------------------------------
    def request_stop(self):
        if self.running:
            self.stop_requested = True
            self.status.setText("stopping…")

    def _stage(self, text):
        """A stage of the run: the bar shows "busy" outside the sweeps."""
        self.bar.setRange(0, 100 if text == "optimizing" else 0)
        self.status.setText(f"{text}…")
        QtGui.QApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)

    def _hook(self, info):
        self.bar.setRange(0, 100)
        self.bar.setValue(int(round(100 * self.rule.update(info))))
        self.status.setText(
            f"sweep {info.get('sweep')}: {info.get('tangled')} tangled, "
            f"min quality {reports.format_value(float(info.get('min_quality', 0.0)), 3)}"
        )
        QtGui.QApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)
        return not self.stop_requested

    def run(self):
        """Runs the optimization; returns the new object, or None (cancelled or failed)."""
        if self.running:
            return None
        self.running = True
        self.stop_requested = False
        self.stop.setEnabled(True)
        for w in self.inputs:
            w.setEnabled(False)
        self.bar.setValue(0)
        self.rule = progress.StopRuleProgress(self.rel_tol.value(), self.max_sweeps.value())
        preferences.set_measure(self.measure.currentData())
        preferences.set_optimize_settings(self.options())
        try:
            with progress.hook(self._hook), progress.stage_hook(self._stage):
                new = runner.run(self.command())
        except api.Cancelled:
            self.status.setText("cancelled: the document is unchanged")
            FreeCAD.Console.PrintMessage("SurfMesh: optimization cancelled, nothing changed\n")
            return None
        except Exception as exc:  # bad input, core error: the document is unchanged
            self.status.setText(f"error: {exc}")
            runner.show_error("SurfMesh: optimize", exc)
            return None
        finally:
            self.running = False
            self.stop.setEnabled(False)
            for w in self.inputs:
                w.setEnabled(True)
            if self.bar.maximum() == 0:
                self.bar.setRange(0, 100)
        self.result = new
        self.bar.setRange(0, 100)
        self.bar.setValue(100)
        self.outcome = document.outcome_of(new)
        self.status.setText(f"Done: {new.Label} (below)")
        self._done(new)
        left = (document.stats_of(new) or {}).get("tangled", 0)
        if left:
            self._warn_left_tangled(new, int(left))
        return new

    def _done(self, new):
        """The panel after a run: its outcome shown, the result selected, the inputs kept as
        the run used them, OK renamed "Close" and Cancel gone (the run is in the document;
        Edit → Undo takes it back)."""
        for w in self.inputs:
            w.setEnabled(False)
        self.stop.setVisible(False)
        self._show_result(new)
        new.Document.recompute()
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(new)
        FreeCADGui.getMainWindow().statusBar().showMessage(
            f"SurfMesh: {new.Label}: {self.outcome}", 60000)
        if self.buttons is not None:
            try:
                ok = self.buttons.button(QtGui.QDialogButtonBox.Ok)
                cancel = self.buttons.button(QtGui.QDialogButtonBox.Cancel)
                if ok is not None:
                    ok.setText("Close")
                    ok.setToolTip("Close this panel (the optimized mesh stays)")
                if cancel is not None:
                    cancel.setVisible(False)
            except RuntimeError:  # the box was deleted with its dialog
                self.buttons = None

    def _warn_left_tangled(self, new, left):
        """The dialog a run that left tangled elements shows: the outcome, and the run's
        warnings (which elements, why, what to try) under "Show Details"."""
        box = QtGui.QMessageBox(FreeCADGui.getMainWindow())
        box.setObjectName("SurfMeshTangledLeft")
        box.setIcon(QtGui.QMessageBox.Warning)
        box.setWindowTitle("SurfMesh: optimize")
        box.setText(f"{left} element{'s' if left != 1 else ''} of {new.Label} "
                    f"{'are' if left != 1 else 'is'} still tangled: a solver will reject the "
                    "mesh.")
        box.setInformativeText(self.outcome)
        warnings = document.run_warnings(new)
        if warnings:
            box.setDetailedText("\n\n".join(warnings))
        box.setStandardButtons(QtGui.QMessageBox.Ok)
        box.exec_()

    # ---- task dialog protocol --------------------------------------------------------------
    def getStandardButtons(self):
        return compat.qt_flags(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def modifyStandardButtons(self, box):
        """FreeCAD hands over the dialog's button box: kept to rename OK after the run."""
        self.buttons = box
        ok = box.button(QtGui.QDialogButtonBox.Ok)
        if ok is not None:
            ok.setToolTip("Optimize the mesh with these settings")

    def _gone(self):
        """What of the panel's mesh and shape was deleted (or its document closed), or None."""
        for what, obj in (("mesh", self.mesh), ("shape", self.shape)):
            try:
                if obj is not None and obj.Document is None:
                    return what
            except (ReferenceError, RuntimeError):
                return what
        return None

    def accept(self):
        if self.running:
            return False
        if self.result is not None:  # "Close" after the run
            FreeCADGui.Control.closeDialog()
            return True
        gone = self._gone()
        if gone is not None:
            runner.show_error("SurfMesh: optimize", ValueError(
                f"the {gone} of this panel was deleted (or its document closed): nothing to "
                "optimize"))
            FreeCADGui.Control.closeDialog()
            return True
        if self.shape is None:
            self.status.setText("no shape: close, select the mesh and its shape, try again")
            return False
        self.run()
        return False  # open: with the outcome after a run, or after a cancel or an error

    def reject(self):
        if self.running:
            self.request_stop()
            return False
        FreeCADGui.Control.closeDialog()
        return True
