// One optimization run: the nonlinear Gauss–Seidel sweeps over the node colours with the δ
// policy, the escapes and the stopping rules (optimizer internals).
#pragma once

#include "surfmesh/optimize/optimizer.h"
#include "sweep_support.h"

#include <utility>
#include <vector>

namespace surfmesh {
namespace detail {

/// A mesh's node positions and parameters (see optimizeOnce's `previous`).
struct MeshPositions {
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> nodeT;
  std::vector<Vec2> cornerUV;
  /// A copy of the mesh's positions.
  static MeshPositions of(const SurfaceMesh& mesh) {
    return {mesh.xyz, mesh.uv, mesh.nodeT, mesh.cornerUV};
  }
  bool empty() const { return xyz.empty(); }
  /// Puts the positions back into `mesh` (a copy: they can be put back again).
  void copyTo(SurfaceMesh& mesh) const {
    mesh.xyz = xyz;
    mesh.uv = uv;
    if (!mesh.nodeT.empty()) mesh.nodeT = nodeT;
    mesh.cornerUV = cornerUV;
  }
  /// Puts the positions back into `mesh`, moved there (this copy is empty afterwards).
  void restore(SurfaceMesh& mesh) {
    mesh.xyz = std::move(xyz);
    mesh.uv = std::move(uv);
    if (!mesh.nodeT.empty()) mesh.nodeT = std::move(nodeT);
    mesh.cornerUV = std::move(cornerUV);
  }
};
/// One run. `before`, when given, is the quality the caller already measured on this mesh
/// (the sliding phase starts from the held phase's result): it is not measured again.
/// `holdAcross`: which linear triangles are held from standing across their surface.
/// `previous`, when given, receives the positions the mesh had before a completed run (the
/// arrays the run replaced: no copy).
OptimizeResult optimizeOnce(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress, const QualityStats* before,
                            HoldAcross holdAcross, MeshPositions* previous = nullptr);

}  // namespace detail
}  // namespace surfmesh
