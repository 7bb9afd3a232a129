"""Document functions: measure_object / optimize_object / clear_colors, stored stats, colors,
undo, cancel (run: freecadcmd -t)."""

import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import coloring


class DocumentCase(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshDocTest")
        self.doc.UndoMode = 1

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)


class TestDocument(DocumentCase):
    def test_measure_object_stores_stats_and_colors(self):
        tor, mobj = T.torus_mesh(self.doc, deflection=0.3)
        mobj.Label = "Torus (Meshed)"  # as MeshPart's task panel names it: finds "Torus"
        rep = SurfMesh.measure_object(mobj, measure="oddy")
        self.assertEqual(mobj.SurfMeshMeasure, "oddy")
        stats = SurfMesh.stats_of(mobj)
        for k in ("min", "max", "mean", "std"):
            self.assertAlmostEqual(stats[k], rep.stats[k], places=12)
        self.assertEqual(stats["elements"], mobj.Mesh.CountFacets)
        np.testing.assert_allclose(mobj.SurfMeshQuality, rep.quality)
        colors = np.array([c[:3] for c in mobj.SurfMeshColors])
        self.assertEqual(len(colors), mobj.Mesh.CountFacets)
        np.testing.assert_allclose(colors, coloring.quality_rgb(rep.quality, rep.tangled),
                                   atol=1e-6)

    def test_optimize_object_one_transaction_and_undo(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        self.doc.recompute()
        names = {o.Name for o in self.doc.Objects}
        undo0 = self.doc.UndoCount
        snap = T.fem_snapshot(mesh.FemMesh)
        new = SurfMesh.optimize_object(mesh, shape=tor, measure="shape")
        self.assertEqual(new.Name, "TorusMesh_optimized")
        self.assertEqual(self.doc.UndoCount, undo0 + 1)
        self.assertEqual(self.doc.UndoNames[0], "SurfMesh optimize")
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), snap)  # original kept
        before, after = SurfMesh.stats_of(new, before=True), SurfMesh.stats_of(new)
        self.assertGreater(before["tangled"], 0)
        self.assertEqual(after["tangled"], 0)
        self.assertEqual(len(new.SurfMeshColors), len(new.FemMesh.Faces))
        self.assertIs(new.SurfMeshOriginal, mesh)
        self.assertIs(new.SurfMeshSource, tor)
        # a second measure finds the shape through the stored link
        rep = SurfMesh.measure_object(new)
        self.assertEqual(rep.stats["tangled"], 0)
        self.doc.undo()  # the measure
        self.doc.undo()  # the optimization
        self.assertEqual({o.Name for o in self.doc.Objects}, names)

    def test_cracked_standard_mesh_object_glued(self):
        """A MeshPart standard mesh of the crank arm has twin nodes along CAD edges (a crack):
        optimize_object keeps each pair together; with duplicates="error" it refuses and
        leaves the document as it was."""
        import Part

        path = T.find_part("occt_crankarm.brep")
        if path is None:
            self.skipTest("occt_crankarm.brep not found")
        part = self.doc.addObject("Part::Feature", "CrankArm")
        part.Shape = Part.read(path)
        diag = part.Shape.BoundBox.DiagonalLength
        mobj = self.doc.addObject("Mesh::Feature", "CrankArmMesh")
        mobj.Mesh = T.standard_mesh_with_cracks(part.Shape, LinearDeflection=diag / 500,
                                                AngularDeflection=0.35, Relative=False)
        self.doc.recompute()
        pts0 = np.array([[p.x, p.y, p.z] for p in mobj.Mesh.Points])
        groups = T.coincident_groups(pts0)
        self.assertGreater(len(groups), 0, "no twin nodes in this mesh any more")
        names = {o.Name for o in self.doc.Objects}
        undo0 = self.doc.UndoCount
        with self.assertRaisesRegex(ValueError, "duplicate node"):
            SurfMesh.optimize_object(mobj, shape=part, boundary="slide", duplicates="error")
        self.assertEqual({o.Name for o in self.doc.Objects}, names)
        self.assertEqual(self.doc.UndoCount, undo0)
        new = SurfMesh.optimize_object(mobj, shape=part, boundary="slide")
        pts = np.array([[p.x, p.y, p.z] for p in new.Mesh.Points])
        twins = np.concatenate(groups)
        self.assertTrue(np.any(pts[twins] != pts0[twins]), "no twin node moved")
        for idx in groups:
            np.testing.assert_array_equal(pts[idx], np.repeat(pts[idx[:1]], len(idx), axis=0))
        self.assertEqual(SurfMesh.stats_of(new)["tangled"], 0)

    def test_gmsh_mesh_finds_its_part(self):
        from SurfMesh.app import examples

        tor = examples.make_torus(self.doc)
        mesh = examples.make_gmsh_mesh(self.doc, tor, 3.0)
        rep = SurfMesh.measure_object(mesh)  # shape from FemMeshGmsh.Part
        self.assertEqual(rep.stats["tangled"], 0)

    def test_cancel_leaves_document_unchanged(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        self.doc.recompute()
        names = {o.Name for o in self.doc.Objects}
        undo0 = self.doc.UndoCount
        with self.assertRaises(SurfMesh.Cancelled):
            SurfMesh.optimize_object(mesh, shape=tor, progress_callback=lambda info: False)
        self.assertEqual({o.Name for o in self.doc.Objects}, names)
        self.assertEqual(self.doc.UndoCount, undo0)

    def test_error_leaves_document_unchanged(self):
        tor, mesh = T.torus_fem(self.doc, tangled=False)
        names = {o.Name for o in self.doc.Objects}
        with self.assertRaises(ValueError):
            SurfMesh.optimize_object(mesh, shape=tor, measure="unknown")
        with self.assertRaises(ValueError):
            SurfMesh.optimize_object(mesh, shape=tor, max_sweeps=-1)
        self.assertEqual({o.Name for o in self.doc.Objects}, names)

    def test_clear_colors(self):
        tor, mobj = T.torus_mesh(self.doc, deflection=0.3)
        SurfMesh.measure_object(mobj, tor)
        self.assertIn("SurfMeshColors", mobj.PropertiesList)
        SurfMesh.clear_colors(mobj)
        self.assertNotIn("SurfMeshColors", mobj.PropertiesList)
        self.assertIsNotNone(SurfMesh.stats_of(mobj))  # stats kept

    def test_tangled_elements_in_user_ids_changes_nothing(self):
        """tangled_elements names the tangled elements by their FEM ids (reference: FreeCAD's
        face normal against each triangle's), with their centroids and CAD faces, and leaves
        the document as it was."""
        from SurfMesh.app.document import tangled_elements

        tor, mesh = T.torus_fem(self.doc, tangled=True)
        self.doc.recompute()
        undo0, props0 = self.doc.UndoCount, sorted(mesh.PropertiesList)
        snap = T.fem_snapshot(mesh.FemMesh)
        pick = tangled_elements(mesh, tor, measure="shape")
        self.assertEqual(self.doc.UndoCount, undo0)
        self.assertEqual(sorted(mesh.PropertiesList), props0)
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), snap)
        fem = mesh.FemMesh
        faces = sorted(fem.Faces)
        ids = sorted(fem.Nodes)
        row = {n: i for i, n in enumerate(ids)}
        nodes = np.array([tuple(fem.Nodes[n]) for n in ids])
        tris = np.array([[row[n] for n in fem.getElementNodes(e)] for e in faces])
        _, ref = T.reference_tri_quality(nodes, tris, tor.Shape.Faces[0])
        expected = [faces[k] for k in np.nonzero(ref)[0]]
        self.assertGreater(len(expected), 0)
        self.assertEqual(pick.kind, "tangled")
        self.assertEqual(pick.ids, expected)
        self.assertEqual(pick.ids, [int(i) for i in pick.report.element_ids[pick.report.tangled]])
        self.assertEqual(pick.faces, ["Face1"] * len(expected))
        self.assertEqual(pick.quality, [0.0] * len(expected))
        for e, c, corners in zip(pick.ids, pick.centers, pick.corners):
            pts = np.array([tuple(fem.getNodeById(n)) for n in fem.getElementNodes(e)])
            np.testing.assert_allclose(c, pts.mean(axis=0), rtol=0, atol=1e-12)
            np.testing.assert_allclose(corners, pts[:3], rtol=0, atol=1e-12)
        text = pick.summary()
        self.assertIn(f"{len(expected)} tangled elements (shape measure)", text)
        self.assertIn(f"the first, element {expected[0]}, lies near (", text)
        self.assertTrue(text.endswith("on Face1"), text)
        np.testing.assert_array_equal(pick.report.element_faces, 0)  # one face: Face1

    def test_tangled_elements_worst_when_none_tangled(self):
        """Without tangled elements: the WORST_ELEMENTS lowest qualities, worst first, by
        0-based facet index for a Mesh (as FreeCAD numbers facets)."""
        from SurfMesh.app.document import WORST_ELEMENTS, tangled_elements

        tor, mobj = T.torus_mesh(self.doc, deflection=0.3)
        snap = T.mesh_snapshot(mobj.Mesh)
        pick = tangled_elements(mobj, tor)
        self.assertEqual(T.mesh_snapshot(mobj.Mesh), snap)
        self.assertNotIn("SurfMeshQuality", mobj.PropertiesList)
        self.assertEqual(pick.kind, "worst")
        self.assertEqual(pick.mesh_kind, "mesh")
        self.assertEqual(len(pick.ids), WORST_ELEMENTS)
        q = pick.report.quality
        self.assertEqual(pick.ids, pick.indices)  # facet indices
        self.assertEqual(pick.quality, sorted(pick.quality))
        others = np.delete(q, pick.indices)
        self.assertLessEqual(max(pick.quality), others.min())
        facet = mobj.Mesh.Facets[pick.ids[0]]
        np.testing.assert_allclose(pick.centers[0], np.mean(facet.Points, axis=0), atol=1e-6)
        self.assertIn(f"no tangled facet (shape measure); the {WORST_ELEMENTS} worst",
                      pick.summary())
        self.assertEqual(len(tangled_elements(mobj, tor, worst=3).ids), 3)
        with self.assertRaises(ValueError):
            tangled_elements(mobj, tor, worst=0)
        with self.assertRaises(ValueError):  # no shape known for a Mesh feature
            tangled_elements(mobj)

    def test_report_object(self):
        import os

        tor, mesh = T.torus_fem(self.doc, tangled=True)
        new = SurfMesh.optimize_object(mesh, shape=tor)
        png = os.path.join(T.output_dir(), "report_test.png")
        if os.path.exists(png):
            os.remove(png)
        rep = SurfMesh.app.document.report_object(new, histogram=png)
        labels = [(m, lab) for m, lab, _ in rep["rows"]]
        self.assertEqual(labels, [("shape", "Initial"), ("shape", "Optimized"),
                                  ("oddy", "Initial"), ("oddy", "Optimized")])
        self.assertGreater(rep["rows"][0][2]["tangled"], 0)
        self.assertEqual(rep["rows"][1][2]["tangled"], 0)
        self.assertIn("Tang. el.", rep["text"])
        with open(png, "rb") as fh:
            self.assertEqual(fh.read(8), b"\x89PNG\r\n\x1a\n")


    def test_left_out_elements_are_not_counted_as_poor_or_tangled(self):
        # A collapsed element (a repeated node, as Gmsh leaves where it merged nodes) is left
        # out of the measure: stored as -1, not 0 (tangled), drawn grey, not in the histogram.
        from SurfMesh.app import document, reports

        tor, mesh = T.torus_fem(self.doc, tangled=False)
        fem = mesh.FemMesh.copy()
        eid = max(fem.Faces) + 1
        a, b, _ = fem.getElementNodes(min(fem.Faces))
        fem.addFace([a, b, a], eid)
        mesh.FemMesh = fem
        rep = SurfMesh.measure_object(mesh, shape=tor)
        k = list(rep.element_ids).index(eid)
        self.assertTrue(rep.skipped[k])
        self.assertEqual(int(rep.skipped.sum()), 1)
        stored = np.asarray(mesh.SurfMeshQuality)
        self.assertEqual(stored[k], -1.0)
        self.assertTrue(np.all(stored[np.arange(len(stored)) != k] > 0.0))
        colors = np.array([c[:3] for c in mesh.SurfMeshColors])
        np.testing.assert_allclose(colors[k], coloring.SKIPPED_RGB, atol=1e-6)
        self.assertFalse(np.allclose(colors[np.arange(len(colors)) != k], coloring.SKIPPED_RGB,
                                     atol=1e-3))
        # the colors rebuilt from the stored quality (apply_colors without a report) agree
        rgb = SurfMesh.apply_colors(mesh)
        np.testing.assert_allclose(rgb, colors, atol=1e-6)
        # the histogram's data: the measured elements only (their mean is the stats' mean)
        rows, series = document.report_rows(mesh, measures=["shape"], shape=tor)
        q = np.asarray(series[0][1])
        self.assertEqual(len(q), len(stored) - 1)
        self.assertAlmostEqual(float(q.mean()), rep.stats["mean"], places=9)
        fig = reports.histogram_figure([("stored", mesh.SurfMeshQuality, 0)])
        counts = sum(p.get_height() for p in fig.axes[0].patches)
        self.assertEqual(counts, len(stored) - 1)

class TestImports(unittest.TestCase):
    def test_headless_layer_never_imports_gui(self):
        # FEM's import test idea: the headless modules import with the GUI down, and their
        # source imports neither FreeCADGui nor PySide.
        import ast
        import importlib
        import os
        import pkgutil

        import SurfMesh.app as app

        for info in pkgutil.iter_modules(app.__path__):
            mod = importlib.import_module(f"SurfMesh.app.{info.name}")
            tree = ast.parse(open(mod.__file__, encoding="utf-8").read())
            for node in ast.walk(tree):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    names = [node.module or ""]
                for n in names:
                    self.assertFalse(n.startswith(("FreeCADGui", "PySide")),
                                     f"{info.name} imports {n}")
        cli = os.path.join(os.path.dirname(SurfMesh.__file__), "cli", "surfmesh_cli.py")
        self.assertNotIn("FreeCADGui", open(cli, encoding="utf-8").read())


if __name__ == "__main__":
    unittest.main()
