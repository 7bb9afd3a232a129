"""The CLI's ``measure --metrics … --csv FILE --vtk FILE`` on a small mesh written here: the CSV
holds hand-computed values per element id, the VTK file the same values as cell data (read
back with meshio), the JSON report their statistics; bad metric names and output files are
refused before anything is read.

Run by scripts/test.sh (``freecadcmd -t test_metrics_cli -M tests/python``).
"""

import csv
import json
import math
import os
import subprocess
import tempfile
import unittest

import FreeCAD as App
import numpy as np
import Part

import surfmesh_testing as T

SQ3 = math.sqrt(3.0)


def run_cli(*args):
    cmd = ["freecadcmd", T.cli_path(), "--"] + [str(a) for a in args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


class MeasureMetricsCli(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import meshio

        cls.dir = tempfile.mkdtemp(prefix="surfmesh_metrics_cli_", dir=T.output_dir())
        cls.shape = os.path.join(cls.dir, "plane.brep")
        Part.makePlane(10, 10, App.Vector(-5, -5, 0)).exportBrep(cls.shape)
        # element 0: right isosceles; element 1: equilateral; element 2: a 2 x 1 rectangle
        cls.nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [1.5, SQ3 / 2, 0],
                              [-3, -3, 0], [-1, -3, 0], [-1, -2, 0], [-3, -2, 0]], float)
        cls.mesh = os.path.join(cls.dir, "mesh.vtk")
        meshio.write(cls.mesh, meshio.Mesh(cls.nodes, [("triangle", [[0, 1, 2], [1, 3, 4]]),
                                                       ("quad", [[5, 6, 7, 8]])]))

    def test_csv_vtk_and_report(self):
        csv_path = os.path.join(self.dir, "m.csv")
        vtk_path = os.path.join(self.dir, "m.vtu")
        report = os.path.join(self.dir, "r.json")
        code, out, err = run_cli("measure", self.shape, self.mesh, "--metrics",
                                 "aspect_ratio,min_angle,stretch,distance_to_cad", "--csv",
                                 csv_path, "--vtk", vtk_path, "--report", report)
        self.assertEqual(code, 0, err)
        self.assertIn("aspect_ratio", out)
        with open(csv_path, newline="") as f:
            rows = list(csv.DictReader(f))
        self.assertEqual([r["type"] for r in rows], ["tri3", "tri3", "quad4"])
        self.assertEqual(list(rows[0])[3:],
                         ["aspect_ratio", "min_angle", "stretch", "distance_to_cad"])
        by_hand = [
            # √3/6 · √2 · (2 + √2), 45°; equilateral: 1, 60°; rectangle 2 x 1: 2·6/8, 90°,
            # stretch √2 · 1 / √5
            (SQ3 / 6 * math.sqrt(2) * (2 + math.sqrt(2)), 45.0, math.nan),
            (1.0, 60.0, math.nan),
            (1.5, 90.0, math.sqrt(2) / math.sqrt(5)),
        ]
        for row, (ar, amin, stretch) in zip(rows, by_hand):
            self.assertAlmostEqual(float(row["aspect_ratio"]), ar, places=8)
            self.assertAlmostEqual(float(row["min_angle"]), amin, places=8)
            if math.isnan(stretch):
                self.assertEqual(row["stretch"], "nan")
            else:
                self.assertAlmostEqual(float(row["stretch"]), stretch, places=8)
            self.assertLess(float(row["distance_to_cad"]), 1e-9)
            self.assertEqual(row["face"], "Face1")

        import meshio

        m = meshio.read(vtk_path)
        ids = np.concatenate(m.cell_data["element_id"])
        ar = np.concatenate(m.cell_data["aspect_ratio"])
        by_id = {int(r["element_id"]): r for r in rows}
        self.assertEqual(sorted(by_id), sorted(int(i) for i in ids))
        for eid, value in zip(ids, ar):
            self.assertAlmostEqual(value, float(by_id[int(eid)]["aspect_ratio"]), places=8)
        np.testing.assert_allclose(m.points, self.nodes)

        with open(report) as f:
            stats = json.load(f)["metrics"]
        self.assertAlmostEqual(stats["min_angle"]["min"], 45.0, places=8)
        self.assertAlmostEqual(stats["min_angle"]["max"], 90.0, places=8)
        self.assertEqual(stats["stretch"]["count"], 1)
        self.assertEqual(stats["stretch"]["not_applicable"], 2)

    def test_csv_alone_writes_every_metric(self):
        csv_path = os.path.join(self.dir, "all.csv")
        code, _, err = run_cli("measure", self.shape, self.mesh, "--csv", csv_path)
        self.assertEqual(code, 0, err)
        with open(csv_path, newline="") as f:
            head = next(csv.reader(f))
        from SurfMesh.app import metrics

        self.assertEqual(head, ["element_id", "type", "face"] + list(metrics.METRIC_NAMES))

    def test_bad_names_and_files_are_refused_first(self):
        code, _, err = run_cli("measure", self.shape, self.mesh, "--metrics", "aspect,skew")
        self.assertEqual(code, 2)
        self.assertIn("unknown metric(s) 'aspect'", err)
        code, _, err = run_cli("measure", self.shape, "/nonexistent/mesh.vtk", "--vtk",
                               os.path.join(self.dir, "m.txt"))
        self.assertEqual(code, 2)
        self.assertIn("give a .vtk or .vtu file", err)
        code, _, err = run_cli("measure", self.shape, self.mesh, "--csv",
                               "/nonexistent/folder/m.csv")
        self.assertEqual(code, 2)
        self.assertIn("folder /nonexistent/folder does not exist", err)


if __name__ == "__main__":
    unittest.main()
