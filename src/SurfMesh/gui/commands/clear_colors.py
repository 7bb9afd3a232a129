"""SurfMesh_ClearColors: remove the quality colors from the selected meshes."""

from __future__ import annotations

import FreeCAD

from SurfMesh import paths
from SurfMesh.gui import runner, selection


class ClearColorsCommand:
    def GetResources(self):
        return {
            "Pixmap": paths.icon("SurfMesh_ClearColors"),
            "MenuText": "Clear quality colors",
            "ToolTip": "Removes the quality colors from the selected meshes (their stored "
            "statistics are kept).",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and len(selection.selected_meshes()) > 0

    def Activated(self):
        for mesh in selection.selected_meshes():
            try:
                runner.run(f"SurfMesh.clear_colors({selection.object_ref(mesh)})")
            except Exception as exc:
                runner.show_error("SurfMesh: clear colors", exc)
