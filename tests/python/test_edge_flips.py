"""Edge flips (topology="flip") through the Python API and the FreeCAD document: the result
object, its element node lists, undo, and the quality judged without SurfMesh
(run: freecadcmd -t test_edge_flips)."""

import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T


def fan_of_slivers():
    """The square [0, 10]² meshed as two fans of slivers: 11 nodes on each of the edges
    y = 0 and y = 10, every bottom node joined to the top-left corner and every top node to
    the bottom-right one (every node on a CAD edge: node motion alone cannot improve it).
    Returns (nodes (22, 3), triangles (20, 3))."""
    nodes = [(float(i), 0.0, 0.0) for i in range(11)] + [(float(i), 10.0, 0.0)
                                                          for i in range(11)]
    tris = [(i, i + 1, 11) for i in range(10)] + [(10, 12 + j, 11 + j) for j in range(10)]
    return np.array(nodes), np.array(tris)


def square(doc):
    import Part

    part = doc.addObject("Part::Feature", "Square")
    part.Shape = Part.makePlane(10, 10)
    doc.recompute()
    return part


def fem_of(doc, nodes, tris, first_element=101):
    import Fem

    fem = Fem.FemMesh()
    for i, (x, y, z) in enumerate(nodes.tolist()):
        fem.addNode(x, y, z, i + 1)
    for k, t in enumerate(tris.tolist()):
        fem.addFace([int(n) + 1 for n in t], first_element + k)
    obj = doc.addObject("Fem::FemMeshObject", "FanMesh")
    obj.FemMesh = fem
    return obj


def independent_quality(points, tris, face):
    q, tangled = T.reference_tri_quality(np.asarray(points, dtype=float), np.asarray(tris), face)
    return q, tangled


class TestEdgeFlips(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshFlips")
        self.doc.UndoMode = 1

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_fem_document_workflow_with_rewired_elements(self):
        part = square(self.doc)
        face = part.Shape.Faces[0]
        nodes, tris = fan_of_slivers()
        obj = fem_of(self.doc, nodes, tris)
        self.doc.recompute()
        snap = T.fem_snapshot(obj.FemMesh)
        names = {o.Name for o in self.doc.Objects}
        q0, t0 = independent_quality(nodes, tris, face)
        self.assertFalse(t0.any())
        # Node motion alone: every node is on a CAD edge, nothing changes.
        plain = SurfMesh.optimize(obj, part)
        self.assertEqual(plain.flips, 0)
        self.assertAlmostEqual(plain.after.stats["min"], q0.min(), places=6)

        new = SurfMesh.optimize_object(obj, shape=part, topology="flip")
        run = dict(new.SurfMeshRun)
        self.assertEqual(run["topology"], "flip")
        flips = int(run["flips"])
        self.assertGreater(flips, 0)
        rewired = [int(e) for e in run["rewired_elements"].split()]
        fem = new.FemMesh
        # Ids, node positions and element count kept; only the rewired lists changed.
        self.assertEqual(sorted(fem.Faces), sorted(obj.FemMesh.Faces))
        self.assertEqual({k: tuple(v) for k, v in fem.Nodes.items()},
                         {k: tuple(v) for k, v in obj.FemMesh.Nodes.items()})
        changed = [e for e in fem.Faces
                   if tuple(fem.getElementNodes(e)) != tuple(obj.FemMesh.getElementNodes(e))]
        self.assertEqual(sorted(changed), sorted(rewired))
        # Judged without SurfMesh: every element valid (wound along the face's normal), the
        # worst far better, and the stored report says the same.
        ids = sorted(fem.Faces)
        new_tris = np.array([[n - 1 for n in fem.getElementNodes(e)] for e in ids])
        q1, t1 = independent_quality(nodes, new_tris, face)
        self.assertFalse(t1.any())
        self.assertGreater(q1.min(), 1.5 * q0.min())
        stats = SurfMesh.stats_of(new)
        self.assertAlmostEqual(stats["min"], q1.min(), places=9)
        self.assertEqual(stats["tangled"], 0)
        self.assertEqual(len(new.SurfMeshColors), len(ids))
        # The original is unchanged; undo removes the result.
        self.assertEqual(T.fem_snapshot(obj.FemMesh), snap)
        self.doc.undo()
        self.assertEqual({o.Name for o in self.doc.Objects}, names)

    def test_mesh_feature_facets_rewired_points_and_segments_kept(self):
        import Mesh

        part = square(self.doc)
        face = part.Shape.Faces[0]
        nodes, tris = fan_of_slivers()
        vec = FreeCAD.Vector
        mesh = Mesh.Mesh(([vec(*p) for p in nodes.tolist()], [tuple(t) for t in tris.tolist()]))
        mesh.addSegment(list(range(10)))
        res = SurfMesh.optimize(mesh, part, topology="flip")
        self.assertGreater(res.flips, 0)
        pts, facets = res.mesh.Topology
        self.assertEqual(len(facets), len(tris))
        np.testing.assert_array_equal(np.array([[p.x, p.y, p.z] for p in pts]), nodes)
        changed = [k for k in range(len(tris)) if tuple(facets[k]) != tuple(tris[k])]
        self.assertEqual(changed, res.rewired_elements)
        self.assertEqual(res.mesh.countSegments(), 1)
        self.assertEqual(list(res.mesh.getSegment(0)), list(range(10)))
        q1, t1 = independent_quality(nodes, np.array(facets), face)
        self.assertFalse(t1.any())
        self.assertAlmostEqual(res.after.stats["min"], q1.min(), places=6)
        self.assertEqual(res.options["topology"], "flip")

    def test_bad_topology_is_refused_before_anything_runs(self):
        part = square(self.doc)
        nodes, tris = fan_of_slivers()
        obj = fem_of(self.doc, nodes, tris)
        names = {o.Name for o in self.doc.Objects}
        with self.assertRaisesRegex(ValueError, "topology must be 'none' or 'flip'"):
            SurfMesh.optimize_object(obj, shape=part, topology="swap")
        self.assertEqual({o.Name for o in self.doc.Objects}, names)


if __name__ == "__main__":
    unittest.main()
