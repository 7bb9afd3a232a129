// SurfMesh — a triangle mesh of a CadShape made with OpenCASCADE's BRepMesh, with the
// mesher's own knowledge of where every node lies (for tests, benchmarks and demos).
#pragma once

#include "surfmesh/cad/cad_bridge.h"

#include <cstdint>
#include <vector>

namespace surfmesh {

/// A BRepMesh triangulation of every face, merged into one conforming mesh.
struct OccMesh {
  /// Tri3 elements wound along each face's outward normal (Reversed faces flipped).
  MeshInput input;
  /// The face each triangle was meshed on.
  std::vector<std::int32_t> elemFace;
  /// What BRepMesh knows of each node: Vertex (end of an edge polygon, or a node on a
  /// degenerated edge), Edge (inside the polygon of an edge that is not a seam), Face
  /// (inside a face triangulation, or on a seam edge of that face); entity = vertex/edge/face id.
  std::vector<NodeClass> nodeClass;
  std::vector<std::int32_t> nodeEntity;
  /// Triangles dropped because they collapsed when the nodes of a pole were merged.
  std::size_t droppedTriangles = 0;
  /// Triangles dropped because merging the nodes of a pole made them coincide with another
  /// one (see dropCoincidentTriangles()).
  std::size_t droppedCoincident = 0;
  /// Faces BRepMesh left without a triangulation.
  std::vector<int> unmeshedFaces;
};

/// Meshes a copy of `shape` with BRepMesh_IncrementalMesh (`linearDeflection` absolute, or
/// relative to each edge's size when `relative`; `angularDeflection` in radians) and merges
/// the per-face triangulations through their shared edge polygons (and all nodes of a pole).
OccMesh meshWithBRepMesh(const CadShape& shape, double linearDeflection,
                         double angularDeflection = 0.5, bool relative = false);

/// Removes coincident triangles (the same three nodes) from an all-Tri3 `mesh`. BRepMesh
/// leaves them where a degenerated edge (a pole) has one node per end and an interior edge
/// of the face sees both ends: once the pole's nodes are merged, the triangles on either side
/// of that edge are one triangle wound both ways, a fold of zero area that makes its edges
/// non-manifold. Per group of coincident triangles, windings cancel in pairs: a group whose
/// windings balance goes entirely, otherwise one triangle with the dominant winding stays
/// (the first of them). `elemFace` (one entry per triangle, or null) follows the triangles.
/// Returns the number removed. Throws std::invalid_argument for an element other than Tri3.
std::size_t dropCoincidentTriangles(MeshInput& mesh, std::vector<std::int32_t>* elemFace);

}  // namespace surfmesh
