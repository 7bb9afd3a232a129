"""Shapes: resolving the CAD shape a mesh lies on, and handing it to the core as BREP text.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations


def _type_id(obj):
    try:
        return obj.TypeId
    except Exception:
        return ""


def is_part_shape(obj) -> bool:
    import Part

    return isinstance(obj, Part.Shape)


def shape_of(obj):
    """The Part.Shape of ``obj``: a Part.Shape itself or a document object with ``.Shape``.
    Raises ValueError for anything else or for a shape without faces."""
    if obj is None:
        raise ValueError("no shape given: pass a Part.Shape or a document object with .Shape")
    if is_part_shape(obj):
        shape = obj
    else:
        shape = getattr(obj, "Shape", None) if hasattr(obj, "isDerivedFrom") else None
        if shape is None or not is_part_shape(shape):
            label = getattr(obj, "Label", None)
            what = f"object {label!r}" if label else repr(obj)
            raise ValueError(f"{what} has no CAD shape (expected a Part.Shape or an object with .Shape)")
    if shape.isNull():
        raise ValueError("the shape is null (empty)")
    if not shape.Faces:
        raise ValueError("the shape has no faces: a mesh can only be measured on CAD faces")
    return shape


def brep_string(shape) -> str:
    """BREP text of a shape (what the core's CadShape.from_brep_string reads)."""
    return shape.exportBrepToString()


def source_shape_object(mesh_obj):
    """The document object a mesh object was made from, when it is known:
    ``FemMeshGmsh.Part`` (and the other FEM mesh objects' ``Part`` / ``Shape`` link), the
    ``SurfMeshSource`` link SurfMesh stores on the objects it creates, or the source recorded
    by MeshPart's task panel (``Mesh::Feature`` objects created from a shape have no link:
    then None)."""
    from SurfMesh.app.compat import MESH_SHAPE_LINKS

    for prop in ("SurfMeshSource",) + MESH_SHAPE_LINKS:
        if prop in getattr(mesh_obj, "PropertiesList", []):
            target = getattr(mesh_obj, prop)
            if target is not None and hasattr(target, "Shape") and hasattr(target, "isDerivedFrom"):
                if not target.Shape.isNull() and target.Shape.Faces:
                    return target
    # A "<shape label> (Meshed)" mesh made by MeshPart's task panel: match the label.
    label = getattr(mesh_obj, "Label", "")
    doc = getattr(mesh_obj, "Document", None)
    if doc is not None and label.endswith(" (Meshed)"):
        base = label[: -len(" (Meshed)")]
        for obj in doc.getObjectsByLabel(base):
            if hasattr(obj, "Shape") and not obj.Shape.isNull() and obj.Shape.Faces:
                return obj
    return None
