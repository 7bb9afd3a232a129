// OptimizeOptions::topology = "flip" (topology.cpp).
#pragma once

#include "surfmesh/optimize/optimizer.h"

namespace surfmesh {

/// optimizeMesh with topology "flip": a run without flips, then up to kMaxFlipRounds passes of
/// flipEdges (the caller's fixedNodes hold their elements), each followed by a run over the
/// nodes within two rings of the elements it rewired, until a pass flips nothing. On
/// cancellation or an exception the mesh is left as it was (node lists included).
OptimizeResult optimizeWithFlips(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                 const ProgressCallback& progress, const QualityStats* before);

}  // namespace surfmesh
