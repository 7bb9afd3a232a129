// The progress of a run made of several optimizer runs (integral then reference stages, flip
// passes between sweeps, a second run after the first): one callback numbers every run's
// sweeps after those of the runs before.
#pragma once

#include "surfmesh/optimize/optimizer.h"

#include <functional>
#include <utility>

namespace surfmesh::detail {

/// `progress` for a run that follows runs of `offset` sweeps in all (`offset` is read at each
/// call, so the caller advances it between runs): sweeps counted from the first run's start,
/// out of `total` when positive, else out of the run's own maximum plus `offset`; the stage
/// mapped by `stage` when given (else the run's own). Empty when `progress` is.
inline ProgressCallback renumbered(const ProgressCallback& progress, const int& offset,
                                   int total = 0, std::function<int(int)> stage = {}) {
  if (!progress) return {};
  return [&progress, &offset, total, stage = std::move(stage)](const OptimizeProgress& p) {
    OptimizeProgress q = p;
    q.sweep += offset;
    q.maxSweeps = total > 0 ? total : p.maxSweeps + offset;
    if (stage) q.stage = stage(p.stage);
    return progress(q);
  };
}

}  // namespace surfmesh::detail
