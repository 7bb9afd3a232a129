"""What SurfMesh noticed reading a mesh on its shape (nodes of no element, elements left out,
curved elements with far side nodes, glued nodes…), told once per mesh in a user's words.

The bridge's diagnostics (``QualityReport.bridge["diagnostics"]``: a code, the text, the ids)
say what happened in the words of the algorithm and with counts; every command on a mesh gives
them again, and an optimized mesh (a new object) gives them once more with other counts. Here
each kind of note is printed once per mesh "lineage" (a mesh and the meshes optimized from it)
and document session, in plain words; the full texts, with the latest counts, are its details
(:func:`details`, shown by the Quality report). A note's kind is its diagnostic's code; the
notes' words are SurfMesh.app.messages's (:data:`~SurfMesh.app.messages.NOTE_WORDS`), beside
the warnings' texts.

Headless: never imports FreeCADGui.
"""

from __future__ import annotations

from SurfMesh.app.messages import user_words  # noqa: F401  (the notes' words, by kind)

#: (document name, lineage root object name) -> {kind: the latest full text}
_seen = {}


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


def new_notes(obj, diagnostics):
    """The notes of ``diagnostics`` (a bridge report's) not yet told for ``obj``'s lineage, in
    a user's words (and they count as told from now on); the details keep every diagnostic's
    latest text."""
    book = _seen.setdefault(_key(obj), {})
    out = []
    for d in diagnostics:
        kind, words = user_words(d)
        if kind not in book:
            out.append(words)
        book[kind] = d["text"]
    return out


def details(obj):
    """The full texts of the notes told for ``obj``'s lineage (the latest counts)."""
    return list(_seen.get(_key(obj), {}).values())


def forget(doc_name=None):
    """Forgets what was told (for a document, or all): the next command tells it again."""
    for k in [k for k in _seen if doc_name is None or k[0] == doc_name]:
        del _seen[k]
