"""The command line (freecadcmd surfmesh_cli.py -- …): round trips through Gmsh .msh v2 and v4,
STL and UNV, the JSON report, and errors (run: freecadcmd -t)."""

import json
import os
import shutil
import subprocess
import unittest

import FreeCAD
import numpy as np

import surfmesh_testing as T

R, r = 10.0, 4.0


def run_cli(*args):
    cmd = ["freecadcmd", T.cli_path(), "--"] + [str(a) for a in args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


def read_msh(path):
    """(node tags, coords, element tags, element node tags) of the 2D elements, read by Gmsh
    itself (in a separate process: the CLI keeps no state here)."""
    from SurfMesh.app import fileio

    gmsh = fileio._gmsh()
    gmsh.clear()
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    _, etags, enodes = gmsh.model.mesh.getElements(2)
    return (np.asarray(tags)[order], np.asarray(coords).reshape(-1, 3)[order],
            np.concatenate(etags), np.concatenate(enodes))


class TestCli(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import Part

        from SurfMesh.app import fileio

        cls.dir = os.path.join(T.output_dir(), "cli")
        shutil.rmtree(cls.dir, ignore_errors=True)
        os.makedirs(cls.dir)
        cls.brep = os.path.join(cls.dir, "torus.brep")
        Part.makeTorus(R, r).exportBrep(cls.brep)
        gmsh = fileio._gmsh()
        gmsh.clear()
        gmsh.model.occ.importShapes(cls.brep)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 2.0)
        gmsh.model.mesh.generate(2)
        # tangle it: move the free nodes in (u, v) on the torus, with a fixed seed
        tags, coords, _ = gmsh.model.mesh.getNodes(2, -1, includeBoundary=False)
        new = T.perturbed_on_torus(coords, 3, 0.045, 0.13, R, r)
        for t, p in zip(tags, new):
            gmsh.model.mesh.setNode(int(t), p.tolist(), [])
        gmsh.option.setNumber("Mesh.SaveAll", 1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        for ver, name in ((4.1, "torus4.msh"), (2.2, "torus2.msh")):
            gmsh.option.setNumber("Mesh.MshFileVersion", ver)
            gmsh.write(os.path.join(cls.dir, name))
        gmsh.write(os.path.join(cls.dir, "torus.stl"))
        gmsh.clear()

    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshCliTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def roundtrip_msh(self, name, version_line):
        src = os.path.join(self.dir, name)
        out = os.path.join(self.dir, "out_" + name)
        rep = os.path.join(self.dir, name + ".json")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep)
        self.assertEqual(code, 0, se)
        with open(out) as fh:
            self.assertEqual(fh.read().split("\n")[1].split()[0], version_line)
        t0, x0, e0, n0 = read_msh(src)
        t1, x1, e1, n1 = read_msh(out)
        np.testing.assert_array_equal(t1, t0)  # node tags
        np.testing.assert_array_equal(e1, e0)  # element tags
        np.testing.assert_array_equal(n1, n0)  # connectivity
        self.assertLess(T.torus_distance(x1, R, r).max(), 1e-9)  # .msh keeps 16 digits
        self.assertGreater(np.abs(x1 - x0).max(), 1e-3)
        data = json.load(open(rep))
        self.assertEqual(data["hints"], "tolerance")  # a mesher's file: FreeCAD's FEM rule
        self.assertGreater(data["before"]["tangled"], 0)
        self.assertEqual(data["after"]["tangled"], 0)
        self.assertEqual(data["after"]["elements"], len(e0))
        self.assertGreater(data["sweeps"], 0)
        self.assertIn("seconds", data)
        self.assertIn("Tang. el.", so)
        # an independent look at the output: no triangle is flipped against the torus normal
        tris = np.searchsorted(t1, n1).reshape(-1, 3)
        import Part

        _, tangled = T.reference_tri_quality(x1, tris, Part.makeTorus(R, r).Faces[0])
        self.assertFalse(tangled.any())

    def test_msh_v4(self):
        self.roundtrip_msh("torus4.msh", "4.1")

    def test_msh_v2(self):
        self.roundtrip_msh("torus2.msh", "2.2")

    def test_stl_and_measure(self):
        import Mesh

        src = os.path.join(self.dir, "torus.stl")
        out = os.path.join(self.dir, "out_torus.stl")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--measure", "shape")
        self.assertEqual(code, 0, se)
        m0, m1 = Mesh.Mesh(src), Mesh.Mesh(out)
        self.assertEqual(m1.CountFacets, m0.CountFacets)
        pts = np.array([(p.x, p.y, p.z) for p in m1.Topology[0]])
        self.assertLess(T.torus_distance(pts, R, r).max(), 1e-5)  # float32 storage
        rep0 = os.path.join(self.dir, "stl.json")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep0)
        after = json.load(open(rep0))["after"]
        self.assertEqual(json.load(open(rep0))["hints"], "none")  # a triangulation: no hints
        self.assertEqual(after["tangled"], 0)
        rep = os.path.join(self.dir, "measure.json")
        code, so, se = run_cli("measure", self.brep, out, "--report", rep)
        self.assertEqual(code, 0, se)
        stats = json.load(open(rep))["stats"]
        # the STL holds float32 points: the re-measured stats agree to rounding, except that an
        # element standing almost perpendicular to the surface may change its orientation sign
        self.assertEqual(stats["elements"], after["elements"])
        self.assertLessEqual(stats["tangled"], 2)
        self.assertAlmostEqual(stats["mean"], after["mean"], delta=1e-3)

    def test_unv(self):
        import Fem

        from SurfMesh.app import fileio

        mf = fileio.read_mesh(os.path.join(self.dir, "torus4.msh"))
        unv = os.path.join(self.dir, "torus.unv")
        fileio.write_mesh(unv, mf, mf.data.nodes)
        out = os.path.join(self.dir, "out_torus.unv")
        code, so, se = run_cli("optimize", self.brep, unv, "-o", out)
        self.assertEqual(code, 0, se)
        f0, f1 = Fem.read(unv), Fem.read(out)
        self.assertEqual(list(f1.Nodes), list(f0.Nodes))
        self.assertEqual(list(f1.Faces), list(f0.Faces))
        pts = np.array([(p.x, p.y, p.z) for p in f1.Nodes.values()])
        self.assertLess(T.torus_distance(pts, R, r).max(), 1e-6)

    def test_vtk_keeps_double_precision(self):
        # VTK files hold the optimized nodes in double precision: on the torus to 1e-12, as
        # the .msh output (FreeCAD's own VTK writer keeps 6 digits: 1e-5 off the surface).
        from SurfMesh.app import fileio

        for ext in (".vtk", ".vtu"):
            with self.subTest(ext=ext):
                out = os.path.join(self.dir, "out_torus" + ext)
                code, so, se = run_cli("optimize", self.brep, os.path.join(self.dir, "torus4.msh"),
                                       "-o", out)
                self.assertEqual(code, 0, se)
                back = fileio.read_mesh(out).data
                _, x0, e0, _ = read_msh(os.path.join(self.dir, "torus4.msh"))
                self.assertEqual(back.element_count, len(e0))
                self.assertLess(T.torus_distance(back.nodes, R, r).max(), 1e-12)

    def test_fixed_nodes_and_faces(self):
        src = os.path.join(self.dir, "torus4.msh")
        t0, x0, _, _ = read_msh(src)
        # The nodes with x > 0 held, by the file's node tags (ranges and single ids).
        held = t0[x0[:, 0] > 0]
        self.assertGreater(len(held), 100)
        runs, start = [], int(held[0])
        for a, b in zip(held[:-1], held[1:]):
            if b != a + 1:
                runs.append(f"{start}-{int(a)}" if int(a) > start else str(start))
                start = int(b)
        runs.append(f"{start}-{int(held[-1])}" if int(held[-1]) > start else str(start))
        out = os.path.join(self.dir, "out_fixed.msh")
        rep = os.path.join(self.dir, "fixed.json")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep,
                               "--fixed-nodes", ",".join(runs), "--faces", "Face1")
        self.assertEqual(code, 0, se)
        t1, x1, _, _ = read_msh(out)
        np.testing.assert_array_equal(t1, t0)
        keep = np.isin(t0, held)
        np.testing.assert_array_equal(x1[keep], x0[keep])
        self.assertGreater(np.count_nonzero(np.abs(x1[~keep] - x0[~keep]).max(axis=1) > 0),
                           0.5 * np.count_nonzero(~keep))
        data = json.load(open(rep))
        self.assertEqual(data["options"]["fixed_nodes"], len(held))
        self.assertEqual(data["options"]["faces"], ["Face1"])
        self.assertGreater(data["held_nodes"], 100)
        # the torus has one face; a list that is not one of ids
        code, _, se = run_cli("optimize", self.brep, src, "-o", out, "--faces", "2")
        self.assertEqual(code, 2)
        self.assertIn("Face2 is not a face of the shape, which has 1 face", se)
        code, _, se = run_cli("optimize", self.brep, src, "-o", out, "--fixed-nodes", "9-3")
        self.assertEqual(code, 2)
        self.assertIn("'9-3' is neither a node id nor a range", se)

    def test_topology_flip_writes_the_rewired_elements(self):
        """A fan of slivers on a square (every node on a CAD edge: only flips improve it),
        through the CLI into .msh 4.1, .msh 2.2 and UNV: the files hold the rewired node lists
        the report gives, the same element ids, and a valid mesh better than the input's,
        judged without SurfMesh."""
        import Part

        from SurfMesh.app import fileio

        square = os.path.join(self.dir, "square.brep")
        Part.makePlane(10, 10).exportBrep(square)
        nodes = np.array([(float(i), 0.0, 0.0) for i in range(11)]
                         + [(float(i), 10.0, 0.0) for i in range(11)])
        tris = np.array([(i, i + 1, 11) for i in range(10)]
                        + [(10, 12 + j, 11 + j) for j in range(10)])
        gmsh = fileio._gmsh()
        gmsh.clear()
        gmsh.model.add("fan")
        gmsh.model.addDiscreteEntity(2, 1)
        gmsh.model.mesh.addNodes(2, 1, list(range(1, 23)), nodes.reshape(-1).tolist())
        gmsh.model.mesh.addElementsByType(1, 2, list(range(1, 21)), (tris + 1).reshape(-1).tolist())
        src = os.path.join(self.dir, "fan.msh")
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(src)
        face = Part.makePlane(10, 10)
        q0, _ = T.reference_tri_quality(nodes, tris, face)
        for name, extra in (("fan_out4.msh", []), ("fan_out2.msh", ["--msh-version", "2.2"]),
                            ("fan_out.unv", [])):
            out = os.path.join(self.dir, name)
            rep = os.path.join(self.dir, name + ".json")
            code, so, se = run_cli("optimize", square, src, "-o", out, "--report", rep,
                                   "--topology", "flip", *extra)
            self.assertEqual(code, 0, se)
            data = json.load(open(rep))
            self.assertGreater(data["flips"], 0)
            self.assertIn(f"{data['flips']} edge flip(s)", so)
            rewired = dict(zip(data["rewired_elements"], map(tuple, data["rewired_nodes"])))
            if name.endswith(".msh"):
                t1, x1, e1, n1 = read_msh(out)
                np.testing.assert_array_equal(t1, np.arange(1, 23))
                np.testing.assert_array_equal(np.sort(e1), np.arange(1, 21))
                conn = dict(zip(e1.tolist(), map(tuple, n1.reshape(-1, 3).tolist())))
                got = np.array([conn[e] for e in range(1, 21)]) - 1
            else:
                import Fem

                fem = Fem.read(out)
                self.assertEqual(sorted(fem.Faces), list(range(1, 21)))
                conn = {e: tuple(fem.getElementNodes(e)) for e in fem.Faces}
                got = np.array([conn[e] for e in range(1, 21)]) - 1
            # The report's ids (a .msh: Gmsh's tags; UNV input ids are the .msh's too).
            for e, ns in rewired.items():
                self.assertEqual(tuple(conn[e]), ns, name)
            unchanged = [e for e in range(1, 21) if e not in rewired]
            for e in unchanged:
                self.assertEqual(tuple(got[e - 1]), tuple(tris[e - 1]), name)
            q1, t1_ = T.reference_tri_quality(nodes, got, face)
            self.assertFalse(t1_.any(), name)
            self.assertGreater(q1.min(), 1.5 * q0.min(), name)
            self.assertAlmostEqual(data["after"]["min"], q1.min(), places=6)

    def test_topology_flip(self):
        # --topology reaches the run: the report's options and flip counts (the torus's Gmsh
        # mesh needs no flip: none made, the output written as without the option)
        src = os.path.join(self.dir, "torus4.msh")
        out = os.path.join(self.dir, "out_flip.msh")
        rep = os.path.join(self.dir, "flip.json")
        code, so, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep,
                               "--topology", "flip")
        self.assertEqual(code, 0, se)
        data = json.load(open(rep))
        self.assertEqual(data["options"]["topology"], "flip")
        self.assertEqual(data["after"]["tangled"], 0)
        self.assertEqual((data["flips"], data["rewired_elements"]), (0, []))
        self.assertNotIn("edge flip", so)  # the summary names flips only when there are some
        t0, _, e0, n0 = read_msh(src)
        t1, _, e1, n1 = read_msh(out)
        np.testing.assert_array_equal(t1, t0)
        np.testing.assert_array_equal(e1, e0)
        np.testing.assert_array_equal(n1, n0)
        # without it: the core's default ("none")
        code, _, se = run_cli("optimize", self.brep, src, "-o", out, "--report", rep)
        self.assertEqual(code, 0, se)
        self.assertEqual(json.load(open(rep))["options"]["topology"], "none")
        code, _, se = run_cli("optimize", self.brep, src, "-o", out, "--topology", "swap")
        self.assertEqual(code, 2)
        self.assertIn("invalid choice: 'swap'", se)

    def test_errors(self):
        src = os.path.join(self.dir, "torus4.msh")
        code, _, se = run_cli("measure", self.brep, os.path.join(self.dir, "missing.msh"))
        self.assertEqual(code, 2)
        self.assertIn("not found", se)
        code, _, se = run_cli("measure", self.brep, src, "--measure", "bogus")
        self.assertEqual(code, 2)
        self.assertIn("bogus", se)
        bad = os.path.join(self.dir, "bad.msh")
        with open(bad, "w") as fh:
            fh.write("not a mesh\n")
        code, _, se = run_cli("measure", self.brep, bad)
        self.assertEqual(code, 2)
        self.assertIn("not a Gmsh", se)
        import Part

        box = os.path.join(self.dir, "box.brep")
        Part.makeBox(3, 3, 3).exportBrep(box)
        code, _, se = run_cli("measure", box, src)  # the mesh of another shape
        self.assertEqual(code, 2)
        self.assertIn("error", se)
        code, _, se = run_cli("optimize", self.brep, src)  # -o missing
        self.assertEqual(code, 2)


class TestCliDefaults(unittest.TestCase):
    """The command line's defaults are SurfMesh.app.options's (the optimizer's: the core's)."""

    def test_parser_defaults_and_help(self):
        import argparse

        from SurfMesh.app import messages, options
        from SurfMesh.cli import surfmesh_cli

        parser = surfmesh_cli.build_parser()
        subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        opt = subs.choices["optimize"]
        actions = {a.dest: a for a in opt._actions}
        self.assertEqual(actions["measure"].default, options.DEFAULT_MEASURE)
        self.assertEqual(subs.choices["measure"].get_default("measure"), options.DEFAULT_MEASURE)
        self.assertEqual(actions["boundary"].default, options.DEFAULT_BOUNDARY)
        self.assertEqual(tuple(actions["boundary"].choices), options.BOUNDARY_MODES)
        # the optimizer's options are not set unless given: the core's defaults apply
        for dest in ("max_sweeps", "rel_tol", "over_relaxation", "threads", "high_order",
                     "topology"):
            self.assertIsNone(actions[dest].default, dest)
        self.assertEqual(tuple(actions["topology"].choices), options.TOPOLOGY_MODES)
        text = " ".join(opt.format_help().split())
        d = options.optimize_defaults()
        self.assertIn(f"by less than this fraction (default {messages.number_text(d['rel_tol'])})",
                      text)
        self.assertIn("(default 1e-3)", text)
        self.assertIn(f"(in [1, 2), default {d['over_relaxation']}; 1: plain Gauss-Seidel)", text)
        self.assertIn("'flip': edge flips between the smoothing runs", text)
        self.assertIn(f"'none': node moves alone (default {d['topology']})", text)


if __name__ == "__main__":
    unittest.main()
