// SurfMesh — edge flips on the CAD faces: the topological repair that node motion cannot do.
//
// Two triangles of one face that share a mesh edge inside the face form a quadrilateral; a
// flip replaces their diagonal by the other one. It is done in the face's (u,v), unwrapped
// across a periodic seam (the second element's parameters shifted by whole periods onto the
// first's), so the new elements are on the CAD surface like the old ones. Never flipped:
//   * a mesh edge on a CAD edge (shared by elements of two faces, or by one element) or on a
//     seam (its ends on the CAD edge and the two elements on either side of the seam in (u,v));
//   * a pair of elements of different faces or types, or of quadrilaterals or of triangles of
//     order 3 and more (their interior nodes would need a new layout);
//   * a tri6 pair whose shared side node may not move (a Face node of the pair's face, not
//     held): that node is reused on the new diagonal, at the face's point nearest the
//     midpoint of its new ends (the straight-sided place);
//   * a pair whose new diagonal is already a mesh edge, or whose new elements are not both
//     wound as the face in (u,v);
//   * a pair in which an element has every node held (heldNodes: outside a region to optimize);
//   * a pair that would make an element whose corners do not tell its face: every corner on
//     CAD edges that bound this face and another one too, or every corner on one CAD edge (a
//     recovery of the mesh from its nodes, as any later measure is, could put it on the other
//     face, folded).
// A flip is kept when both new elements are valid (untangled, not standing across their
// surface, as the quality report judges) and either an old one was invalid, or the pair's
// smaller quality rises (by a relative 1e-6) while neither its smallest scaled Jacobian
// (Verdict's, of the corner triangles) nor, for tri6, its smallest Jacobian ratio falls.
// Node ids and positions (but the reused side node's), element ids and faces are kept; the two
// elements keep their first corner when they can and only their node lists change.
#pragma once

#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <cstdint>
#include <vector>

namespace surfmesh {

/// Flip passes of OptimizeOptions::topology = "flip" at most (each followed by a smoothing run).
constexpr int kMaxFlipRounds = 8;

struct FlipPass {
  std::size_t flips = 0;
  /// Elements whose node lists changed (sorted, each once).
  std::vector<std::int32_t> rewired;
};

/// Flips, in rounds until a round flips nothing (at most `maxRounds`), the pairs of the mesh
/// that the rules above accept. In a round the candidate pairs are taken worst first (the
/// smaller quality of the pair, then the edge's node ids), each element flipped at most once;
/// the result does not depend on threads or on anything but the mesh. `heldNodes`: empty, or
/// one entry per node (nonzero: held). Updates elemNodes, cornerUV and, for tri6, the reused
/// side node's uv and xyz. `elements`: empty, or one entry per element: the first round weighs
/// only the pairs with a marked element (later rounds: those next to the elements rewired by
/// the round before). `valid`: the caller knows every element of the mesh to be valid (as the
/// quality report judges): a linear triangle is then weighed without evaluating the surface
/// (the measure takes it in its own plane), the new elements of a flip always with it.
FlipPass flipEdges(SurfaceMesh& mesh, const PlanarMeasure& measure,
                   const std::vector<unsigned char>& heldNodes, int maxRounds = 16,
                   const std::vector<unsigned char>& elements = {}, bool valid = false);

/// Quality below which an element with every corner on one CAD edge counts as a needle.
constexpr double kNeedleQuality = 0.2;

/// Needles: triangles and quadrilaterals whose corners all lie on one CAD edge (nodes on that
/// edge, nodeEdge, and vertex nodes at its ends) and that are invalid or of quality below
/// `below` (sorted). Their sides along the edge are fixed by the CAD; only their chord may be
/// flipped. (A disk's fan between the nodes of its one circular edge is not one.)
std::vector<std::int32_t> needleElements(const SurfaceMesh& mesh, const PlanarMeasure& measure,
                                         double below = kNeedleQuality);

/// Verdict's scaled Jacobian of a triangle with corners a, b, c (the smallest corner's sine
/// over sin 60°, at most 1; 0 for a degenerate one).
double triangleScaledJacobian(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace surfmesh
