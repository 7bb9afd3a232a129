// OptimizeOptions::topology = "flip": smoothing runs alternating with passes of edge flips
// (as Netgen's surface optimizer alternates edge swapping with smoothing), until a pass flips
// nothing.
#include "topology.h"

#include "progress_relay.h"
#include "surfmesh/optimize/edge_flips.h"
#include "sweep.h"
#include "sweep_support.h"
#include "tangled_report.h"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

namespace {

/// Everything a run with flips may change, to restore on cancellation or an exception.
struct Snapshot {
  detail::MeshPositions positions;
  std::vector<std::int32_t> elemNodes;
  static Snapshot of(const SurfaceMesh& m) { return {detail::MeshPositions::of(m), m.elemNodes}; }
  void restore(SurfaceMesh& m) const {
    positions.copyTo(m);
    m.elemNodes = elemNodes;
  }
};

/// The elements with a node inside `rings` rings of the rewired ones (those the run after a
/// flip pass may change) as a mesh of their own, with `held` marking the nodes that stay: the
/// nodes outside the rings and the caller's held ones. `nodes` / `elements` map back.
SurfaceMesh aroundRewired(const SurfaceMesh& mesh, const std::vector<std::int32_t>& rewired,
                          int rings, const std::vector<unsigned char>& callerHeld,
                          std::vector<unsigned char>* held, std::vector<std::int32_t>* nodes,
                          std::vector<std::int32_t>* elements) {
  const std::size_t N = mesh.nodeCount(), E = mesh.elementCount();
  std::vector<unsigned char> seed(E, 0);
  for (std::int32_t e : rewired) seed[static_cast<std::size_t>(e)] = 1;
  const std::vector<unsigned char> region = detail::widenByRings(mesh, std::move(seed), rings);
  std::vector<unsigned char> free(N, 0);
  for (std::size_t e = 0; e < E; ++e)
    if (region[e])
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const auto n = static_cast<std::size_t>(mesh.elementNodes(e)[k]);
        free[n] = callerHeld.empty() || !callerHeld[n];
      }
  // Every element with a free node.
  std::vector<unsigned char> take(E, 0);
  for (std::size_t e = 0; e < E; ++e)
    for (int k = 0; k < mesh.elementSize(e) && !take[e]; ++k)
      take[e] = free[static_cast<std::size_t>(mesh.elementNodes(e)[k])];
  SurfaceMesh sub;
  sub.surfaces = mesh.surfaces;
  sub.faceOrientation = mesh.faceOrientation;
  sub.curves = mesh.curves;
  std::vector<std::int32_t> local(N, -1);
  nodes->clear();
  elements->clear();
  held->clear();
  const bool edges = mesh.nodeEdge.size() == N, params = mesh.nodeT.size() == N;
  for (std::size_t e = 0; e < E; ++e) {
    if (!take[e]) continue;
    std::int32_t nd[kMaxElementNodes];
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const auto n = static_cast<std::size_t>(mesh.elementNodes(e)[k]);
      if (local[n] < 0) {
        local[n] = static_cast<std::int32_t>(nodes->size());
        nodes->push_back(static_cast<std::int32_t>(n));
        sub.xyz.push_back(mesh.xyz[n]);
        sub.uv.push_back(mesh.uv[n]);
        sub.nodeFace.push_back(mesh.nodeFace[n]);
        if (edges) sub.nodeEdge.push_back(mesh.nodeEdge[n]);
        if (params) sub.nodeT.push_back(mesh.nodeT[n]);
        sub.nodeKind.push_back(mesh.nodeKind[n]);
        held->push_back(free[n] ? 0 : 1);
      }
      nd[k] = local[n];
    }
    sub.addElement(mesh.elemType[e], nd, mesh.elemFace[e], mesh.elementUV(e));
    elements->push_back(static_cast<std::int32_t>(e));
  }
  return sub;
}

/// Writes the run's result on `sub` back to `mesh`.
void writeBack(const SurfaceMesh& sub, const std::vector<std::int32_t>& nodes,
               const std::vector<std::int32_t>& elements, SurfaceMesh& mesh) {
  const bool params = mesh.nodeT.size() == mesh.nodeCount() && sub.nodeT.size() == sub.nodeCount();
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const auto n = static_cast<std::size_t>(nodes[i]);
    mesh.xyz[n] = sub.xyz[i];
    mesh.uv[n] = sub.uv[i];
    if (params) mesh.nodeT[n] = sub.nodeT[i];
  }
  for (std::size_t i = 0; i < elements.size(); ++i) {
    const auto e = static_cast<std::size_t>(elements[i]);
    const int k = mesh.elementSize(e);
    std::copy(sub.elementUV(i), sub.elementUV(i) + k,
              mesh.cornerUV.begin() + static_cast<std::ptrdiff_t>(mesh.elemOffset[e]));
  }
}

}  // namespace

OptimizeResult optimizeWithFlips(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                 const ProgressCallback& progress, const QualityStats* before) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!opt.fixedNodes.empty() && opt.fixedNodes.size() != mesh.nodeCount())
    throw std::invalid_argument("fixedNodes has " + std::to_string(opt.fixedNodes.size()) +
                                " entries for " + std::to_string(mesh.nodeCount()) + " nodes");
  const PlanarMeasure& measure = measureByName(opt.measure);
  mesh.validate();
  const Snapshot original = Snapshot::of(mesh);
  OptimizeOptions inner = opt;
  inner.topology = "none";
  // The runs report their sweeps one after the other, each run's stages after the last's.
  int done = 0, stageBase = 0, stageTop = 0;
  const ProgressCallback staged = detail::renumbered(progress, done, 0, [&](int s) {
    stageTop = std::max(stageTop, stageBase + s);
    return stageBase + s;
  });
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  auto cancelled = [&](const OptimizeResult& r) {
    original.restore(mesh);
    OptimizeResult res = r;
    res.sweeps = done;
    res.reason = StopReason::Cancelled;
    res.after = res.before;
    res.movedNodes = 0;
    res.flips = 0;
    res.rewiredElements.clear();
    res.seconds = seconds();
    return res;
  };

  OptimizeResult res;
  try {
    res = optimizeMesh(mesh, inner, staged, before);
    done += res.sweeps;
    if (res.reason == StopReason::Cancelled) return cancelled(res);
    std::vector<std::int32_t> rewired;
    std::vector<unsigned char> changed;  // the elements the last run could change (empty: all)
    for (int round = 0; round < kMaxFlipRounds; ++round) {
      // Valid after the first run, valid after every flip and run (never worse).
      const bool valid = res.after.tangled == 0 && res.after.across == 0;
      const FlipPass pass = flipEdges(mesh, measure, opt.fixedNodes, 16, changed, valid);
      if (pass.flips == 0) break;
      res.flips += pass.flips;
      rewired.insert(rewired.end(), pass.rewired.begin(), pass.rewired.end());
      // Smoothing around the rewired elements, on the elements it may change.
      OptimizeOptions local = inner;
      local.highOrderTargets.clear();  // (indexed by the whole mesh's elements)
      std::vector<std::int32_t> nodes, elements;
      SurfaceMesh sub = aroundRewired(mesh, pass.rewired, 2, opt.fixedNodes, &local.fixedNodes,
                                      &nodes, &elements);
      changed.assign(mesh.elementCount(), 0);
      for (std::int32_t e : elements) changed[static_cast<std::size_t>(e)] = 1;
      if (elements.empty()) continue;
      stageBase = stageTop + 1;
      stageTop = stageBase;
      const OptimizeResult r = optimizeMesh(sub, local, staged);
      if (r.reason != StopReason::Cancelled) writeBack(sub, nodes, elements, mesh);
      done += r.sweeps;
      if (r.reason == StopReason::Cancelled) return cancelled(res);
      res.patchUntanglings += r.patchUntanglings;
      res.straightenedElements += r.straightenedElements;
      res.restoredNodes += r.restoredNodes;
      res.heldAcross = res.heldAcross || r.heldAcross;
      if (r.reason == StopReason::MaxSweeps) res.reason = StopReason::MaxSweeps;
    }
    std::sort(rewired.begin(), rewired.end());
    rewired.erase(std::unique(rewired.begin(), rewired.end()), rewired.end());
    res.rewiredElements = std::move(rewired);
  } catch (...) {
    original.restore(mesh);
    throw;
  }
  if (res.flips > 0) {
    // The mesh changed: not "nothing to do" (every node fixed) any more.
    if (res.reason == StopReason::NothingToDo) res.reason = StopReason::Converged;
    const MeshQuality q = measureQuality(mesh, measure);
    res.after = q.stats;
    reportTangled(mesh, q, &res);
    res.finalObjective = 0.0;
    for (std::size_t e = 0; e < mesh.elementCount(); ++e)
      res.finalObjective +=
          q.tangled[e] ? 0.0 : 0.5 * (q.distortion[e] - 1.0) * (q.distortion[e] - 1.0);
  }
  res.movedNodes = 0;
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
    res.movedNodes += mesh.xyz[i] != original.positions.xyz[i] ? 1 : 0;
  res.needles = needleElements(mesh, measure);
  if (!res.needles.empty()) {
    std::string t;
    const std::size_t shown = std::min<std::size_t>(res.needles.size(), 20);
    for (std::size_t k = 0; k < shown; ++k) t += (k ? ", " : "") + std::to_string(res.needles[k]);
    if (shown < res.needles.size()) t += ", …";
    std::ostringstream os;
    os << res.needles.size() << " element(s) of quality below " << kNeedleQuality
       << " have every corner on one CAD edge (needles along it) that neither flips nor moves "
          "open: nodes would have to be inserted or removed there (elements "
       << t << ")";
    res.warnings.push_back(os.str());
  }
  res.sweeps = done;
  res.seconds = seconds();
  return res;
}

}  // namespace surfmesh
