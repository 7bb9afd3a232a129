"""FEM meshes as FreeCAD users have them (run: freecadcmd -t test_fem_meshes): meshes with
edge elements on free edges (nodes of no face element), judged with FreeCAD's own geometry
queries (Shape.distToShape) and FemMesh's own element lists."""

import os
import subprocess
import unittest

import FreeCAD
import numpy as np

import SurfMesh
import surfmesh_testing as T


def box_with_free_edge(doc):
    """A Part object: a 10 mm box and a free edge above it (a wire belonging to no face)."""
    import Part

    box = Part.makeBox(10, 10, 10)
    line = Part.makeLine(FreeCAD.Vector(0, 0, 15), FreeCAD.Vector(10, 0, 15))
    part = doc.addObject("Part::Feature", "BoxAndWire")
    part.Shape = Part.makeCompound([box, line])
    doc.recompute()
    return part


def gmsh_mesh(doc, part, order="1st", size=3.0):
    from femmesh.gmshtools import GmshTools
    import ObjectsFem

    mesh = ObjectsFem.makeMeshGmsh(doc, "Mesh")
    mesh.Part = part
    mesh.ElementDimension = "2D"
    mesh.ElementOrder = order
    mesh.CharacteristicLengthMax = size
    GmshTools(mesh).create_mesh()
    return mesh


def face_element_nodes(fem):
    return {n for f in fem.Faces for n in fem.getElementNodes(f)}


class EdgeElementNodes(unittest.TestCase):
    """Issue 41, point 2: nodes that belong to edge elements only."""

    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshFemMeshes")
        self.part = box_with_free_edge(self.doc)
        self.mesh = gmsh_mesh(self.doc, self.part)
        self.fem = self.mesh.FemMesh

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def loose_ids(self):
        return sorted(set(self.fem.Nodes) - face_element_nodes(self.fem))

    def test_the_mesh_has_nodes_on_the_free_edge_only_in_edge_elements(self):
        # the fixture is what the issue describes (else the other tests prove nothing)
        loose = self.loose_ids()
        self.assertGreater(len(loose), 2)
        edge_nodes = {n for e in self.fem.Edges for n in self.fem.getElementNodes(e)}
        self.assertTrue(set(loose) <= edge_nodes)
        wire = self.part.Shape.Edges[-1]
        d = T.distance_to_shape(wire, [self.fem.Nodes[n] for n in loose])
        self.assertLess(d.max(), 1e-9)

    def test_measured_with_every_hint_mode_and_named_in_the_report(self):
        loose = self.loose_ids()
        shape = self.part.Shape
        for hints in ("auto", "none", "all"):
            rep = SurfMesh.measure(self.mesh, self.part, hints=hints)
            b = rep.bridge
            self.assertEqual(sorted(b["loose_nodes"]), loose, hints)
            self.assertEqual(rep.stats["elements"], self.fem.FaceCount)
            # each node lies on the entity named (FreeCAD's distToShape), at the distance given
            for nid, name, dist in zip(b["loose_nodes"], b["loose_on"], b["loose_distance"]):
                entity = shape.getElement(name)
                p = self.fem.Nodes[nid]
                self.assertIn(name[:4], ("Edge", "Vert"), (nid, name))
                self.assertLess(T.distance_to_shape(entity, [p])[0], 1e-9, (nid, name))
                self.assertLess(dist, 1e-9)
                if name.startswith("Edge"):  # the free edge: it bounds no face
                    self.assertEqual(shape.ancestorsOfType(entity, __import__("Part").Face), [])
            note = [w for w in b["warnings"] if "belong to no element" in w]
            self.assertEqual(len(note), 1, b["warnings"])
            self.assertTrue(note[0].startswith(f"{len(loose)} nodes belong to no element"))
            self.assertIn("kept fixed", note[0])

    def test_optimize_keeps_them_and_their_edge_elements(self):
        loose = self.loose_ids()
        before = T.fem_snapshot(self.fem)
        res = SurfMesh.optimize(self.mesh, self.part)
        nodes, elems = T.fem_snapshot(res.mesh)
        self.assertEqual(elems, before[1])  # every element (edges too), same ids and nodes
        self.assertEqual(set(nodes), set(before[0]))
        for n in loose:
            self.assertEqual(nodes[n], before[0][n])
        self.assertEqual(sorted(res.bridge["loose_nodes"]), loose)
        self.assertEqual(T.fem_snapshot(self.fem), before)  # input untouched

    def test_a_mesh_off_the_whole_shape_is_refused_naming_the_nearest_entity(self):
        # The same mesh on the box alone: the wire's nodes are off the shape, 5 mm and more.
        import Part

        box = self.doc.addObject("Part::Feature", "Box")
        box.Shape = Part.makeBox(10, 10, 10)
        with self.assertRaises(ValueError) as cm:
            SurfMesh.measure(self.mesh, box)
        msg = str(cm.exception)
        loose = self.loose_ids()
        self.assertIn(f"{len(loose)} of {self.fem.NodeCount} nodes are farther than the "
                      "tolerance", msg)
        worst = max(loose, key=lambda n: T.distance_to_shape(box.Shape, [self.fem.Nodes[n]])[0])
        d = T.distance_to_shape(box.Shape, [self.fem.Nodes[worst]])[0]
        self.assertIn(f"worst: node {worst} at distance {d:g} ", msg)
        self.assertRegex(msg, r"from (Face|Edge|Vertex)\d+, the nearest")


@unittest.skipUnless(os.path.exists("/usr/bin/gmsh"), "gmsh not installed")
class EdgeElementNodesCli(unittest.TestCase):
    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshFemMeshesCli")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_cli_takes_the_unv_file_and_names_the_nodes_in_its_report(self):
        import json

        part = box_with_free_edge(self.doc)
        mesh = gmsh_mesh(self.doc, part)
        out = T.output_dir()
        shape_path = os.path.join(out, "fem41_box_wire.brep")
        mesh_path = os.path.join(out, "fem41_box_wire.unv")
        part.Shape.exportBrep(shape_path)
        mesh.FemMesh.write(mesh_path)
        result = os.path.join(out, "fem41_box_wire_out.unv")
        report = os.path.join(out, "fem41_box_wire.json")
        proc = subprocess.run(
            ["freecadcmd", T.cli_path(), "--", "optimize", shape_path, mesh_path, "-o", result,
             "--report", report], capture_output=True, text=True, timeout=300)
        self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
        with open(report) as f:
            rep = json.load(f)
        loose = sorted(set(mesh.FemMesh.Nodes) - face_element_nodes(mesh.FemMesh))
        self.assertEqual(sorted(rep["bridge"]["loose_nodes"]), loose)
        import Fem

        back = Fem.read(result)
        self.assertEqual(back.EdgeCount, mesh.FemMesh.EdgeCount)
        for n in loose:
            self.assertLess((back.Nodes[n] - mesh.FemMesh.Nodes[n]).Length, 1e-12)


if __name__ == "__main__":
    unittest.main()


def corner_signs(nodes, tris, face):
    """(E, 3) bool, computed without SurfMesh: whether each triangle's normal
    (x1 − x0) × (x2 − x0) points along the face's outward normal (FreeCAD's Face.normalAt at
    Surface.parameter of the corner) at each of its corners."""
    surf = face.Surface
    out = np.zeros((len(tris), 3), dtype=bool)
    for e, t in enumerate(tris):
        c = np.cross(nodes[t[1]] - nodes[t[0]], nodes[t[2]] - nodes[t[0]])
        for j, k in enumerate(t):
            u, v = surf.parameter(FreeCAD.Vector(*map(float, nodes[k])))
            n = face.normalAt(u, v)
            out[e, j] = float(np.dot(c, (n.x, n.y, n.z))) > 0.0
    return out


def fem_arrays(fem, ids):
    """(node positions, 0-based triangles, element ids) of a tria3 FemMesh."""
    nid = sorted(fem.Nodes)
    at = {n: k for k, n in enumerate(nid)}
    nodes = np.array([tuple(fem.Nodes[n]) for n in nid])
    tris = np.array([[at[n] for n in fem.getElementNodes(e)] for e in ids])
    return nodes, tris


class ResultFigures(unittest.TestCase):
    """Issue 41, points 4 and 5: the figures of a result are those of the mesh returned, and
    the counts read "N invalid (T tangled, A standing across)"."""

    def setUp(self):
        self.doc = FreeCAD.newDocument("SurfMeshResultFigures")

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def test_counts_and_distances_are_those_of_the_returned_mesh(self):
        from SurfMesh.app import reports

        tor, mesh = T.torus_fem(self.doc, tangled=True)
        face = tor.Shape.Faces[0]
        res = SurfMesh.optimize(mesh, tor)
        for fem, rep in ((mesh.FemMesh, res.before), (res.mesh, res.after)):
            ids = [int(e) for e in rep.element_ids]
            nodes, tris = fem_arrays(fem, ids)
            signs = corner_signs(nodes, tris, face)
            across = signs.any(axis=1) & ~signs.all(axis=1)
            invalid = ~signs.all(axis=1)
            s = rep.stats
            self.assertEqual(s["across"], int(across.sum()))
            self.assertEqual(s["invalid"], int(invalid.sum()))
            self.assertEqual(s["invalid"], int(np.count_nonzero(rep.tangled | rep.across)))
            self.assertEqual(reports.validity_text(s), f"{int(invalid.sum())} invalid "
                             f"({s['tangled']} tangled, {int(across.sum())} standing across)")
            self.assertIn(reports.validity_text(s), repr(rep))
        self.assertGreater(res.before.stats["across"], 0)  # the fixture has some
        # distances of the moved nodes, on the mesh returned: FreeCAD's distToShape and the
        # torus' closed form agree with the figures given
        old, new = T.fem_snapshot(mesh.FemMesh)[0], T.fem_snapshot(res.mesh)[0]
        moved = [n for n in new if new[n] != old[n]]
        a = res.after.stats
        self.assertEqual(a["moved_nodes"], len(moved))
        pts = np.array([new[n] for n in moved])
        d_shape = T.distance_to_shape(tor.Shape, pts)
        self.assertLess(abs(a["max_distance_to_shape"] - d_shape.max()), 1e-12)
        self.assertLess(abs(a["max_distance_to_face"] - d_shape.max()), 1e-12)
        self.assertLess(T.torus_distance(pts).max(), 1e-12)
        self.assertIn(a["worst_node_to_face"], moved)

    def test_distances_to_the_trimmed_face_match_freecad(self):
        # The bridge's distance query on points off a trimmed face (beyond its boundary, in its
        # plane, and above it): FreeCAD's Face.distToShape / Shape.distToShape give the same.
        import Part

        from SurfMesh.app import api

        part = self.doc.addObject("Part::Feature", "Plate")
        part.Shape = Part.makeBox(10, 6, 2).cut(Part.makeCylinder(2, 2, FreeCAD.Vector(5, 3, 0)))
        self.doc.recompute()
        import MeshPart

        tri = MeshPart.meshFromShape(Shape=part.Shape, LinearDeflection=0.05)
        data, handle = api.prepare(tri, part)
        shape = part.Shape
        top = [k for k, f in enumerate(shape.Faces)
               if f.Surface.__class__.__name__ == "Plane" and abs(f.CenterOfMass.z - 2) < 1e-9][0]
        pts = np.array([[5.0, 3.0, 2.0],     # in the hole, in the top face's plane
                        [12.0, 3.0, 2.0],    # beyond the face's outer boundary
                        [4.0, 1.0, 2.5],     # above the face
                        [5.0, 4.5, 2.0],     # on the face
                        [-3.0, -4.0, 7.0]])  # off everything
        to_face, to_shape = handle.distances_to_shape(pts, np.full(len(pts), top))
        for k, p in enumerate(pts):
            v = Part.Vertex(FreeCAD.Vector(*p))
            self.assertAlmostEqual(to_face[k], shape.Faces[top].distToShape(v)[0], delta=1e-9)
            self.assertAlmostEqual(to_shape[k], shape.distToShape(v)[0], delta=1e-9)
        self.assertGreater(to_face[0], 1.0)  # the hole: not on the face although on its plane
        with self.assertRaises(ValueError):
            handle.distances_to_shape(pts, np.full(len(pts), len(shape.Faces)))
