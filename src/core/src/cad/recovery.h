// SurfMesh — what the steps of the CAD recovery share (internal to the CAD sources): the
// per-node face search kept for reuse (NodeSearch), names and checks used in the messages,
// the element helpers (see cad_bridge.h for the algorithm).
#pragma once

#include "projector.h"
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/diagnostic.h"
#include "winding.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace surfmesh {

/// The hint a node's classification was forced by.
enum class Forced : std::uint8_t { None, Vertex, Edge, Face };

/// Step 1 of a recovery, kept for reuse (BridgeOptions::keepNodeSearch): what it depends on
/// (nodes, hints, tolerance, tolerance-hint option) and what it found per node. Read-only once
/// made: the recovery that made it and any that reuse it read it in place.
struct NodeSearch {
  // what it depends on (filled only when it is kept)
  std::vector<Vec3> nodes;
  std::vector<std::int32_t> hintFace, hintEdge, hintVertex;
  double tol = 0.0;
  bool toleranceHints = false;
  // per node: candidate faces, the hint taken (entity, edge parameter), a given hint rejected
  std::vector<std::vector<cad_detail::FaceHit>> hits;
  std::vector<Forced> forced;
  std::vector<std::int32_t> forcedId;
  std::vector<double> forcedT;
  std::vector<unsigned char> hintRejected;

  bool matches(const MeshInput& in, double t, bool th) const {
    return t == tol && th == toleranceHints && in.nodes.size() == nodes.size() &&
           std::equal(
               nodes.begin(), nodes.end(), in.nodes.begin(),
               [](const Vec3& a, const Vec3& b) { return (a.array() == b.array()).all(); }) &&
           in.hintFace == hintFace && in.hintEdge == hintEdge && in.hintVertex == hintVertex;
  }
};

namespace cad_detail {

/// Faces named as users know them: by their 1-based position in the shape's face map
/// (TopExp::MapShapes order, FreeCAD's Face1, Face2, ...), where the core counts from 0.
inline std::string faceName(int f) { return "Face" + std::to_string(f + 1); }

inline std::string faceNames(const std::vector<int>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i)
    s += (i ? (i + 1 == v.size() ? " and " : ", ") : "") + faceName(v[i]);
  return s.empty() ? "no face" : s;
}

/// Whether the caller gave node n a hint (a vertex, edge or face of its own; the tolerance
/// rule's are not given ones).
inline bool givenHint(const MeshInput& input, std::size_t n) {
  return (!input.hintVertex.empty() && input.hintVertex[n] >= 0) ||
         (!input.hintEdge.empty() && input.hintEdge[n] >= 0) ||
         (!input.hintFace.empty() && input.hintFace[n] >= 0);
}

inline bool includesAll(const std::vector<int>& sortedSuper, const std::vector<int>& sortedSub) {
  return std::includes(sortedSuper.begin(), sortedSuper.end(), sortedSub.begin(), sortedSub.end());
}

// Local node index pairs of the element's boundary edges, with the high-order nodes on each
// edge (Gmsh ordering: corners, then edge nodes edge by edge).
struct ElementEdges {
  int corners = 3;
  int perEdge = 0;  // high-order nodes per edge
};

inline ElementEdges elementEdges(ElementType t) {
  ElementEdges r;
  r.corners = cornerCount(t);
  r.perEdge = t == ElementType::Quad4 ? 0 : elementOrder(t) - 1;
  return r;
}

/// The normal of an element's corner plane, along its winding, as long as twice its area (a
/// triangle's) or its diagonals' cross product (a quadrilateral's): `nd` its node ids, `nc` its
/// corners.
inline Vec3 cornerPlaneNormal(const MeshInput& input, const std::int32_t* nd, int nc) {
  auto X = [&](int k) { return input.nodes[static_cast<std::size_t>(nd[k])]; };
  return nc == 4 ? Vec3((X(2) - X(0)).cross(X(3) - X(1))) : Vec3((X(1) - X(0)).cross(X(2) - X(0)));
}

/// A warning `code` on `count` nodes, naming the first of them ({node}) by `first`.
inline Diagnostic nodesNote(const char* code, std::size_t count, std::size_t first,
                            std::string format) {
  Diagnostic d;
  d.code = code;
  d.count = static_cast<std::int64_t>(count);
  d.nodes = {static_cast<std::int64_t>(first)};
  d.format = std::move(format);
  return d;
}

/// Adds CAD entity `id` of kind `c` (a vertex, an edge, else a face) to `d`'s lists and returns
/// the placeholder that names it in `d`'s text.
inline const char* nameEntity(Diagnostic& d, NodeClass c, int id) {
  if (c == NodeClass::Vertex) {
    d.vertices.push_back(id);
    return "{vertex}";
  }
  if (c == NodeClass::Edge) {
    d.edges.push_back(id);
    return "{edge}";
  }
  d.faces.push_back(id);
  return "{face}";
}

/// Refuses the input: an InputError with the diagnostic `d`.
[[noreturn]] inline void fail(Diagnostic d) { throw InputError(std::move(d)); }
/// Refuses the input with a message that names no node, element or shape entity.
[[noreturn]] inline void fail(std::string code, std::string text) {
  Diagnostic d;
  d.code = std::move(code);
  d.format = std::move(text);
  throw InputError(std::move(d));
}
/// Refuses the input with a message on one element and / or node ({element}, {node}; -1: none).
[[noreturn]] inline void failAt(std::string code, std::string text, std::int64_t element,
                                std::int64_t node = -1) {
  Diagnostic d;
  d.code = std::move(code);
  d.format = std::move(text);
  d.count = 1;
  if (element >= 0) d.elements.push_back(element);
  if (node >= 0) d.nodes.push_back(node);
  throw InputError(std::move(d));
}

/// A high-order element's side and interior nodes (those that are no element's corner) may lie
/// up to this fraction of the element's longest corner-to-corner side off its face, beyond the
/// tolerance. A mesher that curves an element puts a side node on the face's surface at the
/// midpoint of its ends in (u,v) (Gmsh), which can fall outside the face's trimmed domain:
/// by the sagitta of the face's boundary over the side where that boundary is concave, or
/// onto a neighbouring face of the same surface (Gmsh's order-2 meshes of eight of the twelve
/// CAD parts at diagonal / 17 have such nodes, up to 0.49 × the side off their element's
/// face). Such a node is taken at its nearest point on the element's face; the corners of
/// every element must still lie within the tolerance (a mesh of another shape, or placed
/// elsewhere, is refused as before).
inline constexpr double kHighOrderReach = 1.0;

/// The warning on the nodes of no element (BridgeReport::looseNodes): where they lie.
Diagnostic looseNodesNote(const BridgeReport& r);

/// The state of one recovery (CadMesh's constructor), passed from step to step: the input and
/// options, validated, the projection tools, and what each step found for the next ones.
struct Recovery {
  Recovery(const CadShape& shape, const MeshInput& in, const BridgeOptions& opts)
      : S(shape),
        input(in),
        options(opts),
        N(in.nodes.size()),
        E(in.types.size()),
        NF(shape.faceCount()),
        NE(shape.edgeCount()),
        NV(shape.vertexCount()),
        diag(shape.diagonal()) {}

  const CadShape& S;
  const MeshInput& input;
  const BridgeOptions& options;
  const std::size_t N, E;  // nodes, elements
  const int NF, NE, NV;    // faces, edges, vertices of the shape
  const double diag;       // the shape's diagonal
  // validateInput
  double tol = 0.0;
  bool slide = false;
  int threads = 1;
  std::vector<std::int64_t> offsets;  // E + 1
  // the projection tools (projectorGeometry, one Projector per thread slot)
  std::vector<Box> faceBoxes, edgeBoxes;
  std::vector<double> faceSlack;
  std::unique_ptr<ProjectorPool> projectors;
  // highOrderReach: per node, how far off its face a high-order node may lie (0: tol)
  std::vector<double> reach;
  // step 1: the node search (fresh or lent), and its hits with the far high-order nodes'
  std::shared_ptr<const NodeSearch> search;
  std::vector<std::vector<FaceHit>> withFar;
  const std::vector<std::vector<FaceHit>>& hits() const {
    return withFar.empty() ? search->hits : withFar;
  }
  // step 2: each element's face, the manifold mesh edges
  std::vector<std::int32_t> elemFace;
  std::vector<EdgePair> manifoldEdges;
  // step 3: the faces of each node's elements, shortest incident mesh edge, mesh boundary
  // nodes, roles (bit 0 a corner, bit 1 a high-order node); face nodes' (u,v), poles
  std::vector<std::vector<int>> elemFacesOfNode;
  std::vector<double> hmin;
  std::vector<unsigned char> onMeshBoundary, nodeRoles;
  // a high-order node's side: the corners at its ends (-1, -1 for an element's interior
  // nodes and for corners)
  std::vector<std::array<std::int32_t, 2>> sideEnds;
  std::vector<Vec2> nodeUV;
  std::vector<unsigned char> isPole;
  // the elements' corner (u,v) and their votes on the winding (+1 along the surface normal)
  std::vector<Vec2> allCornerUV;
  std::vector<signed char> vote;
};

// ---- the steps, in the order CadMesh's constructor runs them -------------------------------
/// Checks the options and the input (sizes, offsets, node ids, hints): tol, slide, threads,
/// offsets. Throws std::invalid_argument.
void validateInput(Recovery& r);
/// Reach of each high-order node that is no element's corner (kHighOrderReach), 0 otherwise.
void highOrderReach(Recovery& r);
/// Fails fast on a mesh of another shape (bounding boxes, a sample of nodes).
void checkMeshOnShape(const Recovery& r);
/// Step 1: the faces near every node (hints first).
std::shared_ptr<const NodeSearch> searchNodes(const Recovery& r);
/// High-order nodes beyond the tolerance: every face within their reach (kHighOrderReach),
/// not only the nearest (off its trimmed domain, a node may be nearer to another face than to
/// its element's). Searched on a copy of the hits (withFar), so that a kept node search (which
/// depends on the nodes alone, not on the elements that set the reach) stays as it was.
void farHighOrderNodes(Recovery& r);
/// Node distances, the nodes of no element located on the whole shape; fails on nodes off the
/// shape.
void locateNodes(const Recovery& r, BridgeReport& report);
/// Counts the hints taken and rejected (with a warning).
void reportHints(const Recovery& r, BridgeReport& report);
/// Step 2: the face of every element (elemFace, manifoldEdges).
void assignElementFaces(Recovery& r, BridgeReport& report);
/// Step 3, first part: the faces of each node's elements, mesh boundary nodes, shortest
/// incident mesh edge, node roles.
void meshTopology(Recovery& r);
/// Step 3: node classes (BridgeReport::nodeClass, nodeEntity, nodeParam; nodeUV, isPole).
void classifyNodes(Recovery& r, BridgeReport& report);
/// The corners' (u,v) of every element on its face and the orientation votes (allCornerUV,
/// vote).
void cornerUVs(Recovery& r, const BridgeReport& report);

}  // namespace cad_detail

}  // namespace surfmesh
