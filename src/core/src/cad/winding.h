// SurfMesh — the CAD recovery's winding analysis (internal to the CAD sources): the manifold
// mesh edges between two elements, each face's winding against its outward normal, the
// elements wound against the rest of their face's mesh, and the faces of doubtful elements
// settled by the mesh's winding (steps 2 and 5 of the recovery, see cad_bridge.h).
#pragma once

#include "surfmesh/cad/cad_bridge.h"

#include <cstdint>
#include <vector>

namespace surfmesh::cad_detail {

/// A corner edge used by exactly two elements: whether they run along it in opposite
/// directions (wound alike) or in the same one (wound oppositely).
struct EdgePair {
  std::int32_t e0, e1;
  bool alike;
};

/// The manifold corner edges of the mesh (edges of two distinct elements), in node order.
std::vector<EdgePair> manifoldEdgePairs(const MeshInput& input,
                                        const std::vector<std::int64_t>& offsets);

/// Winding of each face against its outward normal (+1 as the normal, −1 against it, +1 for
/// a face without elements), from the per-face element votes `agree` / `disagree` and the
/// relations between faces across shared mesh edges (see step 5 of CadMesh's constructor).
std::vector<int> faceWindingSigns(const std::vector<EdgePair>& edges,
                                  const std::vector<std::int32_t>& elemFace, int NF,
                                  const std::vector<std::int64_t>& agree,
                                  const std::vector<std::int64_t>& disagree);

/// BridgeReport::miswoundElements: per connected part of a face's mesh (through the manifold
/// corner edges between two of its elements), the elements of the less common winding.
std::vector<std::int32_t> miswoundElements(const std::vector<EdgePair>& edges,
                                           const std::vector<std::int32_t>& elemFace);

/// Settles the faces of the elements whose nodes are all within the tolerance of several faces
/// (`candidates[e]`, sorted, empty for an element with one face): the nearest face (step 2 of
/// CadMesh's constructor) is a guess there — on a thin face between faces tangent to it, the
/// centroid of an element spanning the thin face may be nearer to the neighbour, depending on
/// where the mesher or a smoother put its nodes. Such an element, when its winding disagrees
/// with a neighbour on its face f (across a manifold corner edge), goes to the candidate g
/// where it agrees with more of its neighbours than it disagrees with, by more than on f: an
/// element of a face meshed with the opposite winding to its neighbour's (Gmsh winds each
/// surface by its parametrisation), put on the neighbour, is then not read as wound against
/// that face's mesh (BridgeReport::miswoundElements). An element reversed against all its
/// neighbours has no such candidate and stays. Every move raises the number of links within a
/// face wound alike minus those wound oppositely: the loop ends.
void settleDoubtfulFaces(const std::vector<EdgePair>& edges,
                         const std::vector<std::vector<int>>& candidates,
                         std::vector<std::int32_t>& elemFace);

}  // namespace surfmesh::cad_detail
