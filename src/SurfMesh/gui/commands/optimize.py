"""SurfMesh_Optimize: smooth and untangle the selected mesh on its shape (task panel)."""

from __future__ import annotations

import FreeCADGui

from SurfMesh import paths
from SurfMesh.gui import selection


class OptimizeCommand:
    def GetResources(self):
        return {
            "Pixmap": paths.icon("SurfMesh_Optimize"),
            "MenuText": "Optimize mesh",
            "ToolTip": "Smooths and untangles the selected mesh on its CAD shape; nodes move "
            "in the surfaces' parameters and never leave the CAD geometry.\nCreates a new "
            "mesh named after the original with \"_optimized\" added (the original is kept). "
            "Select one mesh object, and its shape "
            "unless the mesh was made from it; select faces of the shape to optimize only the "
            "elements on them.",
        }

    def IsActive(self):
        return selection.one_mesh_selected() and not FreeCADGui.Control.activeDialog()

    def Activated(self):
        mesh, shape = selection.selected_mesh_or_say()
        if mesh is None:
            return
        why = selection.why_not_optimizable(mesh, shape)
        if why:
            from SurfMesh.gui import runner

            runner.show_error("SurfMesh: optimize", ValueError(why))
            return
        from SurfMesh.gui.taskpanels.optimize_panel import OptimizePanel

        FreeCADGui.Control.showDialog(OptimizePanel(mesh, shape, selection.selected_faces(shape)))
