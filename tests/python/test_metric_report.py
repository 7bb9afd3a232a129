"""Colors by an element metric and the per-metric report, headless: the color scale at the
ideal value, at the threshold and beyond it; what color_by_metric stores, in one undo step,
and what coloring by quality or clearing the colors removes; the count beyond a threshold and
the CSV against values computed here.

Run by scripts/test.sh (``freecadcmd -t test_metric_report -M tests/python``).
"""

import csv
import math
import os
import unittest

import FreeCAD as App
import numpy as np

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import metric_report as MR


class Scale(unittest.TestCase):
    def test_rgb_at_ideal_threshold_beyond_and_na(self):
        rgb = MR.metric_rgb("aspect_ratio", [1.0, 5.5, 10.0, 10.5, math.inf, math.nan], 10.0)
        np.testing.assert_allclose(rgb[0], MR.GOOD_RGB)
        np.testing.assert_allclose(rgb[1], (np.array(MR.GOOD_RGB) + MR.LIMIT_RGB) / 2)
        np.testing.assert_allclose(rgb[2], MR.LIMIT_RGB)  # at the threshold: not beyond
        np.testing.assert_allclose(rgb[3], MR.BEYOND_RGB)
        np.testing.assert_allclose(rgb[4], MR.BEYOND_RGB)  # degenerate: beyond any threshold
        np.testing.assert_allclose(rgb[5], MR.NA_RGB)
        # a metric that gets worse downwards, without an ideal value: the best value is green
        rgb = MR.metric_rgb("min_angle", [60.0, 45.0, 30.0, 10.0], 30.0)
        np.testing.assert_allclose(rgb[0], MR.GOOD_RGB)
        np.testing.assert_allclose(rgb[2], MR.LIMIT_RGB)
        np.testing.assert_allclose(rgb[3], MR.BEYOND_RGB)


class Document(unittest.TestCase):
    def setUp(self):
        self.doc = App.newDocument("SurfMeshMetricReport")
        self.doc.UndoMode = 1

    def tearDown(self):
        App.closeDocument(self.doc.Name)

    def test_color_by_metric_undo_and_back_to_quality(self):
        tor, mesh = T.torus_fem(self.doc, tangled=False)
        self.doc.recompute()
        fem = mesh.FemMesh
        ids = sorted(fem.Faces)
        # the smallest angle of every triangle, by the law of cosines
        ref = []
        for e in ids:
            p = [np.array(tuple(fem.getNodeById(n))) for n in fem.getElementNodes(e)[:3]]
            a, b, c = (np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[1]),
                       np.linalg.norm(p[0] - p[2]))
            ref.append(min(math.degrees(math.acos((y * y + z * z - x * x) / (2 * y * z)))
                           for x, y, z in ((a, b, c), (b, c, a), (c, a, b))))
        ref = np.array(ref)
        t = float(np.quantile(ref, 0.25))
        undo0 = self.doc.UndoCount
        beyond = SurfMesh.color_by_metric(mesh, "min_angle", t, shape=tor)
        self.assertEqual(beyond, int((ref < t).sum()))
        self.assertEqual(self.doc.UndoCount, undo0 + 1)
        self.assertEqual(MR.colored_by(mesh), ("min_angle", t))
        red = np.all(np.isclose([c[:3] for c in mesh.SurfMeshColors], MR.BEYOND_RGB), axis=1)
        np.testing.assert_array_equal(red, ref < t)
        self.doc.undo()
        self.assertIsNone(MR.colored_by(mesh))
        self.doc.redo()
        self.assertEqual(MR.colored_by(mesh), ("min_angle", t))
        SurfMesh.measure_object(mesh, tor)  # quality colors again
        self.assertIsNone(MR.colored_by(mesh))
        self.assertNotIn("SurfMeshColorBy", mesh.PropertiesList)
        SurfMesh.color_by_metric(mesh, "min_angle", t, shape=tor)
        SurfMesh.clear_colors(mesh)
        self.assertNotIn("SurfMeshThreshold", mesh.PropertiesList)
        with self.assertRaisesRegex(ValueError, "unknown metric"):
            SurfMesh.color_by_metric(mesh, "angle", 30, shape=tor)

    def test_report_stats_and_csv(self):
        tor, mesh = T.torus_fem(self.doc, tangled=False)
        self.doc.recompute()
        rep = MR.metric_report(mesh, tor, ["aspect_ratio", "warpage"])
        v = rep.values["aspect_ratio"]
        s = rep.stats("aspect_ratio", 1.2)
        self.assertEqual(s["beyond"], int((v > 1.2).sum()))
        self.assertEqual(rep.stats("warpage")["not_applicable"], len(v))  # triangles only
        path = os.path.join(T.output_dir(), "metric_report.csv")
        rep.write_csv(path)
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([int(r["element_id"]) for r in rows], sorted(mesh.FemMesh.Faces))
        np.testing.assert_allclose([float(r["aspect_ratio"]) for r in rows], v, rtol=1e-9)
        self.assertIn("Aspect ratio", rep.table_html())
        fig = rep.histogram_figure("aspect_ratio", 1.2)
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        self.assertIn(f"> 1.200: {s['beyond']} elements", labels[1])


if __name__ == "__main__":
    unittest.main()
