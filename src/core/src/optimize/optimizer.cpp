#include "surfmesh/optimize/optimizer.h"

#include "progress_relay.h"
#include "reference_mode.h"
#include "straight_sided.h"
#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "sweep.h"
#include "sweep_support.h"
#include "tangled_report.h"
#include "topology.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace surfmesh {

const char* stopReasonName(StopReason r) {
  switch (r) {
    case StopReason::Converged:
      return "converged";
    case StopReason::MaxSweeps:
      return "max_sweeps";
    case StopReason::Cancelled:
      return "cancelled";
    case StopReason::NothingToDo:
      return "nothing_to_do";
  }
  return "?";
}

std::vector<std::vector<std::int32_t>> colorMovableNodes(const SurfaceMesh& mesh) {
  return detail::colorNodes(mesh, detail::buildIncidence(mesh));
}

namespace {

using detail::MeshPositions;
using detail::optimizeOnce;

/// Whether some node of `mesh` slides along a CAD edge (NodeKind::Edge) in this run.
bool hasSlidingNodes(const SurfaceMesh& mesh) {
  return std::find(mesh.nodeKind.begin(), mesh.nodeKind.end(), NodeKind::Edge) !=
         mesh.nodeKind.end();
}

/// A run that continues the completed run `first` on the same mesh: `run` (whose sweeps the
/// progress callback numbers after first's). An exception or a cancellation puts `input` (the
/// positions before `first`) back; the result covers both runs, its seconds those of `run`.
template <class Run>
OptimizeResult continueRun(SurfaceMesh& mesh, const OptimizeResult& first, MeshPositions& input,
                           Run run) {
  OptimizeResult res;
  try {
    res = run();
  } catch (...) {
    if (!input.empty()) input.restore(mesh);
    throw;
  }
  if (res.reason == StopReason::Cancelled) {
    if (!input.empty()) input.restore(mesh);
    res.after = first.before;
  }
  res.before = first.before;
  res.sweeps += first.sweeps;
  res.patchUntanglings += first.patchUntanglings;
  res.straightenedElements += first.straightenedElements;
  res.restoredNodes += first.restoredNodes;
  res.heldAcross = res.heldAcross || first.heldAcross;
  res.initialObjective = first.initialObjective;
  if (res.reason == StopReason::NothingToDo) res.reason = first.reason;
  res.movedNodes = 0;
  for (std::size_t i = 0; !input.empty() && i < mesh.nodeCount(); ++i)
    if (mesh.xyz[i] != input.xyz[i]) ++res.movedNodes;
  return res;
}

/// optimizeOnce holding linear triangles from standing across their surface (acrossArea), those
/// with a node sliding along a CAD edge too where valid. Where that leaves tangled elements a
/// node may move, a run that lets the valid elements with a sliding node lean across follows
/// from its result (with sliding nodes: their holds are not recorded), and where that leaves
/// some, a run without the hold: untangling comes first (e.g. an element folded where the
/// surface turns too fast to untangle it otherwise). Each run's last check still puts back the
/// nodes of any element valid at its start that it left invalid. A cancelled run leaves the
/// mesh as it was before the first.
OptimizeResult optimizeHolding(SurfaceMesh& mesh, const OptimizeOptions& opt,
                               const ProgressCallback& progress, const QualityStats* before) {
  MeshPositions input;  // kept (no copy: the arrays the first run replaced) for a later run
  int offset = 0;
  const ProgressCallback shifted = detail::renumbered(progress, offset);
  const bool sliding = hasSlidingNodes(mesh);
  OptimizeResult res = optimizeOnce(mesh, opt, shifted, before, detail::HoldAcross::All, &input);
  double seconds = res.seconds;
  for (const detail::HoldAcross next :
       {detail::HoldAcross::ExceptSliding, detail::HoldAcross::None}) {
    if (res.reason == StopReason::Cancelled || res.tangledMovable.empty()) break;
    if (next == detail::HoldAcross::ExceptSliding ? !sliding : !res.heldAcross) continue;
    offset = res.sweeps;
    const OptimizeResult first = res;
    res = continueRun(mesh, first, input,
                      [&] { return optimizeOnce(mesh, opt, shifted, &first.after, next); });
    seconds += res.seconds;
  }
  res.seconds = seconds;
  return res;
}

/// `run()` with the nodes i where fixed(i) holds made Fixed; the mesh's own node kinds are
/// back afterwards, also when it throws.
template <class Pred, class Run>
OptimizeResult withNodesFixed(SurfaceMesh& mesh, Pred fixed, Run run) {
  const std::vector<NodeKind> kinds = mesh.nodeKind;
  for (std::size_t i = 0; i < kinds.size(); ++i)
    if (fixed(i)) mesh.nodeKind[i] = NodeKind::Fixed;
  OptimizeResult res;
  try {
    res = run();
  } catch (...) {
    mesh.nodeKind = kinds;
    throw;
  }
  mesh.nodeKind = kinds;
  return res;
}

/// The run with sliding (NodeKind::Edge) nodes in two phases (see optimizeMesh), or one run.
OptimizeResult optimizeBoundary(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                const ProgressCallback& progress, const QualityStats* before) {
  const bool sliding = hasSlidingNodes(mesh);
  if (!sliding || opt.maxSweeps == 0) return optimizeHolding(mesh, opt, progress, before);
  // Sliding edge nodes: first the run with them held (the fixed boundary), then the run that
  // lets them slide from there. The second run never increases the number of tangled elements
  // and (monotone) never lowers the minimum quality of a valid mesh, so sliding never ends
  // worse than the fixed boundary would in those two respects.
  const auto t0 = std::chrono::steady_clock::now();
  MeshPositions input = MeshPositions::of(mesh);
  int offset = 0;
  const ProgressCallback phased = detail::renumbered(progress, offset, 2 * opt.maxSweeps);
  const OptimizeResult held = withNodesFixed(
      mesh, [&](std::size_t i) { return mesh.nodeKind[i] == NodeKind::Edge; },
      [&] { return optimizeHolding(mesh, opt, phased, before); });
  if (held.reason == StopReason::Cancelled) return held;  // the mesh was never touched
  offset = held.sweeps;
  OptimizeResult res = continueRun(mesh, held, input,
                                   [&] { return optimizeHolding(mesh, opt, phased, &held.after); });
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

/// A measure other than the shape measure that leaves tangled elements a node may move (the
/// Oddy measure's barrier can hold a fold the shape measure's opens: a crank arm's sliver):
/// the mesh is untangled with the shape measure from the input, then optimized with the
/// measure from there. That result is kept when it leaves fewer tangled elements; otherwise
/// the first run's. A cancelled run leaves the mesh as it was before the first.
OptimizeResult optimizeUntanglingFirst(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                       const ProgressCallback& progress,
                                       const QualityStats* before) {
  const auto t0 = std::chrono::steady_clock::now();
  MeshPositions input = MeshPositions::of(mesh);
  int offset = 0;
  const ProgressCallback shifted = detail::renumbered(progress, offset);
  OptimizeResult first = optimizeBoundary(mesh, opt, shifted, before);
  if (first.reason == StopReason::Cancelled || first.tangledMovable.empty()) return first;
  MeshPositions reached = MeshPositions::of(mesh);
  input.copyTo(mesh);  // the shape measure starts from the input
  OptimizeOptions byShape = opt;
  byShape.measure = "shape";
  offset = first.sweeps;
  const OptimizeResult untangled = continueRun(
      mesh, first, input, [&] { return optimizeBoundary(mesh, byShape, shifted, nullptr); });
  if (untangled.reason == StopReason::Cancelled) return untangled;
  offset = untangled.sweeps;
  OptimizeResult res = continueRun(mesh, untangled, input,
                                   [&] { return optimizeBoundary(mesh, opt, shifted, nullptr); });
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (res.reason == StopReason::Cancelled) return res;
  if (res.after.tangled >= first.after.tangled) {
    reached.restore(mesh);
    first.sweeps = res.sweeps;  // the work done
    first.seconds = seconds;
    return first;
  }
  res.seconds = seconds;
  return res;
}

}  // namespace

OptimizeResult optimizeMesh(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress, const QualityStats* before) {
  if (opt.topology != "none" && opt.topology != "flip")
    throw std::invalid_argument("topology must be 'none' or 'flip', got '" + opt.topology + "'");
  if (opt.topology == "flip" && opt.maxSweeps > 0)
    return optimizeWithFlips(mesh, opt, progress, before);
  if (!opt.fixedNodes.empty()) {
    // Nodes the caller holds: Fixed for the run (their elements' normals and measures are
    // those of any fixed node), their own kinds back afterwards, whatever happens.
    if (opt.fixedNodes.size() != mesh.nodeCount())
      throw std::invalid_argument("fixedNodes has " + std::to_string(opt.fixedNodes.size()) +
                                  " entries for " + std::to_string(mesh.nodeCount()) + " nodes");
    OptimizeOptions rest = opt;
    rest.fixedNodes.clear();
    return withNodesFixed(
        mesh, [&](std::size_t i) { return opt.fixedNodes[i] != 0; },
        [&] { return optimizeMesh(mesh, rest, progress, before); });
  }
  if (opt.highOrder != "reference" && opt.highOrder != "integral")
    throw std::invalid_argument("highOrder must be 'reference' or 'integral', got '" +
                                opt.highOrder + "'");
  if (opt.highOrder == "reference" && opt.maxSweeps > 0 && hasCurvedElements(mesh))
    return optimizeReference(mesh, opt, progress, before);
  if (opt.measure != "shape" && opt.maxSweeps > 0)
    return optimizeUntanglingFirst(mesh, opt, progress, before);
  return optimizeBoundary(mesh, opt, progress, before);
}

}  // namespace surfmesh
