// Never worse, element by element: no element valid in a run's input is invalid in its result
// (keep_valid.cpp).
#pragma once

#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <cstddef>
#include <utility>
#include <vector>

namespace surfmesh::detail {

/// The positions a run started from (the arrays its write-back replaced: no copy).
struct InputPositions {
  const std::vector<Vec3>& xyz;
  const std::vector<Vec2>& uv;
  const std::vector<double>& nodeT;  ///< empty when the mesh has none
  const std::vector<Vec2>& cornerUV;
};

/// What keepValidElements changed, to undo it.
struct PutBack {
  std::vector<std::size_t> nodes;
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> nodeT;
  std::vector<std::pair<std::size_t, Vec2>> corners;  ///< (cornerUV slot, value)
  /// Puts the run's positions of the nodes put back into `mesh` again.
  void undo(SurfaceMesh& mesh) const;
};

/// Puts back where they were in `input` (positions, parameters and the elements' corner (u,v))
/// the nodes of every element that was valid in the input (`invalid0[e]` 0: by measureQuality,
/// the report's definition: neither tangled nor standing across, the certificate for curved
/// elements) and is invalid in `mesh` (tangled or standing across),
/// then those of the elements that makes invalid, and so on: an element whose every node is
/// back is the input's, so every element valid in the input ends valid. `mesh` must have the
/// input's elements (node lists); `q` is its quality on entry, and on return the quality of the
/// mesh as it ends. Returns the number of nodes put back that had moved; `undo` (when given)
/// receives what undoes it.
std::size_t keepValidElements(SurfaceMesh& mesh, const InputPositions& input,
                              const std::vector<unsigned char>& invalid0,
                              const PlanarMeasure& measure, MeshQuality* q,
                              PutBack* undo = nullptr);

}  // namespace surfmesh::detail
