// The lists and warnings of the elements a run leaves tangled (optimizer.cpp).
#pragma once

#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

namespace surfmesh {

/// Sorts the elements tangled in `q` into res->tangledMovable and res->tangledUnmovable (those
/// that fold where no node that may move acts) and writes res->warnings, one line per
/// non-empty list.
void reportTangled(const SurfaceMesh& mesh, const MeshQuality& q, OptimizeResult* res);

}  // namespace surfmesh
