"""Preparing a run: the mesh and the shape read, checked and given to the core's CAD bridge,
which puts every node on the shape's faces, edges and vertices (:func:`prepare`).

Degenerate elements (collapsed, folded pairs, overlapping or misjoined ones around those, flat
slivers on a CAD edge) are left out here, coincident nodes glued, and the bridge's report
completed and put in the user's ids (:func:`bridge_report`).

This module never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from SurfMesh.app import conversion, messages, options, shapes
from SurfMesh.app import progress as _progress
from SurfMesh.app.native import core

# The bridge report's arrays on the nodes of no element (aligned with "loose_nodes").
_LOOSE_KEYS = ("loose_nodes", "loose_class", "loose_entity", "loose_distance")
_ENTITY_NAMES = ("Vertex", "Edge", "Face")

#: A side node farther from the segment between its side's corners than this many times the
#: side's length: no curved element a mesher makes (a half circle's middle lies at 0.5).
_SIDE_NODE_REACH = 1.0


def core_shape(shape):
    """Core CadShape from a Part.Shape (through BREP text)."""
    return core().CadShape.from_brep_string(shapes.brep_string(shape))


def is_core_shape(obj):
    try:
        return isinstance(obj, core().CadShape)
    except ImportError:
        return False


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
    minutes on big parts; face nodes are classified by the core, and a high-order node
    inside one face's mesh — all its elements on that face, not on the mesh's boundary — is
    a face node, unlike FreeCAD's queries, when it lies on the CAD edge or when its side
    does not follow that edge; other inputs: no hints),
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
    data, handle, _ = prepare_measured(mesh, shape, boundary, tolerance, hints, collapsed,
                                       duplicates)
    return data, handle


def surface_nodes_only(data):
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


def glue_coincident(data):
    """``data`` with its coincident nodes glued (see :func:`prepare`), and (the glued nodes'
    indices, the warning to give), or None when no nodes coincide."""
    rep = data.coincident_nodes()
    if rep is None:
        return data, None
    moved = np.nonzero(rep != np.arange(rep.size))[0]
    a = int(moved[0])
    b = int(rep[a])
    note = messages.glued_nodes(moved.size, int(data.node_ids[b]), int(data.node_ids[a]),
                                tuple(float(c) for c in data.nodes[a]))
    return dataclasses.replace(data, conn=rep[data.conn], glued=rep), (moved, note)


def prepare_measured(mesh, shape, boundary, tolerance, hints, collapsed, duplicates="glue",
                     timings=None, moving=False, keep_flat=False):
    """:func:`prepare`, and the "shape" measure of the returned handle when it was taken on
    the way (else None): measuring it again would give the same result. ``timings`` (a dict),
    when given, receives the seconds of reading the mesh ("read") and of the rest ("recovery").
    ``moving``: for a run that moves nodes (a mesh with volume elements is refused).
    ``keep_flat``: the flat slivers along a CAD edge stay in the mesh (a run with edge flips,
    which can repair them, instead of leaving them out as ``collapsed="skip"`` does).
    """
    t0 = time.perf_counter()
    options.check_prepare_arguments(boundary, tolerance, collapsed, duplicates)
    _progress.phase("reading the mesh")
    data = conversion.read_mesh(mesh)
    t_read = time.perf_counter()
    part_shape = shapes.shape_of(shape) if not is_core_shape(shape) else None
    if data.element_count == 0:
        raise ValueError("the mesh has no elements")
    if moving and data.volume_elements:
        raise ValueError(messages.volume_mesh_refusal(data.volume_elements, data.volume_types))
    if data.volume_elements:
        data = surface_nodes_only(data)
    options.check_hints(hints)
    if data.kind == "fem" and hints == "all" and part_shape is not None:
        conversion.fem_hints(data, part_shape, faces=True)
    tolerance_hints = hints == "tolerance" or (data.kind == "fem" and hints == "auto")
    glue = None
    if duplicates == "glue":
        data, glue = glue_coincident(data)
    data.kept = None
    data.flat = None
    data.flat_kept = None
    bad, reasons = _degenerate_elements(data, collapsed)
    work = data
    if bad.any():
        work = data.subset(~bad)
        data.kept = ~bad
    cshape = shape if part_shape is None else core_shape(part_shape)

    def build(w, keep=False, same_nodes_as=None):
        return _bridge(cshape, data, w, tolerance, boundary, tolerance_hints, keep=keep,
                       same_nodes_as=same_nodes_as)

    # Flat elements found on the first recovery are left out by a second one, which reuses
    # the first's per-node face search (the costly part): same nodes, other elements.
    _progress.phase("placing the nodes on the shape's faces and edges")
    handle = build(work, keep=collapsed == "skip")
    shape_measure = None
    if collapsed == "skip":
        handle, bad, shape_measure, more = _leave_out_flat(data, work, handle, bad, build,
                                                           keep_flat)
        reasons += more
    handle.release_node_search()  # kept only for the second recovery
    if data.kept is not None:
        ids = data.element_ids[bad]
        report = handle.report  # the handle's own dict: additions stay with it
        messages.add_warning(report, messages.left_out(reasons, ids))
        report["skipped_elements"] = [int(i) for i in ids]
    if glue is not None:
        _report_glued(handle, data, glue)
    astray = side_nodes_astray(data)
    if astray.any():
        messages.add_warning(handle.report, messages.side_nodes_astray(data.element_ids[astray]))
    if timings is not None:
        timings["read"] = t_read - t0
        timings["recovery"] = time.perf_counter() - t_read
    return data, handle, shape_measure


def _degenerate_elements(data, collapsed):
    """Bool mask of the elements left out before the bridge (see :func:`prepare`'s
    ``collapsed``) and why (:func:`SurfMesh.app.messages.left_out_reasons`); raises ValueError
    for ``collapsed="error"``, or when every element would be left out."""
    bad = data.collapsed_elements()
    dup = data.duplicate_elements() & ~bad
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
    if not bad.any():
        return bad, []
    if collapsed == "error" or bad.all():
        ids = data.element_ids[bad]
        first = int(np.nonzero(bad)[0][0])
        nodes = [int(n) for n in data.node_ids[data.element(first)]]
        raise ValueError(messages.collapsed_refusal(int(bad.sum()), int(ids[0]), nodes,
                                                    bool(bad.all())))
    n_dup = int(dup.sum())
    n_crowded = int(crowded.sum())
    n_misjoined = int(misjoined.sum())
    return bad, messages.left_out_reasons(
        collapsed=int(bad.sum()) - n_dup - n_crowded - n_misjoined, folded=n_dup,
        crowded=n_crowded, misjoined=n_misjoined)


def _bridge(cshape, data, w, tolerance, boundary, tolerance_hints, keep=False,
            same_nodes_as=None):
    """The core's mesh of ``w`` (``data`` or its subset of the elements kept) on ``cshape``,
    its errors and warnings in the user's ids."""
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
        raise messages.refusal(err, w) from None
    report = h.report  # the handle's own dict: the user's ids in its diagnostics too
    messages.set_diagnostics(report,
                             [messages.for_user(d, w) for d in report.get("diagnostics", [])])
    return h


def _leave_out_flat(data, work, handle, bad, build, keep_flat=False):
    """The second recovery of ``collapsed="skip"``, when the first (``handle``, of ``work``)
    shows flat or miswound elements to leave out; returns (the handle, the mask of the
    elements left out, the "shape" measure taken on the way or None, the reasons added)."""
    # Slivers whose nodes all lie on one CAD edge and its vertices (Gmsh leaves such
    # "invalid" elements along some edges): no node can leave the edge, so no optimizer can
    # make them valid. They are left out like collapsed elements.
    flat, shape_measure = flat_boundary_elements(work, handle)
    if keep_flat:  # edge flips may repair them; the run's report leaves out those still flat
        if flat.any():
            data.flat_kept = np.zeros(data.element_count, dtype=bool)
            data.flat_kept[np.nonzero(~bad)[0][flat]] = True
        flat[:] = False
    # Elements wound against their face's mesh next to the elements left out (a mesher's
    # degenerate spot): tangled wherever their nodes are. Elsewhere (an STL with flipped
    # facets) they stay: measure counts them, optimize refuses and names them.
    miswound = np.zeros(work.element_count, dtype=bool)
    if bad.any():
        near = data.nodes_of(bad)
        for e in np.asarray(handle.report.get("miswound_elements", []), dtype=np.int64):
            miswound[e] = near[work.element(int(e))].any()
    if not flat.any() and not miswound.any():
        return handle, bad, shape_measure, []
    keep = ~bad if bad.any() else np.ones(data.element_count, dtype=bool)
    idx = np.nonzero(keep)[0]
    keep[idx[flat | miswound]] = False
    if flat.any():
        data.flat = np.zeros(data.element_count, dtype=bool)
        data.flat[idx[flat]] = True
    data.kept = keep
    handle = build(data.subset(keep), same_nodes_as=handle)
    # (no "shape" measure: it was taken on the handle replaced here)
    return handle, ~keep, None, messages.left_out_reasons(flat=int(flat.sum()),
                                                          miswound=int(miswound.sum()))


def _report_glued(handle, data, glue):
    """The bridge's report with the glued nodes (``glue``: see :func:`glue_coincident`)."""
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
    diagnostics = []
    for d in report.get("diagnostics", []):
        if d["code"] == "unused_nodes":
            if not unused:
                continue
            d = messages.for_user(messages.loose_nodes(report, d["format"]), data)
        diagnostics.append(d)
    messages.set_diagnostics(report, diagnostics + [note])


def side_nodes_astray(data):
    """Bool mask of the high-order triangles with a side node farther from its side's chord
    than _SIDE_NODE_REACH × the chord's length: the mark of a node list in another order than
    corners first, then the side nodes of sides 1-2, 2-3, 3-1 (Gmsh's and FreeCAD's)."""
    out = np.zeros(data.element_count, dtype=bool)
    sizes = np.diff(data.offsets)
    for code, order in conversion.CURVED_ORDERS.items():
        sel = np.nonzero(data.types == code)[0]
        if sel.size == 0:
            continue
        nc = 4 if code in conversion.QUAD_CODES else 3
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


def still_flat(data, handle, nodes):
    """Bool mask (over ``data``'s elements) of the elements of ``data.flat_kept`` that are
    flat by :func:`flat_boundary_elements` with the node positions ``nodes`` and ``data``'s
    node lists (a run's result, edge flips included): what measuring that result leaves out."""
    out = np.zeros(data.element_count, dtype=bool)
    if data.flat_kept is None:
        return out
    work = data if data.kept is None else data.subset(data.kept)
    flat, _ = flat_boundary_elements(dataclasses.replace(work, nodes=nodes), handle)
    out[input_element_indices(data, np.nonzero(flat)[0])] = True
    return out & data.flat_kept


def flat_boundary_elements(work, handle):
    """Bool mask (over ``work``'s elements) of elements that no node movement can repair:
    tangled ones with two corners on the same CAD vertex (two mesh nodes within that vertex's
    tolerance: a collapsed edge, like a repeated node); ones with three corners on the same CAD
    vertex, measured tangled or not (the CAD sees one point where the element has an area: its
    measure follows from which corner (u,v) stands for that point, and that follows the
    elements around at a degenerate vertex: Gmsh's curvature-sized crank arm has fans of them
    at the pole of a B-spline face, where the same element was valid in the input and tangled
    in a result whose flips changed its neighbours only); and tangled slivers along one CAD
    edge, whose corners all lie on that edge or its vertices:
      * linear ones (tri3, quad4) when (nearly) flat, scaled det S within 1e-2 of 0;
      * curved ones (tri6 ... tri21, quad8) when at a corner both sides that meet there lie on
        CAD edges or vertices (no node of theirs inside a face) and meet at a straight or
        zero angle (the sine of the angle between their tangents there within 0.05 of 0, about
        3°; a cubic side along a curved CAD edge meets its neighbour at 179° there): the
        element's det J there is that angle's, wherever its other nodes go. (Their scaled det
        S is left out of it: a run that moves their free side nodes changes it, and the same
        element would be measured in the input and left out of the result.)
    Returns ``(mask, measured)``: ``measured`` is the handle's "shape" measure this took
    (``handle.measure("shape")``)."""
    cls = np.asarray(handle.report["node_class"])
    ent = np.asarray(handle.report["node_entity"])
    q = handle.measure("shape")
    sigma = np.asarray(q["min_sigma"])
    tangled = np.asarray(q["tangled"])
    tangled = np.asarray(tangled, dtype=bool)
    on_one_vertex = _corners_on_one_vertex(work, cls, ent)
    out = (on_one_vertex >= 3) | (tangled & (on_one_vertex >= 2))
    for e in np.nonzero(tangled & ~out)[0]:
        code = int(work.types[e])
        nc = 4 if code in conversion.QUAD_CODES else 3
        element = work.element(e)
        c, on = cls[element[:nc]], ent[element[:nc]]
        if np.all((c == 0) | (c == 1)) and len(set(on[c == 1].tolist())) <= 1:
            if len(element) == nc:  # tri3, quad4
                out[e] = abs(sigma[e]) <= 1e-2
            else:
                out[e] = _fixed_flat_corner(work.nodes, element, nc,
                                            conversion.CURVED_ORDERS[code] - 1, cls)
    return out, q


def _corners_on_one_vertex(work, cls, ent):
    """Per element of ``work``: the largest number of its corners on one CAD vertex (node
    class 0, the same entity); 0 when none is on a vertex."""
    out = np.zeros(work.element_count, dtype=np.int64)
    quad = np.isin(work.types, list(conversion.QUAD_CODES))
    for nc, sel in ((3, np.nonzero(~quad)[0]), (4, np.nonzero(quad)[0])):
        if sel.size == 0:
            continue
        corners = work.conn[work.offsets[sel][:, None] + np.arange(nc)[None, :]]
        on_vertex = cls[corners] == 0
        vertex = ent[corners]
        for a in range(nc):
            same = on_vertex & on_vertex[:, [a]] & (vertex == vertex[:, [a]])
            out[sel] = np.maximum(out[sel], same.sum(axis=1))
    return out


def _fixed_flat_corner(xyz, element, nc, per_side, cls):
    """Whether a curved element (its node list ``element``, ``nc`` corners first, then each
    side's ``per_side`` nodes from its first corner to its second: Gmsh's order) has a corner
    where both sides lie on CAD edges or vertices (``cls`` ≤ 1 at all their nodes) and meet
    at an angle whose sine is within _FLAT_SINE of 0. The tangent of a side at a corner
    depends on that side's nodes alone (the derivative of its Lagrange interpolant)."""
    weights = _end_derivative(per_side + 1)

    def side(k):  # side k's nodes from corner k to corner k + 1
        inner = element[nc + k * per_side: nc + (k + 1) * per_side]
        return np.concatenate(([element[k]], inner, [element[(k + 1) % nc]])).astype(np.int64)

    for k in range(nc):
        out_side, in_side = side(k), side((k - 1) % nc)[::-1]  # both from corner k
        if np.any(cls[out_side] > 1) or np.any(cls[in_side] > 1):
            continue
        t1 = weights @ xyz[out_side]
        t2 = weights @ xyz[in_side]
        n1, n2 = np.linalg.norm(t1), np.linalg.norm(t2)
        if n1 == 0.0 or n2 == 0.0 or np.linalg.norm(np.cross(t1, t2)) <= _FLAT_SINE * n1 * n2:
            return True
    return False


# The largest sine of a flat corner's angle (_fixed_flat_corner).
_FLAT_SINE = 0.05


def _end_derivative(p):
    """The weights of the derivative at t = 0 of the degree-p Lagrange interpolant on the
    points t = j / p (j = 0 … p): (p + 1,)."""
    t = np.arange(p + 1) / p
    w = np.empty(p + 1)
    for j in range(p + 1):
        others = np.delete(t, j)
        w[j] = np.polyval(np.polyder(np.poly(others)), 0.0) / np.prod(t[j] - others)
    return w


# ---- the core's element indices and the user's ids -------------------------------------------


def input_element_indices(data, core_indices):
    """Core element indices (over the elements that were optimized, i.e. without the skipped
    ones) → 0-based indices into the input's element arrays."""
    idx = np.asarray(list(core_indices), dtype=np.int64)
    kept = getattr(data, "kept", None)
    return np.nonzero(kept)[0][idx] if kept is not None else idx


def user_element_ids(data, core_indices):
    """Core element indices → the user's element ids (FEM ids, else 0-based input indices)."""
    idx = input_element_indices(data, core_indices)
    ids = getattr(data, "element_ids", None)
    if ids is not None:
        idx = np.asarray(ids)[idx]
    return [int(i) for i in idx]


def bridge_report(handle, data):
    """The bridge's report for the user: element and node lists by the user's ids (FEM and
    file ids; 0-based indices of a Mesh.Mesh or of arrays), not the core's indices."""
    out = dict(handle.report)
    if "miswound_elements" in out:
        out["miswound_elements"] = user_element_ids(
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
