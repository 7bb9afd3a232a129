"""Gmsh FEM meshes of real parts (run: freecadcmd -t): the bridge's node classification agrees
with FreeCAD's node queries (FemMesh.getNodesByFace/Edge/Vertex), and occt_crankarm, where Gmsh
itself leaves invalid elements, is untangled."""

import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import api, examples


class GmshCase(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshGmshTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def part(self, name):
        import Part

        path = T.find_part(name)
        if path is None:
            self.skipTest(f"{name} not available")
        obj = self.doc.addObject("Part::Feature", name.split(".")[0])
        obj.Shape = Part.read(path)
        return obj

    def check_classification(self, part, mesh):
        shape = part.Shape
        data, handle = api.prepare(mesh, shape, hints="none")  # the core's own search only
        fem = mesh.FemMesh
        cls = np.asarray(handle.report["node_class"])
        ent = np.asarray(handle.report["node_entity"])
        ids = data.node_ids
        on_face = [set(fem.getNodesByFace(f)) for f in shape.Faces]
        on_edge = [set(fem.getNodesByEdge(e)) for e in shape.Edges]
        on_vertex = [set(fem.getNodesByVertex(v)) for v in shape.Vertexes]
        # seams: in a closed shell, the edges bounding a single face
        seams = set()
        for k, e in enumerate(shape.Edges):
            faces = shape.ancestorsOfType(e, __import__("Part").Face)
            if len(faces) == 1:
                seams.update((k, j) for j, f in enumerate(shape.Faces) if f.isSame(faces[0]))
        counts = {0: 0, 1: 0, 2: 0}
        for i, nid in enumerate(ids.tolist()):
            c, k = int(cls[i]), int(ent[i])
            if c == 3:
                continue
            counts[c] += 1
            if c == 0:
                self.assertIn(nid, on_vertex[k], f"node {nid}: vertex {k}")
            elif c == 1:
                self.assertIn(nid, on_edge[k], f"node {nid}: edge {k}")
            else:
                self.assertIn(nid, on_face[k], f"node {nid}: face {k}")
                # a face node FreeCAD also finds on an edge must be on a seam of that face
                for j, es in enumerate(on_edge):
                    if nid in es:
                        self.assertIn((j, k), seams, f"face node {nid} on non-seam edge {j}")
        # and conversely: every node FreeCAD puts on a vertex where several faces meet is a
        # vertex node of the bridge (a vertex inside one face, where seams cross, need not be)
        import Part

        for k, vs in enumerate(on_vertex):
            if len(shape.ancestorsOfType(shape.Vertexes[k], Part.Face)) < 2:
                continue
            for nid in vs:
                i = int(np.searchsorted(ids, nid))
                self.assertEqual(int(cls[i]), 0, f"node {nid} on vertex {k}")
        self.assertGreater(counts[2], 0)
        return counts

    def test_classification_screw(self):
        part = self.part("occt_screw.step")
        mesh = examples.make_gmsh_mesh(self.doc, part, part.Shape.BoundBox.DiagonalLength / 25)
        counts = self.check_classification(part, mesh)
        self.assertGreater(counts[1], 0)
        self.assertGreater(counts[0], 0)

    def test_classification_torus_seams(self):
        tor = examples.make_torus(self.doc)
        mesh = examples.make_gmsh_mesh(self.doc, tor, 2.0)
        counts = self.check_classification(tor, mesh)
        self.assertEqual(counts[1], 0)  # the torus's two edges are seams: inside the face

    def test_tolerance_hints_match_freecads_queries(self):
        # hints="auto" lets the core hint every node within a CAD vertex's or a single CAD
        # edge's own tolerance (FreeCAD's rule); the same hints from FreeCAD's own queries
        # (FemMesh.getNodesByVertex/Edge, hints="given") give the same classification and the
        # same elements left out. The crank arm's second-order mesh has a CAD feature smaller
        # than the elements, where the hints decide which slivers lie along a CAD edge.
        from SurfMesh.app import conversion

        for name, order in (("occt_crankarm.brep", "2nd"), ("occt_screw.step", "1st")):
            part = self.part(name)
            mesh = examples.make_gmsh_mesh(
                self.doc, part, part.Shape.BoundBox.DiagonalLength / 25, order=order
            )
            d_core, h_core = api.prepare(mesh, part.Shape, hints="auto")
            data = conversion.read_mesh(mesh)
            conversion.fem_hints(data, part.Shape, faces=False)
            self.assertGreater(int((data.hint_edge >= 0).sum()), 0)
            d_fc, h_fc = api.prepare(data, part.Shape, hints="given")
            r_core, r_fc = h_core.report, h_fc.report
            np.testing.assert_array_equal(r_core["node_class"], r_fc["node_class"], name)
            np.testing.assert_array_equal(r_core["node_entity"], r_fc["node_entity"], name)
            self.assertEqual(r_core.get("skipped_elements", []), r_fc.get("skipped_elements", []))
            self.assertEqual(r_core["hints_rejected"], 0)

    def test_crankarm_untangled(self):
        part = self.part("occt_crankarm.brep")
        mesh = examples.make_gmsh_mesh(self.doc, part, 1e22)
        self.assertIn("invalid", mesh.GmshMessages)  # Gmsh says it left invalid elements
        res = SurfMesh.optimize(mesh, part, measure="shape", boundary="fixed")
        # Gmsh's invalid elements are either untangled or, when no node movement can repair
        # them (a repeated node, a sliver along one CAD edge, two nodes on one CAD vertex),
        # left out and reported: nothing measured stays tangled.
        self.assertGreater(res.before.stats["tangled"] + res.before.stats["skipped"], 0)
        self.assertTrue(any("left out" in w for w in res.before.bridge["warnings"]))
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreater(res.after.stats["min"], 0.0)
        skipped = res.before.skipped
        self.assertEqual(res.before.stats["skipped"], int(skipped.sum()))
        self.assertLess(int(skipped.sum()), res.before.quality.size // 5)
        # every skipped element really is collapsed or flat: zero area in the input
        data = SurfMesh.app.conversion.read_mesh(mesh)
        for e in np.nonzero(skipped)[0][:50]:
            x = data.nodes[data.element(e)]
            area = 0.5 * np.linalg.norm(np.cross(x[1] - x[0], x[2] - x[0]))
            self.assertLess(area, 1e-2 * np.sum((x[1] - x[0]) ** 2) + 1e-12)
        # optimized nodes lie on the part
        pts = res.nodes[:: max(1, len(res.nodes) // 200)]
        self.assertLess(T.distance_to_shape(part.Shape, pts).max(), 2e-3)


if __name__ == "__main__":
    unittest.main()
