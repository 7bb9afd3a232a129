"""SurfMesh.app.messages: each rewriting of the core's messages (input string -> output string),
the notes' patterns against the texts they read, and the command line's defaults
(run: freecadcmd -t test_messages). No FreeCAD document, no core run: plain strings."""

import types
import unittest

import numpy as np

from SurfMesh.app import messages

# Node i of the arrays given to the core has id 10 + i, element k has id 101 + k.
DATA = types.SimpleNamespace(node_ids=np.arange(10, 18), element_ids=np.arange(101, 105))


class TestNameByIds(unittest.TestCase):
    """One test per rule of messages.name_by_ids."""

    def rewrite(self, text, data=DATA):
        return messages.name_by_ids(text, data)

    def test_one_node(self):
        self.assertEqual(self.rewrite("node 5 lies off the shape"), "node 15 lies off the shape")

    def test_nodes_listed_with_and(self):
        self.assertEqual(self.rewrite("nodes 2 and 7 coincide"), "nodes 12 and 17 coincide")

    def test_nodes_listed_with_commas(self):
        self.assertEqual(self.rewrite("nodes 2, 7 and 3 are far"), "nodes 12, 17 and 13 are far")
        self.assertEqual(self.rewrite("nodes 1, 2, 3, …"), "nodes 11, 12, 13, …")

    def test_nodes_listed_with_spaces(self):
        self.assertEqual(self.rewrite("e.g. nodes 7 1 3"), "e.g. nodes 17 11 13")

    def test_a_list_stops_before_a_decimal_number(self):
        self.assertEqual(self.rewrite("nodes 1 2.5 from it"), "nodes 11 2.5 from it")

    def test_row_of_the_node_array_is_a_node(self):
        self.assertEqual(self.rewrite("row 5 is not finite"), "node 15 is not finite")

    def test_elements(self):
        self.assertEqual(self.rewrite("element 3 is tangled"), "element 104 is tangled")
        self.assertEqual(self.rewrite("elements 0, 1 and 2 fold"), "elements 101, 102 and 103 fold")

    def test_an_index_out_of_the_table_stays(self):
        self.assertEqual(self.rewrite("node 9 is out of range"), "node 9 is out of range")

    def test_cad_entities_get_freecad_names(self):
        self.assertEqual(self.rewrite("lies 0.3 from face 2"), "lies 0.3 from Face3")
        self.assertEqual(self.rewrite("nodes on edge 0"), "nodes on Edge1")
        self.assertEqual(self.rewrite("the mesh of vertex 3"), "the mesh of Vertex4")
        self.assertEqual(self.rewrite("node 1 of vertex 0 and element 2 on face 1"),
                         "node 11 of Vertex1 and element 103 on Face2")

    def test_counts_stay(self):
        self.assertEqual(self.rewrite("5 nodes belong to no element"),
                         "5 nodes belong to no element")

    def test_without_ids_only_the_entities_change(self):
        bare = types.SimpleNamespace()
        self.assertEqual(self.rewrite("node 5 on face 0", bare), "node 5 on Face1")


class TestUnusedNodes(unittest.TestCase):
    WARNING = "12 nodes belong to no element (e.g. nodes of edge elements); they are kept fixed"

    def test_recognised(self):
        self.assertTrue(messages.is_unused_nodes_warning(self.WARNING))
        self.assertFalse(messages.is_unused_nodes_warning("12 nodes belong to face 3"))
        self.assertFalse(messages.is_unused_nodes_warning("glued 12 nodes belong to no element"))

    def test_recounted(self):
        self.assertEqual(messages.recount_unused_nodes(self.WARNING, 7),
                         "7 nodes belong to no element (e.g. nodes of edge elements); they are "
                         "kept fixed")

    def test_loose_note_from_the_report_arrays(self):
        report = {"loose_nodes": np.array([3, 4, 5]), "loose_class": np.array([0, 1, 2]),
                  "loose_entity": np.array([2, 0, 5]),
                  "loose_distance": np.array([1e-9, 2.5e-7, 1e-8])}
        self.assertEqual(
            messages.loose_note(report),
            "3 nodes belong to no element (e.g. nodes of edge or vertex elements); they are "
            "kept fixed and lie on the shape: 1 on CAD vertices, 1 on CAD edges, 1 on faces; "
            "farthest: node 4 (2.5e-07 from edge 0); e.g. nodes 3 4 5")
        # …which name_by_ids then puts in the user's ids and names
        self.assertTrue(messages.name_by_ids(messages.loose_note(report), DATA).endswith(
            "; farthest: node 14 (2.5e-07 from Edge1); e.g. nodes 13 14 15"))


class TestNotes(unittest.TestCase):
    """Each rule of messages.NOTE_RULES reads the text of the warning it is for."""

    def test_unused(self):
        self.assertEqual(
            messages.user_words("12 nodes belong to no element (e.g. nodes of edge elements)"),
            ("unused", "12 nodes are used by no face element (e.g. nodes of edge elements): "
                       "they stay where they are"))

    def test_left_out(self):
        w = messages.left_out(
            messages.left_out_reasons(collapsed=3, folded=2, crowded=4, misjoined=5, flat=1,
                                      miswound=6), np.arange(12))
        self.assertEqual(
            w, "left out 3 collapsed element(s) (a repeated node) and 2 element(s) with the "
               "same nodes as another one (folded pairs) and 4 element(s) overlapping around "
               "those (more than two on one edge) and 5 high-order element(s) joined to those "
               "through side nodes no conforming mesh shares (a side node that is also a "
               "corner, or on two edges) and 1 flat element(s) on one CAD edge or with two "
               "nodes on one CAD vertex and 6 element(s) wound against their face's mesh next "
               "to those: ids 0, 1, 2, 3, 4, 5, 6, 7, 8, 9 …")
        self.assertEqual(messages.user_words(w),
                         ("left_out", "21 elements are left out (collapsed or degenerate, e.g. "
                                      "where the mesher merged nodes): they keep their place "
                                      "and are drawn grey"))

    def test_node_order(self):
        w = messages.side_nodes_astray(np.array([4, 5]))
        self.assertEqual(
            w, "2 high-order element(s) have a side node farther from its side than the side is "
               "long (ids 4, 5): is the node order corners first, then the side nodes of sides "
               "1-2, 2-3, 3-1?")
        self.assertEqual(messages.user_words(w)[0], "node_order")
        self.assertTrue(messages.user_words(w)[1].startswith("2 curved elements"))

    def test_glued(self):
        w = messages.glued_nodes(3, 7, 9, (1.0, 2.0, 3.5))
        self.assertEqual(
            w, "glued 3 node(s) to another node at the same position (the mesh has a crack "
               "there, e.g. nodes 7 and 9 at (1, 2, 3.5)): they are measured as one node and "
               "move together")
        self.assertEqual(messages.user_words(w),
                         ("glued", "3 nodes sit on another node (a crack along a CAD edge): "
                                   "they are measured as one and move together"))

    def test_unknown_warning_is_its_own_kind(self):
        w = "the shape's tolerance 1e-07 is larger than 0.5 of its size"
        self.assertEqual(messages.user_words(w),
                         ("the shape's tolerance # is larger than # of its size", w))


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
