// SurfMesh — the CAD bridge: a surface mesh made by someone else (BRepMesh, Mefisto, Gmsh,
// an STL…) plus the B-rep it was made on → a SurfaceMesh whose nodes know where they live on
// the B-rep (vertex, edge with curve parameter t, or face with (u,v)).
//
// Classification (CadMesh constructor):
//   1. Every node gets the set C(n) of faces it lies on: candidate faces from their bounding
//      boxes (searched near the node first, out to `tolerance` only when no face is close);
//      the point projected on each face's surface (closed form for planes, cylinders, cones,
//      spheres and tori; OCC's local extremum search Extrema_GenLocateExtPS from the nearest
//      samples of a grid on the face for free-form surfaces, confirmed by
//      ShapeAnalysis_Surface::ValueOfUV when it finds no point on the surface); the result
//      classified against the trimming loops (BRepTopAdaptor_FClass2d); outside them, or when
//      not clearly on the surface, the distance to the face's boundary edges (Extrema_ExtPC on
//      the edge's bounded curve). C(n) keeps the faces no farther than the nearest one plus
//      the tolerance of their boundary near the node (≥ 1e-6·diagonal): a node near a tangent
//      edge or on a thin wall is close to the neighbouring face too, but not on it.
//      Hints (Gmsh's node → face/edge/vertex) replace the search when they check out: the
//      node lies on the entity (within 1e-6·diagonal), or within the tolerance of it with no
//      other entity of its kind nearer (a mesher's node query within the entity's own
//      tolerance also names a neighbouring vertex or edge at a CAD feature smaller than that
//      tolerance). Other hints are ignored, counted and reported in a warning.
//   2. Every element is assigned the face shared by all its nodes (∩ C(n)); when several faces
//      qualify, the one minimizing the sum of its nodes' distances plus its centroid's
//      distance. When they share none (next to a CAD edge whose tolerance is as large as the
//      elements, a mesher's nodes may sit off both faces, each nearer to another one), the
//      face among their candidates that no node is farther from than the tolerance (nearest
//      in the worst node), with a warning; with no such face the element is an error
//      (std::invalid_argument naming the element and its nodes' faces): the mesh must conform
//      to the B-rep.
//   3. Every node gets the faces F(n) of its elements. One face → a face node (seam edges of
//      periodic faces are inside the face), except on the mesh's own boundary, where the node
//      is put on the nearest CAD edge of its face. Several faces → the node is on a CAD vertex
//      shared by them (when closer than a tenth of its shortest mesh edge) or else on their
//      nearest common CAD edge. Nodes on degenerated edges (poles) are vertex nodes.
//   4. Node kinds: face nodes move in (u,v) (NodeKind::Face); vertex nodes, poles and nodes in
//      no element are Fixed (a node of no element — a FEM mesh's node of edge or vertex
//      elements alone, on a free edge or a beam — is located on the whole shape: a CAD vertex
//      or edge within its tolerance, else the nearest face, free edge or lone vertex;
//      BridgeReport::looseNodes); edge nodes are Fixed (boundary "fixed", the paper's setting) or
//      slide along their edge (boundary "slide": NodeKind::Edge with nodeEdge / nodeT).
//   5. Orientation: the reference normal of face f is its outward normal (normalSign · φ_u×φ_v).
//      Faces joined by mesh edges have related windings whatever the node positions: the same
//      against their outward normals where the two elements run along the shared edge in
//      opposite directions, opposite ones otherwise. Through these relations all elements of a
//      connected part of the mesh vote once for its winding; a face wound against its outward
//      normal gets faceOrientation[f] = −1 and is reported as flipped. A consistently oriented
//      mesh is therefore never reported all tangled, and a small face whose own elements are
//      mostly tangled keeps the winding of the mesh around it. A part whose relations
//      contradict each other, or one of whose faces has its own elements clearly against the
//      result (more than 3 to 1, by at least 3), falls back to one vote per face.
//
// Element corners' (u,v) (SurfaceMesh::cornerUV) are computed on the element's face for
// every node (edge nodes through the edge's pcurve, vertex nodes through the vertex
// parameters on the face), unwrapped across periodic seams next to the element's other
// corners; a corner on a pole takes the mean free coordinate of the element's other corners.
//
// Node positions are kept as given (SurfaceMesh::xyz); only the optimizer moves them, and then
// exactly onto φ(u,v) / C(t). Except: a high-order element's side or interior node farther than
// the tolerance from its element's face but within the element's longest side (a mesher's
// curved element whose side node, at the midpoint of its ends in (u,v), fell outside the trimmed
// face) is taken at its nearest point on that face (BridgeReport::placedNodes, with a warning).
//
// Errors (std::invalid_argument with a message saying what and where): empty mesh,
// non-finite coordinates, index out of range, bad element sizes/offsets, bad hints, negative
// tolerance, unknown boundary mode, a mesh that does not lie on the shape (fails after a
// sample of nodes), nodes farther than the tolerance from the whole shape (faces, edges,
// vertices: how many, the worst distance, that node's id and its nearest entity; for
// high-order side and interior nodes, farther than their element's longest side), an
// element's node that lies on a free edge or lone vertex only (on no face), elements whose
// nodes share no face.
#pragma once

#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/diagnostic.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace surfmesh {

/// A mesh as plain arrays (what the bindings receive from numpy).
struct MeshInput {
  /// N node positions.
  std::vector<Vec3> nodes;
  /// E element types.
  std::vector<ElementType> types;
  /// E + 1 offsets into conn (offsets[0] = 0), or empty: then offsets follow from types.
  std::vector<std::int64_t> offsets;
  /// Connectivity, 0-based node ids, Gmsh node order per element (counter-clockwise corners
  /// seen from the outside for a mesh wound like the B-rep).
  std::vector<std::int32_t> conn;
  /// Optional hints, each empty or of size N: 0-based face / edge / vertex id the node lies
  /// on, −1 when unknown. The most specific wins (vertex, then edge, then face). A Gmsh FEM
  /// mesh gives them through FemMesh.getNodesByFace/Edge/Vertex.
  std::vector<std::int32_t> hintFace, hintEdge, hintVertex;
  /// Optional, empty or of size N: nonzero for the nodes of elements the caller left out of
  /// `conn` (collapsed, duplicate or flat elements). Such a node may lie on the mesh's
  /// boundary only through the hole its left-out element leaves: it goes on its face's nearest
  /// CAD edge only when within twice that edge's tolerance (at least 1e-6 × diagonal), and
  /// moves in its face otherwise (other boundary nodes go on an edge within the tolerance).
  std::vector<unsigned char> leftOutNeighbour;
};

struct BridgeOptions {
  /// Largest distance of a node from the shape. 0 → 1e-3 · shape diagonal; < 0 → error.
  double tolerance = 0.0;
  /// "fixed": nodes on CAD edges and vertices never move (the paper). "slide": nodes on CAD
  /// edges slide along their edge (vertices and poles stay fixed).
  std::string boundary = "fixed";
  /// Threads for the node search; 0 = all hardware threads.
  int threads = 0;
  /// Hint the nodes that have none by the entities' own tolerances (BRep_Tool::Tolerance),
  /// as FreeCAD's FemMesh.getNodesByVertex/Edge do, but with one box-grid search per node
  /// instead of one distance query per node and entity: a node within a vertex's tolerance
  /// is hinted to the nearest such vertex; else a node closer than its tolerance to exactly
  /// one edge, to that edge. These hints are checked like given ones (and not counted in
  /// hintsRejected when they do not check out), except that a high-order node inside one
  /// face's mesh (all its elements on that face, not on the mesh's boundary) is a face node
  /// when it lies on the edge (a mesher put it there across a corner of its face) or when its
  /// side does not follow the edge (a corner at its ends hinted neither to the edge nor to one
  /// of its vertices: a side across a face narrower than the edge's tolerance).
  bool toleranceHints = false;
  /// Keep the per-node face search (step 1 of the recovery, the costly part) in the CadMesh,
  /// so that a CadMesh of the same nodes with other elements (e.g. some left out) can reuse
  /// it: about 100 bytes per node while this CadMesh lives.
  bool keepNodeSearch = false;
};

struct NodeSearch;  // the per-node face search of a recovery (recovery.h, node_search.cpp)

/// Where a node lies on the B-rep.
enum class NodeClass : std::uint8_t {
  Vertex = 0,  ///< on a CAD vertex (also nodes on a degenerated edge: poles)
  Edge = 1,    ///< on a CAD edge (not a seam of a single face), parameter t
  Face = 2,    ///< inside a face (seam edges included), parameters (u,v)
  None = 3,    ///< in no element (see BridgeReport::looseNodes), or placed on no entity
};
const char* nodeClassName(NodeClass c);

struct BridgeReport {
  // ---- per node ---------------------------------------------------------------------------
  std::vector<NodeClass> nodeClass;      ///< N
  std::vector<std::int32_t> nodeEntity;  ///< N; vertex, edge or face id (by nodeClass)
  std::vector<double> nodeParam;         ///< N; t for Edge nodes, NaN otherwise
  std::vector<double> nodeDistance;      ///< N; distance to the shape (nearest face; for a node
                                         ///< of no element, also free edges and lone vertices)
  // ---- per face ---------------------------------------------------------------------------
  std::vector<unsigned char> faceFlipped;  ///< F; 1 when the mesh is wound against the face
  std::vector<int> flippedFaces;           ///< ids of the flipped faces
  std::vector<int> faceElements;           ///< F; number of elements on each face
  // ---- per element --------------------------------------------------------------------------
  /// Elements wound against the rest of their face's mesh (sorted): inside one face, two
  /// elements that run along their shared mesh edge in the same direction are wound
  /// oppositely; of the two windings of a connected part of a face's mesh, the elements of
  /// the less common one are listed (none on a tie). Such an element is tangled whatever its
  /// node positions; moving nodes can only fold the mesh over it (its connectivity must be
  /// reversed: an STL with flipped facets, a hand-edited mesh).
  std::vector<std::int32_t> miswoundElements;
  /// High-order nodes (no element's corner) farther than the tolerance from their face but
  /// within their element's longest side (a curved element's side node that a mesher placed
  /// on the face's surface outside its trimmed domain), sorted: the SurfaceMesh has them at
  /// their nearest point on their face, edge or vertex (every other node keeps its position).
  std::vector<std::int32_t> placedNodes;
  /// Nodes in no element of the input (sorted): a FEM mesh's nodes of edge or vertex elements
  /// alone (a free edge's, a beam's in a shell mesh), or nodes nothing uses. They are Fixed
  /// (NodeClass::None) and located on the whole shape, aligned with looseNodes: the entity
  /// they lie on (looseClass Vertex, Edge or Face and looseEntity its id: a CAD vertex or edge
  /// — one bounding no face included — within its tolerance, else the nearest face, free edge
  /// or lone vertex) and their distance to it. A node of no element farther than the tolerance
  /// from the whole shape is an error like any other.
  std::vector<std::int32_t> looseNodes;
  std::vector<NodeClass> looseClass;
  std::vector<std::int32_t> looseEntity;
  std::vector<double> looseDistance;
  /// Trimming curves (pcurves) of the faces carrying elements whose image on the face's surface
  /// lies off the edge's 3D curve by more than twice the edge's tolerance (and 1e-6·diag),
  /// sampled at 7 points: an imported B-rep whose 2D and 3D boundaries disagree. Nodes are kept
  /// inside the 2D boundary, so a node moved next to such an edge may end up `gap` outside the
  /// face's 3D edges; a warning says so.
  struct TrimGap {
    int face = -1, edge = -1;
    double gap = 0.0, tolerance = 0.0;
  };
  std::vector<TrimGap> trimGaps;
  // ---- totals -----------------------------------------------------------------------------
  double tolerance = 0.0;    ///< the tolerance used
  double maxDistance = 0.0;  ///< largest node distance to the shape
  std::int32_t worstNode = -1;
  std::size_t vertexNodes = 0, edgeNodes = 0, faceNodes = 0, unusedNodes = 0;
  std::size_t poleNodes = 0;     ///< vertex nodes on degenerated edges
  std::size_t fixedNodes = 0;    ///< NodeKind::Fixed
  std::size_t slidingNodes = 0;  ///< NodeKind::Edge
  std::size_t facesUsed = 0;     ///< faces carrying at least one element
  std::size_t hintsRejected = 0;
  std::size_t hintsTaken = 0;  ///< nodes classified by a hint (given or from tolerances)
  /// What the recovery noticed, as diagnostics (codes, ids: surfmesh/diagnostic.h) and the
  /// same as text (warnings[k] is diagnostics[k].render()).
  std::vector<Diagnostic> diagnostics;
  std::vector<std::string> warnings;
  double seconds = 0.0;  ///< time of the whole recovery

  /// Adds a warning (to `diagnostics`, and its text to `warnings`).
  void warn(Diagnostic d);

  /// A few lines for the user ("1234 nodes: 12 on vertices, …; 2 faces flipped: 3, 7").
  std::string summary() const;
};

/// A mesh recovered on a CAD shape: owns the Surface / Curve objects its SurfaceMesh points
/// to (clones of the shape's, one set per CadMesh), so two CadMesh on one shape can be used
/// from two threads. Movable, not copyable.
class CadMesh {
 public:
  /// Classifies `input` on `shape` (see the file comment). Throws std::invalid_argument.
  /// `sameNodes`, when given and built with BridgeOptions::keepNodeSearch from the same
  /// nodes, hints, tolerance and tolerance-hint option (its elements may differ: typically
  /// this input leaves some of them out), lends its per-node face search instead of running
  /// it again; the result is the same as without it. Otherwise it is ignored.
  CadMesh(std::shared_ptr<const CadShape> shape, const MeshInput& input,
          const BridgeOptions& options = {}, const CadMesh* sameNodes = nullptr);
  ~CadMesh();
  CadMesh(CadMesh&&) = default;
  CadMesh& operator=(CadMesh&&) = default;
  CadMesh(const CadMesh&) = delete;
  CadMesh& operator=(const CadMesh&) = delete;

  SurfaceMesh& mesh() { return mesh_; }
  const SurfaceMesh& mesh() const { return mesh_; }
  const BridgeReport& report() const { return report_; }
  const CadShape& shape() const { return *shape_; }
  const std::shared_ptr<const CadShape>& shapePtr() const { return shape_; }
  const BridgeOptions& options() const { return options_; }
  /// Whether this CadMesh keeps its node search (BridgeOptions::keepNodeSearch).
  bool keepsNodeSearch() const { return nodeSearch_ != nullptr; }
  /// Frees the kept node search (when no second recovery will need it).
  void releaseNodeSearch() { nodeSearch_.reset(); }
  /// Independent of the mesh: for each point, its distance to the trimmed face `faces[k]`
  /// (the surface inside the face's trimming loops, or the 3D curve of one of its boundary
  /// edges if nearer: a node on a toleranced edge is on the face, as FreeCAD's distToShape
  /// says; NaN for faces[k] = −1) and to the whole shape (its faces, edges and lone
  /// vertices), with the recovery's projection tools and threads. For figures of a result measured
  /// on the positions it returns. Throws std::invalid_argument on a face id out of range or sizes
  /// that differ.
  void distancesToShape(const std::vector<Vec3>& points, const std::vector<std::int32_t>& faces,
                        std::vector<double>* toFace, std::vector<double>* toShape) const;

 private:
  std::shared_ptr<const CadShape> shape_;
  BridgeOptions options_;
  std::vector<std::unique_ptr<Surface>> surfaces_;
  std::vector<std::unique_ptr<Curve>> curves_;
  SurfaceMesh mesh_;
  BridgeReport report_;
  std::shared_ptr<const NodeSearch> nodeSearch_;
};

/// Convenience for the bindings: a MeshInput of linear triangles from flat arrays
/// (xyz: 3N doubles, tris: 3E node ids).
MeshInput triangleMeshInput(const std::vector<double>& xyz, const std::vector<std::int32_t>& tris);

}  // namespace surfmesh
