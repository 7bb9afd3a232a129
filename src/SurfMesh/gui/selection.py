"""What the commands work on: one mesh object (+ a shape) from the selection; and selecting
elements of a mesh (sub-elements of its object, outlined in the 3D view while selected)."""

from __future__ import annotations

import FreeCADGui

from SurfMesh.app import api, compat, document, shapes


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


def selected_faces(shape_obj):
    """FreeCAD names ("Face3") of the faces of ``shape_obj`` picked in the selection, in the
    order of their numbers; empty when none is (the whole mesh is then optimized)."""
    if shape_obj is None:
        return []
    names = set()
    for sel in FreeCADGui.Selection.getSelectionEx():
        if sel.Object is shape_obj:
            names.update(n for n in sel.SubElementNames if n.startswith("Face"))
    return sorted(names, key=lambda n: int(n[4:]) if n[4:].isdigit() else 0)


def why_not_optimizable(mesh, shape):
    """Why the Optimize panel would fail on ``mesh`` whatever its settings (no shape known, a
    volume mesh), in words; None when it may run."""
    if shape is None:
        try:
            document.resolve_shape(mesh)
        except ValueError as exc:
            return str(exc)
    fem = getattr(mesh, "FemMesh", None) if "FemMesh" in mesh.PropertiesList else None
    if fem is not None and fem.VolumeCount > 0:
        return f"{mesh.Label!r}: " + api.volume_mesh_refusal(fem.VolumeCount)
    return None


def selected_meshes():
    return [o for o in FreeCADGui.Selection.getSelection() if is_mesh_object(o)]


def object_ref(obj) -> str:
    """Python expression for a document object, for FreeCADGui.doCommand."""
    return f"App.getDocument({obj.Document.Name!r}).getObject({obj.Name!r})"


def one_mesh_selected() -> bool:
    """Whether a command on one mesh applies: a document is open and one mesh is selected."""
    import FreeCAD

    return FreeCAD.ActiveDocument is not None and len(selected_meshes()) == 1


def selected_mesh_or_say():
    """selected_mesh_and_shape(), after telling the user what to select when it does not fit."""
    mesh, shape = selected_mesh_and_shape()
    if mesh is None:
        from SurfMesh.gui import runner

        runner.show_error("SurfMesh", ValueError(
            "select one mesh object, and at most one shape (the one it lies on; none when the "
            "mesh was made from it)"))
    return mesh, shape


def run_on_selected_mesh(function, title, extra=""):
    """Runs ``function(mesh[, shape]<extra>)`` (Python text, e.g. "SurfMesh.measure_object")
    on the selected mesh and its shape through runner.run, so that the console shows the call.
    Returns (mesh, what it returned), or (None, None) after telling the user what to select or
    what went wrong (a message box titled ``title``)."""
    from SurfMesh.gui import runner

    mesh, shape = selected_mesh_or_say()
    if mesh is None:
        return None, None
    try:
        return mesh, runner.run(f"{function}({call_arguments(mesh, shape)}{extra})")
    except Exception as exc:
        runner.show_error(title, exc)
        return None, None


def call_arguments(mesh, shape, shape_keyword=False) -> str:
    """The arguments of a SurfMesh call on ``mesh`` and ``shape`` (when not None; passed as
    ``shape=`` when shape_keyword), as Python for FreeCADGui.doCommand."""
    args = object_ref(mesh)
    if shape is not None:
        args += (", shape=" if shape_keyword else ", ") + object_ref(shape)
    return args


# ---- selecting mesh elements -----------------------------------------------------------------
#
# What FreeCAD 0.20.2 does with mesh sub-elements (tried in its GUI):
# - FreeCADGui.Selection.addSelection(doc, obj, sub) stores any sub-element name on a FEM mesh
#   or a Mesh object without checking it, and neither view draws a selected sub-element;
# - a click on a FEM mesh selects "Elem<id>F1" (<id>: the FEM element id; F1: its face), a
#   click on a Mesh object selects the whole object (the Mesh view names no facet);
# - FreeCAD numbers facets from 0 (Mesh > Face info says "Facet 26" for mesh.Facets[26]).
# So a FEM element is selected by the name a click gives it, a facet as "Facet<index>", and the
# selected elements are outlined in the 3D view (on top of the mesh, which hides a tangled
# element folded under its neighbours) while any of them stays selected.

#: Color of the outlines and centre markers of the selected elements (apart from the quality
#: colors: red to green, purple).
MARK_RGB = (0.0, 0.85, 1.0)
MARK_LINE_WIDTH = 3.0
_marks = {}  # (document name, object name) -> (outline node, sub-element names)
_observer = None
_check_pending = False


def element_names(obj, ids):
    """Sub-element names of elements ``ids`` of mesh object ``obj`` in FreeCAD's selection:
    "Elem<id>F1" for FEM element ids (what a click on the element selects), "Facet<index>"
    for 0-based Mesh facet indices."""
    if "FemMesh" in obj.PropertiesList:
        return [f"Elem{int(i)}F1" for i in ids]
    return [f"Facet{int(i)}" for i in ids]


def select_elements(obj, ids, corners=None, centers=None):
    """Makes elements ``ids`` of mesh object ``obj`` the selection (sub-elements, see
    element_names) and outlines them in the 3D view (``corners``: the corner positions of
    each, ``centers``: a marker each; global coordinates) until none of them is selected.
    Returns the sub-element names."""
    names = element_names(obj, ids)
    unmark(obj)
    FreeCADGui.Selection.clearSelection()
    if names:
        FreeCADGui.Selection.addSelection(obj, names)
        if corners is not None or centers is not None:
            _mark(obj, corners or [], centers or [], names)
    return names


def marked(obj):
    """Sub-element names of ``obj`` outlined in the 3D view (empty when none)."""
    entry = _marks.get((obj.Document.Name, obj.Name))
    return sorted(entry[1]) if entry else []


def unmark(obj=None):
    """Removes the outlines of ``obj`` (of all objects when None) from the 3D view."""
    keys = list(_marks) if obj is None else [(obj.Document.Name, obj.Name)]
    for key in keys:
        entry = _marks.pop(key, None)
        target = _object(key)
        vo = getattr(target, "ViewObject", None) if target is not None else None
        if entry is not None and vo is not None:
            for mode in _display_modes(vo):
                if mode.findChild(entry[0]) >= 0:
                    mode.removeChild(entry[0])


def _object(key):
    """The document object of a (document name, object name) key; None once it is gone."""
    import FreeCAD

    doc = FreeCAD.listDocuments().get(key[0])
    return doc.getObject(key[1]) if doc is not None else None


def _display_modes(vo):
    """The nodes of the view's display modes (children of its mode switch): what they hold is
    drawn while the object is shown, in its display mode."""
    from pivy import coin

    switch = vo.SwitchNode
    modes = (switch.getChild(i) for i in range(switch.getNumChildren()))
    return [m for m in modes if m.isOfType(coin.SoGroup.getClassTypeId())]


def _mark(obj, corners, centers, names):
    """Adds the outlines to the object's own scene graph, in each of its display modes (drawn
    with the object in every view, hidden with it, gone with it): local coordinates, under an
    SoAnnotation (drawn last, over the mesh), not pickable (a click still picks the mesh)."""
    import FreeCAD
    from pivy import coin

    vo = getattr(obj, "ViewObject", None)
    if vo is None:
        return
    inv = obj.Placement.inverse()

    def local(p):
        v = inv.multVec(FreeCAD.Vector(*map(float, p)))
        return (v.x, v.y, v.z)

    node = coin.SoAnnotation()
    node.setName("SurfMeshSelectedElements")
    pick = coin.SoPickStyle()
    pick.style = coin.SoPickStyle.UNPICKABLE
    light = coin.SoLightModel()
    light.model = coin.SoLightModel.BASE_COLOR
    binding = coin.SoMaterialBinding()  # the mesh's own per-vertex / per-face binding
    binding.value = coin.SoMaterialBinding.OVERALL  # reaches here through its mode switch
    color = coin.SoBaseColor()
    color.rgb.setValue(*MARK_RGB)
    style = coin.SoDrawStyle()
    style.style = coin.SoDrawStyle.FILLED
    style.lineWidth = MARK_LINE_WIDTH
    for child in (pick, light, binding, color, style):
        node.addChild(child)
    points, index = [], []
    for poly in corners:
        start = len(points)
        points.extend(local(p) for p in poly)
        index.extend(list(range(start, len(points))) + [start, -1])
    if points:
        coords = coin.SoCoordinate3()
        coords.point.setValues(0, len(points), points)
        lines = coin.SoIndexedLineSet()
        lines.coordIndex.setValues(0, len(index), index)
        node.addChild(coords)
        node.addChild(lines)
    if centers:
        coords = coin.SoCoordinate3()
        coords.point.setValues(0, len(centers), [local(c) for c in centers])
        markers = coin.SoMarkerSet()
        markers.markerIndex = FreeCADGui.getMarkerIndex("CIRCLE_FILLED", 9)
        node.addChild(coords)
        node.addChild(markers)
    for mode in _display_modes(vo):
        mode.addChild(node)
    _marks[(obj.Document.Name, obj.Name)] = (node, set(names))
    _watch_selection()


class _SelectionObserver:
    """Removes the outlines of elements no longer selected (checked once the selection has
    settled: a command changes it in several steps)."""

    def addSelection(self, doc, obj, sub, pnt):
        _schedule_check()

    def removeSelection(self, doc, obj, sub):
        _schedule_check()

    def setSelection(self, doc):
        _schedule_check()

    def clearSelection(self, doc):
        _schedule_check()


def _watch_selection():
    global _observer
    if _observer is None:
        _observer = _SelectionObserver()
        FreeCADGui.Selection.addObserver(_observer)


def _schedule_check():
    global _check_pending
    if _check_pending or not _marks:
        return
    _check_pending = True
    from PySide import QtCore

    QtCore.QTimer.singleShot(0, _check_marks)


def _check_marks():
    global _check_pending
    _check_pending = False
    for key, (_, names) in list(_marks.items()):
        try:
            if _object(key) is None:  # deleted, or its document closed: its outlines too
                _marks.pop(key, None)
                continue
            selected = set()
            for sel in compat.selection_with_subelements(FreeCADGui, key[0]):
                if sel.ObjectName == key[1]:
                    selected.update(sel.SubElementNames)
            if not selected & names:
                unmark(_object(key))
        except Exception as exc:  # an observer must not raise into FreeCAD's selection
            import FreeCAD

            _marks.pop(key, None)
            FreeCAD.Console.PrintWarning(f"SurfMesh: outlines of the selected elements: {exc}\n")
