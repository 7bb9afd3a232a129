"""What the commands work on: one mesh object (+ a shape) from the selection."""

from __future__ import annotations

import FreeCADGui

from SurfMesh.app import shapes


def is_mesh_object(obj) -> bool:
    if "FemMesh" in obj.PropertiesList:
        return True
    return "Mesh" in obj.PropertiesList and obj.TypeId.startswith("Mesh::")


def has_faces(obj) -> bool:
    try:
        return obj.TypeId.startswith("Part::") or (
            hasattr(obj, "Shape") and not obj.Shape.isNull() and bool(obj.Shape.Faces)
        )
    except Exception:
        return False


def selected_mesh_and_shape():
    """(mesh object, shape object or None) from the selection: exactly one mesh object, plus
    optionally one object with faces. The shape defaults to the one the mesh was made from.
    (None, None) when the selection does not fit."""
    sel = FreeCADGui.Selection.getSelection()
    meshes = [o for o in sel if is_mesh_object(o)]
    others = [o for o in sel if not is_mesh_object(o) and has_faces(o)]
    if len(meshes) != 1 or len(others) > 1:
        return None, None
    mesh = meshes[0]
    shape = others[0] if others else shapes.source_shape_object(mesh)
    return mesh, shape


def selected_meshes():
    return [o for o in FreeCADGui.Selection.getSelection() if is_mesh_object(o)]


def object_ref(obj) -> str:
    """Python expression for a document object, for FreeCADGui.doCommand."""
    return f"App.getDocument({obj.Document.Name!r}).getObject({obj.Name!r})"
