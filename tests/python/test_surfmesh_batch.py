"""The `surfmesh` command and `surfmesh batch` (run: freecadcmd -t): the installed command runs
the command line's subcommands with its options, messages and exit statuses; a batch runs each
manifest row in a process of its own, on the local pool and on a Dask cluster started here on
127.0.0.1, survives a broken file, a refused option and a row that runs past its timeout,
records one JSON line per row, resumes, and gives the same meshes as single runs."""

import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import unittest

import FreeCAD
import numpy as np

import surfmesh_testing as T

R, r = 10.0, 4.0


def surfmesh_command():
    """The installed `surfmesh` command (scripts/install.sh puts it in /usr/local/bin as root,
    else ~/.local/bin, or SURFMESH_BIN_DIR)."""
    cands = [shutil.which("surfmesh"), os.path.expanduser("~/.local/bin/surfmesh"),
             "/usr/local/bin/surfmesh"]
    if os.environ.get("SURFMESH_BIN_DIR"):
        cands.insert(0, os.path.join(os.environ["SURFMESH_BIN_DIR"], "surfmesh"))
    for c in cands:
        if c and os.access(c, os.X_OK):
            return c
    raise AssertionError(f"no installed surfmesh command among {cands}: run scripts/install.sh")


def run(*args, timeout=600):
    cmd = [surfmesh_command()] + [str(a) for a in args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout,
                       stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


def run_cli(*args):
    cmd = ["freecadcmd", T.cli_path(), "--"] + [str(a) for a in args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                       stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


def records(out_dir):
    with open(os.path.join(out_dir, "results.jsonl")) as fh:
        return [json.loads(ln) for ln in fh]


def by_id(recs):
    return {r["id"]: r for r in recs}


def msh_nodes_and_triangles(path):
    """(node coordinates, triangles as indices into them) read by Gmsh itself."""
    from SurfMesh.app import fileio

    gmsh = fileio._gmsh()
    gmsh.clear()
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    tags = np.asarray(tags)[order]
    xyz = np.asarray(coords).reshape(-1, 3)[order]
    _, _, enodes = gmsh.model.mesh.getElements(2)
    gmsh.clear()
    tris = np.searchsorted(tags, np.concatenate(enodes)).reshape(-1, 3)
    return xyz, tris


def processes_with(text):
    """Pids of running processes whose command line holds ``text``."""
    out = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as fh:
                if text.encode() in fh.read():
                    out.append(int(pid))
        except OSError:
            pass
    return out


def write_manifest(path, header, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


class TestSurfmeshBatch(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import Part

        from SurfMesh.app import fileio

        cls.dir = os.path.join(T.output_dir(), "batch")
        shutil.rmtree(cls.dir, ignore_errors=True)
        os.makedirs(os.path.join(cls.dir, "parts"))
        cls.brep = os.path.join(cls.dir, "parts", "torus.brep")
        Part.makeTorus(R, r).exportBrep(cls.brep)
        gmsh = fileio._gmsh()
        for name, h, seed in (("a.msh", 2.0, 3), ("b.msh", 1.5, 4), ("slow.msh", 0.25, 5)):
            gmsh.clear()
            gmsh.model.occ.importShapes(cls.brep)
            gmsh.model.occ.synchronize()
            gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
            gmsh.model.mesh.generate(2)
            # tangle it: the free nodes moved in (u, v) on the torus, with a fixed seed
            tags, coords, _ = gmsh.model.mesh.getNodes(2, -1, includeBoundary=False)
            new = T.perturbed_on_torus(coords, seed, 0.045, 0.13, R, r)
            for t, p in zip(tags, new):
                gmsh.model.mesh.setNode(int(t), p.tolist(), [])
            gmsh.option.setNumber("Mesh.SaveAll", 1)
            gmsh.option.setNumber("Mesh.Binary", 0)
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.write(os.path.join(cls.dir, "parts", name))
        gmsh.clear()
        cls.face = Part.makeTorus(R, r).Faces[0]
        with open(os.path.join(cls.dir, "parts", "broken.msh"), "w") as fh:
            fh.write("this is not a mesh\n")
        # The same rows as single runs of the command, for comparison.
        cls.single = {}
        for rid, mesh, opts in (("a", "a.msh", []),
                                ("b", "b.msh", ["--boundary", "slide", "--max-sweeps", "50"])):
            out = os.path.join(cls.dir, f"single_{rid}.msh")
            rep = os.path.join(cls.dir, f"single_{rid}.json")
            code, so, se = run("optimize", cls.brep, os.path.join(cls.dir, "parts", mesh),
                               "-o", out, "--report", rep, *opts)
            assert code == 0, se
            cls.single[rid] = (out, json.load(open(rep)))
        # The manifest: paths relative to its folder; a refused option, a file that is no
        # mesh, a row that runs past its own timeout (30 000 triangles, converging only after
        # some 20 s of sweeps), and a measure row.
        cls.manifest = os.path.join(cls.dir, "manifest.csv")
        write_manifest(cls.manifest,
                       ["id", "shape", "mesh", "command", "boundary", "max-sweeps", "rel_tol",
                        "timeout"],
                       [["a", "parts/torus.brep", "parts/a.msh", "", "", "", "", ""],
                        ["b", "parts/torus.brep", "parts/b.msh", "", "slide", "50", "", ""],
                        ["m", "parts/torus.brep", "parts/a.msh", "measure", "", "", "", ""],
                        ["broken", "parts/torus.brep", "parts/broken.msh", "", "", "", "", ""],
                        ["sideways", "parts/torus.brep", "parts/a.msh", "", "sideways", "", "",
                         ""],
                        ["slow", "parts/torus.brep", "parts/slow.msh", "", "", "100000",
                         "1e-15", "3"]])

    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshBatchTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    # ---- the command ------------------------------------------------------------------------

    def test_command_version_usage_and_the_cli_s_exit_statuses(self):
        import SurfMesh

        code, so, se = run("--version")
        self.assertEqual(code, 0, se)
        self.assertIn(f"surfmesh {SurfMesh.__version__}", so)
        self.assertIn("FreeCAD " + ".".join(FreeCAD.Version()[:2]), so)
        code, so, se = run()
        self.assertEqual(code, 2)
        self.assertIn("batch", so)
        code, so, se = run("measures")
        self.assertEqual(code, 0, se)
        self.assertEqual(so.split(), list(SurfMesh.measure_names()))
        # bad input: the command line's own message and status 2, the same as through freecadcmd
        missing = os.path.join(self.dir, "nothing.step")
        code, so, se = run("measure", missing, os.path.join(self.dir, "parts", "a.msh"))
        c2, _, se2 = run_cli("measure", missing, os.path.join(self.dir, "parts", "a.msh"))
        self.assertEqual((code, c2), (2, 2))
        self.assertIn(f"surfmesh: error: shape file not found: {missing}", se)
        self.assertEqual(se.strip(), se2.strip())
        code, so, se = run("optimize", "--max-sweeps", "x")
        self.assertEqual(code, 2)
        self.assertIn("usage: surfmesh optimize", se)

    def test_command_gives_the_freecadcmd_cli_s_mesh(self):
        src = os.path.join(self.dir, "parts", "b.msh")
        out1, out2 = (os.path.join(self.dir, f"same_{k}.msh") for k in (1, 2))
        rep1, rep2 = (os.path.join(self.dir, f"same_{k}.json") for k in (1, 2))
        code, so, se = run("optimize", self.brep, src, "-o", out1, "--report", rep1)
        self.assertEqual(code, 0, se)
        c2, so2, se2 = run_cli("optimize", self.brep, src, "-o", out2, "--report", rep2)
        self.assertEqual(c2, 0, se2)
        with open(out1) as f1, open(out2) as f2:
            self.assertEqual(f1.read(), f2.read())
        j1, j2 = json.load(open(rep1)), json.load(open(rep2))
        self.assertEqual(j1["after"], j2["after"])
        self.assertGreater(j1["before"]["tangled"], 0)
        self.assertEqual(j1["after"]["tangled"], 0)
        self.assertIn("Tang. el.", so)

    def test_command_reads_every_format_as_freecadcmd_does(self):
        """The command runs FreeCAD as a library: FEM's readers (Python modules of FEM's
        resource folder) must be there as in freecadcmd. Each format measured both ways."""
        import gzip

        crank = os.path.join(T.data_dir(), "occt_crankarm.brep")
        inp = os.path.join(self.dir, "crankarm_order2.inp")
        with gzip.open(os.path.join(T.data_dir(), "occt_crankarm_gmsh_order2.inp.gz")) as src:
            with open(inp, "wb") as dst:
                dst.write(src.read())
        fcstd = os.path.join(self.dir, "torus_fem.FCStd")
        doc = FreeCAD.newDocument("SurfMeshBatchFcstd")
        try:
            import Part

            feat = doc.addObject("Part::Feature", "Torus")
            feat.Shape = Part.makeTorus(R, r)
            mesh = doc.addObject("Fem::FemMeshObject", "TorusMesh")
            mesh.FemMesh = self._fem_of_msh(os.path.join(self.dir, "parts", "a.msh"))
            doc.recompute()
            doc.saveAs(fcstd)
        finally:
            FreeCAD.closeDocument(doc.Name)
        cases = [
            ("inp", crank, inp, []),
            ("unv", crank, os.path.join(T.data_dir(), "occt_crankarm_fillet_fold.unv"), []),
            ("msh", self.brep, os.path.join(self.dir, "parts", "a.msh"), []),
            ("fcstd", fcstd, fcstd, ["--shape-object", "Torus", "--mesh-object", "TorusMesh"]),
        ]
        for name, shape, mesh_path, opts in cases:
            with self.subTest(fmt=name):
                r1 = os.path.join(self.dir, f"fmt_{name}_1.json")
                r2 = os.path.join(self.dir, f"fmt_{name}_2.json")
                code, so, se = run("measure", shape, mesh_path, "--report", r1, *opts)
                self.assertEqual(code, 0, se)
                c2, so2, se2 = run_cli("measure", shape, mesh_path, "--report", r2, *opts)
                self.assertEqual(c2, 0, se2)
                j1, j2 = json.load(open(r1)), json.load(open(r2))
                self.assertEqual(j1["stats"], j2["stats"])
                self.assertEqual(j1["mesh"], j2["mesh"])
                self.assertGreater(j1["stats"]["elements"], 0)

    def _fem_of_msh(self, path):
        """A Fem.FemMesh of a Gmsh .msh file's triangles, node and element ids kept."""
        import Fem

        from SurfMesh.app import fileio

        data = fileio.read_mesh(path).data
        fem = Fem.FemMesh()
        for nid, p in zip(data.node_ids, data.nodes):
            fem.addNode(float(p[0]), float(p[1]), float(p[2]), int(nid))
        for e, eid in enumerate(data.element_ids):
            nodes = data.conn[data.offsets[e]:data.offsets[e + 1]]
            fem.addFace([int(data.node_ids[n]) for n in nodes], int(eid))
        return fem

    # ---- batch on the local pool ------------------------------------------------------------

    def check_batch(self, out, recs, worker_field=False):
        got = by_id(recs)
        self.assertEqual(sorted(got), sorted(["a", "b", "m", "broken", "sideways", "slow"]))
        for rid in ("a", "b", "m"):
            self.assertEqual(got[rid]["status"], "ok", got[rid])
            self.assertIsNone(got[rid]["error"])
        for rec in recs:
            for key in ("id", "shape", "mesh", "status", "error", "before", "after",
                        "seconds", "output"):
                self.assertIn(key, rec)
        # optimized rows: the same mesh, byte for byte, and the same figures as single runs
        for rid in ("a", "b"):
            rec = got[rid]
            single_out, single_rep = self.single[rid]
            self.assertEqual(rec["output"], os.path.join(out, "meshes", f"{rid}.msh"))
            with open(rec["output"]) as f1, open(single_out) as f2:
                self.assertEqual(f1.read(), f2.read(), rid)
            self.assertEqual(rec["before"], single_rep["before"])
            self.assertEqual(rec["after"], single_rep["after"])
            self.assertEqual(rec["after"]["tangled"], 0)
            self.assertEqual(rec["after"]["invalid"], 0)
            # an independent look at the output: no triangle flipped against the torus normal
            xyz, tris = msh_nodes_and_triangles(rec["output"])
            q, tangled = T.reference_tri_quality(xyz, tris, self.face)
            self.assertFalse(tangled.any(), rid)
            self.assertAlmostEqual(q.min(), rec["after"]["min"], places=6)
            self.assertLess(T.torus_distance(xyz, R, r).max(), 1e-9)
            self.assertEqual(json.load(open(os.path.join(out, "reports", f"{rid}.json")))
                             ["after"], rec["after"])
        # the measure row: statistics of the input, no output
        self.assertEqual(got["m"]["command"], "measure")
        self.assertEqual(got["m"]["before"], self.single["a"][1]["before"])
        self.assertIsNone(got["m"]["after"])
        # failures say what and where
        self.assertEqual(got["broken"]["status"], "error")
        self.assertIn(os.path.join(self.dir, "parts", "broken.msh"), got["broken"]["error"])
        self.assertEqual(got["broken"]["exit_code"], 2)
        self.assertEqual(got["sideways"]["status"], "error")
        self.assertIn("line 6", got["sideways"]["error"])
        self.assertIn("sideways", got["sideways"]["error"])
        self.assertEqual(got["slow"]["status"], "timeout")
        self.assertIn("3 s", got["slow"]["error"])
        self.assertLess(got["slow"]["seconds"], 60)
        self.assertFalse(os.path.exists(got["slow"]["output"]))
        self.assertFalse(os.path.exists(got["broken"]["output"]))
        with open(os.path.join(out, "logs", "broken.log")) as fh:
            self.assertIn("broken.msh", fh.read())
        if worker_field:
            self.assertTrue(all(got[k].get("worker") for k in ("a", "b", "m", "slow")))

    def test_local_pool_survives_bad_rows_and_resumes(self):
        out = os.path.join(self.dir, "out_local")
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.monotonic()
        code, so, se = run("batch", self.manifest, "--out", out, "--jobs", "2", "--timeout",
                           "300")
        self.assertEqual(code, 1, so + se)  # not every row ok
        self.assertLess(time.monotonic() - t0, 120)
        self.assertIn("6 row(s): 3 ok, 2 error, 1 timeout", so)
        recs = records(out)
        self.assertEqual(len(recs), 6)
        self.check_batch(out, recs)
        # the row that ran past its timeout left no process behind
        self.assertEqual(processes_with(os.path.join(self.dir, "parts", "slow.msh")), [])
        # a results file is never run over by accident
        code, so, se = run("batch", self.manifest, "--out", out)
        self.assertEqual(code, 2)
        self.assertIn("--resume", se)
        # resume: a new row runs, the recorded ones do not
        log_a = os.path.join(out, "logs", "a.log")
        stamp = os.stat(log_a).st_mtime_ns
        more = os.path.join(self.dir, "manifest_more.csv")
        shutil.copy(self.manifest, more)
        with open(more, "a") as fh:
            fh.write("c,parts/torus.brep,parts/a.msh,,,,,\n")
        code, so, se = run("batch", more, "--out", out, "--resume", "--jobs", "2")
        self.assertEqual(code, 1, so + se)
        self.assertIn("1 to run", so)
        self.assertIn("6 already recorded", so)
        recs2 = records(out)
        self.assertEqual(len(recs2), 7)
        self.assertEqual(recs2[:6], recs)
        self.assertEqual(recs2[6]["id"], "c")
        self.assertEqual(recs2[6]["status"], "ok")
        self.assertEqual(os.stat(log_a).st_mtime_ns, stamp)
        # retry the failed rows after the broken file is replaced by a mesh: that row is ok now
        shutil.copy(os.path.join(self.dir, "parts", "a.msh"),
                    os.path.join(self.dir, "parts", "broken_fixed.msh"))
        fixed = os.path.join(self.dir, "manifest_fixed.csv")
        with open(more) as fh:
            text = fh.read().replace("parts/broken.msh", "parts/broken_fixed.msh")
        with open(fixed, "w") as fh:
            fh.write(text)
        code, so, se = run("batch", fixed, "--out", out, "--resume", "--retry-failed")
        self.assertEqual(code, 1, so + se)  # the slow row times out again
        self.assertIn("3 to run", so)
        final = by_id(records(out))
        self.assertEqual(final["broken"]["status"], "ok")
        self.assertEqual(final["slow"]["status"], "timeout")
        self.assertEqual(final["sideways"]["status"], "error")
        # all rows ok: exit status 0
        good = os.path.join(self.dir, "manifest_good.csv")
        write_manifest(good, ["shape", "mesh"], [["parts/torus.brep", "parts/a.msh"],
                                                 ["parts/torus.brep", "parts/b.msh"]])
        out2 = os.path.join(self.dir, "out_good")
        shutil.rmtree(out2, ignore_errors=True)
        code, so, se = run("batch", good, "--out", out2)
        self.assertEqual(code, 0, so + se)
        self.assertEqual([r["id"] for r in sorted(records(out2), key=lambda r: r["id"])],
                         ["1", "2"])

    def test_manifest_errors_stop_before_any_row(self):
        out = os.path.join(self.dir, "out_bad_manifest")
        bad = os.path.join(self.dir, "bad.csv")
        cases = [
            (["shape", "mesh", "colour"], [["parts/torus.brep", "parts/a.msh", "red"]],
             "unknown column(s) colour"),
            (["shape", "msh"], [["parts/torus.brep", "parts/a.msh"]], "no 'mesh' column"),
            (["id", "shape", "mesh"], [["x", "parts/torus.brep", "parts/a.msh"],
                                       ["x", "parts/torus.brep", "parts/b.msh"]],
             "id 'x' is also the id of line 2"),
            (["shape", "mesh"], [], "has a header but no rows"),
        ]
        for header, rows, message in cases:
            write_manifest(bad, header, rows)
            shutil.rmtree(out, ignore_errors=True)
            code, so, se = run("batch", bad, "--out", out)
            self.assertEqual(code, 2, (message, so, se))
            self.assertIn(message, se)
            self.assertFalse(os.path.exists(os.path.join(out, "results.jsonl")))
        code, so, se = run("batch", os.path.join(self.dir, "none.csv"), "--out", out)
        self.assertEqual(code, 2)
        self.assertIn("does not exist", se)

    def test_docs_example_manifest_runs(self):
        manifest = os.path.join(T.REPO, "docs", "examples", "batch_manifest.csv")
        out = os.path.join(self.dir, "out_docs_example")
        shutil.rmtree(out, ignore_errors=True)
        code, so, se = run("batch", manifest, "--out", out, "--jobs", "2")
        self.assertEqual(code, 0, so + se)
        recs = by_id(records(out))
        self.assertEqual(sorted(recs), ["crankarm-fixed", "crankarm-oddy", "crankarm-slide-vtk"])
        for rid, name in (("crankarm-fixed", "crankarm_fixed.unv"),
                          ("crankarm-slide-vtk", "crankarm_slide.vtk")):
            self.assertEqual(recs[rid]["output"], os.path.join(out, name))
            self.assertTrue(os.path.getsize(recs[rid]["output"]) > 0)
            self.assertEqual(recs[rid]["after"]["tangled"], 0)
        self.assertEqual(recs["crankarm-oddy"]["command"], "measure")

    # ---- batch on a Dask cluster ------------------------------------------------------------

    def test_dask_cluster(self):
        try:
            import distributed  # noqa: F401
        except ImportError:
            self.fail("Dask distributed is missing (python3-distributed: scripts/install.sh)")
        work = os.path.join(self.dir, "dask")
        shutil.rmtree(work, ignore_errors=True)
        os.makedirs(work)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        address = f"tcp://127.0.0.1:{port}"
        procs = []

        def start(args, log):
            procs.append(subprocess.Popen(
                [sys.executable if os.path.basename(sys.executable).startswith("python")
                 else "/usr/bin/python3", "-m"] + args,
                stdout=open(os.path.join(work, log), "w"), stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL, cwd=work, start_new_session=True))

        try:
            start(["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
                   str(port), "--no-dashboard"], "scheduler.log")
            for k in (1, 2):
                start(["distributed.cli.dask_worker", address, "--nthreads", "1",
                       "--no-dashboard", "--name", f"w{k}", "--local-directory", work],
                      f"worker{k}.log")
            from distributed import Client

            deadline = time.monotonic() + 120
            while True:
                try:
                    with Client(address, timeout="5s") as c:
                        if len(c.scheduler_info()["workers"]) == 2:
                            break
                except OSError:
                    pass
                self.assertLess(time.monotonic(), deadline, "the Dask cluster did not start")
                time.sleep(1)
            out = os.path.join(self.dir, "out_dask")
            shutil.rmtree(out, ignore_errors=True)
            code, so, se = run("batch", self.manifest, "--out", out, "--timeout", "300",
                               "--dask", address)
            self.assertEqual(code, 1, so + se)
            self.assertIn(f"on Dask scheduler {address}", so)
            recs = records(out)
            self.assertEqual(len(recs), 6)
            self.check_batch(out, recs, worker_field=True)
            workers = {r["worker"] for r in recs if r.get("worker")}
            self.assertEqual(len(workers), 2, workers)  # both workers ran rows
            self.assertEqual(processes_with(os.path.join(self.dir, "parts", "slow.msh")), [])
            # resume on the cluster: nothing left to run
            code, so, se = run("batch", self.manifest, "--out", out, "--resume", "--dask",
                               address)
            self.assertEqual(code, 1)
            self.assertIn("0 to run", so)
            self.assertEqual(len(records(out)), 6)
        finally:
            for p in procs:
                try:
                    os.killpg(p.pid, signal.SIGTERM)
                except ProcessLookupError:
                    pass
            for p in procs:
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
        # an unreachable scheduler: a clear error, no row recorded as run
        out = os.path.join(self.dir, "out_dask_down")
        shutil.rmtree(out, ignore_errors=True)
        code, so, se = run("batch", self.manifest, "--out", out, "--dask", address,
                           timeout=120)
        self.assertEqual(code, 2, so + se)
        self.assertIn(f"cannot reach the Dask scheduler at {address}", se)


if __name__ == "__main__":
    unittest.main()
