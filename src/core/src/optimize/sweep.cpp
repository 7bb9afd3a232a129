#include "sweep.h"

#include "node_updater.h"
#include "tangled_report.h"

#include <chrono>
#include <type_traits>

namespace surfmesh {
namespace detail {

namespace {

/// Colors with fewer nodes are updated on the calling thread alone (see the sweep).
constexpr std::size_t kMinParallelNodes = 128;

struct GlobalEval {
  double objective = 0.0;         // ½ Σ (η − 1)² with the sweep's δ
  double objective0 = 0.0;        // the same with δ = 0 (+∞ while tangled)
  double movable0 = 0.0;          // objective0 without the elements no move can change
  double deficit = 0.0;           // Σ (1 − q) over the same elements, the tangled left out
  std::size_t tangled = 0;        // tangled elements with a movable node
  std::size_t frozenTangled = 0;  // tangled elements without one (no move can change them)
  double minSigma = kInf;
  // Smallest det S of the held elements (folded where no movable node acts, see foldHeld).
  double heldMinSigma = kInf;
  double minValidMovable = 1.0;  // lowest quality of the valid elements with a movable node
  // The progress reports' view, the quality report's: the triangles tangled only by the across
  // hold (counted in tangled or frozenTangled) are valid there, with the paper's quality.
  std::size_t leaning = 0;
  double minQuality = 1.0;  // over every element, 0 when one is tangled (but leaning)
};
}  // namespace

OptimizeResult optimizeOnce(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress, const QualityStats* before,
                            bool holdAcross, MeshPositions* previous) {
  const auto t0 = std::chrono::steady_clock::now();
  if (opt.maxSweeps < 0) throw std::invalid_argument("maxSweeps must be >= 0");
  if (!(opt.relTol >= 0.0) || !(opt.moveTol >= 0.0))
    throw std::invalid_argument("tolerances must be >= 0");
  if (opt.innerIterations < 1) throw std::invalid_argument("innerIterations must be >= 1");
  if (opt.maxLineSearch < 1) throw std::invalid_argument("maxLineSearch must be >= 1");
  if (!(opt.overRelaxation >= 1.0 && opt.overRelaxation < 2.0))
    throw std::invalid_argument("overRelaxation must be in [1, 2)");
  if (opt.deltaPolicy != "auto" && opt.deltaPolicy != "fixed")
    throw std::invalid_argument("deltaPolicy must be 'auto' or 'fixed', got '" + opt.deltaPolicy +
                                "'");
  if (!(opt.deltaEpsilon > 0.0) || !(opt.delta > 0.0))
    throw std::invalid_argument("delta and deltaEpsilon must be > 0");
  if (opt.threads < 0) throw std::invalid_argument("threads must be >= 0");
  const PlanarMeasure& measure = measureByName(opt.measure);
  mesh.validate();

  OptimizeResult res;
  res.before = before ? *before : measureQuality(mesh, measure).stats;

  auto state = std::make_unique<State>(mesh, measure, opt, holdAcross);
  State& s = *state;
  const std::size_t E = mesh.elementCount();
  const auto colors = colorNodes(mesh, s.inc);
  const int nthreads = std::max(1, std::min(resolveThreads(opt.threads), 64));
  res.threadsUsed = nthreads;
  std::vector<std::unique_ptr<Worker>> workers;
  for (int k = 0; k < nthreads; ++k) workers.push_back(std::make_unique<Worker>(s));
  Team team(nthreads);
  std::exception_ptr error;
  std::mutex errorMutex;

  std::size_t movable = 0;
  for (const auto& c : colors) movable += c.size();
  {
    // What the surfaces of the faces with Face nodes build on first use (a trimmed face's
    // grid), built here in parallel over the faces rather than by the first trial on each.
    std::vector<unsigned char> used(mesh.surfaces.size(), 0);
    for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
      if (mesh.nodeKind[i] == NodeKind::Face) used[static_cast<std::size_t>(mesh.nodeFace[i])] = 1;
    std::vector<std::size_t> faces;
    for (std::size_t f = 0; f < used.size(); ++f)
      if (used[f] && mesh.surfaces[f]) faces.push_back(f);
    const ThreadGeometry& geo0 = workers[0]->geo;
    parallelChunks(
        team, faces.size(), 1,
        [&](std::size_t a, std::size_t b) {
          for (std::size_t k = a; k < b; ++k) geo0.surfaces[faces[k]]->prepare();
        },
        error, errorMutex);
  }

  double epsilon = opt.deltaEpsilon;  // ε of the automatic policy, cycled on stalls
  int epsilonLevel = 0;
  auto chooseDelta = [&](const GlobalEval& g) {
    if (g.tangled == 0) return 0.0;
    if (opt.deltaPolicy == "fixed") return opt.delta;
    const double eps = epsilon;
    // The held elements still set δ while other elements are tangled: their nodes' moves are
    // measured with the same regularization as if they could be repaired (as before they were
    // held), only they no longer keep the untangling going.
    const double sm = std::min({g.minSigma, g.heldMinSigma, 0.0});
    return std::sqrt(eps * (eps - sm));
  };
  auto freezeScales = [&]() {
    parallelChunks(
        team, E, 8192,
        [&](std::size_t a, std::size_t b) {
          for (std::size_t e = a; e < b; ++e) s.elemSize[e] = std::sqrt(s.cornerScale(e));
        },
        error, errorMutex);
  };
  constexpr std::size_t kChunk = 4096;
  std::vector<double> chunkF((E + kChunk - 1) / kChunk);
  // Tangled count, minimum quality, f at δ = 0 and smallest det S from the element cache.
  // A tangled element without a movable node cannot change: it neither keeps the untangling
  // (δ > 0) sweeps going nor sets δ; it is counted apart.
  // Also set, during the run, for the elements whose untangling is given up (see giveUpSweeps).
  std::vector<unsigned char> frozen = frozenElements(mesh);
  std::vector<unsigned char> held(E, 0);  // frozen by foldHeld (below)
  auto cachedTangled = [&](std::size_t e) {
    return s.minSigma[e] <= 0.0 || !std::isfinite(s.eta0[e]);
  };
  auto summarize = [&](GlobalEval& g) {
    for (std::size_t e = 0; e < E; ++e) {
      const double et = s.eta0[e];
      const bool tangled = cachedTangled(e);
      // η at δ = 0 is finite for a valid element and for one tangled by the hold only (see
      // ElemOut::eta0), +∞ for the others.
      if (tangled && std::isfinite(et)) ++g.leaning;
      g.minQuality = std::min(g.minQuality, std::isfinite(et) ? 1.0 / et : 0.0);
      if (frozen[e] && tangled) {
        ++g.frozenTangled;
        if (held[e]) g.heldMinSigma = std::min(g.heldMinSigma, s.minSigma[e]);
        continue;
      }
      if (tangled) {
        ++g.tangled;
        g.objective0 = g.movable0 = kInf;
      } else {
        if (!frozen[e]) g.minValidMovable = std::min(g.minValidMovable, 1.0 / et);
        g.objective0 += 0.5 * (et - 1.0) * (et - 1.0);
        if (!frozen[e]) {
          g.movable0 += 0.5 * (et - 1.0) * (et - 1.0);
          g.deficit += 1.0 - 1.0 / et;
        }
      }
      g.minSigma = std::min(g.minSigma, s.minSigma[e]);
    }
  };
  // Every element at the current positions: fills the cache (η at δ = 0, det S) and sums.
  auto fullEval = [&](double deltaHat) {
    parallelChunks(
        team, E, kChunk,
        [&](std::size_t a, std::size_t b) {
          double f = 0.0;
          for (std::size_t e = a; e < b; ++e) {
            const ElemOut ev = s.evalWhole(e, deltaHat * s.deltaScale[e]);
            s.eta0[e] = ev.eta0;
            s.minSigma[e] = ev.tangled ? std::min(ev.minSigma, 0.0) : ev.minSigma;
            f += std::isfinite(ev.eta) ? 0.5 * (ev.eta - 1.0) * (ev.eta - 1.0) : kInf;
          }
          chunkF[a / kChunk] = f;
        },
        error, errorMutex);
    GlobalEval g;
    for (double f : chunkF) g.objective += f;
    summarize(g);
    return g;
  };
  // The same statistics from the cache (exact in δ = 0 sweeps, where every accepted move
  // refreshes its elements).
  auto cachedEval = [&]() {
    GlobalEval g;
    summarize(g);
    g.objective = g.objective0;
    return g;
  };

  freezeScales();
  {
    std::vector<double> nodeScale(mesh.nodeCount(), 0.0);
    for (std::size_t i = 0; i < mesh.nodeCount(); ++i) {
      const std::int64_t b = s.inc.offset[i], en = s.inc.offset[i + 1];
      for (std::int64_t p = b; p < en; ++p)
        nodeScale[i] +=
            s.cornerScale(static_cast<std::size_t>(s.inc.elem[static_cast<std::size_t>(p)]));
      if (en > b) nodeScale[i] /= static_cast<double>(en - b);
    }
    s.deltaScale.assign(E, 0.0);
    for (std::size_t e = 0; e < E; ++e) {
      const int nc = cornerCount(mesh.elemType[e]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < nc; ++k) s.deltaScale[e] += nodeScale[static_cast<std::size_t>(nd[k])];
      s.deltaScale[e] /= nc;
    }
  }
  // Tangled high-order triangles with valid corners: straight sides in (u,v) first.
  if (!s.allTri3 && movable > 0 && opt.maxSweeps > 0)
    NodeUpdater(s, *workers[0]).straightenHighOrder(frozen, false);
  // Elements folded where no movable node acts are held like those without a movable node:
  // they do not keep the untangling (δ > 0) going, which would only spend the run on them
  // until it gives up. While other elements are tangled, they still set δ and take part in
  // the escapes, as before they were held: the run is the same until no other element is
  // tangled, then it smooths with δ = 0 at once.
  // (A linear triangle with a movable node is never held: all-Tri3 meshes skip the pass.)
  for (std::size_t e = 0; !s.allTri3 && e < E; ++e)
    if (!frozen[e] && foldHeld(mesh, s.xyz, e, s.elementNormal(e, -1, Vec3::Zero(), Vec3::Zero())))
      frozen[e] = held[e] = 1;
  // What the escapes leave alone: the frozen elements but the held ones. A held element cannot
  // be untangled, but while others are tangled the joint moves of the nodes around it may
  // untangle a neighbour (kept only then), as before it was held.
  std::vector<unsigned char> noEscape(E, 0);
  for (std::size_t e = 0; e < E; ++e) noEscape[e] = frozen[e] && !held[e];
  GlobalEval g = fullEval(0.0);
  s.deltaHat = chooseDelta(g);
  res.initialObjective = s.deltaHat > 0.0 ? fullEval(s.deltaHat).objective : g.objective0;
  res.reason = StopReason::MaxSweeps;
  if (movable == 0 || opt.maxSweeps == 0) res.reason = StopReason::NothingToDo;

  double prevDelta = -1.0;
  std::size_t bestTangled = g.tangled;
  int stalled = 0, zeroMoves = 0, stuckSweeps = 0;
  // Untangling gives up after this many sweeps without fewer tangled elements than ever
  // before: two full cycles of ε (see below), every escape tried with each ε twice. (Over the
  // 198 runs of the perturbation grid on three parts, and the test suite, the longest wait for
  // a new best before reaching 0 tangled was 17 sweeps.)
  const int giveUpSweeps = 6 * std::max(1, opt.deltaStallSweeps);
  std::size_t fewestTangled = g.tangled;
  int lastProgress = 0;
  for (int sweep = 1; movable > 0 && sweep <= opt.maxSweeps; ++sweep) {
    freezeScales();
    s.deltaHat = chooseDelta(g);
    s.trackCache = s.deltaHat == 0.0;
    // Untangling sweeps keep every valid submesh's minimum (the relaxed bar would let the
    // valid elements around a fold give way to moves that only lower f̂).
    s.qualityFloor = s.deltaHat > 0.0 ? kInf : g.minValidMovable;
    // While δ > 0 it (and the scaled δ of every element) changes from sweep to sweep: every
    // node is revisited. In δ = 0 sweeps a node is revisited only when it or a neighbour
    // moved by more than moveTol × its local size since its last update.
    if (s.deltaHat > 0.0 || s.deltaHat != prevDelta) s.validFrom = s.clock + 1;
    prevDelta = s.deltaHat;
    // The stopping rule's f leaves out the elements no move can change: a poor element between
    // fixed nodes would otherwise dwarf the decrease over the rest of the mesh.
    const double fStartMovable = g.movable0;
    const double deficitStart = g.deficit;
    for (auto& w : workers) {
      w->maxRelMove = 0.0;
      w->updated = w->moved = 0;
    }
    for (const auto& color : colors) {
      ++s.clock;
      const std::int32_t clock = s.clock;
      const std::size_t n = color.size();
      std::atomic<std::size_t> next{0};
      const std::size_t chunk = std::max<std::size_t>(16, n / (16 * nthreads) + 1);
      auto job = [&](int tid) {
        try {
          Worker& w = *workers[static_cast<std::size_t>(tid)];
          NodeUpdater up(s, w);
          for (;;) {
            const std::size_t a = next.fetch_add(chunk, std::memory_order_relaxed);
            if (a >= n) break;
            const std::size_t b = std::min(n, a + chunk);
            for (std::size_t k = a; k < b; ++k) {
              const std::size_t i = static_cast<std::size_t>(color[k]);
              const std::int32_t last = s.lastVisit[i];
              bool active = last < s.validFrom || s.movedAt[i] == last;
              for (std::int64_t p = s.begin(i); !active && p < s.end(i); ++p) {
                const std::size_t e =
                    static_cast<std::size_t>(s.inc.elem[static_cast<std::size_t>(p)]);
                const std::int32_t* nd = mesh.elementNodes(e);
                for (int q = 0; q < mesh.elementSize(e); ++q)
                  if (s.movedAt[static_cast<std::size_t>(nd[q])] > last) active = true;
              }
              if (!active) continue;
              ++w.updated;
              s.lastVisit[i] = clock;
              const double mv = up.update(i);
              if (mv > 0.0) {
                ++w.moved;
                const double L = s.localSize(i);
                const double rel = L > 0.0 ? mv / L : kInf;
                w.maxRelMove = std::max(w.maxRelMove, rel);
                if (rel > opt.moveTol) s.movedAt[i] = clock;
              }
            }
          }
        } catch (...) {
          std::lock_guard<std::mutex> lock(errorMutex);
          if (!error) error = std::current_exception();
        }
      };
      // A small color runs on the calling thread: waking a sleeping worker costs more than
      // its nodes (the result is the same: the nodes of a color share no element).
      if (n < kMinParallelNodes)
        job(0);
      else
        team.run(job);
      if (error) std::rethrow_exception(error);
    }
    double maxMove = 0.0;
    std::size_t moved = 0;
    for (const auto& w : workers) {
      maxMove = std::max(maxMove, w->maxRelMove);
      moved += w->moved;
    }
    res.sweeps = sweep;
    g = s.deltaHat > 0.0 ? fullEval(s.deltaHat) : cachedEval();
    // Sweeps in a row that left more tangled elements than the best so far.
    stuckSweeps = (g.tangled > 0 && g.tangled >= bestTangled) ? stuckSweeps + 1 : 0;
    if (stuckSweeps > 0) {
      NodeUpdater up(s, *workers[0]);
      std::size_t gained = s.allTri3 ? 0 : up.straightenHighOrder(noEscape, true);
      gained += up.escapeTangledElements(noEscape, stuckSweeps >= 3, sweep, epsilonLevel, frozen);
      if (gained > 0) g = fullEval(s.deltaHat);  // stuck elements untangled by joint moves
    }
    // The report comes after the escapes: it describes the mesh as the sweep leaves it (the
    // mesh a run stopped here returns).
    const double fEnd = s.deltaHat > 0.0 ? g.objective : g.objective0;
    res.finalObjective = fEnd;
    if (progress) {
      OptimizeProgress pr;
      pr.sweep = sweep;
      pr.maxSweeps = opt.maxSweeps;
      pr.objective = fEnd;
      pr.tangled = g.tangled + g.frozenTangled - g.leaning;
      pr.minQuality = g.minQuality;
      pr.delta = s.deltaHat;
      if (!progress(pr)) {
        res.reason = StopReason::Cancelled;
        res.after = res.before;
        res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return res;  // the mesh was never touched
      }
    }
    if (g.tangled < fewestTangled) {
      fewestTangled = g.tangled;
      lastProgress = sweep;
    }
    if (g.tangled > 0 && sweep - lastProgress >= giveUpSweeps) {
      // No progress for giveUpSweeps sweeps: the elements still tangled are held like those
      // without a movable node (their nodes stay where they are, they no longer keep δ > 0;
      // reported in tangledMovable) and the rest of the mesh is smoothed with δ = 0. The cache
      // is current (δ > 0 sweeps end with a full evaluation).
      for (std::size_t e = 0; e < E; ++e)
        if (!frozen[e] && cachedTangled(e)) frozen[e] = noEscape[e] = 1;
      g = cachedEval();
      continue;
    }
    if (g.tangled > 0 && opt.deltaPolicy == "auto") {
      // Untangling stalls: cycle ε through ε, ε/3, ε/9 (see OptimizeOptions::deltaEpsilon).
      if (g.tangled < bestTangled) {
        bestTangled = g.tangled;
        stalled = 0;
      } else {
        ++stalled;
      }
      zeroMoves = moved == 0 ? zeroMoves + 1 : 0;
      if (stalled >= std::max(1, opt.deltaStallSweeps) || moved == 0) {
        epsilonLevel = (epsilonLevel + 1) % 3;
        static const double kFactors[3] = {1.0, 1.0 / 3.0, 1.0 / 9.0};
        epsilon = opt.deltaEpsilon * kFactors[epsilonLevel];
        stalled = 0;
      }
      if (zeroMoves >= 3) {
        // No node moved with any of the three ε: a fixed point.
        res.reason = StopReason::Converged;
        break;
      }
      continue;
    }
    if (moved == 0 && (g.tangled == 0 || chooseDelta(g) == s.deltaHat)) {
      // Nothing moved and the next sweep would repeat this one: a fixed point.
      res.reason = StopReason::Converged;
      break;
    }
    if (g.tangled == 0 && s.deltaHat == 0.0) {
      auto decreaseBelowTol = [&](double start, double end) {
        return !(start > 0.0) || (start - end) <= opt.relTol * std::max(start, 1e-300);
      };
      const bool decreaseSmall =
          decreaseBelowTol(fStartMovable, g.movable0) && decreaseBelowTol(deficitStart, g.deficit);
      if (decreaseSmall || maxMove <= opt.moveTol) {
        res.reason = StopReason::Converged;
        break;
      }
    }
  }

  // Write back: positions, parameters, and the element corners' (u,v) of the nodes that moved
  // (unwrapped next to their previous value, across periodic seams). Built in copies and
  // swapped in, so that an exception here or while measuring the result leaves the mesh
  // exactly as it was (as on cancellation).
  // What the write-back does not need goes first (it lowers the run's peak memory).
  auto release = [](auto& v) { std::decay_t<decltype(v)>().swap(v); };
  release(s.d2);
  release(s.nodeNormal);
  release(s.fixedNormal);
  release(s.elemSize);
  release(s.deltaScale);
  release(s.eta0);
  release(s.minSigma);
  const ThreadGeometry& geo = workers[0]->geo;
  std::vector<Vec2> cornerUV = mesh.cornerUV;
  std::size_t moved = 0;
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i) {
    if (s.xyz[i] == mesh.xyz[i]) continue;
    ++moved;
    const NodeKind kind = mesh.nodeKind[i];
    for (std::int64_t p = s.begin(i); p < s.end(i); ++p) {
      const std::size_t pp = static_cast<std::size_t>(p);
      const std::size_t e = static_cast<std::size_t>(s.inc.elem[pp]);
      const std::size_t slot = static_cast<std::size_t>(mesh.elemOffset[e]) + s.inc.local[pp];
      const int f = mesh.elemFace[e];
      const Surface& sf = *geo.surfaces[static_cast<std::size_t>(f)];
      if (kind == NodeKind::Face) {
        cornerUV[slot] = sf.unwrapNear(s.uv[i], cornerUV[slot]);
      } else if (kind == NodeKind::Edge) {
        const Curve& c = *geo.curves[static_cast<std::size_t>(mesh.nodeEdge[i])];
        cornerUV[slot] = sf.unwrapNear(c.uvOnFace(f, s.t[i], cornerUV[slot]), cornerUV[slot]);
      }
    }
  }
  res.movedNodes = moved;
  res.patchUntanglings = s.patchUntanglings;
  for (const auto& w : workers) res.heldAcross = res.heldAcross || w->heldAcross;
  res.straightenedElements = s.straightened;
  std::vector<Vec3> xyz = std::move(s.xyz);
  std::vector<Vec2> uv = std::move(s.uv);
  std::vector<double> t = std::move(s.t);
  workers.clear();
  state.reset();
  auto exchange = [&]() {
    std::swap(mesh.xyz, xyz);
    std::swap(mesh.uv, uv);
    if (!mesh.nodeT.empty()) std::swap(mesh.nodeT, t);
    std::swap(mesh.cornerUV, cornerUV);
  };
  exchange();
  try {
    const MeshQuality q = measureQuality(mesh, measure);
    res.after = q.stats;
    reportTangled(mesh, q, &res);
  } catch (...) {
    exchange();  // back to the input
    throw;
  }
  if (previous) {
    previous->xyz = std::move(xyz);
    previous->uv = std::move(uv);
    if (!mesh.nodeT.empty()) previous->nodeT = std::move(t);
    previous->cornerUV = std::move(cornerUV);
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace detail
}  // namespace surfmesh
