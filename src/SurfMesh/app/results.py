"""The results of SurfMesh's runs: :class:`QualityReport` (the quality of every element of a
mesh with one measure) and :class:`OptimizeResult`, and the report built from the core's measure
(:func:`quality_report`).

This module never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from SurfMesh.app import preparing, reports


class Cancelled(RuntimeError):
    """Raised by :func:`SurfMesh.optimize` when the progress callback asked to stop; nothing
    changed."""


@dataclasses.dataclass
class QualityReport:
    """Per-element quality of a mesh with one measure, and the paper's statistics."""

    measure: str
    quality: np.ndarray  # (E,) float64 in [0, 1], q = 1/η, 0 for tangled elements
    tangled: np.ndarray  # (E,) bool
    distortion: np.ndarray  # (E,) float64 η ≥ 1, inf for tangled elements
    min_sigma: np.ndarray  # (E,) float64 smallest scaled det S (≤ 0: tangled)
    # min, max, mean, std, tangled, elements (measured), skipped (left out), across (see below)
    stats: dict
    element_ids: np.ndarray  # (E,) int64 ids of the elements (FEM ids, or facet indices)
    element_types: list = dataclasses.field(default_factory=list)
    bridge: dict = dataclasses.field(default_factory=dict)  # how nodes were put on the shape
    skipped: np.ndarray = None  # (E,) bool: collapsed elements left out (not in the stats)
    # (E,) int64: 0-based index in shape.Faces of the CAD face each element lies on (FreeCAD's
    # Face1 is 0), -1 for the elements left out
    element_faces: np.ndarray = None
    # (E,) bool: elements standing across their surface — their plane wound along the face's
    # normal at some corners and against it at others (e.g. a triangle spanning more than half
    # the way round a thin tube: its plane cuts through the part). The measure (the paper's)
    # orients an element by the sum of its corner normals, so such an element can count as
    # valid and well shaped; ``stats["across"]`` counts them, tangled or not.
    across: np.ndarray = None

    def __repr__(self):
        s = self.stats
        return (
            f"<QualityReport {self.measure}: min {s['min']:.4f} max {s['max']:.4f} "
            f"mean {s['mean']:.4f} std {s['std']:.4f}; {s['elements']} elements, "
            f"{reports.validity_text(s)}>"
        )

    def to_dict(self, arrays=False):
        d = {"measure": self.measure, "stats": dict(self.stats)}
        if arrays:
            d["quality"] = self.quality.tolist()
            d["element_ids"] = self.element_ids.tolist()
        return d


@dataclasses.dataclass
class OptimizeResult:
    """Result of :func:`SurfMesh.optimize`."""

    mesh: object  # new Mesh.Mesh / Fem.FemMesh (None for array input)
    nodes: np.ndarray  # (N, 3) float64 optimized node positions (double precision)
    before: QualityReport
    after: QualityReport
    sweeps: int
    seconds: float  # wall time of the optimization itself
    reason: str  # "converged", "max_sweeps", "nothing_to_do"
    moved_nodes: int = 0
    threads: int = 1
    # Tangled second- and higher-order triangles untangled by straight sides in (u,v): a
    # mesher's edge nodes folded across an element whose corners are fine.
    straightened_elements: int = 0
    # Nodes that would have moved but were held by ``faces=`` or ``fixed_nodes=``.
    held_nodes: int = 0
    # Nodes put back where they were because the run left invalid an element that was valid
    # in the input (the core's last check: no valid element is made invalid).
    restored_nodes: int = 0
    # topology="flip": the edge flips made, the elements whose node lists they changed (ids
    # and faces kept; ``mesh`` has the new lists) and the needles left (elements of quality
    # below 0.2 with every corner on one CAD edge: only inserting or removing nodes opens them),
    # by the user's ids as below.
    flips: int = 0
    rewired_elements: list = dataclasses.field(default_factory=list)
    # The new node lists of ``rewired_elements`` (the same order; node ids as the input's:
    # FEM node ids, 0-based indices of a Mesh or of arrays).
    rewired_nodes: list = dataclasses.field(default_factory=list)
    needles: list = dataclasses.field(default_factory=list)
    options: dict = dataclasses.field(default_factory=dict)
    bridge: dict = dataclasses.field(default_factory=dict)
    # Elements still tangled after the run, by their ids (FEM element ids; 0-based indices of
    # the input for Mesh.Mesh facets and arrays): those with no node that may move where they
    # fold (all on CAD vertices, fixed CAD edges or poles: only changing the mesh repairs
    # them) and those the sweeps could not free. ``warnings`` says the same in words.
    tangled_unmovable: list = dataclasses.field(default_factory=list)
    tangled_movable: list = dataclasses.field(default_factory=list)
    warnings: list = dataclasses.field(default_factory=list)
    # Wall seconds of the parts of the call: read (the mesh into arrays), recovery (the CAD
    # bridge: nodes put on the shape), before / after (the quality reports), optimize (the
    # whole core call, ``seconds`` included), rebuild (the new mesh), total.
    timings: dict = dataclasses.field(default_factory=dict)

    def __repr__(self):
        b, a = self.before.stats, self.after.stats
        return (
            f"<OptimizeResult {self.before.measure}: {self.sweeps} sweeps, {self.seconds:.2f} s, "
            f"{self.reason}; min {b['min']:.4f} -> {a['min']:.4f}, "
            f"{reports.validity_text(b)} -> {reports.validity_text(a)}>"
        )

    def to_dict(self):
        return {
            "measure": self.before.measure,
            "before": dict(self.before.stats),
            "after": dict(self.after.stats),
            "sweeps": self.sweeps,
            "seconds": self.seconds,
            "reason": self.reason,
            "moved_nodes": self.moved_nodes,
            "threads": self.threads,
            "straightened_elements": self.straightened_elements,
            "held_nodes": self.held_nodes,
            "restored_nodes": self.restored_nodes,
            "flips": self.flips,
            "rewired_elements": list(self.rewired_elements),
            "rewired_nodes": [list(n) for n in self.rewired_nodes],
            "needles": list(self.needles),
            "tangled_unmovable": list(self.tangled_unmovable),
            "tangled_movable": list(self.tangled_movable),
            "warnings": list(self.warnings),
            "options": dict(self.options),
            "bridge": self.bridge,
        }


def left_out(report: QualityReport, mask) -> QualityReport:
    """``report`` with the elements of ``mask`` left out as well (skipped: quality 0, not
    tangled, not across, no face), its statistics those of the elements still measured."""
    mask = np.asarray(mask, dtype=bool) & ~report.skipped
    if not mask.any():
        return report
    skipped = report.skipped | mask
    quality = np.where(mask, 0.0, report.quality)
    tangled, across = report.tangled & ~mask, report.across & ~mask
    q = quality[~skipped]
    stats = dict(report.stats)
    stats.update(elements=int(q.size), skipped=int(skipped.sum()),
                 tangled=int(np.count_nonzero(tangled)), across=int(np.count_nonzero(across)),
                 invalid=int(np.count_nonzero(tangled | across)))
    if q.size:
        mean = float(q.sum()) / q.size
        stats.update(min=float(q.min()), max=float(q.max()), mean=mean,
                     std=float(np.sqrt(((q - mean) ** 2).sum() / q.size)))
    return dataclasses.replace(
        report, quality=quality, tangled=tangled, across=across, stats=stats, skipped=skipped,
        distortion=np.where(mask, np.inf, report.distortion),
        min_sigma=np.where(mask, 0.0, report.min_sigma),
        element_faces=np.where(mask, -1, report.element_faces))


def quality_report(data, handle, name, bridge=None, measured=None) -> QualityReport:
    """The :class:`QualityReport` of measure ``name`` on ``handle`` (the core's mesh of
    ``data``), of every element of the input (the elements left out: quality 0, not tangled);
    ``measured``: the core's measure when it was already taken."""
    r = measured if measured is not None else handle.measure(name)
    stats = dict(r["stats"])
    quality = np.asarray(r["quality"], dtype=np.float64)
    tangled = np.asarray(r["tangled"], dtype=bool)
    distortion = np.asarray(r["distortion"], dtype=np.float64)
    min_sigma = np.asarray(r["min_sigma"], dtype=np.float64)
    across = np.asarray(r["across"], dtype=bool)
    faces = np.asarray(handle.element_faces(), dtype=np.int64)
    skipped = np.zeros(data.element_count, dtype=bool)
    kept = getattr(data, "kept", None)
    if kept is not None:  # expand to every input element; skipped ones: quality 0, not tangled
        skipped = ~kept

        def expand(a, fill):
            out = np.full(data.element_count, fill, dtype=a.dtype)
            out[kept] = a
            return out

        quality, tangled = expand(quality, 0.0), expand(tangled, False)
        across = expand(across, False)
        distortion, min_sigma = expand(distortion, np.inf), expand(min_sigma, 0.0)
        faces = expand(faces, -1)
    stats["skipped"] = int(skipped.sum())
    # Invalid: tangled or standing across (or both), so that no invalid element hides behind a
    # count of 0 tangled (see validity_text).
    stats["invalid"] = int(np.count_nonzero(tangled | across))
    return QualityReport(
        measure=name,
        quality=quality,
        tangled=tangled,
        distortion=distortion,
        min_sigma=min_sigma,
        stats=stats,
        element_ids=data.element_ids,
        element_types=data.type_names(),
        bridge=bridge if bridge is not None else preparing.bridge_report(handle, data),
        skipped=skipped,
        element_faces=faces,
        across=across,
    )
