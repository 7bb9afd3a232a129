"""Gmsh never runs in the FreeCAD process (run: freecadcmd -t): fileio reads and writes .msh files
through gmsh_worker.py in a child process. The FreeCAD process never imports gmsh; the files are
the ones Gmsh's API writes in process, byte for byte; a Gmsh that aborts, fails, hangs or cannot
be found gives a clear error naming the file, and the process that asked lives on."""

import contextlib
import importlib.abc
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
import unittest

import numpy as np

import surfmesh_testing as T
from SurfMesh.app import conversion, fileio


def square_grid(n=3, size=10.0):
    """Nodes (n×n, z = 0) and counter-clockwise triangles of a square."""
    xs = np.linspace(0.0, size, n)
    nodes = np.array([(x, y, 0.0) for y in xs for x in xs])
    tris = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            tris += [(a, b, c), (a, c, d)]
    return nodes, np.array(tris)


def write_msh(path, nodes, tris, lines=()):
    """Gmsh .msh 2.2 (ASCII): 1-based node ids, the triangles, then 2-node line elements."""
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(nodes))
        for i, p in enumerate(nodes):
            f.write("%d %r %r %r\n" % (i + 1, float(p[0]), float(p[1]), float(p[2])))
        f.write("$EndNodes\n$Elements\n%d\n" % (len(tris) + len(lines)))
        for e, t in enumerate(tris):
            f.write("%d 2 2 1 1 %s\n" % (e + 1, " ".join(str(int(k) + 1) for k in t)))
        for e, ln in enumerate(lines):
            f.write("%d 1 2 2 1 %s\n" % (len(tris) + e + 1, " ".join(str(int(k) + 1)
                                                                    for k in ln)))
        f.write("$EndElements\n")


class _NoGmsh(importlib.abc.MetaPathFinder):
    """Refuses (and counts) every import of gmsh."""

    def __init__(self):
        self.asked = []

    def find_spec(self, fullname, path=None, target=None):
        if fullname == "gmsh" or fullname.startswith("gmsh."):
            self.asked.append(fullname)
            raise ImportError(f"{fullname} imported in the FreeCAD process")
        return None


@contextlib.contextmanager
def environ(**values):
    """os.environ with ``values`` set (None: removed), restored after."""
    def put(items):
        for k, v in items.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v

    saved = {k: os.environ.get(k) for k in values}
    try:
        put(values)
        yield
    finally:
        put(saved)


FAKE_GMSH = '''
import os, sys, time
__version__ = "0.0 (a test's fake Gmsh)"
class option:
    @staticmethod
    def setNumber(name, value):
        pass
def initialize(*args, **kwargs):
    pass
def clear():
    pass
def open(path):
{body}
'''


class GmshIsolation(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="surfmesh-gmsh-isolation-")
        cls.dir = cls.tmp.name
        cls.nodes, cls.tris = square_grid()
        cls.msh = os.path.join(cls.dir, "square.msh")
        write_msh(cls.msh, cls.nodes, cls.tris, lines=[(0, 1), (1, 2)])

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def moved(self, mf):
        return mf.data.nodes + np.array([0.0, 0.0, 0.25])

    def fake_gmsh(self, body):
        """A folder holding a gmsh.py whose open() runs ``body``; put first on PYTHONPATH,
        the worker imports it instead of Gmsh."""
        d = tempfile.mkdtemp(prefix="fake-gmsh-", dir=self.dir)
        with open(os.path.join(d, "gmsh.py"), "w") as f:
            f.write(FAKE_GMSH.format(body=textwrap.indent(textwrap.dedent(body), "    ")))
        path = os.environ.get("PYTHONPATH")
        return environ(PYTHONPATH=d + (os.pathsep + path if path else ""))

    def out(self, name):
        path = os.path.join(self.dir, name)
        if os.path.exists(path):
            os.remove(path)
        return path

    # -- (a) no Gmsh in this process -------------------------------------------------------------
    def test_fileio_never_imports_gmsh(self):
        # gmsh is hidden from this process (another test may have imported it) and refused:
        # reading, writing both ways and the 1D elements for a VTU go through the worker.
        saved = {k: sys.modules.pop(k) for k in list(sys.modules)
                 if k == "gmsh" or k.startswith("gmsh.")}
        guard = _NoGmsh()
        sys.meta_path.insert(0, guard)
        try:
            mf = fileio.read_mesh(self.msh)
            self.assertEqual((mf.fmt, mf.msh_version), ("gmsh", 2.2))
            np.testing.assert_array_equal(mf.data.nodes, self.nodes)
            self.assertEqual(mf.data.element_count, len(self.tris))
            new = self.moved(mf)
            for version in (2.2, 4.1):
                out = self.out(f"moved_{version}.msh")
                fileio.write_mesh(out, mf, new, msh_version=version)
                back = fileio.read_mesh(out)
                self.assertEqual(back.msh_version, version)
                np.testing.assert_array_equal(back.data.nodes, new)
                np.testing.assert_array_equal(back.data.conn, mf.data.conn)
            # a mesh of another format: a new Gmsh model (0-based ids shifted by one)
            data = conversion.MeshData(
                kind="arrays", nodes=self.nodes, types=np.zeros(len(self.tris), np.int64),
                offsets=np.arange(0, 3 * len(self.tris) + 1, 3, dtype=np.int64),
                conn=self.tris.reshape(-1).astype(np.int64),
                node_ids=np.arange(len(self.nodes), dtype=np.int64),
                element_ids=np.arange(len(self.tris), dtype=np.int64))
            out = self.out("new_model.msh")
            fileio.write_mesh(out, fileio.MeshFile("square.stl", "mesh", data), self.nodes)
            back = fileio.read_mesh(out)
            np.testing.assert_array_equal(back.data.node_ids, data.node_ids + 1)
            np.testing.assert_array_equal(back.data.conn, data.conn)
            cells = fileio._line_cells(mf)  # what a .vtu output of this .msh keeps
            self.assertEqual([(n, c.tolist()) for n, c in cells], [("line", [[0, 1], [1, 2]])])
        finally:
            sys.meta_path.remove(guard)
            sys.modules.update(saved)
        self.assertEqual(guard.asked, [])
        self.assertNotIn("gmsh", set(sys.modules) - set(saved))

    def test_a_fresh_freecad_process_never_loads_gmsh(self):
        script = os.path.join(self.dir, "read_write.py")
        out = self.out("fresh.msh")
        with open(script, "w") as f:
            f.write(textwrap.dedent(f"""
                import sys
                from SurfMesh.app import fileio
                mf = fileio.read_mesh({self.msh!r})
                fileio.write_mesh({out!r}, mf, mf.data.nodes, msh_version=4.1)
                print("gmsh loaded:", "gmsh" in sys.modules)
            """))
        p = subprocess.run(["freecadcmd", script], capture_output=True, text=True, timeout=300,
                           stdin=subprocess.DEVNULL)
        self.assertIn("gmsh loaded: False", p.stdout, p.stdout[-2000:] + p.stderr[-2000:])
        self.assertTrue(os.path.exists(out))

    # -- the same files as Gmsh's API in process -------------------------------------------------
    def test_files_are_those_gmsh_writes_in_process(self):
        mf = fileio.read_mesh(self.msh)
        new = self.moved(mf)
        gmsh = fileio._gmsh()  # Gmsh in this (the test's) process, as fileio used it before
        for version in (2.2, 4.1):
            with self.subTest(version=version, model="the input's"):
                out, ref = self.out(f"worker_{version}.msh"), self.out(f"ref_{version}.msh")
                fileio.write_mesh(out, mf, new, msh_version=version)
                gmsh.clear()
                gmsh.open(self.msh)
                for tag, xyz in zip(mf.data.node_ids.tolist(), new.tolist()):
                    gmsh.model.mesh.setNode(int(tag), xyz, [])
                gmsh.option.setNumber("Mesh.MshFileVersion", version)
                gmsh.option.setNumber("Mesh.SaveAll", 1)
                gmsh.option.setNumber("Mesh.Binary", 0)
                gmsh.write(ref)
                with open(out, "rb") as a, open(ref, "rb") as b:
                    self.assertEqual(a.read(), b.read())
            with self.subTest(version=version, model="new"):
                src = fileio.MeshFile("square.obj", "mesh", mf.data)
                out, ref = self.out(f"worker_new_{version}.msh"), self.out(f"ref_new_{version}.msh")
                fileio.write_mesh(out, src, new, msh_version=version)
                gmsh.clear()
                gmsh.model.add("surfmesh")
                gmsh.model.addDiscreteEntity(2, 1)
                gmsh.model.mesh.addNodes(2, 1, mf.data.node_ids.tolist(), new.reshape(-1).tolist())
                gmsh.model.mesh.addElementsByType(
                    1, 2, mf.data.element_ids.tolist(),
                    mf.data.node_ids[mf.data.conn].tolist())
                gmsh.option.setNumber("Mesh.MshFileVersion", version)
                gmsh.option.setNumber("Mesh.SaveAll", 1)
                gmsh.option.setNumber("Mesh.Binary", 0)
                gmsh.write(ref)
                with open(out, "rb") as a, open(ref, "rb") as b:
                    self.assertEqual(a.read(), b.read())
        gmsh.clear()

    # -- (b) a failing Gmsh: an error, this process lives on --------------------------------------
    def check_error(self, cm, *fragments):
        msg = str(cm.exception)
        for f in fragments:
            self.assertIn(f, msg)
        return msg

    def test_gmsh_abort_is_an_error_and_this_process_lives_on(self):
        mf = fileio.read_mesh(self.msh)
        body = """
            sys.stderr.write("terminate called after throwing an instance of 'FakeGmshError'\\n")
            sys.stderr.flush()
            os.abort()
        """
        with self.fake_gmsh(body):
            with self.assertRaises(fileio.GmshProcessError) as cm:
                fileio.read_mesh(self.msh)
            self.check_error(cm, f"reading {self.msh}", "SIGABRT", "FakeGmshError",
                             "FreeCAD session is unaffected")
            self.assertIsInstance(cm.exception, ValueError)  # the CLI: exit 2, one line
            self.assertNotIn("\n", str(cm.exception))
            out = self.out("aborted.msh")
            with self.assertRaises(fileio.GmshProcessError) as cm:
                fileio.write_mesh(out, mf, mf.data.nodes)
            self.check_error(cm, f"writing {out}", "SIGABRT", "FreeCAD session is unaffected")
            self.assertFalse(os.path.exists(out), "a partial output was left")
        # and Gmsh works again afterwards, in this same process
        self.assertEqual(fileio.read_mesh(self.msh).data.element_count, len(self.tris))

    def test_gmsh_abort_through_the_cli(self):
        # The command's own process would die with Gmsh (exit -6): it says what happened.
        import Part

        brep = os.path.join(self.dir, "square.brep")
        Part.makePlane(10, 10).exportBrep(brep)
        with self.fake_gmsh("os.abort()"):
            p = subprocess.run(["freecadcmd", T.cli_path(), "--", "measure", brep, self.msh],
                               capture_output=True, text=True, timeout=300,
                               stdin=subprocess.DEVNULL, env=dict(os.environ))
        text = p.stdout + p.stderr
        self.assertEqual(p.returncode, 2, text[-2000:])
        self.assertNotIn("Traceback", text)
        self.assertIn(f"surfmesh: error: Gmsh failed reading {self.msh}", text)
        self.assertIn("SIGABRT", text)

    def test_gmsh_exception_reads_as_before(self):
        # Gmsh refusing the file (its API raises): the message it always gave.
        with self.fake_gmsh('raise Exception("Fake Gmsh: unknown mesh format")'):
            with self.assertRaises(ValueError) as cm:
                fileio.read_mesh(self.msh)
        self.assertEqual(str(cm.exception),
                         f"Gmsh cannot read {self.msh}: Fake Gmsh: unknown mesh format")

    def test_worker_failure_names_the_exit_status_and_what_was_said(self):
        with self.fake_gmsh('raise SystemExit("Fake Gmsh: out of memory")'):
            with self.assertRaises(fileio.GmshProcessError) as cm:
                fileio.read_mesh(self.msh)
        self.check_error(cm, self.msh, "exited with status 1", "Fake Gmsh: out of memory",
                         "FreeCAD session is unaffected")

    def test_gmsh_that_hangs_is_stopped(self):
        t0 = time.monotonic()
        with self.fake_gmsh("time.sleep(120)"), environ(SURFMESH_GMSH_TIMEOUT="1.5"):
            with self.assertRaises(fileio.GmshProcessError) as cm:
                fileio.read_mesh(self.msh)
        self.assertLess(time.monotonic() - t0, 60)
        self.check_error(cm, self.msh, "did not finish within 1.5 s",
                         "FreeCAD session is unaffected")

    def test_gmsh_import_that_hangs_is_a_timeout(self):
        # Stopped while still importing Gmsh (a machine so loaded that the import outlasts the
        # limit): a timeout, not "no Python imports Gmsh", and no other Python is tried.
        d = tempfile.mkdtemp(prefix="slow-gmsh-", dir=self.dir)
        with open(os.path.join(d, "gmsh.py"), "w") as f:
            f.write("import time\ntime.sleep(120)\n")
        path = os.environ.get("PYTHONPATH")
        t0 = time.monotonic()
        with environ(PYTHONPATH=d + (os.pathsep + path if path else ""),
                     SURFMESH_GMSH_TIMEOUT="1.5"):
            with self.assertRaises(fileio.GmshProcessError) as cm:
                fileio.read_mesh(self.msh)
        self.assertLess(time.monotonic() - t0, 20)
        self.check_error(cm, self.msh, "did not finish within 1.5 s",
                         "FreeCAD session is unaffected")
        self.assertNotIn("no Python here imports", str(cm.exception))

    def test_no_python_with_gmsh(self):
        for python in (os.path.join(self.dir, "no_such_python"), shutil.which("true")):
            with self.subTest(python=python), environ(SURFMESH_GMSH_PYTHON=python):
                with self.assertRaises(fileio.GmshProcessError) as cm:
                    fileio.read_mesh(self.msh)
                self.check_error(cm, f"cannot run Gmsh for reading {self.msh}", python,
                                 "SURFMESH_GMSH_PYTHON")


if __name__ == "__main__":
    unittest.main()
