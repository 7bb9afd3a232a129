"""The compiled module SurfMesh._surfmesh: array validation before C++ sees the data, error
translation, analytic surfaces against closed forms, measure/optimize on a single surface
(run: freecadcmd -t)."""

import math
import unittest

import numpy as np

from SurfMesh import _surfmesh as sm


def torus_grid(nu=24, nv=12, R=10.0, r=4.0):
    """A structured triangulation of the torus in (u, v): nodes and triangles, wound so that
    φu × φv (the outward normal) is their normal."""
    u = np.arange(nu) * 2 * math.pi / nu
    v = np.arange(nv) * 2 * math.pi / nv
    uu, vv = np.meshgrid(u, v, indexing="ij")
    uv = np.stack([uu.ravel(), vv.ravel()], axis=1)
    idx = lambda i, j: (i % nu) * nv + (j % nv)  # noqa: E731
    tris = []
    for i in range(nu):
        for j in range(nv):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            tris += [(a, b, c), (a, c, d)]
    return uv, np.array(tris, dtype=np.int64)


class TestBindings(unittest.TestCase):
    def setUp(self):
        import FreeCAD

        self.doc = FreeCAD.newDocument("SurfMeshBindingsTest")

    def tearDown(self):
        import FreeCAD

        FreeCAD.closeDocument(self.doc.Name)

    def test_torus_surface_matches_closed_form_and_occ(self):
        import Part

        t = sm.TorusSurface(10.0, 4.0)
        face = Part.makeTorus(10, 4).Faces[0]
        for u, v in [(0.0, 0.0), (1.0, 2.0), (4.0, 5.5)]:
            x = np.asarray(t.value(u, v))
            ref = [(10 + 4 * math.cos(v)) * math.cos(u), (10 + 4 * math.cos(v)) * math.sin(u),
                   4 * math.sin(v)]
            np.testing.assert_allclose(x, ref, atol=1e-12)
            p = face.Surface.value(u, v)  # OCC's torus: the same parameterization
            np.testing.assert_allclose(x, [p.x, p.y, p.z], atol=1e-12)
            n = np.asarray(t.normal(u, v))
            n_ref = face.normalAt(u, v)
            np.testing.assert_allclose(n, [n_ref.x, n_ref.y, n_ref.z], atol=1e-12)
        self.assertTrue(t.u_periodic and t.v_periodic)
        with self.assertRaises(ValueError):
            sm.TorusSurface(-1.0, 4.0)

    def test_planar_distortion_closed_forms(self):
        # shape: η = |S|²/(2 det S); Oddy: η = (|S|⁴ − 3 det²)/det² … for 2×2 S
        S = np.array([[2.0, 0.5], [0.1, 1.0]])
        F, det = float(np.sum(S * S)), float(np.linalg.det(S))
        self.assertAlmostEqual(sm.planar_distortion("shape", S), F / (2 * det), places=12)
        self.assertAlmostEqual(sm.planar_distortion("oddy", S), (F * F - 3 * det * det) / det**2,
                               places=10)
        self.assertEqual(sm.planar_distortion("shape", np.eye(2)), 1.0)
        self.assertTrue(math.isinf(sm.planar_distortion("shape", np.diag([1.0, -1.0]))))
        self.assertTrue(math.isfinite(sm.planar_distortion("shape", np.diag([1.0, -1.0]), 0.1)))
        with self.assertRaises(ValueError) as cm:
            sm.planar_distortion("nope", np.eye(2))
        self.assertIn("shape", str(cm.exception))

    def test_single_surface_mesh_measure_and_optimize(self):
        t = sm.TorusSurface(10.0, 4.0)
        uv, tris = torus_grid()
        mesh = sm.single_surface_mesh(t, uv, "tri3", tris)
        q0 = mesh.measure("shape")
        self.assertEqual(q0["stats"]["tangled"], 0)
        # perturb one node across its neighbours in (u,v): tangles elements
        uv2 = uv.copy()
        uv2[5] += [0.0, 0.9]
        m2 = sm.single_surface_mesh(t, uv2, "tri3", tris)
        q = m2.measure("shape")
        self.assertGreater(q["stats"]["tangled"], 0)
        calls = []
        r = m2.optimize(measure="shape", progress=lambda info: calls.append(info["sweep"]))
        self.assertEqual(r["after"]["tangled"], 0)
        self.assertEqual(calls, list(range(1, r["sweeps"] + 1)))
        x = m2.positions()
        rho = np.hypot(x[:, 0], x[:, 1])
        self.assertLess(np.abs(np.hypot(rho - 10, x[:, 2]) - 4).max(), 1e-12)
        # cancel: mesh unchanged
        m3 = sm.single_surface_mesh(t, uv2, "tri3", tris)
        before = m3.positions()
        r3 = m3.optimize(progress=lambda info: False)
        self.assertEqual(r3["reason"], "cancelled")
        np.testing.assert_array_equal(m3.positions(), before)

    def test_optimize_defaults_are_the_apis(self):
        # The binding's defaults are the core's, as documented in api.OPTIMIZE_DEFAULTS: a run
        # with no option and one with every option of the API's table spelled out take the
        # same sweeps to the same positions (a different rel_tol or move_tol would not).
        from SurfMesh.app import api

        t = sm.TorusSurface(10.0, 4.0)
        uv, tris = torus_grid(nu=40, nv=16)
        rng = np.random.default_rng(3)
        uv = uv + rng.uniform(-0.3, 0.3, uv.shape) * [2 * math.pi / 40, 2 * math.pi / 16]
        runs = []
        for opts in ({}, dict(api.OPTIMIZE_DEFAULTS)):
            m = sm.single_surface_mesh(t, uv, "tri3", tris)
            r = m.optimize(**opts)
            runs.append((r["sweeps"], r["reason"], m.positions()))
        self.assertEqual(runs[0][0], runs[1][0])
        self.assertEqual(runs[0][1], "converged")
        np.testing.assert_array_equal(runs[0][2], runs[1][2])
        # …and not those of a tighter tolerance (the test can tell them apart).
        m = sm.single_surface_mesh(t, uv, "tri3", tris)
        tight = m.optimize(rel_tol=1e-6, move_tol=1e-5)
        self.assertGreater(tight["sweeps"], runs[0][0])

    def test_validators(self):
        import Part

        shape = sm.CadShape.from_brep_string(Part.makeTorus(10, 4).exportBrepToString())
        self.assertEqual((shape.face_count, shape.edge_count, shape.vertex_count), (1, 2, 1))
        uv, tris = torus_grid(8, 6)
        t = sm.TorusSurface(10.0, 4.0)
        nodes = np.array([t.value(*p) for p in uv])
        types = np.zeros(len(tris), dtype=np.int64)
        offsets = np.arange(0, 3 * len(tris) + 1, 3, dtype=np.int64)
        conn = tris.reshape(-1)
        ok = sm.cad_mesh(shape, nodes, types, offsets, conn)
        self.assertEqual(ok.element_count, len(tris))
        self.assertEqual(ok.report["face_nodes"] + ok.report["vertex_nodes"]
                         + ok.report["edge_nodes"], len(nodes))

        def err(words, **kw):
            args = dict(nodes=nodes, types=types, offsets=offsets, conn=conn)
            args.update(kw)
            with self.assertRaises(ValueError) as cm:
                sm.cad_mesh(shape, args.pop("nodes"), args.pop("types"), args.pop("offsets"),
                            args.pop("conn"), **args)
            for w in words:
                self.assertIn(w, str(cm.exception))

        bad = conn.copy()
        bad[7] = len(nodes)
        err(["conn[7]", "out of range"], conn=bad)
        bad = conn.copy()
        bad[4] = -1
        err(["conn[4] = -1"], conn=bad)  # a negative index too (not only the maximum)
        nan = nodes.copy()
        nan[3, 1] = np.nan
        err(["non-finite", "in node 3"], nodes=nan)
        with self.assertRaises(sm.InputError) as cm:  # the same as a structured diagnostic
            sm.cad_mesh(shape, nan, types, offsets, conn)
        self.assertEqual((cm.exception.diagnostic["code"], cm.exception.diagnostic["nodes"]),
                         ("non_finite_node", [3]))
        err(["shape (N, 3)"], nodes=nodes[:, :2])
        err(["types[0]"], types=np.full(len(tris), 9, dtype=np.int64))
        err(["offsets"], offsets=offsets[:-1])
        off = offsets.copy()
        off[1] = 4
        err(["element 0", "4 nodes"], offsets=off)
        err(["hint_face"], hint_face=np.full(len(nodes), 3, dtype=np.int64))
        err(["hint_edge", "entries"], hint_edge=np.zeros(2, dtype=np.int64))
        err(["tolerance"], tolerance=-1.0)
        err(["boundary"], boundary="free")
        err(["no nodes"], nodes=np.zeros((0, 3)), conn=np.zeros(0, dtype=np.int64),
            types=np.zeros(0, dtype=np.int64), offsets=np.zeros(1, dtype=np.int64))
        with self.assertRaises(ValueError):
            sm.CadShape.from_brep_string("not a brep")
        with self.assertRaises(ValueError) as cm:
            sm.CadShape.from_file("/nonexistent/part.step")
        self.assertIn("/nonexistent/part.step", str(cm.exception))


if __name__ == "__main__":
    unittest.main()
