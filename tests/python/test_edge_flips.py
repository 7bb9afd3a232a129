"""Edge flips (topology="flip") through the Python API and the FreeCAD document: the result
object, its element node lists, undo, and the quality judged without SurfMesh
(run: freecadcmd -t test_edge_flips)."""

import os
import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T


def fan_of_slivers():
    """The square [0, 10]² meshed as two fans of slivers: 11 nodes on each of the edges
    y = 0 and y = 10, every bottom node joined to the top-left corner and every top node to
    the bottom-right one (every node on a CAD edge: node motion alone cannot improve it).
    Returns (nodes (22, 3), triangles (20, 3))."""
    nodes = [(float(i), 0.0, 0.0) for i in range(11)] + [(float(i), 10.0, 0.0)
                                                          for i in range(11)]
    tris = [(i, i + 1, 11) for i in range(10)] + [(10, 12 + j, 11 + j) for j in range(10)]
    return np.array(nodes), np.array(tris)


def square(doc):
    import Part

    part = doc.addObject("Part::Feature", "Square")
    part.Shape = Part.makePlane(10, 10)
    doc.recompute()
    return part


def fem_of(doc, nodes, tris, first_element=101):
    import Fem

    fem = Fem.FemMesh()
    for i, (x, y, z) in enumerate(nodes.tolist()):
        fem.addNode(x, y, z, i + 1)
    for k, t in enumerate(tris.tolist()):
        fem.addFace([int(n) + 1 for n in t], first_element + k)
    obj = doc.addObject("Fem::FemMeshObject", "FanMesh")
    obj.FemMesh = fem
    return obj


def independent_quality(points, tris, face):
    q, tangled = T.reference_tri_quality(np.asarray(points, dtype=float), np.asarray(tris), face)
    return q, tangled


class TestEdgeFlips(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshFlips")
        self.doc.UndoMode = 1

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_fem_document_workflow_with_rewired_elements(self):
        part = square(self.doc)
        face = part.Shape.Faces[0]
        nodes, tris = fan_of_slivers()
        obj = fem_of(self.doc, nodes, tris)
        self.doc.recompute()
        snap = T.fem_snapshot(obj.FemMesh)
        names = {o.Name for o in self.doc.Objects}
        q0, t0 = independent_quality(nodes, tris, face)
        self.assertFalse(t0.any())
        # Node motion alone: every node is on a CAD edge, nothing changes.
        plain = SurfMesh.optimize(obj, part)
        self.assertEqual(plain.flips, 0)
        self.assertAlmostEqual(plain.after.stats["min"], q0.min(), places=6)

        new = SurfMesh.optimize_object(obj, shape=part, topology="flip")
        run = dict(new.SurfMeshRun)
        self.assertEqual(run["topology"], "flip")
        flips = int(run["flips"])
        self.assertGreater(flips, 0)
        rewired = [int(e) for e in run["rewired_elements"].split()]
        fem = new.FemMesh
        # Ids, node positions and element count kept; only the rewired lists changed.
        self.assertEqual(sorted(fem.Faces), sorted(obj.FemMesh.Faces))
        self.assertEqual({k: tuple(v) for k, v in fem.Nodes.items()},
                         {k: tuple(v) for k, v in obj.FemMesh.Nodes.items()})
        changed = [e for e in fem.Faces
                   if tuple(fem.getElementNodes(e)) != tuple(obj.FemMesh.getElementNodes(e))]
        self.assertEqual(sorted(changed), sorted(rewired))
        # Judged without SurfMesh: every element valid (wound along the face's normal), the
        # worst far better, and the stored report says the same.
        ids = sorted(fem.Faces)
        new_tris = np.array([[n - 1 for n in fem.getElementNodes(e)] for e in ids])
        q1, t1 = independent_quality(nodes, new_tris, face)
        self.assertFalse(t1.any())
        self.assertGreater(q1.min(), 1.5 * q0.min())
        stats = SurfMesh.stats_of(new)
        self.assertAlmostEqual(stats["min"], q1.min(), places=9)
        self.assertEqual(stats["tangled"], 0)
        self.assertEqual(len(new.SurfMeshColors), len(ids))
        # The outcome line names the flips; the run is not "nothing to do" (every node fixed,
        # but the mesh changed).
        from SurfMesh.app import document

        line = document.outcome_of(new)
        self.assertIn(f"; {flips} edge flip", line)
        self.assertEqual(run["reason"], "converged")
        # The original is unchanged; undo removes the result.
        self.assertEqual(T.fem_snapshot(obj.FemMesh), snap)
        self.doc.undo()
        self.assertEqual({o.Name for o in self.doc.Objects}, names)

    def test_mesh_feature_facets_rewired_points_and_segments_kept(self):
        import Mesh

        part = square(self.doc)
        face = part.Shape.Faces[0]
        nodes, tris = fan_of_slivers()
        vec = FreeCAD.Vector
        mesh = Mesh.Mesh(([vec(*p) for p in nodes.tolist()], [tuple(t) for t in tris.tolist()]))
        mesh.addSegment(list(range(10)))
        res = SurfMesh.optimize(mesh, part, topology="flip")
        self.assertGreater(res.flips, 0)
        pts, facets = res.mesh.Topology
        self.assertEqual(len(facets), len(tris))
        np.testing.assert_array_equal(np.array([[p.x, p.y, p.z] for p in pts]), nodes)
        changed = [k for k in range(len(tris)) if tuple(facets[k]) != tuple(tris[k])]
        self.assertEqual(changed, res.rewired_elements)
        self.assertEqual(res.mesh.countSegments(), 1)
        self.assertEqual(list(res.mesh.getSegment(0)), list(range(10)))
        q1, t1 = independent_quality(nodes, np.array(facets), face)
        self.assertFalse(t1.any())
        self.assertAlmostEqual(res.after.stats["min"], q1.min(), places=6)
        self.assertEqual(res.options["topology"], "flip")

    def test_flat_slivers_along_cad_edges_are_kept_and_repaired(self):
        """FreeCAD's Gmsh mesh of the crank arm has flat slivers along CAD edges (every corner
        on one edge: no motion repairs them), which measuring leaves out. With flips they stay
        in the run, and flips with their neighbours across their chords repair them, judged
        with FreeCAD's normalAt (no element wound against its face or standing across it).
        The report leaves out those still flat, before and after, as measuring the input and
        the returned mesh does; a warning names them."""
        import Part

        from SurfMesh.app import conversion, examples

        part = self.doc.addObject("Part::Feature", "CrankArm")
        part.Shape = Part.read(os.path.join(T.data_dir(), "occt_crankarm.brep"))
        mesh = examples.make_gmsh_mesh(self.doc, part, part.Shape.BoundBox.DiagonalLength / 17,
                                       name="CrankMesh")
        plain = SurfMesh.optimize(mesh, part)
        res = SurfMesh.optimize(mesh, part, topology="flip")
        measured = SurfMesh.measure(mesh, part)
        # The flat slivers: left out of the figures of the input, as measuring it does.
        for key in ("tangled", "across", "invalid", "elements", "skipped"):
            self.assertEqual(res.before.stats[key], measured.stats[key], key)
            self.assertEqual(res.before.stats[key], plain.before.stats[key], key)
        for key in ("min", "mean"):
            self.assertAlmostEqual(res.before.stats[key], measured.stats[key], places=12)
        ids = np.asarray(res.after.element_ids)
        other = set(res.bridge.get("skipped_elements", []))  # collapsed ones, left out of the run
        was_flat = np.setdiff1d(ids[np.asarray(res.before.skipped)], list(other))
        self.assertGreater(len(was_flat), 0)
        self.assertGreater(res.flips, 0)
        self.assertGreaterEqual(res.after.stats["mean"], plain.after.stats["mean"])
        # Flips repair some (all on Gmsh 4.8's mesh; Gmsh 4.15's has two left): the returned
        # mesh measures as the result says, the flat ones left are named.
        left = np.setdiff1d(ids[np.asarray(res.after.skipped)], list(other))
        self.assertLess(len(left), len(was_flat))
        again = SurfMesh.measure(res.mesh, part)
        for key in ("tangled", "across", "invalid", "elements", "skipped"):
            self.assertEqual(again.stats[key], res.after.stats[key], key)
        for key in ("min", "mean"):
            self.assertAlmostEqual(again.stats[key], res.after.stats[key], places=9)
        self.assertEqual(set(ids[np.asarray(again.skipped)].tolist()), set(left.tolist()) | other)
        if len(left):
            self.assertTrue(any(f"elements {left[0]}" in w for w in res.warnings), res.warnings)
        # Independent: the elements that were flat and every rewired one, valid now, wound along
        # their face's normal at every corner.
        data = conversion.read_mesh(res.mesh)
        check = np.setdiff1d(np.union1d(was_flat, np.asarray(res.rewired_elements)), left)
        rows = np.searchsorted(ids, check)
        tris = np.array([data.element(int(np.searchsorted(data.element_ids, e)))[:3]
                         for e in check])
        faces = np.asarray(res.after.element_faces)[rows]
        nodes = data.nodes
        import FreeCAD

        for t, f, e in zip(tris, faces, check):
            face = part.Shape.Faces[int(f)]
            c = np.cross(nodes[t[1]] - nodes[t[0]], nodes[t[2]] - nodes[t[0]])
            for k in t:
                u, v = face.Surface.parameter(FreeCAD.Vector(*map(float, nodes[k])))
                n = face.normalAt(u, v)
                self.assertGreater(float(np.dot(c, (n.x, n.y, n.z))), 0.0, f"element {e}")

    def test_the_returned_mesh_measures_as_the_result_says(self):
        """Gmsh's meshes of the bottle and of the housing (CAD edges between faces, thin faces,
        a few tangled elements) as FEM meshes: the mesh returned, measured again from scratch
        (its faces found anew from its nodes), has the result's figures. A flip that made an
        element whose corners all lie on CAD edges between two faces could be read back on the
        other face, folded."""
        import Part

        from SurfMesh.app import fileio

        for name in ("occt_bottle.brep", "occt_housing_bottom.brep"):
            with self.subTest(part=name):
                path = os.path.join(T.data_dir(), name)
                shape = Part.read(path)
                gmsh = fileio._gmsh()
                opts = {"Mesh.MeshSizeMax": shape.BoundBox.DiagonalLength / 21,
                        "Mesh.MeshSizeFromCurvature": 0, "Mesh.Algorithm": 6}
                saved = {k: gmsh.option.getNumber(k) for k in opts}
                try:
                    gmsh.clear()
                    gmsh.model.occ.importShapes(path)
                    gmsh.model.occ.synchronize()
                    for k, v in opts.items():
                        gmsh.option.setNumber(k, v)
                    gmsh.model.mesh.generate(2)
                    tags, coords, _ = gmsh.model.mesh.getNodes()
                    _, _, enodes = gmsh.model.mesh.getElements(2)
                finally:
                    for k, v in saved.items():
                        gmsh.option.setNumber(k, v)
                    gmsh.clear()
                order = np.argsort(tags)
                nodes = coords.reshape(-1, 3)[order]
                tris = np.searchsorted(tags[order], np.concatenate(enodes)).reshape(-1, 3)
                obj = fem_of(self.doc, nodes, tris)
                res = SurfMesh.optimize(obj, shape, topology="flip")
                self.assertGreater(res.flips, 0)
                again = SurfMesh.measure(res.mesh, shape)
                for key in ("tangled", "across", "invalid", "elements", "skipped"):
                    self.assertEqual(again.stats[key], res.after.stats[key], key)
                for key in ("min", "mean"):
                    self.assertAlmostEqual(again.stats[key], res.after.stats[key], places=9)
                self.assertLessEqual(res.after.stats["tangled"], res.before.stats["tangled"])

    def test_tri6_flips_on_a_gmsh_second_order_mesh(self):
        """Gmsh's second-order mesh of NIST's PMI part 1: after tri6 flips the mesh still
        conforms (each side has one side node, named by both its elements), the reused side
        nodes lie on the part (FreeCAD's distToShape), no element is left invalid, and the
        minimum quality is the run without flips' or better."""
        import Part

        from SurfMesh.app import conversion, fileio

        path = os.path.join(T.data_dir(), "nist_pmi_1.step")
        shape = Part.read(path)
        diag = shape.BoundBox.DiagonalLength
        msh = T.gmsh_second_order(path, os.path.join(T.output_dir(), "flips_pmi1_o2.msh"),
                                  {"Mesh.MeshSizeMax": diag / 17})
        data = fileio.read_mesh(msh).data
        self.assertTrue(np.all(data.types == conversion.ELEMENT_TYPES["tri6"]))
        plain = SurfMesh.optimize(data, shape)
        res = SurfMesh.optimize(data, shape, topology="flip")
        self.assertGreater(res.flips, 0)
        self.assertEqual(res.after.stats["tangled"] + res.after.stats["across"], 0, res.warnings)
        self.assertGreaterEqual(res.after.stats["min"], plain.after.stats["min"] - 1e-12)
        x = res.nodes
        # The result conforms: every side (pair of corners) has one side node, whichever of
        # its elements names it (by the file's ids: Gmsh's element and node tags).
        conn = {int(data.element_ids[e]): [int(n) for n in data.node_ids[data.element(e)]]
                for e in range(data.element_count)}
        given = dict(conn)
        for e, nodes in zip(res.rewired_elements, res.rewired_nodes):
            self.assertEqual(len(nodes), 6)
            conn[e] = list(nodes)

        def sides(conn):
            side_node, uses = {}, {}
            for e, nodes in conn.items():
                for k in range(3):
                    side = tuple(sorted((nodes[k], nodes[(k + 1) % 3])))
                    self.assertEqual(side_node.setdefault(side, nodes[3 + k]), nodes[3 + k],
                                     f"element {e} side {side}")
                    uses[side] = uses.get(side, 0) + 1
            self.assertEqual(len(set(side_node.values())), len(side_node))  # one side a node
            return sorted(uses.values())

        # As many sides, used as often, as in the input (a flip trades one side for another).
        self.assertEqual(sides(conn), sides(given))
        index = {int(n): i for i, n in enumerate(data.node_ids)}
        moved_side = {index[n[3 + k]] for n in res.rewired_nodes for k in range(3)
                      if np.any(x[index[n[3 + k]]] != data.nodes[index[n[3 + k]]])}
        self.assertGreater(len(moved_side), 0)
        idx = sorted(moved_side)
        self.assertLess(T.distance_to_shape(shape, x[idx]).max(), 1e-7 * diag)

    def test_bad_topology_is_refused_before_anything_runs(self):
        part = square(self.doc)
        nodes, tris = fan_of_slivers()
        obj = fem_of(self.doc, nodes, tris)
        names = {o.Name for o in self.doc.Objects}
        with self.assertRaisesRegex(ValueError, "topology must be 'none' or 'flip'"):
            SurfMesh.optimize_object(obj, shape=part, topology="swap")
        self.assertEqual({o.Name for o in self.doc.Objects}, names)


if __name__ == "__main__":
    unittest.main()
