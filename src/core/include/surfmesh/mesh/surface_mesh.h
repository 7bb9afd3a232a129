// SurfMesh — a surface mesh whose nodes live on one or several parameterized surfaces (the
// faces of a B-rep, or a single analytic surface).
//
// Layout (structure of arrays, CSR connectivity) is chosen for the optimizer's sweeps:
//   nodes     xyz[N] (double), uv[N] on nodeFace[N] (−1 when the node is not inside a face:
//             on a CAD edge or vertex), nodeKind[N];
//   elements  elemType[E], elemOffset[E+1] into elemNodes (Gmsh node ordering),
//             elemFace[E] the face the element lies on, cornerUV aligned with elemNodes: the
//             (u,v) of each element node on the element's face, unwrapped across periodic seams
//             so that the corners of one element are close to each other in (u,v).
#pragma once

#include "surfmesh/geometry/curve.h"
#include "surfmesh/geometry/surface.h"

#include <cstdint>
#include <string>
#include <vector>

namespace surfmesh {

/// Supported element types. Node ordering is Gmsh's (corners first, counter-clockwise, then
/// edge nodes edge by edge, then interior nodes).
enum class ElementType : std::uint8_t {
  Tri3 = 0,   ///< linear triangle
  Quad4 = 1,  ///< bilinear quadrilateral
  Tri6 = 2,   ///< quadratic triangle (p = 2)
  Tri10 = 3,  ///< cubic triangle (p = 3)
  Tri15 = 4,  ///< quartic triangle (p = 4)
  Tri21 = 5,  ///< quintic triangle (p = 5)
  Quad8 = 6,  ///< serendipity quadrilateral (p = 2): 4 corners, then the middle of each side
};

/// Nodes of the largest element type (Tri21): a bound for per-element scratch arrays.
constexpr int kMaxElementNodes = 21;

/// Whether `code` is the value of an ElementType (0…6).
bool isElementTypeCode(int code);
/// Number of nodes of an element type. Throws std::invalid_argument for a value outside the
/// enumeration (e.g. a type code cast from unchecked input).
int nodeCount(ElementType t);
/// Polynomial order (1 for Tri3 and Quad4, 2 for Tri6 and Quad8).
int elementOrder(ElementType t);
/// Whether t is a quadrilateral: Quad4 or Quad8.
inline bool isQuad(ElementType t) { return t == ElementType::Quad4 || t == ElementType::Quad8; }
/// Number of corner (vertex) nodes: 3 or 4.
inline int cornerCount(ElementType t) { return isQuad(t) ? 4 : 3; }
/// Whether t is a curved (high-order) triangle: Tri6…Tri21.
inline bool isHighOrderTriangle(ElementType t) { return t != ElementType::Tri3 && !isQuad(t); }
/// "tri3", "quad4", "tri6", "tri10", "tri15", "tri21", "quad8".
const char* elementTypeName(ElementType t);
/// Inverse of elementTypeName; throws std::invalid_argument on an unknown name.
ElementType elementTypeFromName(const std::string& name);
/// The triangle type of order p (1…5); throws std::invalid_argument otherwise.
ElementType triangleOfOrder(int p);

/// How a node may move.
enum class NodeKind : std::uint8_t {
  Fixed = 0,  ///< never moves (CAD vertices, edge nodes in "fixed" boundary mode, poles…)
  Face = 1,   ///< moves in (u,v) of nodeFace
  Edge = 2,   ///< slides along curve nodeEdge in t (boundary mode "slide")
};

struct SurfaceMesh {
  // ---- geometry (not owned) ---------------------------------------------------------------
  std::vector<const Surface*> surfaces;  ///< face id → surface
  /// face id → ±1: multiplies the surface's outward normal to give the reference normal that
  /// decides what "tangled" means on that face (−1 where the mesh is wound the other way).
  std::vector<int> faceOrientation;
  std::vector<const Curve*> curves;  ///< edge id → curve (only needed for sliding nodes)

  // ---- nodes ------------------------------------------------------------------------------
  std::vector<Vec3> xyz;               ///< N positions
  std::vector<Vec2> uv;                ///< N; (u,v) on nodeFace (wrapped into the period)
  std::vector<std::int32_t> nodeFace;  ///< N; face id or −1
  std::vector<std::int32_t> nodeEdge;  ///< N; edge id or −1 (may be empty when unused)
  std::vector<double> nodeT;           ///< N; curve parameter on nodeEdge (may be empty)
  std::vector<NodeKind> nodeKind;      ///< N

  // ---- elements ---------------------------------------------------------------------------
  std::vector<ElementType> elemType;     ///< E
  std::vector<std::int64_t> elemOffset;  ///< E + 1
  std::vector<std::int32_t> elemNodes;   ///< connectivity
  std::vector<std::int32_t> elemFace;    ///< E
  std::vector<Vec2> cornerUV;            ///< aligned with elemNodes

  // ---- accessors --------------------------------------------------------------------------
  std::size_t nodeCount() const { return xyz.size(); }
  std::size_t elementCount() const { return elemType.size(); }
  int elementSize(std::size_t e) const {
    return static_cast<int>(elemOffset[e + 1] - elemOffset[e]);
  }
  const std::int32_t* elementNodes(std::size_t e) const { return elemNodes.data() + elemOffset[e]; }
  const Vec2* elementUV(std::size_t e) const { return cornerUV.data() + elemOffset[e]; }
  /// Reference (outward) unit normal of face f at (u,v): surface normal × faceOrientation[f].
  Vec3 referenceNormal(int f, const Vec2& uv) const;
  /// The same on `s`, a copy of face f's surface (a worker thread's own: an OCC surface's
  /// evaluation caches are not thread-safe).
  Vec3 referenceNormal(int f, const Vec2& uv, const Surface& s) const;
  /// The same where the surface has a normal; inside a pole's band, its normal across the
  /// singular line (Surface::normalAcrossPole) × faceOrientation[f].
  Vec3 referenceNormalAcrossPole(int f, const Vec2& uv, const Surface& s) const;

  /// Appends an element; `uvs` may be null (then the nodes' uv are used, unwrapped).
  void addElement(ElementType t, const std::int32_t* nodes, int face, const Vec2* uvs = nullptr);

  /// Checks the mesh; throws std::invalid_argument with a message naming the problem and the
  /// offending node/element ids (and counts where there are several). Checked:
  ///   * array sizes, element offsets (0, non-decreasing, ending at elemNodes.size()), element
  ///     type codes, node counts per element, face ids, faceOrientation (±1);
  ///   * finite positions, (u,v) of face nodes, t of edge nodes and corner (u,v);
  ///   * element node ids in range and not repeated within an element; the corner (u,v) of a
  ///     face node on its own face equal to the node's (u,v) up to whole periods;
  ///   * one element order (tri3 and quad4 may be mixed, so may tri6 and quad8; tri3 with tri6
  ///     may not: the mesh would not conform along the edges between them);
  ///   * no duplicate nodes: two nodes used by elements at the same position make the mesh
  ///     non-conforming (a crack that the optimizer would open) — the error gives how many
  ///     and an example pair, merge them first;
  ///   * no duplicate elements (same corner nodes);
  ///   * manifold within each face: a mesh edge shared by more than two elements of one face
  ///     (elements on different faces may share an edge: a non-manifold B-rep edge).
  /// Degenerate (zero-area) elements are NOT an error: they are reported as tangled
  /// (quality 0) and the optimizer untangles them like any tangled element (one whose nodes
  /// are all fixed stays tangled and is counted in the result's `tangled`).
  void validate() const;
};

/// Builds a single-surface mesh: every node carries (u,v) on `surface` (face 0), positions are
/// φ(u,v), nodes listed in `fixedNodes` are Fixed, the others Face. Elements are `type`, with
/// `nodesPerElement` = nodeCount(type) entries each in `conn`.
SurfaceMesh makeSingleSurfaceMesh(const Surface& surface, const std::vector<Vec2>& uv,
                                  ElementType type, const std::vector<std::int32_t>& conn,
                                  const std::vector<std::int32_t>& fixedNodes);

/// Re-evaluates xyz = φ(uv) for every Face node (after uv changed), and refreshes the
/// corresponding cornerUV entries.
void syncFaceNodes(SurfaceMesh& mesh);

}  // namespace surfmesh
