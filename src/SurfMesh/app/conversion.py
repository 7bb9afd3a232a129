"""Conversion of FreeCAD meshes to the arrays the core reads, and back.

The interchange format is fixed once (see also ``src/bindings/arrays.h``):

* ``nodes``    float64, shape (N, 3), C order: node positions in global coordinates;
* ``types``    int64, shape (E,): core element type codes (:data:`ELEMENT_TYPES`);
* ``offsets``  int64, shape (E + 1,): element ``e`` is ``conn[offsets[e]:offsets[e + 1]]``;
* ``conn``     int64: 0-based node indices, Gmsh node ordering (corners counter-clockwise first,
  then the edge nodes);
* ``hint_face`` / ``hint_edge`` / ``hint_vertex``  int64, shape (N,): optional 0-based index of
  the CAD face / edge / vertex (in ``shape.Faces`` / ``Edges`` / ``Vertexes`` order) a node
  was generated on, −1 when unknown.

Two kinds of FreeCAD meshes are read:

``Mesh.Mesh`` (Mesh workbench)
    triangles only; points are stored in single precision (float32) by FreeCAD, so a result
    written back into a ``Mesh.Mesh`` lies on the CAD surface only to float32 rounding
    (~1e-7 × model size).  Node "ids" are the 0-based point indices, element ids the 0-based
    facet indices.

``Fem.FemMesh`` (FEM workbench)
    doubles; node and element ids are arbitrary positive integers (Gmsh meshes hold edge
    elements first, so face ids do not start at 1).  Face elements tria3, tria6, quad4 and
    quad8 are read; edge and volume elements are carried over untouched when the mesh is rebuilt.

This module is headless: it never imports FreeCADGui.
"""

from __future__ import annotations

import dataclasses
import itertools
import operator
from typing import Optional

import numpy as np

# Core element type codes (surfmesh::ElementType) and node counts.
ELEMENT_TYPES = {"tri3": 0, "quad4": 1, "tri6": 2, "tri10": 3, "tri15": 4, "tri21": 5,
                 "quad8": 6}
ELEMENT_NAMES = {code: name for name, code in ELEMENT_TYPES.items()}
NODES_PER_TYPE = {"tri3": 3, "quad4": 4, "tri6": 6, "tri10": 10, "tri15": 15, "tri21": 21,
                  "quad8": 8}
#: The quadrilateral type codes (4 corners; quad8 has a side node after them on each side).
QUAD_CODES = (ELEMENT_TYPES["quad4"], ELEMENT_TYPES["quad8"])
#: The curved types' order p by type code: p - 1 side nodes per side, after the corners.
CURVED_ORDERS = {ELEMENT_TYPES[n]: p for n, p in (("tri6", 2), ("tri10", 3), ("tri15", 4),
                                                  ("tri21", 5), ("quad8", 2))}

# FEM face elements by node count (SMESH ordering equals Gmsh ordering for these).
_FEM_FACE_TYPES = {3: "tri3", 6: "tri6", 4: "quad4", 8: "quad8"}
_FEM_UNSUPPORTED = {9: "quad9", 7: "tria7"}


@dataclasses.dataclass
class MeshData:
    """A surface mesh as flat arrays, plus what is needed to rebuild the FreeCAD mesh."""

    kind: str  # "mesh" (Mesh.Mesh), "fem" (Fem.FemMesh) or "arrays" (files, tests)
    nodes: np.ndarray  # (N, 3) float64
    types: np.ndarray  # (E,) int64 core codes
    offsets: np.ndarray  # (E + 1,) int64
    conn: np.ndarray  # (offsets[-1],) int64, 0-based
    node_ids: np.ndarray  # (N,) int64: FEM node ids, or 0..N-1
    element_ids: np.ndarray  # (E,) int64: FEM element ids, or 0..E-1
    hint_face: Optional[np.ndarray] = None
    hint_edge: Optional[np.ndarray] = None
    hint_vertex: Optional[np.ndarray] = None
    source: object = None  # the Mesh.Mesh / Fem.FemMesh the arrays were read from
    kept: Optional[np.ndarray] = None  # set by api.prepare when elements were left out
    # Set by api.prepare when flat elements were left out (bool per element): optimize holds
    # their nodes, so that no run folds them.
    flat: Optional[np.ndarray] = None
    # Set by api.prepare for a run with edge flips, which keeps the flat elements that it
    # would otherwise leave out (bool per element): its report leaves out those still flat.
    flat_kept: Optional[np.ndarray] = None
    # Set by api.prepare when coincident nodes were glued: glued[i] is the node that node i
    # moves with (i itself for most nodes); ``conn`` then names only those nodes.
    glued: Optional[np.ndarray] = None
    # Volume elements of the source (FEM mesh, Gmsh or meshio file), which are carried over
    # untouched: their count and type names. SurfMesh refuses to move the surface nodes of
    # such a mesh (the interior nodes would not follow: boundary elements would be inverted).
    volume_elements: int = 0
    volume_types: str = ""
    # Set by with_rewired: the 0-based indices of the elements whose node lists edge flips
    # changed (``conn`` holds the new lists); rebuild writes them.
    rewired: Optional[np.ndarray] = None

    @property
    def node_count(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def element_count(self) -> int:
        return int(self.types.shape[0])

    def type_names(self):
        """Sorted list of the element type names present."""
        return sorted({ELEMENT_NAMES.get(int(t), str(int(t))) for t in np.unique(self.types)})

    def corner_counts(self):
        """(E,) int64: each element's corner count, 4 for quadrilaterals, 3 for triangles."""
        return np.where(np.isin(self.types, QUAD_CODES), 4, 3).astype(np.int64)

    def element(self, e):
        """0-based node indices of element ``e``."""
        return self.conn[self.offsets[e] : self.offsets[e + 1]]

    def collapsed_elements(self):
        """Bool mask of the elements that repeat a node (collapsed: zero area). Gmsh meshes
        made through FreeCAD have them where nodes were merged, e.g. at the apex of a cone."""
        sizes = np.diff(self.offsets)
        out = np.zeros(self.element_count, dtype=bool)
        for k in np.unique(sizes):
            sel = np.nonzero(sizes == k)[0]
            idx = self.offsets[sel][:, None] + np.arange(k)[None, :]
            block = np.sort(self.conn[idx], axis=1)
            out[sel] = np.any(block[:, 1:] == block[:, :-1], axis=1)
        return out

    def coincident_nodes(self):
        """(N,) int64: for every node used by an element, the lowest-numbered node used by an
        element at exactly the same position; every other node maps to itself. None when no
        two used nodes coincide. Such pairs are a crack in the mesh: FreeCAD's standard mesher
        leaves them along CAD edges where it meshed the two faces apart."""
        used = np.unique(self.conn)
        if used.size < 2 or used[0] < 0 or used[-1] >= self.node_count:
            return None  # out-of-range ids: the core's check names them
        _, group, counts = np.unique(
            self.nodes[used], axis=0, return_inverse=True, return_counts=True
        )
        group = np.asarray(group).reshape(-1)
        if not np.any(counts > 1):
            return None
        first = np.full(counts.size, np.iinfo(np.int64).max, dtype=np.int64)
        np.minimum.at(first, group, used)
        rep = np.arange(self.node_count, dtype=np.int64)
        rep[used] = first[group]
        return rep

    def duplicate_elements(self):
        """Bool mask of the elements whose corner nodes are those of another element (a pair
        folded onto itself: one of the two is always inverted)."""
        out = np.zeros(self.element_count, dtype=bool)
        corners = self.corner_counts()
        for k in (3, 4):
            sel = np.nonzero(corners == k)[0]
            if sel.size < 2:
                continue
            idx = self.offsets[sel][:, None] + np.arange(k)[None, :]
            keys = np.sort(self.conn[idx], axis=1)
            order = np.lexsort(keys.T[::-1])
            keys = keys[order]
            same = np.all(keys[1:] == keys[:-1], axis=1)  # row i+1 repeats row i
            hit = np.zeros(sel.size, dtype=bool)
            hit[1:] |= same
            hit[:-1] |= same
            out[sel[order[hit]]] = True
        return out

    def crowded_edge_elements(self, left_out):
        """Bool mask of the elements not ``left_out`` (a bool mask) around a corner edge that
        more than two of them share, when every one of those touches a node of a left-out
        element: a mesher's degenerate spot (Gmsh's recombination where it merged nodes at a
        point, e.g. where a fillet ends) left overlapping elements around its collapsed ones.
        A non-manifold edge elsewhere is not touched (the core refuses it)."""
        left_out = np.asarray(left_out, dtype=bool)
        out = np.zeros(self.element_count, dtype=bool)
        if not left_out.any():
            return out
        near = self.nodes_of(left_out)
        corners = self.corner_counts()
        a_all, b_all, e_all = [], [], []
        for k in (3, 4):
            sel = np.nonzero((corners == k) & ~left_out)[0]
            if sel.size == 0:
                continue
            idx = self.offsets[sel][:, None] + np.arange(k)[None, :]
            c = self.conn[idx]
            nxt = np.roll(c, -1, axis=1)
            a_all.append(np.minimum(c, nxt).ravel())
            b_all.append(np.maximum(c, nxt).ravel())
            e_all.append(np.repeat(sel, k))
        if not a_all:
            return out
        a, b, e = np.concatenate(a_all), np.concatenate(b_all), np.concatenate(e_all)
        # Whether each use's element touches such a node (its corners; a quad's fourth too).
        touches = near[self.conn[self.offsets[e][:, None] + np.arange(3)[None, :]]].any(axis=1)
        q = np.nonzero(corners[e] == 4)[0]
        touches[q] |= near[self.conn[self.offsets[e[q]] + 3]]
        order = np.lexsort((b, a))
        a, b, e, touches = a[order], b[order], e[order], touches[order]
        start = np.r_[0, np.nonzero((a[1:] != a[:-1]) | (b[1:] != b[:-1]))[0] + 1]
        count = np.diff(np.r_[start, a.size])
        for s0, n in zip(start[count > 2], count[count > 2]):
            if touches[s0:s0 + n].all():
                out[e[s0:s0 + n]] = True
        return out

    def misjoined_elements(self, left_out):
        """Bool mask of the high-order triangles not ``left_out`` (a bool mask) that share a
        side or interior node with another element in a way no conforming mesh does (the node
        also a corner, on two different corner edges, on one edge of more than two elements,
        or inside two elements), when they touch a node of a left-out element: a mesher's
        degenerate spot (Gmsh's second-order mesh of the bottle's thread, where the thread
        ends) joins overlapping curved elements through their side nodes around its collapsed
        ones. Elsewhere such elements are not touched."""
        left_out = np.asarray(left_out, dtype=bool)
        out = np.zeros(self.element_count, dtype=bool)
        high = np.isin(self.types, list(CURVED_ORDERS)) & ~left_out
        if not left_out.any() or not high.any():
            return out
        # One row per use of a node by an element not left out: (node, a, b, element), with
        # (a, b) the sorted corner pair of its edge; a = b = −1 for a corner, −2 − e for an
        # interior node of element e (unique to it).
        rows = []
        sizes = np.diff(self.offsets)
        for k in np.unique(sizes):
            sel = np.nonzero((sizes == k) & ~left_out)[0]
            if sel.size == 0:
                continue
            idx = self.offsets[sel][:, None] + np.arange(k)[None, :]
            c = self.conn[idx]
            code = int(self.types[sel[0]])
            p = CURVED_ORDERS.get(code)
            nc = 4 if code in QUAD_CODES else 3
            ones = np.ones(sel.size, dtype=np.int64)
            for j in range(nc if p else k):  # the corners (every node of tri3 and quad4)
                rows.append(np.stack([c[:, j], -ones, -ones, sel], axis=1))
            if p is None:
                continue
            for edge in range(nc):
                a = np.minimum(c[:, edge], c[:, (edge + 1) % nc])
                b = np.maximum(c[:, edge], c[:, (edge + 1) % nc])
                for j in range(nc + edge * (p - 1), nc + (edge + 1) * (p - 1)):
                    rows.append(np.stack([c[:, j], a, b, sel], axis=1))
            for j in range(nc * p, k):
                inner = -2 - sel.astype(np.int64)
                rows.append(np.stack([c[:, j], inner, inner, sel], axis=1))
        r = np.concatenate(rows).astype(np.int64)
        r = r[np.lexsort((r[:, 2], r[:, 1], r[:, 0]))]
        node, key = r[:, 0], r[:, 1:3]
        start = np.r_[0, np.nonzero(node[1:] != node[:-1])[0] + 1]
        uses = np.diff(np.r_[start, node.size])
        # Per node: distinct (a, b) keys among its uses, and whether it is a side node.
        new_key = np.r_[True, (node[1:] != node[:-1]) | np.any(key[1:] != key[:-1], axis=1)]
        keys = np.add.reduceat(new_key.astype(np.int64), start)
        corner_use = np.add.reduceat((key[:, 0] == -1).astype(np.int64), start)
        bad = (keys > 1) | ((corner_use == 0) & (uses > 2))
        bad_nodes = np.zeros(self.node_count, dtype=bool)
        bad_nodes[node[start[bad]]] = True
        near = self.nodes_of(left_out)
        starts = self.offsets[:-1]
        touches_bad = np.logical_or.reduceat(bad_nodes[self.conn], starts)
        touches_near = np.logical_or.reduceat(near[self.conn], starts)
        return high & touches_bad & touches_near

    def nodes_of(self, elements):
        """Bool mask of the nodes used by the elements where ``elements`` (a bool mask) is
        True."""
        out = np.zeros(self.node_count, dtype=bool)
        out[self.subset(elements).conn] = True
        return out

    def subset(self, keep):
        """A MeshData with only the elements where ``keep`` is True (same nodes)."""
        keep = np.asarray(keep, dtype=bool)
        sizes = np.diff(self.offsets)[keep]
        offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        # conn positions of the kept elements: each element's start, then its consecutive nodes
        starts = np.asarray(self.offsets[:-1], dtype=np.int64)[keep]
        idx = np.repeat(starts - offsets[:-1], sizes) + np.arange(offsets[-1], dtype=np.int64)
        return dataclasses.replace(
            self, types=self.types[keep], offsets=offsets, conn=self.conn[idx],
            element_ids=self.element_ids[keep],
        )


def positions_of(table, ids):
    """(positions, missing): for each of ``ids``, its position in the id array ``table``
    (unique ids, any order), and a bool mask of the ids ``table`` does not hold (their
    positions are meaningless)."""
    table = np.asarray(table)
    ids = np.asarray(ids)
    order = np.argsort(table, kind="stable")
    pos = order[np.clip(np.searchsorted(table, ids, sorter=order), 0, max(len(table) - 1, 0))]
    return pos, table[pos] != ids


def from_arrays(nodes, elements, element_type="tri3", node_ids=None, element_ids=None):
    """MeshData from plain arrays: ``elements`` is (E, k) with 0-based node indices."""
    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    if nodes.ndim != 2 or nodes.shape[1] != 3:
        raise ValueError(f"nodes must have shape (N, 3), got {nodes.shape}")
    elements = np.asarray(elements, dtype=np.int64)
    if elements.ndim != 2:
        raise ValueError(f"elements must have shape (E, k), got {elements.shape}")
    if element_type not in ELEMENT_TYPES:
        raise ValueError(
            f"unknown element type {element_type!r}; known: {', '.join(ELEMENT_TYPES)}"
        )
    k = NODES_PER_TYPE[element_type]
    if elements.shape[1] != k:
        raise ValueError(f"{element_type} elements have {k} nodes, got {elements.shape[1]}")
    n_el = elements.shape[0]
    return MeshData(
        kind="arrays",
        nodes=nodes,
        types=np.full(n_el, ELEMENT_TYPES[element_type], dtype=np.int64),
        offsets=np.arange(0, k * n_el + 1, k, dtype=np.int64),
        conn=np.ascontiguousarray(elements.reshape(-1)),
        node_ids=(
            np.arange(nodes.shape[0], dtype=np.int64)
            if node_ids is None
            else np.asarray(node_ids, dtype=np.int64)
        ),
        element_ids=(
            np.arange(n_el, dtype=np.int64)
            if element_ids is None
            else np.asarray(element_ids, dtype=np.int64)
        ),
    )


# ---- recognising inputs ----------------------------------------------------------------------


def _type_id(obj):
    try:
        return obj.TypeId
    except Exception:
        return ""


def is_mesh_kernel(obj) -> bool:
    """Whether ``obj`` is a Mesh.Mesh (its TypeId is not reliable: "BadType")."""
    import Mesh

    return isinstance(obj, Mesh.Mesh)


def is_fem_mesh(obj) -> bool:
    import Fem

    return isinstance(obj, Fem.FemMesh)


def mesh_of(obj):
    """The Mesh.Mesh or Fem.FemMesh held by ``obj`` (itself, or a document object's
    ``Mesh`` / ``FemMesh`` property). Raises ValueError otherwise."""
    if is_mesh_kernel(obj) or is_fem_mesh(obj):
        return obj
    for attr in ("FemMesh", "Mesh"):
        inner = getattr(obj, attr, None) if hasattr(obj, "isDerivedFrom") else None
        if inner is not None and (is_mesh_kernel(inner) or is_fem_mesh(inner)):
            return inner
    label = getattr(obj, "Label", None)
    what = f"object {label!r} ({_type_id(obj) or type(obj).__name__})" if label else repr(obj)
    raise ValueError(
        f"{what} is not a mesh: expected a Mesh.Mesh, a Fem.FemMesh or a document object "
        "holding one"
    )


# ---- reading ---------------------------------------------------------------------------------


def read_mesh(obj) -> MeshData:
    """MeshData of a Mesh.Mesh, Fem.FemMesh or document object holding one."""
    if isinstance(obj, MeshData):
        return obj
    mesh = mesh_of(obj)
    if is_mesh_kernel(mesh):
        return _read_mesh_kernel(mesh)
    return _read_fem_mesh(mesh)


def _vectors_to_array(vectors) -> np.ndarray:
    vectors = list(vectors)
    xyz = itertools.chain.from_iterable(map(operator.attrgetter("x", "y", "z"), vectors))
    return np.fromiter(xyz, dtype=np.float64, count=3 * len(vectors)).reshape(-1, 3)


def _read_mesh_kernel(mesh) -> MeshData:
    points, facets = mesh.Topology  # global coordinates
    nodes = _vectors_to_array(points)
    tris = np.fromiter(
        itertools.chain.from_iterable(facets), dtype=np.int64, count=3 * len(facets)
    ).reshape(-1, 3)
    data = from_arrays(nodes, tris, "tri3")
    data.kind = "mesh"
    data.source = mesh
    return data


def _read_fem_mesh(fem) -> MeshData:
    node_map = fem.Nodes  # id -> Vector (global coordinates)
    node_ids = np.fromiter(node_map.keys(), dtype=np.int64, count=len(node_map))
    nodes = _vectors_to_array(node_map.values())
    face_ids = list(fem.Faces)
    if not face_ids:
        detail = ""
        if fem.VolumeCount:
            detail = f" (it has {fem.VolumeCount} volume elements: mesh the surfaces, 2D)"
        elif fem.EdgeCount:
            detail = f" (it has only {fem.EdgeCount} edge elements)"
        raise ValueError(f"the FEM mesh has no face elements{detail}")
    element_nodes = [fem.getElementNodes(e) for e in face_ids]
    counts = np.fromiter((len(n) for n in element_nodes), dtype=np.int64, count=len(face_ids))
    bad = [i for i, c in enumerate(counts) if int(c) not in _FEM_FACE_TYPES]
    if bad:
        c = int(counts[bad[0]])
        name = _FEM_UNSUPPORTED.get(c, f"{c}-node")
        raise ValueError(
            f"unsupported FEM element type {name}: {len(bad)} element(s), first id "
            f"{face_ids[bad[0]]}; supported face elements: tria3, tria6, quad4, quad8"
        )
    volume_count = int(fem.VolumeCount)
    names = [_FEM_FACE_TYPES[int(c)] for c in counts]
    types = np.array([ELEMENT_TYPES[n] for n in names], dtype=np.int64)
    offsets = np.zeros(len(face_ids) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    flat_ids = np.fromiter(
        (n for nodes_of in element_nodes for n in nodes_of), dtype=np.int64, count=int(offsets[-1])
    )
    conn, missing = positions_of(node_ids, flat_ids)
    if np.any(missing):
        raise ValueError(f"FEM mesh elements reference unknown node id {int(flat_ids[missing][0])}")
    return MeshData(
        kind="fem",
        nodes=nodes,
        types=types,
        offsets=offsets,
        conn=np.ascontiguousarray(conn, dtype=np.int64),
        node_ids=node_ids,
        element_ids=np.array(face_ids, dtype=np.int64),
        source=fem,
        volume_elements=volume_count,
        volume_types=_fem_volume_types(fem) if volume_count else "",
    )


def _fem_volume_types(fem):
    """'tetra4 (5909)'-style summary of a FEM mesh's volume elements."""
    names = {4: "tetra4", 5: "pyra5", 6: "penta6", 8: "hexa8", 10: "tetra10", 13: "pyra13",
             15: "penta15", 20: "hexa20"}
    counts = {}
    for v in fem.Volumes:
        n = len(fem.getElementNodes(v))
        k = names.get(n, f"{n}-node")
        counts[k] = counts.get(k, 0) + 1
    return ", ".join(f"{k} ({n})" for k, n in sorted(counts.items()))


# ---- hints from FreeCAD's node classification -----------------------------------------------


def fem_hints(data: MeshData, shape, faces=True):
    """Fills data.hint_face/edge/vertex from ``FemMesh.getNodesByVertex/Edge/Face`` on ``shape``.

    These queries find, for each sub-shape, the mesh nodes within its tolerance: a node found
    on exactly one face (and on no edge) is hinted to that face, a node on an edge to the edge
    (to the vertex when it is on one).  Face queries are slow in FreeCAD 0.20 (a distance
    computation per node and face: seconds on parts with a few thousand nodes); pass
    ``faces=False`` to let the core classify the face nodes by projection.
    """
    if data.kind != "fem":
        raise ValueError("FEM hints need a Fem.FemMesh input")
    fem = data.source
    n = data.node_count
    index = {int(i): k for k, i in enumerate(data.node_ids)}
    hint_vertex = np.full(n, -1, dtype=np.int64)
    hint_edge = np.full(n, -1, dtype=np.int64)
    hint_face = np.full(n, -1, dtype=np.int64)
    for k, v in enumerate(shape.Vertexes):
        for node in fem.getNodesByVertex(v):
            if node in index:
                hint_vertex[index[node]] = k
    edge_count = np.zeros(n, dtype=np.int64)
    for k, e in enumerate(shape.Edges):
        for node in fem.getNodesByEdge(e):
            if node in index:
                i = index[node]
                edge_count[i] += 1
                hint_edge[i] = k
    # A node found on several edges lies on a vertex (or a tolerance overlap): no edge hint.
    hint_edge[edge_count > 1] = -1
    hint_edge[hint_vertex >= 0] = -1
    if faces:
        face_count = np.zeros(n, dtype=np.int64)
        for k, f in enumerate(shape.Faces):
            for node in fem.getNodesByFace(f):
                if node in index:
                    i = index[node]
                    face_count[i] += 1
                    hint_face[i] = k
        hint_face[(face_count != 1) | (edge_count > 0) | (hint_vertex >= 0)] = -1
    data.hint_face, data.hint_edge, data.hint_vertex = hint_face, hint_edge, hint_vertex
    return data


# ---- writing back ----------------------------------------------------------------------------


def _vector_list(nodes: np.ndarray):
    import FreeCAD

    vec = FreeCAD.Vector
    return [vec(float(x), float(y), float(z)) for x, y, z in nodes]


def with_rewired(data: MeshData, elements, node_lists) -> MeshData:
    """A copy of ``data`` in which the elements of 0-based indices ``elements`` have the node
    lists ``node_lists`` (0-based, as ``conn``; each as long as the element's): what edge
    flips made of them. Their types, ids and order are kept."""
    conn = data.conn.copy()
    elements = np.asarray(elements, dtype=np.int64)
    for e, nodes in zip(elements.tolist(), node_lists):
        a, b = int(data.offsets[e]), int(data.offsets[e + 1])
        if len(nodes) != b - a:
            raise ValueError(f"element {e}: {len(nodes)} nodes for an element of {b - a}")
        conn[a:b] = nodes
    return dataclasses.replace(data, conn=conn, rewired=np.sort(elements))


def rebuild(data: MeshData, new_nodes: np.ndarray):
    """A NEW mesh of the input's kind with the node positions ``new_nodes`` (N, 3); ids,
    element order, segments / groups and non-face elements are kept; ``data.source`` is not
    modified."""
    new_nodes = np.asarray(new_nodes, dtype=np.float64)
    if new_nodes.shape != data.nodes.shape:
        raise ValueError(f"expected {data.nodes.shape} node positions, got {new_nodes.shape}")
    if data.kind == "mesh":
        return _rebuild_mesh_kernel(data, new_nodes)
    if data.kind == "fem":
        return _rebuild_fem(data, new_nodes)
    raise ValueError(f"cannot rebuild a FreeCAD mesh from {data.kind!r} data")


def _rebuild_mesh_kernel(data: MeshData, new_nodes: np.ndarray):
    import FreeCAD

    if data.rewired is not None and len(data.rewired):
        return _rebuild_mesh_rewired(data, new_nodes)
    mesh = data.source.copy()  # keeps facets, segments and placement
    vec = FreeCAD.Vector
    changed = np.nonzero(np.any(new_nodes != data.nodes, axis=1))[0]
    set_point = mesh.setPoint
    for i, (x, y, z) in zip(changed.tolist(), new_nodes[changed].tolist()):
        set_point(i, vec(x, y, z))  # global coordinates
    return mesh


def _rebuild_mesh_rewired(data: MeshData, new_nodes: np.ndarray):
    """A Mesh.Mesh with the facets of ``data.conn`` (edge flips changed some) at ``new_nodes``
    (global coordinates: the new mesh has no placement of its own) and the source's
    segments (facet indices, kept)."""
    import FreeCAD
    import Mesh

    if data.glued is not None:
        raise ValueError("edge flips in a Mesh with coincident points are not written back")
    vec = FreeCAD.Vector
    points = [vec(x, y, z) for x, y, z in new_nodes.tolist()]
    facets = [tuple(t) for t in data.conn.reshape(-1, 3).tolist()]
    mesh = Mesh.Mesh((points, facets))
    if mesh.CountPoints != len(points) or mesh.CountFacets != len(facets):
        raise RuntimeError("the rewired Mesh lost points or facets")
    old = data.source
    for i in range(old.countSegments()):
        mesh.addSegment(old.getSegment(i))
    return mesh


def _rebuild_fem(data: MeshData, new_nodes: np.ndarray):
    import Fem

    old = data.source
    fem = Fem.FemMesh()
    for nid, (x, y, z) in zip(data.node_ids.tolist(), new_nodes.tolist()):
        fem.addNode(x, y, z, nid)
    # Elements in id order, whatever their dimension, so that every id is kept.
    elements = []
    for e in old.Edges:
        elements.append((e, 1))
    for e in old.Faces:
        elements.append((e, 2))
    for e in old.Volumes:
        elements.append((e, 3))
    elements.sort()
    # The face elements edge flips rewired: their new node lists, by FEM ids.
    rewired = {}
    if data.rewired is not None:
        for e in data.rewired.tolist():
            a, b = int(data.offsets[e]), int(data.offsets[e + 1])
            rewired[int(data.element_ids[e])] = [int(data.node_ids[n]) for n in data.conn[a:b]]
    for eid, dim in elements:
        nodes = rewired[eid] if dim == 2 and eid in rewired else list(old.getElementNodes(eid))
        if dim == 1:
            fem.addEdge(nodes, eid)
        elif dim == 2:
            fem.addFace(nodes, eid)
        else:
            fem.addVolume(nodes, eid)
    for gid in old.Groups:
        name = old.getGroupName(gid)
        gtype = old.getGroupElementType(gid)
        new_gid = fem.addGroup(name, gtype)
        members = list(old.getGroupElements(gid))
        if members:
            fem.addGroupElements(new_gid, members)
    return fem
