"""What SurfMesh noticed reading a mesh on its shape (nodes of no element, elements left out,
curved elements with far side nodes, glued nodes…), told once per mesh in a user's words.

The bridge's warnings (``QualityReport.bridge["warnings"]``) say what happened in the words of
the algorithm and with counts; every command on a mesh gives them again, and an optimized mesh
(a new object) gives them once more with other counts. Here each kind of note is printed once
per mesh "lineage" (a mesh and the meshes optimized from it) and document session, in plain
words; the full texts, with the latest counts, are its details (:func:`details`, shown by the
Quality report).

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

import re

# "364 collapsed element(s)", "10 high-order element(s)": the counts of a "left out" warning
_COUNTED = re.compile(r"(\d+) [a-z-]*\s*element")
# (pattern, kind, the note in a user's words from the match)
_RULES = [
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

#: (document name, lineage root object name) -> {kind: the latest full text}
_seen = {}


def user_words(warning):
    """(kind, the note in a user's words) of one bridge warning; an unknown warning is its own
    kind (numbers aside) and is given as it is."""
    for pattern, kind, words in _RULES:
        m = pattern.search(warning)
        if m:
            return kind, words(m)
    return re.sub(r"\d+(?:\.\d+)?(?:e[-+]?\d+)?", "#", warning)[:60], warning


def lineage(obj):
    """The mesh ``obj`` was optimized from, and so on back (SurfMeshOriginal): its root."""
    seen = set()
    while "SurfMeshOriginal" in getattr(obj, "PropertiesList", []) and obj.SurfMeshOriginal \
            is not None and obj.Name not in seen:
        seen.add(obj.Name)
        obj = obj.SurfMeshOriginal
    return obj


def _key(obj):
    root = lineage(obj)
    return (root.Document.Name, root.Name)


def new_notes(obj, warnings):
    """The notes of ``warnings`` not yet told for ``obj``'s lineage, in a user's words (and
    they count as told from now on); the details keep every warning's latest text."""
    book = _seen.setdefault(_key(obj), {})
    out = []
    for w in warnings:
        kind, words = user_words(w)
        if kind not in book:
            out.append(words)
        book[kind] = w
    return out


def details(obj):
    """The full texts of the notes told for ``obj``'s lineage (the latest counts)."""
    return list(_seen.get(_key(obj), {}).values())


def forget(doc_name=None):
    """Forgets what was told (for a document, or all): the next command tells it again."""
    for k in [k for k in _seen if doc_name is None or k[0] == doc_name]:
        del _seen[k]
