#include "surfmesh/optimize/optimizer.h"

#include "surfmesh/measures/element_measure.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>

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

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxElementNodes = 21;

bool isMovable(NodeKind k) { return k == NodeKind::Face || k == NodeKind::Edge; }

/// Node → (element, local index) incidence in CSR form.
struct Incidence {
  std::vector<std::int64_t> offset;
  std::vector<std::int32_t> elem;
  std::vector<std::int8_t> local;
};

Incidence buildIncidence(const SurfaceMesh& m) {
  Incidence inc;
  const std::size_t N = m.nodeCount();
  inc.offset.assign(N + 1, 0);
  for (std::int32_t n : m.elemNodes) ++inc.offset[static_cast<std::size_t>(n) + 1];
  for (std::size_t i = 0; i < N; ++i) inc.offset[i + 1] += inc.offset[i];
  inc.elem.resize(m.elemNodes.size());
  inc.local.resize(m.elemNodes.size());
  std::vector<std::int64_t> fill(inc.offset.begin(), inc.offset.end() - 1);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < m.elementSize(e); ++k) {
      const std::int64_t p = fill[static_cast<std::size_t>(nd[k])]++;
      inc.elem[static_cast<std::size_t>(p)] = static_cast<std::int32_t>(e);
      inc.local[static_cast<std::size_t>(p)] = static_cast<std::int8_t>(k);
    }
  }
  return inc;
}

/// Per-thread geometry: clones of the surfaces and curves (OCC adaptors are not shared).
struct ThreadGeometry {
  std::vector<std::unique_ptr<Surface>> surfaces;
  std::vector<std::unique_ptr<Curve>> curves;
  explicit ThreadGeometry(const SurfaceMesh& m) {
    for (const Surface* s : m.surfaces) surfaces.push_back(s ? s->clone() : nullptr);
    for (const Curve* c : m.curves) curves.push_back(c ? c->clone() : nullptr);
  }
};

/// The optimizer's working state: copies of the movable data, written back at the end.
struct State {
  const SurfaceMesh& mesh;
  const PlanarMeasure& measure;
  const OptimizeOptions& opt;
  Incidence inc;
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> t;
  std::vector<Vec2> cornerUV;
  std::vector<Vec3> cornerNormal;  // reference normal at each element corner (zero at poles)
  std::vector<double> elemScale;   // frozen per sweep: mean squared corner edge length
  double deltaHat = 0.0;           // dimensionless δ of the current sweep

  State(const SurfaceMesh& m, const PlanarMeasure& pm, const OptimizeOptions& o)
      : mesh(m),
        measure(pm),
        opt(o),
        inc(buildIncidence(m)),
        xyz(m.xyz),
        uv(m.uv),
        t(m.nodeT),
        cornerUV(m.cornerUV) {
    cornerNormal.assign(m.elemNodes.size(), Vec3::Zero());
    for (std::size_t e = 0; e < m.elementCount(); ++e) {
      const int nc = cornerCount(m.elemType[e]);
      for (int k = 0; k < nc; ++k) {
        const std::size_t p = static_cast<std::size_t>(m.elemOffset[e]) + k;
        cornerNormal[p] = m.referenceNormal(m.elemFace[e], cornerUV[p]);
      }
    }
    elemScale.assign(m.elementCount(), 1.0);
  }

  Vec3 elementNormal(std::size_t e) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::size_t p0 = static_cast<std::size_t>(mesh.elemOffset[e]);
    Vec3 n = Vec3::Zero();
    for (int k = 0; k < nc; ++k) n += cornerNormal[p0 + k];
    if (n.squaredNorm() == 0.0) return elementReferenceNormal(mesh, e);
    return n.normalized();
  }

  double cornerScale(std::size_t e) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    double s = 0.0;
    for (int k = 0; k < nc; ++k) s += (xyz[nd[(k + 1) % nc]] - xyz[nd[k]]).squaredNorm();
    return s / nc;
  }

  ElementEval evalElement(std::size_t e, double delta) const {
    Vec3 x[kMaxElementNodes];
    const std::int32_t* nd = mesh.elementNodes(e);
    const int n = mesh.elementSize(e);
    for (int k = 0; k < n; ++k) x[k] = xyz[nd[k]];
    return elementDistortion(measure, mesh.elemType[e], x, elementNormal(e), delta);
  }
};

struct GlobalEval {
  double objective = 0.0;
  std::size_t tangled = 0;
  double minSigma = kInf;
  double minQuality = 1.0;
};

GlobalEval evaluateAll(const State& s, bool regularized) {
  GlobalEval g;
  for (std::size_t e = 0; e < s.mesh.elementCount(); ++e) {
    const double delta = regularized ? s.deltaHat * s.elemScale[e] : 0.0;
    const ElementEval ev = s.evalElement(e, delta);
    if (ev.tangled) ++g.tangled;
    g.minSigma = std::min(g.minSigma, ev.minSigma);
    const double q = (ev.tangled || !std::isfinite(ev.eta)) ? 0.0 : 1.0 / ev.eta;
    g.minQuality = std::min(g.minQuality, q);
    g.objective += std::isfinite(ev.eta) ? 0.5 * (ev.eta - 1.0) * (ev.eta - 1.0) : kInf;
  }
  return g;
}

/// Evaluation of a node's submesh at a candidate position of the node.
struct LocalEval {
  double f = 0.0;           // Σ (η − 1)² with the sweep's δ
  int tangled = 0;          // elements with det S ≤ 0
  double minQuality = 1.0;  // min 1/η with δ = 0 (0 when tangled)
  bool finite = true;
};

class NodeUpdater {
 public:
  NodeUpdater(State& s, ThreadGeometry& g) : s_(s), g_(g) {}

  /// One safeguarded Newton step (with line search) on node i; returns the 3D move.
  double update(std::size_t i) {
    if (s_.mesh.nodeKind[i] == NodeKind::Face) return updateFaceNode(i);
    if (s_.mesh.nodeKind[i] == NodeKind::Edge) return updateEdgeNode(i);
    return 0.0;
  }

 private:
  State& s_;
  ThreadGeometry& g_;
  // Scratch: the free node's normal per incident element during trials.
  Vec3 trialNormal_[64];

  std::int64_t begin(std::size_t i) const { return s_.inc.offset[i]; }
  std::int64_t end(std::size_t i) const { return s_.inc.offset[i + 1]; }

  /// Sets the element normal of incident element j (index in the incidence list) with the
  /// free node's corner normal replaced by `nfree`.
  Vec3 normalWith(std::size_t e, int local, const Vec3& nfree) const {
    const int nc = cornerCount(s_.mesh.elemType[e]);
    const std::size_t p0 = static_cast<std::size_t>(s_.mesh.elemOffset[e]);
    Vec3 n = Vec3::Zero();
    for (int k = 0; k < nc; ++k) n += (k == local) ? nfree : s_.cornerNormal[p0 + k];
    if (n.squaredNorm() == 0.0) return s_.elementNormal(e);
    return n.normalized();
  }

  /// Evaluates the submesh of node i with the node at x and, for each incident element, the
  /// free node's corner normal given by normals[j]. With derivatives when g/H are non-null.
  LocalEval evalLocal(std::size_t i, const Vec3& x, const Vec3* normals, bool wantQuality, Vec3* g,
                      Mat3* H) const {
    LocalEval r;
    if (g) g->setZero();
    if (H) H->setZero();
    Vec3 xs[kMaxElementNodes];
    for (std::int64_t p = begin(i); p < end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int local = s_.inc.local[static_cast<std::size_t>(p)];
      const std::int32_t* nd = s_.mesh.elementNodes(e);
      const int n = s_.mesh.elementSize(e);
      for (int k = 0; k < n; ++k) xs[k] = (k == local) ? x : s_.xyz[nd[k]];
      const int nc = cornerCount(s_.mesh.elemType[e]);
      const Vec3 nref =
          local < nc ? normalWith(e, local, normals[p - begin(i)]) : s_.elementNormal(e);
      const double delta = s_.deltaHat * s_.elemScale[e];
      Vec3 ge;
      Mat3 He;
      const ElementEval ev = elementDistortion(s_.measure, s_.mesh.elemType[e], xs, nref, delta,
                                               local, g ? &ge : nullptr, H ? &He : nullptr);
      if (ev.tangled) ++r.tangled;
      if (!std::isfinite(ev.eta)) {
        r.finite = false;
        r.f = kInf;
        continue;
      }
      const double d = ev.eta - 1.0;
      r.f += d * d;
      if (g) *g += 2.0 * d * ge;
      if (H) *H += 2.0 * (ge * ge.transpose() + d * He);
      if (wantQuality) {
        double q;
        if (ev.tangled) {
          q = 0.0;
        } else if (delta == 0.0) {
          q = 1.0 / ev.eta;
        } else {
          const ElementEval e0 = elementDistortion(s_.measure, s_.mesh.elemType[e], xs, nref, 0.0);
          q = std::isfinite(e0.eta) ? 1.0 / e0.eta : 0.0;
        }
        r.minQuality = std::min(r.minQuality, q);
      }
    }
    return r;
  }

  /// Acceptance test of a trial against the current state.
  bool acceptable(const LocalEval& cur, const LocalEval& trial) const {
    if (!trial.finite) return false;
    if (trial.tangled > cur.tangled) return false;
    if (!(trial.f < cur.f)) return false;
    if (s_.opt.monotone && cur.tangled == 0 && trial.minQuality < cur.minQuality) return false;
    return true;
  }

  /// Mean edge length of the node's submesh at its node (a local size for step caps).
  double localSize(std::size_t i) const {
    double s = 0.0;
    int n = 0;
    for (std::int64_t p = begin(i); p < end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      s += std::sqrt(s_.cornerScale(e));
      ++n;
    }
    return n ? s / n : 0.0;
  }

  /// Newton direction for a 2×2 (or 1×1 via size) system with an eigenvalue safeguard.
  static Vec2 newtonDirection(const Vec2& g, const Mat2& H) {
    Eigen::SelfAdjointEigenSolver<Mat2> es(0.5 * (H + H.transpose()));
    Vec2 lam = es.eigenvalues();
    const double lmax = std::max(std::abs(lam(0)), std::abs(lam(1)));
    if (!(lmax > 0.0) || !std::isfinite(lmax)) return -g;
    const double floor = 1e-8 * lmax;
    for (int k = 0; k < 2; ++k) lam(k) = std::max(std::abs(lam(k)), floor);
    const Mat2 V = es.eigenvectors();
    return -(V * lam.cwiseInverse().asDiagonal() * V.transpose() * g);
  }

  double updateFaceNode(std::size_t i) {
    const int face = s_.mesh.nodeFace[i];
    const Surface& surf = *g_.surfaces[static_cast<std::size_t>(face)];
    const std::int64_t deg = end(i) - begin(i);
    if (deg == 0 || deg > 64) return 0.0;
    const double L = localSize(i);
    if (!(L > 0.0)) return 0.0;
    double moved = 0.0;
    for (int it = 0; it < s_.opt.innerIterations; ++it) {
      const Vec2 uv0 = s_.uv[i];
      const SurfaceD2 d = surf.d2(uv0.x(), uv0.y());
      if (isDegenerate({d.p, d.du, d.dv})) return moved;  // a pole: stays fixed
      for (std::int64_t p = begin(i); p < end(i); ++p)
        trialNormal_[p - begin(i)] = s_.cornerNormal[static_cast<std::size_t>(p)];
      Vec3 gx;
      Mat3 Hx;
      const Vec3 x0 = s_.xyz[i];
      const LocalEval cur = evalLocal(i, x0, trialNormal_, s_.opt.monotone, &gx, &Hx);
      if (!cur.finite || cur.f == 0.0) return moved;
      Vec2 gu;
      Mat2 Hu;
      chainToSurface(d, gx, Hx, &gu, &Hu);
      if (!gu.allFinite() || !Hu.allFinite()) return moved;
      Vec2 dir = newtonDirection(gu, Hu);
      if (gu.dot(dir) >= 0.0) dir = -gu;  // not a descent direction: use the gradient
      // Cap the step so that its first-order 3D length is at most the local size.
      const double len3 = (d.du * dir.x() + d.dv * dir.y()).norm();
      if (len3 > L) dir *= L / len3;
      bool accepted = false;
      double alpha = 1.0;
      Vec2 uvNew;
      Vec3 xNew;
      for (int ls = 0; ls < s_.opt.maxLineSearch; ++ls, alpha *= 0.5) {
        uvNew = surf.wrap(uv0 + alpha * dir);
        if (!surf.contains(uvNew.x(), uvNew.y())) continue;
        const SurfaceD1 dn = surf.d1(uvNew.x(), uvNew.y());
        if (isDegenerate(dn)) continue;
        const Vec3 nn = (s_.mesh.faceOrientation[static_cast<std::size_t>(face)] *
                         surf.normalSign() * dn.du.cross(dn.dv).normalized())
                            .eval();
        for (std::int64_t p = begin(i); p < end(i); ++p) trialNormal_[p - begin(i)] = nn;
        const LocalEval tr = evalLocal(i, dn.p, trialNormal_, s_.opt.monotone, nullptr, nullptr);
        if (acceptable(cur, tr)) {
          accepted = true;
          xNew = dn.p;
          break;
        }
      }
      if (!accepted) return moved;
      // Commit: position, (u,v), and the node's corner data in every incident element.
      const double step = (xNew - x0).norm();
      moved += step;
      s_.uv[i] = uvNew;
      s_.xyz[i] = xNew;
      for (std::int64_t p = begin(i); p < end(i); ++p) {
        const std::size_t pp = static_cast<std::size_t>(p);
        const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
        const std::size_t slot = static_cast<std::size_t>(s_.mesh.elemOffset[e]) + s_.inc.local[pp];
        s_.cornerUV[slot] = surf.unwrapNear(uvNew, s_.cornerUV[slot]);
        if (s_.inc.local[pp] < cornerCount(s_.mesh.elemType[e]))
          s_.cornerNormal[slot] = trialNormal_[p - begin(i)];
      }
      if (step < 1e-14 * L) break;
    }
    return moved;
  }

  double updateEdgeNode(std::size_t i) {
    const int edge = s_.mesh.nodeEdge[i];
    const Curve& curve = *g_.curves[static_cast<std::size_t>(edge)];
    const std::int64_t deg = end(i) - begin(i);
    if (deg == 0 || deg > 64) return 0.0;
    const double L = localSize(i);
    if (!(L > 0.0)) return 0.0;
    // The node stays between its neighbours on the same edge (and inside the edge's range).
    const double t0 = s_.t[i];
    double lo = curve.tmin(), hi = curve.tmax();
    const bool periodic = curve.isPeriodic();
    for (std::int64_t p = begin(i); p < end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* nd = s_.mesh.elementNodes(e);
      for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        if (j == i || s_.mesh.nodeEdge.empty() || s_.mesh.nodeEdge[j] != edge) continue;
        double tj = s_.t[j];
        if (periodic) tj = tj - std::round((tj - t0) / curve.period()) * curve.period();
        if (tj < t0) lo = periodic ? std::max(lo, tj) : std::max(lo, tj);
        if (tj > t0) hi = std::min(hi, tj);
      }
    }
    if (periodic) {
      // Without two neighbours on the edge a closed edge gives no interval: stay put.
      if (lo == curve.tmin() || hi == curve.tmax()) return 0.0;
    }
    const CurveD2 d = curve.d2(t0);
    if (!(d.dt.norm() > 0.0)) return 0.0;
    for (std::int64_t p = begin(i); p < end(i); ++p)
      trialNormal_[p - begin(i)] = s_.cornerNormal[static_cast<std::size_t>(p)];
    Vec3 gx;
    Mat3 Hx;
    const Vec3 x0 = s_.xyz[i];
    const LocalEval cur = evalLocal(i, x0, trialNormal_, s_.opt.monotone, &gx, &Hx);
    if (!cur.finite || cur.f == 0.0) return 0.0;
    double gt, Ht;
    chainToCurve(d, gx, Hx, &gt, &Ht);
    if (!std::isfinite(gt) || !std::isfinite(Ht) || gt == 0.0) return 0.0;
    double dt = (Ht > 0.0) ? -gt / Ht : -gt / (std::abs(Ht) + 1e-12);
    if (dt * gt > 0.0) dt = -dt;
    const double len3 = std::abs(dt) * d.dt.norm();
    if (len3 > L) dt *= L / len3;
    const double margin = 1e-3 * (hi - lo);
    double alpha = 1.0;
    for (int ls = 0; ls < s_.opt.maxLineSearch; ++ls, alpha *= 0.5) {
      const double tn = t0 + alpha * dt;
      if (!(tn > lo + margin && tn < hi - margin)) continue;
      const Vec3 xn = curve.value(tn);
      // Corner normals on each incident element's face at the new point.
      for (std::int64_t p = begin(i); p < end(i); ++p) {
        const std::size_t pp = static_cast<std::size_t>(p);
        const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
        const std::size_t slot = static_cast<std::size_t>(s_.mesh.elemOffset[e]) + s_.inc.local[pp];
        const int f = s_.mesh.elemFace[e];
        const Vec2 uvf = curve.uvOnFace(f, tn, s_.cornerUV[slot]);
        const Surface& sf = *g_.surfaces[static_cast<std::size_t>(f)];
        const Vec3 nn =
            (s_.mesh.faceOrientation[static_cast<std::size_t>(f)] * sf.normal(uvf.x(), uvf.y()))
                .eval();
        trialNormal_[p - begin(i)] = nn;
      }
      const LocalEval tr = evalLocal(i, xn, trialNormal_, s_.opt.monotone, nullptr, nullptr);
      if (!acceptable(cur, tr)) continue;
      s_.t[i] = tn;
      s_.xyz[i] = xn;
      for (std::int64_t p = begin(i); p < end(i); ++p) {
        const std::size_t pp = static_cast<std::size_t>(p);
        const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
        const std::size_t slot = static_cast<std::size_t>(s_.mesh.elemOffset[e]) + s_.inc.local[pp];
        const int f = s_.mesh.elemFace[e];
        const Surface& sf = *g_.surfaces[static_cast<std::size_t>(f)];
        s_.cornerUV[slot] =
            sf.unwrapNear(curve.uvOnFace(f, tn, s_.cornerUV[slot]), s_.cornerUV[slot]);
        if (s_.inc.local[pp] < cornerCount(s_.mesh.elemType[e]))
          s_.cornerNormal[slot] = trialNormal_[p - begin(i)];
      }
      return (xn - x0).norm();
    }
    return 0.0;
  }
};

int resolveThreads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

}  // namespace

std::vector<std::vector<std::int32_t>> colorMovableNodes(const SurfaceMesh& mesh) {
  const Incidence inc = buildIncidence(mesh);
  const std::size_t N = mesh.nodeCount();
  std::vector<int> color(N, -1);
  std::vector<std::vector<std::int32_t>> colors;
  std::vector<int> mark;  // mark[c] == i when color c is used by a neighbour of i
  for (std::size_t i = 0; i < N; ++i) {
    if (!isMovable(mesh.nodeKind[i])) continue;
    for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p) {
      const std::size_t e = static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const int c = color[static_cast<std::size_t>(nd[k])];
        if (c >= 0) mark[static_cast<std::size_t>(c)] = static_cast<int>(i);
      }
    }
    int c = 0;
    while (c < static_cast<int>(mark.size()) &&
           mark[static_cast<std::size_t>(c)] == static_cast<int>(i))
      ++c;
    if (c == static_cast<int>(mark.size())) {
      mark.push_back(-1);
      colors.emplace_back();
    }
    color[i] = c;
    colors[static_cast<std::size_t>(c)].push_back(static_cast<std::int32_t>(i));
  }
  return colors;
}

OptimizeResult optimizeMesh(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  if (opt.maxSweeps < 0) throw std::invalid_argument("maxSweeps must be >= 0");
  if (!(opt.relTol >= 0.0) || !(opt.moveTol >= 0.0))
    throw std::invalid_argument("tolerances must be >= 0");
  if (opt.innerIterations < 1) throw std::invalid_argument("innerIterations must be >= 1");
  if (opt.maxLineSearch < 1) throw std::invalid_argument("maxLineSearch must be >= 1");
  if (opt.deltaPolicy != "auto" && opt.deltaPolicy != "fixed")
    throw std::invalid_argument("deltaPolicy must be 'auto' or 'fixed', got '" + opt.deltaPolicy +
                                "'");
  if (!(opt.deltaEpsilon > 0.0) || !(opt.delta > 0.0))
    throw std::invalid_argument("delta and deltaEpsilon must be > 0");
  if (opt.threads < 0) throw std::invalid_argument("threads must be >= 0");
  const PlanarMeasure& measure = measureByName(opt.measure);
  mesh.validate();

  OptimizeResult res;
  const MeshQuality q0 = measureQuality(mesh, measure);
  res.before = q0.stats;

  State s(mesh, measure, opt);
  const auto colors = colorMovableNodes(mesh);
  const int nthreads = std::max(1, std::min(resolveThreads(opt.threads), 64));
  res.threadsUsed = nthreads;
  std::vector<std::unique_ptr<ThreadGeometry>> geo;
  for (int k = 0; k < nthreads; ++k) geo.push_back(std::make_unique<ThreadGeometry>(mesh));

  std::size_t movable = 0;
  for (const auto& c : colors) movable += c.size();

  auto chooseDelta = [&](const GlobalEval& g) {
    if (g.tangled == 0) return 0.0;
    if (opt.deltaPolicy == "fixed") return opt.delta;
    const double eps = opt.deltaEpsilon;
    const double sm = std::min(g.minSigma, 0.0);
    return std::sqrt(eps * (eps - sm));
  };
  auto freezeScales = [&]() {
    for (std::size_t e = 0; e < mesh.elementCount(); ++e) s.elemScale[e] = s.cornerScale(e);
  };

  freezeScales();
  GlobalEval g = evaluateAll(s, false);
  s.deltaHat = chooseDelta(g);
  res.initialObjective = s.deltaHat > 0.0 ? evaluateAll(s, true).objective : g.objective;
  res.reason = StopReason::MaxSweeps;
  if (movable == 0 || opt.maxSweeps == 0) res.reason = StopReason::NothingToDo;

  for (int sweep = 1; movable > 0 && sweep <= opt.maxSweeps; ++sweep) {
    freezeScales();
    s.deltaHat = chooseDelta(g);
    const double fStart = s.deltaHat > 0.0 ? evaluateAll(s, true).objective : g.objective;
    std::vector<double> maxRel(static_cast<std::size_t>(nthreads), 0.0);
    std::exception_ptr error;
    std::mutex errorMutex;
    for (const auto& color : colors) {
      const std::size_t n = color.size();
      auto work = [&](int tid) {
        try {
          NodeUpdater up(s, *geo[static_cast<std::size_t>(tid)]);
          const std::size_t a = n * static_cast<std::size_t>(tid) / nthreads;
          const std::size_t b = n * static_cast<std::size_t>(tid + 1) / nthreads;
          double m = 0.0;
          for (std::size_t k = a; k < b; ++k) {
            const std::size_t node = static_cast<std::size_t>(color[k]);
            const double mv = up.update(node);
            if (mv > 0.0) {
              double L = 0.0;
              int cnt = 0;
              for (std::int64_t p = s.inc.offset[node]; p < s.inc.offset[node + 1]; ++p) {
                L += std::sqrt(
                    s.elemScale[static_cast<std::size_t>(s.inc.elem[static_cast<std::size_t>(p)])]);
                ++cnt;
              }
              if (cnt > 0 && L > 0.0) m = std::max(m, mv / (L / cnt));
            }
          }
          maxRel[static_cast<std::size_t>(tid)] =
              std::max(maxRel[static_cast<std::size_t>(tid)], m);
        } catch (...) {
          std::lock_guard<std::mutex> lock(errorMutex);
          if (!error) error = std::current_exception();
        }
      };
      if (nthreads == 1 || n < 64) {
        // Small colors: run on the calling thread, split the same way for determinism.
        for (int tid = 0; tid < nthreads; ++tid) work(tid);
      } else {
        std::vector<std::thread> pool;
        for (int tid = 1; tid < nthreads; ++tid) pool.emplace_back(work, tid);
        work(0);
        for (auto& th : pool) th.join();
      }
      if (error) std::rethrow_exception(error);
    }
    res.sweeps = sweep;
    const double fEnd = s.deltaHat > 0.0 ? evaluateAll(s, true).objective : 0.0;
    g = evaluateAll(s, false);
    const double fEndCmp = s.deltaHat > 0.0 ? fEnd : g.objective;
    const double maxMove = *std::max_element(maxRel.begin(), maxRel.end());
    res.finalObjective = fEndCmp;
    if (progress) {
      OptimizeProgress pr;
      pr.sweep = sweep;
      pr.maxSweeps = opt.maxSweeps;
      pr.objective = fEndCmp;
      pr.tangled = g.tangled;
      pr.minQuality = g.minQuality;
      pr.delta = s.deltaHat;
      if (!progress(pr)) {
        res.reason = StopReason::Cancelled;
        res.after = res.before;
        res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return res;  // the mesh was never touched
      }
    }
    const bool decreaseSmall =
        !(fStart > 0.0) || (fStart - fEndCmp) <= opt.relTol * std::max(fStart, 1e-300);
    if (g.tangled == 0 && s.deltaHat == 0.0 && decreaseSmall && maxMove <= opt.moveTol) {
      res.reason = StopReason::Converged;
      break;
    }
    if (g.tangled == 0 && s.deltaHat == 0.0 && maxMove == 0.0) {
      res.reason = StopReason::Converged;
      break;
    }
  }

  // Write back.
  std::size_t moved = 0;
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
    if (s.xyz[i] != mesh.xyz[i]) ++moved;
  res.movedNodes = moved;
  mesh.xyz = std::move(s.xyz);
  mesh.uv = std::move(s.uv);
  if (!mesh.nodeT.empty()) mesh.nodeT = std::move(s.t);
  mesh.cornerUV = std::move(s.cornerUV);
  res.after = measureQuality(mesh, measure).stats;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace surfmesh
