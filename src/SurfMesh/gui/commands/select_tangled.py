"""SurfMesh_SelectTangled: select the tangled elements of the selected mesh (the worst ones when
none is tangled) and say where they are."""

from __future__ import annotations

import FreeCAD
import FreeCADGui

from SurfMesh import paths
from SurfMesh.gui import preferences, selection


class SelectTangledCommand:
    def GetResources(self):
        from SurfMesh.app.document import WORST_ELEMENTS

        return {
            "Pixmap": paths.icon("SurfMesh_SelectTangled"),
            "MenuText": "Select tangled elements",
            "ToolTip": "Measures the selected mesh (Mesh or FEM) on its CAD shape and selects "
            "its tangled elements, outlined in the 3D view; when none is tangled, its "
            f"{WORST_ELEMENTS} worst elements.\nThe report view lists their ids and where the "
            "first one is. The document is not changed. Select one mesh object, and its shape "
            "unless the mesh was made from it.",
        }

    def IsActive(self):
        return selection.one_mesh_selected()

    def Activated(self):
        mesh, pick = selection.run_on_selected_mesh(
            "SurfMesh.app.document.tangled_elements",
            "SurfMesh: select tangled elements",
            f", measure={preferences.measure()!r}",
        )
        if mesh is None:
            return
        names = selection.select_elements(mesh, pick.ids, pick.corners, pick.centers)
        shown = ", ".join(f"{mesh.Name}.{n}" for n in names[:3]) + (", …" if len(names) > 3
                                                                    else "")
        FreeCAD.Console.PrintMessage(
            f"SurfMesh: {mesh.Label}: {pick.summary()}. Selected as {shown}; FreeCAD draws no "
            f"selected mesh {pick.noun}, so they are outlined in the 3D view while selected.\n"
        )
        FreeCADGui.updateGui()
