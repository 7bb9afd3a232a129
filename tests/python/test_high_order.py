"""High-order and quadrilateral meshes end to end (run: freecadcmd -t): a second-order FEM mesh
(tria6) made by Gmsh through FreeCAD, measured, tangled and optimized, with per-node colors;
Gmsh .msh files of order 3, 5 triangles and of quads measured and optimized through the CLI.

Independent references: a straight-sided tria6 (a planar face: Gmsh puts the mid-edge nodes at
the midpoints) has exactly the planar shape quality of its corner triangle, 4√3·A/Σl²; nodes
of the optimized meshes are checked on the torus with its closed-form distance."""

import json
import os
import shutil
import subprocess
import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import coloring, conversion, document, examples

R, r = 10.0, 4.0


def run_cli(*args):
    cmd = ["freecadcmd", T.cli_path(), "--"] + [str(a) for a in args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=900, stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


class HighOrderFem(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshHighOrderTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_straight_tria6_has_the_quality_of_its_linear_triangle(self):
        import Part

        plane = self.doc.addObject("Part::Feature", "Plate")
        plane.Shape = Part.makePlane(20.0, 10.0)
        mesh = examples.make_gmsh_mesh(self.doc, plane, 2.0, name="PlateMesh", order="2nd")
        data = conversion.read_mesh(mesh.FemMesh)
        self.assertTrue(np.all(data.types == conversion.ELEMENT_TYPES["tri6"]))
        rep = SurfMesh.measure(mesh, plane)
        corners = data.conn.reshape(-1, 6)[:, :3]
        ref_q, ref_t = T.reference_tri_quality(data.nodes, corners, plane.Shape.Faces[0])
        self.assertFalse(ref_t.any())
        np.testing.assert_allclose(rep.quality, ref_q, atol=1e-9)
        self.assertEqual(rep.stats["tangled"], 0)

    def test_tria6_torus_untangled_and_colored_by_nodes(self):
        tor = examples.make_torus(self.doc)
        mesh = examples.make_gmsh_mesh(self.doc, tor, 2.0, name="TorusMesh6", order="2nd")
        data0 = conversion.read_mesh(mesh.FemMesh)
        self.assertTrue(np.all(data0.types == conversion.ELEMENT_TYPES["tri6"]))
        # Gmsh's mid-edge nodes are on the torus
        self.assertLess(T.torus_distance(data0.nodes, R, r).max(), 1e-6)
        _, count = examples.tangle_to(mesh, tor.Shape, target=30, seed=2)
        self.assertGreater(count, 10)
        rep = document.measure_object(mesh, tor)
        self.assertEqual(rep.stats["tangled"], count)
        self.assertEqual(document.stats_of(mesh)["tangled"], count)

        new = document.optimize_object(mesh, tor)
        before, after = document.stats_of(new, before=True), document.stats_of(new)
        print(f"\ntria6 torus ({len(data0.types)} elements): "
              f"min {before['min']:.2f}→{after['min']:.2f}  mean {before['mean']:.2f}→"
              f"{after['mean']:.2f}  tangled {before['tangled']}→{after['tangled']}")
        self.assertEqual(before["tangled"], count)
        self.assertEqual(after["tangled"], 0)
        self.assertGreater(after["min"], 0.5)
        self.assertGreater(after["mean"], before["mean"])
        # node ids, element ids and connectivity kept; every node (mid-edge ones included) on
        # the torus to double precision
        n0, e0 = T.fem_snapshot(mesh.FemMesh)
        n1, e1 = T.fem_snapshot(new.FemMesh)
        self.assertEqual(list(n1), list(n0))
        self.assertEqual(e1, e0)
        self.assertLess(T.torus_distance(np.array(list(n1.values())), R, r).max(), 1e-9)
        # an independent re-measure of the new mesh agrees with the stored stats
        again = SurfMesh.measure(new, tor)
        self.assertEqual(again.stats["tangled"], 0)
        self.assertAlmostEqual(again.stats["min"], after["min"], places=9)
        # colors: one per element recorded; tria6 is colored through its nodes (ElementColor
        # draws wrong colors on tria6 in FreeCAD 0.20): every node gets the worst quality of
        # the elements around it, mid-edge nodes included
        self.assertEqual(len(new.SurfMeshColors), len(data0.types))
        data1 = conversion.read_mesh(new.FemMesh)
        node_q = coloring.node_values(data1, again.quality, reduce="min")
        self.assertEqual(len(node_q), data1.node_count)
        conn = data1.conn.reshape(-1, 6)
        for e in (0, len(conn) // 2, len(conn) - 1):
            for k in range(6):
                self.assertLessEqual(node_q[conn[e, k]], again.quality[e] + 1e-15)
        self.assertGreaterEqual(node_q.min(), after["min"] - 1e-12)


class HighOrderGmshFiles(unittest.TestCase):
    """Order-3 and order-5 triangles and quads in Gmsh .msh files, through the CLI."""

    @classmethod
    def setUpClass(cls):
        import Part

        from SurfMesh.app import fileio

        cls.dir = os.path.join(T.output_dir(), "high_order")
        shutil.rmtree(cls.dir, ignore_errors=True)
        os.makedirs(cls.dir)
        cls.brep = os.path.join(cls.dir, "torus.brep")
        Part.makeTorus(R, r).exportBrep(cls.brep)
        gmsh = fileio._gmsh()
        cls.files = {}
        for name, order, quads in (("tri10", 3, False), ("tri21", 5, False), ("quad4", 1, True)):
            gmsh.clear()
            gmsh.model.occ.importShapes(cls.brep)
            gmsh.model.occ.synchronize()
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 4.0 if order > 1 else 2.0)
            gmsh.option.setNumber("Mesh.RecombineAll", 1 if quads else 0)
            gmsh.option.setNumber("Mesh.Algorithm", 6)  # (8 crashes on the torus in 4.8.4)
            gmsh.model.mesh.generate(2)
            if order > 1:
                gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
                gmsh.model.mesh.setOrder(order)
            # tangle: move the face's own nodes (not those on the seam circles) in (u, v)
            tags, coords, _ = gmsh.model.mesh.getNodes(2, -1, includeBoundary=False)
            xyz = np.asarray(coords).reshape(-1, 3)
            u = np.arctan2(xyz[:, 1], xyz[:, 0])
            v = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]) - R)
            rng = np.random.default_rng(11)
            amp = 0.35 / order**2  # high-order nodes are far more sensitive
            u = u + amp * 0.3 * rng.standard_normal(len(u))
            v = v + amp * rng.standard_normal(len(v))
            new = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u),
                            r * np.sin(v)], axis=1)
            for t, p in zip(tags, new):
                gmsh.model.mesh.setNode(int(t), p.tolist(), [])
            gmsh.option.setNumber("Mesh.SaveAll", 1)
            gmsh.option.setNumber("Mesh.Binary", 0)
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            path = os.path.join(cls.dir, name + ".msh")
            gmsh.write(path)
            cls.files[name] = path
        gmsh.clear()
        gmsh.option.setNumber("Mesh.RecombineAll", 0)

    def run_case(self, name):
        from SurfMesh.app import fileio

        src = self.files[name]
        mf = fileio.read_mesh(src)
        types = set(int(t) for t in np.unique(mf.data.types))
        self.assertIn(conversion.ELEMENT_TYPES[name], types)
        out = os.path.join(self.dir, "out_" + name + ".msh")
        rep = os.path.join(self.dir, name + ".json")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep)
        self.assertEqual(code, 0, se)
        data = json.load(open(rep))
        print(f"\n{name}: before {data['before']}\n       after  {data['after']}")
        self.assertGreater(data["before"]["tangled"], 0)
        self.assertEqual(data["after"]["tangled"], 0)
        self.assertGreater(data["after"]["mean"], data["before"]["mean"])
        out_mf = fileio.read_mesh(out)
        np.testing.assert_array_equal(out_mf.data.conn, mf.data.conn)
        self.assertLess(T.torus_distance(out_mf.data.nodes, R, r).max(), 1e-9)
        # re-measured by the CLI: the written file holds the optimized mesh
        rep2 = os.path.join(self.dir, name + "_measure.json")
        code, so, se = run_cli("measure", self.brep, out, "--report", rep2)
        self.assertEqual(code, 0, se)
        self.assertEqual(json.load(open(rep2))["stats"]["tangled"], 0)

    def test_tri10(self):
        self.run_case("tri10")

    def test_tri21(self):
        self.run_case("tri21")

    def test_quad4(self):
        self.run_case("quad4")


if __name__ == "__main__":
    unittest.main()
