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
        if rep is not None:
            from SurfMesh.app import reports

            text = f"SurfMesh: {mesh.Label}: {reports.measure_text(rep.stats, rep.measure)}"
            FreeCAD.Console.PrintMessage(text + "\n")
            FreeCADGui.getMainWindow().statusBar().showMessage(text, 30000)
        FreeCADGui.updateGui()
