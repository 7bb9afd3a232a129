"""The color scale of the quality colors, drawn in the 3D views of a document while one of its
visible meshes shows SurfMesh's colors: the bar from red (q = 0) to green (q = 1) with its
ticks, the measure, and the colors of tangled and left-out elements.

Drawn as an overlay (its own orthographic camera, on top of the scene, not pickable) that
does not count in the scene's bounding box, so "fit all" is unchanged. Kept up to date by the
document observer of InitGui.py (update(doc) after colors are applied, cleared, shown or
hidden)."""

from __future__ import annotations

import FreeCAD
import FreeCADGui

from SurfMesh.app import coloring

#: Overlay node per document name.
_nodes = {}

_X0, _X1 = -0.975, -0.95  # the bar's left and right (the view's width spans -1 … 1)
_Y0, _Y1 = -0.55, 0.45  # its bottom (q = 0) and top (q = 1)
# The title's height above the bar's top (its first line; the second one is a line below):
# clear of the top label down to views ~300 px high (13 px text; the view's height spans 2).
_TITLE_GAP = 0.2
# The panel under the legend (x0, y0, x1, y1): the bar, its labels, the title and the two
# swatches below; light and nearly opaque.
_PANEL = (-0.99, -0.78, -0.58, 0.76)
_PANEL_RGB = (0.97, 0.97, 0.97)
_PANEL_TRANSPARENCY = 0.15


def _colored_objects(doc):
    out = []
    for obj in doc.Objects:
        try:
            if "SurfMeshColors" not in obj.PropertiesList:
                continue
            vo = getattr(obj, "ViewObject", None)
            if vo is not None and vo.Visibility:
                out.append(obj)
        except Exception:  # an object being deleted
            continue
    return out


def title(objects) -> str:
    """The legend's title: the measure(s) of the colored objects, or the metric and its
    threshold when one of them is colored by a metric."""
    scale = metric_scale(objects)
    if scale is not None:
        name, threshold = scale
        from SurfMesh.app import metrics, reports

        sign = ">" if metrics.METRICS[name]["worse"] == "high" else "<"
        return (f"SurfMesh: {metrics.METRICS[name]['label']} "
                f"(red: {sign} {reports.format_value(threshold, 3)})")
    names = sorted({o.SurfMeshMeasure for o in objects if "SurfMeshMeasure" in o.PropertiesList
                    and o.SurfMeshMeasure})
    return "SurfMesh quality" + (f" ({', '.join(names)})" if names else "")


def metric_scale(objects):
    """(metric, threshold) of the first of ``objects`` colored by a metric, or None."""
    from SurfMesh.app import metric_report

    for o in objects:
        by = metric_report.colored_by(o)
        if by is not None:
            return by
    return None


def _text(parent, xy, text, rgb=(0.0, 0.0, 0.0)):
    """Text from ``xy`` (its first line's baseline); "\n" starts a line below."""
    from pivy import coin

    sep = coin.SoSeparator()
    col = coin.SoBaseColor()
    col.rgb = rgb
    tr = coin.SoTranslation()
    tr.translation = (xy[0], xy[1], 0.0)
    t = coin.SoText2()
    lines = text.split("\n")
    t.string.setValues(0, len(lines), lines)
    for n in (col, tr, t):
        sep.addChild(n)
    parent.addChild(sep)


def _quad(parent, x0, y0, x1, y1, colors, transparency=0.0):
    """A quad with one color per corner (bottom left, bottom right, top right, top left)."""
    from pivy import coin

    sep = coin.SoSeparator()
    mat = coin.SoMaterial()
    mat.diffuseColor.setValues(0, 4, [tuple(map(float, c)) for c in colors])
    if transparency:
        mat.transparency.setValue(float(transparency))
    bind = coin.SoMaterialBinding()
    bind.value = coin.SoMaterialBinding.PER_VERTEX_INDEXED
    co = coin.SoCoordinate3()
    co.point.setValues(0, 4, [(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0)])
    fs = coin.SoIndexedFaceSet()
    fs.coordIndex.setValues(0, 5, [0, 1, 2, 3, -1])
    fs.materialIndex.setValues(0, 5, [0, 1, 2, 3, -1])
    for n in (mat, bind, co, fs):
        sep.addChild(n)
    parent.addChild(sep)


def build(heading: str, scale=None):
    """The overlay's scene graph (``scale``: (metric, threshold) for colors by a metric)."""
    from pivy import coin

    root = coin.SoSeparator()
    root.setName("SurfMeshLegend")
    over = coin.SoAnnotation()  # drawn last, over the scene
    cam = coin.SoOrthographicCamera()
    cam.viewportMapping = coin.SoCamera.LEAVE_ALONE
    cam.position = (0.0, 0.0, 5.0)
    cam.height = 2.0
    cam.nearDistance = 0.1
    cam.farDistance = 10.0
    pick = coin.SoPickStyle()
    pick.style = coin.SoPickStyle.UNPICKABLE
    light = coin.SoLightModel()
    light.model = coin.SoLightModel.BASE_COLOR
    font = coin.SoFont()
    font.name = "sans"
    font.size = 13.0
    for n in (cam, pick, light, font):
        over.addChild(n)
    # a light panel under the scale and its labels, so that they read over any model
    _quad(over, *_PANEL, [_PANEL_RGB] * 4, transparency=_PANEL_TRANSPARENCY)
    if scale is None:
        stops = coloring._STOPS
        ticks = [(q, f"{q:g}") for q in (0.0, 0.25, 0.5, 0.75, 1.0)]
        swatches = ((coloring.TANGLED_RGB, "tangled"), (coloring.SKIPPED_RGB, "left out"))
    else:
        from SurfMesh.app import metric_report, metrics, reports

        name, threshold = scale
        info = metrics.METRICS[name]
        stops = [(0.0,) + metric_report.GOOD_RGB, (1.0,) + metric_report.LIMIT_RGB]
        ideal = "best" if info["ideal"] is None else reports.format_value(info["ideal"], 3)
        ticks = [(0.0, ideal), (1.0, reports.format_value(threshold, 3))]
        sign = ">" if info["worse"] == "high" else "<"
        swatches = ((metric_report.BEYOND_RGB, f"{sign} {reports.format_value(threshold, 3)}"),
                    (metric_report.NA_RGB, "n/a"))
    for a, b in zip(stops[:-1], stops[1:]):
        ya = _Y0 + (_Y1 - _Y0) * a[0]
        yb = _Y0 + (_Y1 - _Y0) * b[0]
        _quad(over, _X0, ya, _X1, yb, [a[1:], a[1:], b[1:], b[1:]])
    for q, label in ticks:
        y = _Y0 + (_Y1 - _Y0) * q
        _text(over, (_X1 + 0.01, y - 0.01), label)
    # the title in two lines (the measure or the threshold below), to stay on the panel
    _text(over, (_X0, _Y1 + _TITLE_GAP), heading.replace(" (", "\n(", 1))
    h = 0.05
    for k, (rgb, label) in enumerate(swatches):
        y = _Y0 - 0.08 - k * 1.5 * h
        _quad(over, _X0, y, _X1, y + h, [rgb] * 4)
        _text(over, (_X1 + 0.01, y + 0.01), label)
    root.addChild(over)
    # The overlay's geometry (in its own camera's space) takes no part in "fit all".
    reset = coin.SoResetTransform()
    reset.whatToReset = coin.SoResetTransform.BBOX
    root.addChild(reset)
    return root


def _scene_roots(doc):
    gdoc = FreeCADGui.getDocument(doc.Name)
    roots = []
    for view in gdoc.mdiViewsOfType("Gui::View3DInventor"):
        try:
            roots.append(view.getSceneGraph())
        except Exception:
            continue
    return roots


def update(doc):
    """Shows the legend in the 3D views of ``doc`` while one of its visible meshes shows
    SurfMesh's colors, and removes it otherwise. Returns whether it is shown."""
    if not FreeCAD.GuiUp or doc is None:
        return False
    objects = _colored_objects(doc)
    old = _nodes.pop(doc.Name, None)
    roots = _scene_roots(doc)
    if old is not None:
        node, _ = old
        for root in roots:
            if root.findChild(node) >= 0:
                root.removeChild(node)
    if not objects:
        return False
    heading = title(objects)
    node = build(heading, metric_scale(objects))
    for root in roots:
        if root.findChild(node) < 0:  # (views may share their document's scene)
            root.insertChild(node, 0)  # first: its bounding-box reset clears only itself
    _nodes[doc.Name] = (node, heading)
    return True


def shown(doc):
    """The title of the legend shown in ``doc``'s views, or None."""
    entry = _nodes.get(doc.Name)
    return None if entry is None else entry[1]
