// SurfMesh — structured diagnostics: what the core tells about its input, as a code, a text
// template and the ids and numbers the text names, so that a caller can name the nodes and
// elements by its own ids (FEM ids, FreeCAD's Face5) without reading the text.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace surfmesh {

/// The codes of the core's diagnostics (Diagnostic::code), each with what it says.
namespace code {
inline constexpr char kUnusedNodes[] = "unused_nodes";
inline constexpr char kHighOrderNodesPlaced[] = "high_order_nodes_placed";
inline constexpr char kMiswoundElements[] = "miswound_elements";
inline constexpr char kTrimGaps[] = "trim_gaps";
inline constexpr char kElementsOffFace[] = "elements_off_face";
inline constexpr char kBoundaryNodesOffEdges[] = "boundary_nodes_off_edges";
inline constexpr char kNodesBetweenFaces[] = "nodes_between_faces";
inline constexpr char kHintsRejected[] = "hints_rejected";
inline constexpr char kBadOption[] = "bad_option";
inline constexpr char kBadLayout[] = "bad_layout";
inline constexpr char kEmptyMesh[] = "empty_mesh";
inline constexpr char kNonFiniteNode[] = "non_finite_node";
inline constexpr char kNodeOutOfRange[] = "node_out_of_range";
inline constexpr char kRepeatedNode[] = "repeated_node";
inline constexpr char kBadHint[] = "bad_hint";
inline constexpr char kMeshOffShape[] = "mesh_off_shape";
inline constexpr char kNodesOffShape[] = "nodes_off_shape";
inline constexpr char kNodesOnNoFace[] = "nodes_on_no_face";
inline constexpr char kElementOnNoFace[] = "element_on_no_face";
inline constexpr char kDuplicateNodes[] = "duplicate_nodes";
inline constexpr char kDuplicateElements[] = "duplicate_elements";
inline constexpr char kNonManifold[] = "non_manifold";
inline constexpr char kMixedOrders[] = "mixed_orders";
}  // namespace code

/// One code of the core's diagnostics: whether it refuses the input (an InputError) or warns
/// (BridgeReport::diagnostics), and what it is about.
struct DiagnosticCode {
  const char* code;
  bool refusal;
  const char* meaning;
};

/// Every code the core gives (the one list: the bindings' diagnostic_codes(), the docs' table).
inline constexpr DiagnosticCode kDiagnosticCodes[] = {
    {code::kUnusedNodes, false,
     "nodes of no element (of edge or vertex elements alone): kept fixed, located on the shape"},
    {code::kHighOrderNodesPlaced, false,
     "high-order nodes off their face within their element's side, taken at their nearest point on "
     "it"},
    {code::kMiswoundElements, false, "elements wound against the rest of their face's mesh"},
    {code::kTrimGaps, false,
     "trimming curves of faces lying off their 3D edges (an imported B-rep)"},
    {code::kElementsOffFace, false,
     "elements put on the face all their nodes are within the tolerance of, though each node is "
     "nearest to another"},
    {code::kBoundaryNodesOffEdges, false,
     "nodes on the mesh's boundary on no CAD edge of their face: kept fixed"},
    {code::kNodesBetweenFaces, false,
     "nodes touching elements of several faces on none of their common CAD edges or vertices: kept "
     "fixed"},
    {code::kHintsRejected, false,
     "node hints (the face, edge or vertex a mesher put a node on) ignored as too far from it"},
    {code::kBadOption, true, "an option out of its range, or no shape"},
    {code::kBadLayout, true, "arrays of the wrong size or layout (offsets, connectivity, hints)"},
    {code::kEmptyMesh, true, "a mesh with no nodes or no elements"},
    {code::kNonFiniteNode, true, "a node with a NaN or infinite coordinate"},
    {code::kNodeOutOfRange, true, "an element referencing a node that does not exist"},
    {code::kRepeatedNode, true, "an element listing one node twice"},
    {code::kBadHint, true, "a node hint naming no face, edge or vertex of the shape"},
    {code::kMeshOffShape, true,
     "the mesh does not lie on the shape (another shape, placement or units)"},
    {code::kNodesOffShape, true, "nodes farther than the tolerance from the shape"},
    {code::kNodesOnNoFace, true,
     "nodes of face elements on a free edge or lone vertex of the shape, which bounds no face"},
    {code::kElementOnNoFace, true, "an element whose nodes share no face (across a CAD edge)"},
    {code::kDuplicateNodes, true,
     "nodes at the position of another node (a crack), when not glued"},
    {code::kDuplicateElements, true, "elements with the same corner nodes as another one"},
    {code::kNonManifold, true, "a mesh edge shared by more than two elements of one face"},
    {code::kMixedOrders, true, "elements of different orders in one mesh"},
};

/// One message of the core about its input (a warning of the CAD bridge, or the reason it
/// refuses the input).
///
/// `format` is the text with placeholders, filled by render():
///  - `{node}` (= `{node0}`), `{node1}`, …: `nodes[k]`; `{nodes}`: every node of `nodes`,
///    separated by spaces; `{nodes1}`: those from `nodes[1]` on. The same for `element` /
///    `elements`, `face` / `faces`, `edge` / `edges`, `vertex` / `vertices`.
///  - `{count}`: `count`; `{name}`: the number `values` holds under that name (an integer without
///  decimals, any
///    other number with 6 significant digits, as std::ostream writes it).
/// Nodes and elements are the 0-based indices of the arrays the core was given; faces, edges
/// and vertices the 0-based indices of the shape's maps (CadShape), rendered as FreeCAD names
/// them ("Face5" for face 4). A placeholder with nothing behind it stays as it is.
struct Diagnostic {
  std::string code;        ///< stable identifier of the kind of message, e.g. "nodes_off_shape"
  std::string format;      ///< the text, with placeholders
  std::int64_t count = 0;  ///< how many nodes / elements / entities the message is about
  std::vector<std::int64_t> nodes, elements;
  std::vector<int> faces, edges, vertices;
  std::vector<std::pair<std::string, double>> values;

  /// The text with the core's indices (and FreeCAD's names of the shape's entities).
  std::string render() const;
};

/// A number as render() writes it: an integer without decimals, others with 6 significant
/// digits.
std::string diagnosticNumber(double v);

/// The core's refusal of its input, with its diagnostic (what() is the rendered text).
class InputError : public std::invalid_argument {
 public:
  explicit InputError(Diagnostic d);
  const Diagnostic& diagnostic() const noexcept { return diagnostic_; }

 private:
  Diagnostic diagnostic_;
};

}  // namespace surfmesh
