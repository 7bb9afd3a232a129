"""What differs between the FreeCAD releases SurfMesh runs in (0.20.2 on Debian bookworm, 1.0 on
trixie, 1.1 on sid), in one place. Each function says which releases do what; every other module
asks here instead of testing versions itself (tests/python/test_compat.py checks each one on the
FreeCAD it runs in). Headless: nothing here imports FreeCADGui.
"""

from __future__ import annotations

import sys


def freecad_version() -> tuple:
    """FreeCAD's (major, minor, patch) as integers, e.g. (0, 20, 2) or (1, 0, 0)."""
    import FreeCAD

    out = []
    for part in FreeCAD.Version()[:3]:
        digits = "".join(ch for ch in str(part) if ch.isdigit())
        out.append(int(digits) if digits else 0)
    return tuple(out)


def script_args(argv=None) -> list:
    """The arguments given to a script run as ``freecadcmd script.py -- a b``: ``[a, b]``.
    FreeCAD 0.20 sets ``sys.argv = [script, "--", a, b]``, 1.x ``[freecadcmd, script, "--", a,
    b]``; a script run by plain Python (``python3 script.py a b``) gets ``[a, b]`` too."""
    argv = list(sys.argv if argv is None else argv)
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return argv[1:]


#: The properties by which a FEM mesh object links the shape it meshes: Gmsh's mesh object calls
#: it ``Part`` in 0.20 and ``Shape`` in 1.x; the Netgen one ``Shape`` in both.
MESH_SHAPE_LINKS = ("Part", "Shape")


def mesh_shape_link(mesh_obj):
    """Name of the property of ``mesh_obj`` that links the shape it was made from (``Part`` or
    ``Shape``, see MESH_SHAPE_LINKS), or None when it has none."""
    props = getattr(mesh_obj, "PropertiesList", [])
    for name in MESH_SHAPE_LINKS:
        if name in props and mesh_obj.getTypeIdOfProperty(name) == "App::PropertyLink":
            return name
    return None


def set_mesh_shape(mesh_obj, shape_obj):
    """Links ``mesh_obj`` (a FEM mesh object) to ``shape_obj`` through whichever of ``Part`` /
    ``Shape`` it has (a plain FEM mesh object, which has neither, gets ``Part``)."""
    name = mesh_shape_link(mesh_obj)
    if name is None:
        mesh_obj.addProperty("App::PropertyLink", "Part", "FEM Mesh",
                             "The shape the mesh was made from")
        name = "Part"
    setattr(mesh_obj, name, shape_obj)
    return name


#: The properties a FEM mesh view keeps its colors in on FreeCAD 1.x (0.20 has none of them:
#: its colors are no properties).
FEM_COLOR_PROPERTIES = ("ColorMode", "ElementColorArray", "NodeColorArray")


def _colors_leave_document_unmodified(view_obj):
    """On 1.x a FEM view's colors are view properties: changing them would mark the document
    modified, although they are only shown (SurfMesh keeps the qualities in the object's own
    properties and shows them again on opening). Their NoModify status says so."""
    props = getattr(view_obj, "PropertiesList", [])
    for name in FEM_COLOR_PROPERTIES:
        if name in props:
            try:
                view_obj.setPropertyStatus(name, "NoModify")
            except Exception:  # noqa: BLE001  (a FreeCAD without that status: modified)
                pass


def qt_flags(value) -> int:
    """The integer of a combination of Qt flags (a task panel's standard buttons): PySide2
    (FreeCAD 0.20, 1.0) converts its flags with int(); PySide6's (1.1) are enums whose number
    is their value."""
    try:
        return int(value)
    except TypeError:
        return int(value.value)


#: The parts of a view's material that light its colors up: FreeCAD 1.x's default appearance of
#: a FEM mesh view has an ambient 0.33 and a specular 0.53, which wash out per-node and
#: per-element colors (a pure red drawn as (1, 0.6, 0.6), far from the legend's red).
_LIGHTING = ("AmbientColor", "SpecularColor", "EmissiveColor")


def flatten_view_material(view_obj):
    """Takes the ambient, specular and emissive parts out of a view's ShapeAppearance (1.x) so
    that the colors it shows are drawn as given; returns what they were, as text for
    restore_view_material, or None when there is nothing to change (0.20: no ShapeAppearance;
    already flat)."""
    if "ShapeAppearance" not in getattr(view_obj, "PropertiesList", []):
        return None
    mats = list(view_obj.ShapeAppearance)
    if not mats:
        return None
    black = (0.0, 0.0, 0.0, 0.0)
    old = [tuple(getattr(mats[0], k)) for k in _LIGHTING]
    if all(tuple(c[:3]) == black[:3] for c in old):
        return None
    for m in mats:
        for k in _LIGHTING:
            setattr(m, k, black)
    try:
        view_obj.setPropertyStatus("ShapeAppearance", "NoModify")
    except Exception:  # noqa: BLE001
        pass
    view_obj.ShapeAppearance = mats
    return ";".join(",".join(repr(float(x)) for x in c) for c in old)


def restore_view_material(view_obj, saved: str):
    """Gives a view's ShapeAppearance back the parts flatten_view_material took out."""
    if not saved or "ShapeAppearance" not in getattr(view_obj, "PropertiesList", []):
        return
    colors = [tuple(float(x) for x in c.split(",")) for c in saved.split(";")]
    mats = list(view_obj.ShapeAppearance)
    for m in mats:
        for k, c in zip(_LIGHTING, colors):
            setattr(m, k, c)
    view_obj.ShapeAppearance = mats


def show_fem_colors(view_obj, by: str):
    """After ElementColor / NodeColor were set on a FEM mesh view: FreeCAD 1.x draws them only
    when ``ColorMode`` says so (``by`` is "element" or "node"); 0.20 has no such property."""
    if "ColorMode" in getattr(view_obj, "PropertiesList", []):
        view_obj.ColorMode = {"element": "ByElement", "node": "ByNode"}[by]


def hide_fem_colors(view_obj):
    """The FEM mesh view's colors back to its one color (1.x: ColorMode "Overall")."""
    if "ColorMode" in getattr(view_obj, "PropertiesList", []):
        view_obj.ColorMode = "Overall"


def set_fem_element_colors(view_obj, colors: dict):
    """Colors a FEM mesh view per element ({element id: (r, g, b)}), shown on every release,
    without marking the document modified."""
    _colors_leave_document_unmodified(view_obj)
    view_obj.resetNodeColor()
    view_obj.ElementColor = colors
    show_fem_colors(view_obj, "element")


def set_fem_node_colors(view_obj, colors: dict):
    """Colors a FEM mesh view per node ({node id: (r, g, b)}), shown on every release, without
    marking the document modified."""
    _colors_leave_document_unmodified(view_obj)
    view_obj.ElementColor = {}
    view_obj.NodeColor = colors
    show_fem_colors(view_obj, "node")


def clear_fem_colors(view_obj):
    """A FEM mesh view back to its one color, on every release, without marking the document
    modified."""
    _colors_leave_document_unmodified(view_obj)
    view_obj.ElementColor = {}
    view_obj.resetNodeColor()
    hide_fem_colors(view_obj)


def selection_with_subelements(gui, doc_name):
    """The selection of document ``doc_name`` with the names of its sub-elements as picked
    (FEM elements "Elem<id>F1", faces, …): ``gui`` is FreeCADGui. 1.x's default
    getSelectionEx resolves FEM sub-element names away; unresolved (0) keeps them, on 0.20
    too."""
    return gui.Selection.getSelectionEx(doc_name, 0)


def run_gmsh_mesher(mesh_obj) -> str:
    """Runs FreeCAD's Gmsh mesher on a FemMeshGmsh object (FEM's GmshTools) and returns Gmsh's
    messages: 0.20 and 1.0 return them from create_mesh(), 1.1 returns None (they go to the
    report view), then "". Whether a mesh was made is the object's FemMesh either way."""
    from femmesh.gmshtools import GmshTools

    message = GmshTools(mesh_obj).create_mesh()
    return message if isinstance(message, str) else ""

