"""SurfMesh_Measure: color the selected mesh by element quality and store the stats on it."""

from __future__ import annotations

import FreeCAD
import FreeCADGui

from SurfMesh import paths
from SurfMesh.gui import preferences, selection


class MeasureCommand:
    def GetResources(self):
        return {
            "Pixmap": paths.icon("SurfMesh_Measure"),
            "MenuText": "Measure quality",
            "ToolTip": "Colors the selected mesh (Mesh or FEM) by element quality on its CAD "
            "shape (red: poor, green: good, purple: tangled) and stores the statistics on it.\n"
            "Select one mesh object, and its shape unless the mesh was made from it.",
        }

    def IsActive(self):
        return selection.one_mesh_selected()

    def Activated(self):
        mesh, rep = selection.run_on_selected_mesh(
            "SurfMesh.measure_object", "SurfMesh: measure", f", measure={preferences.measure()!r}"
        )
        if mesh is None:
            return
        if rep is not None and preferences.color_by() != "quality":
            self._color_by_metric(mesh, preferences.color_by())
        if rep is not None:
            from SurfMesh.app import reports

            text = f"SurfMesh: {mesh.Label}: {reports.measure_text(rep.stats, rep.measure)}"
            FreeCAD.Console.PrintMessage(text + "\n")
            FreeCADGui.getMainWindow().statusBar().showMessage(text, 30000)
        FreeCADGui.updateGui()

    def _color_by_metric(self, mesh, name):
        """Colors the measured mesh by the metric of the preferences (red beyond its
        threshold), and says how many elements are beyond it."""
        from SurfMesh.app import metrics, reports
        from SurfMesh.gui import runner

        _, shape = selection.selected_mesh_and_shape()
        t = preferences.metric_threshold(name)
        args = selection.object_ref(mesh) + f", {name!r}, {t!r}"
        if shape is not None:
            args += ", shape=" + selection.object_ref(shape)
        try:
            beyond = runner.run(f"SurfMesh.color_by_metric({args})")
        except Exception as exc:
            runner.show_error("SurfMesh: color by metric", exc)
            return
        info = metrics.METRICS[name]
        sign = ">" if info["worse"] == "high" else "<"
        FreeCAD.Console.PrintMessage(
            f"SurfMesh: {mesh.Label}: colored by {info['label'].lower()}: {beyond} element(s) "
            f"{sign} {reports.format_value(mesh.SurfMeshThreshold, 3)} in red\n")
