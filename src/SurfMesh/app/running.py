"""Running SurfMesh on a prepared mesh: :func:`measure`, :func:`metrics` and :func:`optimize`
(the core's optimizer on the nodes the run may move, the result read back, its warnings).

This module never imports FreeCADGui.
"""

from __future__ import annotations

import re
import time
from typing import Callable, Optional

import numpy as np

from SurfMesh.app import conversion, messages, preparing, results, shapes
from SurfMesh.app import options as _options
from SurfMesh.app import progress as _progress
from SurfMesh.app.options import DEFAULT_BOUNDARY, DEFAULT_MEASURE

# A run that ends at max_sweeps with tangled elements left advises more sweeps only when their
# number dropped within this many sweeps before the end (3 × the core's deltaStallSweeps: every
# level of its ε tried once since).
_STILL_DROPPING = 24


def measure(mesh, shape, measure=DEFAULT_MEASURE, *, tolerance=None, hints="auto",
            collapsed="skip", duplicates="glue") -> results.QualityReport:
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
    _options.check_measure(measure)
    data, handle, measured = preparing.prepare_measured(mesh, shape, "fixed", tolerance,
                                                        hints, collapsed, duplicates)
    return results.quality_report(data, handle, measure,
                                  measured=measured if measure == "shape" else None)


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
            the element, curved sides included, J signed by the face's normal: <= 0 folded
            or wound against the face), ``side_node_offset`` (a high-order element's side
            nodes off their straight sides, over the side's length; 0 for linear elements)
            and ``distance_to_cad`` (largest distance of the element's interior from its CAD
            face's surface, sampled densely). See docs/metrics.md.
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
    data, handle, measured = preparing.prepare_measured(mesh, shape, "fixed", tolerance,
                                                        hints, collapsed, duplicates)
    rep = results.quality_report(data, handle, "shape", measured=measured)
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
    measure=DEFAULT_MEASURE,
    boundary=DEFAULT_BOUNDARY,
    *,
    tolerance=None,
    hints="auto",
    collapsed="skip",
    duplicates="glue",
    progress: Optional[Callable[[dict], Optional[bool]]] = None,
    faces=None,
    fixed_nodes=None,
    **options,
) -> results.OptimizeResult:
    """Smooths and untangles ``mesh`` on ``shape``; the input is not modified.

    Args:
        mesh, shape, measure, tolerance, hints, collapsed, duplicates: as in :func:`measure`.
        boundary: "fixed" (nodes on CAD edges and vertices stay) or "slide" (nodes on CAD edges
            slide along their edge; vertices stay).
        progress: called after every sweep with a dict (sweep, max_sweeps, objective, tangled,
            min_quality, delta, stage); return False to cancel (then :class:`Cancelled` is raised).
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
    _options.check_measure(measure)
    opts = _options.resolve_options(options)
    if progress is not None and not callable(progress):
        raise ValueError("progress must be callable (or None)")
    t_start = time.perf_counter()
    timings = {}
    data, handle, measured = preparing.prepare_measured(
        mesh, shape, boundary, tolerance, hints, collapsed, duplicates, timings=timings,
        moving=True, keep_flat=opts["topology"] == "flip",
    )
    bridge = preparing.bridge_report(handle, data)
    _refuse_miswound(data, handle)
    held = _held_nodes(data, handle, shape, faces, fixed_nodes)
    # the held nodes that would have moved (kind 0: fixed anyway)
    held_nodes = (0 if held is None
                  else int(np.count_nonzero(held & (np.asarray(handle.node_kinds()) != 0))))
    # The nodes of the flat elements left out stay where they are (see _flat_nodes).
    flat_nodes = _flat_nodes(data, handle)
    fixed = held
    if flat_nodes is not None:
        fixed = flat_nodes if held is None else held | flat_nodes
    t0 = time.perf_counter()
    before = results.quality_report(data, handle, measure, bridge,
                                    measured=measured if measure == "shape" else None)
    t1 = time.perf_counter()
    stats = {k: before.stats[k]
             for k in ("min", "max", "mean", "std", "tangled", "elements", "across")}
    # A run with edge flips keeps the flat elements measure leaves out (a flip may repair
    # them); its report leaves them out as measure does, before and, those still flat, after.
    if data.flat_kept is not None:
        before = results.left_out(before, data.flat_kept)
    # when the run last reached fewer tangled elements; a new stage (the runs of the curved
    # elements' "reference" mode, each counting its own mesh's) starts the count again
    fewest = {"tangled": None, "sweep": 0, "stage": 0}

    def track(p):
        stage = p.get("stage", 0)
        if (fewest["tangled"] is None or p["tangled"] < fewest["tangled"]
                or stage != fewest["stage"]):
            fewest.update(tangled=p["tangled"], sweep=p["sweep"], stage=stage)
        return None if progress is None else progress(p)

    _progress.phase("optimizing")
    r = handle.optimize(measure=measure, progress=track, before=stats, fixed=fixed, **opts)
    r["topology"] = opts["topology"]
    if r["reason"] == "cancelled":
        raise results.Cancelled(messages.cancelled(r["sweeps"]))
    t2 = time.perf_counter()
    seconds = float(r.get("seconds", t2 - t1))
    new_nodes = handle.positions()
    if data.glued is not None:  # a glued node goes where the node it is glued to went
        new_nodes = new_nodes[data.glued]
    # Edge flips (topology="flip") gave some elements new node lists: the result is built,
    # and measured in Python, with them.
    rewired_core = [int(e) for e in r.get("rewired_elements", [])]
    rewired_nodes = []
    if rewired_core:
        lists = handle.element_nodes(rewired_core)
        data = conversion.with_rewired(data, preparing.input_element_indices(data, rewired_core),
                                       lists)
        rewired_nodes = [[int(data.node_ids[n]) for n in nodes] for nodes in lists]
    _progress.phase("measuring the result")
    after = results.quality_report(data, handle, measure, bridge)
    flat = None
    if data.flat_kept is not None:
        flat = preparing.still_flat(data, handle, new_nodes)
        after = results.left_out(after, flat)
        for key in ("tangled_unmovable", "tangled_movable"):  # (core indices)
            core = [int(e) for e in r.get(key, [])]
            r[key] = [e for e, i in zip(core, preparing.input_element_indices(data, core))
                      if not flat[i]]
    new_mesh = conversion.rebuild(data, new_nodes) if data.kind in ("mesh", "fem") else None
    # The distances of the moved nodes, on the positions returned (a Mesh.Mesh's float32 ones).
    returned = new_nodes if data.kind != "mesh" else conversion.read_mesh(new_mesh).nodes
    after.stats.update(_moved_node_distances(data, handle, returned))
    t3 = time.perf_counter()
    t4 = time.perf_counter()
    timings.update(before=t1 - t0, optimize=t2 - t1, after=t3 - t2, rebuild=t4 - t3,
                   total=t4 - t_start)
    unmovable = preparing.user_element_ids(data, r.get("tangled_unmovable", []))
    movable = preparing.user_element_ids(data, r.get("tangled_movable", []))
    warnings = _run_warnings(data, handle, new_nodes, r, boundary, fixed is not None,
                             int(r["sweeps"]) - fewest["sweep"], before, after)
    if flat is not None and flat.any():
        warnings.append(messages.flat_left_out([int(i) for i in data.element_ids[flat]]))
    return results.OptimizeResult(
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
        restored_nodes=int(r.get("restored_nodes", 0)),
        flips=int(r.get("flips", 0)),
        rewired_elements=preparing.user_element_ids(data, rewired_core),
        rewired_nodes=rewired_nodes,
        needles=preparing.user_element_ids(data, r.get("needles", [])),
        options=dict(opts, measure=measure, boundary=boundary,
                     **({} if faces is None else {"faces": _face_names(faces)}),
                     **({} if fixed_nodes is None else {"fixed_nodes": len(fixed_nodes)})),
        bridge=bridge,
        tangled_unmovable=unmovable,
        tangled_movable=movable,
        warnings=warnings,
        timings=timings,
    )


def _refuse_miswound(data, handle):
    """ValueError naming the elements wound against their face's mesh, when there are any."""
    miswound = [int(e) for e in np.asarray(handle.report.get("miswound_elements", []))]
    if miswound:
        raise ValueError(messages.miswound_refusal(
            preparing.user_element_ids(data, miswound), _where(data, handle, data.nodes,
                                                               miswound)))


def _run_warnings(data, handle, nodes, r, boundary, held, quiet, before, after):
    """The result's warnings: the elements left tangled (``r``: the core's result; ``held``:
    the run held nodes, by faces= or fixed_nodes= or those of flat elements left out; ``quiet``:
    sweeps since their number last dropped) and
    those standing across their surface, each with where the first is (at ``nodes``)."""
    core_unmovable = list(r.get("tangled_unmovable", []))
    core_movable = list(r.get("tangled_movable", []))
    warnings = []
    if core_unmovable:
        warnings.append(messages.tangled_unmovable(
            preparing.user_element_ids(data, core_unmovable),
            _where(data, handle, nodes, core_unmovable), boundary, held,
            r.get("topology", "none")))
    if core_movable:
        warnings.append(messages.tangled_movable(
            preparing.user_element_ids(data, core_movable),
            _where(data, handle, nodes, core_movable), boundary, r["reason"], quiet,
            _STILL_DROPPING))
    core_needles = list(r.get("needles", []))
    if core_needles:
        warnings.append(messages.needles(preparing.user_element_ids(data, core_needles),
                                         _where(data, handle, nodes, core_needles)))
    n_across0, n_across = int(before.stats["across"]), int(after.stats["across"])
    if n_across:
        mask = after.across if data.kept is None else after.across[data.kept]
        core_across = [int(k) for k in np.nonzero(mask)[0]]
        warnings.append(messages.standing_across(
            n_across, n_across0, preparing.user_element_ids(data, core_across),
            _where(data, handle, nodes, core_across)))
    return warnings


def _where(data, handle, nodes, core_indices):
    """Where the first of these elements is, for a warning: its centroid (at `nodes`) and the
    CAD face it lies on, by FreeCAD's name (Face1 is the shape's first face)."""
    if not core_indices:
        return ""
    k = int(core_indices[0])
    e = int(preparing.input_element_indices(data, [k])[0])
    c = nodes[data.conn[data.offsets[e]:data.offsets[e + 1]]].mean(axis=0)
    return messages.where(c, int(handle.element_faces()[k]) + 1)


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
        part = None if preparing.is_core_shape(shape) else shapes.shape_of(shape)
        count = shape.face_count if part is None else len(part.Faces)
        chosen = np.asarray(_face_numbers(faces, part, count), dtype=np.int64) - 1
        elem_faces = np.asarray(handle.element_faces(), dtype=np.int64)
        carried = np.isin(chosen, elem_faces)
        if not carried.all():
            bare = ", ".join(f"Face{int(f) + 1}" for f in chosen[~carried])
            raise ValueError(f"faces: no element of the mesh lies on {bare}")
        # every node of an element (of the input's) on another face
        elsewhere = np.zeros(data.element_count, dtype=bool)
        others = np.nonzero(~np.isin(elem_faces, chosen))[0]
        elsewhere[preparing.input_element_indices(data, others)] = True
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
                             f"{messages.id_list([int(i) for i in ids[missing]], 10)}")
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
