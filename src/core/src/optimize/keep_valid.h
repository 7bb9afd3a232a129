// Never worse, element by element: no element valid in a run's input is invalid in its result,
// none untangled in it is tangled (keep_valid.cpp).
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
/// the nodes of every element that `mesh` has made worse than the input by
/// MeshQuality::grade (`grade0[e]`, by measureQuality: the report's definition, the certificate
/// for curved elements): valid in the input and invalid (tangled or standing across) now, or
/// standing across but untangled in the input and tangled now; then those of the elements
/// that makes worse, and so on: an element whose every node is back is the input's, so every
/// element valid in the input ends valid and none ends tangled that was not. `mesh` must have the
/// input's elements (node lists); `q` is its quality on entry, and on return the quality of the
/// mesh as it ends. Returns the number of nodes put back that had moved; `undo` (when given)
/// receives what undoes it.
std::size_t keepValidElements(SurfaceMesh& mesh, const InputPositions& input,
                              const std::vector<unsigned char>& grade0,
                              const PlanarMeasure& measure, MeshQuality* q,
                              PutBack* undo = nullptr);

}  // namespace surfmesh::detail
