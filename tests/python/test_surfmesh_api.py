"""SurfMesh.measure / SurfMesh.optimize on Mesh and FEM tria3 inputs (run: freecadcmd -t).

References are independent of SurfMesh: planar triangle shape quality with FreeCAD's surface
normals (surfmesh_testing.reference_tri_quality), FreeCAD's geometry queries and the torus's
closed-form distance for node positions.
"""

import os
import re
import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T


class ApiCase(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshApiTest")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)


class TestMeasure(ApiCase):
    def test_measure_names(self):
        self.assertEqual(SurfMesh.measure_names()[:2], ["shape", "oddy"])

    def test_fem_tria3_quality_matches_planar_reference(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        rep = SurfMesh.measure(mesh, tor, measure="shape")
        data = SurfMesh.app.conversion.read_mesh(mesh)
        tris = data.conn.reshape(-1, 3)
        ref_q, ref_t = T.reference_tri_quality(data.nodes, tris, tor.Shape.Faces[0])
        self.assertEqual(rep.quality.shape, (data.element_count,))
        self.assertEqual(rep.quality.dtype, np.float64)
        self.assertEqual(rep.tangled.dtype, bool)
        self.assertGreater(int(ref_t.sum()), 0, "fixture must be tangled")
        np.testing.assert_array_equal(rep.tangled, ref_t)
        np.testing.assert_allclose(rep.quality, ref_q, atol=1e-9)
        self.assertTrue(np.all((rep.quality >= 0) & (rep.quality <= 1)))
        self.assertTrue(np.all(rep.quality[rep.tangled] == 0))
        s = rep.stats
        self.assertEqual(s["elements"], data.element_count)
        self.assertEqual(s["tangled"], int(ref_t.sum()))
        self.assertAlmostEqual(s["min"], 0.0)
        self.assertAlmostEqual(s["max"], float(ref_q.max()), places=9)
        self.assertAlmostEqual(s["mean"], float(ref_q.mean()), places=9)
        self.assertAlmostEqual(s["std"], float(ref_q.std()), places=9)
        # element ids are the FEM face ids, which do not start at 1 (edges come first)
        np.testing.assert_array_equal(rep.element_ids, np.array(mesh.FemMesh.Faces))
        self.assertGreater(int(rep.element_ids.min()), 1)

    def test_mesh_input_and_document_object(self):
        tor, mobj = T.torus_mesh(self.doc)
        r1 = SurfMesh.measure(mobj, tor.Shape)  # object + Part.Shape
        r2 = SurfMesh.measure(mobj.Mesh, tor)  # Mesh.Mesh + object with .Shape
        np.testing.assert_array_equal(r1.quality, r2.quality)
        data = SurfMesh.app.conversion.read_mesh(mobj)
        ref_q, ref_t = T.reference_tri_quality(data.nodes, data.conn.reshape(-1, 3),
                                               tor.Shape.Faces[0])
        self.assertFalse(ref_t.any())
        np.testing.assert_allclose(r1.quality, ref_q, atol=1e-9)
        self.assertEqual(r1.stats["tangled"], 0)

    def test_an_element_between_two_faces_goes_on_the_face_along_its_plane(self):
        # Gmsh's curvature-sized mesh of the bottle, around an element whose corners all lie
        # on the CAD edge between a thread face and the neck's cylinder (two on one of its
        # vertices): its plane lies along the cylinder, its centroid is nearer the thread face.
        # Put on the nearer face it stood across it: tangled (no hints), or left out as a flat
        # element (FEM hints). Each face's winding is taken from its other elements, by
        # FreeCAD's normals, independently of SurfMesh.
        import Mesh
        import Part

        shape = Part.read(os.path.join(T.data_dir(), "occt_bottle.brep"))
        with open(os.path.join(T.data_dir(), "occt_bottle_neck_edge_fan.txt")) as f:
            n, e = map(int, f.readline().split())
            xyz = np.array([[float(x) for x in f.readline().split()] for _ in range(n)])
            tris = np.array([[int(x) for x in f.readline().split()] for _ in range(e)])
        seed = 185
        mesh = Mesh.Mesh([[FreeCAD.Vector(*xyz[i]) for i in t] for t in tris])
        self.assertEqual((mesh.CountPoints, mesh.CountFacets), (n, e))
        for hints in ("none", "tolerance"):
            rep = SurfMesh.measure(mesh, shape, hints=hints)
            self.assertEqual((rep.stats["invalid"], rep.stats["skipped"]), (0, 0), hints)
            data = SurfMesh.app.conversion.read_mesh(mesh)
            t = data.conn.reshape(-1, 3)
            faces = rep.element_faces
            x = data.nodes[t[seed]]
            g = np.cross(x[1] - x[0], x[2] - x[0])
            face = shape.Faces[int(faces[seed])]
            u, v = face.Surface.parameter(FreeCAD.Vector(*x.mean(axis=0)))
            nrm = face.normalAt(u, v)
            self.assertGreater(abs(np.dot(g, (nrm.x, nrm.y, nrm.z))) / np.linalg.norm(g), 0.9)
            # valid against its face's normal as the face's other elements are wound
            on = np.nonzero(faces == faces[seed])[0]
            _, tangled = T.reference_tri_quality(data.nodes, t[on], face)
            k = int(np.nonzero(on == seed)[0][0])
            majority = tangled.sum() * 2 > len(on)
            self.assertEqual(bool(tangled[k]), bool(majority), hints)
            self.assertGreaterEqual(len(on), 4)

    def test_oddy_is_lower_than_shape(self):
        # Oddy is more restrictive than shape (paper Table 2): q_oddy ≤ q_shape elementwise.
        tor, mesh = T.torus_fem(self.doc, tangled=False)
        qs = SurfMesh.measure(mesh, tor, "shape").quality
        qo = SurfMesh.measure(mesh, tor, "oddy").quality
        self.assertTrue(np.all(qo <= qs + 1e-12))
        self.assertLess(qo.mean(), qs.mean())


class TestOptimize(ApiCase):
    def test_small_face_mostly_inverted_keeps_the_winding_of_the_mesh_around_it(self):
        """On a small face, tangled elements can outnumber the rest. The face is still read
        as wound like the mesh around it, so SurfMesh counts as tangled exactly the face's
        elements inverted against FreeCAD's outward face normal, and untangles them all. (A vote of
        the face's own elements would read it as flipped: the valid ones would count as
        tangled, and the run would chase the mirror image.)"""
        import MeshPart
        import Part

        path = T.find_part("occt_bottle.brep")
        if path is None:
            self.skipTest("occt_bottle.brep not found")
        shape = Part.read(path)
        diag = shape.BoundBox.DiagonalLength
        mesh = MeshPart.meshFromShape(Shape=shape, MaxLength=diag / 30)  # Mefisto
        from SurfMesh.app import api, conversion

        data, handle = api.prepare(mesh, shape)
        self.assertEqual(handle.report["flipped_faces"], [])
        kinds = np.asarray(handle.node_kinds())
        faces = np.asarray(handle.node_faces())
        tris = np.asarray(data.conn).reshape(-1, 3)
        nodes = np.asarray(data.nodes)

        def inverted(x, elems, face):
            """Elements of ``elems`` wound against FreeCAD's outward normal of ``face``."""
            out = []
            for e in elems:
                p, q, r = x[tris[e]]
                c = FreeCAD.Vector(*((p + q + r) / 3))
                n = face.normalAt(*face.Surface.parameter(c))
                if np.dot(np.cross(q - p, r - p), [n.x, n.y, n.z]) < 0:
                    out.append(int(e))
            return out

        # The smallest face with at least three Face nodes; its Face nodes moved to random
        # points of the face until most of its elements are inverted.
        counts = np.bincount(faces[kinds == 1], minlength=len(shape.Faces))
        fid = min((int((faces[tris] == f).any(axis=1).sum()), f)
                  for f in np.nonzero(counts >= 3)[0])[1]
        face = shape.Faces[int(fid)]
        elems = np.nonzero((faces[tris] == fid).any(axis=1))[0]
        inner = np.nonzero((kinds == 1) & (faces == fid))[0]
        u0, u1, v0, v1 = face.ParameterRange
        rng = np.random.default_rng(7)
        for _ in range(2000):
            x = nodes.copy()
            for i in inner:
                while True:
                    u, v = rng.uniform(u0, u1), rng.uniform(v0, v1)
                    if face.isPartOfDomain(u, v):
                        break
                p = face.Surface.value(u, v)
                x[i] = (p.x, p.y, p.z)
            bad = inverted(x, elems, face)
            if 2 * len(bad) > len(elems):
                break
        else:
            self.fail(f"no placement of Face{fid + 1}'s nodes inverts most of its elements")
        trial = conversion.from_arrays(x, tris)
        rep = SurfMesh.measure(trial, shape)
        self.assertEqual(rep.bridge["flipped_faces"], [])
        tangled = np.asarray(rep.tangled)
        self.assertEqual(np.nonzero(tangled[elems])[0].size, len(bad))
        self.assertEqual(sorted(int(e) for e in elems[tangled[elems]]), bad)
        res = SurfMesh.optimize(trial, shape)
        self.assertEqual(res.tangled_movable, [], res.warnings)
        self.assertEqual(inverted(res.nodes, elems, face), [])
        self.assertFalse(np.asarray(res.after.tangled)[elems].any())

    def test_standard_mesh_with_cracks_along_cad_edges_is_glued(self):
        """FreeCAD's standard mesher meshes some faces apart: along those CAD edges each node
        has a twin at the same position (a crack). The twins move together, so the mesh
        stays closed (FreeCAD's own merge of coincident points gives a solid before and
        after), and every moved node stays on the part."""
        import Part

        path = T.find_part("occt_housing_bottom.brep")
        if path is None:
            self.skipTest("occt_housing_bottom.brep not found")
        shape = Part.read(path)
        diag = shape.BoundBox.DiagonalLength
        mesh = T.standard_mesh_with_cracks(shape, LinearDeflection=diag / 500,
                                           AngularDeflection=0.35, Relative=False)
        pts0 = np.array([[p.x, p.y, p.z] for p in mesh.Points])
        groups = T.coincident_groups(pts0)
        twins = np.sort(np.concatenate(groups)) if groups else np.zeros(0, dtype=int)
        self.assertGreater(len(twins), 0, "the standard mesh has no crack any more")
        merged = mesh.copy()
        merged.removeDuplicatedPoints()
        self.assertTrue(merged.isSolid())
        with self.assertRaisesRegex(ValueError, "duplicate node"):
            SurfMesh.measure(mesh, shape, duplicates="error")
        res = SurfMesh.optimize(mesh, shape, boundary="slide")
        self.assertEqual(res.bridge["glued_nodes"], len(twins) - len(groups))
        pts = np.array([[p.x, p.y, p.z] for p in res.mesh.Points])
        for idx in groups:
            np.testing.assert_array_equal(pts[idx], np.repeat(pts[idx[:1]], len(idx), axis=0))
        moved = np.nonzero(np.any(pts != pts0, axis=1))[0]
        moved_twins = np.intersect1d(moved, twins)
        self.assertGreater(len(moved_twins), 0, "no glued node slid along its edge")
        merged = res.mesh.copy()
        merged.removeDuplicatedPoints()
        self.assertTrue(merged.isSolid(), "the optimization opened a crack")
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreater(res.after.stats["mean"], res.before.stats["mean"])
        sample = np.concatenate([moved_twins[:60], moved[:: max(1, len(moved) // 60)]])
        # Mesh.Mesh stores float32 points: on the part to that precision
        self.assertLess(T.distance_to_shape(shape, pts[sample]).max(), 1e-6 * diag)

    def test_fem_untangled_on_surface_ids_kept_input_untouched(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        before = T.fem_snapshot(mesh.FemMesh)
        res = SurfMesh.optimize(mesh, tor, measure="shape", boundary="fixed")
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), before, "input changed")
        new = res.mesh
        self.assertEqual(new.TypeId, "Fem::FemMesh")
        self.assertIsNot(new, mesh.FemMesh)
        nodes0, elems0 = before
        nodes1, elems1 = T.fem_snapshot(new)
        self.assertEqual(list(nodes1), list(nodes0))  # node ids and order
        self.assertEqual(elems1, elems0)  # element ids (faces and edges) and connectivity
        self.assertGreater(res.before.stats["tangled"], 0)
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreater(res.after.stats["min"], res.before.stats["min"])
        self.assertGreater(res.after.stats["mean"], res.before.stats["mean"])
        self.assertGreater(res.sweeps, 0)
        self.assertGreater(res.seconds, 0.0)
        pts = np.array(list(nodes1.values()))
        # FEM meshes store doubles: nodes on the torus to double precision
        self.assertLess(T.torus_distance(pts).max(), 1e-9)
        self.assertLess(T.distance_to_surface(tor.Shape.Faces[0], pts[::25]).max(), 1e-7)
        moved = np.linalg.norm(pts - np.array(list(nodes0.values())), axis=1)
        self.assertGreater(int((moved > 1e-6).sum()), len(pts) // 2)
        # the after report agrees with an independent evaluation of the new mesh
        data = SurfMesh.app.conversion.read_mesh(new)
        ref_q, ref_t = T.reference_tri_quality(data.nodes, data.conn.reshape(-1, 3),
                                               tor.Shape.Faces[0])
        self.assertFalse(ref_t.any())
        np.testing.assert_allclose(res.after.quality, ref_q, atol=1e-9)

    def test_fem_tria6(self):
        from SurfMesh.app import examples

        tor = examples.make_torus(self.doc)
        mesh = examples.make_gmsh_mesh(self.doc, tor, 2.5, order="2nd")
        self.assertEqual(len(mesh.FemMesh.getElementNodes(mesh.FemMesh.Faces[0])), 6)
        before = T.fem_snapshot(mesh.FemMesh)
        res = SurfMesh.optimize(mesh, tor, measure="shape")
        self.assertEqual(res.before.element_types, ["tri6"])
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), before)
        nodes1, elems1 = T.fem_snapshot(res.mesh)
        self.assertEqual(elems1, before[1])
        self.assertEqual(list(nodes1), list(before[0]))
        pts = np.array(list(nodes1.values()))
        self.assertLess(T.torus_distance(pts).max(), 1e-9)  # mid-edge nodes too
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreaterEqual(res.after.stats["min"], res.before.stats["min"])

    def test_mesh_float32_on_surface(self):
        tor, mobj = T.torus_mesh(self.doc)
        before = T.mesh_snapshot(mobj.Mesh)
        res = SurfMesh.optimize(mobj, tor, measure="oddy")
        self.assertEqual(T.mesh_snapshot(mobj.Mesh), before, "input changed")
        self.assertTrue(SurfMesh.app.conversion.is_mesh_kernel(res.mesh))
        pts, tris = T.mesh_snapshot(res.mesh)
        self.assertEqual(tris, before[1])  # facets and their order kept
        self.assertEqual(len(pts), len(before[0]))
        pts = np.array(pts)
        # float32 storage: on the surface to float32 rounding of coordinates ~14
        self.assertLess(T.torus_distance(pts).max(), 14 * 4e-7)
        d = T.distance_to_shape(tor.Shape, pts[::40])
        self.assertLess(d.max(), 1e-5)
        # the double-precision result itself is on the surface where nodes moved; nodes that
        # did not move keep their float32 input position exactly
        data = SurfMesh.app.conversion.read_mesh(mobj.Mesh)
        moved = np.any(res.nodes != data.nodes, axis=1)
        self.assertGreater(moved.sum(), len(moved) // 2)
        self.assertLess(T.torus_distance(res.nodes[moved]).max(), 1e-9)
        self.assertGreaterEqual(res.after.stats["min"], res.before.stats["min"])
        self.assertGreater(res.after.stats["mean"], res.before.stats["mean"])

    def test_mesh_on_a_helical_sweep(self):
        """A circle swept along a five-turn helix: one B-spline face whose normal turns around
        the tube and along the helix, its turns 4 apart. Every node of FreeCAD's (float32)
        mesh inside that face is recovered on it at its own position, and the optimized nodes
        lie on the part."""
        import MeshPart
        import Part

        helix = Part.Wire(Part.makeHelix(8, 40, 15))
        circle = Part.Wire(Part.makeCircle(2, FreeCAD.Vector(15, 0, 0), FreeCAD.Vector(0, 1, 0)))
        shape = helix.makePipeShell([circle], True, True)
        sweep = [i for i, f in enumerate(shape.Faces)
                 if f.Surface.TypeId == "Part::GeomBSplineSurface"]
        self.assertEqual(len(sweep), 1)
        diag = shape.BoundBox.DiagonalLength
        m = MeshPart.meshFromShape(Shape=shape, LinearDeflection=diag / 300,
                                   AngularDeflection=0.35, Relative=False)
        data, handle = SurfMesh.app.api.prepare(m, shape)
        kinds, faces, uv = handle.node_kinds(), handle.node_faces(), handle.uv()
        inside = np.nonzero((kinds == 1) & (faces == sweep[0]))[0]
        self.assertGreater(len(inside), 0.9 * len(data.nodes))
        face = shape.Faces[sweep[0]]
        for i in inside[:: max(1, len(inside) // 400)]:
            u, v = map(float, uv[i])
            self.assertTrue(face.isPartOfDomain(u, v), f"node {i}: (u,v) outside its face")
            p = face.Surface.value(u, v)
            gap = (p - FreeCAD.Vector(*map(float, data.nodes[i]))).Length
            # float32 storage: 2^-24 of each coordinate (at most 17 here) away from the face
            self.assertLess(gap, 17 * 2e-7, f"node {i} recovered {gap} away from its position")
        res = SurfMesh.optimize(m, shape, max_sweeps=20)
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreaterEqual(res.after.stats["min"], res.before.stats["min"] - 1e-12)
        self.assertGreater(res.after.stats["mean"], res.before.stats["mean"])
        moved = np.nonzero(np.any(res.nodes != data.nodes, axis=1))[0]
        self.assertGreater(len(moved), len(inside) // 2)
        d = T.distance_to_shape(shape, res.nodes[moved[:: max(1, len(moved) // 150)]])
        self.assertLess(d.max(), 1e-9 * diag)

    def test_elements_standing_across_a_thin_tube_are_counted(self):
        """A tube of radius 2 swept along a helix, meshed by BRepMesh with about five elements
        around, its Face nodes moved in (u,v) by up to 0.3 × the median edge: triangles
        whose plane cuts across the tube (wound along the face's normal at some corners and
        against it at others) are counted in ``across``, before and after optimizing, as
        FreeCAD's own normals say, and a run that leaves some names them."""
        import MeshPart
        import Part

        helix = Part.Wire(Part.makeHelix(8, 40, 15))
        circle = Part.Wire(Part.makeCircle(2, FreeCAD.Vector(15, 0, 0), FreeCAD.Vector(0, 1, 0)))
        shape = helix.makePipeShell([circle], True, True)
        m = MeshPart.meshFromShape(Shape=shape, LinearDeflection=shape.BoundBox.DiagonalLength / 50,
                                   AngularDeflection=1.2, Relative=False)
        data, handle = SurfMesh.app.api.prepare(m, shape)
        kinds, faces, uv = handle.node_kinds(), handle.node_faces(), handle.uv()
        tris = np.asarray([f.PointIndices for f in m.Facets], dtype=np.int64)
        size = np.median(np.linalg.norm(data.nodes[tris[:, 1]] - data.nodes[tris[:, 0]], axis=1))
        rng = np.random.default_rng(1)
        moved = m.copy()
        for i in np.nonzero(kinds == 1)[0]:
            face = shape.Faces[int(faces[i])]
            u, v = map(float, uv[i])
            du, dv = face.derivative1At(u, v)
            step = 0.3 * size * rng.uniform(-1.0, 1.0, 2) / np.array([du.Length, dv.Length])
            if face.isPartOfDomain(u + step[0], v + step[1]):
                moved.setPoint(int(i), face.Surface.value(u + step[0], v + step[1]))
        nodes = np.array([(p.x, p.y, p.z) for p in moved.Points])  # as stored (float32)
        rep = SurfMesh.measure(moved, shape)
        # The reference on the flagged triangles and as many others.
        check = np.union1d(np.nonzero(rep.across)[0],
                           rng.choice(len(tris), int(rep.across.sum()), replace=False))
        ref = T.reference_across(nodes, tris, rep.element_faces, shape, check)
        np.testing.assert_array_equal(rep.across[check], ref)
        self.assertGreater(ref.sum(), 20, "the perturbation stands triangles across")
        self.assertEqual(rep.stats["across"], int(rep.across.sum()))
        self.assertEqual(rep.stats["tangled"], int(rep.tangled.sum()))
        res = SurfMesh.optimize(moved, shape)
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertEqual(res.before.stats["across"], rep.stats["across"])
        check = np.union1d(np.nonzero(res.after.across)[0],
                           rng.choice(len(tris), 200, replace=False))
        after = T.reference_across(res.nodes, tris, res.after.element_faces, shape, check)
        np.testing.assert_array_equal(res.after.across[check], after)
        said = [w for w in res.warnings if "stand across the surface" in w]
        self.assertEqual(len(said), 1 if res.after.stats["across"] else 0, res.warnings)
        if said:
            named = re.search(r"elements ([0-9, …]+)", said[0]).group(1)
            ids = [int(i) for i in named.replace("…", "").split(",") if i.strip()]
            self.assertEqual(ids, [int(i) for i in np.nonzero(res.after.across)[0][:20]])

    def test_slide_boundary_on_real_part(self):
        path = T.find_part("occt_screw.step")
        if path is None:
            self.skipTest("occt_screw.step not available")
        import MeshPart
        import Part

        shape = Part.read(path)
        m = MeshPart.meshFromShape(Shape=shape, LinearDeflection=shape.BoundBox.DiagonalLength / 300)
        res = SurfMesh.optimize(m, shape, boundary="slide", max_sweeps=20)
        self.assertEqual(res.after.stats["tangled"], 0)
        self.assertGreaterEqual(res.after.stats["min"], res.before.stats["min"] - 1e-12)
        self.assertGreater(res.bridge["sliding_nodes"], 0)
        d = T.distance_to_shape(shape, res.nodes[:: max(1, len(res.nodes) // 150)])
        self.assertLess(d.max(), 1e-6 * shape.BoundBox.DiagonalLength + 1e-7)

    def test_oddy_untangles_what_the_shape_measure_untangles(self):
        # FreeCAD's Gmsh mesh of the crank arm (diagonal / 25) around one tangled sliver at a
        # fillet next to a tolerant CAD edge (tests/data/occt_crankarm_fillet_fold.unv, two
        # rings of elements, 654): untangling it takes a node where OCC counts it on that edge,
        # which smoothing moves avoid. Both measures untangle it (where the Oddy run alone
        # cannot, the run untangles with the shape measure first, then optimizes with Oddy).
        import os

        import Fem
        import Part

        from SurfMesh.app import conversion

        shape = Part.Shape()
        shape.read(os.path.join(T.data_dir(), "occt_crankarm.brep"))
        fem = Fem.read(os.path.join(T.data_dir(), "occt_crankarm_fillet_fold.unv"))
        diag = shape.BoundBox.DiagonalLength
        for boundary in ("fixed", "slide"):
            with self.subTest(boundary=boundary):
                by_shape = SurfMesh.optimize(fem, shape, measure="shape", boundary=boundary)
                self.assertEqual(by_shape.after.stats["tangled"], 0)
                res = SurfMesh.optimize(fem, shape, measure="oddy", boundary=boundary)
                self.assertEqual(res.before.stats["tangled"], 1)
                self.assertEqual(res.after.stats["tangled"], 0, res.warnings)
                self.assertEqual(res.tangled_movable, [])
                # measured with Oddy, as asked; the nodes it moved lie on the part
                self.assertEqual(res.after.measure, "oddy")
                again = SurfMesh.measure(res.mesh, shape, measure="oddy")
                self.assertEqual(again.stats["tangled"], 0)
                self.assertAlmostEqual(again.stats["mean"], res.after.stats["mean"], places=9)
                x0 = conversion.read_mesh(fem).nodes
                moved = np.nonzero(np.any(res.nodes != x0, axis=1))[0]
                self.assertGreater(len(moved), 0)
                # (FreeCAD's distToShape near a trimming loop: up to 3e-8 × diagonal)
                self.assertLess(T.distance_to_shape(shape, res.nodes[moved]).max(), 1e-7 * diag)

    def test_unrepairable_tangled_elements_are_named(self):
        # BRepMesh leaves tangled triangles on the propeller's blades; two have every node on
        # CAD vertices or edges (the surface turns by more than 100° across them): a fixed
        # boundary cannot repair them, and the result names them by facet index. Sliding edge
        # nodes repairs them.
        path = T.find_part("occt_propeller.brep")
        if path is None:
            self.skipTest("occt_propeller.brep not available")
        import MeshPart
        import Part

        shape = Part.read(path)
        diag = shape.BoundBox.DiagonalLength
        m = MeshPart.meshFromShape(Shape=shape, LinearDeflection=1e-3 * diag,
                                   AngularDeflection=0.5, Relative=False)
        res = SurfMesh.optimize(m, shape, max_sweeps=30)
        tangled = set(np.nonzero(res.after.tangled)[0].tolist())
        self.assertGreater(res.before.stats["tangled"], 0)
        self.assertEqual(tangled, set(res.tangled_unmovable) | set(res.tangled_movable))
        self.assertEqual(res.tangled_movable, [])
        self.assertGreater(len(res.tangled_unmovable), 0)
        self.assertTrue(any("no node that may move" in w for w in res.warnings))
        # the warning says where the first one is: its centroid, on a face of the shape
        # (FreeCAD's own name and distance query)
        warn = next(w for w in res.warnings if "no node that may move" in w)
        self.assertIn("try boundary='slide'", warn)
        where = re.search(r"near \(([^)]*)\) on Face(\d+)", warn)
        self.assertIsNotNone(where, warn)
        near = FreeCAD.Vector(*[float(x) for x in where.group(1).split(",")])
        first = res.tangled_unmovable[0]
        centroid = sum((FreeCAD.Vector(*p) for p in m.Facets[first].Points), FreeCAD.Vector())
        self.assertLess((near - centroid * (1.0 / 3.0)).Length, 1e-5 * diag)
        face = shape.Faces[int(where.group(2)) - 1]
        for p in m.Facets[first].Points:
            self.assertLess(face.distToShape(Part.Vertex(FreeCAD.Vector(*p)))[0], 1e-5 * diag)
        # every node of those facets lies on a CAD edge or vertex (FreeCAD's own query)
        edges = Part.Compound(shape.Edges)
        for f in res.tangled_unmovable:
            for p in m.Facets[f].Points:
                d = edges.distToShape(Part.Vertex(FreeCAD.Vector(*p)))[0]
                self.assertLess(d, 1e-5 * diag, f"facet {f}: node {p} is not on a CAD edge")
        slide = SurfMesh.optimize(m, shape, boundary="slide", max_sweeps=30)
        self.assertEqual(slide.after.stats["tangled"], 0)
        # Nothing stays tangled; BRepMesh's coarse blade edges have elements standing across.
        self.assertEqual([w for w in slide.warnings if "stand across" not in w], [])
        self.assertGreaterEqual(slide.after.stats["min"], res.after.stats["min"])

    def test_progress_and_cancel(self):
        tor, mesh = T.torus_fem(self.doc, tangled=True)
        before = T.fem_snapshot(mesh.FemMesh)
        seen = []

        def stop_at_two(info):
            seen.append(dict(info))
            return info["sweep"] < 2

        with self.assertRaises(SurfMesh.Cancelled):
            SurfMesh.optimize(mesh, tor, progress=stop_at_two)
        self.assertEqual([s["sweep"] for s in seen], [1, 2])
        self.assertIn("tangled", seen[0])
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), before)

        def boom(info):
            raise KeyError("from callback")

        with self.assertRaises(KeyError):
            SurfMesh.optimize(mesh, tor, progress=boom)
        self.assertEqual(T.fem_snapshot(mesh.FemMesh), before)


class TestOnlySomeFaces(ApiCase):
    """optimize(faces=…, fixed_nodes=…): a region of the mesh optimized, the rest left as it is.
    References: FreeCAD's distances to the chosen faces and the input's own positions."""

    @classmethod
    def setUpClass(cls):
        import MeshPart
        import Part

        path = T.find_part("occt_housing_bottom.brep")
        cls.shape = Part.read(path)
        cls.diag = cls.shape.BoundBox.DiagonalLength
        # FreeCAD's standard mesher: poor elements to improve, and cracks along CAD edges
        # (coincident nodes, glued) to keep closed.
        cls.mesh = MeshPart.meshFromShape(Shape=cls.shape, LinearDeflection=cls.diag / 500,
                                          AngularDeflection=0.35, Relative=False)
        cls.x0 = np.array([(p.x, p.y, p.z) for p in cls.mesh.Points])
        cls.tris = np.array([f.PointIndices for f in cls.mesh.Facets])
        rep = SurfMesh.measure(cls.mesh, cls.shape)
        cls.before = rep
        counts = np.bincount(rep.element_faces[rep.element_faces >= 0])
        cls.chosen = [int(f) for f in np.argsort(counts)[::-1][:3]]  # 0-based, most elements
        cls.names = [f"Face{f + 1}" for f in cls.chosen]

    def test_nodes_off_the_chosen_faces_stay(self):
        import Part

        res = SurfMesh.optimize(self.mesh, self.shape, faces=self.names)
        moved = np.nonzero(np.linalg.norm(res.nodes - self.x0, axis=1) > 0)[0]
        self.assertGreater(len(moved), 300)
        self.assertGreater(res.held_nodes, 1000)
        self.assertEqual(res.options["faces"], self.names)
        # FreeCAD: every node that moved lies on one of the chosen faces (before and after).
        region = Part.makeCompound([self.shape.Faces[f] for f in self.chosen])
        self.assertLess(T.distance_to_shape(region, self.x0[moved]).max(), 1e-6 * self.diag)
        self.assertLess(T.distance_to_shape(region, res.nodes[moved]).max(), 1e-5 * self.diag)
        # Elements on other faces keep their quality exactly; those on the chosen faces gain.
        on = np.isin(self.before.element_faces, self.chosen)
        np.testing.assert_array_equal(res.after.quality[~on], self.before.quality[~on])
        self.assertGreater(res.after.quality[on].mean(), self.before.quality[on].mean())
        self.assertGreater(res.after.quality[on].min(), self.before.quality[on].min())

        def objective(rep):
            return np.sum((rep.distortion[on] - 1.0) ** 2)

        self.assertLess(objective(res.after), 0.9 * objective(self.before))
        self.assertEqual(res.after.stats["tangled"], 0)
        # Cracks stay closed: coincident input nodes are still coincident.
        for g in T.coincident_groups(self.x0):
            self.assertEqual(np.ptp(res.nodes[g], axis=0).max(), 0.0)
        # The same faces by number and as Part.Face objects; without faces= the run moves
        # nodes off them (the test above can fail).
        by_number = SurfMesh.optimize(self.mesh, self.shape, faces=[f + 1 for f in self.chosen])
        np.testing.assert_array_equal(by_number.nodes, res.nodes)
        by_face = SurfMesh.optimize(self.mesh, self.shape,
                                    faces=[self.shape.Faces[f] for f in self.chosen])
        np.testing.assert_array_equal(by_face.nodes, res.nodes)
        whole = SurfMesh.optimize(self.mesh, self.shape)
        self.assertEqual(whole.held_nodes, 0)
        self.assertGreater(
            int(np.count_nonzero(np.linalg.norm(whole.nodes - self.x0, axis=1) > 0)),
            len(moved) + 1000)

    def test_fixed_nodes_stay(self):
        fixed = list(range(0, len(self.x0), 3))
        res = SurfMesh.optimize(self.mesh, self.shape, fixed_nodes=fixed)
        delta = np.linalg.norm(res.nodes - self.x0, axis=1)
        self.assertEqual(delta[fixed].max(), 0.0)
        self.assertGreater(np.count_nonzero(delta > 0), 500)
        self.assertEqual(res.options["fixed_nodes"], len(fixed))
        # a node glued to a fixed one (the two sides of a crack) stays with it
        for g in T.coincident_groups(self.x0):
            self.assertEqual(np.ptp(res.nodes[g], axis=0).max(), 0.0)
            if any(int(i) % 3 == 0 for i in g):
                self.assertEqual(delta[g].max(), 0.0)

    def test_bad_faces_and_node_ids(self):
        import Part

        n = len(self.shape.Faces)
        cases = [
            (["Face0"], f"Face0 is not a face of the shape, which has {n} face"),
            ([n + 1], f"Face{n + 1} is not a face of the shape"),
            (["Top"], "'Top' is not a face name"),
            ([], "faces is empty"),
            ([Part.makeBox(1, 1, 1).Faces[0]], "not a face of the shape"),
        ]
        for faces, text in cases:
            with self.assertRaises(ValueError) as cm:
                SurfMesh.optimize(self.mesh, self.shape, faces=faces)
            self.assertIn(text, str(cm.exception))
        # a face the mesh does not cover: a face of the shape with no element on it
        bare = [f for f in range(n) if f not in set(self.before.element_faces.tolist())]
        if bare:
            with self.assertRaises(ValueError) as cm:
                SurfMesh.optimize(self.mesh, self.shape, faces=[bare[0] + 1])
            self.assertIn(f"no element of the mesh lies on Face{bare[0] + 1}", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            SurfMesh.optimize(self.mesh, self.shape, fixed_nodes=[0, len(self.x0) + 7])
        self.assertIn(f"no node with id {len(self.x0) + 7}", str(cm.exception))
        with self.assertRaises(ValueError):
            SurfMesh.optimize(self.mesh, self.shape, fixed_nodes=[1.5])
        # In the document: an error leaves it unchanged.
        obj = self.doc.addObject("Mesh::Feature", "Housing")
        obj.Mesh = self.mesh
        part = self.doc.addObject("Part::Feature", "Part")
        part.Shape = self.shape
        self.doc.recompute()
        names = [o.Name for o in self.doc.Objects]
        with self.assertRaises(ValueError):
            SurfMesh.optimize_object(obj, part, faces=["Face0"])
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        new = SurfMesh.optimize_object(obj, part, faces=self.names[:1])
        self.assertIn(f"faces={self.names[:1]!r}", new.SurfMeshRun["options"])


class TestDefaults(unittest.TestCase):
    """One source of the optimizer's defaults: the core's OptimizeOptions, through the binding."""

    def test_bound_defaults_are_the_apis(self):
        import inspect

        from SurfMesh.app import api, document, options

        bound = dict(api.core().SurfaceMesh.optimize_defaults())
        self.assertEqual(bound.pop("measure"), options.DEFAULT_MEASURE)
        self.assertEqual(SurfMesh.OPTIMIZE_DEFAULTS, bound)
        self.assertEqual(list(SurfMesh.OPTIMIZE_DEFAULTS), list(bound))  # same order
        self.assertIs(api.OPTIMIZE_DEFAULTS, SurfMesh.OPTIMIZE_DEFAULTS)
        self.assertIs(options.optimize_defaults(), SurfMesh.OPTIMIZE_DEFAULTS)
        for k, v in bound.items():  # same types too (True, not 1; 0, not 0.0)
            self.assertIs(type(SurfMesh.OPTIMIZE_DEFAULTS[k]), type(v), k)
        # The values the API had before they came from the core.
        self.assertEqual(SurfMesh.OPTIMIZE_DEFAULTS, {
            "max_sweeps": 100, "rel_tol": 1e-3, "move_tol": 1e-3, "inner_iterations": 1,
            "max_line_search": 30, "over_relaxation": 1.9, "delta_policy": "auto",
            "delta_epsilon": 1e-2, "delta": 1e-2, "monotone": True, "threads": 0,
            "high_order": "reference", "topology": "none"})
        # The signatures' defaults are the same ones.
        for fn in (api.measure, api.optimize, document.measure_object,
                   document.tangled_elements, document.optimize_object):
            params = inspect.signature(fn).parameters
            self.assertEqual(params["measure"].default, options.DEFAULT_MEASURE, fn.__name__)
            if "boundary" in params:
                self.assertEqual(params["boundary"].default, options.DEFAULT_BOUNDARY)
        self.assertEqual(inspect.signature(api.prepare).parameters["boundary"].default,
                         options.DEFAULT_BOUNDARY)
        self.assertEqual(options.DEFAULT_BOUNDARY, api.BOUNDARY_MODES[0])

    def test_documented_options_are_the_defaults(self):
        # The table of **options in docs/python-api.md: every option of it is a key, with the
        # default it gives, and it names every key.
        with open(os.path.join(T.REPO, "docs", "python-api.md"), encoding="utf-8") as f:
            text = f.read()
        table = text[text.index("| option | default | meaning |"):]
        table = table[:table.index("\n\n")]
        rows = re.findall(r"^\| `(\w+)` \| (.+?) \| ", table, flags=re.M)
        self.assertGreater(len(rows), 5)
        documented = {}
        for name, value in rows:
            value = value.strip("`")
            if value in ("True", "False"):
                documented[name] = value == "True"
            elif value.startswith('"'):
                documented[name] = value.strip('"')
            else:
                documented[name] = int(value) if re.fullmatch(r"\d+", value) else float(value)
        self.assertEqual(documented, dict(SurfMesh.OPTIMIZE_DEFAULTS))

    def test_unknown_option_names_the_known_ones(self):
        with self.assertRaises(ValueError) as ctx:
            SurfMesh.optimize(None, None, sweeps=3)
        known = ", ".join(SurfMesh.OPTIMIZE_DEFAULTS)
        self.assertEqual(str(ctx.exception), f"unknown option(s) sweeps; known: {known}")


class TestErrors(ApiCase):
    def assertValueError(self, fn, *words):
        with self.assertRaises(ValueError) as cm:
            fn()
        msg = str(cm.exception)
        for w in words:
            self.assertIn(w, msg)
        return msg

    def test_bad_arguments(self):
        tor, mobj = T.torus_mesh(self.doc, deflection=0.5)
        self.assertValueError(lambda: SurfMesh.measure(mobj, tor, measure="nope"), "nope", "shape")
        self.assertValueError(lambda: SurfMesh.optimize(mobj, tor, boundary="free"), "free")
        self.assertValueError(lambda: SurfMesh.optimize(mobj, tor, max_sweep=3), "max_sweep")
        self.assertValueError(lambda: SurfMesh.optimize(mobj, tor, max_sweeps=0), "max_sweeps")
        self.assertValueError(lambda: SurfMesh.measure(mobj, tor, tolerance=-1.0), "tolerance")
        self.assertValueError(lambda: SurfMesh.measure(tor, tor), "not a mesh")
        self.assertValueError(lambda: SurfMesh.measure(mobj, mobj), "no CAD shape")
        import Part

        self.assertValueError(lambda: SurfMesh.measure(mobj, Part.Shape()), "null")
        self.assertValueError(lambda: SurfMesh.measure(mobj, Part.Vertex(0, 0, 0)), "no faces")

    def test_mesh_of_another_shape(self):
        import Part

        tor, mobj = T.torus_mesh(self.doc, deflection=0.5)
        other = tor.Shape.copy()
        other.translate(FreeCAD.Vector(100, 0, 0))
        self.assertValueError(lambda: SurfMesh.measure(mobj, other))
        sphere = Part.makeSphere(5)
        self.assertValueError(lambda: SurfMesh.measure(mobj, sphere))

    def test_quad8_fem_element_is_measured(self):
        # FreeCAD's 8-node quadrilateral: a 2 × 1 rectangle with its side nodes at the midpoints
        # has Knupp's shape 2·2/(4 + 1) = 0.8, the quality of the quad4 on its corners.
        import Fem

        fem = Fem.FemMesh()
        for i, p in enumerate([(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0), (1, 0, 0), (2, 0.5, 0),
                               (1, 1, 0), (0, 0.5, 0)]):
            fem.addNode(float(p[0]), float(p[1]), float(p[2]), i + 1)
        fem.addFace([1, 2, 3, 4, 5, 6, 7, 8], 10)
        plane = __import__("Part").makePlane(2, 1)
        rep = SurfMesh.measure(fem, plane)
        self.assertEqual(rep.element_types, ["quad8"])
        self.assertEqual(list(rep.element_ids), [10])
        self.assertAlmostEqual(float(rep.quality[0]), 0.8, places=12)

    def test_empty_and_volume_meshes(self):
        import Fem

        self.assertValueError(lambda: SurfMesh.measure(Fem.FemMesh(), __import__("Part").makeBox(1, 1, 1)), "no face elements")


if __name__ == "__main__":
    unittest.main()
