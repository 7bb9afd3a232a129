"""Quality colors: a fixed color scale from quality to RGB, shared by the GUI and the demo.

The scale is absolute (q ∈ [0, 1]) so that the colors of a mesh before and after optimization
compare directly: red (q → 0) · orange · yellow · green (q = 1); tangled elements are drawn in
a dark purple that no quality value takes, and elements left out of the measure (collapsed,
duplicate or flat ones, see SurfMesh.measure) in grey.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import numpy as np

#: color of tangled (inverted or degenerate) elements
TANGLED_RGB = (0.35, 0.0, 0.45)
#: color of elements left out of the measure (no quality: collapsed, duplicate, flat)
SKIPPED_RGB = (0.6, 0.6, 0.6)

# (quality, r, g, b) stops of the scale
_STOPS = np.array(
    [
        [0.00, 0.75, 0.00, 0.00],
        [0.25, 1.00, 0.25, 0.00],
        [0.50, 1.00, 0.65, 0.00],
        [0.75, 1.00, 1.00, 0.15],
        [1.00, 0.10, 0.70, 0.20],
    ]
)


def quality_rgb(quality, tangled=None, skipped=None):
    """(E, 3) float RGB in [0, 1] for per-element qualities (tangled → TANGLED_RGB, skipped →
    SKIPPED_RGB)."""
    q = np.clip(np.nan_to_num(np.asarray(quality, dtype=float), nan=0.0), 0.0, 1.0)
    rgb = np.stack([np.interp(q, _STOPS[:, 0], _STOPS[:, c]) for c in (1, 2, 3)], axis=1)
    if tangled is not None:
        rgb[np.asarray(tangled, dtype=bool)] = TANGLED_RGB
    if skipped is not None:
        rgb[np.asarray(skipped, dtype=bool)] = SKIPPED_RGB
    return rgb


def node_values(data, element_values, reduce="min", ignore=None):
    """Per-node values from per-element values (for node coloring of FEM tria6 meshes): the
    minimum (default) or mean over the elements around each node, without the elements where
    ``ignore`` (a bool per element) is set; 1 where no element is left."""
    n = data.node_count
    out = np.full(n, np.inf if reduce == "min" else 0.0)
    sizes = np.diff(data.offsets)
    per_entry = np.repeat(np.asarray(element_values, dtype=float), sizes)
    conn = data.conn
    if ignore is not None:
        keep = ~np.repeat(np.asarray(ignore, dtype=bool), sizes)
        per_entry, conn = per_entry[keep], conn[keep]
    if reduce == "min":
        np.minimum.at(out, conn, per_entry)
        out[np.isinf(out)] = 1.0
    else:
        counts = np.zeros(n)
        np.add.at(out, conn, per_entry)
        np.add.at(counts, conn, 1.0)
        out = np.where(counts > 0, out / np.maximum(counts, 1), 1.0)
    return out


def worst_element_per_node(data, rank):
    """For each node, the index of the element around it with the highest ``rank`` (a float
    per element, larger: worse; NaN: lowest), for node coloring by "the color of the worst
    element around the node"; -1 for a node in no element. Elements of equal rank around a
    node must have the same color (any of them is taken)."""
    sizes = np.diff(data.offsets)
    elem = np.repeat(np.arange(len(sizes)), sizes)
    r = np.asarray(rank, dtype=float)
    r = np.where(np.isnan(r), -np.inf, r)[elem]
    best = np.full(data.node_count, -np.inf)
    np.maximum.at(best, data.conn, r)
    out = np.full(data.node_count, -1, dtype=np.int64)
    top = r == best[data.conn]
    out[data.conn[top]] = elem[top]
    return out
