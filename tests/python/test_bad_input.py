"""Bad input through SurfMesh's Python API and CLI: every case gives a ValueError (the CLI: a
non-zero exit and a message on stderr) naming the problem and the offending ids/counts, and
leaves the input objects and the document unchanged (node coordinates, objects, undo stack).
Also: cancellation through the progress callback and an exception raised by it change nothing.

Run by scripts/test.sh (``freecadcmd -t test_bad_input -M tests/python``) against the installed
workbench. Small bad files live in tests/data/bad; shapes are made with Part here.
"""

import math
import os
import subprocess
import sys
import tempfile
import unittest

import FreeCAD as App
import Fem
import Mesh
import numpy as np
import Part

import SurfMesh
from SurfMesh.app import conversion

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.environ.get("SURFMESH_REPO", os.path.normpath(os.path.join(HERE, "..", "..")))
DATA = os.environ.get("SURFMESH_TEST_DATA_DIR", os.path.join(REPO, "tests", "data"))
BAD = os.path.join(DATA, "bad")
SHARED = os.environ.get(
    "SURFMESH_SHARED_DATA_DIR", os.path.normpath(os.path.join(REPO, "..", "shared", "data", "cad"))
)
FEM_NODE_ID0 = 101  # FEM node ids start here (so that ids and 0-based indices differ)
FEM_ELEM_ID0 = 1001


# ---- meshes made here ------------------------------------------------------------------------


def box_grid(n=4, size=10.0):
    """Structured triangulation of the surface of the box [0, size]³: n×n cells per face,
    shared nodes on the box's edges, triangles wound along the outward normals.
    Returns (nodes (N, 3) float64, tris (E, 3) int64)."""
    ids = {}
    nodes, tris = [], []

    def node(g):
        if g not in ids:
            ids[g] = len(nodes)
            nodes.append([c * size / n for c in g])
        return ids[g]

    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            for i in range(n):
                for j in range(n):

                    def at(di, dj):
                        g = [0, 0, 0]
                        g[axis], g[a], g[b] = side * n, i + di, j + dj
                        return node(tuple(g))

                    p, q, r, t = at(0, 0), at(1, 0), at(1, 1), at(0, 1)
                    if side == 1:
                        tris += [(p, q, r), (p, r, t)]
                    else:
                        tris += [(p, r, q), (p, t, r)]
    return np.array(nodes, dtype=np.float64), np.array(tris, dtype=np.int64)


def interior_node(nodes, size=10.0):
    """Index of a node strictly inside a face of the box (not on its edges)."""
    for i, p in enumerate(nodes):
        if sum(1 for c in p if 1e-9 < c < size - 1e-9) == 2:
            return i
    raise AssertionError("no interior node")


def make_mesh(nodes, tris):
    return Mesh.Mesh(([App.Vector(*map(float, p)) for p in nodes], [tuple(map(int, t)) for t in tris]))


def make_fem(nodes, elems):
    """Fem.FemMesh with node ids FEM_NODE_ID0 + index and face ids FEM_ELEM_ID0 + index."""
    fem = Fem.FemMesh()
    for i, p in enumerate(nodes):
        fem.addNode(float(p[0]), float(p[1]), float(p[2]), FEM_NODE_ID0 + i)
    for e, el in enumerate(elems):
        fem.addFace([FEM_NODE_ID0 + int(k) for k in el], FEM_ELEM_ID0 + e)
    return fem


def arrays(nodes, elems, types=None):
    """A MeshData (the API's array input) that may hold anything, even invalid codes."""
    elems = [list(map(int, e)) for e in elems]
    counts = [len(e) for e in elems]
    if types is None:
        types = [{3: 0, 4: 1, 6: 2, 8: 6}[c] for c in counts]
    offsets = np.zeros(len(elems) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(counts)
    nodes = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 3)
    return conversion.MeshData(
        kind="arrays",
        nodes=nodes,
        types=np.array(types, dtype=np.int64),
        offsets=offsets,
        conn=np.array([k for e in elems for k in e], dtype=np.int64),
        node_ids=np.arange(len(nodes), dtype=np.int64),
        element_ids=np.arange(len(elems), dtype=np.int64),
    )


def mesh_points(mesh):
    """Node coordinates of a Mesh.Mesh or Fem.FemMesh, for before/after comparisons (as text:
    a NaN coordinate compares equal to itself)."""
    if isinstance(mesh, Mesh.Mesh):
        return repr(([(p.x, p.y, p.z) for p in mesh.Topology[0]],
                     [tuple(f) for f in mesh.Topology[1]]))
    return repr((
        sorted((i, v.x, v.y, v.z) for i, v in mesh.Nodes.items()),
        sorted((e, tuple(mesh.getElementNodes(e))) for e in mesh.Faces),
    ))


def box_volume_fem(nodes, tris):
    """The box's surface triangles plus a volume mesh on them: one node at the box's centre
    and a tetrahedron from each surface triangle to it (all of positive volume)."""
    fem = make_fem(nodes, tris)
    centre = FEM_NODE_ID0 + len(nodes)
    fem.addNode(5.0, 5.0, 5.0, centre)
    for t in tris:
        fem.addVolume([FEM_NODE_ID0 + int(t[0]), FEM_NODE_ID0 + int(t[2]),
                       FEM_NODE_ID0 + int(t[1]), centre])
    return fem


def box_shape():
    return Part.makeBox(10, 10, 10)


def write_msh(path, nodes, elems, node_ids=None, types=None):
    """Gmsh .msh 2.2 (ASCII) with the given node coordinates (written with repr: nan/inf
    survive) and elements (0-based node indices; `types` Gmsh element type codes, default by
    node count: 3 → 2 (tri3), 4 → 3 (quad4), 6 → 9 (tri6), 8 → 16 (quad8)). Node ids are
    1-based indices unless `node_ids` is given; an element may name any id (out of range too)
    through a negative index −id."""
    node_ids = list(range(1, len(nodes) + 1)) if node_ids is None else list(node_ids)
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(nodes))
        for i, p in zip(node_ids, nodes):
            f.write("%d %r %r %r\n" % (i, float(p[0]), float(p[1]), float(p[2])))
        f.write("$EndNodes\n$Elements\n%d\n" % len(elems))
        for e, el in enumerate(elems):
            code = types[e] if types is not None else {3: 2, 4: 3, 6: 9, 8: 16}[len(el)]
            ids = [(-int(k) if int(k) < 0 else node_ids[int(k)]) for k in el]
            f.write("%d %d 2 1 1 %s\n" % (e + 1, code, " ".join(map(str, ids))))
        f.write("$EndElements\n")


# ---- the API catalogue -----------------------------------------------------------------------


class BadInputApi(unittest.TestCase):
    """Each bad input through SurfMesh.measure and SurfMesh.optimize."""

    def setUp(self):
        self.shape = box_shape()
        self.nodes, self.tris = box_grid()

    def expect_error(self, mesh, *fragments, shape=None, call=("measure", "optimize"), **kw):
        """Both API calls raise ValueError whose message holds every fragment; the mesh
        (Mesh.Mesh / FemMesh input) is unchanged."""
        shape = self.shape if shape is None else shape
        before = mesh_points(mesh) if isinstance(mesh, (Mesh.Mesh, Fem.FemMesh)) else None
        messages = []
        for name in call:
            fn = getattr(SurfMesh, name)
            with self.subTest(call=name):
                with self.assertRaises(ValueError) as cm:
                    fn(mesh, shape, **kw)
                msg = str(cm.exception)
                messages.append(msg)
                for f in fragments:
                    self.assertIn(f.lower(), msg.lower(), f"{name}: message {msg!r} lacks {f!r}")
                if before is not None:
                    self.assertEqual(mesh_points(mesh), before, f"{name} changed its input")
        return messages

    # -- sanity: the good inputs work
    def test_good_box_mesh_and_fem_work(self):
        rep = SurfMesh.measure(make_mesh(self.nodes, self.tris), self.shape)
        self.assertEqual(rep.stats["elements"], len(self.tris))
        self.assertEqual(rep.stats["tangled"], 0)
        rep = SurfMesh.measure(make_fem(self.nodes, self.tris), self.shape)
        self.assertEqual(rep.stats["elements"], len(self.tris))

    def test_empty_mesh(self):
        self.expect_error(Mesh.Mesh(), "no elements")
        self.expect_error(Fem.FemMesh(), "no face elements")
        self.expect_error(arrays(np.zeros((0, 3)), []), "no")

    def test_nan_and_inf_coordinates(self):
        i = interior_node(self.nodes)
        for bad in (math.nan, math.inf):
            nodes = self.nodes.copy()
            nodes[i, 2] = bad
            with self.subTest(value=bad):
                fem = make_fem(nodes, self.tris)
                self.expect_error(fem, "non-finite", str(FEM_NODE_ID0 + i))
                self.expect_error(arrays(nodes, self.tris), "non-finite", str(i))

    def test_element_indices_out_of_range(self):
        tris = self.tris.copy()
        tris[5, 1] = len(self.nodes) + 7
        self.expect_error(arrays(self.nodes, tris), "out of range", str(len(self.nodes) + 7))
        tris[5, 1] = -2
        self.expect_error(arrays(self.nodes, tris), "out of range", "-2")

    def test_repeated_node_in_one_element(self):
        # Policy of the API: a collapsed element (a repeated node, zero area; Gmsh leaves them
        # where it merged nodes) is left out and reported by default (collapsed="skip"), an
        # error with collapsed="error", and always an error when every element is collapsed.
        tris = self.tris.copy()
        tris[5, 2] = tris[5, 0]
        self.expect_error(arrays(self.nodes, tris), "element id 5", "repeat a node",
                          str(tris[5, 0]), collapsed="error")
        fem = make_fem(self.nodes, tris)
        self.expect_error(fem, f"element id {FEM_ELEM_ID0 + 5}", "repeat a node",
                          str(FEM_NODE_ID0 + tris[5, 0]), collapsed="error")
        rep = SurfMesh.measure(fem, self.shape)
        self.assertEqual(rep.bridge.get("skipped_elements"), [FEM_ELEM_ID0 + 5])
        self.assertTrue(any("collapsed" in w for w in rep.bridge["warnings"]))
        res = SurfMesh.optimize(fem, self.shape, max_sweeps=2)
        self.assertEqual(sorted(res.mesh.Faces), sorted(fem.Faces))  # kept in the output
        one = np.array([[0, 1, 0]])
        self.expect_error(arrays(self.nodes, one), "repeat a node")

    def test_duplicate_nodes(self):
        # Element 0 gets its own copy of node k: a crack. duplicates="error" refuses it.
        i = interior_node(self.nodes)
        tris = self.tris.copy()
        e = int(np.nonzero((tris == i).any(axis=1))[0][0])
        nodes = np.vstack([self.nodes, self.nodes[i]])
        tris[e][tris[e] == i] = len(self.nodes)
        copy_id = len(self.nodes)
        self.expect_error(arrays(nodes, tris), "1 duplicate node", f"{i} and {copy_id}",
                          duplicates="error")
        # FEM: the message names FEM node ids.
        self.expect_error(
            make_fem(nodes, tris),
            "duplicate node",
            f"{FEM_NODE_ID0 + i} and {FEM_NODE_ID0 + copy_id}",
            duplicates="error",
        )
        self.expect_error(arrays(self.nodes, self.tris), "duplicates", duplicates="merge")

    def test_duplicate_nodes_are_glued_by_default(self):
        """The crack's two nodes move as one: the run gives what the same mesh without the
        crack gives, and both copies end at that node's place."""
        i = interior_node(self.nodes)
        moved = self.nodes.copy()
        d = next(d for d in range(3) if moved[i][d] in (0.0, 10.0))  # the face's normal axis
        step = np.zeros(3)
        step[(d + 1) % 3] = 1.4  # within the face, far enough to spoil the grid
        moved[i] += step
        tris = self.tris.copy()
        es = np.nonzero((tris == i).any(axis=1))[0][:2]
        copy_id = len(moved)
        for e in es:
            tris[e][tris[e] == i] = copy_id
        cracked = np.vstack([moved, moved[i]])
        ref = SurfMesh.optimize(arrays(moved, self.tris), self.shape)
        self.assertGreater(np.linalg.norm(ref.nodes[i] - moved[i]), 0.5)  # the node did move
        for make, ids in ((arrays, (i, copy_id)),
                          (make_fem, (FEM_NODE_ID0 + i, FEM_NODE_ID0 + copy_id))):
            with self.subTest(input=make.__name__):
                res = SurfMesh.optimize(make(cracked, tris), self.shape)
                np.testing.assert_allclose(res.nodes[:copy_id], ref.nodes, rtol=0, atol=1e-12)
                np.testing.assert_array_equal(res.nodes[copy_id], res.nodes[i])
                for k in ("min", "mean", "max", "tangled"):
                    self.assertAlmostEqual(res.after.stats[k], ref.after.stats[k], places=12)
                self.assertEqual(res.bridge["glued_nodes"], 1)
                self.assertEqual(res.bridge["unused_nodes"], 0)
                self.assertFalse(any("no element" in w for w in res.bridge["warnings"]))
                glued = [w for w in res.bridge["warnings"] if w.startswith("glued 1 node")]
                self.assertEqual(len(glued), 1, res.bridge["warnings"])
                self.assertIn(f"nodes {ids[0]} and {ids[1]}", glued[0])
                if make is make_fem:  # the new FemMesh: both ids at the node's new place
                    a = res.mesh.getNodeById(ids[0])
                    b = res.mesh.getNodeById(ids[1])
                    self.assertEqual((a.x, a.y, a.z), (b.x, b.y, b.z))
                    np.testing.assert_allclose([a.x, a.y, a.z], ref.nodes[i], atol=1e-12)
        rep = SurfMesh.measure(arrays(cracked, tris), self.shape)
        ref_rep = SurfMesh.measure(arrays(moved, self.tris), self.shape)
        np.testing.assert_allclose(rep.quality, ref_rep.quality, rtol=0, atol=1e-14)

    def test_degenerate_elements_are_tangled_and_get_untangled(self):
        # An element inside a face (no node on the box's edges): one of its nodes moved onto
        # the segment between the two others.
        inner = {k for k in range(len(self.nodes))
                 if sum(1 for c in self.nodes[k] if 1e-9 < c < 10 - 1e-9) == 2}
        e = next(e for e, t in enumerate(self.tris) if all(int(k) in inner for k in t))
        i, others = int(self.tris[e][0]), [int(k) for k in self.tris[e][1:]]
        nodes = self.nodes.copy()
        nodes[i] = 0.5 * (nodes[others[0]] + nodes[others[1]])
        fem = make_fem(nodes, self.tris)
        rep = SurfMesh.measure(fem, self.shape)
        self.assertTrue(rep.tangled[e])
        self.assertEqual(rep.quality[e], 0.0)
        res = SurfMesh.optimize(fem, self.shape)
        self.assertGreaterEqual(res.before.stats["tangled"], 1)
        self.assertEqual(res.after.stats["tangled"], 0)

    def test_non_manifold_edge(self):
        # A third triangle on an interior edge (a, b) of one face.
        i = interior_node(self.nodes)
        e = int(np.nonzero((self.tris == i).any(axis=1))[0][0])
        a, b, c = (int(k) for k in self.tris[e])
        axis = next(d for d in range(3) if self.nodes[i][d] in (0.0, 10.0))
        far = next(
            k
            for k in range(len(self.nodes))
            if self.nodes[k][axis] == self.nodes[i][axis]
            and np.linalg.norm(self.nodes[k] - self.nodes[i]) > 4.0
            and k != c
        )
        tris = np.vstack([self.tris, [a, b, far]])
        lo, hi = min(a, b), max(a, b)
        self.expect_error(arrays(self.nodes, tris), "non-manifold", f"nodes {lo} and {hi}")
        # FEM: named by FEM node ids. (A Mesh.Mesh cannot hold it: FreeCAD's mesh kernel drops
        # such facets itself when the mesh is built.)
        msg = self.expect_error(
            make_fem(self.nodes, tris),
            "non-manifold",
            f"nodes {FEM_NODE_ID0 + lo} and {FEM_NODE_ID0 + hi}",
        )[0]
        # The elements by their FEM ids (the third one is the last), the face by its name.
        self.assertIn(f"{FEM_ELEM_ID0 + len(tris) - 1})", msg)
        face = next(k + 1 for k, f in enumerate(self.shape.Faces)
                    if f.distToShape(Part.Vertex(App.Vector(*self.nodes[i])))[0] < 1e-9)
        self.assertIn(f"on Face{face}", msg)

    def test_unsupported_element_types(self):
        # FEM quad8 (8-node quadrilateral) faces are taken (FreeCAD's FemMesh holds no other
        # face type SurfMesh lacks): a square with its side nodes at the midpoints, quality 1.
        pts = [(0, 0, 0), (10, 0, 0), (10, 10, 0), (0, 10, 0), (5, 0, 0), (10, 5, 0), (5, 10, 0),
               (0, 5, 0)]
        rep = SurfMesh.measure(make_fem(pts, [list(range(8))]), self.shape)
        self.assertEqual(rep.element_types, ["quad8"])
        self.assertAlmostEqual(float(rep.quality[0]), 1.0, places=12)
        # A quad8 repeating a node and quad8 with tri3 (orders mixed): refused, naming them.
        self.expect_error(make_fem(pts, [[0, 1, 2, 3, 4, 5, 6, 4]]), "repeat",
                          str(FEM_ELEM_ID0), call=("measure",), collapsed="error")
        nodes = list(map(list, self.nodes))
        quad = [list(map(float, p)) for p in pts]
        off = len(nodes)
        elems = [list(t) for t in self.tris if all(self.nodes[k][2] > 0 for k in t)]
        elems.append([off + k for k in range(8)])
        self.expect_error(arrays(nodes + quad, elems), "mixes element orders", "quad8")
        # An invalid type code in the array input.
        data = arrays(self.nodes, self.tris, types=[9] + [0] * (len(self.tris) - 1))
        self.expect_error(data, "types", "9")

    def test_edge_element_nodes(self):
        # The box's FEM mesh with edge (beam) elements: one along a box edge, in no face element
        # (taken: located on the shape, listed in the report), one reaching 3 above the box's
        # top corner (off the whole shape: refused, naming the node, its distance and the
        # nearest entity; the mesh unchanged).
        fem = make_fem(self.nodes, self.tris)
        top = max(range(len(self.nodes)), key=lambda k: tuple(self.nodes[k][[2, 0, 1]]))
        corner = np.asarray(self.nodes[top], dtype=float)
        on_edge = FEM_NODE_ID0 + len(self.nodes)
        fem.addNode(float(corner[0]), float(corner[1]) - 1.25, float(corner[2]), on_edge)
        fem.addEdge([FEM_NODE_ID0 + top, on_edge], 5001)
        rep = SurfMesh.measure(fem, self.shape)
        self.assertEqual(rep.bridge["loose_nodes"], [on_edge])
        self.assertTrue(rep.bridge["loose_on"][0].startswith("Edge"), rep.bridge["loose_on"])
        off = on_edge + 1
        fem.addNode(float(corner[0]), float(corner[1]), float(corner[2]) + 3.0, off)
        fem.addEdge([FEM_NODE_ID0 + top, off], 5002)
        msg = self.expect_error(fem, "farther than the tolerance", f"node {off} at distance 3 ",
                                ", the nearest")
        self.assertRegex(msg[0], r"from (Face|Edge|Vertex)\d+, the nearest")

    def test_mixed_orders(self):
        # Element 0 becomes a tri6 (its mid-edge nodes added), the rest stay tri3.
        nodes = list(map(list, self.nodes))
        a, b, c = (int(k) for k in self.tris[0])
        mids = []
        for p, q in ((a, b), (b, c), (c, a)):
            nodes.append(list(0.5 * (self.nodes[p] + self.nodes[q])))
            mids.append(len(nodes) - 1)
        elems = [[a, b, c] + mids] + [list(t) for t in self.tris[1:]]
        self.expect_error(arrays(nodes, elems), "mixes element orders", "tri6")
        self.expect_error(make_fem(nodes, elems), "mixes element orders", "tri6")

    def test_scrambled_tri6_node_order_is_named(self):
        # Every triangle of the box grid becomes a tri6 (shared mid-side nodes, FreeCAD's and
        # Gmsh's order: corners, then sides 1-2, 2-3, 3-1). Two elements then list their
        # mid-side nodes first: each such "side node" is a corner, a whole side away from the
        # chord between two mid-side nodes, which no curved element comes near (reference:
        # the construction; a half circle's middle lies at half its chord).
        nodes = list(map(list, self.nodes))
        mid = {}
        elems = []
        for t in self.tris:
            t = [int(k) for k in t]
            sides = []
            for p, q in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                key = (min(p, q), max(p, q))
                if key not in mid:
                    nodes.append(list(0.5 * (self.nodes[p] + self.nodes[q])))
                    mid[key] = len(nodes) - 1
                sides.append(mid[key])
            elems.append(t + sides)

        def astray(warnings):
            return [w for w in warnings if "side node farther from its side" in w]

        for make, id0 in ((lambda n, e: arrays(n, e), 0), (make_fem, FEM_ELEM_ID0)):
            with self.subTest(input="arrays" if id0 == 0 else "FemMesh"):
                rep = SurfMesh.measure(make(nodes, elems), self.shape)
                self.assertEqual(astray(rep.bridge["warnings"]), [], "the right order")
                self.assertEqual(rep.stats["tangled"], 0)
                scrambled = [list(e) for e in elems]
                for e in (5, 9):
                    scrambled[e] = elems[e][3:] + elems[e][:3]
                rep = SurfMesh.measure(make(nodes, scrambled), self.shape)
                named = astray(rep.bridge["warnings"])
                self.assertEqual(len(named), 1, rep.bridge["warnings"])
                self.assertIn("2 high-order element(s)", named[0])
                self.assertIn(f"ids {id0 + 5}, {id0 + 9})", named[0])

    def test_nodes_off_the_shape(self):
        i = interior_node(self.nodes)
        nodes = self.nodes.copy()
        d = next(d for d in range(3) if nodes[i][d] in (0.0, 10.0))
        nodes[i][d] += 1.0 if nodes[i][d] == 10.0 else -1.0
        msgs = self.expect_error(make_fem(nodes, self.tris), "1 of", "farther than the tolerance")
        # The offending node is named (FEM: its id).
        for m in msgs:
            self.assertIn(f"node {FEM_NODE_ID0 + i}", m)
        self.expect_error(make_mesh(nodes, self.tris), "farther than the tolerance", f"node {i}")
        # A larger tolerance accepts it.
        SurfMesh.measure(make_mesh(nodes, self.tris), self.shape, tolerance=1.5)

    def test_faces_whose_trimming_curves_disagree_with_their_edges(self):
        # An imported face whose 2D trimming curve lies off its 3D edge is no bad input: its
        # mesh is taken and the report names the curve. A node of that mesh moved off the
        # surface next to such an edge is refused as any other, named, the mesh unchanged.
        import MeshPart
        import surfmesh_testing as T

        path = T.find_part("nist_pmi_2.step")
        if path is None:
            self.skipTest("nist_pmi_2.step not available")
        shape = Part.read(path)
        diag = shape.BoundBox.DiagonalLength
        tol = diag / 200
        mesh = MeshPart.meshFromShape(Shape=shape, LinearDeflection=diag / 500)
        rep = SurfMesh.measure(mesh, shape, tolerance=tol)
        gaps = rep.bridge["trim_gaps"]
        self.assertGreater(len(gaps), 0)
        worst = max(gaps, key=lambda g: g["gap"])
        edge = shape.getElement(worst["edge"])
        face = shape.getElement(worst["face"])
        mid = edge.valueAt(0.5 * (edge.FirstParameter + edge.LastParameter))
        nodes = np.array([(p.x, p.y, p.z) for p in mesh.Topology[0]])
        tris = [tuple(f) for f in mesh.Topology[1]]
        i = int(np.argmin(np.linalg.norm(nodes - np.array(tuple(mid)), axis=1)))
        u, v = face.Surface.parameter(App.Vector(*nodes[i]))
        n = face.normalAt(u, v)
        nodes[i] += 5 * tol * np.array((n.x, n.y, n.z))
        self.expect_error(make_mesh(nodes, tris), "1 of", "farther than the tolerance",
                          f"node {i}", shape=shape, tolerance=tol)

    def test_every_node_of_a_list_is_named_by_its_id(self):
        # Four nodes pushed off the box: the message's list names each one by its FEM id
        # (ids start at FEM_NODE_ID0, not at the 0-based row the core reports).
        nodes = self.nodes.copy()
        off = [i for i, p in enumerate(nodes)
               if sum(1 for c in p if 1e-9 < c < 10.0 - 1e-9) == 2][:4]
        for i in off:
            d = next(d for d in range(3) if nodes[i][d] in (0.0, 10.0))
            nodes[i][d] += 1.0 if nodes[i][d] == 10.0 else -1.0
        msgs = self.expect_error(make_fem(nodes, self.tris), "4 of", "farther than the tolerance")
        listed = " ".join(str(FEM_NODE_ID0 + i) for i in off)
        for m in msgs:
            self.assertIn(f"e.g. nodes {listed}", m)

    def test_refusals_carry_their_diagnostic_in_the_users_ids(self):
        # The core's refusal as a structured diagnostic: its code, the node by its FEM id, the
        # text the exception says; the core's own text (0-based rows) is the same diagnostic
        # rendered with its indices.
        from SurfMesh.app.native import core

        i = interior_node(self.nodes)
        nodes = self.nodes.copy()
        d = next(d for d in range(3) if nodes[i][d] in (0.0, 10.0))
        nodes[i][d] += 1.0 if nodes[i][d] == 10.0 else -1.0
        with self.assertRaises(ValueError) as cm:
            SurfMesh.measure(make_fem(nodes, self.tris), self.shape)
        diag = cm.exception.diagnostic
        self.assertEqual(diag["code"], "nodes_off_shape")
        self.assertEqual(diag["count"], 1)
        self.assertEqual(diag["nodes"][0], FEM_NODE_ID0 + i)
        self.assertEqual(diag["text"], str(cm.exception))
        m = core()
        cshape = m.CadShape.from_brep_string(self.shape.exportBrepToString())
        tris = np.asarray(self.tris, dtype=np.int64)
        with self.assertRaises(m.InputError) as raw:
            m.cad_mesh(cshape, nodes, np.zeros(len(tris), dtype=np.int64),
                       np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64), tris.reshape(-1))
        core_diag = raw.exception.diagnostic
        self.assertEqual(core_diag["nodes"][0], i)
        self.assertEqual(core_diag["text"], str(raw.exception))
        self.assertIn(f"worst: node {i} at distance", str(raw.exception))
        # the same placeholders, filled with the user's ids, give the user's text
        self.assertEqual(str(raw.exception).replace(f"node {i} ", f"node {FEM_NODE_ID0 + i} ")
                         .replace(f"e.g. nodes {i}", f"e.g. nodes {FEM_NODE_ID0 + i}"),
                         diag["text"])

    def test_every_diagnostic_code_is_documented(self):
        # docs/python-api.md's table of codes is the list the core and messages give, each
        # as a refusal or a warning as they say.
        import re

        import surfmesh_testing as T
        from SurfMesh.app import messages

        with open(os.path.join(T.REPO, "docs", "python-api.md"), encoding="utf-8") as f:
            documented = dict(re.findall(r"^\| `([a-z_]+)` \| (refusal|warning) \|", f.read(),
                                         re.M))
        codes = {c["code"]: "refusal" if c["refusal"] else "warning"
                 for c in messages.diagnostic_codes()}
        self.assertGreater(len(codes), 20)
        self.assertEqual(documented, codes)

    def test_mesh_of_another_shape(self):
        far = Part.makeCylinder(3, 8, App.Vector(100, 0, 0))
        self.expect_error(make_mesh(self.nodes, self.tris), "does not lie on this shape", shape=far)
        inside = Part.makeSphere(5, App.Vector(5, 5, 5))
        self.expect_error(make_mesh(self.nodes, self.tris), "does not lie on this shape",
                          shape=inside)

    def test_invalid_or_empty_shape(self):
        mesh = make_mesh(self.nodes, self.tris)
        self.expect_error(mesh, "null", shape=Part.Shape())
        wire = Part.Wire([Part.makeLine(App.Vector(0, 0, 0), App.Vector(1, 0, 0))])
        self.expect_error(mesh, "no faces", shape=wire)
        for bad in (42, "box.step"):
            with self.subTest(shape=bad):
                with self.assertRaises(ValueError):
                    SurfMesh.measure(mesh, bad)

    def test_not_a_mesh(self):
        for bad in (None, 3.5, "mesh.msh", self.shape):
            with self.subTest(mesh=repr(bad)[:30]):
                with self.assertRaises(ValueError) as cm:
                    SurfMesh.measure(bad, self.shape)
                self.assertIn("not a mesh", str(cm.exception))

    def test_shape_with_free_faces_only_works(self):
        face = Part.makePlane(10, 10)  # a face, no solid
        nodes = self.nodes[self.nodes[:, 2] == 0.0]
        index = {tuple(p): k for k, p in enumerate(map(tuple, nodes))}
        tris = [
            [index[tuple(self.nodes[k])] for k in t]
            for t in self.tris
            if all(self.nodes[k][2] == 0.0 for k in t)
        ]
        tris = [t[::-1] for t in tris]  # the bottom face was wound for −z
        mesh = make_mesh(nodes, tris)
        rep = SurfMesh.measure(mesh, face)
        self.assertEqual(rep.stats["elements"], len(tris))
        res = SurfMesh.optimize(mesh, face)
        self.assertEqual(res.after.stats["tangled"], 0)

    def test_shape_with_poles_works(self):
        sphere = Part.makeSphere(4)  # two degenerated edges (poles)
        import MeshPart

        mesh = MeshPart.meshFromShape(Shape=sphere, LinearDeflection=0.05, AngularDeflection=0.3)
        rep = SurfMesh.measure(mesh, sphere)
        self.assertGreater(rep.bridge["pole_nodes"], 0)
        res = SurfMesh.optimize(mesh, sphere, max_sweeps=5)
        self.assertLessEqual(res.after.stats["tangled"], res.before.stats["tangled"])

    def test_elements_wound_against_their_face_are_refused_by_optimize(self):
        # Three triangles with their node order reversed (an STL with flipped facets): each is
        # tangled whatever its node positions, and untangling them by moving nodes folds the
        # mesh. measure counts them tangled and says why; optimize refuses, naming them.
        tris = self.tris.copy()
        flipped = [5, 40, 77]
        for e in flipped:
            tris[e, [1, 2]] = tris[e, [2, 1]]
        for mesh, ids in ((make_fem(self.nodes, tris), [FEM_ELEM_ID0 + e for e in flipped]),
                          (make_mesh(self.nodes, tris), flipped)):
            with self.subTest(kind=type(mesh).__name__):
                rep = SurfMesh.measure(mesh, self.shape)
                self.assertEqual(rep.stats["tangled"], len(flipped))
                self.assertTrue(any("wound against the rest of their face" in w
                                    for w in rep.bridge["warnings"]), rep.bridge["warnings"])
                # the report names them by the mesh's own element ids (FEM ids here)
                self.assertEqual(sorted(rep.bridge["miswound_elements"]), ids)
                listed = ", ".join(str(i) for i in ids)
                self.expect_error(mesh, "wound against the rest of their face",
                                  f"element(s) {listed}", call=("optimize",))

    def test_degenerate_spot_left_out(self):
        """A mesher's degenerate spot (Gmsh's recombined quads where a fillet ends in a point:
        collapsed elements with, around them, a third element on one edge and elements wound
        against their face's mesh) is left out, with the collapsed elements, instead of refusing
        the whole mesh; the same non-manifold edge or reversed element away from collapsed
        elements is still refused (test_non_manifold_edge and the test above)."""
        i = interior_node(self.nodes)
        around = [int(e) for e in np.nonzero((self.tris == i).any(axis=1))[0]]
        a, b, c = (int(k) for k in self.tris[around[0]])
        axis = next(d for d in range(3) if self.nodes[i][d] in (0.0, 10.0))
        far = next(k for k in range(len(self.nodes))
                   if self.nodes[k][axis] == self.nodes[i][axis]
                   and np.linalg.norm(self.nodes[k] - self.nodes[i]) > 4.0 and k != c)
        collapsed = [i, i, far]                # a repeated node: zero area
        third = [a, b, far]                    # a third element on edge (a, b), next to node i
        flipped = around[-1]                   # reversed, next to node i
        tris = [list(map(int, t)) for t in self.tris]
        tris[flipped][1], tris[flipped][2] = tris[flipped][2], tris[flipped][1]
        tris += [collapsed, third]
        E = len(self.tris)
        res = SurfMesh.optimize(arrays(self.nodes, tris), self.shape)
        left = set(res.bridge["skipped_elements"])
        # The two elements of the original mesh on edge (a, b) and the third one: all three
        # touch node i of the collapsed element, so none of them can be told apart as wrong.
        on_ab = {e for e in range(E) if {a, b} <= set(map(int, self.tris[e]))}
        self.assertEqual(len(on_ab), 2)
        self.assertEqual(left, {E, E + 1, flipped} | on_ab)
        warning = next(w for w in res.bridge["warnings"] if w.startswith("left out"))
        for f in ("1 collapsed element", "3 element(s) overlapping around those",
                  "1 element(s) wound against their face's mesh next to those"):
            self.assertIn(f, warning)
        self.assertEqual(res.after.stats["elements"], len(tris) - len(left))
        self.assertEqual(res.after.stats["tangled"], 0)
        # Without the collapsed element the same mesh is refused (non-manifold edge).
        self.expect_error(arrays(self.nodes, tris[:-2] + [third]), "non-manifold",
                          call=("optimize",))

    def test_misjoined_second_order_elements_at_a_degenerate_spot_left_out(self):
        """Gmsh's second-order mesh of the bottle's thread where it ends: around collapsed
        elements, curved elements joined through side nodes no conforming mesh shares (a side
        node that is also a corner). They are left out with the collapsed elements, and every
        element using such a node with them (none can be told apart as wrong); the same
        element away from collapsed ones is not touched."""
        plane = Part.makePlane(10, 10)
        n = 4  # 4 × 4 squares, two second-order triangles each, side nodes at the midpoints
        pts, index = [], {}

        def node(x, y):
            key = (round(x, 9), round(y, 9))
            if key not in index:
                index[key] = len(pts)
                pts.append((x, y, 0.0))
            return index[key]

        h = 10.0 / n
        tris = []
        for i in range(n):
            for j in range(n):
                for a, b, c in (((i, j), (i + 1, j), (i + 1, j + 1)),
                                ((i, j), (i + 1, j + 1), (i, j + 1))):
                    cs = [node(x * h, y * h) for x, y in (a, b, c)]
                    mids = [node((p[0] + q[0]) * h / 2, (p[1] + q[1]) * h / 2)
                            for p, q in ((a, b), (b, c), (c, a))]
                    tris.append(cs + mids)
        E = len(tris)
        centre = node(2 * h, 2 * h)
        right = node(3 * h, 2 * h)  # a corner next to it
        far1, far2 = len(pts), len(pts) + 1
        pts += [(3.2 * h, 2.6 * h, 0.0), (2.6 * h, 2.9 * h, 0.0)]
        extra = len(pts)
        pts += [((3 * h + 2.6 * h) / 2, 2.45 * h, 0.0), (2.9 * h, 2.75 * h, 0.0),
                (2.3 * h, 2.5 * h, 0.0), (2.2 * h, 2.3 * h, 0.0), (2.4 * h, 2.2 * h, 0.0)]
        # Its side node on (right, far1) is `centre`, a corner of the grid's elements.
        misjoined = [right, far1, far2, centre, extra, extra + 1]
        collapsed = [centre, centre, far2, extra + 2, extra + 3, extra + 4]
        nodes = np.array(pts)
        res = SurfMesh.optimize(arrays(nodes, tris + [misjoined, collapsed]), plane)
        left = set(res.bridge["skipped_elements"])
        around = {e for e in range(E) if centre in tris[e][:3]}
        self.assertEqual(len(around), 6)
        self.assertEqual(left, {E, E + 1} | around)
        warning = next(w for w in res.bridge["warnings"] if w.startswith("left out"))
        self.assertIn("1 collapsed element", warning)
        self.assertIn("7 high-order element(s) joined to those through side nodes", warning)
        self.assertEqual(res.after.stats["elements"], E + 2 - len(left))
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertLess(np.abs(res.nodes[:, 2]).max(), 1e-12)  # on the plane
        # Without the collapsed element nothing is left out (no degenerate spot).
        rep = SurfMesh.measure(arrays(nodes, tris + [misjoined]), plane)
        self.assertEqual(rep.stats["elements"], E + 1)
        self.assertEqual(rep.bridge.get("skipped_elements", []), [])

    def test_volume_mesh_is_measured_but_not_moved(self):
        # Moving the surface nodes of a volume mesh would leave its interior nodes behind and
        # could invert the tetrahedra along the surface: optimize refuses, measure works.
        nodes, tris = self.nodes, self.tris
        fem = box_volume_fem(nodes, tris)
        self.assertEqual(fem.VolumeCount, len(tris))
        rep = SurfMesh.measure(fem, self.shape)
        self.assertEqual(rep.stats["elements"], len(tris))
        self.expect_error(fem, "volume element", "tetra4 (%d)" % len(tris), call=("optimize",))

    def test_unknown_measure_name(self):
        mesh = make_mesh(self.nodes, self.tris)
        for bad in ("aspect", "", None, 3):
            with self.subTest(measure=bad):
                self.expect_error(mesh, "unknown measure", "shape", "oddy", measure=bad)

    def test_negative_zero_or_nan_tolerances(self):
        mesh = make_mesh(self.nodes, self.tris)
        for bad in (-1.0, 0.0, math.nan, math.inf, "a", True):
            with self.subTest(tolerance=bad):
                self.expect_error(mesh, "tolerance", tolerance=bad)
        for key, bad in (("rel_tol", -1e-5), ("move_tol", -1.0), ("rel_tol", math.nan),
                         ("delta", 0.0), ("max_sweeps", 0), ("max_sweeps", -3),
                         ("threads", -1), ("delta_policy", "sometimes"),
                         ("over_relaxation", 2.0), ("over_relaxation", 0.5),
                         ("over_relaxation", math.nan), ("monotone", "no"),
                         ("monotone", "False"), ("monotone", 1)):
            with self.subTest(option=key, value=bad):
                self.expect_error(mesh, key, call=("optimize",), **{key: bad})
        self.expect_error(mesh, "unknown option", "bogus", call=("optimize",), bogus=1)
        self.expect_error(mesh, "boundary", call=("optimize",), boundary="glue")

    @unittest.skipUnless(
        os.path.exists(os.path.join(SHARED, "gmsh_u_joint.step")), "shared u-joint part absent"
    )
    def test_benchmark_u_joint_with_degenerated_edges(self):
        """Benchmark-only (GPL part read from ../shared): a shape with 44 poles. Its BRepMesh
        triangulation is non-manifold at the poles (see the data README): SurfMesh must either
        work on it or say exactly that."""
        import MeshPart

        shape = Part.read(os.path.join(SHARED, "gmsh_u_joint.step"))
        diag = shape.BoundBox.DiagonalLength
        mesh = MeshPart.meshFromShape(Shape=shape, LinearDeflection=diag / 1000,
                                      AngularDeflection=0.5, Relative=False)
        before = mesh_points(mesh)
        try:
            rep = SurfMesh.measure(mesh, shape)
        except ValueError as e:
            self.assertRegex(str(e), "non-manifold|duplicate")
        else:
            self.assertGreater(rep.bridge["pole_nodes"], 0)
        self.assertEqual(mesh_points(mesh), before)


# ---- the document: errors, cancellation and exceptions change nothing --------------------------


class DocumentUnchanged(unittest.TestCase):
    def setUp(self):
        self.doc = App.newDocument("SurfMeshBadInput")
        self.doc.UndoMode = 1
        self.part = self.doc.addObject("Part::Feature", "Box")
        self.part.Shape = box_shape()
        nodes, tris = box_grid()
        i = interior_node(nodes)
        # Tangle one element so that the optimizer has work for several sweeps.
        e = int(np.nonzero((tris == i).any(axis=1))[0][0])
        others = [k for k in tris[e] if k != i]
        nodes[i] = nodes[others[0]] + 0.9 * (nodes[others[1]] - nodes[others[0]])
        self.mesh_obj = self.doc.addObject("Mesh::Feature", "BoxMesh")
        self.mesh_obj.Mesh = make_mesh(nodes, tris)
        self.fem_obj = self.doc.addObject("Fem::FemMeshObject", "BoxFem")
        self.fem_obj.FemMesh = make_fem(nodes, tris)
        self.doc.recompute()
        self.doc.clearUndos()

    def tearDown(self):
        App.closeDocument(self.doc.Name)

    def snapshot(self):
        return {
            "objects": [o.Name for o in self.doc.Objects],
            "undo": (self.doc.UndoCount, list(self.doc.UndoNames)),
            "mesh": mesh_points(self.mesh_obj.Mesh),
            "fem": mesh_points(self.fem_obj.FemMesh),
            "mesh_props": list(self.mesh_obj.PropertiesList),
            "fem_props": list(self.fem_obj.PropertiesList),
        }

    def test_cancel_through_the_progress_callback(self):
        for obj in (self.mesh_obj, self.fem_obj):
            with self.subTest(obj=obj.Name):
                before = self.snapshot()
                calls = []

                def stop(info):
                    calls.append(info)
                    return False

                with self.assertRaises(SurfMesh.Cancelled):
                    SurfMesh.optimize(obj, self.part, progress=stop)
                self.assertEqual(len(calls), 1)
                self.assertEqual(self.snapshot(), before)
                with self.assertRaises(SurfMesh.Cancelled):
                    SurfMesh.optimize_object(obj, self.part, progress_callback=stop)
                self.assertEqual(self.snapshot(), before)

    def test_cancel_after_some_sweeps(self):
        before = self.snapshot()
        sweeps = []

        # Cancel after the first sweep: the tangled element may be repaired in one sweep, and
        # the callback is called after every sweep before any stopping test.
        def stop(info):
            sweeps.append(info["sweep"])
            return False

        with self.assertRaises(SurfMesh.Cancelled):
            SurfMesh.optimize_object(self.fem_obj, self.part, progress_callback=stop,
                                     rel_tol=1e-12, move_tol=1e-12)
        self.assertEqual(sweeps, [1])
        self.assertEqual(self.snapshot(), before)

    def test_exception_in_the_progress_callback(self):
        before = self.snapshot()

        class Boom(Exception):
            pass

        def boom(info):
            raise Boom("from the callback")

        for obj in (self.mesh_obj, self.fem_obj):
            with self.subTest(obj=obj.Name):
                with self.assertRaises(Boom):
                    SurfMesh.optimize(obj, self.part, progress=boom)
                with self.assertRaises(Boom):
                    SurfMesh.optimize_object(obj, self.part, progress_callback=boom)
                self.assertEqual(self.snapshot(), before)

    def test_bad_input_on_document_objects(self):
        before = self.snapshot()
        for fn in (SurfMesh.measure_object, SurfMesh.optimize_object):
            with self.subTest(fn=fn.__name__):
                with self.assertRaises(ValueError):
                    fn(self.mesh_obj, self.part, measure="aspect")
                with self.assertRaises(ValueError):
                    fn(self.mesh_obj, Part.makeCylinder(3, 8, App.Vector(100, 0, 0)))
                with self.assertRaises(ValueError):
                    fn(self.part)  # not a mesh
                self.assertEqual(self.snapshot(), before)

    def test_volume_mesh_object_is_not_optimized(self):
        nodes, tris = box_grid()
        vol = self.doc.addObject("Fem::FemMeshObject", "BoxVolume")
        vol.FemMesh = box_volume_fem(nodes, tris)
        self.doc.recompute()
        self.doc.clearUndos()
        before = self.snapshot()
        points = mesh_points(vol.FemMesh)
        with self.assertRaises(ValueError) as cm:
            SurfMesh.optimize_object(vol, self.part)
        self.assertIn("volume element", str(cm.exception))
        self.assertEqual(self.snapshot(), before)
        self.assertEqual(mesh_points(vol.FemMesh), points)

    def test_catalogue_on_document_objects(self):
        """Each bad FEM mesh of the catalogue in a document object: measure_object and
        optimize_object raise ValueError naming the problem, and the document (objects, undo
        stack, node coordinates, properties) is unchanged."""
        nodes, tris = box_grid()
        i = interior_node(nodes)
        cases = []
        n = nodes.copy()
        n[i, 0] = math.nan
        cases.append(("nan", make_fem(n, tris), ["non-finite", str(FEM_NODE_ID0 + i)]))
        strict = {"duplicates": "error"}  # the default glues coincident nodes
        e = int(np.nonzero((tris == i).any(axis=1))[0][0])
        t2 = tris.copy()
        t2[e][t2[e] == i] = len(nodes)
        cases.append(("duplicate", make_fem(np.vstack([nodes, nodes[i]]), t2),
                      ["duplicate node", f"{FEM_NODE_ID0 + i} and {FEM_NODE_ID0 + len(nodes)}"],
                      strict))
        a, b, c = (int(k) for k in tris[e])
        axis = next(d for d in range(3) if nodes[i][d] in (0.0, 10.0))
        far = next(k for k in range(len(nodes)) if nodes[k][axis] == nodes[i][axis]
                   and np.linalg.norm(nodes[k] - nodes[i]) > 4.0 and k != c)
        cases.append(("non-manifold", make_fem(nodes, np.vstack([tris, [a, b, far]])),
                      ["non-manifold"]))
        n = nodes.copy()
        d = next(d for d in range(3) if n[i][d] in (0.0, 10.0))
        n[i][d] += 1.0 if n[i][d] == 10.0 else -1.0
        cases.append(("off shape", make_fem(n, tris),
                      ["farther than the tolerance", f"node {FEM_NODE_ID0 + i}"]))
        mixed_nodes = list(map(list, nodes))
        p0, p1, p2 = (int(k) for k in tris[0])
        mids = []
        for p, q in ((p0, p1), (p1, p2), (p2, p0)):
            mixed_nodes.append(list(0.5 * (nodes[p] + nodes[q])))
            mids.append(len(mixed_nodes) - 1)
        cases.append(("mixed orders", make_fem(mixed_nodes, [[p0, p1, p2] + mids]
                                               + [list(t) for t in tris[1:]]),
                      ["mixes element orders"]))
        cases.append(("empty", Fem.FemMesh(), ["no face elements"]))
        cases = [c if len(c) == 4 else c + ({},) for c in cases]
        for name, fem, fragments, kw in cases:
            obj = self.doc.addObject("Fem::FemMeshObject", "Bad")
            obj.FemMesh = fem
            self.doc.recompute()
            self.doc.clearUndos()
            before = self.snapshot()
            bad_before = (mesh_points(obj.FemMesh), list(obj.PropertiesList))
            for fn in (SurfMesh.measure_object, SurfMesh.optimize_object):
                with self.subTest(case=name, fn=fn.__name__):
                    with self.assertRaises(ValueError) as cm:
                        fn(obj, self.part, **kw)
                    for f in fragments:
                        self.assertIn(f.lower(), str(cm.exception).lower())
                    self.assertEqual(self.snapshot(), before)
                    self.assertEqual((mesh_points(obj.FemMesh), list(obj.PropertiesList)),
                                     bad_before)
                    self.assertEqual(self.doc.UndoCount, 0)
            self.doc.removeObject(obj.Name)

    def test_a_good_run_still_works_after_the_errors(self):
        with self.assertRaises(ValueError):
            SurfMesh.optimize_object(self.fem_obj, self.part, measure="aspect")
        new = SurfMesh.optimize_object(self.fem_obj, self.part)
        self.assertIn(new.Name, [o.Name for o in self.doc.Objects])
        self.assertEqual(self.doc.UndoCount, 1)
        self.doc.undo()
        self.assertNotIn("BoxFem_optimized", [o.Name for o in self.doc.Objects])


# ---- the CLI ------------------------------------------------------------------------------------


def find_cli():
    """surfmesh_cli.py of the installed workbench (or of the repository)."""
    import SurfMesh as pkg

    base = os.path.dirname(pkg.__file__)
    for path in (
        os.path.join(base, "cli", "surfmesh_cli.py"),
        os.path.join(base, "surfmesh_cli.py"),
        os.path.join(REPO, "src", "SurfMesh", "cli", "surfmesh_cli.py"),
    ):
        if os.path.exists(path):
            return path
    return None


class BadInputCli(unittest.TestCase):
    """Each bad file / option through ``freecadcmd surfmesh_cli.py -- ...``: non-zero exit, a
    message naming the problem, no output written."""

    @classmethod
    def setUpClass(cls):
        cls.cli = find_cli()
        if cls.cli is None:
            raise unittest.SkipTest("no surfmesh_cli.py in the installed workbench yet")
        cls.tmp = tempfile.TemporaryDirectory(prefix="surfmesh-bad-cli-")
        d = cls.tmp.name
        cls.box = os.path.join(d, "box.brep")
        box_shape().exportBrep(cls.box)
        cls.far = os.path.join(d, "far_cylinder.brep")
        Part.makeCylinder(3, 8, App.Vector(100, 0, 0)).exportBrep(cls.far)
        nodes, tris = box_grid()
        cls.mesh = os.path.join(d, "box.stl")
        make_mesh(nodes, tris).write(cls.mesh)

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "tmp", None) is not None:
            cls.tmp.cleanup()

    def run_cli(self, *args):
        exe = os.environ.get("FREECADCMD", "freecadcmd")
        out = os.path.join(self.tmp.name, "out.stl")
        msh = os.path.join(self.tmp.name, "out.msh")
        report = os.path.join(self.tmp.name, "report.json")
        for p in (out, msh, report):
            if os.path.exists(p):
                os.remove(p)
        cmd = [exe, self.cli, "--"] + [a.format(out=out, msh=msh, report=report) for a in args]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                           stdin=subprocess.DEVNULL)
        return p, (msh if "{msh}" in args else out), report

    def expect_failure(self, *args, fragments=()):
        p, out, report = self.run_cli(*args)
        text = p.stdout + p.stderr
        self.assertNotEqual(p.returncode, 0, f"exit 0 for bad input {args}:\n{text[-2000:]}")
        self.assertNotIn("Traceback", text, f"a traceback instead of a message:\n{text[-2000:]}")
        for f in fragments:
            self.assertIn(f.lower(), text.lower(), f"output lacks {f!r}:\n{text[-2000:]}")
        self.assertFalse(os.path.exists(out), "an output mesh was written")
        self.assertFalse(os.path.exists(report), "a report was written")
        return text

    def test_good_run_works(self):
        p, out, report = self.run_cli("optimize", self.box, self.mesh, "-o", "{out}",
                                      "--report", "{report}")
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        self.assertTrue(os.path.exists(out))

    def test_output_format_other_than_the_input(self):
        # An STL input written as .msh: either done, or refused with a clear message (exit 2);
        # never an internal error.
        p, out, report = self.run_cli("optimize", self.box, self.mesh, "-o", "{msh}")
        text = p.stdout + p.stderr
        self.assertIn(p.returncode, (0, 2), text[-2000:])
        self.assertNotIn("Traceback", text)

    def test_missing_files(self):
        self.expect_failure("optimize", os.path.join(BAD, "does_not_exist.step"), self.mesh,
                            "-o", "{out}", "--report", "{report}", fragments=["does_not_exist"])
        self.expect_failure("optimize", self.box, os.path.join(BAD, "does_not_exist.msh"),
                            "-o", "{out}", "--report", "{report}", fragments=["does_not_exist"])

    def test_files_that_are_not_shapes(self):
        for name in ("not_a_shape.step", "not_a_shape.brep", "empty.step", "empty.brep",
                     "square.msh"):
            with self.subTest(file=name):
                self.expect_failure("optimize", os.path.join(BAD, name), self.mesh, "-o",
                                    "{out}", "--report", "{report}", fragments=[name])

    def test_files_that_are_not_meshes(self):
        for name in ("empty.msh", "not_a_mesh.msh"):
            with self.subTest(file=name):
                self.expect_failure("optimize", self.box, os.path.join(BAD, name), "-o",
                                    "{out}", "--report", "{report}", fragments=[name])

    def test_mesh_of_another_shape(self):
        self.expect_failure("optimize", self.far, self.mesh, "-o", "{out}", "--report",
                            "{report}", fragments=["does not lie on this shape"])
        self.expect_failure("measure", self.far, os.path.join(BAD, "square.msh"),
                            "--report", "{report}", fragments=["does not lie on this shape"])

    def test_output_problems_are_found_before_the_run(self):
        # A missing folder, an unknown or missing extension, a report in a missing folder:
        # refused with exit 2 and a one-line message before anything is optimized.
        d = self.tmp.name
        for out, report, fragment in (
                (os.path.join(d, "no_such_dir", "out.msh"), "{report}", "does not exist"),
                (os.path.join(d, "out.xyz"), "{report}", "unknown output mesh format"),
                (os.path.join(d, "out"), "{report}", "no extension"),
                ("{out}", os.path.join(d, "no_such_dir", "r.json"), "does not exist")):
            with self.subTest(out=os.path.basename(out), report=os.path.basename(report)):
                text = self.expect_failure("optimize", self.box, self.mesh, "-o", out,
                                           "--report", report, fragments=[fragment])
                self.assertNotIn("Optimized", text, "the run went on before the error")
                self.assertFalse(os.path.exists(out))

    def test_volume_meshes_are_refused(self):
        # A FEM volume mesh (.unv) and a Gmsh volume mesh (.msh, tetrahedra and the surface
        # triangles): optimize refuses both with exit 2, measure reads them.
        nodes, tris = box_grid()
        unv = os.path.join(self.tmp.name, "box_volume.unv")
        box_volume_fem(nodes, tris).write(unv)
        msh = os.path.join(self.tmp.name, "box_volume.msh")
        from SurfMesh.app import fileio

        gmsh = fileio._gmsh()  # initialized as the CLI does
        gmsh.clear()
        gmsh.model.occ.addBox(0, 0, 0, 10, 10, 10)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 3.0)
        gmsh.model.mesh.generate(3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.SaveAll", 1)
        gmsh.write(msh)
        gmsh.clear()
        for path in (unv, msh):
            with self.subTest(file=os.path.basename(path)):
                self.expect_failure("optimize", self.box, path, "-o", "{msh}", "--report",
                                    "{report}", fragments=["volume element", "tetra"])
                p, _, report = self.run_cli("measure", self.box, path, "--report", "{report}")
                self.assertEqual(p.returncode, 0, (p.stdout + p.stderr)[-2000:])
                self.assertTrue(os.path.exists(report))

    def test_bad_options(self):
        self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}", "--measure",
                            "aspect", fragments=["aspect"])
        for bad in ("-1", "0", "nan"):
            with self.subTest(tolerance=bad):
                self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}",
                                    "--tolerance", bad, fragments=["tolerance"])
                self.expect_failure("measure", self.box, self.mesh, "--report", "{report}",
                                    "--tolerance", bad, fragments=["tolerance"])
        self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}", "--rel-tol", "-1",
                            fragments=["rel_tol"])
        self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}", "--max-sweeps",
                            "0", fragments=["max_sweeps"])
        self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}",
                            "--over-relaxation", "2.5", fragments=["over_relaxation"])
        self.expect_failure("optimize", self.box, self.mesh, "-o", "{out}", "--boundary", "glue",
                            fragments=["glue"])

    # -- the bad-input catalogue as .msh files (both CLI commands)
    def bad_msh(self, name, nodes, elems, **kw):
        path = os.path.join(self.tmp.name, name + ".msh")
        write_msh(path, nodes, elems, **kw)
        return path

    def expect_both_fail(self, path, fragments, extra=()):
        before = open(path, "rb").read()
        for command in ("measure", "optimize"):
            with self.subTest(command=command, file=os.path.basename(path)):
                args = [command, self.box, path, "--report", "{report}", *extra]
                if command == "optimize":
                    args += ["-o", "{msh}"]
                p, out, report = self.run_cli(*args)
                text = p.stdout + p.stderr
                self.assertNotEqual(p.returncode, 0, f"exit 0 for {path}:\n{text[-2000:]}")
                self.assertNotIn("Traceback", text, text[-2000:])
                for f in fragments:
                    self.assertIn(f.lower(), text.lower(), f"output lacks {f!r}:\n{text[-2000:]}")
                self.assertFalse(os.path.exists(out), "an output mesh was written")
                self.assertFalse(os.path.exists(report), "a report was written")
        self.assertEqual(open(path, "rb").read(), before, "the input file was changed")

    def test_catalogue_nan_and_inf_coordinates(self):
        nodes, tris = box_grid()
        i = interior_node(nodes)
        for bad in (math.nan, math.inf):
            n = nodes.copy()
            n[i, 2] = bad
            path = self.bad_msh(f"nonfinite_{bad}", n, tris)
            self.expect_both_fail(path, ["non-finite", f"node {i + 1}"])

    def test_catalogue_element_node_out_of_range(self):
        nodes, tris = box_grid()
        elems = [list(t) for t in tris]
        elems[5][1] = -(len(nodes) + 7)  # node id N + 7: not in the file
        path = self.bad_msh("out_of_range", nodes, elems)
        self.expect_both_fail(path, [str(len(nodes) + 7)])

    def test_catalogue_repeated_node_in_one_element(self):
        # Policy: left out and reported (a warning naming the element), the rest is processed.
        nodes, tris = box_grid()
        elems = [list(t) for t in tris]
        elems[5][2] = elems[5][0]
        path = self.bad_msh("repeated_node", nodes, elems)
        p, out, report = self.run_cli("optimize", self.box, path, "-o", "{msh}", "--report",
                                      "{report}")
        text = p.stdout + p.stderr
        self.assertEqual(p.returncode, 0, text[-2000:])
        import json

        with open(report) as f:
            rep = json.load(f)
        warnings = " ".join(rep["bridge"]["warnings"])
        self.assertIn("collapsed", warnings)
        self.assertIn("6", warnings)  # element id 6 (1-based in the file)
        # Every element collapsed: an error.
        path = self.bad_msh("all_repeated", nodes[:3], [[0, 1, 0]])
        self.expect_both_fail(path, ["repeat a node"])

    def test_catalogue_duplicate_nodes(self):
        nodes, tris = box_grid()
        i = interior_node(nodes)
        elems = [list(t) for t in tris]
        e = next(k for k, t in enumerate(elems) if i in t)
        nodes2 = np.vstack([nodes, nodes[i]])
        elems[e][elems[e].index(i)] = len(nodes)
        path = self.bad_msh("duplicate_nodes", nodes2, elems)
        self.expect_both_fail(path, ["duplicate node", f"{i + 1} and {len(nodes) + 1}"],
                              extra=("--duplicates", "error"))
        # By default the two nodes are glued: the run works and they stay together.
        p, out, report = self.run_cli("optimize", self.box, path, "-o", "{msh}", "--report",
                                      "{report}")
        self.assertEqual(p.returncode, 0, (p.stdout + p.stderr)[-2000:])
        self.assertIn("glued 1 node", p.stdout + p.stderr)
        import json

        with open(report) as f:
            self.assertEqual(json.load(f)["bridge"]["glued_nodes"], 1)
        from SurfMesh.app import fileio

        out_nodes = fileio.read_mesh(out).data.nodes
        np.testing.assert_array_equal(out_nodes[len(nodes)], out_nodes[i])

    def test_catalogue_degenerate_element_is_tangled_and_untangled(self):
        nodes, tris = box_grid()
        inner = {k for k in range(len(nodes))
                 if sum(1 for c in nodes[k] if 1e-9 < c < 10 - 1e-9) == 2}
        e = next(e for e, t in enumerate(tris) if all(int(k) in inner for k in t))
        i, a, b = (int(k) for k in tris[e])
        n = nodes.copy()
        n[i] = 0.5 * (n[a] + n[b])  # zero area
        path = self.bad_msh("zero_area", n, tris)
        p, out, report = self.run_cli("optimize", self.box, path, "-o", "{msh}", "--report",
                                      "{report}")
        self.assertEqual(p.returncode, 0, (p.stdout + p.stderr)[-2000:])
        import json

        with open(report) as f:
            rep = json.load(f)
        self.assertGreaterEqual(rep["before"]["tangled"], 1)
        self.assertEqual(rep["after"]["tangled"], 0)

    def test_catalogue_non_manifold_edge(self):
        nodes, tris = box_grid()
        i = interior_node(nodes)
        e = int(np.nonzero((tris == i).any(axis=1))[0][0])
        a, b, c = (int(k) for k in tris[e])
        axis = next(d for d in range(3) if nodes[i][d] in (0.0, 10.0))
        far = next(k for k in range(len(nodes)) if nodes[k][axis] == nodes[i][axis]
                   and np.linalg.norm(nodes[k] - nodes[i]) > 4.0 and k != c)
        path = self.bad_msh("non_manifold", nodes, [list(t) for t in tris] + [[a, b, far]])
        lo, hi = min(a, b) + 1, max(a, b) + 1
        self.expect_both_fail(path, ["non-manifold", f"nodes {lo} and {hi}"])

    def test_catalogue_unsupported_element_type(self):
        pts = [(0, 0, 0), (10, 0, 0), (10, 10, 0), (0, 10, 0), (5, 0, 0), (10, 5, 0),
               (5, 10, 0), (0, 5, 0)]
        path = self.bad_msh("quad9", pts + [(5, 5, 0)], [list(range(9))], types=[10])
        self.expect_both_fail(path, ["unsupported", "quad9"])

    def test_catalogue_mixed_orders(self):
        nodes, tris = box_grid()
        nodes = [list(p) for p in nodes]
        a, b, c = (int(k) for k in tris[0])
        mids = []
        for p, q in ((a, b), (b, c), (c, a)):
            nodes.append([0.5 * (nodes[p][d] + nodes[q][d]) for d in range(3)])
            mids.append(len(nodes) - 1)
        elems = [[a, b, c] + mids] + [list(t) for t in tris[1:]]
        path = self.bad_msh("mixed_orders", nodes, elems)
        self.expect_both_fail(path, ["mixes element orders", "tri6"])

    def test_catalogue_nodes_off_the_shape(self):
        nodes, tris = box_grid()
        i = interior_node(nodes)
        n = nodes.copy()
        d = next(d for d in range(3) if n[i][d] in (0.0, 10.0))
        n[i][d] += 1.0 if n[i][d] == 10.0 else -1.0
        path = self.bad_msh("off_shape", n, tris)
        self.expect_both_fail(path, ["farther than the tolerance", f"node {i + 1}"])

    def test_catalogue_shapes_with_free_faces_or_poles_work(self):
        import MeshPart

        for name, shape in (("face", Part.makePlane(10, 10)), ("sphere", Part.makeSphere(4))):
            with self.subTest(shape=name):
                brep = os.path.join(self.tmp.name, name + ".brep")
                shape.exportBrep(brep)
                stl = os.path.join(self.tmp.name, name + ".stl")
                MeshPart.meshFromShape(Shape=shape, LinearDeflection=0.1,
                                       AngularDeflection=0.4).write(stl)
                p, out, report = self.run_cli("optimize", brep, stl, "-o", "{out}",
                                              "--report", "{report}", "--max-sweeps", "5")
                self.assertEqual(p.returncode, 0, (p.stdout + p.stderr)[-2000:])
                import json

                with open(report) as f:
                    rep = json.load(f)
                self.assertLessEqual(rep["after"]["tangled"], rep["before"]["tangled"])
                if name == "sphere":
                    self.assertGreater(rep["bridge"]["pole_nodes"], 0)


if __name__ == "__main__":
    unittest.main()
