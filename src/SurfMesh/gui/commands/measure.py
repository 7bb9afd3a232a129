"""SurfMesh_Measure: color the selected mesh by element quality and store the stats on it."""

from __future__ import annotations

import FreeCAD
import FreeCADGui

from SurfMesh import paths
from SurfMesh.gui import preferences, runner, selection


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
        return FreeCAD.ActiveDocument is not None and len(selection.selected_meshes()) == 1

    def Activated(self):
        mesh, shape = selection.selected_mesh_and_shape()
        if mesh is None:
            runner.show_error("SurfMesh", ValueError("select one mesh object (and its shape)"))
            return
        args = selection.object_ref(mesh)
        if shape is not None:
            args += ", " + selection.object_ref(shape)
        args += f", measure={preferences.measure()!r}"
        try:
            rep = runner.run(f"SurfMesh.measure_object({args})")
        except Exception as exc:
            runner.show_error("SurfMesh: measure", exc)
            return
        if rep is not None:
            FreeCAD.Console.PrintMessage(f"SurfMesh: {mesh.Label}: {rep!r}\n")
        FreeCADGui.updateGui()
