// Curved elements measured against their straight-sided counterpart (reference_mode.cpp).
#pragma once

#include "surfmesh/optimize/optimizer.h"

namespace surfmesh {

/// Whether the mesh has an element other than tri3 and quad4.
bool hasCurvedElements(const SurfaceMesh& mesh);

/// optimizeMesh in OptimizeOptions::highOrder = "reference" mode (see reference_mode.cpp);
/// optimizeMesh calls it, after holding the caller's fixedNodes.
OptimizeResult optimizeReference(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                 const ProgressCallback& progress, const QualityStats* before);

}  // namespace surfmesh
