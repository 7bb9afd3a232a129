// SurfMesh — what the steps of the CAD recovery share (internal to the CAD sources): the
// per-node face search kept for reuse (NodeSearch), names and checks used in the messages,
// the element helpers (see cad_bridge.h for the algorithm).
#pragma once

#include "projector.h"
#include "surfmesh/cad/cad_bridge.h"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
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

inline void fail(const std::string& msg) { throw std::invalid_argument(msg); }

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
std::string looseNodesNote(const BridgeReport& r);

}  // namespace cad_detail

}  // namespace surfmesh
