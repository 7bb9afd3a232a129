"""Document-level functions (Draft / FEM "make" style), usable with and without the GUI.

    import SurfMesh
    rep = SurfMesh.measure_object(doc.FEMMeshGmsh)             # colors it, stores the stats
    new = SurfMesh.optimize_object(doc.FEMMeshGmsh, measure="shape")   # "<name>_optimized"
    SurfMesh.clear_colors(new)
    pick = SurfMesh.app.document.tangled_elements(doc.FEMMeshGmsh)   # changes nothing
    pick.ids, pick.summary()                                  # tangled (or the worst) elements

The shape defaults to the one the mesh was made from (``FemMeshGmsh.Part``, the source of a
MeshPart mesh, or the shape SurfMesh recorded on an optimized mesh).

What is stored on a measured object (property group "SurfMesh"):
    SurfMeshMeasure (String), SurfMeshStats (Map: min, max, mean, std, tangled, elements),
    SurfMeshQuality (FloatList, one per element in element order; 0 = tangled, -1 = left out
    of the measure: collapsed, duplicate or flat),
    SurfMeshColors (ColorList, one color per element: drawn by Mesh objects with Coloring;
    on FEM objects the record of the colors given to the view, which FreeCAD does not save:
    the GUI shows them again when the document is opened, see show_stored_colors).
An optimized object also gets SurfMeshStatsBefore, SurfMeshQualityBefore, SurfMeshSource
(link to the shape) and SurfMeshOriginal (link to the input mesh object).

Colors in the 3D view are applied when the object has a view provider (GUI up): Mesh objects
through ``Coloring``, FEM tria3 meshes through ``ElementColor``, other FEM meshes (tria6, quad4,
mixed) through per-node colors (``ElementColor`` draws wrong colors on tria6 in FreeCAD 0.20).
While colored, a selection draws the object's bounding box, and while tangled elements are
shown, the view draws back faces (see _show_colors_in_view).

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from SurfMesh.app import api, coloring, compat, conversion, messages, progress, shapes
from SurfMesh.app.options import DEFAULT_BOUNDARY, DEFAULT_MEASURE, optimize_defaults

GROUP = "SurfMesh"
STAT_KEYS = ("min", "max", "mean", "std", "tangled", "elements", "across", "invalid")
_COUNT_KEYS = ("tangled", "elements", "across", "invalid")


# ---- helpers ---------------------------------------------------------------------------------


def _ensure(obj, ptype, name, doc=""):
    if name not in obj.PropertiesList:
        obj.addProperty(ptype, name, GROUP, doc)


def _is_fem_object(obj):
    return "FemMesh" in obj.PropertiesList


def _mesh_kind(obj):
    if "FemMesh" in obj.PropertiesList:
        return "fem"
    if "Mesh" in obj.PropertiesList and conversion.is_mesh_kernel(obj.Mesh):
        return "mesh"
    raise ValueError(
        f"object {obj.Label!r} ({obj.TypeId}) holds no mesh: select a Mesh or FEM mesh object"
    )


def resolve_shape(obj, shape=None):
    """The shape to use for mesh object ``obj``: ``shape`` if given, else the shape the mesh
    was made from; ValueError when none is known."""
    if shape is not None:
        return shapes.shape_of(shape)
    src = shapes.source_shape_object(obj)
    if src is None:
        raise ValueError(
            f"no shape known for mesh {obj.Label!r}: select the part's shape together with "
            "the mesh (in Python: give it as shape=)"
        )
    return src.Shape


def _stats_map(stats):
    return {k: (str(int(stats[k])) if k in _COUNT_KEYS else repr(float(stats[k])))
            for k in STAT_KEYS if k in stats}


def stats_of(obj, before=False):
    """The stats stored on ``obj`` by :func:`measure_object` / :func:`optimize_object` as a
    dict (None when it has none)."""
    name = "SurfMeshStatsBefore" if before else "SurfMeshStats"
    if name not in obj.PropertiesList:
        return None
    m = getattr(obj, name)
    if not m:
        return None
    # (documents saved before "across" was counted lack it)
    return {k: (int(m[k]) if k in _COUNT_KEYS else float(m[k])) for k in STAT_KEYS if k in m}


def store_report(obj, report, before=False):
    """Stores a QualityReport's measure, stats and per-element quality on ``obj``."""
    suffix = "Before" if before else ""
    _ensure(obj, "App::PropertyString", "SurfMeshMeasure", "Measure of the stored quality")
    _ensure(obj, "App::PropertyMap", "SurfMeshStats" + suffix, "Quality statistics")
    _ensure(obj, "App::PropertyFloatList", "SurfMeshQuality" + suffix,
            "Quality per element (element order), 0 = tangled, -1 = left out of the measure")
    obj.SurfMeshMeasure = report.measure
    setattr(obj, "SurfMeshStats" + suffix, _stats_map(report.stats))
    setattr(obj, "SurfMeshQuality" + suffix, [float(q) for q in stored_quality(report)])


#: What SurfMeshQuality holds for an element left out of the measure.
LEFT_OUT = -1.0


def stored_quality(report):
    """The per-element quality as stored (SurfMeshQuality): the report's, with LEFT_OUT for
    the elements it left out."""
    q = np.asarray(report.quality, dtype=float)
    skipped = getattr(report, "skipped", None)
    if skipped is not None and np.any(skipped):
        q = np.where(skipped, LEFT_OUT, q)
    return q


def _stored_classes(quality):
    """(quality, tangled, skipped) of a stored SurfMeshQuality list."""
    q = np.asarray(quality, dtype=float)
    skipped = q < 0.0
    return np.where(skipped, 0.0, q), (q == 0.0), skipped


# ---- colors ----------------------------------------------------------------------------------


def apply_colors(obj, report=None):
    """Colors ``obj`` by quality (``report``, or the quality stored on it)."""
    if report is not None:
        quality = np.asarray(report.quality, dtype=float)
        tangled = np.asarray(report.tangled, dtype=bool)
        skipped = (np.asarray(report.skipped, dtype=bool)
                   if getattr(report, "skipped", None) is not None
                   else np.zeros(len(quality), dtype=bool))
    elif "SurfMeshQuality" in obj.PropertiesList and obj.SurfMeshQuality:
        quality, tangled, skipped = _stored_classes(obj.SurfMeshQuality)
    else:
        raise ValueError(f"{obj.Label!r} has no quality to show: measure it first")
    kind = _mesh_kind(obj)
    rgb = coloring.quality_rgb(quality, tangled, skipped)
    data = conversion.read_mesh(obj.FemMesh) if kind == "fem" else None
    count = obj.Mesh.CountFacets if kind == "mesh" else len(data.types)
    if len(rgb) != count:
        raise ValueError("stored quality does not match the mesh's elements: measure again")
    # Mesh objects draw this property (Coloring); FEM objects keep it as the record of the
    # colors given to the view (ElementColor / NodeColor cannot be read back in 0.20).
    _ensure(obj, "App::PropertyColorList", "SurfMeshColors", "Quality color per element")
    obj.SurfMeshColors = [tuple(map(float, c)) for c in rgb]
    _forget_metric_colors(obj)
    vo = getattr(obj, "ViewObject", None)
    if vo is None:
        return rgb
    _show_colors_in_view(obj, vo, kind, bool(np.any(tangled)))
    if kind == "mesh":
        vo.Coloring = False  # toggle: the view keeps stale colors otherwise
        vo.Coloring = True
        return rgb
    _color_fem_view(vo, data, rgb, quality, tangled, skipped)
    _fem_view_colored(obj, True)
    return rgb


def _color_fem_view(vo, data, rgb, quality, tangled, skipped):
    """Gives a FEM mesh's view its colors: per element on tria3 meshes; per node (the least
    quality of the measured elements around it) on others, where FreeCAD 0.20 draws element
    colors wrong."""
    tri3 = conversion.ELEMENT_TYPES["tri3"]
    if np.all(data.types == tri3):
        compat.set_fem_element_colors(
            vo, {int(e): tuple(map(float, c)) for e, c in zip(data.element_ids, rgb)})
    else:
        node_q = coloring.node_values(data, np.where(tangled, 0.0, quality), reduce="min",
                                      ignore=skipped)
        node_rgb = coloring.quality_rgb(node_q, node_q <= 0.0)
        compat.set_fem_node_colors(
            vo, {int(n): tuple(map(float, c)) for n, c in zip(data.node_ids, node_rgb)})


def show_stored_colors(obj):
    """Shows the quality colors stored on FEM mesh object ``obj`` in its view again (FreeCAD
    does not save a FEM view's colors): from its SurfMeshQuality, when it has SurfMeshColors
    (it was colored and not cleared since). Changes no property of the document. Returns
    whether colors were shown."""
    vo = getattr(obj, "ViewObject", None)
    if (vo is not None and "FemMesh" in obj.PropertiesList
            and "SurfMeshColorBy" in obj.PropertiesList and "SurfMeshColors" in obj.PropertiesList):
        return _show_stored_metric_colors(obj, vo)
    if (vo is None or "FemMesh" not in obj.PropertiesList
            or "SurfMeshColors" not in obj.PropertiesList
            or "SurfMeshQuality" not in obj.PropertiesList or not obj.SurfMeshQuality):
        return False
    quality, tangled, skipped = _stored_classes(obj.SurfMeshQuality)
    data = conversion.read_mesh(obj.FemMesh)
    if len(quality) != len(data.types):
        return False
    _color_fem_view(vo, data, coloring.quality_rgb(quality, tangled, skipped), quality,
                    tangled, skipped)
    _true_colors(obj, vo)
    _fem_view_colored(obj, True)
    return True


def _show_stored_metric_colors(obj, vo):
    """A FEM mesh colored by a metric (SurfMesh.app.metric_report) gets its stored colors
    back: per element on tria3 meshes, else per node as color_by_metric gave them (the color
    of the worst element around each node, the colors telling which is worst)."""
    from SurfMesh.app import metric_report

    data = conversion.read_mesh(obj.FemMesh)
    rgb = np.array([tuple(c)[:3] for c in obj.SurfMeshColors], dtype=float)
    if len(rgb) != data.element_count:
        return False
    if np.all(data.types == conversion.ELEMENT_TYPES["tri3"]):
        compat.set_fem_element_colors(
            vo, {int(e): tuple(map(float, c)) for e, c in zip(data.element_ids, rgb)})
    else:
        node_rgb = metric_report.node_rgb(data, rgb, metric_report.color_rank(rgb))
        compat.set_fem_node_colors(
            vo, {int(n): tuple(map(float, c)) for n, c in zip(data.node_ids, node_rgb)})
    _true_colors(obj, vo)
    _fem_view_colored(obj, True)
    return True


#: FEM mesh objects whose view shows SurfMesh's colors, by document name. FreeCAD 0.20 cannot
#: read a FEM view's ElementColor / NodeColor back, and undo does not restore them: this is
#: how sync_view_colors knows which views to clear.
_FEM_COLORED = {}


def _fem_view_colored(obj, colored):
    names = _FEM_COLORED.setdefault(obj.Document.Name, set())
    if colored:
        names.add(obj.Name)
    else:
        names.discard(obj.Name)


def sync_view_colors(doc):
    """Makes the FEM views of ``doc`` show what the document holds, after an undo or a redo:
    FreeCAD undoes SurfMesh's properties (and the views' own properties: a Mesh's Coloring,
    the selection style) but not a FEM view's element or node colors. A FEM mesh with
    SurfMeshColors shows its stored colors again; one SurfMesh colored that has lost them
    shows its own color again. Changes no property of the document. Returns the objects whose
    view changed."""
    changed = []
    colored = _FEM_COLORED.setdefault(doc.Name, set())
    for obj in doc.Objects:
        if "FemMesh" not in obj.PropertiesList or getattr(obj, "ViewObject", None) is None:
            continue
        if "SurfMeshColors" in obj.PropertiesList:
            if show_stored_colors(obj):
                changed.append(obj)
        elif obj.Name in colored:
            compat.clear_fem_colors(obj.ViewObject)
            colored.discard(obj.Name)
            changed.append(obj)
    colored.intersection_update(o.Name for o in doc.Objects)
    return changed


_VIEW_SAVED = "SurfMeshViewSaved"


def _true_colors(obj, vo):
    """A view draws its element or node colors as given (FreeCAD 1.x's default material
    lightens them, see compat.flatten_view_material); the material's own parts are recorded on
    the object the first time, for _restore_view."""
    old = compat.flatten_view_material(vo)
    if old is None:
        return
    saved = dict(getattr(obj, _VIEW_SAVED)) if _VIEW_SAVED in obj.PropertiesList else {}
    if "ShapeAppearance" not in saved:
        saved["ShapeAppearance"] = old
        if _VIEW_SAVED not in obj.PropertiesList:
            obj.addProperty("App::PropertyMap", _VIEW_SAVED, GROUP,
                            "The view's own settings, given back when the colors are cleared")
            obj.setEditorMode(_VIEW_SAVED, 2)
        setattr(obj, _VIEW_SAVED, saved)


def _set_view(obj, vo, prop, value):
    """Sets view property ``prop`` while SurfMesh's colors are shown, recording the view's own
    value on the object (hidden map SurfMeshViewSaved) the first time, for _restore_view."""
    if prop not in vo.PropertiesList:
        return
    saved = dict(getattr(obj, _VIEW_SAVED)) if _VIEW_SAVED in obj.PropertiesList else {}
    if prop not in saved:
        saved[prop] = str(getattr(vo, prop))
        if _VIEW_SAVED not in obj.PropertiesList:
            obj.addProperty("App::PropertyMap", _VIEW_SAVED, GROUP,
                            "The view's own settings, given back when the colors are cleared")
            obj.setEditorMode(_VIEW_SAVED, 2)  # hidden: bookkeeping of the view, not the mesh
        setattr(obj, _VIEW_SAVED, saved)
    setattr(vo, prop, value)


def _restore_view(obj, vo, props=None):
    """Gives the view back its own value of ``props`` (all recorded ones when None)."""
    if _VIEW_SAVED not in obj.PropertiesList:
        return
    saved = dict(getattr(obj, _VIEW_SAVED))
    for prop in list(saved) if props is None else [p for p in props if p in saved]:
        value = saved.pop(prop)
        if prop == "ShapeAppearance":
            compat.restore_view_material(vo, value)
        elif prop in vo.PropertiesList:
            setattr(vo, prop, value == "True" if prop == "BackfaceCulling" else value)
    if saved:
        setattr(obj, _VIEW_SAVED, saved)
    else:
        obj.removeProperty(_VIEW_SAVED)


def _show_colors_in_view(obj, vo, kind, tangled):
    """What the view needs for the colors to reach the screen:
    - a selected object is drawn in FreeCAD's selection color over its own ("Shape" selection
      style; tangled elements lose their purple): while colored, a selection draws the
      object's bounding box instead;
    - a tangled element is wound against its neighbours, so the view sees its back face, which
      FEM views cull (BackfaceCulling) and Mesh views leave unlit (one-sided Lighting): while
      the colors show tangled elements, back faces are drawn (FEM) and lit (Mesh).
    The view's own settings are given back by clear_colors (and the back-face one by colors
    without tangled elements)."""
    _set_view(obj, vo, "SelectionStyle", "BoundBox")
    _true_colors(obj, vo)  # FreeCAD 1.x's default material lightens colors (Mesh and FEM)
    back = "BackfaceCulling" if kind == "fem" else "Lighting"
    if tangled:
        _set_view(obj, vo, back, False if kind == "fem" else "Two side")
    else:
        _restore_view(obj, vo, [back])


def clear_colors(obj):
    """Removes the quality colors from ``obj`` (the stored stats are kept), in an undo step of
    its own."""
    kind = _mesh_kind(obj)
    doc = obj.Document
    doc.openTransaction("SurfMesh clear colors")
    try:
        _clear_colors(obj, kind)
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()


def _forget_metric_colors(obj):
    """Removes what colors by a metric (SurfMesh.app.metric_report) stored on ``obj``."""
    for prop in ("SurfMeshColorBy", "SurfMeshThreshold"):
        if prop in obj.PropertiesList:
            obj.removeProperty(prop)


def _clear_colors(obj, kind):
    if "SurfMeshColors" in obj.PropertiesList:
        obj.removeProperty("SurfMeshColors")
    _forget_metric_colors(obj)
    vo = getattr(obj, "ViewObject", None)
    if vo is None:
        return
    _restore_view(obj, vo)
    if kind == "mesh":
        vo.Coloring = False
    else:
        compat.clear_fem_colors(vo)
        _fem_view_colored(obj, False)


# ---- make functions --------------------------------------------------------------------------


def _fem_mesh_type():
    """The type of a new FEM mesh object. FreeCAD 0.20 draws a plain Fem::FemMeshObject made
    without the GUI as nothing once its file is opened in the GUI (its view is not built from
    the restored mesh), while the Python variant is drawn; but made in the GUI, the Python
    variant without a view proxy has no display mode (drawn as nothing, none can be set) while
    the plain one is drawn. So: the plain object in the GUI, the Python variant headless."""
    import FreeCAD

    return "Fem::FemMeshObject" if FreeCAD.GuiUp else "Fem::FemMeshObjectPython"


def _print_warnings(warnings):
    """The run's warnings (elements left tangled) on FreeCAD's report view."""
    if warnings:
        import FreeCAD

        for w in warnings:
            FreeCAD.Console.PrintWarning(f"SurfMesh: {w}\n")


def _print_notes(obj, diagnostics):
    """How the mesh was read on the CAD (elements left out, nodes glued…): each kind once per
    mesh and the meshes optimized from it, in a user's words (SurfMesh.app.notes; the full
    texts are its details, in the Quality report)."""
    from SurfMesh.app import notes

    fresh = notes.new_notes(obj, diagnostics)
    if fresh:
        import FreeCAD

        label = notes.lineage(obj).Label
        for n in fresh:
            FreeCAD.Console.PrintWarning(f"SurfMesh: {label}: {n}\n")


def measure_object(obj, shape=None, measure=DEFAULT_MEASURE, color=True, **kwargs):
    """Measures mesh object ``obj`` on ``shape`` (default: its source shape), stores the
    stats on it and colors it. Returns the QualityReport."""
    shp = resolve_shape(obj, shape)
    rep = api.measure(obj, shp, measure=measure, **kwargs)
    doc = obj.Document
    doc.openTransaction("SurfMesh measure")
    try:
        store_report(obj, rep)
        if color:
            apply_colors(obj, rep)
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()
    _print_notes(obj, rep.bridge.get("diagnostics", []))
    return rep


#: How many elements :func:`tangled_elements` picks when none is tangled: the worst ones.
WORST_ELEMENTS = 10
#: How many ids :meth:`ElementPick.summary` writes out (all of them are in ``ids``).
_SHOWN_IDS = 100


@dataclasses.dataclass
class ElementPick:
    """Elements of a mesh object picked by :func:`tangled_elements`, in the user's numbering.

    ``ids`` are what FreeCAD shows: FEM element ids, or 0-based facet indices of a Mesh
    (FreeCAD's Mesh > Face info says "Facet 26" for ``mesh.Facets[26]``)."""

    kind: str  # "tangled": every tangled element; "worst": none is tangled, the lowest qualities
    measure: str
    mesh_kind: str  # "fem" or "mesh"
    ids: list  # user ids (tangled: in element order; worst: worst first)
    indices: list  # 0-based positions in the mesh's element order (the report's arrays)
    quality: list  # their quality (0 for tangled elements)
    centers: list  # (x, y, z) centroid of each (all its nodes), global coordinates
    faces: list  # the CAD face each lies on, by FreeCAD's name ("Face3"); "" when unknown
    corners: list  # the corner positions of each, in order around the element
    report: api.QualityReport = None

    @property
    def noun(self) -> str:
        return "facet" if self.mesh_kind == "mesh" else "element"

    def summary(self) -> str:
        """What was picked, in words: how many, their ids, where the first one is."""
        n, noun = len(self.ids), self.noun
        ids = f"{noun}{'s' if n != 1 else ''} {messages.id_list(self.ids, shown=_SHOWN_IDS)}"
        if n == 0:
            return f"no {noun} measured"
        c = self.centers[0]
        where = f"near ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g})" + (
            f" on {self.faces[0]}" if self.faces[0] else "")
        faces = self.face_counts()
        # every face involved, most elements first, when they lie on more than one
        spread = ("" if len(faces) < 2 else f"; they lie on {len(faces)} faces: "
                  + ", ".join(f"{f} ({k})" for f, k in faces))
        if self.kind == "tangled":
            first = "the first" if n > 1 else "it"
            return (f"{n} tangled {noun}{'s' if n != 1 else ''} ({self.measure} measure): "
                    f"{ids}; {first}, {noun} {self.ids[0]}, lies {where}{spread}")
        return (f"no tangled {noun} ({self.measure} measure); the {n} worst, quality "
                f"{self.quality[0]:.4g} to {self.quality[-1]:.4g}: {ids}; the worst, "
                f"{noun} {self.ids[0]} (quality {self.quality[0]:.4g}), lies {where}{spread}")

    def face_counts(self):
        """[(face name, how many of the picked elements lie on it)], most first."""
        counts = {}
        for f in self.faces:
            if f:
                counts[f] = counts.get(f, 0) + 1
        return sorted(counts.items(), key=lambda fc: (-fc[1], int(fc[0][4:])))


def tangled_elements(obj, shape=None, measure=DEFAULT_MEASURE, worst=WORST_ELEMENTS, **kwargs):
    """The tangled elements of mesh object ``obj`` measured on ``shape`` (default: its source
    shape) with ``measure``, as :func:`measure_object` measures it; when none is tangled, its
    ``worst`` elements of lowest quality (worst first; elements left out of the measure are
    not picked). Changes nothing: no property, no transaction. Returns an :class:`ElementPick`;
    the run's warnings go to the report view as with :func:`measure_object`."""
    kind = _mesh_kind(obj)
    if isinstance(worst, bool) or not isinstance(worst, (int, np.integer)) or worst < 1:
        raise ValueError(f"worst must be a positive integer, got {worst!r}")
    shp = resolve_shape(obj, shape)
    rep = api.measure(obj, shp, measure=measure, **kwargs)
    _print_notes(obj, rep.bridge.get("diagnostics", []))
    if rep.tangled.any():
        picked, what = np.nonzero(rep.tangled)[0], "tangled"
    else:
        measured = np.nonzero(~rep.skipped)[0] if rep.skipped is not None else \
            np.arange(len(rep.quality))
        order = np.argsort(rep.quality[measured], kind="stable")[: int(worst)]
        picked, what = measured[order], "worst"
    data = conversion.read_mesh(obj)
    centers, corners = [], []
    for e in picked:
        nodes = data.nodes[data.element(int(e))]
        centers.append(tuple(float(x) for x in nodes.mean(axis=0)))
        k = 4 if data.types[e] in conversion.QUAD_CODES else 3
        corners.append([tuple(float(x) for x in p) for p in nodes[:k]])
    faces = rep.element_faces
    return ElementPick(
        kind=what,
        measure=rep.measure,
        mesh_kind=kind,
        ids=[int(rep.element_ids[e]) for e in picked],
        indices=[int(e) for e in picked],
        quality=[float(rep.quality[e]) for e in picked],
        centers=centers,
        faces=[f"Face{int(faces[e]) + 1}" if faces is not None and faces[e] >= 0 else ""
               for e in picked],
        corners=corners,
        report=rep,
    )


def analysis_of(obj):
    """The FEM analysis ``obj`` is a member of, or None."""
    doc = getattr(obj, "Document", None)
    for a in (doc.Objects if doc is not None else []):
        try:
            if a.isDerivedFrom("Fem::FemAnalysis") and obj in a.Group:
                return a
        except Exception:  # an object on its way out
            continue
    return None


def optimize_object(obj, shape=None, measure=DEFAULT_MEASURE, boundary=DEFAULT_BOUNDARY,
                    name=None, color=True, progress_callback=None, replace_in_analysis=None,
                    **options):
    """Optimizes mesh object ``obj``; creates ``<name>_optimized`` (the original is kept, and
    hidden in the GUI) in one undo transaction, stores before/after stats on it and colors it.
    Returns the new object (its ``SurfMeshStats`` / ``SurfMeshStatsBefore`` hold the result).

    ``progress_callback`` is called after every sweep (see SurfMesh.optimize); returning
    False cancels: then SurfMesh.Cancelled is raised and the document is unchanged.

    ``replace_in_analysis`` (FEM meshes; default: True when ``obj`` is in a FEM analysis): the
    new mesh takes the original's place in its analysis, with the original's shape link (a
    ``Part`` link, which FEM's solvers read), and the original leaves the analysis (it stays
    in the document) — in the same undo step.
    """
    kind = _mesh_kind(obj)
    analysis = analysis_of(obj) if kind == "fem" else None
    if replace_in_analysis is None:
        replace_in_analysis = analysis is not None
    elif replace_in_analysis and analysis is None:
        raise ValueError(f"replace_in_analysis: {obj.Label!r} is in no FEM analysis")
    shp = resolve_shape(obj, shape)
    src = shape if (shape is not None and hasattr(shape, "isDerivedFrom")) else \
        shapes.source_shape_object(obj)
    total = int(options.get("max_sweeps", optimize_defaults()["max_sweeps"]))
    callback, finish = progress.make_callback(progress_callback, total=total)
    try:
        res = api.optimize(obj, shp, measure=measure, boundary=boundary, progress=callback,
                           **options)
    finally:
        finish()
    doc = obj.Document
    doc.openTransaction("SurfMesh optimize")
    try:
        new_name = name or f"{obj.Name}_optimized"
        if kind == "mesh":
            new = doc.addObject("Mesh::Feature", new_name)
            new.Mesh = res.mesh
        else:
            new = doc.addObject(_fem_mesh_type(), new_name)
            new.FemMesh = res.mesh
        new.Label = f"{obj.Label}_optimized" if name is None else name
        _ensure(new, "App::PropertyLink", "SurfMeshOriginal", "The mesh this one was optimized from")
        new.SurfMeshOriginal = obj
        if src is not None and hasattr(src, "Shape"):
            _ensure(new, "App::PropertyLink", "SurfMeshSource", "The shape the mesh lies on")
            new.SurfMeshSource = src
        _ensure(new, "App::PropertyMap", "SurfMeshRun", "Optimization run")
        new.SurfMeshRun = {
            "measure": measure,
            "boundary": boundary,
            "sweeps": str(res.sweeps),
            "seconds": f"{res.seconds:.3f}",
            "reason": res.reason,
            "topology": str(res.options.get("topology", "none")),
            # Edge flips: how many, and the elements they rewired (ids kept).
            **({"flips": str(res.flips),
                "rewired_elements": " ".join(str(e) for e in res.rewired_elements)}
               if res.flips else {}),
            # The options given (the others: SurfMesh.OPTIMIZE_DEFAULTS), to repeat the run.
            **({"options": ", ".join(f"{k}={v!r}" for k, v in sorted(options.items()))}
               if options else {}),
            **({"warnings": " | ".join(res.warnings)} if res.warnings else {}),
        }
        _print_notes(obj, res.bridge.get("diagnostics", []))
        _print_warnings(res.warnings)
        store_report(new, res.before, before=True)
        store_report(new, res.after)
        if color:
            apply_colors(new, res.after)
        if replace_in_analysis:
            _replace_in_analysis(analysis, obj, new, src)
        doc.recompute()
        # The new mesh takes the original's place in the 3D view (undone with the rest).
        vo = getattr(obj, "ViewObject", None)
        if vo is not None:
            vo.Visibility = False
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()
    import FreeCAD

    FreeCAD.Console.PrintMessage(f"SurfMesh: {new.Label}: {outcome_of(new)}\n")
    return new


def _replace_in_analysis(analysis, old, new, src):
    """``new`` takes ``old``'s place in FEM ``analysis``, with its shape link: FEM reads a
    mesh's shape from its ``Shape`` or ``Part`` property (femmesh.meshsetsgetter)."""
    link = None
    for prop in ("Part", "Shape"):
        if prop in old.PropertiesList and old.getTypeIdOfProperty(prop) == "App::PropertyLink":
            link = getattr(old, prop)
            if link is not None:
                break
    if link is None and src is not None and hasattr(src, "Shape"):
        link = src
    if link is not None:
        if "Part" not in new.PropertiesList:
            new.addProperty("App::PropertyLink", "Part", "FEM Mesh",
                            "The shape the mesh was made from (as a Gmsh mesh's Part)")
        new.Part = link
    group = list(analysis.Group)
    group[group.index(old)] = new  # the analysis keeps its order
    analysis.Group = group


def outcome_of(obj):
    """What the optimization that made ``obj`` did, in one line (see reports.outcome_text),
    from what :func:`optimize_object` stored on it; None for an object it did not make."""
    from SurfMesh.app import reports

    before, after = stats_of(obj, before=True), stats_of(obj)
    if before is None or after is None or "SurfMeshRun" not in obj.PropertiesList:
        return None
    run = dict(obj.SurfMeshRun)
    return reports.outcome_text(before, after, int(run.get("sweeps", 0)),
                                float(run.get("seconds", 0.0)), run.get("reason", ""),
                                flips=int(run.get("flips", 0)))


def run_warnings(obj):
    """The warnings of the optimization that made ``obj`` (elements left tangled, …), as
    :func:`optimize_object` stored them."""
    if "SurfMeshRun" not in obj.PropertiesList:
        return []
    text = dict(obj.SurfMeshRun).get("warnings", "")
    return [w for w in text.split(" | ") if w]


def report_rows(obj, measures=None, shape=None):
    """Rows for the paper-style table of ``obj``: for an optimized object, (measure, "Initial",
    stats) of its original and (measure, "Optimized", stats) of itself for every measure;
    otherwise (measure, label, stats). Also returns histogram series for the object's stored
    measure. Returns (rows, series)."""
    measures = measures or api.measure_names()
    shp = resolve_shape(obj, shape)
    original = getattr(obj, "SurfMeshOriginal", None) if "SurfMeshOriginal" in obj.PropertiesList else None
    rows, series = [], []
    main = obj.SurfMeshMeasure if "SurfMeshMeasure" in obj.PropertiesList else measures[0]
    for m in measures:
        if original is not None:
            r0 = api.measure(original, shp, measure=m)
            rows.append((m, "Initial", r0.stats))
        r1 = api.measure(obj, shp, measure=m)
        rows.append((m, "Optimized" if original is not None else obj.Label, r1.stats))
        if m == main:
            if original is not None:
                series.append(("before", _measured(r0), r0.stats["tangled"]))
                series.append(("after", _measured(r1), r1.stats["tangled"]))
            else:
                series.append((obj.Label, _measured(r1), r1.stats["tangled"]))
    return rows, series


def _measured(report):
    """The qualities of the elements a report measured (without those it left out)."""
    q = np.asarray(report.quality, dtype=float)
    return q if report.skipped is None else q[~np.asarray(report.skipped, dtype=bool)]


def report_object(obj, shape=None, measures=None, histogram=None):
    """Paper-style report of mesh object ``obj``: a dict with ``rows`` (measure, mesh, stats),
    ``text`` (plain table), ``html`` and, when ``histogram`` is a path, the quality histogram
    (before/after for an optimized mesh) written there as PNG."""
    from SurfMesh.app import reports

    rows, series = report_rows(obj, measures=measures, shape=shape)
    out = {
        "rows": rows,
        "text": reports.format_table(rows, title=f"Quality of {obj.Label}"),
        "html": reports.table_html(rows),
        "histogram": None,
    }
    if histogram:
        main = rows[0][0] if rows else "shape"
        if "SurfMeshMeasure" in obj.PropertiesList and obj.SurfMeshMeasure:
            main = obj.SurfMeshMeasure
        reports.save_histogram(histogram, series, title=f"{obj.Label}: {main} quality")
        out["histogram"] = histogram
    return out
