"""SurfMesh's words to its users: the warnings and refusals of reading a mesh on its shape and
of a run, and the rewriting of the core's messages.

The core names nodes, elements and CAD entities by their 0-based indices in the arrays it was
given; :func:`name_by_ids` rewrites its messages into the user's ids and FreeCAD's names, and
:func:`user_words` turns a bridge warning into the short note the document functions print
once per mesh (SurfMesh.app.notes). Every pattern that reads a message (the core's, or one of
this module's) is here, next to the text it reads.

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


# ---- the core's messages in the user's ids ---------------------------------------------------

# "node 5", "nodes 2 and 7", "nodes 2, 7 and 9", "nodes 7 19 32" (lists as the core writes
# them), "row 5" (a row of the node array); the same for elements.
_ID_LIST = r"(\d+(?:(?:, | and | )\d+(?!\d|\.\d))*)"
_NODE_REF = re.compile(r"\b(nodes?|row) " + _ID_LIST)
_ELEMENT_REF = re.compile(r"\b(elements?) " + _ID_LIST)
_FACE_INDEX = re.compile(r"\b(on|from|of) (face|edge|vertex) (\d+)\b")


def name_by_ids(message, data):
    """The core names nodes and elements by their 0-based position in the arrays it was given;
    users know them by their ids (FEM node and element ids, which need not start at 0 or 1).
    Rewrites "node 5", "nodes 2 and 7", "nodes 2, 7 and 9", "nodes 7 19 32", "row 5" (a row
    of the node array) and "element 3" (every id of a list) by ``data.node_ids`` and
    ``data.element_ids``; "on face 4" and "from edge 2" (the core's indices of the shape's
    faces, edges and vertices) become FreeCAD's names, "on Face5", "from Edge3"."""
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


# The core's warning on the nodes of no element: "<n> nodes belong to no element …".
_UNUSED_NODES = re.compile(r"^\d+ nodes belong(?= to no element)")


def is_unused_nodes_warning(warning):
    """Whether ``warning`` is the core's warning on the nodes of no element."""
    return _UNUSED_NODES.match(warning) is not None


def recount_unused_nodes(warning, count):
    """The core's warning on the nodes of no element with another count (glued nodes taken
    out of it)."""
    return _UNUSED_NODES.sub(f"{count} nodes belong", warning, count=1)


def loose_note(report):
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


# ---- reading a mesh on its shape -------------------------------------------------------------


def glued_nodes(count, kept_id, glued_id, xyz):
    """The bridge's warning on ``count`` nodes glued to another (a crack), naming one pair."""
    x, y, z = xyz
    return (
        f"glued {count} node(s) to another node at the same position (the mesh has a "
        f"crack there, e.g. nodes {kept_id} and {glued_id} at "
        f"({x:.9g}, {y:.9g}, {z:.9g})): they are measured as one node and move together"
    )


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
    return f"left out {' and '.join(reasons)}: ids {short_id_list(ids)}"


def side_nodes_astray(ids):
    """The bridge's warning on high-order elements with a side node far from its side."""
    return (
        f"{len(ids)} high-order element(s) have a side node farther from its side than the side "
        f"is long (ids {short_id_list(ids)}): is the node order corners first, then the side "
        "nodes of sides 1-2, 2-3, 3-1?"
    )


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

# "364 collapsed element(s)", "10 high-order element(s)": the counts of a "left out" warning
_COUNTED = re.compile(r"(\d+) [a-z-]*\s*element")
# (pattern, kind, the note in a user's words from the match): one per warning of this module
# (and the core's on the nodes of no element) that a user is told once per mesh.
NOTE_RULES = [
    (re.compile(r"^(\d+) nodes belong to no element"), "unused",
     lambda m: f"{m.group(1)} nodes are used by no face element (e.g. nodes of edge "
               "elements): they stay where they are"),
    (re.compile(r"^left out (.*?): ids"), "left_out",
     lambda m: f"{sum(int(n) for n in _COUNTED.findall(m.group(1)))} elements are left out "
               "(collapsed or degenerate, e.g. where the mesher merged nodes): they keep their "
               "place and are drawn grey"),
    (re.compile(r"^(\d+) high-order element\(s\) have a side node farther"), "node_order",
     lambda m: f"{m.group(1)} curved elements have a side node far from their side (sharp "
               "features, or a node order other than corners first): they are measured as "
               "they are"),
    (re.compile(r"^glued (\d+) node"), "glued",
     lambda m: f"{m.group(1)} nodes sit on another node (a crack along a CAD edge): they are "
               "measured as one and move together"),
]


def user_words(warning):
    """(kind, the note in a user's words) of one bridge warning; an unknown warning is its own
    kind (numbers aside) and is given as it is."""
    for pattern, kind, words in NOTE_RULES:
        m = pattern.search(warning)
        if m:
            return kind, words(m)
    return re.sub(r"\d+(?:\.\d+)?(?:e[-+]?\d+)?", "#", warning)[:60], warning
