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


class NodeColors(unittest.TestCase):
    """Second-order meshes are colored per node: each node in the color of the worst element
    around it, the same from the values (color_by_metric) as from the stored colors (a
    document opened again)."""

    def mesh(self):
        import Fem

        from SurfMesh.app import conversion

        # three tria6 in a row: 1 and 2 share the side 2-3, 2 and 3 the side 2-4
        fm = Fem.FemMesh()
        xy = {1: (0, 0), 2: (2, 0), 3: (1, 2), 4: (3, 2), 5: (4, 0)}
        for n, (x, y) in xy.items():
            fm.addNode(float(x), float(y), 0.0, n)
        corners = {1: (1, 2, 3), 2: (2, 4, 3), 3: (2, 5, 4)}
        mid = {}
        for e, c in corners.items():
            for a, b in zip(c, c[1:] + c[:1]):
                if (b, a) not in mid:
                    mid[a, b] = 100 + len(mid)
                    pa, pb = np.array(xy[a]), np.array(xy[b])
                    fm.addNode(*map(float, (pa + pb) / 2), 0.0, mid[a, b])
        for e, c in corners.items():
            sides = [mid.get((a, b), mid.get((b, a))) for a, b in zip(c, c[1:] + c[:1])]
            fm.addFace(list(c) + sides, e)
        return conversion.read_mesh(fm), mid

    def test_worst_element_colors_each_node(self):
        data, mid = self.mesh()
        values = np.array([3.0, 1.5, math.nan])  # aspect ratios: beyond 2, within, n/a
        rgb = MR.metric_rgb("aspect_ratio", values, 2.0)
        nodes = MR.node_rgb(data, rgb, MR.badness("aspect_ratio", values))
        color = {int(n): tuple(c) for n, c in zip(data.node_ids, nodes)}
        for n in (1, 2, 3, mid[1, 2], mid[2, 3], mid[3, 1]):  # element 1's: red all over
            np.testing.assert_allclose(color[n], MR.BEYOND_RGB)
        for n in (4, mid[4, 3], mid[2, 4]):  # element 2's own, beside n/a element 3
            np.testing.assert_allclose(color[n], rgb[1])
        for n in (5, mid[2, 5], mid[5, 4]):  # element 3's alone: n/a
            np.testing.assert_allclose(color[n], MR.NA_RGB)
        # from the stored colors, as saved (8 bits a channel): the same
        saved = np.round(rgb * 255) / 255
        again = MR.node_rgb(data, saved, MR.color_rank(saved))
        np.testing.assert_allclose(again, nodes, atol=1 / 255)

    def test_color_rank_orders_as_the_values(self):
        values = np.array([61.0, 55.0, 40.0, 30.0, 29.0, 10.0, math.nan])  # smallest angles
        rgb = np.round(MR.metric_rgb("min_angle", values, 30.0) * 255) / 255
        rank = MR.color_rank(rgb)
        self.assertEqual(list(np.argsort(-rank, kind="stable")[:5]), [4, 5, 3, 2, 1])
        self.assertEqual(rank[-1], -1.0)
        self.assertAlmostEqual(rank[0], 0.0, places=2)  # green: the best value


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
