"""The element quality metrics FEM users know, per element, under Verdict's names.

    import SurfMesh
    m = SurfMesh.metrics(mesh, shape)                 # every metric
    m = SurfMesh.metrics(mesh, shape, ["aspect_ratio", "distance_to_cad"])
    m["aspect_ratio"]   # numpy float64, one value per element, in the order of measure()

Triangle and quadrilateral metrics follow Verdict (Sandia's element quality library,
``V_TriMetric.cpp`` / ``V_QuadMetric.cpp``; C. J. Stimpson, C. D. Ernst, P. Knupp, P. P. Pébay,
D. Thompson, "The Verdict Geometric Quality Library", SAND2007-1751) and are computed on the
element's corner nodes as given (which lie on the CAD surface within the tolerance), as
Verdict does for high-order elements. ``jacobian_ratio`` and ``distance_to_cad`` are computed
by the core on the element as its shape functions map it (curved sides included),
``distance_to_cad`` against the surface of the CAD face the element lies on. Formulas and
references: docs/metrics.md. :data:`METRICS` describes each metric (one source of truth for
the CLI, the GUI and the docs).

Where Verdict returns its ``VERDICT_DBL_MAX`` for a degenerate element (zero area or a side
of zero length) these functions return ``inf``; a metric that does not apply to an element
(``warpage`` of a triangle) is ``nan``. Verdict's triangle ``scaled_jacobian`` and ``shape``
are unsigned; here they are negative for an element SurfMesh finds tangled on its face (wound
against the face's outward normal), as are a quadrilateral's.

This module never imports FreeCADGui.
"""

from __future__ import annotations

import numpy as np

from SurfMesh.app import conversion

# name -> label (a user's words), unit, which elements it applies to, the ideal value, and the
# direction in which it gets worse ("high": larger is worse, "low": smaller is worse).
METRICS = {
    "aspect_ratio": dict(label="Aspect ratio", unit="", applies="all", ideal=1.0, worse="high",
                         threshold=10.0),
    "min_angle": dict(label="Smallest angle", unit="°", applies="all", ideal=None, worse="low",
                      threshold=20.0),
    "max_angle": dict(label="Largest angle", unit="°", applies="all", ideal=None, worse="high",
                      threshold=150.0),
    "scaled_jacobian": dict(label="Scaled Jacobian", unit="", applies="all", ideal=1.0,
                            worse="low", threshold=0.3),
    "condition": dict(label="Condition number", unit="", applies="all", ideal=1.0, worse="high",
                      threshold=3.0),
    "shape": dict(label="Shape (Verdict)", unit="", applies="all", ideal=1.0, worse="low",
                  threshold=0.3),
    "equiangle_skew": dict(label="Equiangle skew", unit="", applies="all", ideal=0.0,
                           worse="high", threshold=0.8),
    "warpage": dict(label="Warpage (cos³ of the corner normals' angle)", unit="", applies="quad",
                    ideal=1.0, worse="low", threshold=0.9),
    "taper": dict(label="Taper", unit="", applies="quad", ideal=0.0, worse="high",
                  threshold=0.5),
    "skew": dict(label="Skew", unit="", applies="quad", ideal=0.0, worse="high",
                 threshold=0.5),
    "stretch": dict(label="Stretch", unit="", applies="quad", ideal=1.0, worse="low",
                    threshold=0.25),
    "jacobian_ratio": dict(label="Jacobian ratio (min J / max J)", unit="", applies="all",
                           ideal=1.0, worse="low", threshold=0.3),
    "side_node_offset": dict(label="Side node offset (of the side's length)", unit="",
                             applies="curved", ideal=0.0, worse="high", threshold=0.25),
    "distance_to_cad": dict(label="Distance to the CAD face", unit="length", applies="all",
                            ideal=0.0, worse="high", threshold=None),
}
METRIC_NAMES = tuple(METRICS)

#: Grid steps per side of the reference element at which ``distance_to_cad`` samples an
#: element (45 points on a triangle, 81 on a quadrilateral) and ``jacobian_ratio`` its det J.
SAMPLE_DIVISIONS = 8

_DEG = 180.0 / np.pi


def metric_names(names=None):
    """The metric names ``names`` asks for (None or "all": every one), checked."""
    if names is None or names == "all" or (isinstance(names, (list, tuple)) and
                                          list(names) == ["all"]):
        return list(METRIC_NAMES)
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    try:
        names = list(names)
    except TypeError:
        raise ValueError(f"names must be a list of metric names, got {names!r}") from None
    if not names:
        raise ValueError("names is empty: give metric names, or None for all of them")
    unknown = [n for n in names if n not in METRICS]
    if unknown:
        raise ValueError(f"unknown metric(s) {', '.join(map(repr, unknown))}; known: "
                         f"{', '.join(METRIC_NAMES)}")
    return list(dict.fromkeys(names))


# ---- Verdict's formulas on corner coordinates --------------------------------------------------


def _norm(v):
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _angle(a, b):
    """Angle between vectors a and b in degrees (atan2 of |a×b| and a·b: exact near 0, 180)."""
    return np.arctan2(_norm(np.cross(a, b)), _dot(a, b)) * _DEG


def triangle_metrics(x):
    """Verdict's triangle metrics of the triangles with corners ``x`` ((n, 3, 3) float64).

    Returns a dict name -> (n,) array: aspect_ratio, min_angle, max_angle, scaled_jacobian,
    condition, shape, equiangle_skew (unsigned, as Verdict's; see :func:`metrics` for signs).
    """
    x = np.asarray(x, dtype=np.float64)
    p0, p1, p2 = x[:, 0], x[:, 1], x[:, 2]
    a, b, c = p1 - p0, p2 - p1, p0 - p2  # sides
    la, lb, lc = _norm(a), _norm(b), _norm(c)
    cross = _norm(np.cross(p1 - p0, p2 - p0))  # twice the area
    degenerate = ~(cross > np.finfo(float).tiny)
    with np.errstate(divide="ignore", invalid="ignore"):
        hmax = np.maximum(np.maximum(la, lb), lc)
        # aspect_ratio = hmax (a + b + c) / (4 √3 A) = √3/6 hmax (a + b + c) / |a × b|
        aspect = np.where(degenerate, np.inf, np.sqrt(3.0) / 6.0 * hmax * (la + lb + lc) / cross)
        v1, v2 = p1 - p0, p2 - p0
        # condition = (|v1|² + |v2|² − v1·v2) / (√3 |v1 × v2|)
        cond = np.where(degenerate, np.inf,
                        (_dot(v1, v1) + _dot(v2, v2) - _dot(v1, v2)) / (np.sqrt(3.0) * cross))
        shape = np.where(degenerate, 0.0, 1.0 / cond)
        # scaled_jacobian = 2/√3 |v1 × v2| / max of the products of two side lengths
        prod = np.maximum(np.maximum(la * lc, lc * lb), la * lb)
        sj = np.where(prod < np.finfo(float).tiny, 0.0, 2.0 / np.sqrt(3.0) * cross / prod)
    angles = np.stack([_angle(p1 - p0, p2 - p0), _angle(p2 - p1, p0 - p1),
                       _angle(p0 - p2, p1 - p2)], axis=1)
    zero_side = (la == 0) | (lb == 0) | (lc == 0)
    amin = np.where(zero_side, 0.0, angles.min(axis=1))
    amax = np.where(zero_side, 0.0, angles.max(axis=1))
    skew = np.maximum((amax - 60.0) / 120.0, (60.0 - amin) / 60.0)
    return dict(aspect_ratio=aspect, min_angle=amin, max_angle=amax, scaled_jacobian=sj,
                condition=cond, shape=shape, equiangle_skew=skew)


def quad_metrics(x):
    """Verdict's quadrilateral metrics of the quads with corners ``x`` ((n, 4, 3) float64).

    Returns a dict name -> (n,) array: aspect_ratio, min_angle, max_angle, scaled_jacobian,
    condition, shape, equiangle_skew, warpage, taper, skew, stretch. A quad whose last two
    corners coincide is measured as the triangle of its first three (Verdict's collapsed quad)
    for the triangle metrics.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    tiny = np.finfo(float).tiny
    p = [x[:, k] for k in range(4)]
    L = [p[(k + 1) % 4] - p[k] for k in range(4)]  # edges L0..L3
    ln = [_norm(v) for v in L]
    corner_normals = [np.cross(L[(k + 3) % 4], L[k]) for k in range(4)]  # N_k = L_{k−1} × L_k
    axes = np.cross(L[0] - L[2], L[1] - L[3])
    axes_len = _norm(axes)
    with np.errstate(divide="ignore", invalid="ignore"):
        center_normal = axes / np.where(axes_len > 0, axes_len, 1.0)[:, None]
        alpha = np.stack([_dot(center_normal, nk) for nk in corner_normals], axis=1)
        hm = np.maximum(np.maximum(ln[0], ln[1]), np.maximum(ln[2], ln[3]))
        perimeter = ln[0] + ln[1] + ln[2] + ln[3]
        area_sum = alpha.sum(axis=1)
        aspect = np.where(area_sum > tiny, hm * perimeter / area_sum, np.inf)
        zero_edge = np.min(np.stack(ln, axis=1), axis=1) < tiny
        # condition = max_k (|x_k − x_{k+1}|² + |x_k − x_{k−1}|²) / (2 α_k)
        cond_k = np.stack([(ln[k] ** 2 + ln[(k + 3) % 4] ** 2) / alpha[:, k] for k in range(4)],
                          axis=1)
        cond_k = np.where(alpha < tiny, np.inf, cond_k)
        cond = cond_k.max(axis=1) / 2.0
        # scaled_jacobian = min_k α_k / (|L_k| |L_{k−1}|)
        sj = np.stack([alpha[:, k] / (ln[k] * ln[(k + 3) % 4]) for k in range(4)],
                      axis=1).min(axis=1)
        sj = np.where(zero_edge, 0.0, sj)
        # shape = min_k 2 α_k / (|L_k|² + |L_{k−1}|²), 0 when negative
        shape = 2.0 * np.stack([alpha[:, k] / (ln[k] ** 2 + ln[(k + 3) % 4] ** 2)
                                for k in range(4)], axis=1).min(axis=1)
        shape = np.where(zero_edge | (shape < tiny), 0.0, shape)
        # angles at the corners: acos(−L_k · L_{k+1} / (|L_k| |L_{k+1}|)) at corner k+1
        ang = np.stack([_angle(-L[k], L[(k + 1) % 4]) for k in range(4)], axis=1)
        amin = ang.min(axis=1)
        amax = ang.max(axis=1)
        amax = np.where((alpha < 0).any(axis=1), 360.0 - amax, amax)
        # warpage = min(n̂0 · n̂2, n̂1 · n̂3)³ (unit corner normals)
        cn_len = np.stack([_norm(v) for v in corner_normals], axis=1)
        unit = [corner_normals[k] / np.where(cn_len[:, k] > 0, cn_len[:, k], 1.0)[:, None]
                for k in range(4)]
        warp = np.minimum(_dot(unit[0], unit[2]), _dot(unit[1], unit[3])) ** 3
        warp = np.where((cn_len < tiny).any(axis=1), 0.0, warp)
        # principal axes X1 = x1 + x2 − x0 − x3, X2 = x2 + x3 − x0 − x1, cross derivative
        X1 = p[1] + p[2] - p[0] - p[3]
        X2 = p[2] + p[3] - p[0] - p[1]
        X12 = p[0] + p[2] - p[1] - p[3]
        l1, l2 = _norm(X1), _norm(X2)
        lmin = np.minimum(l1, l2)
        taper = np.where(lmin < tiny, np.inf, _norm(X12) / lmin)
        skew = np.where(lmin < tiny, 0.0, np.abs(_dot(X1, X2)) / (l1 * l2))
        # stretch = √2 min edge / max diagonal
        diag = np.maximum(_norm(p[2] - p[0]), _norm(p[3] - p[1]))
        stretch = np.where(diag < tiny, np.inf,
                           np.sqrt(2.0) * np.min(np.stack(ln, axis=1), axis=1) / diag)
    amin = np.where(zero_edge, 0.0, amin)
    amax = np.where(zero_edge, 180.0, amax)
    skew_eq = np.maximum((amax - 90.0) / 90.0, (90.0 - amin) / 90.0)
    out = dict(aspect_ratio=aspect, min_angle=amin, max_angle=amax, scaled_jacobian=sj,
               condition=cond, shape=shape, equiangle_skew=skew_eq, warpage=warp, taper=taper,
               skew=skew, stretch=stretch)
    collapsed = np.all(p[3] == p[2], axis=1)  # Verdict: measured as the triangle 0 1 2
    if collapsed.any():
        tri = triangle_metrics(x[collapsed, :3])
        for k in ("min_angle", "max_angle", "scaled_jacobian", "condition"):
            out[k][collapsed] = tri[k]
        out["equiangle_skew"][collapsed] = np.maximum((tri["max_angle"] - 90.0) / 90.0,
                                                      (90.0 - tri["min_angle"]) / 90.0)
    assert all(v.shape == (n,) for v in out.values())
    return out


# ---- side nodes ---------------------------------------------------------------------------------

#: Side nodes per element type in Gmsh's order: (corner a, corner b, fraction along a -> b) for
#: each node after the corners that lies on a side.
def _side_layout(name):
    orders = {"tri6": 2, "tri10": 3, "tri15": 4, "tri21": 5}
    if name in orders:
        p = orders[name]
        return [(s, (s + 1) % 3, j / p) for s in range(3) for j in range(1, p)], 3
    if name in ("quad8", "quad9"):
        return [(s, (s + 1) % 4, 0.5) for s in range(4)], 4
    return [], 4 if name == "quad4" else 3


def side_node_offset(xyz, name):
    """Largest distance of a side node from where it would lie on its straight side (the
    point at its own fraction of the way between the side's corners), over the side's length,
    for elements of type ``name`` with node positions ``xyz`` ((n, k, 3)). 0 for straight
    sides with evenly spaced nodes, e.g. 0.5 for a side node at a half circle's top."""
    layout, corners = _side_layout(name)
    xyz = np.asarray(xyz, dtype=np.float64)
    out = np.zeros(xyz.shape[0])
    for j, (a, b, t) in enumerate(layout):
        chord = xyz[:, b] - xyz[:, a]
        length = _norm(chord)
        off = _norm(xyz[:, corners + j] - (xyz[:, a] + t * chord))
        with np.errstate(divide="ignore", invalid="ignore"):
            out = np.maximum(out, np.where(length > 0, off / length, np.inf))
    return out


# ---- the whole mesh ----------------------------------------------------------------------------


def element_metrics(data, names, tangled=None):
    """The metrics of ``names`` that need only node positions (Verdict's and side_node_offset)
    for every element of the MeshData ``data``, in its element order. ``tangled`` (bool per
    element) makes scaled_jacobian and shape negative for those elements."""
    E = data.element_count
    out = {n: np.full(E, np.nan) for n in names}
    sizes = np.diff(data.offsets)
    for code in np.unique(data.types):
        name = conversion.ELEMENT_NAMES.get(int(code), "")
        sel = np.nonzero(data.types == code)[0]
        k = int(sizes[sel[0]])
        idx = data.offsets[sel][:, None] + np.arange(k)[None, :]
        xyz = data.nodes[data.conn[idx]]  # (n, k, 3)
        quad = name.startswith("quad")
        values = quad_metrics(xyz[:, :4]) if quad else triangle_metrics(xyz[:, :3])
        for n in names:
            if n in values:
                out[n][sel] = values[n]
        if "side_node_offset" in out:
            out["side_node_offset"][sel] = side_node_offset(xyz, name)
    if tangled is not None:
        t = np.asarray(tangled, dtype=bool)
        for n in ("scaled_jacobian", "shape"):
            if n in out:
                out[n][t] = -np.abs(out[n][t])
    return out


def statistics(values):
    """min, max, mean, std and the count of the finite values of one metric (and how many are
    not finite: inf for degenerate elements, nan where the metric does not apply)."""
    v = np.asarray(values, dtype=np.float64)
    finite = v[np.isfinite(v)]
    stats = {"count": int(finite.size), "infinite": int(np.isinf(v).sum()),
             "not_applicable": int(np.isnan(v).sum())}
    if finite.size:
        stats.update(min=float(finite.min()), max=float(finite.max()),
                     mean=float(finite.mean()), std=float(finite.std()))
    else:
        stats.update(min=None, max=None, mean=None, std=None)
    return stats


def beyond(name, values, threshold):
    """Bool mask of the elements worse than ``threshold`` for metric ``name`` (above it for a
    metric that gets worse upwards, below for one that gets worse downwards; an infinite value
    of an "upwards" metric is beyond every threshold, nan never is)."""
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        if METRICS[name]["worse"] == "high":
            return v > threshold
        return v < threshold


# ---- files --------------------------------------------------------------------------------------


def _cell(v):
    """A CSV cell: 10 significant digits; inf, -inf and nan as Python and pandas read them."""
    v = float(v)
    if np.isnan(v):
        return "nan"
    if np.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.10g}"


def write_csv(path, values, element_ids, element_types=None, element_faces=None):
    """Writes one row per element: its id, type and CAD face (FreeCAD's name, empty when left
    out) when given, then the metrics of ``values`` (name -> array) in their order."""
    names = list(values)
    head = ["element_id"] + (["type"] if element_types is not None else []) + \
        (["face"] if element_faces is not None else []) + names
    cols = [np.asarray(values[n], dtype=np.float64) for n in names]
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.write(",".join(head) + "\n")
        for e, eid in enumerate(np.asarray(element_ids)):
            row = [str(int(eid))]
            if element_types is not None:
                row.append(str(element_types[e]))
            if element_faces is not None:
                face = int(element_faces[e])
                row.append(f"Face{face + 1}" if face >= 0 else "")
            row.extend(_cell(c[e]) for c in cols)
            f.write(",".join(row) + "\n")
    return path


def write_vtk(path, data, values, nodes=None):
    """Writes the mesh of the MeshData ``data`` (at ``nodes``, default its own) with the
    metrics of ``values`` (name -> array per element) and ``element_id`` as cell data, through
    meshio (.vtk legacy or .vtu, by the extension; positions in double precision)."""
    import meshio

    from SurfMesh.app import fileio

    cells = fileio._meshio_cells(data)
    blocks = [np.nonzero(data.types == code)[0] for code in np.unique(data.types)]
    cell_data = {"element_id": [np.asarray(data.element_ids)[b] for b in blocks]}
    for name, v in values.items():
        v = np.asarray(v, dtype=np.float64)
        cell_data[name] = [v[b] for b in blocks]
    pts = data.nodes if nodes is None else np.asarray(nodes, dtype=np.float64)
    meshio.write(path, meshio.Mesh(pts, cells, cell_data=cell_data))
    return path


def per_element_types(data):
    """The element type name of every element of the MeshData ``data``."""
    return [conversion.ELEMENT_NAMES.get(int(t), str(int(t))) for t in data.types]


def format_statistics(values, digits=4):
    """A plain-text table: one row per metric with min, mean, max and the count of the
    elements it does not apply to or that are degenerate (inf)."""
    rows = [("Metric", "Min", "Mean", "Max", "Elements", "Degenerate")]
    for name, v in values.items():
        s = statistics(v)
        if s["count"] == 0:
            rows.append((name, "-", "-", "-", "0", str(s["infinite"])))
            continue
        rows.append((name, f"{s['min']:.{digits}g}", f"{s['mean']:.{digits}g}",
                     f"{s['max']:.{digits}g}", str(s["count"] + s["infinite"]),
                     str(s["infinite"])))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in
                       enumerate(zip(r, widths))) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
