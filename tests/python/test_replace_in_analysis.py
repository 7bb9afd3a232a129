"""optimize_object on a FEM mesh in an analysis: by default the result takes the original's
place in the analysis (same position), linked to the original's shape, and the original
leaves it — in one undo step; FEM's own queries (femtools.membertools.get_mesh_to_solve, the
shape link femmesh.meshsetsgetter reads) see the result. replace_in_analysis=False leaves the
analysis alone; asking for it with a mesh in no analysis is refused.

Run by scripts/test.sh (``freecadcmd -t test_replace_in_analysis -M tests/python``).
"""

import unittest

import FreeCAD as App
import ObjectsFem

import SurfMesh
from SurfMesh.app import examples


class ReplaceInAnalysis(unittest.TestCase):
    def setUp(self):
        self.doc = App.newDocument("SurfMeshAnalysis")
        self.doc.UndoMode = 1
        self.tor = examples.make_torus(self.doc)
        self.mesh = examples.make_gmsh_mesh(self.doc, self.tor, 2.0, name="TorusMesh")
        examples.tangle_to(self.mesh, self.tor.Shape, target=10, seed=3)
        self.analysis = ObjectsFem.makeAnalysis(self.doc, "Analysis")
        self.material = ObjectsFem.makeMaterialSolid(self.doc, "Material")
        self.analysis.addObject(self.material)
        self.analysis.addObject(self.mesh)
        self.doc.recompute()

    def tearDown(self):
        App.closeDocument(self.doc.Name)

    def test_default_replaces_in_one_undo_step(self):
        from femtools import membertools

        group0 = list(self.analysis.Group)
        undo0 = self.doc.UndoCount
        new = SurfMesh.optimize_object(self.mesh)
        self.assertEqual(SurfMesh.stats_of(new)["tangled"], 0)
        self.assertEqual(self.analysis.Group, [self.material, new])  # the mesh's place
        self.assertIn(self.mesh, self.doc.Objects)  # kept in the document
        self.assertIs(new.Part, self.tor)
        self.assertEqual(membertools.get_mesh_to_solve(self.analysis), (new, ""))
        self.assertEqual(self.doc.UndoCount, undo0 + 1)
        self.doc.undo()
        self.assertEqual(self.analysis.Group, group0)
        self.assertIsNone(self.doc.getObject("TorusMesh_optimized"))
        self.assertEqual(membertools.get_mesh_to_solve(self.analysis), (self.mesh, ""))

    def test_off_leaves_the_analysis(self):
        new = SurfMesh.optimize_object(self.mesh, replace_in_analysis=False)
        self.assertEqual(self.analysis.Group, [self.material, self.mesh])
        self.assertNotIn("Part", new.PropertiesList)

    def test_refused_for_a_mesh_in_no_analysis(self):
        self.analysis.removeObject(self.mesh)
        names = {o.Name for o in self.doc.Objects}
        with self.assertRaisesRegex(ValueError, "'TorusMesh' is in no FEM analysis"):
            SurfMesh.optimize_object(self.mesh, replace_in_analysis=True)
        self.assertEqual({o.Name for o in self.doc.Objects}, names)


if __name__ == "__main__":
    unittest.main()
