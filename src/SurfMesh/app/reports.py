"""Reports: the paper's statistics table, JSON, and the quality histogram (matplotlib, Agg).

Headless: never imports FreeCADGui; matplotlib is used through its object API and the Agg
canvas, so no GUI backend is touched.
"""

from __future__ import annotations

import json

import numpy as np

COLUMNS = ("Min. Q.", "Max. Q.", "Mean Q.", "Std. Dev.", "Tang. el.")


def format_value(v, digits=2):
    """``v`` with ``digits`` decimals, except where that would round a non-zero value to 0
    (|v| < 0.5·10^-digits): there with ``digits`` significant digits, so that a minimum quality
    of 2.8e-6 reads "2.8e-06", not "0.00" (which reads like a tangled mesh)."""
    v = float(v)
    if v != 0.0 and np.isfinite(v) and abs(v) < 0.5 * 10.0 ** -digits:
        return f"{v:.{digits}g}"
    return f"{v:.{digits}f}"


def stats_row(stats):
    return [
        format_value(stats["min"]),
        format_value(stats["max"]),
        format_value(stats["mean"]),
        format_value(stats["std"]),
        f"{int(stats['tangled'])}",
    ]


def invalid_count(stats):
    """The invalid count of :func:`validity_text` as text: the tangled count for statistics
    stored before it was counted where nothing stands across, else "unknown" there."""
    invalid = stats.get("invalid")
    if invalid is None and int(stats.get("across", 0)) == 0:
        invalid = stats.get("tangled", 0)
    return "unknown" if invalid is None else str(int(invalid))


def validity_text(stats):
    """"N invalid (T tangled, A standing across)": an element is invalid when it is tangled or
    stands across its surface (wound along the face's normal at some corners and against it at
    others), so that no invalid element hides behind a count of 0 tangled. Statistics stored
    before ``invalid`` was counted give it only where nothing stands across."""
    tangled, across = int(stats.get("tangled", 0)), int(stats.get("across", 0))
    invalid = invalid_count(stats)
    counts = f"{tangled} tangled, {across} standing across"
    return f"{counts} (invalid: unknown)" if invalid == "unknown" else \
        f"{invalid} invalid ({counts})"


def format_table(rows, title=None, digits=2):
    """Plain-text table in the layout of the paper's Tables 1-4, then one line per row with
    its invalid elements (:func:`validity_text`), where its statistics count them.

    rows: iterable of (measure, mesh_label, stats) — consecutive rows with the same measure
    show it once.  ``digits`` decimals for the quality columns.
    """
    head = ["Measure", "Mesh"] + list(COLUMNS)
    body = _table_body(rows, digits)
    widths = [max(len(r[i]) for r in [head] + body) for i in range(len(head))]
    lines = []
    if title:
        lines.append(title)
    fmt = "  ".join("{:<%d}" % w if i < 2 else "{:>%d}" % w for i, w in enumerate(widths))
    lines.append(fmt.format(*head))
    lines.append("  ".join("-" * w for w in widths))
    for r in body:
        lines.append(fmt.format(*r))
    lines.extend(_validity_lines(rows))
    return "\n".join(lines)


def _validity_lines(rows):
    """"<mesh>: N invalid (T tangled, A standing across)" for the rows whose statistics count
    the elements standing across."""
    return [f"{label}: {validity_text(stats)}" for _measure, label, stats in rows
            if "across" in stats]


def _table_body(rows, digits):
    """Cells of the table rows: measure (shown once per run of equal measures), mesh label,
    then the columns of COLUMNS."""
    body = []
    last = None
    for measure, label, stats in rows:
        cells = [format_value(stats[k], digits) for k in ("min", "max", "mean", "std")] + [
            f"{int(stats['tangled'])}"]
        body.append([measure.capitalize() if measure != last else "", label] + cells)
        last = measure
    return body


def table_html(rows, digits=2):
    """The same table as HTML (for the GUI's report dialog)."""
    out = ["<table border='1' cellspacing='0' cellpadding='4'>", "<tr>"]
    for h in ["Measure", "Mesh"] + list(COLUMNS):
        out.append(f"<th>{h}</th>")
    out.append("</tr>")
    for name, label, *cells in _table_body(rows, digits):
        out.append("<tr><td>%s</td><td>%s</td>" % (name, label))
        out.extend(f"<td align='right'>{c}</td>" for c in cells)
        out.append("</tr>")
    out.append("</table>")
    out.extend(f"<p>{line}</p>" for line in _validity_lines(rows))
    return "".join(out)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if np.isfinite(v) else None
    return x


def write_json(path, data):
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(_jsonable(data), fh, indent=2, sort_keys=False)
        fh.write("\n")


def histogram_figure(series, title="Element quality", bins=20):
    """A matplotlib Figure (Agg canvas) with one quality histogram per entry of ``series``:
    a list of (label, quality array, tangled count). Negative entries (elements left out of
    the measure, as SurfMeshQuality stores them) are not counted."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.0), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    edges = np.linspace(0.0, 1.0, bins + 1)
    colors = ["#d62728", "#2ca02c", "#1f77b4", "#ff7f0e"]
    for k, (label, quality, tangled) in enumerate(series):
        q = np.asarray(quality, dtype=float)
        q = q[~(q < 0.0)]
        if len(q) == 0:
            continue
        lab = (f"{label} (min {format_value(q.min())}, mean {format_value(q.mean())}, "
               f"tangled {int(tangled)})")
        ax.hist(q, bins=edges, alpha=0.55, color=colors[k % len(colors)], label=lab,
                edgecolor="black", linewidth=0.4)
    ax.set_xlim(0.0, 1.0)
    ax.set_xlabel("quality q = 1/η  (0 = tangled)")
    ax.set_ylabel("elements")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def save_histogram(path, series, title="Element quality", bins=20):
    """Writes the histogram of :func:`histogram_figure` to ``path`` (PNG by extension)."""
    fig = histogram_figure(series, title=title, bins=bins)
    fig.savefig(path)
    return path


#: The optimizer's reasons for stopping, in a user's words.
REASONS = {
    "converged": "converged",
    "max_sweeps": "stopped at the sweep limit",
    "nothing_to_do": "nothing to do",
}


def run_text(sweeps, seconds, reason):
    """How a run went: "48 sweeps, 5.5 s (converged)"."""
    return (f"{int(sweeps)} sweep{'s' if int(sweeps) != 1 else ''}, "
            f"{float(seconds):.2g} s ({REASONS.get(reason, reason)})")


def outcome_rows(before, after):
    """What an optimization did as rows (key, label, before, after): the invalid elements, of
    them the tangled ones and those standing across, the minimum and the mean quality (the
    Optimize panel's Result table; the numbers of :func:`outcome_text`)."""
    return [
        ("invalid", "Invalid elements", invalid_count(before), invalid_count(after)),
        ("tangled", "    tangled", str(int(before.get("tangled", 0))),
         str(int(after.get("tangled", 0)))),
        ("across", "    standing across", str(int(before.get("across", 0))),
         str(int(after.get("across", 0)))),
        ("min", "Min. quality", format_value(before["min"]), format_value(after["min"])),
        ("mean", "Mean quality", format_value(before["mean"]), format_value(after["mean"])),
    ]


def outcome_text(before, after, sweeps, seconds, reason, flips=0):
    """One line saying what an optimization did, from the statistics before and after it:
    "49 invalid (49 tangled, 0 standing across) → 0 invalid (0 tangled, 0 standing across),
    min quality 2.8e-06 → 0.31, mean 0.85 → 0.90; 48 sweeps, 5.5 s (converged)", and
    "; 12 edge flips" when edge flips were made."""
    def arrow(key, fmt):
        return f"{fmt(before[key])} → {fmt(after[key])}"

    return (f"{validity_text(before)} → {validity_text(after)}, "
            f"min quality {arrow('min', format_value)}, mean {arrow('mean', format_value)}; "
            f"{run_text(sweeps, seconds, reason)}"
            + (f"; {int(flips)} edge flip{'s' if int(flips) != 1 else ''}" if flips else ""))


def measure_text(stats, measure):
    """One line saying what a measure found: "4898 elements, 49 invalid (49 tangled, 0 standing
    across), min quality 2.8e-06, mean 0.85 (shape measure)"."""
    skipped = int(stats.get("skipped", 0))
    left = f", {skipped} left out" if skipped else ""
    return (f"{int(stats['elements'])} elements, {validity_text(stats)}{left}, "
            f"min quality {format_value(stats['min'])}, mean {format_value(stats['mean'])} "
            f"({measure} measure)")


#: The measures and boundary modes as the GUI names them (the API's names are the keys).
MEASURE_LABELS = {
    "shape": "Shape (Knupp's shape measure)",
    "oddy": "Oddy (angles and aspect)",
}
BOUNDARY_LABELS = {
    "fixed": "Nodes on CAD edges stay",
    "slide": "Nodes slide along CAD edges",
}
HIGH_ORDER_LABELS = {
    "reference": "Straight-sided on the surface (FEM)",
    "integral": "Integral measure (the paper's)",
}


def measure_label(name):
    """A measure's name in the GUI (its API name when it has no label)."""
    return MEASURE_LABELS.get(name, name.capitalize())
