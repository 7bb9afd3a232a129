"""SurfMesh's headless Python API: measure and optimize a mesh lying on a CAD shape.

    import SurfMesh
    rep = SurfMesh.measure(mesh, shape, measure="shape")
    rep.quality   # numpy float64, one value per element, in [0, 1], 0 for tangled
    rep.tangled   # numpy bool, one per element
    rep.stats     # dict: min, max, mean, std, tangled, elements (+ skipped)
    res = SurfMesh.optimize(mesh, shape, measure="shape", boundary="fixed")  # or "slide"
    res.mesh      # a NEW Mesh.Mesh / Fem.FemMesh; the input is untouched
    res.before, res.after, res.sweeps, res.seconds

``mesh`` is a ``Mesh.Mesh``, a ``Fem.FemMesh`` or a document object holding one; ``shape`` a
``Part.Shape`` or a document object with ``.Shape``.  Element order, element ids and (FEM)
node ids and node order are preserved.  Precision of the results: FEM meshes store doubles, so
their optimized nodes lie on the CAD surfaces to double precision; ``Mesh.Mesh`` stores float32
points, so there the nodes lie on the surfaces to float32 rounding (~1e-7 × model size).

Bad input raises ``ValueError`` with a message naming the problem; a run cancelled through the
``progress`` callback raises :class:`Cancelled` and changes nothing.

This module never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses
import re
import time
from typing import Callable, Optional

import numpy as np

from SurfMesh.app import conversion, progress as _progress, reports, shapes
from SurfMesh.app.native import core

BOUNDARY_MODES = ("fixed", "slide")

#: Options of :func:`optimize` that map to the core's OptimizeOptions, with their defaults.
OPTIMIZE_DEFAULTS = {
    "max_sweeps": 100,  # maximum number of Gauss-Seidel sweeps over the movable nodes
    "rel_tol": 1e-3,  # once untangled, stop when the relative decrease over a sweep of both the
    # objective and the quality deficit sum(1 - q) (over the elements with a movable node) is
    # below rel_tol,
    "move_tol": 1e-3,  # or when no node moved more than move_tol × its local size
    "inner_iterations": 1,  # Newton iterations per node and sweep (the paper uses 1)
    "max_line_search": 30,  # maximum halvings of the backtracking line search
    "over_relaxation": 1.9,  # ω in [1, 2): once untangled, a node first tries ω × its Newton
    # step (accepted only when it lowers the objective); 1 = plain Gauss-Seidel
    "delta_policy": "auto",  # "auto": δ from the smallest det S each sweep; "fixed": `delta`
    "delta_epsilon": 1e-2,  # ε of the automatic δ policy (relative to the local size²)
    "delta": 1e-2,  # δ of the fixed policy (dimensionless)
    "monotone": True,  # reject moves that would lower a valid mesh's minimum quality
    "threads": 0,  # worker threads; 0 = all hardware threads (result independent of it)
}


# A run that ends at max_sweeps with tangled elements left advises more sweeps only when their
# number dropped within this many sweeps before the end (3 × the core's deltaStallSweeps: every
# level of its ε tried once since).
_STILL_DROPPING = 24


class Cancelled(RuntimeError):
    """Raised by :func:`optimize` when the progress callback asked to stop; nothing changed."""


def measure_names():
    """Names of the distortion measures the core provides ("shape", "oddy", …)."""
    return list(core().measure_names())


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
    """Result of :func:`optimize`."""

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
            "tangled_unmovable": list(self.tangled_unmovable),
            "tangled_movable": list(self.tangled_movable),
            "warnings": list(self.warnings),
            "options": dict(self.options),
            "bridge": self.bridge,
        }


# ---- building the core mesh ------------------------------------------------------------------


def _check_measure(name):
    names = measure_names()
    if not isinstance(name, str) or name not in names:
        raise ValueError(f"unknown measure {name!r}; known measures: {', '.join(names)}")
    return name


def _check_boundary(boundary):
    if boundary not in BOUNDARY_MODES:
        raise ValueError(f"unknown boundary mode {boundary!r}; use 'fixed' or 'slide'")
    return boundary


def _core_shape(shape):
    """Core CadShape from a Part.Shape (through BREP text)."""
    return core().CadShape.from_brep_string(shapes.brep_string(shape))


def prepare(mesh, shape, boundary="fixed", tolerance=None, hints="auto", collapsed="skip",
            duplicates="glue"):
    """Reads ``mesh`` and ``shape`` and builds the core's surface mesh.

    Returns ``(data, handle)``: the :class:`~SurfMesh.app.conversion.MeshData` read from the
    input and the core mesh handle (``handle.report`` says how every node was classified).
    When elements were left out (``collapsed="skip"``), ``data.kept`` is the bool mask of the
    elements given to the core.

    hints: "auto" (FEM inputs: a node within a CAD vertex's or a single CAD edge's own
    tolerance is hinted to it — the rule of FreeCAD's ``getNodesByVertex/Edge``, applied by the
    core with a box grid instead of a distance query per node and entity: seconds instead of
    minutes on big parts; face nodes are classified by the core, and a high-order side node
    lying on a CAD edge inside one face's mesh — all its elements on that face, not on the
    mesh's boundary — is a face node, unlike FreeCAD's queries; other inputs: no hints),
    "tolerance" (that rule whatever the input: for the arrays of a FEM mesher's mesh read
    from a file, whose nodes on CAD edges were put there by the mesher), "all" (FreeCAD's
    own ``getNodesByVertex/Edge/Face`` queries: slow on big parts), "none", or "given" (the
    MeshData's hint arrays are used as they are).

    collapsed: what to do with elements that repeat a node (zero area: Gmsh meshes made
    through FreeCAD have them where nodes were merged, e.g. at the apex of a cone) and with
    flat tangled slivers whose nodes all lie on one CAD edge (Gmsh's "elements remain invalid"):
    "skip" leaves them, and pairs of elements on the same nodes (folded onto each other), out
    of measuring and optimizing, with the elements of the mesher's degenerate spot around
    collapsed ones: overlapping elements (more than two on one edge), elements wound against
    their face's mesh, and high-order elements joined through side nodes no conforming mesh
    shares (a side node that is also a corner, or on two different edges: Gmsh's second-order
    mesh of the bottle's thread where it ends). They are reported in ``skipped`` and in the
    bridge warnings; their nodes stay where they are. "error" raises ValueError naming the
    first collapsed element (flat boundary elements are then measured as tangled).

    duplicates: what to do with nodes used by elements at exactly the same position as another
    such node (a crack: FreeCAD's standard mesher leaves them along CAD edges where it meshed
    two faces apart). "glue" (default) measures and optimizes the mesh as if they were one
    node and moves them together, so the crack stays closed (``data.glued`` maps each node to
    the one it moves with; the bridge report gives ``glued_nodes`` and a warning names a
    pair); "error" raises ValueError naming a pair.
    """
    data, handle, _ = _prepare(mesh, shape, boundary, tolerance, hints, collapsed, duplicates)
    return data, handle


def _surface_nodes_only(data):
    """A mesh with volume elements holds interior nodes, which lie off the shape and belong to
    no surface element: measuring its surface takes the nodes of the surface elements only."""
    used = np.unique(data.conn)
    if used.size == data.node_count or used.size == 0 or used[0] < 0 or used[-1] >= data.node_count:
        return data
    index = np.full(data.node_count, -1, dtype=np.int64)
    index[used] = np.arange(used.size, dtype=np.int64)
    return dataclasses.replace(data, nodes=data.nodes[used], node_ids=data.node_ids[used],
                               conn=index[data.conn], hint_face=None, hint_edge=None,
                               hint_vertex=None)


def _glue_coincident(data):
    """``data`` with its coincident nodes glued (see :func:`prepare`), and (the glued nodes'
    indices, the warning to give), or None when no nodes coincide."""
    rep = data.coincident_nodes()
    if rep is None:
        return data, None
    moved = np.nonzero(rep != np.arange(rep.size))[0]
    a = int(moved[0])
    b = int(rep[a])
    x, y, z = (float(c) for c in data.nodes[a])
    note = (
        f"glued {moved.size} node(s) to another node at the same position (the mesh has a "
        f"crack there, e.g. nodes {int(data.node_ids[b])} and {int(data.node_ids[a])} at "
        f"({x:.9g}, {y:.9g}, {z:.9g})): they are measured as one node and move together"
    )
    return dataclasses.replace(data, conn=rep[data.conn], glued=rep), (moved, note)


def _prepare(mesh, shape, boundary, tolerance, hints, collapsed, duplicates="glue",
             timings=None, moving=False):
    """:func:`prepare`, and the "shape" measure of the returned handle when it was taken on
    the way (else None): measuring it again would give the same result. ``timings`` (a dict),
    when given, receives the seconds of reading the mesh ("read") and of the rest ("recovery").
    """
    t0 = time.perf_counter()
    _check_boundary(boundary)
    if tolerance is not None and (isinstance(tolerance, bool)
                                  or not isinstance(tolerance, (int, float, np.floating,
                                                                np.integer))
                                  or not (tolerance > 0 and np.isfinite(tolerance))):
        raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
    if collapsed not in ("skip", "error"):
        raise ValueError(f"collapsed must be 'skip' or 'error', got {collapsed!r}")
    if duplicates not in ("glue", "error"):
        raise ValueError(f"duplicates must be 'glue' or 'error', got {duplicates!r}")
    _progress.phase("reading the mesh")
    data = conversion.read_mesh(mesh)
    t_read = time.perf_counter()
    part_shape = shapes.shape_of(shape) if not _is_core_shape(shape) else None
    if data.element_count == 0:
        raise ValueError("the mesh has no elements")
    if moving and data.volume_elements:
        raise ValueError(volume_mesh_refusal(data.volume_elements, data.volume_types))
    if data.volume_elements:
        data = _surface_nodes_only(data)
    if hints not in ("auto", "tolerance", "all", "none", "given"):
        raise ValueError(
            f"unknown hints mode {hints!r}; use 'auto', 'tolerance', 'all', 'none' or 'given'"
        )
    if data.kind == "fem" and hints == "all" and part_shape is not None:
        conversion.fem_hints(data, part_shape, faces=True)
    tolerance_hints = hints == "tolerance" or (data.kind == "fem" and hints == "auto")
    glue = None
    if duplicates == "glue":
        data, glue = _glue_coincident(data)
    bad = data.collapsed_elements()
    dup = data.duplicate_elements() & ~bad
    work = data
    data.kept = None
    data.flat = None
    crowded = np.zeros(data.element_count, dtype=bool)
    misjoined = np.zeros(data.element_count, dtype=bool)
    if collapsed == "skip":
        bad = bad | dup
        # Overlapping elements around the collapsed ones (a mesher's degenerate spot), joined
        # through a corner edge or through side nodes.
        for _ in range(8):
            gone = bad | crowded | misjoined
            more = data.crowded_edge_elements(gone) & ~gone
            joined = data.misjoined_elements(gone) & ~gone & ~more
            if not more.any() and not joined.any():
                break
            crowded |= more
            misjoined |= joined
        bad = bad | crowded | misjoined
    if bad.any():
        ids = data.element_ids[bad]
        if collapsed == "error" or bad.all():
            first = int(np.nonzero(bad)[0][0])
            nodes = [int(n) for n in data.node_ids[data.element(first)]]
            raise ValueError(
                f"{int(bad.sum())} element(s) repeat a node (collapsed, zero area), first: "
                f"element id {int(ids[0])} with nodes {nodes}"
                + ("" if bad.all() else "; pass collapsed='skip' to leave them out")
            )
        work = data.subset(~bad)
        data.kept = ~bad
    cshape = shape if part_shape is None else _core_shape(part_shape)

    def build(w, keep=False, same_nodes_as=None):
        # The nodes of the elements left out border the holes those leave: not the mesh's
        # boundary (the core puts them on a CAD edge only when they lie on it).
        left_out = None
        if data.kept is not None:
            left_out = data.nodes_of(~data.kept)
        try:
            h = core().cad_mesh(
                cshape, w.nodes, w.types, w.offsets, w.conn,
                hint_face=w.hint_face, hint_edge=w.hint_edge, hint_vertex=w.hint_vertex,
                tolerance=0.0 if tolerance is None else float(tolerance), boundary=boundary,
                tolerance_hints=tolerance_hints, keep_node_search=keep,
                same_nodes_as=same_nodes_as, left_out_nodes=left_out,
            )
        except ValueError as err:
            raise ValueError(_name_by_ids(str(err), w)) from None
        report = h.report  # the handle's own dict: the user's ids in its warnings too
        report["warnings"] = [_name_by_ids(x, w) for x in report.get("warnings", [])]
        return h

    # Flat elements found on the first recovery are left out by a second one, which reuses
    # the first's per-node face search (the costly part): same nodes, other elements.
    _progress.phase("placing the nodes on the shape's faces and edges")
    handle = build(work, keep=collapsed == "skip")
    shape_measure = None
    reasons = []
    if bad.any():
        n_dup = int(dup.sum()) if collapsed == "skip" else 0
        n_crowded = int(crowded.sum())
        n_misjoined = int(misjoined.sum())
        if int(bad.sum()) - n_dup - n_crowded - n_misjoined:
            reasons.append(f"{int(bad.sum()) - n_dup - n_crowded - n_misjoined} collapsed "
                           "element(s) (a repeated node)")
        if n_dup:
            reasons.append(f"{n_dup} element(s) with the same nodes as another one (folded pairs)")
        if n_crowded:
            reasons.append(f"{n_crowded} element(s) overlapping around those (more than two on "
                           "one edge)")
        if n_misjoined:
            reasons.append(f"{n_misjoined} high-order element(s) joined to those through side "
                           "nodes no conforming mesh shares (a side node that is also a corner, "
                           "or on two edges)")
    if collapsed == "skip":
        # Slivers whose nodes all lie on one CAD edge and its vertices (Gmsh leaves such
        # "invalid" elements along some edges): no node can leave the edge, so no optimizer can
        # make them valid. They are left out like collapsed elements.
        flat, shape_measure = _flat_boundary_elements(work, handle)
        # Elements wound against their face's mesh next to the elements left out (a mesher's
        # degenerate spot): tangled wherever their nodes are. Elsewhere (an STL with flipped
        # facets) they stay: measure counts them, optimize refuses and names them.
        miswound = np.zeros(work.element_count, dtype=bool)
        if bad.any():
            near = data.nodes_of(bad)
            for e in np.asarray(handle.report.get("miswound_elements", []), dtype=np.int64):
                miswound[e] = near[work.element(int(e))].any()
        if flat.any() or miswound.any():
            keep = ~bad if bad.any() else np.ones(data.element_count, dtype=bool)
            idx = np.nonzero(keep)[0]
            keep[idx[flat | miswound]] = False
            if flat.any():
                data.flat = np.zeros(data.element_count, dtype=bool)
                data.flat[idx[flat]] = True
            bad = ~keep
            work = data.subset(keep)
            data.kept = keep
            handle = build(work, same_nodes_as=handle)
            shape_measure = None  # measured on the handle replaced here
            if flat.any():
                reasons.append(
                    f"{int(flat.sum())} flat element(s) on one CAD edge or with two nodes on "
                    "one CAD vertex"
                )
            if miswound.any():
                reasons.append(f"{int(miswound.sum())} element(s) wound against their face's "
                               "mesh next to those")
    handle.release_node_search()  # kept only for the second recovery
    if data.kept is not None:
        ids = data.element_ids[bad]
        report = handle.report  # the handle's own dict: additions stay with it
        n = int(bad.sum())
        shown = ", ".join(str(int(i)) for i in ids[:10]) + (" …" if n > 10 else "")
        report["warnings"] = list(report.get("warnings", [])) + [
            f"left out {' and '.join(reasons)}: ids {shown}"
        ]
        report["skipped_elements"] = [int(i) for i in ids]
    if glue is not None:
        # The core sees the glued nodes as nodes of no element: they are not counted as such.
        glued, note = glue
        report = handle.report
        report["glued_nodes"] = int(glued.size)
        unused = max(0, int(report.get("unused_nodes", 0)) - glued.size)
        report["unused_nodes"] = unused
        if "loose_nodes" in report:
            keep = ~np.isin(np.asarray(report["loose_nodes"], dtype=np.int64), glued)
            for key in _LOOSE_KEYS:
                report[key] = np.asarray(report[key])[keep]
        if "fixed_nodes" in report:  # a glued node is fixed when the node it moves with is
            kinds = np.asarray(handle.node_kinds())
            report["fixed_nodes"] = int(report["fixed_nodes"]) - glued.size + int(
                np.count_nonzero(kinds[data.glued[glued]] == 0))
        warnings = []
        for w in report.get("warnings", []):
            if _UNUSED_NODES.match(w):
                if not unused:
                    continue
                w = (_name_by_ids(_loose_note(report), data) if "loose_nodes" in report
                     else _UNUSED_NODES.sub(f"{unused} nodes belong", w, count=1))
            warnings.append(w)
        report["warnings"] = warnings + [note]
    astray = _side_nodes_astray(data)
    if astray.any():
        n = int(astray.sum())
        ids = data.element_ids[astray]
        shown = ", ".join(str(int(i)) for i in ids[:10]) + (" …" if n > 10 else "")
        report = handle.report
        report["warnings"] = list(report.get("warnings", [])) + [
            f"{n} high-order element(s) have a side node farther from its side than the side is "
            f"long (ids {shown}): is the node order corners first, then the side nodes of "
            "sides 1-2, 2-3, 3-1?"
        ]
    if timings is not None:
        timings["read"] = t_read - t0
        timings["recovery"] = time.perf_counter() - t_read
    return data, handle, shape_measure


_UNUSED_NODES = re.compile(r"^\d+ nodes belong(?= to no element)")
# The bridge report's arrays on the nodes of no element (aligned with "loose_nodes").
_LOOSE_KEYS = ("loose_nodes", "loose_class", "loose_entity", "loose_distance")
_ENTITY_NAMES = ("Vertex", "Edge", "Face")


def _loose_note(report):
    """The core's warning on the nodes of no element (its indices), from the report's arrays
    (after glued nodes were taken out of them)."""
    loose = np.asarray(report["loose_nodes"], dtype=np.int64)
    cls = np.asarray(report["loose_class"], dtype=np.int64)
    dist = np.asarray(report["loose_distance"], dtype=np.float64)
    ent = np.asarray(report["loose_entity"], dtype=np.int64)
    k = int(np.argmax(dist))
    kind = ("vertex", "edge", "face", "none")[int(cls[k])]
    return (f"{loose.size} nodes belong to no element (e.g. nodes of edge or vertex elements); "
            "they are kept fixed and lie on the shape: "
            f"{int(np.sum(cls == 0))} on CAD vertices, {int(np.sum(cls == 1))} on CAD edges, "
            f"{int(np.sum(cls == 2))} on faces; farthest: node {int(loose[k])} "
            f"({float(dist[k]):.6g} from {kind} {int(ent[k])}); e.g. nodes "
            + " ".join(str(int(n)) for n in loose[:5]))
# "node 5", "nodes 2 and 7", "nodes 2, 7 and 9", "nodes 7 19 32" (lists as the core writes
# them), "row 5" (a row of the node array); the same for elements.
_ID_LIST = r"(\d+(?:(?:, | and | )\d+(?!\d|\.\d))*)"
_NODE_REF = re.compile(r"\b(nodes?|row) " + _ID_LIST)
_ELEMENT_REF = re.compile(r"\b(elements?) " + _ID_LIST)
_FACE_INDEX = re.compile(r"\b(on|from|of) (face|edge|vertex) (\d+)\b")


#: A side node farther from the segment between its side's corners than this many times the
#: side's length: no curved element a mesher makes (a half circle's middle lies at 0.5).
_SIDE_NODE_REACH = 1.0


def _side_nodes_astray(data):
    """Bool mask of the high-order triangles with a side node farther from its side's chord
    than _SIDE_NODE_REACH × the chord's length: the mark of a node list in another order than
    corners first, then the side nodes of sides 1-2, 2-3, 3-1 (Gmsh's and FreeCAD's)."""
    out = np.zeros(data.element_count, dtype=bool)
    sizes = np.diff(data.offsets)
    for name, order in (("tri6", 2), ("tri10", 3), ("tri15", 4), ("tri21", 5), ("quad8", 2)):
        sel = np.nonzero(data.types == conversion.ELEMENT_TYPES[name])[0]
        if sel.size == 0:
            continue
        nc = 4 if name == "quad8" else 3
        k = int(sizes[sel[0]])
        idx = data.offsets[sel][:, None] + np.arange(k)[None, :]
        xyz = data.nodes[data.conn[idx]]  # (n, k, 3)
        for side in range(nc):
            a, b = xyz[:, side], xyz[:, (side + 1) % nc]
            ab = b - a
            length2 = np.einsum("ij,ij->i", ab, ab)
            for j in range(order - 1):
                x = xyz[:, nc + side * (order - 1) + j]
                t = np.einsum("ij,ij->i", x - a, ab) / np.where(length2 > 0, length2, 1.0)
                foot = a + np.clip(t, 0.0, 1.0)[:, None] * ab
                d2 = np.einsum("ij,ij->i", x - foot, x - foot)
                out[sel] |= d2 > _SIDE_NODE_REACH**2 * length2
    return out


def _name_by_ids(message, data):
    """The core names nodes and elements by their 0-based position in the arrays it was given;
    users know them by their ids (FEM node and element ids, which need not start at 0 or 1).
    Rewrites "node 5", "nodes 2 and 7", "nodes 2, 7 and 9", "nodes 7 19 32", "row 5" (a row
    of the node array) and "element 3" (every id of a list); "on face 4" and "from edge 2"
    (the core's indices of the shape's faces, edges and vertices) become FreeCAD's names,
    "on Face5", "from Edge3"."""
    def ids_of(table, label_row=False):
        def one(m):
            k = int(m.group(0))
            return str(int(table[k])) if 0 <= k < len(table) else m.group(0)

        def sub(m):
            word = "node" if (label_row and m.group(1) == "row") else m.group(1)
            return f"{word} " + re.sub(r"\d+", one, m.group(2))
        return sub

    if getattr(data, "node_ids", None) is not None:
        message = _NODE_REF.sub(ids_of(data.node_ids, label_row=True), message)
    if getattr(data, "element_ids", None) is not None:
        message = _ELEMENT_REF.sub(ids_of(data.element_ids), message)
    # The core's face index (the shape's faces counted from 0) as FreeCAD names the face.
    return _FACE_INDEX.sub(
        lambda m: f"{m.group(1)} {m.group(2).capitalize()}{int(m.group(3)) + 1}", message)


def _flat_boundary_elements(work, handle):
    """Bool mask (over ``work``'s elements) of tangled elements that no node movement can
    repair: (nearly) zero-area ones (scaled det S within 1e-2 of 0) whose corners all lie on
    CAD edges or vertices, the edge nodes all on one edge (slivers along a CAD edge), and ones
    with two corners on the same CAD vertex (two mesh nodes within that vertex's tolerance: a
    collapsed edge, like a repeated node). Returns ``(mask, measured)``: ``measured`` is the
    handle's "shape" measure this took (``handle.measure("shape")``)."""
    cls = np.asarray(handle.report["node_class"])
    ent = np.asarray(handle.report["node_entity"])
    q = handle.measure("shape")
    sigma = np.asarray(q["min_sigma"])
    tangled = np.asarray(q["tangled"])
    out = np.zeros(work.element_count, dtype=bool)
    for e in np.nonzero(tangled)[0]:
        nodes = work.element(e)[:3 if work.types[e] not in conversion.QUAD_CODES else 4]
        c = cls[nodes]
        vertices = ent[nodes][c == 0].tolist()
        if len(vertices) != len(set(vertices)):
            out[e] = True
        elif abs(sigma[e]) <= 1e-2 and np.all((c == 0) | (c == 1)):
            edges = set(ent[nodes][c == 1].tolist())
            if len(edges) <= 1:
                out[e] = True
    return out, q


def volume_mesh_refusal(count, types=None):
    """Why optimize refuses a mesh with ``count`` volume elements (of ``types``, when known)."""
    kinds = f" ({types})" if types else ""
    return (f"the mesh has {count} volume element(s){kinds} besides its surface elements: "
            "moving the surface nodes would distort them (their interior nodes do not follow), "
            "and those along the surface could be inverted. Optimize the surface (2D) mesh, "
            "then mesh the volume from it; measure works as it is")


def _bridge_report(handle, data):
    """The bridge's report for the user: element and node lists by the user's ids (FEM and
    file ids; 0-based indices of a Mesh.Mesh or of arrays), not the core's indices."""
    out = dict(handle.report)
    if "miswound_elements" in out:
        out["miswound_elements"] = _user_element_ids(
            data, [int(e) for e in np.asarray(out["miswound_elements"])])
    if "placed_nodes" in out:
        out["placed_nodes"] = [int(data.node_ids[int(n)])
                               for n in np.asarray(out["placed_nodes"])]
    if "loose_nodes" in out:
        # The nodes of no element (of edge or vertex elements alone), by the user's ids, and
        # where each lies: FreeCAD's name of the vertex, edge or face, and the distance to it.
        out["loose_nodes"] = [int(data.node_ids[int(n)]) for n in np.asarray(out["loose_nodes"])]
        out["loose_on"] = [
            f"{_ENTITY_NAMES[int(c)]}{int(e) + 1}" if int(c) < 3 and int(e) >= 0 else ""
            for c, e in zip(np.asarray(out.pop("loose_class")),
                            np.asarray(out.pop("loose_entity")))]
        out["loose_distance"] = [float(d) for d in np.asarray(out["loose_distance"])]
    if "trim_gaps" in out:  # FreeCAD's names of the faces and edges
        out["trim_gaps"] = [dict(face=f"Face{int(g['face']) + 1}", edge=f"Edge{int(g['edge']) + 1}",
                                 gap=float(g["gap"]), tolerance=float(g["tolerance"]))
                            for g in out["trim_gaps"]]
    return out


def _is_core_shape(obj):
    try:
        return isinstance(obj, core().CadShape)
    except ImportError:
        return False


def _report(data, handle, name, bridge=None, measured=None) -> QualityReport:
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
        bridge=bridge if bridge is not None else _bridge_report(handle, data),
        skipped=skipped,
        element_faces=faces,
        across=across,
    )


# ---- public API ------------------------------------------------------------------------------


def measure(mesh, shape, measure="shape", *, tolerance=None, hints="auto",
            collapsed="skip", duplicates="glue") -> QualityReport:
    """Quality of every element of ``mesh`` on ``shape`` with the named measure.

    Args:
        mesh: Mesh.Mesh, Fem.FemMesh or a document object holding one (or a MeshData).
        shape: Part.Shape or a document object with ``.Shape``.
        measure: a name of :func:`measure_names` ("shape": Knupp's shape measure, "oddy").
        tolerance: distance under which a node counts as lying on the shape (default: chosen
            by the core from the shape's size and its tolerances).
        hints, collapsed, duplicates: see :func:`prepare`.

    Returns:
        QualityReport with ``quality`` (1/η, 0 tangled), ``tangled``, ``stats``.
    """
    _check_measure(measure)
    data, handle, measured = _prepare(mesh, shape, "fixed", tolerance, hints, collapsed,
                                      duplicates)
    return _report(data, handle, measure, measured=measured if measure == "shape" else None)


def metrics(mesh, shape, names=None, *, tolerance=None, hints="auto", collapsed="skip",
            duplicates="glue", divisions=None) -> dict:
    """The element quality metrics FEM users know, per element, in the order of :func:`measure`.

    Args:
        mesh, shape, tolerance, hints, collapsed, duplicates: as in :func:`measure`.
        names: metric names (a list, or a comma-separated string); None or "all" for every
            one of :data:`SurfMesh.app.metrics.METRIC_NAMES`: Verdict's ``aspect_ratio``,
            ``min_angle``, ``max_angle`` (degrees), ``scaled_jacobian``, ``condition``,
            ``shape``, ``equiangle_skew``; for quadrilaterals also ``warpage``, ``taper``,
            ``skew``, ``stretch`` (nan for triangles); ``jacobian_ratio`` (min J / max J over
            the element, curved sides included: <= 0 folded), ``side_node_offset`` (a
            high-order element's side nodes off their straight sides, over the side's length;
            0 for linear elements) and ``distance_to_cad`` (largest distance of the element's
            interior from its CAD face's surface, sampled densely). See docs/metrics.md.
        divisions: grid steps per side of the reference element at which distance_to_cad and
            jacobian_ratio sample an element (default ``SAMPLE_DIVISIONS``, 8).

    Returns:
        dict name -> numpy float64 array (E,). Elements left out (see ``collapsed``) have nan
        for jacobian_ratio and distance_to_cad (the metrics that need their CAD face).
    """
    from SurfMesh.app import metrics as _metrics

    wanted = _metrics.metric_names(names)
    if divisions is None:
        divisions = _metrics.SAMPLE_DIVISIONS
    if isinstance(divisions, bool) or not isinstance(divisions, (int, np.integer)) \
            or divisions < 1:
        raise ValueError(f"divisions must be a positive integer, got {divisions!r}")
    data, handle, measured = _prepare(mesh, shape, "fixed", tolerance, hints, collapsed,
                                      duplicates)
    rep = _report(data, handle, "shape", measured=measured)
    out = _metrics.element_metrics(data, [n for n in wanted if n not in _CORE_METRICS],
                                   tangled=rep.tangled)
    kept = getattr(data, "kept", None)
    for name in wanted:
        if name not in _CORE_METRICS:
            continue
        values = np.asarray(getattr(handle, _CORE_METRICS[name])(int(divisions)),
                            dtype=np.float64)
        if kept is not None:
            full = np.full(data.element_count, np.nan)
            full[kept] = values
            values = full
        out[name] = values
    return {n: out[n] for n in wanted}


# Metrics the core computes on the handle (its own elements: the ones not left out).
_CORE_METRICS = {"distance_to_cad": "distance_to_face", "jacobian_ratio": "jacobian_ratio"}


def optimize(
    mesh,
    shape,
    measure="shape",
    boundary="fixed",
    *,
    tolerance=None,
    hints="auto",
    collapsed="skip",
    duplicates="glue",
    progress: Optional[Callable[[dict], Optional[bool]]] = None,
    faces=None,
    fixed_nodes=None,
    **options,
) -> OptimizeResult:
    """Smooths and untangles ``mesh`` on ``shape``; the input is not modified.

    Args:
        mesh, shape, measure, tolerance, hints, collapsed, duplicates: as in :func:`measure`.
        boundary: "fixed" (nodes on CAD edges and vertices stay) or "slide" (nodes on CAD edges
            slide along their edge; vertices stay).
        progress: called after every sweep with a dict (sweep, max_sweeps, objective, tangled,
            min_quality, delta); return False to cancel (then :class:`Cancelled` is raised).
        faces: optimize only the elements on these faces of the shape, by FreeCAD's names
            ("Face3") or numbers (3 for Face3), or as Part.Face objects of the shape: every
            node of an element on another face stays where it is (so does a node on a CAD edge
            between a chosen and another face). The whole mesh is measured.
        fixed_nodes: ids of nodes to leave where they are (FEM node ids; 0-based point indices
            of a Mesh.Mesh or of arrays).
        **options: the core's optimizer options, see :data:`OPTIMIZE_DEFAULTS`.

    Returns:
        OptimizeResult: ``mesh`` (new, same kind as the input), ``nodes``, ``before``,
        ``after``, ``sweeps``, ``seconds``, ``reason``.
    """
    _check_measure(measure)
    unknown = sorted(set(options) - set(OPTIMIZE_DEFAULTS))
    if unknown:
        raise ValueError(
            f"unknown option(s) {', '.join(unknown)}; known: {', '.join(OPTIMIZE_DEFAULTS)}"
        )
    opts = dict(OPTIMIZE_DEFAULTS)
    opts.update(options)
    _check_options(opts)
    if progress is not None and not callable(progress):
        raise ValueError("progress must be callable (or None)")
    t_start = time.perf_counter()
    timings = {}
    data, handle, measured = _prepare(
        mesh, shape, boundary, tolerance, hints, collapsed, duplicates, timings=timings,
        moving=True,
    )
    bridge = _bridge_report(handle, data)
    miswound = [int(e) for e in np.asarray(handle.report.get("miswound_elements", []))]
    if miswound:
        raise ValueError(
            f"{len(miswound)} element(s) are wound against the rest of their face's mesh "
            f"(their nodes are listed in the opposite order): element(s) "
            f"{_id_list(_user_element_ids(data, miswound))}"
            f"{_where(data, handle, data.nodes, miswound)}. They are tangled whatever their node "
            "positions, and moving nodes would only fold the mesh over them: reverse their "
            "node order first (FreeCAD: Mesh > Analyze > Evaluate and repair > Orientation, or "
            "Mesh.harmonizeNormals())"
        )
    held = _held_nodes(data, handle, shape, faces, fixed_nodes)
    # the held nodes that would have moved (kind 0: fixed anyway)
    held_nodes = (0 if held is None
                  else int(np.count_nonzero(held & (np.asarray(handle.node_kinds()) != 0))))
    # The nodes of the flat elements left out stay where they are (see _flat_nodes).
    flat_nodes = _flat_nodes(data, handle)
    if flat_nodes is not None:
        held = flat_nodes if held is None else held | flat_nodes
    t0 = time.perf_counter()
    before = _report(data, handle, measure, bridge,
                     measured=measured if measure == "shape" else None)
    t1 = time.perf_counter()
    stats = {k: before.stats[k]
             for k in ("min", "max", "mean", "std", "tangled", "elements", "across")}
    fewest = {"tangled": None, "sweep": 0}  # when the run last reached fewer tangled elements

    def track(p):
        if fewest["tangled"] is None or p["tangled"] < fewest["tangled"]:
            fewest.update(tangled=p["tangled"], sweep=p["sweep"])
        return None if progress is None else progress(p)

    _progress.phase("optimizing")
    r = handle.optimize(measure=measure, progress=track, before=stats, fixed=held, **opts)
    if r["reason"] == "cancelled":
        raise Cancelled(f"optimization cancelled after {r['sweeps']} sweep(s); nothing changed")
    t2 = time.perf_counter()
    seconds = float(r.get("seconds", t2 - t1))
    new_nodes = handle.positions()
    if data.glued is not None:  # a glued node goes where the node it is glued to went
        new_nodes = new_nodes[data.glued]
    _progress.phase("measuring the result")
    after = _report(data, handle, measure, bridge)
    new_mesh = conversion.rebuild(data, new_nodes) if data.kind in ("mesh", "fem") else None
    # The distances of the moved nodes, on the positions returned (a Mesh.Mesh's float32 ones).
    returned = new_nodes if data.kind != "mesh" else conversion.read_mesh(new_mesh).nodes
    after.stats.update(_moved_node_distances(data, handle, returned))
    t3 = time.perf_counter()
    t4 = time.perf_counter()
    timings.update(before=t1 - t0, optimize=t2 - t1, after=t3 - t2, rebuild=t4 - t3,
                   total=t4 - t_start)
    core_unmovable = list(r.get("tangled_unmovable", []))
    core_movable = list(r.get("tangled_movable", []))
    unmovable = _user_element_ids(data, core_unmovable)
    movable = _user_element_ids(data, core_movable)
    warnings = []
    if unmovable:
        hint = "try boundary='slide', or change" if boundary == "fixed" else "change"
        kept = ", held by faces= or fixed_nodes=" if held is not None else ""
        warnings.append(
            f"{len(unmovable)} element(s) stay tangled with no node that may move where they "
            f"fold (their nodes there are all on CAD vertices, fixed CAD edges or poles{kept}; "
            f"{hint} the mesh there): elements "
            f"{_id_list(unmovable)}{_where(data, handle, new_nodes, core_unmovable)}"
        )
    if movable:
        quiet = int(r["sweeps"]) - fewest["sweep"]  # sweeps since the last drop
        if r["reason"] == "max_sweeps" and quiet < _STILL_DROPPING:
            hint = ("the run reached max_sweeps while their number was still dropping: try more "
                    "sweeps")
        else:
            hint = ("the run found no motion of their movable nodes that repairs them"
                    if r["reason"] != "max_sweeps" else
                    f"the run reached max_sweeps, but their number has not dropped over its last "
                    f"{quiet} sweeps, so more sweeps are unlikely to help")
            sep = "; " if r["reason"] == "max_sweeps" else ": "
            if boundary == "fixed":
                hint += sep + "try boundary='slide'"
            else:
                hint += (sep + "change the mesh there, e.g. elements smaller than the CAD "
                         "feature they span")
        warnings.append(
            f"{len(movable)} element(s) stay tangled although some of their nodes may move "
            f"({hint}): elements {_id_list(movable)}"
            f"{_where(data, handle, new_nodes, core_movable)}"
        )
    n_across0, n_across = int(before.stats["across"]), int(after.stats["across"])
    if n_across:
        mask = after.across if data.kept is None else after.across[data.kept]
        core_across = [int(k) for k in np.nonzero(mask)[0]]
        warnings.append(
            f"{n_across} element(s) stand across the surface after the run ({n_across0} "
            "before): each is wound along its face's normal at some corners and against it at "
            "others, like a triangle spanning more than half the way round a thin tube, whose "
            "plane cuts through the part. The measure (the paper's: the element in its own "
            "plane, oriented by the sum of its corner normals) can count them valid and well "
            "shaped; elements smaller than the surface's radius of curvature there avoid them: "
            f"elements {_id_list(_user_element_ids(data, core_across))}"
            f"{_where(data, handle, new_nodes, core_across)}"
        )
    return OptimizeResult(
        mesh=new_mesh,
        nodes=new_nodes,
        before=before,
        after=after,
        sweeps=int(r["sweeps"]),
        seconds=seconds,
        reason=str(r["reason"]),
        moved_nodes=int(r.get("moved_nodes", 0)),
        threads=int(r.get("threads", 1)),
        straightened_elements=int(r.get("straightened_elements", 0)),
        held_nodes=held_nodes,
        options=dict(opts, measure=measure, boundary=boundary,
                     **({} if faces is None else {"faces": _face_names(faces)}),
                     **({} if fixed_nodes is None else {"fixed_nodes": len(fixed_nodes)})),
        bridge=bridge,
        tangled_unmovable=unmovable,
        tangled_movable=movable,
        warnings=warnings,
        timings=timings,
    )


def _moved_node_distances(data, handle, nodes):
    """Figures of a result on its returned positions ``nodes`` (N, 3): how many nodes moved,
    the largest distance of a moved node to its face (the trimmed face, its boundary edges
    included: a node beyond them is as far as its nearest boundary point) and to the whole
    shape, and the ids of the nodes where they are reached (-1 when no node moved)."""
    moved = np.any(nodes != data.nodes, axis=1)
    out = {"moved_nodes": int(np.count_nonzero(moved)), "max_distance_to_face": 0.0,
           "max_distance_to_shape": 0.0, "worst_node_to_face": -1, "worst_node_to_shape": -1}
    if not moved.any():
        return out
    # each node's face: the one it moves on, else (a node sliding on a CAD edge) the face of an
    # element of it; a glued node takes the face of the node it is glued to
    work = data if data.kept is None else data.subset(data.kept)
    face = np.full(data.node_count, -1, dtype=np.int64)
    face[work.conn] = np.repeat(np.asarray(handle.element_faces(), dtype=np.int64),
                                np.diff(work.offsets))
    own = np.asarray(handle.node_faces(), dtype=np.int64)
    face = np.where(own >= 0, own, face)
    if data.glued is not None:
        face = face[data.glued]
    idx = np.nonzero(moved)[0]
    to_face, to_shape = handle.distances_to_shape(
        np.ascontiguousarray(nodes[idx], dtype=np.float64), face[idx])
    to_face = np.where(np.isnan(to_face), to_shape, to_face)
    kf, ks = int(np.argmax(to_face)), int(np.argmax(to_shape))
    out.update(max_distance_to_face=float(to_face[kf]), max_distance_to_shape=float(to_shape[ks]),
               worst_node_to_face=int(data.node_ids[idx[kf]]),
               worst_node_to_shape=int(data.node_ids[idx[ks]]))
    return out


def face_list(text):
    """The faces of a typed list ("Face3, Face7", "3;7", "Face3 7") as :func:`optimize`
    takes them: names stay, numbers become names (["Face3", "Face7"])."""
    items = [t for t in text.replace(";", ",").replace(" ", ",").split(",") if t]
    return [f"Face{t}" if t.isdigit() else t for t in items]


def _face_items(faces):
    """``faces=`` as a list (one name, number or face given alone is a list of one)."""
    if isinstance(faces, (str, int, np.integer)) or hasattr(faces, "ShapeType"):
        return [faces]
    try:
        return list(faces)
    except TypeError:
        raise ValueError(f"faces must be a list of face names, numbers or faces, got {faces!r}") \
            from None


def _face_numbers(faces, part, count):
    """FreeCAD face numbers (1 for Face1) of ``faces`` (names, numbers or Part.Face objects of
    the Part.Shape ``part``, None for a core shape), checked against its ``count`` faces."""
    items = _face_items(faces)
    if not items:
        raise ValueError("faces is empty: give the faces whose elements to optimize")
    numbers = []
    for f in items:
        if hasattr(f, "ShapeType"):
            if f.ShapeType != "Face" or part is None:
                raise ValueError(f"faces: {f!r} is not a face of the shape")
            match = [k + 1 for k, g in enumerate(part.Faces) if g.isSame(f)]
            if not match:
                raise ValueError("faces: a Part.Face given is not a face of the shape")
            numbers.append(match[0])
            continue
        if isinstance(f, str):
            m = re.fullmatch(r"\s*Face(\d+)\s*", f)
            if not m:
                raise ValueError(f"faces: {f!r} is not a face name (Face1, Face2, …)")
            n = int(m.group(1))
        elif isinstance(f, (int, np.integer)) and not isinstance(f, bool):
            n = int(f)
        else:
            raise ValueError(f"faces: {f!r} is neither a face name, a number nor a face")
        if not 1 <= n <= count:
            raise ValueError(f"faces: Face{n} is not a face of the shape, which has {count} "
                             f"face(s), Face1 to Face{count}")
        numbers.append(n)
    return sorted(set(numbers))


def _face_names(faces):
    """The faces= option as the result's options record it (names when given as such)."""
    return [f if isinstance(f, str) else (int(f) if isinstance(f, (int, np.integer))
                                          else "Part.Face") for f in _face_items(faces)]


def _held_nodes(data, handle, shape, faces, fixed_nodes):
    """The core's bool mask of the nodes ``faces=`` and ``fixed_nodes=`` hold (see
    :func:`optimize`), or None when neither is given."""
    if faces is None and fixed_nodes is None:
        return None
    held = np.zeros(data.node_count, dtype=bool)
    if faces is not None:
        part = None if _is_core_shape(shape) else shapes.shape_of(shape)
        count = shape.face_count if part is None else len(part.Faces)
        chosen = np.asarray(_face_numbers(faces, part, count), dtype=np.int64) - 1
        elem_faces = np.asarray(handle.element_faces(), dtype=np.int64)
        carried = np.isin(chosen, elem_faces)
        if not carried.all():
            bare = ", ".join(f"Face{int(f) + 1}" for f in chosen[~carried])
            raise ValueError(f"faces: no element of the mesh lies on {bare}")
        # every node of an element (of the input's) on another face
        elsewhere = np.zeros(data.element_count, dtype=bool)
        elsewhere[_input_element_indices(data, np.nonzero(~np.isin(elem_faces, chosen))[0])] = True
        held |= data.nodes_of(elsewhere)
    if fixed_nodes is not None:
        if isinstance(fixed_nodes, (int, np.integer)):
            fixed_nodes = [fixed_nodes]
        try:
            ids = np.asarray(list(fixed_nodes))
        except TypeError:
            raise ValueError(f"fixed_nodes must be a list of node ids, got {fixed_nodes!r}") \
                from None
        if ids.size and (ids.dtype.kind not in "iu"):
            raise ValueError(f"fixed_nodes must be integer node ids, got {fixed_nodes!r}")
        idx, missing = conversion.positions_of(data.node_ids, ids.astype(np.int64))
        if missing.any():
            raise ValueError(f"fixed_nodes: the mesh has no node with id "
                             f"{_id_list([int(i) for i in ids[missing]], 10)}")
        # a glued node moves with the one it is glued to: that one is held
        held[idx if data.glued is None else data.glued[idx]] = True
    return held


def _flat_nodes(data, handle):
    """The core's bool mask of the nodes of the flat elements left out (see
    :func:`_flat_boundary_elements`) that the run would move, or None when there are none.

    A flat element is not measured, so the optimizer cannot see it fold: a high-order one
    in a cusp of its face (two tangent CAD edges at a corner: zero angle there) shares side
    nodes with measured elements, and moving those by a fraction of the element's size turns
    it inside out while every measured element improves. Measured again, it is then tangled
    (and no longer flat). Holding its nodes keeps it exactly as it was, so it is left out
    again; every other node moves as before (nothing changes in a mesh without flat elements,
    nor where their nodes all lie on fixed CAD edges and vertices, as Gmsh's slivers along an
    edge do)."""
    flat = getattr(data, "flat", None)
    if flat is None or not flat.any():
        return None
    nodes = data.nodes_of(flat) & (np.asarray(handle.node_kinds()) != 0)
    return nodes if nodes.any() else None


def _input_element_indices(data, core_indices):
    """Core element indices (over the elements that were optimized, i.e. without the skipped
    ones) → 0-based indices into the input's element arrays."""
    idx = np.asarray(list(core_indices), dtype=np.int64)
    kept = getattr(data, "kept", None)
    return np.nonzero(kept)[0][idx] if kept is not None else idx


def _user_element_ids(data, core_indices):
    """Core element indices → the user's element ids (FEM ids, else 0-based input indices)."""
    idx = _input_element_indices(data, core_indices)
    ids = getattr(data, "element_ids", None)
    if ids is not None:
        idx = np.asarray(ids)[idx]
    return [int(i) for i in idx]


def _where(data, handle, nodes, core_indices):
    """Where the first of these elements is, for a warning: its centroid (at `nodes`) and the
    CAD face it lies on, by FreeCAD's name (Face1 is the shape's first face)."""
    if not core_indices:
        return ""
    k = int(core_indices[0])
    e = int(_input_element_indices(data, [k])[0])
    c = nodes[data.conn[data.offsets[e]:data.offsets[e + 1]]].mean(axis=0)
    face = int(handle.element_faces()[k]) + 1
    return f" (the first near ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) on Face{face})"


def _id_list(ids, shown=20):
    text = ", ".join(str(i) for i in ids[:shown])
    return text + (", …" if len(ids) > shown else "")


def _check_options(o):
    def positive_int(k):
        v = o[k]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{k} must be a positive integer, got {v!r}")

    def positive_float(k):
        v = o[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0) or v == np.inf:
            raise ValueError(f"{k} must be a positive number, got {v!r}")

    for k in ("max_sweeps", "inner_iterations", "max_line_search"):
        positive_int(k)
    for k in ("rel_tol", "move_tol", "delta_epsilon", "delta"):
        positive_float(k)
    w = o["over_relaxation"]
    if isinstance(w, bool) or not isinstance(w, (int, float)) or not (1 <= w < 2):
        raise ValueError(f"over_relaxation must be a number in [1, 2), got {w!r}")
    if o["delta_policy"] not in ("auto", "fixed"):
        raise ValueError(f"delta_policy must be 'auto' or 'fixed', got {o['delta_policy']!r}")
    t = o["threads"]
    if isinstance(t, bool) or not isinstance(t, (int, np.integer)) or t < 0:
        raise ValueError(f"threads must be an integer ≥ 0, got {t!r}")
    if not isinstance(o["monotone"], (bool, np.bool_)):
        raise ValueError(f"monotone must be True or False, got {o['monotone']!r}")
    o["monotone"] = bool(o["monotone"])
