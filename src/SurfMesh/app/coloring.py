"""Quality colors: a fixed color scale from quality to RGB, shared by the GUI and the demo.

The scale is absolute (q ∈ [0, 1]) so that the colors of a mesh before and after optimization
compare directly: red (q → 0) · orange · yellow · green (q = 1); tangled elements are drawn in
a dark purple that no quality value takes.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import numpy as np

#: color of tangled (inverted or degenerate) elements
TANGLED_RGB = (0.35, 0.0, 0.45)

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


def quality_rgb(quality, tangled=None):
    """(E, 3) float RGB in [0, 1] for per-element qualities (tangled → TANGLED_RGB)."""
    q = np.clip(np.nan_to_num(np.asarray(quality, dtype=float), nan=0.0), 0.0, 1.0)
    rgb = np.stack([np.interp(q, _STOPS[:, 0], _STOPS[:, c]) for c in (1, 2, 3)], axis=1)
    if tangled is not None:
        rgb[np.asarray(tangled, dtype=bool)] = TANGLED_RGB
    return rgb


def node_values(data, element_values, reduce="min"):
    """Per-node values from per-element values (for node coloring of FEM tria6 meshes): the
    minimum (default) or mean over the elements around each node."""
    n = data.node_count
    out = np.full(n, np.inf if reduce == "min" else 0.0)
    counts = np.zeros(n)
    vals = np.asarray(element_values, dtype=float)
    sizes = np.diff(data.offsets)
    per_entry = np.repeat(vals, sizes)
    if reduce == "min":
        np.minimum.at(out, data.conn, per_entry)
        out[np.isinf(out)] = 1.0
    else:
        np.add.at(out, data.conn, per_entry)
        np.add.at(counts, data.conn, 1.0)
        out = np.where(counts > 0, out / np.maximum(counts, 1), 1.0)
    return out
