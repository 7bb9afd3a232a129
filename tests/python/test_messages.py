"""SurfMesh.app.messages: the core's diagnostics in the user's ids (each placeholder), the notes
by diagnostic code, the run's warnings and the command line's defaults
(run: freecadcmd -t test_messages). No FreeCAD document, no core run: plain values."""

import types
import unittest

import numpy as np

from SurfMesh.app import messages

# Node i of the arrays given to the core has id 10 + i, element k has id 101 + k.
DATA = types.SimpleNamespace(node_ids=np.arange(10, 18), element_ids=np.arange(101, 105))


def core_diag(fmt, **kw):
    """A diagnostic as the core gives it (its 0-based indices)."""
    d = {"code": kw.pop("code", "example"), "format": fmt, "count": kw.pop("count", 0),
         "nodes": [], "elements": [], "faces": [], "edges": [], "vertices": [], "values": {}}
    d.update(kw)
    return d


class TestDiagnostics(unittest.TestCase):
    """The core's diagnostics in the user's ids: each placeholder, by hand-written texts."""

    def user(self, fmt, data=DATA, **kw):
        return messages.for_user(core_diag(fmt, **kw), data)["text"]

    def test_one_node_and_one_element(self):
        self.assertEqual(self.user("element {element} repeats node {node}", nodes=[5],
                                   elements=[3]), "element 104 repeats node 15")

    def test_indexed_and_listed_ids(self):
        self.assertEqual(self.user("nodes {node} and {node1}; e.g. nodes {nodes1}; all {nodes}",
                                   nodes=[2, 7, 1, 3]),
                         "nodes 12 and 17; e.g. nodes 17 11 13; all 12 17 11 13")
        self.assertEqual(self.user("elements {element0}, {element1} and {element2} fold",
                                   elements=[0, 1, 2]), "elements 101, 102 and 103 fold")

    def test_counts_and_numbers(self):
        self.assertEqual(self.user("{count} of {total} nodes at {distance} ({relative} x)",
                                   count=5, values={"total": 1234567.0, "distance": 2.5e-7,
                                                    "relative": 1.0 / 3.0}),
                         "5 of 1234567 nodes at 2.5e-07 (0.333333 x)")

    def test_cad_entities_get_freecad_names(self):
        d = messages.for_user(core_diag("node {node} of {vertex}, element {element} on {face}, "
                                        "{edge}", nodes=[1], vertices=[0], elements=[2],
                                        faces=[1], edges=[0]), DATA)
        self.assertEqual(d["text"], "node 11 of Vertex1, element 103 on Face2, Edge1")
        # the dict in the user's ids: FEM ids, FreeCAD's numbers of the shape's entities
        self.assertEqual((d["nodes"], d["elements"], d["faces"], d["edges"], d["vertices"]),
                         ([11], [103], [2], [1], [1]))

    def test_an_index_out_of_the_table_stays(self):
        self.assertEqual(self.user("node {node} is out of range", nodes=[9]),
                         "node 9 is out of range")

    def test_without_ids_only_the_entities_change(self):
        bare = types.SimpleNamespace()
        self.assertEqual(self.user("node {node} on {face}", bare, nodes=[5], faces=[0]),
                         "node 5 on Face1")

    def test_what_cannot_be_filled_stays(self):
        self.assertEqual(self.user("{node3} {unknown} {nodes}", nodes=[1]), "{node3} {unknown} 11")

    def test_refusal_in_the_users_ids(self):
        err = ValueError("element 3 repeats node 5")
        err.diagnostic = core_diag("element {element} repeats node {node}", code="repeated_node",
                                   nodes=[5], elements=[3])
        out = messages.refusal(err, DATA)
        self.assertIsInstance(out, ValueError)
        self.assertEqual(str(out), "element 104 repeats node 15")
        self.assertEqual(out.diagnostic["code"], "repeated_node")
        # a ValueError without a diagnostic (not the core's refusal) keeps its text
        self.assertEqual(str(messages.refusal(ValueError("node 5 is odd"), DATA)), "node 5 is odd")


class TestUnusedNodes(unittest.TestCase):
    FORMAT = ("{count} nodes belong to no element (e.g. nodes of edge or vertex elements); they "
              "are kept fixed and lie on the shape: {on_vertices} on CAD vertices, {on_edges} on "
              "CAD edges, {on_faces} on faces; farthest: node {node} ({distance} from {vertex}); "
              "e.g. nodes {nodes1}")

    def test_loose_nodes_from_the_report_arrays(self):
        # the farthest lies on an edge now: the core's format names the edge instead
        report = {"loose_nodes": np.array([3, 4, 5]), "loose_class": np.array([0, 1, 2]),
                  "loose_entity": np.array([2, 0, 5]),
                  "loose_distance": np.array([1e-9, 2.5e-7, 1e-8])}
        d = messages.loose_nodes(report, self.FORMAT)
        self.assertEqual(d["code"], "unused_nodes")
        self.assertEqual(
            messages.for_user(d, DATA)["text"],
            "3 nodes belong to no element (e.g. nodes of edge or vertex elements); they are "
            "kept fixed and lie on the shape: 1 on CAD vertices, 1 on CAD edges, 1 on faces; "
            "farthest: node 14 (2.5e-07 from Edge1); e.g. nodes 13 14 15")


class TestNotes(unittest.TestCase):
    """Each note of messages.NOTE_WORDS, by its diagnostic's code and count."""

    def test_unused(self):
        d = messages.for_user(core_diag("{count} nodes belong to no element", code="unused_nodes",
                                        count=12), DATA)
        self.assertEqual(messages.user_words(d),
                         ("unused_nodes", "12 nodes are used by no face element (e.g. nodes of "
                                          "edge elements): they stay where they are"))

    def test_left_out(self):
        d = messages.left_out(
            messages.left_out_reasons(collapsed=3, folded=2, crowded=4, misjoined=5, flat=1,
                                      miswound=6), np.arange(21))
        self.assertEqual(
            d["text"], "left out 3 collapsed element(s) (a repeated node) and 2 element(s) with "
                       "the same nodes as another one (folded pairs) and 4 element(s) overlapping "
                       "around those (more than two on one edge) and 5 high-order element(s) "
                       "joined to those through side nodes no conforming mesh shares (a side "
                       "node that is also a corner, or on two edges) and 1 flat element(s) on one "
                       "CAD edge or with two nodes on one CAD vertex and 6 element(s) wound "
                       "against their face's mesh next to those: ids 0, 1, 2, 3, 4, 5, 6, 7, 8, "
                       "9 …")
        self.assertEqual(d["elements"], list(range(21)))
        self.assertEqual(messages.user_words(d),
                         ("left_out", "21 elements are left out (collapsed or degenerate, e.g. "
                                      "where the mesher merged nodes): they keep their place "
                                      "and are drawn grey"))

    def test_node_order(self):
        d = messages.side_nodes_astray(np.array([4, 5]))
        self.assertEqual(
            d["text"], "2 high-order element(s) have a side node farther from its side than the "
                       "side is long (ids 4, 5): is the node order corners first, then the side "
                       "nodes of sides 1-2, 2-3, 3-1?")
        self.assertEqual(messages.user_words(d)[0], "node_order")
        self.assertTrue(messages.user_words(d)[1].startswith("2 curved elements"))

    def test_glued(self):
        d = messages.glued_nodes(3, 7, 9, (1.0, 2.0, 3.5))
        self.assertEqual(
            d["text"], "glued 3 node(s) to another node at the same position (the mesh has a "
                       "crack there, e.g. nodes 7 and 9 at (1, 2, 3.5)): they are measured as one "
                       "node and move together")
        self.assertEqual(d["nodes"], [7, 9])
        self.assertEqual(messages.user_words(d),
                         ("glued", "3 nodes sit on another node (a crack along a CAD edge): "
                                   "they are measured as one and move together"))

    def test_another_code_is_its_own_kind(self):
        d = messages.for_user(core_diag("{count} trimming curve(s) of {face}", code="trim_gaps",
                                        count=2, faces=[3]), DATA)
        self.assertEqual(messages.user_words(d), ("trim_gaps", "2 trimming curve(s) of Face4"))


class TestRunWarnings(unittest.TestCase):
    def test_lists_and_places(self):
        self.assertEqual(messages.id_list(list(range(3))), "0, 1, 2")
        self.assertTrue(messages.id_list(list(range(25))).endswith(", 18, 19, …"))
        self.assertEqual(messages.where((1.0, 2.5, -3.0), 4),
                         " (the first near (1, 2.5, -3) on Face4)")

    def test_tangled_movable_hints(self):
        # still dropping at max_sweeps: more sweeps; else: what to change
        w = messages.tangled_movable([7], "", "fixed", "max_sweeps", 3, 24)
        self.assertIn("(the run reached max_sweeps while their number was still dropping: try "
                      "more sweeps): elements 7", w)
        w = messages.tangled_movable([7, 8], "", "slide", "max_sweeps", 30, 24)
        self.assertIn("over its last 30 sweeps, so more sweeps are unlikely to help; change the "
                      "mesh there", w)
        w = messages.tangled_movable([7], "", "fixed", "converged", 30, 24)
        self.assertIn("repairs them: try boundary='slide'): elements 7", w)

    def test_tangled_unmovable_hints(self):
        w = messages.tangled_unmovable([5], "", "fixed", held=True)
        self.assertIn("or poles, held by faces= or fixed_nodes=; try boundary='slide' or "
                      "topology='flip', or change the mesh there): elements 5", w)
        self.assertIn("or poles; try topology='flip', or change the mesh there",
                      messages.tangled_unmovable([5], "", "slide", held=False))
        self.assertIn("or poles; change the mesh there",
                      messages.tangled_unmovable([5], "", "slide", held=False, topology="flip"))


class TestNumberText(unittest.TestCase):
    def test_defaults_as_the_help_gives_them(self):
        self.assertEqual(messages.number_text(1e-3), "1e-3")
        self.assertEqual(messages.number_text(2.5e-4), "2.5e-4")
        self.assertEqual(messages.number_text(1.9), "1.9")
        self.assertEqual(messages.number_text(100), "100")
        self.assertEqual(messages.number_text(0.0), "0")


if __name__ == "__main__":
    unittest.main()
