"""SurfMesh.app.compat, the differences between FreeCAD 0.20, 1.0 and 1.1 (run: freecadcmd -t),
each checked on the FreeCAD the suite runs in, and the script arguments of both releases."""

import os
import subprocess
import unittest

import FreeCAD

import surfmesh_testing as T


class TestCompat(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshCompatTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_version(self):
        from SurfMesh.app import compat

        v = compat.freecad_version()
        self.assertEqual(len(v), 3)
        self.assertEqual(".".join(map(str, v[:2])), ".".join(FreeCAD.Version()[:2]))
        self.assertIn(v[:2], ((0, 20), (0, 21), (1, 0), (1, 1), (1, 2)))

    def test_script_args_of_every_release(self):
        from SurfMesh.app import compat

        # FreeCAD 0.20, 1.x, plain Python
        self.assertEqual(compat.script_args(["s.py", "--", "a", "b"]), ["a", "b"])
        self.assertEqual(compat.script_args(["freecadcmd", "s.py", "--", "a", "b"]), ["a", "b"])
        self.assertEqual(compat.script_args(["s.py", "a", "b"]), ["a", "b"])
        self.assertEqual(compat.script_args(["freecadcmd", "s.py", "--"]), [])

    def test_script_args_in_this_freecadcmd(self):
        """A script run as freecadcmd script.py -- a b gets [a, b], whatever this FreeCAD puts
        in sys.argv (the command line's and the demo's arguments come through here)."""
        import SurfMesh.app.compat as compat_module

        script = os.path.join(T.output_dir(), "compat_args.py")
        out = os.path.join(T.output_dir(), "compat_args.txt")
        with open(script, "w") as fh:
            fh.write("import sys\n"
                     f"sys.path.insert(0, {os.path.dirname(os.path.dirname(os.path.dirname(compat_module.__file__)))!r})\n"
                     "from SurfMesh.app import compat\n"
                     f"open({out!r}, 'w').write(repr(compat.script_args()))\n")
        if os.path.exists(out):
            os.remove(out)
        subprocess.run(["freecadcmd", script, "--", "first", "second value"], timeout=300,
                       stdin=subprocess.DEVNULL, capture_output=True)
        with open(out) as fh:
            self.assertEqual(fh.read(), repr(["first", "second value"]))

    def test_mesh_shape_link_of_gmsh_and_plain_fem_meshes(self):
        import ObjectsFem
        import Part

        from SurfMesh.app import compat, shapes

        box = self.doc.addObject("Part::Box", "Box")
        self.doc.recompute()
        gm = ObjectsFem.makeMeshGmsh(self.doc, "GmshMesh")
        name = compat.mesh_shape_link(gm)
        self.assertIn(name, compat.MESH_SHAPE_LINKS)
        # 0.20 names it Part, 1.x Shape
        self.assertEqual(name, "Part" if compat.freecad_version() < (1, 0, 0) else "Shape")
        self.assertEqual(compat.set_mesh_shape(gm, box), name)
        self.assertIs(getattr(gm, name), box)
        self.assertIs(shapes.source_shape_object(gm), box)
        plain = self.doc.addObject("Fem::FemMeshObject", "Plain")
        self.assertIsNone(compat.mesh_shape_link(plain))
        self.assertEqual(compat.set_mesh_shape(plain, box), "Part")
        self.assertIs(plain.Part, box)
        self.assertIs(shapes.source_shape_object(plain), box)
        self.assertTrue(Part.Shape)  # Part imported: the link is to a shape object

    def test_gmsh_mesher_messages(self):
        """FEM's Gmsh mesher through compat: its messages as text on every release (1.1's
        create_mesh returns None), the mesh on the object."""
        import ObjectsFem

        from SurfMesh.app import compat

        box = self.doc.addObject("Part::Box", "Box")
        self.doc.recompute()
        gm = ObjectsFem.makeMeshGmsh(self.doc, "GmshMesh")
        compat.set_mesh_shape(gm, box)
        gm.ElementDimension = "2D"
        gm.CharacteristicLengthMax = 4.0
        self.doc.recompute()
        message = compat.run_gmsh_mesher(gm)
        self.assertIsInstance(message, str)
        self.assertGreater(gm.FemMesh.FaceCount, 12)
        self.assertEqual(gm.FemMesh.VolumeCount, 0)

    def test_view_material_flattened_and_restored(self):
        """1.x's default FEM view material lightens per-node colors (ambient 0.33, specular
        0.53): flattened while SurfMesh's colors show, given back after; 0.20's views have no
        ShapeAppearance and are left alone."""
        from SurfMesh.app import compat

        class View:
            def __init__(self):
                m = FreeCAD.Material()
                m.AmbientColor = (0.333, 0.333, 0.333)
                m.SpecularColor = (0.533, 0.533, 0.533)
                m.DiffuseColor = (1.0, 0.7, 0.0)
                self.PropertiesList = ["ShapeAppearance"]
                self.ShapeAppearance = [m]
                self.status = []

            def setPropertyStatus(self, name, status):
                self.status.append((name, status))

        v = View()
        saved = compat.flatten_view_material(v)
        m = v.ShapeAppearance[0]
        self.assertEqual(tuple(m.AmbientColor)[:3], (0.0, 0.0, 0.0))
        self.assertEqual(tuple(m.SpecularColor)[:3], (0.0, 0.0, 0.0))
        self.assertAlmostEqual(tuple(m.DiffuseColor)[1], 0.7, places=6)  # its own color stays
        self.assertIn(("ShapeAppearance", "NoModify"), v.status)
        self.assertIsNone(compat.flatten_view_material(v))  # already flat: nothing to record
        compat.restore_view_material(v, saved)
        self.assertAlmostEqual(tuple(v.ShapeAppearance[0].AmbientColor)[0], 0.333, places=6)
        self.assertAlmostEqual(tuple(v.ShapeAppearance[0].SpecularColor)[0], 0.533, places=6)

        class OldView:
            PropertiesList = []

        self.assertIsNone(compat.flatten_view_material(OldView()))

    def test_qt_flags(self):
        from SurfMesh.app import compat

        self.assertEqual(compat.qt_flags(0x400 | 0x400000), 0x400400)

        class Flag:  # PySide6's enums: no int(), a value
            value = 0x400400

            def __int__(self):
                raise TypeError("int() argument must be ... not 'StandardButton'")

        self.assertEqual(compat.qt_flags(Flag()), 0x400400)

    def test_fem_color_mode(self):
        """1.x draws a FEM view's colors only in the ColorMode they were set for; a view without
        that property (0.20) is left alone. (The GUI suite draws them for real.)"""
        from SurfMesh.app import compat

        class View:
            def __init__(self, with_mode):
                self.PropertiesList = ["ColorMode"] if with_mode else []
                if with_mode:
                    self.ColorMode = "Overall"

        v = View(True)
        compat.show_fem_colors(v, "element")
        self.assertEqual(v.ColorMode, "ByElement")
        compat.show_fem_colors(v, "node")
        self.assertEqual(v.ColorMode, "ByNode")
        compat.hide_fem_colors(v)
        self.assertEqual(v.ColorMode, "Overall")
        old = View(False)
        compat.show_fem_colors(old, "element")
        compat.hide_fem_colors(old)
        self.assertFalse(hasattr(old, "ColorMode"))


if __name__ == "__main__":
    unittest.main()
