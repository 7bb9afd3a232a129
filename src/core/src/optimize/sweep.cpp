#include "sweep.h"

#include "keep_valid.h"
#include "node_updater.h"
#include "sweep_policy.h"
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

/// The options a run refuses, with what is wrong.
void checkOptions(const OptimizeOptions& opt) {
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
}

/// One run (optimizeOnce): the State, the workers and their team, the element flags and the
/// whole-mesh evaluations; run() sweeps and writes the result back.
class SweepRun {
 public:
  /// `grade0`: how invalid each element of the input is (MeshQuality::grade: valid, standing
  /// across, tangled; keepValidElements).
  SweepRun(SurfaceMesh& mesh, const OptimizeOptions& opt, const ProgressCallback& progress,
           const PlanarMeasure& measure, HoldAcross holdAcross, std::vector<unsigned char> grade0)
      : mesh_(mesh),
        opt_(opt),
        progress_(progress),
        measure_(measure),
        state_(std::make_unique<State>(mesh, measure, opt, holdAcross)),
        s_(*state_),
        E_(mesh.elementCount()),
        colors_(colorNodes(mesh, s_.inc)),
        nthreads_(std::max(1, std::min(resolveThreads(opt.threads), 64))),
        team_(nthreads_),
        chunkF_((E_ + kChunk - 1) / kChunk),
        frozen_(frozenElements(mesh)),
        held_(E_, 0),
        grade0_(std::move(grade0)) {
    for (int k = 0; k < nthreads_; ++k) workers_.push_back(std::make_unique<Worker>(s_));
    for (const auto& c : colors_) movable_ += c.size();
  }

  /// The sweeps, then the write-back (see optimizeOnce). `res` holds `before` on entry.
  OptimizeResult run(OptimizeResult res, MeshPositions* previous,
                     std::chrono::steady_clock::time_point t0);

 private:
  static constexpr std::size_t kChunk = 4096;

  void prepareSurfaces();
  void freezeScales();
  void setDeltaScales();
  void holdFolds();
  bool cachedTangled(std::size_t e) const {
    return s_.minSigma[e] <= 0.0 || !std::isfinite(s_.eta0[e]);
  }
  void summarize(GlobalEval& g) const;
  GlobalEval fullEval(double deltaHat);
  GlobalEval cachedEval() const;
  double deltaFor(const DeltaPolicy& policy, const GlobalEval& g) const {
    return policy.delta(g.tangled, std::min(g.minSigma, g.heldMinSigma));
  }
  void sweepColors();
  void sweepColor(const std::vector<std::int32_t>& color);
  std::size_t escape(int stuckSweeps, int sweep, int epsilonLevel);
  bool report(int sweep, const GlobalEval& g, OptimizeResult* res) const;
  void giveUp();
  void writeBack(OptimizeResult* res, MeshPositions* previous);

  SurfaceMesh& mesh_;
  const OptimizeOptions& opt_;
  const ProgressCallback& progress_;
  const PlanarMeasure& measure_;
  std::unique_ptr<State> state_;
  State& s_;
  const std::size_t E_;
  const std::vector<std::vector<std::int32_t>> colors_;
  const int nthreads_;
  std::vector<std::unique_ptr<Worker>> workers_;
  Team team_;
  std::exception_ptr error_;
  std::mutex errorMutex_;
  std::size_t movable_ = 0;     // movable nodes
  std::vector<double> chunkF_;  // fullEval's per-chunk sums
  // Tangled count, minimum quality, f at δ = 0 and smallest det S from the element cache.
  // A tangled element without a movable node cannot change: it neither keeps the untangling
  // (δ > 0) sweeps going nor sets δ; it is counted apart.
  // Also set, during the run, for the elements whose untangling is given up (see StopRule).
  std::vector<unsigned char> frozen_;
  std::vector<unsigned char> held_;      // frozen by foldHeld (holdFolds)
  std::vector<unsigned char> noEscape_;  // what the escapes leave alone (holdFolds)
  std::vector<unsigned char> grade0_;    // the input's MeshQuality::grade per element
  // The last sweep's largest relative move and number of nodes moved.
  double maxMove_ = 0.0;
  std::size_t moved_ = 0;
};

/// What the surfaces of the faces with Face nodes build on first use (a trimmed face's grid),
/// built here in parallel over the faces rather than by the first trial on each.
void SweepRun::prepareSurfaces() {
  std::vector<unsigned char> used(mesh_.surfaces.size(), 0);
  for (std::size_t i = 0; i < mesh_.nodeCount(); ++i)
    if (mesh_.nodeKind[i] == NodeKind::Face) used[static_cast<std::size_t>(mesh_.nodeFace[i])] = 1;
  std::vector<std::size_t> faces;
  for (std::size_t f = 0; f < used.size(); ++f)
    if (used[f] && mesh_.surfaces[f]) faces.push_back(f);
  const ThreadGeometry& geo0 = workers_[0]->geo;
  parallelChunks(
      team_, faces.size(), 1,
      [&](std::size_t a, std::size_t b) {
        for (std::size_t k = a; k < b; ++k) geo0.surfaces[faces[k]]->prepare();
      },
      error_, errorMutex_);
}

void SweepRun::freezeScales() {
  parallelChunks(
      team_, E_, 8192,
      [&](std::size_t a, std::size_t b) {
        for (std::size_t e = a; e < b; ++e) s_.elemSize[e] = std::sqrt(s_.cornerScale(e));
      },
      error_, errorMutex_);
}

/// State::deltaScale: the corner scales averaged over the elements around each corner.
void SweepRun::setDeltaScales() {
  std::vector<double> nodeScale(mesh_.nodeCount(), 0.0);
  for (std::size_t i = 0; i < mesh_.nodeCount(); ++i) {
    const std::int64_t b = s_.inc.offset[i], en = s_.inc.offset[i + 1];
    for (std::int64_t p = b; p < en; ++p)
      nodeScale[i] +=
          s_.cornerScale(static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]));
    if (en > b) nodeScale[i] /= static_cast<double>(en - b);
  }
  s_.deltaScale.assign(E_, 0.0);
  for (std::size_t e = 0; e < E_; ++e) {
    const int nc = cornerCount(mesh_.elemType[e]);
    const std::int32_t* nd = mesh_.elementNodes(e);
    for (int k = 0; k < nc; ++k) s_.deltaScale[e] += nodeScale[static_cast<std::size_t>(nd[k])];
    s_.deltaScale[e] /= nc;
  }
}

/// Elements folded where no movable node acts are held like those without a movable node:
/// they do not keep the untangling (δ > 0) going, which would only spend the run on them
/// until it gives up. While other elements are tangled, they still set δ and take part in
/// the escapes, as before they were held: the run is the same until no other element is
/// tangled, then it smooths with δ = 0 at once.
/// (A linear triangle with a movable node is never held: all-Tri3 meshes skip the pass.)
void SweepRun::holdFolds() {
  for (std::size_t e = 0; !s_.allTri3 && e < E_; ++e)
    if (!frozen_[e] &&
        foldHeld(mesh_, s_.xyz, e, s_.elementNormal(e, -1, Vec3::Zero(), Vec3::Zero())))
      frozen_[e] = held_[e] = 1;
  // What the escapes leave alone: the frozen elements but the held ones. A held element cannot
  // be untangled, but while others are tangled the joint moves of the nodes around it may
  // untangle a neighbour (kept only then), as before it was held.
  noEscape_.assign(E_, 0);
  for (std::size_t e = 0; e < E_; ++e) noEscape_[e] = frozen_[e] && !held_[e];
}

void SweepRun::summarize(GlobalEval& g) const {
  for (std::size_t e = 0; e < E_; ++e) {
    const double et = s_.eta0[e];
    const bool tangled = cachedTangled(e);
    // η at δ = 0 is finite for a valid element and for one tangled by the hold only (see
    // ElemOut::eta0), +∞ for the others.
    if (tangled && std::isfinite(et)) ++g.leaning;
    g.minQuality = std::min(g.minQuality, std::isfinite(et) ? 1.0 / et : 0.0);
    if (frozen_[e] && tangled) {
      ++g.frozenTangled;
      if (held_[e]) g.heldMinSigma = std::min(g.heldMinSigma, s_.minSigma[e]);
      continue;
    }
    if (tangled) {
      ++g.tangled;
      g.objective0 = g.movable0 = kInf;
    } else {
      if (!frozen_[e]) g.minValidMovable = std::min(g.minValidMovable, 1.0 / et);
      g.objective0 += 0.5 * (et - 1.0) * (et - 1.0);
      if (!frozen_[e]) {
        g.movable0 += 0.5 * (et - 1.0) * (et - 1.0);
        g.deficit += 1.0 - 1.0 / et;
      }
    }
    g.minSigma = std::min(g.minSigma, s_.minSigma[e]);
  }
}

/// Every element at the current positions: fills the cache (η at δ = 0, det S) and sums.
GlobalEval SweepRun::fullEval(double deltaHat) {
  parallelChunks(
      team_, E_, kChunk,
      [&](std::size_t a, std::size_t b) {
        double f = 0.0;
        for (std::size_t e = a; e < b; ++e) {
          const ElemOut ev = s_.evalWhole(e, deltaHat * s_.deltaScale[e]);
          s_.eta0[e] = ev.eta0;
          s_.minSigma[e] = ev.tangled ? std::min(ev.minSigma, 0.0) : ev.minSigma;
          f += std::isfinite(ev.eta) ? 0.5 * (ev.eta - 1.0) * (ev.eta - 1.0) : kInf;
        }
        chunkF_[a / kChunk] = f;
      },
      error_, errorMutex_);
  GlobalEval g;
  for (double f : chunkF_) g.objective += f;
  summarize(g);
  return g;
}

/// The same statistics from the cache (exact in δ = 0 sweeps, where every accepted move
/// refreshes its elements).
GlobalEval SweepRun::cachedEval() const {
  GlobalEval g;
  summarize(g);
  g.objective = g.objective0;
  return g;
}

/// One Gauss–Seidel sweep over the colours; sets maxMove_ and moved_.
void SweepRun::sweepColors() {
  for (auto& w : workers_) {
    w->maxRelMove = 0.0;
    w->updated = w->moved = 0;
  }
  for (const auto& color : colors_) sweepColor(color);
  maxMove_ = 0.0;
  moved_ = 0;
  for (const auto& w : workers_) {
    maxMove_ = std::max(maxMove_, w->maxRelMove);
    moved_ += w->moved;
  }
}

/// The nodes of one colour (they share no element), in chunks taken by the team. A node is
/// updated when the sweep revisits every node (State::validFrom), or it or a neighbour moved
/// since its last update.
void SweepRun::sweepColor(const std::vector<std::int32_t>& color) {
  ++s_.clock;
  const std::int32_t clock = s_.clock;
  const std::size_t n = color.size();
  std::atomic<std::size_t> next{0};
  const std::size_t chunk = std::max<std::size_t>(16, n / (16 * nthreads_) + 1);
  auto job = [&](int tid) {
    try {
      Worker& w = *workers_[static_cast<std::size_t>(tid)];
      NodeUpdater up(s_, w);
      for (;;) {
        const std::size_t a = next.fetch_add(chunk, std::memory_order_relaxed);
        if (a >= n) break;
        const std::size_t b = std::min(n, a + chunk);
        for (std::size_t k = a; k < b; ++k) {
          const std::size_t i = static_cast<std::size_t>(color[k]);
          const std::int32_t last = s_.lastVisit[i];
          bool active = last < s_.validFrom || s_.movedAt[i] == last;
          for (std::int64_t p = s_.begin(i); !active && p < s_.end(i); ++p) {
            const std::size_t e =
                static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
            const std::int32_t* nd = mesh_.elementNodes(e);
            for (int q = 0; q < mesh_.elementSize(e); ++q)
              if (s_.movedAt[static_cast<std::size_t>(nd[q])] > last) active = true;
          }
          if (!active) continue;
          ++w.updated;
          s_.lastVisit[i] = clock;
          const double mv = up.update(i);
          if (mv > 0.0) {
            ++w.moved;
            const double L = s_.localSize(i);
            const double rel = L > 0.0 ? mv / L : kInf;
            w.maxRelMove = std::max(w.maxRelMove, rel);
            if (rel > opt_.moveTol) s_.movedAt[i] = clock;
          }
        }
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(errorMutex_);
      if (!error_) error_ = std::current_exception();
    }
  };
  // A small color runs on the calling thread: waking a sleeping worker costs more than
  // its nodes (the result is the same: the nodes of a color share no element).
  if (n < kMinParallelNodes)
    job(0);
  else
    team_.run(job);
  if (error_) std::rethrow_exception(error_);
}

/// The escapes after `stuckSweeps` sweeps in a row without fewer tangled elements (see
/// NodeUpdater::escapeTangledElements); returns the elements they untangled.
std::size_t SweepRun::escape(int stuckSweeps, int sweep, int epsilonLevel) {
  NodeUpdater up(s_, *workers_[0]);
  std::size_t gained = s_.allTri3 || !(opt_.escapes & kEscapeStraighten)
                           ? 0
                           : up.straightenHighOrder(noEscape_, true);
  gained += up.escapeTangledElements(noEscape_, stuckSweeps >= 3, sweep, epsilonLevel, frozen_);
  return gained;
}

/// The progress record of sweep `sweep` (whose end `g` describes); false when the caller
/// cancels.
bool SweepRun::report(int sweep, const GlobalEval& g, OptimizeResult* res) const {
  // The report comes after the escapes: it describes the mesh as the sweep leaves it (the
  // mesh a run stopped here returns).
  const double fEnd = s_.mode.deltaHat > 0.0 ? g.objective : g.objective0;
  res->finalObjective = fEnd;
  if (!progress_) return true;
  OptimizeProgress pr;
  pr.sweep = sweep;
  pr.maxSweeps = opt_.maxSweeps;
  pr.objective = fEnd;
  pr.tangled = g.tangled + g.frozenTangled - g.leaning;
  pr.minQuality = g.minQuality;
  pr.delta = s_.mode.deltaHat;
  return progress_(pr);
}

/// No progress for StopRule::giveUpSweeps sweeps: the elements still tangled are held like
/// those without a movable node (their nodes stay where they are, they no longer keep δ > 0;
/// reported in tangledMovable) and the rest of the mesh is smoothed with δ = 0. The cache is
/// current (δ > 0 sweeps end with a full evaluation).
void SweepRun::giveUp() {
  for (std::size_t e = 0; e < E_; ++e)
    if (!frozen_[e] && cachedTangled(e)) frozen_[e] = noEscape_[e] = 1;
}

OptimizeResult SweepRun::run(OptimizeResult res, MeshPositions* previous,
                             std::chrono::steady_clock::time_point t0) {
  res.threadsUsed = nthreads_;
  prepareSurfaces();
  freezeScales();
  setDeltaScales();
  // Tangled high-order triangles with valid corners: straight sides in (u,v) first.
  if (!s_.allTri3 && movable_ > 0 && opt_.maxSweeps > 0 && (opt_.escapes & kEscapeStraighten))
    NodeUpdater(s_, *workers_[0]).straightenHighOrder(frozen_, false);
  holdFolds();
  GlobalEval g = fullEval(0.0);
  DeltaPolicy policy(opt_, g.tangled);
  StopRule stop(opt_, g.tangled);
  s_.mode.deltaHat = deltaFor(policy, g);
  res.initialObjective =
      s_.mode.deltaHat > 0.0 ? fullEval(s_.mode.deltaHat).objective : g.objective0;
  res.reason = StopReason::MaxSweeps;
  if (movable_ == 0 || opt_.maxSweeps == 0) res.reason = StopReason::NothingToDo;

  double prevDelta = -1.0;
  int stuckSweeps = 0;
  for (int sweep = 1; movable_ > 0 && sweep <= opt_.maxSweeps; ++sweep) {
    freezeScales();
    s_.mode.deltaHat = deltaFor(policy, g);
    s_.mode.trackCache = s_.mode.deltaHat == 0.0;
    // Untangling sweeps keep every valid submesh's minimum (the relaxed bar would let the
    // valid elements around a fold give way to moves that only lower f̂).
    s_.mode.qualityFloor = s_.mode.deltaHat > 0.0 ? kInf : g.minValidMovable;
    // While δ > 0 it (and the scaled δ of every element) changes from sweep to sweep: every
    // node is revisited. In δ = 0 sweeps a node is revisited only when it or a neighbour
    // moved by more than moveTol × its local size since its last update.
    if (s_.mode.deltaHat > 0.0 || s_.mode.deltaHat != prevDelta) s_.validFrom = s_.clock + 1;
    prevDelta = s_.mode.deltaHat;
    // The stopping rule's f leaves out the elements no move can change: a poor element between
    // fixed nodes would otherwise dwarf the decrease over the rest of the mesh.
    const double fStartMovable = g.movable0;
    const double deficitStart = g.deficit;
    sweepColors();
    res.sweeps = sweep;
    g = s_.mode.deltaHat > 0.0 ? fullEval(s_.mode.deltaHat) : cachedEval();
    // Sweeps in a row that left more tangled elements than the best so far.
    stuckSweeps = (g.tangled > 0 && g.tangled >= policy.bestTangled()) ? stuckSweeps + 1 : 0;
    if (stuckSweeps > 0 && escape(stuckSweeps, sweep, policy.epsilonLevel()) > 0)
      g = fullEval(s_.mode.deltaHat);  // stuck elements untangled by joint moves
    if (!report(sweep, g, &res)) {
      res.reason = StopReason::Cancelled;
      res.after = res.before;
      res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return res;  // the mesh was never touched
    }
    if (stop.givesUp(sweep, g.tangled)) {
      giveUp();
      g = cachedEval();
      continue;
    }
    if (g.tangled > 0 && policy.automatic()) {
      // Untangling stalls: cycle ε through ε, ε/3, ε/9 (see OptimizeOptions::deltaEpsilon).
      if (policy.afterUntanglingSweep(g.tangled, moved_)) {
        // No node moved with any of the three ε: a fixed point.
        res.reason = StopReason::Converged;
        break;
      }
      continue;
    }
    if (moved_ == 0 && (g.tangled == 0 || deltaFor(policy, g) == s_.mode.deltaHat)) {
      // Nothing moved and the next sweep would repeat this one: a fixed point.
      res.reason = StopReason::Converged;
      break;
    }
    if (g.tangled == 0 && s_.mode.deltaHat == 0.0 &&
        stop.smoothed(fStartMovable, g.movable0, deficitStart, g.deficit, maxMove_)) {
      res.reason = StopReason::Converged;
      break;
    }
  }
  writeBack(&res, previous);
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

/// Write back: positions, parameters, and the element corners' (u,v) of the nodes that moved
/// (unwrapped next to their previous value, across periodic seams). Built in copies and
/// swapped in, so that an exception here or while measuring the result leaves the mesh exactly
/// as it was (as on cancellation). Ends the State and the workers.
void SweepRun::writeBack(OptimizeResult* res, MeshPositions* previous) {
  const double lastDelta = s_.mode.deltaHat;
  // What the write-back does not need goes first (it lowers the run's peak memory).
  auto release = [](auto& v) { std::decay_t<decltype(v)>().swap(v); };
  release(s_.d2);
  release(s_.nodeNormal);
  release(s_.fixedNormal);
  release(s_.elemSize);
  release(s_.deltaScale);
  release(s_.eta0);
  release(s_.minSigma);
  const ThreadGeometry& geo = workers_[0]->geo;
  std::vector<Vec2> cornerUV = mesh_.cornerUV;
  std::size_t moved = 0;
  for (std::size_t i = 0; i < mesh_.nodeCount(); ++i) {
    if (s_.xyz[i] == mesh_.xyz[i]) continue;
    ++moved;
    const NodeKind kind = mesh_.nodeKind[i];
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t pp = static_cast<std::size_t>(p);
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
      const std::size_t slot = static_cast<std::size_t>(mesh_.elemOffset[e]) + s_.inc.local[pp];
      const int f = mesh_.elemFace[e];
      const Surface& sf = *geo.surfaces[static_cast<std::size_t>(f)];
      if (kind == NodeKind::Face) {
        cornerUV[slot] = sf.unwrapNear(s_.uv[i], cornerUV[slot]);
      } else if (kind == NodeKind::Edge) {
        const Curve& c = *geo.curves[static_cast<std::size_t>(mesh_.nodeEdge[i])];
        cornerUV[slot] = sf.unwrapNear(c.uvOnFace(f, s_.t[i], cornerUV[slot]), cornerUV[slot]);
      }
    }
  }
  res->movedNodes = moved;
  res->patchUntanglings = s_.patchUntanglings;
  for (const auto& w : workers_) res->heldAcross = res->heldAcross || w->heldAcross;
  res->straightenedElements = s_.straightened;
  std::vector<Vec3> xyz = std::move(s_.xyz);
  std::vector<Vec2> uv = std::move(s_.uv);
  std::vector<double> t = std::move(s_.t);
  workers_.clear();
  state_.reset();
  auto exchange = [&]() {
    std::swap(mesh_.xyz, xyz);
    std::swap(mesh_.uv, uv);
    if (!mesh_.nodeT.empty()) std::swap(mesh_.nodeT, t);
    std::swap(mesh_.cornerUV, cornerUV);
  };
  exchange();
  bool cancelled = false, revertAll = false;
  try {
    MeshQuality q = measureQuality(mesh_, measure_);
    // Never worse, element by element: the nodes of the elements valid in the input (neither
    // tangled nor standing across) that the run left invalid go back, and those of the
    // elements standing across in the input that it left tangled. On a valid input that
    // is always kept; on an invalid one, unless it leaves more invalid elements than the run
    // did (untangling may trade a valid element for invalid ones the run could not repair
    // otherwise).
    const std::size_t invalidRun = invalidCount(q);
    PutBack undo;
    const std::size_t restored = keepValidElements(mesh_, InputPositions{xyz, uv, t, cornerUV},
                                                   grade0_, measure_, &q, &undo);
    const bool validInput = std::find_if(grade0_.begin(), grade0_.end(),
                                         [](unsigned char g) { return g != 0; }) == grade0_.end();
    if (restored > 0 && validInput && opt_.monotone && q.stats.min < res->before.min) {
      // (The elements around the nodes put back are valid but poorer than the input's worst:
      // the input, never worse.)
      revertAll = true;
    } else if (restored > 0 && invalidCount(q) <= invalidRun) {
      res->restoredNodes = restored;
      res->movedNodes -= restored;
    } else if (restored > 0) {
      undo.undo(mesh_);
      q = measureQuality(mesh_, measure_);
    }
    res->after = q.stats;
    reportTangled(mesh_, q, res);
    if ((res->restoredNodes > 0 || revertAll) && progress_) {
      // The last progress record describes the mesh the run returns; like every record, it
      // may cancel the run (the input back).
      OptimizeProgress pr;
      pr.sweep = res->sweeps;
      pr.maxSweeps = opt_.maxSweeps;
      pr.objective = res->finalObjective;
      const QualityStats& shown = revertAll ? res->before : q.stats;
      pr.tangled = shown.tangled;
      pr.minQuality = shown.min;
      pr.delta = lastDelta;
      cancelled = !progress_(pr);
    }
  } catch (...) {
    exchange();  // back to the input
    throw;
  }
  if (revertAll || cancelled) {
    exchange();  // back to the input
    if (cancelled) res->reason = StopReason::Cancelled;
    res->restoredNodes = cancelled ? 0 : res->movedNodes;
    res->movedNodes = 0;
    res->after = res->before;
    res->tangledUnmovable.clear();
    res->tangledMovable.clear();
    res->warnings.clear();
    return;
  }
  if (previous) {
    previous->xyz = std::move(xyz);
    previous->uv = std::move(uv);
    if (!mesh_.nodeT.empty()) previous->nodeT = std::move(t);
    previous->cornerUV = std::move(cornerUV);
  }
}

}  // namespace

OptimizeResult optimizeOnce(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress, const QualityStats* before,
                            HoldAcross holdAcross, MeshPositions* previous) {
  const auto t0 = std::chrono::steady_clock::now();
  checkOptions(opt);
  const PlanarMeasure& measure = measureByName(opt.measure);
  mesh.validate();
  OptimizeResult res;
  std::vector<unsigned char> grade0;  // how invalid each input element is (keepValidElements)
  {
    MeshQuality q0 = measureQuality(mesh, measure);  // (the rest freed before the run)
    res.before = before ? *before : q0.stats;
    grade0.resize(q0.tangled.size());
    for (std::size_t e = 0; e < grade0.size(); ++e) grade0[e] = q0.grade(e);
  }
  return SweepRun(mesh, opt, progress, measure, holdAcross, std::move(grade0))
      .run(std::move(res), previous, t0);
}

}  // namespace detail
}  // namespace surfmesh
