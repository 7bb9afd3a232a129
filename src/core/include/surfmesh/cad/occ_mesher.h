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
  /// Faces BRepMesh left without a triangulation.
  std::vector<int> unmeshedFaces;
};

/// Meshes a copy of `shape` with BRepMesh_IncrementalMesh (`linearDeflection` absolute, or
/// relative to each edge's size when `relative`; `angularDeflection` in radians) and merges
/// the per-face triangulations through their shared edge polygons (and all nodes of a pole).
OccMesh meshWithBRepMesh(const CadShape& shape, double linearDeflection,
                         double angularDeflection = 0.5, bool relative = false);

}  // namespace surfmesh
