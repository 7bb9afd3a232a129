"""The color scales of SurfMesh's colors, drawn in the 3D views of a document while its visible
meshes show them: one scale per distinct coloring among those meshes, each titled with what it
shows and naming the meshes it belongs to:
- by quality (SurfMesh.measure_object, Optimize): the bar from red (q = 0) to green (q = 1)
  with its ticks and the colors of tangled and left-out elements, one scale per measure;
- by a metric (SurfMesh.color_by_metric): the bar from green (the ideal value) to yellow (the
  threshold) and the colors beyond the threshold and n/a, one scale per metric and threshold.
So a mesh colored by quality is never read against a metric's scale, nor the other way round.
One scale stands at the view's left; several are stacked, two to a column, the columns side by
side (each on its light panel, in the order of their first mesh in the document).

Drawn as an overlay (its own orthographic camera, on top of the scene, not pickable) that
does not count in the scene's bounding box, so "fit all" is unchanged. Kept up to date by the
document observer of InitGui.py (update(doc) after colors are applied, cleared, shown or
hidden, and after a colored mesh is renamed)."""

from __future__ import annotations

import dataclasses

import FreeCAD
import FreeCADGui

from SurfMesh.app import coloring

#: Overlay per document name: (its root node, shown(doc)'s text, drawn(doc)'s list).
_nodes = {}

# The view spans -1 … 1 in both directions (its width and its height), whatever its size; the
# text is 13 px high, about 0.045 of a 600 px view's height.
#: The panel of a lone scale (x0, y0, x1, y1): the bar, its labels, the title with the meshes'
#: names above it and the two swatches below; light and nearly opaque.
_PANEL = (-0.99, -0.78, -0.58, 0.80)
_PANEL_RGB = (0.97, 0.97, 0.97)
_PANEL_TRANSPARENCY = 0.15
# Where the parts stand in a panel (x0, y0, x1, y1), from its edges:
_BAR_X = (0.015, 0.04)  # the bar's left and right, from x0
_BAR_BELOW = 0.23  # the bar's bottom above y0 (room for the swatches)
_BAR_ABOVE = 0.35  # the bar's top below y1 (room for the title's three lines)
_TITLE_BELOW = 0.10  # the title's first baseline below y1
# Stacked panels: two to a column over the view's height, the columns side by side.
_STACK_TOP, _STACK_BOTTOM, _GAP = 0.98, -0.98, 0.02
#: Characters of the line that names the meshes (about the panel's width).
_NAMES_WIDTH = 24
_TEXT_RGB = (0.0, 0.0, 0.0)
_NAMES_RGB = (0.25, 0.25, 0.25)


@dataclasses.dataclass(frozen=True)
class Scale:
    """One coloring of the document's visible colored meshes and the meshes showing it."""

    key: tuple  # ("quality", measure) or ("metric", name, threshold)
    title: str  # e.g. "SurfMesh quality (shape)", "SurfMesh: Aspect ratio (red: > 1.27)"
    metric: tuple | None  # (name, threshold) for colors by a metric, None by quality
    labels: tuple  # the meshes' labels, in document order


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


def _coloring(obj):
    """(key, title, metric) of what the colors of ``obj`` show."""
    from SurfMesh.app import metric_report, metrics, reports

    by = metric_report.colored_by(obj)
    if by is not None:
        name, threshold = by
        sign = ">" if metrics.METRICS[name]["worse"] == "high" else "<"
        title = (f"SurfMesh: {metrics.METRICS[name]['label']} "
                 f"(red: {sign} {reports.format_value(threshold, 3)})")
        # thresholds that read the same and color the same are one scale
        return ("metric", name, float(f"{threshold:.9g}")), title, (name, threshold)
    measure = obj.SurfMeshMeasure if "SurfMeshMeasure" in obj.PropertiesList else ""
    title = "SurfMesh quality" + (f" ({measure})" if measure else "")
    return ("quality", measure), title, None


def scales(objects):
    """The distinct colorings of ``objects`` (colored meshes), each with the labels of the
    meshes showing it, in the order of their first mesh."""
    groups = {}
    for obj in objects:
        key, title, metric = _coloring(obj)
        entry = groups.setdefault(key, [title, metric, []])
        entry[2].append(obj.Label)
    return [Scale(key, title, metric, tuple(labels))
            for key, (title, metric, labels) in groups.items()]


def names_line(labels, width=_NAMES_WIDTH) -> str:
    """The line under a scale's title that names its meshes, within ``width`` characters:
    "Mesh: A" / "Meshes: A, B", then "+N more" for those that do not fit."""
    head = "Mesh: " if len(labels) == 1 else "Meshes: "
    shown = []
    for k, label in enumerate(labels):
        rest = len(labels) - k - 1
        tail = f" +{rest} more" if rest else ""
        line = head + ", ".join(shown + [label]) + tail
        if len(line) <= width:
            shown.append(label)
            continue
        if not shown:  # the first name alone is too long: cut it
            room = width - len(head) - len(tail) - 3
            shown.append(label[:max(room, 4)] + "...")
            continue
        return head + ", ".join(shown) + f" +{len(labels) - len(shown)} more"
    return head + ", ".join(shown)


def layout(n):
    """The panels (x0, y0, x1, y1) of ``n`` scales: a lone one at _PANEL; several stacked two
    to a column from the view's top left, the columns side by side."""
    if n <= 1:
        return [_PANEL][:n]
    width = _PANEL[2] - _PANEL[0]
    height = (_STACK_TOP - _STACK_BOTTOM - _GAP) / 2
    out = []
    for k in range(n):
        col, row = divmod(k, 2)
        x0 = _PANEL[0] + col * (width + _GAP)
        y1 = _STACK_TOP - row * (height + _GAP)
        out.append((x0, y1 - height, x0 + width, y1))
    return out


def bar_of(panel):
    """The bar (x0, y0, x1, y1) of the scale on ``panel``."""
    x0, y0, _x1, y1 = panel
    return (x0 + _BAR_X[0], y0 + _BAR_BELOW, x0 + _BAR_X[1], y1 - _BAR_ABOVE)


def _title_lines(scale):
    """The title in two lines (the measure or the threshold on the second one), then the line
    naming the meshes."""
    first, _, rest = scale.title.partition(" (")
    lines = [first] + ([f"({rest}"] if rest else [])
    return lines, names_line(scale.labels)


def _scale_parts(scale):
    """(stops, ticks, swatches) of ``scale``: the bar's colors (fraction, r, g, b), its labels
    (fraction, text) and the swatches below it ((r, g, b), text)."""
    if scale.metric is None:
        stops = [tuple(map(float, s)) for s in coloring._STOPS]
        ticks = [(q, f"{q:g}") for q in (0.0, 0.25, 0.5, 0.75, 1.0)]
        swatches = ((coloring.TANGLED_RGB, "tangled"), (coloring.SKIPPED_RGB, "left out"))
        return stops, ticks, swatches
    from SurfMesh.app import metric_report, metrics, reports

    name, threshold = scale.metric
    info = metrics.METRICS[name]
    stops = [(0.0,) + metric_report.GOOD_RGB, (1.0,) + metric_report.LIMIT_RGB]
    ideal = "best" if info["ideal"] is None else reports.format_value(info["ideal"], 3)
    ticks = [(0.0, ideal), (1.0, reports.format_value(threshold, 3))]
    sign = ">" if info["worse"] == "high" else "<"
    swatches = ((metric_report.BEYOND_RGB, f"{sign} {reports.format_value(threshold, 3)}"),
                (metric_report.NA_RGB, "n/a"))
    return stops, ticks, swatches


def _text(parent, xy, text, rgb=_TEXT_RGB):
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


def _draw_scale(over, scale, panel):
    """Draws ``scale`` on ``panel`` into ``over``; returns what was drawn (see drawn())."""
    stops, ticks, swatches = _scale_parts(scale)
    # a light panel under the scale and its labels, so that they read over any model
    _quad(over, *panel, [_PANEL_RGB] * 4, transparency=_PANEL_TRANSPARENCY)
    bx0, by0, bx1, by1 = bar = bar_of(panel)
    for a, b in zip(stops[:-1], stops[1:]):
        ya = by0 + (by1 - by0) * a[0]
        yb = by0 + (by1 - by0) * b[0]
        _quad(over, bx0, ya, bx1, yb, [a[1:], a[1:], b[1:], b[1:]])
    for q, label in ticks:
        y = by0 + (by1 - by0) * q
        _text(over, (bx1 + 0.01, y - 0.01), label)
    lines, names = _title_lines(scale)
    top = panel[3] - _TITLE_BELOW
    _text(over, (bx0, top), "\n".join(lines + [names]))
    h = 0.05
    drawn_swatches = []
    for k, (rgb, label) in enumerate(swatches):
        y = by0 - 0.08 - k * 1.5 * h
        _quad(over, bx0, y, bx1, y + h, [rgb] * 4)
        _text(over, (bx1 + 0.01, y + 0.01), label)
        drawn_swatches.append((tuple(map(float, rgb)), label, (bx0, y, bx1, y + h)))
    return dict(title=scale.title, lines=lines, names=names, labels=scale.labels,
                metric=scale.metric, panel=tuple(panel), bar=bar, stops=stops,
                swatches=drawn_swatches)


def build(scale_list):
    """The overlay's scene graph for ``scale_list`` (Scale, see scales()); returns (root node,
    what was drawn per scale)."""
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
    drawn = [_draw_scale(over, s, panel) for s, panel in zip(scale_list, layout(len(scale_list)))]
    root.addChild(over)
    # The overlay's geometry (in its own camera's space) takes no part in "fit all".
    reset = coin.SoResetTransform()
    reset.whatToReset = coin.SoResetTransform.BBOX
    root.addChild(reset)
    return root, drawn


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
    """Shows the scales of the colorings of the visible colored meshes of ``doc`` in its 3D
    views, and removes them when there are none. Returns whether a scale is shown."""
    if not FreeCAD.GuiUp or doc is None:
        return False
    objects = _colored_objects(doc)
    old = _nodes.pop(doc.Name, None)
    roots = _scene_roots(doc)
    if old is not None:
        for root in roots:
            if root.findChild(old[0]) >= 0:
                root.removeChild(old[0])
    if not objects:
        return False
    scale_list = scales(objects)
    node, drawn_list = build(scale_list)
    for root in roots:
        if root.findChild(node) < 0:  # (views may share their document's scene)
            root.insertChild(node, 0)  # first: its bounding-box reset clears only itself
    _nodes[doc.Name] = (node, "\n".join(s.title for s in scale_list), drawn_list)
    return True


def shown(doc):
    """The title of the scale shown in ``doc``'s views (several: their titles, one a line), or
    None."""
    entry = _nodes.get(doc.Name)
    return None if entry is None else entry[1]


def drawn(doc):
    """What the views of ``doc`` show, one dict per scale (top to bottom, column by column):
    title, lines (the title's lines as drawn), names (the line naming the meshes), labels,
    metric ((name, threshold), None for quality), panel and bar ((x0, y0, x1, y1) in the view's
    -1 … 1 coordinates), stops (the bar's colors (fraction, r, g, b) from bottom to top) and
    swatches (((r, g, b), text, (x0, y0, x1, y1)) each). Empty when nothing is shown."""
    entry = _nodes.get(doc.Name)
    return [] if entry is None else list(entry[2])


def texts(doc):
    """Every text line of the overlay shown in ``doc``'s views, read from its scene graph."""
    entry = _nodes.get(doc.Name)
    if entry is None:
        return []
    from pivy import coin

    search = coin.SoSearchAction()
    search.setType(coin.SoText2.getClassTypeId())
    search.setInterest(coin.SoSearchAction.ALL)
    search.apply(entry[0])
    paths = search.getPaths()
    out = []
    for i in range(paths.getLength()):
        s = paths[i].getTail().string
        out.extend(s[k] if isinstance(s[k], str) else s[k].getString()
                   for k in range(s.getNum()))
    return out
