"""Periodic faces whatever their parameter range (run: freecadcmd -t): tori with v in [-π, π]
(Part.makeTorus(R, r, p, d, -180, 180)), [π, 3π] (the Part::Torus feature), [-π/2, 3π/2] and
[0, 2π], and the feature sphere and cylinder. Each mesh is tangled by moving its nodes in the
torus's own angles (closed form, not the face's parameters), measured and optimized; checked
with closed-form distances and an independent orientation test."""

import unittest

import FreeCAD
import numpy as np

import surfmesh_testing as T

R, r = 10.0, 4.0


def torus_faces(doc):
    import Part

    out = []
    for lo, hi in ((-180, 180), (0, 360), (-90, 270)):
        shape = Part.makeTorus(R, r, FreeCAD.Vector(), FreeCAD.Vector(0, 0, 1), lo, hi)
        out.append((f"makeTorus({lo}, {hi})", shape))
    feat = doc.addObject("Part::Torus", "Torus")
    feat.Radius1, feat.Radius2 = R, r
    doc.recompute()
    out.append(("Part::Torus", feat.Shape))
    return out


def tangled_torus_mesh(shape, seed):
    """A MeshPart triangulation of the torus ``shape``, its nodes moved in the torus's angles
    (double precision arrays), as SurfMesh's MeshData."""
    import MeshPart

    from SurfMesh.app import conversion

    m = MeshPart.meshFromShape(Shape=shape, MaxLength=1.5)
    xyz = np.array([[p.x, p.y, p.z] for p in m.Points])
    tris = np.array([f.PointIndices for f in m.Facets], dtype=np.int64)
    new = T.perturbed_on_torus(xyz, seed, 0.04, 0.12, R, r)
    return conversion.from_arrays(new, tris), new, tris


class TestPeriodicRanges(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshPeriodicTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_tori_of_every_parameter_range_are_measured_and_untangled(self):
        import SurfMesh

        ranges = []
        for k, (name, shape) in enumerate(torus_faces(self.doc)):
            with self.subTest(torus=name):
                face = shape.Faces[0]
                ranges.append(tuple(round(x, 6) for x in face.ParameterRange[2:]))
                data, xyz, tris = tangled_torus_mesh(shape, 11 + k)
                _, tangled0 = T.reference_tri_quality(xyz, tris, face)
                rep = SurfMesh.measure(data, shape)
                self.assertEqual(rep.stats["tangled"], int(tangled0.sum()))
                self.assertGreater(rep.stats["tangled"], 10)
                res = SurfMesh.optimize(data, shape)
                self.assertEqual(res.after.stats["tangled"], 0)
                self.assertLess(T.torus_distance(res.nodes, R, r).max(), 1e-12 * 28.0)
                q, tangled = T.reference_tri_quality(res.nodes, tris, face)
                self.assertFalse(tangled.any())
                self.assertAlmostEqual(q.min(), res.after.stats["min"], places=9)
                self.assertGreater(res.after.stats["min"], 0.5)
        # the faces really start their v range at -π, 0, -π/2 and π
        self.assertEqual(sorted(r0 for r0, _ in ranges),
                         sorted([round(-np.pi, 6), 0.0, round(-np.pi / 2, 6), round(np.pi, 6)]))

    def test_the_same_torus_from_zero_for_gmsh(self):
        """Gmsh 4.13 refuses the Part::Torus's face (v in [π, 3π]); examples.make_gmsh_mesh
        then meshes the same surface over [0, 2π]: the same points, placed where the part is."""
        import Part

        from SurfMesh.app import examples

        feat = self.doc.addObject("Part::Torus", "Torus")
        feat.Radius1, feat.Radius2 = R, r
        feat.Placement.Base = FreeCAD.Vector(3, -2, 5)
        self.doc.recompute()
        same = examples._periodic_from_zero(feat.Shape)
        self.assertIsNotNone(same)
        self.assertEqual(tuple(round(x, 12) for x in same.Faces[0].ParameterRange),
                         (0.0, round(2 * np.pi, 12), 0.0, round(2 * np.pi, 12)))
        f = same.Faces[0]
        g = feat.Shape.Faces[0]
        for u in np.linspace(0, 2 * np.pi, 7):
            for v in np.linspace(0, 2 * np.pi, 7):
                p = f.valueAt(u, v)
                self.assertLess(feat.Shape.distToShape(Part.Vertex(p))[0], 1e-9)
                # the same side out: Gmsh winds the mesh by the face's normal
                gu, gv = g.Surface.parameter(p)
                self.assertGreater(f.normalAt(u, v).dot(g.normalAt(gu, gv)), 0.999)
        self.assertAlmostEqual(f.Area, feat.Shape.Area, places=9)
        self.assertIsNone(examples._periodic_from_zero(Part.makeBox(1, 2, 3)))
        self.assertIsNone(examples._periodic_from_zero(Part.makeTorus(R, r)))  # from 0 already

    def test_feature_sphere_and_cylinder(self):
        import MeshPart

        import SurfMesh

        sphere = self.doc.addObject("Part::Sphere", "Sphere")
        sphere.Radius = 5.0
        cyl = self.doc.addObject("Part::Cylinder", "Cylinder")
        cyl.Radius, cyl.Height = 3.0, 10.0
        self.doc.recompute()
        for obj in (sphere, cyl):
            with self.subTest(shape=obj.TypeId):
                m = MeshPart.meshFromShape(Shape=obj.Shape, MaxLength=0.8)
                res = SurfMesh.optimize(m, obj.Shape)
                self.assertEqual(res.after.stats["tangled"], 0)
                self.assertGreaterEqual(res.after.stats["min"], res.before.stats["min"])
                d = T.distance_to_shape(obj.Shape, res.nodes)
                self.assertLess(d.max(), 2e-6)  # unmoved nodes keep float32 positions


if __name__ == "__main__":
    unittest.main()
