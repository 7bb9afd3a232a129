"""SurfMesh's words to its users: the warnings and refusals of reading a mesh on its shape and
of a run, and the core's diagnostics in the user's ids.

The core names nodes, elements and CAD entities by their 0-based indices in the arrays it was
given, in structured diagnostics (a code, a text template, the ids); :func:`for_user` and
:func:`render` give them in the user's ids and FreeCAD's names, and :func:`user_words` turns a
bridge diagnostic into the short note the document functions print once per mesh
(SurfMesh.app.notes), by its code. No message is read back from its text.

The functions take plain values (counts, ids, positions) and return text: what to measure is
the callers' (SurfMesh.app.preparing, SurfMesh.app.running).

This module never imports FreeCADGui.
"""

from __future__ import annotations

import re

import numpy as np

# ---- lists and places ------------------------------------------------------------------------


def id_list(ids, shown=20):
    """"3, 7, 9" (the first ``shown`` ids, then ", …")."""
    text = ", ".join(str(i) for i in ids[:shown])
    return text + (", …" if len(ids) > shown else "")


def short_id_list(ids, shown=10):
    """"3, 7, 9" (the first ``shown`` ids, then " …"): the lists of the bridge's warnings."""
    return ", ".join(str(int(i)) for i in ids[:shown]) + (" …" if len(ids) > shown else "")


def where(centroid, face):
    """Where the first element of a warning's list is: its centroid and FreeCAD's number of its
    face (1 for Face1)."""
    c = centroid
    return f" (the first near ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}) on Face{face})"


def number_text(value):
    """A default as the command line's help gives it: 1e-3, 1.9, 100."""
    if isinstance(value, float) and value != 0 and abs(value) < 1e-2:
        mantissa, exponent = f"{value:.15e}".split("e")
        mantissa = mantissa.rstrip("0").rstrip(".")
        return f"{mantissa}e{int(exponent)}"
    return f"{value:g}" if isinstance(value, float) else str(value)


# ---- diagnostics: the core's messages, and this module's on reading a mesh ------------------
#
# The core tells what it noticed (and why it refuses an input) as diagnostics: a code, a text
# with placeholders (``format``) and the ids and numbers the text names (the core's
# surfmesh/diagnostic.h says the placeholders). Its ids are the 0-based indices of the arrays it
# was given, and of the shape's faces, edges and vertices; :func:`for_user` gives the
# diagnostic in the user's ids (FEM node and element ids, FreeCAD's Face5) with its text. The
# warnings of this module on reading a mesh are diagnostics in the user's ids from the start
# (:func:`diagnostic`). A report keeps them under "diagnostics", their texts under "warnings".

_LISTS = {"node": "nodes", "element": "elements", "face": "faces", "edge": "edges",
          "vertex": "vertices"}
_SHAPE_NAMES = {"face": "Face", "edge": "Edge", "vertex": "Vertex"}
_PLACEHOLDER = re.compile(r"\{([a-z_]+?)(\d*)\}")


def _number(v):
    """A number as the core writes it: an integer without decimals, others to 6 digits."""
    v = float(v)
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return f"{v:.6g}"


def render(diag):
    """The text of a diagnostic in the user's ids (:func:`for_user`, :func:`diagnostic`):
    its ``format`` with the placeholders filled, as the core fills them (surfmesh/diagnostic.h),
    the shape's faces, edges and vertices by FreeCAD's numbers ("Face5")."""
    values = diag.get("values", {})

    def fill(m):
        key, index = m.group(1), m.group(2)
        if key == "count" and not index:
            return str(int(diag.get("count", 0)))
        if key in values and not index:
            return _number(values[key])
        kind, plural = key, False
        if key == "vertices" or (key.endswith("s") and key[:-1] in _LISTS):
            kind, plural = ("vertex" if key == "vertices" else key[:-1]), True
        if kind not in _LISTS:
            return m.group(0)
        ids = [_SHAPE_NAMES.get(kind, "") + str(int(i)) for i in diag.get(_LISTS[kind], [])]
        k = int(index or 0)
        if k >= len(ids):
            return m.group(0)
        return " ".join(ids[k:]) if plural else ids[k]
    return _PLACEHOLDER.sub(fill, diag["format"])


#: The codes of this module's diagnostics on reading a mesh (warnings), with what each says;
#: the core's are its ``diagnostic_codes()``.
CODES = {
    "left_out": "elements left out of the run (collapsed, folded pairs, flat on a CAD edge, …)",
    "node_order": "high-order elements with a side node farther from its side than the side is "
                  "long (another node order?)",
    "glued": "nodes at the position of another node (a crack) measured and moved as one",
}


def diagnostic_codes():
    """Every diagnostic code a report or a refusal can give: [{code, refusal, meaning}], the
    core's then this module's."""
    from SurfMesh.app.native import core
    return list(core().diagnostic_codes()) + [
        {"code": c, "refusal": False, "meaning": m} for c, m in CODES.items()]


def _new(code, format, count, values, **ids):
    """A diagnostic dict, as the core's bindings give one (``ids``: lists by the keys of
    :data:`_LISTS`' values), without its text."""
    d = {"code": code, "format": format, "count": int(count), "values": dict(values or {})}
    for key in _LISTS.values():
        d[key] = [int(i) for i in ids.get(key, ())]
    return d


def diagnostic(code, format, count=0, nodes=(), elements=(), values=None):
    """A diagnostic of this module (``code``: one of :data:`CODES`; ids: the user's), with its
    ``text``."""
    if code not in CODES:
        raise KeyError(f"unknown diagnostic code {code!r}")
    d = _new(code, format, count, values, nodes=nodes, elements=elements)
    d["text"] = render(d)
    return d


def for_user(diag, data):
    """A core diagnostic (a dict, as the core's report or its InputError gives it) in the user's
    ids: its nodes and elements by ``data.node_ids`` and ``data.element_ids`` (when ``data`` has
    them; an index out of their range stays as it is), its faces, edges and vertices by
    FreeCAD's numbers (the core's index + 1), and its ``text`` in those."""
    def ids(key, table):
        out = [int(i) for i in diag.get(key, [])]
        if table is None:
            return out
        return [int(table[i]) if 0 <= i < len(table) else i for i in out]
    d = dict(diag)
    d["nodes"] = ids("nodes", getattr(data, "node_ids", None))
    d["elements"] = ids("elements", getattr(data, "element_ids", None))
    for key in ("faces", "edges", "vertices"):
        d[key] = [int(i) + 1 for i in diag.get(key, [])]
    d["values"] = dict(diag.get("values", {}))
    d["text"] = render(d)
    return d


def refusal(err, data):
    """The core's refusal of an input (a ValueError; the core's InputError carries its
    diagnostic) as a ValueError in the user's ids, with the diagnostic in them under
    ``diagnostic``."""
    diag = getattr(err, "diagnostic", None)
    if diag is None:
        return ValueError(str(err))
    d = for_user(diag, data)
    out = ValueError(d["text"])
    out.diagnostic = d
    return out


def set_diagnostics(report, diagnostics):
    """A bridge report's diagnostics (in the user's ids), and their texts as its "warnings"."""
    report["diagnostics"] = list(diagnostics)
    report["warnings"] = [d["text"] for d in report["diagnostics"]]


def add_warning(report, diag):
    """Adds a diagnostic (in the user's ids) to a bridge report: its text to "warnings"."""
    set_diagnostics(report, list(report.get("diagnostics", [])) + [diag])


def loose_nodes(report, fmt):
    """The core's diagnostic on the nodes of no element (in its indices), from the report's
    arrays (after glued nodes were taken out of them); ``fmt``: the core's format of it, whose
    entity placeholder is set to the entity the farthest node now lies on."""
    loose = np.asarray(report["loose_nodes"], dtype=np.int64)
    cls = np.asarray(report["loose_class"], dtype=np.int64)
    dist = np.asarray(report["loose_distance"], dtype=np.float64)
    ent = np.asarray(report["loose_entity"], dtype=np.int64)
    k = int(np.argmax(dist))
    kind = ("vertex", "edge", "face")[min(int(cls[k]), 2)]
    return _new("unused_nodes", re.sub(r"\{(vertex|edge|face)\}", "{" + kind + "}", fmt),
                loose.size,
                {"on_vertices": int(np.sum(cls == 0)), "on_edges": int(np.sum(cls == 1)),
                 "on_faces": int(np.sum(cls == 2)), "distance": float(dist[k])},
                nodes=[loose[k]] + list(loose[:5]), **{_LISTS[kind]: [ent[k]]})


# ---- reading a mesh on its shape -------------------------------------------------------------


def glued_nodes(count, kept_id, glued_id, xyz):
    """The bridge's warning on ``count`` nodes glued to another (a crack), naming one pair."""
    x, y, z = xyz
    return diagnostic(
        "glued",
        "glued {count} node(s) to another node at the same position (the mesh has a crack "
        f"there, e.g. nodes {{node}} and {{node1}} at ({x:.9g}, {y:.9g}, {z:.9g})): they are "
        "measured as one node and move together",
        count=count, nodes=(kept_id, glued_id))


def collapsed_refusal(count, first_id, first_nodes, all_bad):
    """Why reading refuses collapsed elements (``collapsed="error"``, or all of them)."""
    return (
        f"{count} element(s) repeat a node (collapsed, zero area), first: "
        f"element id {first_id} with nodes {first_nodes}"
        + ("" if all_bad else "; pass collapsed='skip' to leave them out")
    )


def left_out_reasons(collapsed=0, folded=0, crowded=0, misjoined=0, flat=0, miswound=0):
    """Why elements were left out, one phrase a kind (the kinds with none left out)."""
    out = []
    if collapsed:
        out.append(f"{collapsed} collapsed element(s) (a repeated node)")
    if folded:
        out.append(f"{folded} element(s) with the same nodes as another one (folded pairs)")
    if crowded:
        out.append(f"{crowded} element(s) overlapping around those (more than two on one edge)")
    if misjoined:
        out.append(f"{misjoined} high-order element(s) joined to those through side nodes no "
                   "conforming mesh shares (a side node that is also a corner, or on two edges)")
    if flat:
        out.append(f"{flat} flat element(s) on one CAD edge or with two nodes on one CAD vertex")
    if miswound:
        out.append(f"{miswound} element(s) wound against their face's mesh next to those")
    return out


def left_out(reasons, ids):
    """The bridge's warning on the elements left out (``reasons``: :func:`left_out_reasons`)."""
    return diagnostic("left_out", f"left out {' and '.join(reasons)}: ids {short_id_list(ids)}",
                      count=len(ids), elements=ids)


def side_nodes_astray(ids):
    """The bridge's warning on high-order elements with a side node far from its side."""
    return diagnostic(
        "node_order",
        f"{{count}} high-order element(s) have a side node farther from its side than the side "
        f"is long (ids {short_id_list(ids)}): is the node order corners first, then the side "
        "nodes of sides 1-2, 2-3, 3-1?", count=len(ids), elements=ids)


def volume_mesh_refusal(count, types=None):
    """Why optimize refuses a mesh with ``count`` volume elements (of ``types``, when known)."""
    kinds = f" ({types})" if types else ""
    return (f"the mesh has {count} volume element(s){kinds} besides its surface elements: "
            "moving the surface nodes would distort them (their interior nodes do not follow), "
            "and those along the surface could be inverted. Optimize the surface (2D) mesh, "
            "then mesh the volume from it; measure works as it is")


# ---- a run -----------------------------------------------------------------------------------


def miswound_refusal(ids, place):
    """Why optimize refuses elements wound against their face's mesh (``place``: :func:`where`
    of the first)."""
    return (
        f"{len(ids)} element(s) are wound against the rest of their face's mesh "
        f"(their nodes are listed in the opposite order): element(s) "
        f"{id_list(ids)}"
        f"{place}. They are tangled whatever their node "
        "positions, and moving nodes would only fold the mesh over them: reverse their "
        "node order first (FreeCAD: Mesh > Analyze > Evaluate and repair > Orientation, or "
        "Mesh.harmonizeNormals())"
    )


def cancelled(sweeps):
    """The message of a run cancelled through its progress callback."""
    return f"optimization cancelled after {sweeps} sweep(s); nothing changed"


def tangled_unmovable(ids, place, boundary, held, topology="none"):
    """The result's warning on the elements left tangled where no node may move (``held``:
    nodes were held by faces= or fixed_nodes=; ``topology``: the run's)."""
    tries = ([] if boundary != "fixed" else ["boundary='slide'"]) + (
        ["topology='flip'"] if topology != "flip" else [])
    hint = f"try {' or '.join(tries)}, or change" if tries else "change"
    kept = ", held by faces= or fixed_nodes=" if held else ""
    return (
        f"{len(ids)} element(s) stay tangled with no node that may move where they "
        f"fold (their nodes there are all on CAD vertices, fixed CAD edges or poles{kept}; "
        f"{hint} the mesh there): elements "
        f"{id_list(ids)}{place}"
    )


def flat_left_out(ids):
    """The result's warning on the flat elements a run with edge flips kept and left flat."""
    return (f"{len(ids)} flat element(s) on one CAD edge or with two nodes on one CAD vertex are "
            f"left out of the result's figures, as measuring it leaves them out: elements "
            f"{id_list(ids)}")


def needles(ids, place):
    """The result's warning on the needles left by a run with edge flips."""
    return (
        f"{len(ids)} element(s) of quality below 0.2 have every corner on one CAD edge "
        f"(needles along it): neither edge flips nor node motion opens them, the mesh needs "
        f"nodes inserted or removed there: elements {id_list(ids)}{place}"
    )


def tangled_movable(ids, place, boundary, reason, quiet, still_dropping):
    """The result's warning on the elements left tangled although some of their nodes may move
    (``quiet``: sweeps since their number last dropped; ``still_dropping``: the most that
    still advise more sweeps at max_sweeps)."""
    if reason == "max_sweeps" and quiet < still_dropping:
        hint = ("the run reached max_sweeps while their number was still dropping: try more "
                "sweeps")
    else:
        hint = ("the run found no motion of their movable nodes that repairs them"
                if reason != "max_sweeps" else
                f"the run reached max_sweeps, but their number has not dropped over its last "
                f"{quiet} sweeps, so more sweeps are unlikely to help")
        sep = "; " if reason == "max_sweeps" else ": "
        if boundary == "fixed":
            hint += sep + "try boundary='slide'"
        else:
            hint += (sep + "change the mesh there, e.g. elements smaller than the CAD "
                     "feature they span")
    return (
        f"{len(ids)} element(s) stay tangled although some of their nodes may move "
        f"({hint}): elements {id_list(ids)}"
        f"{place}"
    )


def standing_across(count, count_before, ids, place):
    """The result's warning on the elements standing across their surface after the run."""
    return (
        f"{count} element(s) stand across the surface after the run ({count_before} "
        "before): each is wound along its face's normal at some corners and against it at "
        "others, like a triangle spanning more than half the way round a thin tube, whose "
        "plane cuts through the part. The measure (the paper's: the element in its own "
        "plane, oriented by the sum of its corner normals) can count them valid and well "
        "shaped; elements smaller than the surface's radius of curvature there avoid them: "
        f"elements {id_list(ids)}"
        f"{place}"
    )


# ---- notes: the bridge's warnings in a user's words ------------------------------------------

#: The note a user is told once per mesh, by diagnostic code (SurfMesh.app.notes): the
#: diagnostics of the core and of this module that are part of reading most FEM meshes.
NOTE_WORDS = {
    "unused_nodes": lambda d: f"{d['count']} nodes are used by no face element (e.g. nodes of "
                              "edge elements): they stay where they are",
    "left_out": lambda d: f"{d['count']} elements are left out (collapsed or degenerate, e.g. "
                          "where the mesher merged nodes): they keep their place and are drawn "
                          "grey",
    "node_order": lambda d: f"{d['count']} curved elements have a side node far from their side "
                            "(sharp features, or a node order other than corners first): they "
                            "are measured as they are",
    "glued": lambda d: f"{d['count']} nodes sit on another node (a crack along a CAD edge): "
                       "they are measured as one and move together",
}


def user_words(diag):
    """(kind, the note in a user's words) of one bridge diagnostic: its code, and the note of
    :data:`NOTE_WORDS` (a diagnostic of another code is given as its text)."""
    words = NOTE_WORDS.get(diag["code"])
    return diag["code"], (words(diag) if words else diag["text"])
