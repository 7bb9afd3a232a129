"""What SurfMesh tells a user after a run: numbers below 0.01 keep their significant digits
(a minimum quality of 2.8e-6 must not read "0.00"), the one-line outcome of an optimization
(before → after, sweeps, time) stored with the result and printed on the report view, and
the faces of every picked element.

Run by scripts/test.sh (``freecadcmd -t test_outcome_wording -M tests/python``).
"""

import re
import unittest

import FreeCAD as App
import numpy as np

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import document, reports


class FormatValue(unittest.TestCase):
    def test_small_values_keep_significant_digits(self):
        self.assertEqual(reports.format_value(2.8e-6), "2.8e-06")
        self.assertEqual(reports.format_value(0.0042), "0.0042")
        self.assertEqual(reports.format_value(-0.0031), "-0.0031")
        self.assertEqual(reports.format_value(0.0), "0.00")
        self.assertEqual(reports.format_value(0.85), "0.85")
        self.assertEqual(reports.format_value(0.005), "0.01")  # rounds to a non-zero 0.01
        self.assertEqual(reports.format_value(1.0), "1.00")

    def test_table_and_histogram_legend(self):
        stats = dict(min=2.8e-6, max=1.0, mean=0.85, std=0.2, tangled=0)
        table = reports.format_table([("shape", "m", stats)])
        self.assertIn("2.8e-06", table)
        self.assertNotIn(" 0.00 ", table)
        self.assertIn("2.8e-06", reports.table_html([("shape", "m", stats)]))
        fig = reports.histogram_figure([("after", np.array([2.8e-6, 0.5, 1.0]), 0)])
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        self.assertIn("min 2.8e-06", labels[0])


class Outcome(unittest.TestCase):
    def setUp(self):
        self.doc = App.newDocument("SurfMeshOutcome")
        self.doc.UndoMode = 1

    def tearDown(self):
        App.closeDocument(self.doc.Name)

    def test_outcome_text(self):
        before = dict(min=0.0, max=1.0, mean=0.85, std=0.1, tangled=49, elements=100, across=0)
        after = dict(min=2.8e-6, max=1.0, mean=0.9, std=0.1, tangled=0, elements=100, across=0)
        self.assertEqual(reports.outcome_text(before, after, 48, 5.5, "converged"),
                         "49 invalid (49 tangled, 0 standing across) → 0 invalid (0 tangled, "
                         "0 standing across), min quality 0.00 → 2.8e-06, mean 0.85 → 0.90; "
                         "48 sweeps, 5.5 s (converged)")
        self.assertIn("(stopped at the sweep limit)",
                      reports.outcome_text(before, after, 100, 12.0, "max_sweeps"))
        self.assertTrue(reports.outcome_text(before, after, 48, 5.5, "converged", flips=12)
                        .endswith("48 sweeps, 5.5 s (converged); 12 edge flips"))
        self.assertTrue(reports.outcome_text(before, after, 48, 5.5, "converged", flips=1)
                        .endswith("(converged); 1 edge flip"))

    def test_optimize_object_stores_and_prints_its_outcome(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        self.doc.recompute()
        rep = SurfMesh.measure(mesh, tor)
        self.assertGreater(rep.stats["tangled"], 0)
        new = SurfMesh.optimize_object(mesh, tor)
        text = document.outcome_of(new)
        after = SurfMesh.measure(new, tor)
        run = dict(new.SurfMeshRun)
        m = re.fullmatch(r"(\d+) invalid \((\d+) tangled, (\d+) standing across\) → "
                         r"(\d+) invalid \((\d+) tangled, (\d+) standing across\), "
                         r"min quality (\S+) → (\S+), mean (\S+) → (\S+)"
                         r"; (\d+) sweeps?, (\S+) s \((.*)\)", text)
        self.assertIsNotNone(m, text)
        # measured here, independently
        for k, s, key in ((1, rep.stats, "invalid"), (2, rep.stats, "tangled"),
                          (3, rep.stats, "across"), (4, after.stats, "invalid"),
                          (5, after.stats, "tangled"), (6, after.stats, "across")):
            self.assertEqual(int(m.group(k)), s[key], key)
        self.assertEqual(m.group(8), reports.format_value(after.stats["min"]))
        self.assertEqual(m.group(10), reports.format_value(after.stats["mean"]))
        self.assertEqual(int(m.group(11)), int(run["sweeps"]))
        self.assertEqual(m.group(13), reports.REASONS[run["reason"]])
        self.assertIsNone(document.outcome_of(mesh))  # not made by optimize_object


class StopRuleProgress(unittest.TestCase):
    def test_untangling_then_converging(self):
        from SurfMesh.app.progress import StopRuleProgress

        rule = StopRuleProgress(rel_tol=1e-3, max_sweeps=100)
        p = [rule.update(dict(sweep=1, max_sweeps=100, tangled=10, objective=100.0)),
             rule.update(dict(sweep=2, max_sweeps=100, tangled=5, objective=90.0))]
        self.assertEqual(p, [0.01, 0.25])  # sweep 1 of 100 (untangling not begun), half of 0.5
        p.append(rule.update(dict(sweep=3, max_sweeps=100, tangled=0, objective=10.0)))
        self.assertEqual(p[-1], 0.5)  # untangled: the first half done
        # decreases 10 % (r0), then 1 %: log(0.1 / 0.01) / log(0.1 / 0.001) = 1/2 of the rest
        rule.update(dict(sweep=4, max_sweeps=100, tangled=0, objective=9.0))
        self.assertAlmostEqual(rule.update(dict(sweep=5, max_sweeps=100, tangled=0,
                                                objective=9.0 * 0.99)), 0.75, places=12)
        # below rel_tol: done, whatever the sweep count says
        self.assertEqual(rule.update(dict(sweep=6, max_sweeps=100, tangled=0,
                                          objective=9.0 * 0.99 * 0.9999)), 1.0)

    def test_never_drops_and_follows_the_sweep_limit(self):
        from SurfMesh.app.progress import StopRuleProgress

        rule = StopRuleProgress(rel_tol=1e-3, max_sweeps=10)
        a = rule.update(dict(sweep=1, max_sweeps=10, tangled=4, objective=1.0))
        b = rule.update(dict(sweep=2, max_sweeps=10, tangled=6, objective=1.0))  # more tangled
        self.assertEqual((a, b), (0.1, 0.2))
        self.assertEqual(rule.update(dict(sweep=10, max_sweeps=10, tangled=6)), 1.0)


class FacesOfPickedElements(unittest.TestCase):
    def test_summary_names_every_face(self):
        pick = document.ElementPick(
            kind="tangled", measure="shape", mesh_kind="fem", ids=[7, 8, 9, 10],
            indices=[0, 1, 2, 3], quality=[0.0] * 4, centers=[(0.0, 0.0, 0.0)] * 4,
            faces=["Face2", "Face7", "Face7", "Face7"], corners=[])
        text = pick.summary()
        self.assertTrue(text.endswith("lies near (0, 0, 0) on Face2; they lie on 2 faces: "
                                      "Face7 (3), Face2 (1)"), text)
        self.assertEqual(pick.face_counts(), [("Face7", 3), ("Face2", 1)])
        one = document.ElementPick(
            kind="tangled", measure="shape", mesh_kind="fem", ids=[7], indices=[0],
            quality=[0.0], centers=[(0.0, 0.0, 0.0)], faces=["Face2"], corners=[])
        self.assertTrue(one.summary().endswith("on Face2"), one.summary())


if __name__ == "__main__":
    unittest.main()
