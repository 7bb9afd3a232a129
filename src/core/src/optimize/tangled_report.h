// Which tangled elements no node motion repairs, and the lists and warnings of the elements a
// run leaves tangled (tangled_report.cpp).
#pragma once

#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <vector>

namespace surfmesh {

namespace detail {

/// Whether element e (nodes at `xyz`, reference normal n) folds where no node that may move
/// acts: no node motion can repair it (see tangled_report.cpp).
bool foldHeld(const SurfaceMesh& m, const std::vector<Vec3>& xyz, std::size_t e, const Vec3& n);

/// Per element: 1 when none of its nodes may move (it is in no node's submesh).
std::vector<unsigned char> frozenElements(const SurfaceMesh& m);

}  // namespace detail

/// Sorts the elements tangled in `q` into res->tangledMovable and res->tangledUnmovable (those
/// that fold where no node that may move acts) and writes res->warnings, one line per
/// non-empty list.
void reportTangled(const SurfaceMesh& mesh, const MeshQuality& q, OptimizeResult* res);

}  // namespace surfmesh
