"""What SurfMesh noticed reading a mesh, told once per mesh in a user's words: the bridge's
warnings on Gmsh's second-order mesh of the crank arm (nodes of no element, collapsed elements
left out, side nodes far from their sides) become one note each, with the counts of the
warnings; a second command on the mesh, or on a mesh optimized from it, tells nothing new;
the details keep the full texts.

Run by scripts/test.sh (``freecadcmd -t test_notes -M tests/python``).
"""

import gzip
import os
import re
import shutil
import unittest

import FreeCAD as App
import Fem
import Part

import SurfMesh
import surfmesh_testing as T
from SurfMesh.app import notes


class Notes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.inp = os.path.join(T.output_dir(), "notes_crankarm_order2.inp")
        with gzip.open(os.path.join(T.data_dir(), "occt_crankarm_gmsh_order2.inp.gz")) as src, \
                open(cls.inp, "wb") as dst:
            shutil.copyfileobj(src, dst)

    def setUp(self):
        self.doc = App.newDocument("SurfMeshNotes")
        self.doc.UndoMode = 1
        self.part = self.doc.addObject("Part::Feature", "CrankArm")
        self.part.Shape = Part.read(os.path.join(T.data_dir(), "occt_crankarm.brep"))
        self.mesh = self.doc.addObject("Fem::FemMeshObjectPython", "Mesh2nd")
        self.mesh.FemMesh = Fem.read(self.inp)

    def tearDown(self):
        notes.forget(self.doc.Name)
        App.closeDocument(self.doc.Name)

    def test_user_words_with_the_warnings_counts(self):
        rep = SurfMesh.measure(self.mesh, self.part)
        diagnostics = rep.bridge["diagnostics"]
        # the warnings are the diagnostics' texts
        self.assertEqual(rep.bridge["warnings"], [d["text"] for d in diagnostics])
        words = dict(notes.user_words(d) for d in diagnostics)
        self.assertEqual(set(words), {"unused_nodes", "left_out", "node_order"},
                         rep.bridge["warnings"])
        for d in diagnostics:  # the counts as the warnings' texts give them
            w = d["text"]
            if d["code"] == "left_out":
                n = sum(int(k) for k in re.findall(r"(\d+) [a-z-]*\s*element",
                                                   w.split(": ids")[0]))
                self.assertEqual(n, len(rep.bridge["skipped_elements"]))
            else:
                n = int(re.match(r"\D*(\d+)", w).group(1))
            self.assertEqual(d["count"], n, w)
            self.assertTrue(words[d["code"]].startswith(f"{n} "), (d["code"], words[d["code"]]))
        for text in words.values():
            self.assertNotRegex(text, r"node order corners first, then|\?")
        # every id a diagnostic names is one of the mesh's (FEM ids)
        fem = self.mesh.FemMesh
        for d in diagnostics:
            self.assertTrue(set(d["nodes"]) <= set(fem.Nodes), d)
            self.assertTrue(set(d["elements"]) <= set(fem.Faces) | set(fem.Edges), d)

    def test_once_per_mesh_and_its_optimized_meshes(self):
        SurfMesh.measure_object(self.mesh, self.part)
        told = notes.details(self.mesh)
        self.assertEqual(len(told), 3)
        rep = SurfMesh.measure(self.mesh, self.part)
        self.assertEqual(notes.new_notes(self.mesh, rep.bridge["diagnostics"]), [])
        # a mesh optimized from it (its SurfMeshOriginal) is the same mesh for the notes
        child = self.doc.addObject("Fem::FemMeshObjectPython", "Mesh2nd_optimized")
        child.addProperty("App::PropertyLink", "SurfMeshOriginal", "SurfMesh")
        child.SurfMeshOriginal = self.mesh
        changed = [dict(d, count=7, text=re.sub(r"\d+", "7", d["text"]))  # other counts
                   for d in rep.bridge["diagnostics"]]
        self.assertEqual(notes.new_notes(child, changed), [])
        self.assertEqual(notes.details(child), [d["text"] for d in changed])  # the latest texts
        other = self.doc.addObject("Fem::FemMeshObjectPython", "Other")
        self.assertEqual(len(notes.new_notes(other, changed)), 3)


if __name__ == "__main__":
    unittest.main()
