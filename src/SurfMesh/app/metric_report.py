"""The element metrics of a mesh object in the document: per-metric statistics with the count
beyond a threshold, a histogram with the threshold, CSV export, and colors by a metric.

    from SurfMesh.app import metric_report
    rep = metric_report.metric_report(obj)               # every metric of SurfMesh.metrics
    rep.stats("aspect_ratio", 10.0)                      # min, max, mean, count, beyond
    rep.save_histogram("h.png", "aspect_ratio", 10.0)    # the threshold drawn on it
    rep.write_csv("m.csv")
    metric_report.color_by_metric(obj, "aspect_ratio", 10.0)   # red beyond 10, one undo step

The shape defaults to the one the mesh was made from (as SurfMesh.measure_object).

Colors by a metric: the elements within the threshold go from green (the metric's ideal value,
or the best value in the mesh when it has none) to yellow (the threshold), those beyond it are
red, and those the metric does not apply to (a quadrilateral metric on a triangle) grey. What
is stored on the object: SurfMeshColors (the colors, as for quality colors), SurfMeshColorBy
(the metric) and SurfMeshThreshold; coloring by quality again (SurfMesh.measure_object) or
clearing the colors removes them.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from SurfMesh.app import api, coloring, compat, conversion, metrics

#: Colors of the metric scale: the ideal value, the threshold, beyond the threshold.
GOOD_RGB = (0.10, 0.70, 0.20)
LIMIT_RGB = (1.00, 0.90, 0.15)
BEYOND_RGB = (0.85, 0.00, 0.00)
#: Elements the metric does not apply to.
NA_RGB = (0.6, 0.6, 0.6)


def default_threshold(name, values=None):
    """The threshold a metric starts with: METRICS' default, or (none there) the largest
    finite value of ``values`` (nothing beyond it)."""
    t = metrics.METRICS[name]["threshold"]
    if t is not None:
        return float(t)
    v = np.asarray(values if values is not None else [], dtype=float)
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else 0.0


def metric_rgb(name, values, threshold):
    """(E, 3) RGB of ``values`` of metric ``name`` against ``threshold`` (see the module)."""
    v = np.asarray(values, dtype=float)
    info = metrics.METRICS[name]
    finite = v[np.isfinite(v)]
    ideal = info["ideal"]
    if ideal is None:  # no ideal value: the best value in the mesh is the green end
        ideal = (finite.max() if info["worse"] == "low" else finite.min()) if finite.size \
            else threshold
    span = float(threshold) - float(ideal)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip((v - ideal) / span, 0.0, 1.0) if span != 0 else np.zeros_like(v)
    t = np.nan_to_num(t, nan=0.0)
    good, limit = np.array(GOOD_RGB), np.array(LIMIT_RGB)
    rgb = good[None, :] * (1.0 - t[:, None]) + limit[None, :] * t[:, None]
    rgb[metrics.beyond(name, v, threshold)] = BEYOND_RGB
    rgb[np.isnan(v)] = NA_RGB
    return rgb


@dataclasses.dataclass
class MetricReport:
    """The metrics of one mesh object (arrays in the element order of SurfMesh.measure)."""

    label: str
    values: dict  # name -> (E,) float64
    element_ids: np.ndarray
    element_types: list
    element_faces: np.ndarray

    def stats(self, name, threshold=None):
        """min, max, mean, std, count (finite), infinite, not_applicable and beyond (the
        elements worse than ``threshold``, default: the metric's default threshold)."""
        v = self.values[name]
        t = default_threshold(name, v) if threshold is None else float(threshold)
        out = metrics.statistics(v)
        out["threshold"] = t
        out["beyond"] = int(metrics.beyond(name, v, t).sum())
        return out

    def table_html(self, thresholds=None):
        """Per-metric statistics as an HTML table (one row per metric; ``thresholds``:
        name -> threshold, the defaults elsewhere)."""
        from SurfMesh.app import reports

        thresholds = thresholds or {}
        head = ["Metric", "Min", "Mean", "Max", "Threshold", "Beyond", "Elements", "n/a"]
        out = ["<table border='1' cellspacing='0' cellpadding='3'><tr>"]
        out.extend(f"<th>{h}</th>" for h in head)
        out.append("</tr>")
        for name in self.values:
            s = self.stats(name, thresholds.get(name))
            info = metrics.METRICS[name]
            sign = ">" if info["worse"] == "high" else "<"

            def num(x):
                return "-" if x is None else reports.format_value(x, 3)

            cells = [info["label"], num(s["min"]), num(s["mean"]), num(s["max"]),
                     f"{sign} {reports.format_value(s['threshold'], 3)}", str(s["beyond"]),
                     str(s["count"] + s["infinite"]), str(s["not_applicable"])]
            out.append("<tr>" + "".join(
                f"<td>{c}</td>" if k == 0 else f"<td align='right'>{c}</td>"
                for k, c in enumerate(cells)) + "</tr>")
        out.append("</table>")
        return "".join(out)

    def histogram_figure(self, name, threshold=None, bins=30):
        """A matplotlib Figure (Agg) with the histogram of ``name`` (finite values), the
        threshold as a vertical red line and the count beyond it in the legend."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from SurfMesh.app import reports

        s = self.stats(name, threshold)
        v = self.values[name]
        v = v[np.isfinite(v)]
        fig = Figure(figsize=(6.4, 3.6), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(111)
        info = metrics.METRICS[name]
        if v.size:
            ax.hist(v, bins=bins, color="#2ca02c", edgecolor="black", linewidth=0.4,
                    label=f"{v.size} elements (min {reports.format_value(v.min(), 3)}, max "
                          f"{reports.format_value(v.max(), 3)})")
        sign = ">" if info["worse"] == "high" else "<"
        ax.axvline(s["threshold"], color="red", linewidth=2.0,
                   label=f"{sign} {reports.format_value(s['threshold'], 3)}: {s['beyond']} "
                         "elements")
        unit = info["unit"]
        ax.set_xlabel(info["label"] + (f" ({unit})" if unit and unit != "length" else ""))
        ax.set_ylabel("elements")
        ax.set_title(f"{self.label}: {info['label']}")
        ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        return fig

    def save_histogram(self, path, name, threshold=None):
        self.histogram_figure(name, threshold).savefig(path)
        return path

    def write_csv(self, path, names=None):
        """The metrics (all, or ``names``) per element, as SurfMesh's CLI writes them."""
        values = self.values if names is None else {n: self.values[n] for n in names}
        return metrics.write_csv(path, values, self.element_ids, self.element_types,
                                 self.element_faces)


def metric_report(obj, shape=None, names=None, **kwargs):
    """The metrics (all, or ``names``) of mesh object ``obj`` on ``shape`` (default: the shape
    it was made from). Changes nothing in the document."""
    from SurfMesh.app import document

    shp = document.resolve_shape(obj, shape)
    values = api.metrics(obj, shp, names, **kwargs)
    rep = api.measure(obj, shp, **{k: v for k, v in kwargs.items() if k != "divisions"})
    data = conversion.read_mesh(obj)
    return MetricReport(label=obj.Label, values=values, element_ids=rep.element_ids,
                        element_types=metrics.per_element_types(data),
                        element_faces=rep.element_faces)


def color_by_metric(obj, name, threshold=None, shape=None, values=None):
    """Colors mesh object ``obj`` by metric ``name``: red beyond ``threshold`` (default: the
    metric's default), green to yellow within it, grey where it does not apply; in one undo
    step. ``values`` (the metric per element) saves computing it again. Returns the number
    of elements beyond the threshold."""
    from SurfMesh.app import document

    metrics.metric_names([name])
    if values is None:
        values = api.metrics(obj, document.resolve_shape(obj, shape), [name])[name]
    values = np.asarray(values, dtype=float)
    t = default_threshold(name, values) if threshold is None else float(threshold)
    kind = document._mesh_kind(obj)
    data = conversion.read_mesh(obj)
    if len(values) != data.element_count:
        raise ValueError(f"{len(values)} values for the {data.element_count} elements of "
                         f"{obj.Label!r}")
    rgb = metric_rgb(name, values, t)
    doc = obj.Document
    doc.openTransaction("SurfMesh color by metric")
    try:
        document._ensure(obj, "App::PropertyColorList", "SurfMeshColors",
                         "Quality color per element")
        obj.SurfMeshColors = [tuple(map(float, c)) for c in rgb]
        document._ensure(obj, "App::PropertyString", "SurfMeshColorBy",
                         "The metric the colors show")
        document._ensure(obj, "App::PropertyFloat", "SurfMeshThreshold",
                         "The colors' threshold: red beyond it")
        obj.SurfMeshColorBy = name
        obj.SurfMeshThreshold = t
        vo = getattr(obj, "ViewObject", None)
        if vo is not None:
            document._show_colors_in_view(obj, vo, kind, False)
            if kind == "mesh":
                vo.Coloring = False
                vo.Coloring = True
            else:
                _color_fem_by_metric(vo, data, name, values, t, rgb)
                document._fem_view_colored(obj, True)
    except Exception:
        doc.abortTransaction()
        raise
    doc.commitTransaction()
    return int(metrics.beyond(name, values, t).sum())


def badness(name, values):
    """How bad ``values`` of metric ``name`` are, larger: worse (the value, or its negative for
    a metric that gets worse as it falls); NaN (the metric does not apply) lowest."""
    v = np.asarray(values, dtype=float)
    b = v if metrics.METRICS[name]["worse"] == "high" else -v
    return np.where(np.isnan(b), -np.inf, b)


def color_rank(rgb):
    """How bad the elements are that metric colors ``rgb`` (as stored in SurfMeshColors, 8 bits
    per channel once saved) show, larger: worse: red (beyond the threshold) highest, then from
    yellow (the threshold, 1) to green (0), grey (n/a) lowest. The colors of a metric order
    its elements as their values do (see badness)."""
    rgb = np.asarray(rgb, dtype=float)[:, :3]
    rank = np.clip((rgb[:, 0] - GOOD_RGB[0]) / (LIMIT_RGB[0] - GOOD_RGB[0]), 0.0, 1.0)
    rank[np.all(np.abs(rgb - np.array(BEYOND_RGB)) < 0.02, axis=1)] = 2.0
    rank[np.all(np.abs(rgb - np.array(NA_RGB)) < 0.02, axis=1)] = -1.0
    return rank


def node_rgb(data, rgb, rank):
    """Per-node colors of a mesh colored per element by a metric (``rgb``; ``rank``: larger
    worse, see badness and color_rank): each node takes the color of the worst element around
    it, so that an element beyond the threshold is red all over."""
    rgb = np.asarray(rgb, dtype=float)[:, :3]
    worst = coloring.worst_element_per_node(data, rank)
    out = np.tile(np.array(NA_RGB, dtype=float), (data.node_count, 1))
    out[worst >= 0] = rgb[worst[worst >= 0]]
    return out


def _color_fem_by_metric(vo, data, name, values, threshold, rgb):
    """Per element on tria3 meshes; per node elsewhere (FreeCAD 0.20 draws element colors
    wrong on tria6): the color of the worst element around each node (node_rgb)."""
    if np.all(data.types == conversion.ELEMENT_TYPES["tri3"]):
        compat.set_fem_element_colors(
            vo, {int(e): tuple(map(float, c)) for e, c in zip(data.element_ids, rgb)})
        return
    colors = node_rgb(data, rgb, badness(name, values))
    compat.set_fem_node_colors(
        vo, {int(n): tuple(map(float, c)) for n, c in zip(data.node_ids, colors)})


def colored_by(obj):
    """(metric, threshold) the colors of ``obj`` show, or None (quality colors or none)."""
    if "SurfMeshColorBy" in obj.PropertiesList and obj.SurfMeshColorBy \
            and "SurfMeshColors" in obj.PropertiesList:
        return obj.SurfMeshColorBy, float(obj.SurfMeshThreshold)
    return None
