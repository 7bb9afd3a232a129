#include "surfmesh/optimize/optimizer.h"

#include "reference_mode.h"
#include "straight_sided.h"
#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "tangled_report.h"
#include "topology.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <unordered_map>

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

bool isMovable(NodeKind k) { return k == NodeKind::Face || k == NodeKind::Edge; }

/// Node → (element, local index) incidence in CSR form: the compact neighbour data of the
/// sweep (a node's submesh is elem[offset[i] .. offset[i+1]), its place in each element local).
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

/// Greedy coloring on a given incidence (see colorMovableNodes).
std::vector<std::vector<std::int32_t>> colorNodes(const SurfaceMesh& mesh, const Incidence& inc) {
  const std::size_t N = mesh.nodeCount();
  std::vector<int> color(N, -1);
  std::vector<std::vector<std::int32_t>> colors;
  std::vector<std::int64_t> mark;  // mark[c] == i when color c is used by a neighbour of i
  for (std::size_t i = 0; i < N; ++i) {
    if (!isMovable(mesh.nodeKind[i])) continue;
    const auto ii = static_cast<std::int64_t>(i);
    for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p) {
      const std::size_t e = static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const int c = color[static_cast<std::size_t>(nd[k])];
        if (c >= 0) mark[static_cast<std::size_t>(c)] = ii;
      }
    }
    std::size_t c = 0;
    while (c < mark.size() && mark[c] == ii) ++c;
    if (c == mark.size()) {
      mark.push_back(-1);
      colors.emplace_back();
    }
    color[i] = static_cast<int>(c);
    colors[c].push_back(static_cast<std::int32_t>(i));
  }
  return colors;
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

/// A persistent team of worker threads for the whole run: run(job) executes job(tid) on
/// every member (the caller is member 0) and returns when all are done — the barrier between
/// colors. Waiting members spin briefly, then sleep (so an oversubscribed machine is not
/// burnt by spinning).
class Team {
 public:
  explicit Team(int n) : n_(n) {
    for (int t = 1; t < n_; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Team() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stop_ = true;
      gen_.fetch_add(1, std::memory_order_release);
    }
    cv_.notify_all();
    for (auto& w : workers_) w.join();
  }
  Team(const Team&) = delete;
  Team& operator=(const Team&) = delete;

  int size() const { return n_; }

  template <class F>
  void run(F& job) {
    if (n_ == 1) {
      job(0);
      return;
    }
    job_ = [](void* ctx, int tid) { (*static_cast<F*>(ctx))(tid); };
    ctx_ = &job;
    pending_.store(n_ - 1, std::memory_order_relaxed);
    {
      std::lock_guard<std::mutex> lock(m_);
      gen_.fetch_add(1, std::memory_order_release);
    }
    cv_.notify_all();
    job(0);
    for (int spin = 0; pending_.load(std::memory_order_acquire) != 0; ++spin) {
      if (spin < 4000) continue;
      std::unique_lock<std::mutex> lock(m_);
      doneCv_.wait(lock, [this] { return pending_.load(std::memory_order_acquire) == 0; });
    }
  }

 private:
  void loop(int tid) {
    std::uint64_t seen = 0;
    for (;;) {
      std::uint64_t g = gen_.load(std::memory_order_acquire);
      for (int spin = 0; g == seen && spin < 4000; ++spin) g = gen_.load(std::memory_order_acquire);
      if (g == seen) {
        std::unique_lock<std::mutex> lock(m_);
        cv_.wait(lock, [&] { return gen_.load(std::memory_order_acquire) != seen; });
        g = gen_.load(std::memory_order_acquire);
      }
      seen = g;
      if (stop_) return;
      job_(ctx_, tid);
      if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        std::lock_guard<std::mutex> lock(m_);
        doneCv_.notify_one();
      }
    }
  }

  int n_;
  std::vector<std::thread> workers_;
  std::mutex m_;
  std::condition_variable cv_, doneCv_;
  std::atomic<std::uint64_t> gen_{0};
  std::atomic<int> pending_{0};
  bool stop_ = false;
  void (*job_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
};

/// Cached surface derivatives at a node's accepted position (reused by its next Newton step).
struct NodeD2 {
  Vec3 du, dv, duu, duv, dvv;
};

/// One element's distortion with the free node at local index `local`, evaluated at δ and
/// (when asked) at δ = 0 for the quality.
struct ElemOut {
  double eta = 1.0;  // η with the sweep's δ (+∞ when δ = 0 and tangled)
  // η with δ = 0 (+∞ when tangled), filled when wantEta0. A triangle tangled only by the
  // across hold (held, wound along the surface by the paper's σ) gets the paper's η: the
  // progress reports count it as the quality report will.
  double eta0 = 1.0;
  double minSigma = 0.0;
  bool tangled = false;
  bool held = false;  // σ from acrossArea (the triangle leans across its surface)
};

/// A node whose submesh holds an element with η above this tries fallback directions when its
/// Newton step fails (quality below 1/4).
constexpr double kFallbackEta = 4.0;

/// The line search stops halving once the step's first-order 3D length is below this fraction
/// of moveTol × the node's local size (moveTol = 0: it always runs maxLineSearch halvings).
constexpr double kMinStepFraction = 0.1;

/// Colors with fewer nodes are updated on the calling thread alone (see the sweep).
constexpr std::size_t kMinParallelNodes = 128;

const double kInvSqrt3 = 0.57735026918962576451;
const double kDetWinv = 2.0 * kInvSqrt3;  // det W⁻¹ of the equilateral ideal triangle

/// A linear triangle that was neither standing across its surface nor leaning far from it at
/// the start of the run (see standsAcross) is kept from becoming so: its area ‖c‖ in σ
/// (c = (x1 − x0) × (x2 − x0)) is replaced by
///     a = min(‖c‖, kAcrossSlope · m) when m ≥ 0,   a = m when m < 0,
/// with m the least c·n_k over its corners (n_k the unit corner normals, zero ones skipped):
/// a = ‖c‖, the paper's σ, until its plane leans more than acos(1/kAcrossSlope) ≈ 84° from the
/// surface's normal at a corner, and a ≤ 0 — tangled for the run — when it is wound against the
/// normal at a corner. a is continuous in the node positions. The quality report keeps the
/// paper's σ; elements the input has standing across keep it in the run too (Gmsh's meshes of
/// CAD parts have some at small fillets and holes, which no node motion may right).
constexpr double kAcrossSlope = 10.0;

/// a of the comment above, for c, its norm cn and the corner normals n[0 … 2]. When a ≠ ‖c‖,
/// *which is the corner of m and a = *slope · c·n[*which] (linear in each node); otherwise
/// *which = −1.
inline double acrossArea(const Vec3& c, double cn, const Vec3* n, int* which, double* slope) {
  *which = -1;
  *slope = 0.0;
  // Every corner within acos(1/kAcrossSlope) (a zero normal gives 0: the loop below skips it).
  if (kAcrossSlope * std::min({c.dot(n[0]), c.dot(n[1]), c.dot(n[2])}) >= cn) return cn;
  int k = -1;
  double m = 0.0;
  for (int j = 0; j < 3; ++j) {
    if (!(n[j].squaredNorm() > 0.0)) continue;
    const double s = c.dot(n[j]);
    if (k < 0 || s < m) {
      m = s;
      k = j;
    }
  }
  if (k < 0) return cn;
  const double f = m >= 0.0 ? kAcrossSlope : 1.0;
  const double a = f * m;
  if (!(a < cn)) return cn;
  *which = k;
  *slope = f;
  return a;
}

/// faceCorners bit: the element is held from standing across its surface (a linear triangle:
/// acrossArea; a high-order one: see State's constructor).
constexpr unsigned kAcrossGuard = 0x80u;
/// Corner normals kept per element (cornerN): a quad's four.
constexpr int kCornerSlots = 4;
/// Normals kept per held element in a node update (Worker::cornerNormals): a high-order
/// triangle's at every node (certifyTriangleAgainstNodeNormals), a quad8's at its corners.
constexpr int kHeldSlots = kMaxElementNodes;
/// Curved elements held from standing across by their tangent planes at the corners (State's
/// constructor): high-order triangles and quad8.
inline bool heldCurved(ElementType t) { return isHighOrderTriangle(t) || t == ElementType::Quad8; }

/// Tangent basis of a Face node's (u,v) at its current position: derivatives are assembled
/// directly in (u,v) (g_u = Jᵀ g, H_u = Jᵀ H J) instead of as 3×3 Hessians.
struct Tangent {
  Vec3 du, dv;
  Mat2 metric;  // JᵀJ
};

/// What a linear triangle's derivatives are built from (see triangleKernel).
struct TriPieces {
  InvariantDerivs d;
  Vec3 gF, gs, w, mw;
  double pcoef = 0.0;  // coefficient of [w]×ᵀ(I − ννᵀ)[w]× in the Hessian (0 when degenerate)
};

/// Linear triangle (x0 free, x1, x2 the next corners counter-clockwise), equilateral ideal:
/// the closed form of jacobianDistortion for b = (−1, −1), W⁻¹ = [[1, −1/√3], [0, 2/√3]].
/// With `pieces` non-null, fills what the gradient and Hessian with respect to x0 are made of.
/// `corners`: the surface's unit normals at x0, x1, x2 (acrossArea), or null.
inline ElemOut triangleCore(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1, const Vec3& x2,
                            const Vec3& n, double delta, bool wantEta0, TriPieces* pieces,
                            bool projected = false, const Vec3* corners = nullptr) {
  ElemOut r;
  const Vec3 J0 = x1 - x0, J1 = x2 - x0;
  const Vec3 K1 = (2.0 * J1 - J0) * kInvSqrt3;  // K = J W⁻¹ = [J0, K1]
  const double F = J0.squaredNorm() + K1.squaredNorm();
  const Vec3 c = J0.cross(J1);
  const double cn = c.norm();
  if (!std::isfinite(F) || !std::isfinite(cn) || !(F > 0.0)) {
    r.eta = r.eta0 = kInf;
    r.minSigma = -1.0;
    r.tangled = true;
    return r;
  }
  const double orient = c.dot(n);
  const double nlen = n.norm();
  // η at δ = 0 of a tangled triangle (see ElemOut::eta0): the paper's, when only the hold
  // made it tangled.
  auto tangledEta0 = [&]() {
    const double s0 = kDetWinv * cn;
    return (r.held && orient > 0.0 && s0 > 0.0) ? m.invariantValue(F, s0, s0) : kInf;
  };
  if (projected && nlen > 0.0) {
    // σ of the triangle projected on the plane normal to n: continuous through a triangle
    // standing across the surface (where ±‖c‖ jumps), linear in x0.
    const Vec3 nu = n / nlen;
    double sigma = kDetWinv * orient / nlen;
    // Leaning across the surface at a corner (acrossArea) takes the lower of the two.
    int across = -1;
    double acrossSlope = 0.0;
    if (corners) {
      const double a = kDetWinv * acrossArea(c, cn, corners, &across, &acrossSlope);
      if (across >= 0 && a < sigma - 1e-9 * std::abs(sigma))  // not mere rounding
        sigma = a;
      else
        across = -1;
    }
    r.minSigma = 2.0 * sigma / F;
    r.tangled = !(sigma > 0.0);
    r.held = across >= 0;
    const double sigmaStar = regularizedSigmaValue(sigma, delta);
    if (!pieces) {
      r.eta = m.invariantValue(F, sigma, sigmaStar);
      if (r.tangled && delta == 0.0) r.eta = kInf;
      r.eta0 = r.tangled ? tangledEta0() : m.invariantValue(F, sigma, sigma);
      return r;
    }
    const InvariantDerivs d = m.invariants(F, sigma, regularizedSigma(sigma, delta));
    r.eta = d.h;
    r.eta0 = r.tangled ? tangledEta0() : m.invariants(F, sigma, regularizedSigma(sigma, 0.0)).h;
    TriPieces& P = *pieces;
    P.d = d;
    P.gF = -2.0 * (J0 + K1 * kInvSqrt3);
    P.w = x2 - x1;
    P.mw = across >= 0 ? Vec3((acrossSlope * corners[across]).cross(P.w)) : Vec3(nu.cross(P.w));
    P.gs = kDetWinv * P.mw;
    P.pcoef = 0.0;
    return r;
  }
  const bool regular = cn > 1e-14 * F && orientationDefined(orient, cn * cn, n.squaredNorm());
  const double gamma = (regular && orient > 0.0) ? 1.0 : -1.0;
  // A triangle leaning across its surface: σ from acrossArea (linear in x0).
  int across = -1;
  double acrossSlope = 0.0, area = cn;
  if (corners && regular && gamma > 0.0) area = acrossArea(c, cn, corners, &across, &acrossSlope);
  const double sigma = regular ? (across >= 0 ? area : gamma * cn) * kDetWinv : 0.0;
  r.minSigma = 2.0 * sigma / F;
  r.tangled = !(sigma > 0.0);
  r.held = across >= 0;
  if (r.tangled && delta == 0.0) {
    r.eta = kInf;
    r.eta0 = wantEta0 ? tangledEta0() : kInf;
    return r;
  }
  if (!pieces) {  // a value: line-search trials, whole-mesh sums
    r.eta = m.invariantValue(F, sigma, regularizedSigmaValue(sigma, delta));
    if (wantEta0)
      r.eta0 = delta == 0.0 ? r.eta : r.tangled ? tangledEta0() : m.invariantValue(F, sigma, sigma);
    return r;
  }
  const InvariantDerivs d = m.invariants(F, sigma, regularizedSigma(sigma, delta));
  r.eta = d.h;
  if (wantEta0)
    r.eta0 = delta == 0.0 ? d.h
             : r.tangled  ? tangledEta0()
                          : m.invariants(F, sigma, regularizedSigma(sigma, 0.0)).h;
  {
    // β = W⁻ᵀ b = (−1, −1/√3); ∂F/∂x0 = 2 K β; w = x2 − x1; ∂σ/∂x0 = det W⁻¹ ν × w.
    TriPieces& P = *pieces;
    P.d = d;
    P.gF = -2.0 * (J0 + K1 * kInvSqrt3);
    P.w = x2 - x1;
    if (across >= 0) {  // σ = det W⁻¹ · slope · c·n_k: ∂σ/∂x0 = det W⁻¹ slope n_k × w
      P.mw = (acrossSlope * corners[across]).cross(P.w);
      P.gs = kDetWinv * P.mw;
      P.pcoef = 0.0;
    } else {
      const Vec3 nu = regular ? Vec3(gamma * c / cn) : n.normalized();
      P.mw = nu.cross(P.w);
      P.gs = kDetWinv * P.mw;
      P.pcoef = regular ? d.hs * kDetWinv * gamma / cn : 0.0;
    }
  }
  return r;
}

/// triangleCore with the gradient and the 3×3 Hessian with respect to x0.
inline ElemOut triangleKernel(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1,
                              const Vec3& x2, const Vec3& n, double delta, bool wantEta0,
                              Vec3* grad, Mat3* hess, bool projected = false,
                              const Vec3* corners = nullptr) {
  TriPieces P;
  const ElemOut r =
      triangleCore(m, x0, x1, x2, n, delta, wantEta0, grad ? &P : nullptr, projected, corners);
  if (grad && std::isfinite(r.eta)) {
    const InvariantDerivs& d = P.d;
    *grad = d.hF * P.gF + d.hs * P.gs;
    Mat3 H = d.hFF * P.gF * P.gF.transpose() +
             d.hFs * (P.gF * P.gs.transpose() + P.gs * P.gF.transpose()) +
             d.hss * P.gs * P.gs.transpose();
    H.diagonal().array() += d.hF * (8.0 / 3.0);  // 2 ‖β‖²
    if (P.pcoef != 0.0) H += P.pcoef * crossProjected(P.w, P.mw);
    *hess = H;
  }
  return r;
}

/// Symmetric 2×2 a·xxᵀ + b·(xyᵀ + yxᵀ) + c·yyᵀ as (h00, h01, h11).
inline Vec3 sym2(double a, double b, double c, const Vec2& x, const Vec2& y) {
  return Vec3(a * x.x() * x.x() + 2.0 * b * x.x() * y.x() + c * y.x() * y.x(),
              a * x.x() * x.y() + b * (x.x() * y.y() + x.y() * y.x()) + c * y.x() * y.y(),
              a * x.y() * x.y() + 2.0 * b * x.y() * y.y() + c * y.y() * y.y());
}

/// triangleCore with the 3D gradient and the Hessian projected on the tangent basis, Jᵀ H J,
/// assembled from projected vectors (2×2 arithmetic instead of 3×3).
inline ElemOut triangleKernelUV(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1,
                                const Vec3& x2, const Vec3& n, double delta, bool wantEta0,
                                const Tangent& T, Vec3* grad, Vec3* hessUV, bool projected = false,
                                const Vec3* corners = nullptr) {
  TriPieces P;
  const ElemOut r = triangleCore(m, x0, x1, x2, n, delta, wantEta0, &P, projected, corners);
  if (std::isfinite(r.eta)) {
    const InvariantDerivs& d = P.d;
    *grad = d.hF * P.gF + d.hs * P.gs;
    const Vec2 gF(T.du.dot(P.gF), T.dv.dot(P.gF)), gs(T.du.dot(P.gs), T.dv.dot(P.gs));
    Vec3 h = sym2(d.hFF, d.hFs, d.hss, gF, gs);
    double gcoef = d.hF * (8.0 / 3.0);
    if (P.pcoef != 0.0) {
      const Vec2 w(T.du.dot(P.w), T.dv.dot(P.w)), mw(T.du.dot(P.mw), T.dv.dot(P.mw));
      gcoef += P.pcoef * P.w.squaredNorm();
      h -= P.pcoef * (sym2(1.0, 0.0, 1.0, w, mw));
    }
    h += gcoef * Vec3(T.metric(0, 0), T.metric(0, 1), T.metric(1, 1));
    *hessUV = h;
  }
  return r;
}

/// Closed-form symmetric 2×2 eigen-decomposition → safeguarded Newton direction −|H|⁻¹ g
/// (eigenvalues replaced by their absolute values, floored at 1e-8 of the largest).
inline Vec2 newtonDirection(const Vec2& g, const Mat2& Hin) {
  const double a = Hin(0, 0), b = 0.5 * (Hin(0, 1) + Hin(1, 0)), c = Hin(1, 1);
  const double tr = 0.5 * (a + c), df = 0.5 * (a - c);
  const double rad = std::sqrt(df * df + b * b);
  double l1 = tr + rad, l2 = tr - rad;
  const double lmax = std::max(std::abs(l1), std::abs(l2));
  if (!(lmax > 0.0) || !std::isfinite(lmax)) return -g;
  // Unit eigenvector of l1.
  Vec2 v1;
  if (rad == 0.0) {
    v1 = Vec2(1.0, 0.0);
  } else if (df >= 0.0) {
    v1 = Vec2(df + rad, b);
  } else {
    v1 = Vec2(b, rad - df);
  }
  const double nv = v1.norm();
  v1 = nv > 0.0 ? Vec2(v1 / nv) : Vec2(1.0, 0.0);
  const Vec2 v2(-v1.y(), v1.x());
  const double floor = 1e-8 * lmax;
  l1 = std::max(std::abs(l1), floor);
  l2 = std::max(std::abs(l2), floor);
  return -(v1 * (v1.dot(g) / l1) + v2 * (v2.dot(g) / l2));
}

int resolveThreads(int requested) {
  if (requested > 0) return requested;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

}  // namespace

namespace {

/// The optimizer's working state. Node positions and parameters are copies of the mesh's
/// (written back at the end, so that a cancelled run leaves the mesh untouched); element
/// corner (u,v) are not copied: they are refreshed from the final node parameters.
struct State {
  const SurfaceMesh& mesh;
  const PlanarMeasure& measure;
  const OptimizeOptions& opt;
  Incidence inc;
  bool allTri3 = true;
  std::size_t maxDegree = 0;
  // ---- nodes -----------------------------------------------------------------------------
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> t;
  std::vector<Vec3> nodeNormal;         // reference normal of Face nodes at their (u,v)
  std::vector<NodeD2> d2;               // surface derivatives at a Face node's position
  std::vector<unsigned char> d2Valid;   // whether d2[i] is current
  std::vector<std::int32_t> lastVisit;  // clock of the node's last update
  std::vector<std::int32_t> movedAt;    // clock of its last significant move (0: never)
  /// Per node: its last accepted Newton step of a smoothing sweep, in (u,v) (Face nodes) or t
  /// (x; sliding nodes); zero after any other move. Over-relaxation follows it (see
  /// OptimizeOptions::overRelaxation).
  std::vector<Eigen::Vector2f> lastStep;
  // ---- elements --------------------------------------------------------------------------
  // Reference normal of element e: normalized (fixedNormal[e] + Σ nodeNormal over its Face
  // corners), fixedNormal holding the corner normals of its Fixed and Edge corners.
  std::vector<Vec3> fixedNormal;
  std::vector<std::uint8_t> faceCorners;  // bit k: corner k of element e is a Face node
  // The surface's normal at the corners of the linear triangles with a corner that is not a
  // Face node (acrossArea): cornerElems lists those triangles in increasing order, cornerN
  // holds 3 normals per entry, current for sliding nodes (commitEdgeMove); Face corners'
  // entries are unused (nodeNormal holds them). No per-element array: most elements have none.
  std::vector<std::int32_t> cornerElems;
  std::vector<Vec3> cornerN;
  std::vector<double> elemSize;  // √(mean squared corner edge length), frozen per sweep
  // Size² that scales δ for element e: the input's corner scales averaged over the elements
  // around its corners, frozen for the whole run. Frozen, because a δ that followed the
  // element's own size would let a tangled element shrink to a point at no cost; averaged,
  // because a tangled input element may itself be tiny.
  std::vector<double> deltaScale;
  std::vector<double> eta0;      // η with δ = 0 (+∞ tangled), kept current in δ = 0 sweeps
  std::vector<double> minSigma;  // scaled det S (≤ 0 tangled), idem
  // ---- sliding nodes ---------------------------------------------------------------------
  std::vector<std::int64_t> edgeSlot;  // N (or empty): first index in edgeNormal, −1
  std::vector<Vec3> edgeNormal;        // corner normal of an Edge node in each incident element
  // ---- sweep -----------------------------------------------------------------------------
  double deltaHat = 0.0;  // dimensionless δ of the current sweep
  // Monotone mode, δ = 0 sweeps: the lowest quality of the valid elements with a movable node
  // at the start of the sweep. A move may lower its submesh's minimum quality down to this
  // floor, not below it, so that the mesh's minimum over those elements never decreases.
  // +∞ in untangling sweeps (no valid submesh's minimum may drop).
  double qualityFloor = kInf;
  bool trackCache = true;  // δ = 0 sweep: keep eta0/minSigma current at every accepted move
  // Patch untangling (escapeTangledElements → relaxPatch): a node's move may tangle more
  // elements of its submesh than it had (only f̂ must decrease), linear triangles use their
  // projected σ; the patch as a whole is kept only when it ends with fewer tangled elements.
  bool relaxTangled = false;
  // Backoff of the patch untangling per stuck element (escapeTangledElements): after n failed
  // attempts in a row, an element's patches are relaxed again only min(2^(n−1),
  // deltaStallSweeps) sweeps later, or as soon as ε has moved to another level. Only elements
  // that stay tangled have an entry.
  struct RelaxBackoff {
    int fails = 0;
    int nextSweep = 0;
    int epsilonLevel = 0;
    /// One more failure at `sweep`: the next try waits min(2^(fails−1), stallSweeps) sweeps.
    void failed(int sweep, int stallSweeps) {
      ++fails;
      const int wait = 1 << std::min(fails - 1, 20);
      nextSweep = sweep + std::min(wait, std::max(1, stallSweeps));
    }
  };
  std::unordered_map<std::size_t, RelaxBackoff> relaxBackoff;
  // The same backoff for the harmonic layout alone (the escapes of the first stalled sweeps,
  // before the joint untangling is allowed): it does not depend on δ, only on the positions,
  // so retrying it at every stalled sweep mostly repeats a failure (hundreds of stuck
  // elements made it cost more than the sweep on a second-order mesh).
  std::unordered_map<std::size_t, RelaxBackoff> harmonicBackoff;
  // The backoff of widenElement's joint search (see escapeTangledElements), without the cap
  // of deltaStallSweeps: a search that failed mostly fails again, and costs hundreds of
  // element evaluations per start.
  std::unordered_map<std::size_t, RelaxBackoff> widenBackoff;
  std::size_t patchUntanglings = 0;  // elements whose patches were relaxed (per escape)
  std::size_t straightened = 0;      // elements untangled by straightenHighOrder
  std::int32_t clock = 0;            // advanced once per color
  std::int32_t validFrom = 1;        // a node last visited before this clock is revisited

  State(const SurfaceMesh& m, const PlanarMeasure& pm, const OptimizeOptions& o, bool holdAcross)
      : mesh(m), measure(pm), opt(o), inc(buildIncidence(m)), xyz(m.xyz), uv(m.uv), t(m.nodeT) {
    const std::size_t N = m.nodeCount(), E = m.elementCount();
    for (std::size_t e = 0; e < E; ++e)
      if (m.elemType[e] != ElementType::Tri3) allTri3 = false;
    for (std::size_t i = 0; i < N; ++i)
      maxDegree = std::max(maxDegree, static_cast<std::size_t>(inc.offset[i + 1] - inc.offset[i]));
    nodeNormal.assign(N, Vec3::Zero());
    d2.resize(N);
    d2Valid.assign(N, 0);
    lastVisit.assign(N, 0);
    movedAt.assign(N, 0);
    lastStep.assign(N, Eigen::Vector2f::Zero());
    bool anyEdge = false;
    for (std::size_t i = 0; i < N; ++i) {
      if (m.nodeKind[i] == NodeKind::Face) nodeNormal[i] = m.referenceNormal(m.nodeFace[i], uv[i]);
      if (m.nodeKind[i] == NodeKind::Edge) anyEdge = true;
    }
    fixedNormal.assign(E, Vec3::Zero());
    faceCorners.assign(E, 0);
    for (std::size_t e = 0; e < E; ++e) {
      const int nc = cornerCount(m.elemType[e]);
      const std::int32_t* nd = m.elementNodes(e);
      for (int k = 0; k < nc; ++k) {
        if (m.nodeKind[static_cast<std::size_t>(nd[k])] != NodeKind::Face) {
          const Vec3 nk = m.referenceNormal(m.elemFace[e], m.elementUV(e)[k]);
          fixedNormal[e] += nk;
          if (m.elemType[e] == ElementType::Tri3 || heldCurved(m.elemType[e])) {
            if (cornerElems.empty() || cornerElems.back() != static_cast<std::int32_t>(e)) {
              cornerElems.push_back(static_cast<std::int32_t>(e));
              cornerN.resize(cornerN.size() + kCornerSlots, Vec3::Zero());
            }
            cornerN[cornerN.size() - kCornerSlots + static_cast<std::size_t>(k)] = nk;
          }
        } else {
          faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | (1u << k));
        }
      }
    }
    // Linear triangles not standing across their surface at the start are held so
    // (kAcrossGuard, acrossArea).
    for (std::size_t e = 0; holdAcross && e < E; ++e) {
      if (m.elemType[e] != ElementType::Tri3) continue;
      const std::int32_t* nd = m.elementNodes(e);
      Vec3 corners[3];
      for (int k = 0; k < 3; ++k) corners[k] = cornerNormal(e, k);
      const Vec3 x[3] = {xyz[static_cast<std::size_t>(nd[0])], xyz[static_cast<std::size_t>(nd[1])],
                         xyz[static_cast<std::size_t>(nd[2])]};
      const Vec3 c = (x[1] - x[0]).cross(x[2] - x[0]);
      const double cn = c.norm();
      const CornerSides sides = cornerSides(ElementType::Tri3, x, corners);
      const bool along = sides.along, against = sides.against;
      int which;
      double slope;
      // Valid, not standing across and not leaning; or tangled (wound against every corner)
      // with a corner free on the face: untangling must not turn it over the top of the
      // surface into standing across. Not held: a tangled one whose corners all lie on CAD
      // edges, and any with a node sliding along a CAD edge — where the surface turns by more
      // than a right angle between two edges (BRepMesh's coarse blade edges), standing across
      // can be the only valid state there is, and sliding nodes reach it through their
      // elements.
      bool sliding = false;
      for (int k = 0; k < 3; ++k)
        sliding = sliding || m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Edge;
      const bool guard =
          !sliding &&
          (along ? !against && acrossArea(c, cn, corners, &which, &slope) == cn && which < 0
                 : against && (faceCorners[e] & 0x7u) != 0);
      if (cn > 0.0 && guard)
        faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | kAcrossGuard);
    }
    // High-order triangles and quad8 whose tangent plane at every corner is wound along the
    // surface's normal there are held so too: a move that turns the plane at a corner against
    // the normal (the curved element then leaves the surface at that corner, standing across
    // it, while the measure, which orients the element by the sum of its corner normals, can
    // still find it valid and well shaped) counts as tangling it. Not held: those with a
    // sliding node.
    for (std::size_t e = 0; holdAcross && e < E; ++e) {
      if (!heldCurved(m.elemType[e])) continue;
      const std::int32_t* nd = m.elementNodes(e);
      bool sliding = false;
      for (int k = 0; k < m.elementSize(e); ++k)
        sliding = sliding || m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Edge;
      Vec3 corners[kHeldSlots];
      for (int k = 0; k < heldNormalCount(e); ++k) corners[k] = heldNormal(e, k);
      const CornerSides sides = cornerSidesAt(e, -1, Vec3::Zero(), corners);
      if (!sliding && sides.along && !turnedAgainst(e, -1, Vec3::Zero(), corners))
        faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | kAcrossGuard);
    }
    if (anyEdge) {
      edgeSlot.assign(N, -1);
      for (std::size_t i = 0; i < N; ++i) {
        if (m.nodeKind[i] != NodeKind::Edge) continue;
        edgeSlot[i] = static_cast<std::int64_t>(edgeNormal.size());
        for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p) {
          const std::size_t e = static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)]);
          const int k = inc.local[static_cast<std::size_t>(p)];
          edgeNormal.push_back(k < cornerCount(m.elemType[e])
                                   ? m.referenceNormal(m.elemFace[e], m.elementUV(e)[k])
                                   : Vec3::Zero());
        }
      }
    }
    elemSize.assign(E, 1.0);
    eta0.assign(E, 1.0);
    minSigma.assign(E, 1.0);
  }

  std::int64_t begin(std::size_t i) const { return inc.offset[i]; }
  std::int64_t end(std::size_t i) const { return inc.offset[i + 1]; }

  /// Reference normal (any length) of element e with the corner normal of free node i (in this
  /// element) replaced by `nfree` (i < 0: the current normals). `oldFree` is the corner normal i
  /// had in e when i is an Edge node (it is part of fixedNormal), zero otherwise.
  Vec3 elementNormal(std::size_t e, std::int64_t i, const Vec3& nfree, const Vec3& oldFree) const {
    return usableNormal(e, rawNormal(e, i, nfree, oldFree));
  }

  /// elementNormal without the fallback for a zero sum.
  Vec3 rawNormal(std::size_t e, std::int64_t i, const Vec3& nfree, const Vec3& oldFree) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    const unsigned mask = faceCorners[e];
    Vec3 n = fixedNormal[e];
    for (int k = 0; k < nc; ++k) {
      const std::int32_t j = nd[k];
      if (j == i) {
        n += nfree - oldFree;
      } else if ((mask >> k) & 1u) {
        n += nodeNormal[static_cast<std::size_t>(j)];
      }
    }
    return n;
  }

  /// Not normalized: the element measures only use its direction (the sign of c·n, and n/‖n‖
  /// for degenerate elements). Corner normals that cancel give no direction (zero, as in
  /// elementReferenceNormal); all corners at a pole: the normal at the centroid.
  Vec3 usableNormal(std::size_t e, const Vec3& n) const {
    const double n2 = n.squaredNorm();
    if (n2 == 0.0) return elementReferenceNormal(mesh, e);
    if (n2 < kNormalCancelTol * kNormalCancelTol) return Vec3::Zero();
    return n;
  }

  double cornerScale(std::size_t e) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    double s = 0.0;
    for (int k = 0; k < nc; ++k) s += (xyz[nd[(k + 1) % nc]] - xyz[nd[k]]).squaredNorm();
    return s / nc;
  }

  /// Mean edge length of node i's submesh (from the frozen scales).
  double localSize(std::size_t i) const {
    double s = 0.0;
    const std::int64_t b = begin(i), en = end(i);
    for (std::int64_t p = b; p < en; ++p)
      s += elemSize[static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)])];
    return en > b ? s / static_cast<double>(en - b) : 0.0;
  }

  /// Element e's node positions, its node `local` at x (local < 0: every node where it is).
  void positions(std::size_t e, int local, const Vec3& x, Vec3* xs) const {
    const std::int32_t* nd = mesh.elementNodes(e);
    const int cnt = mesh.elementSize(e);
    for (int k = 0; k < cnt; ++k) xs[k] = (k == local) ? x : xyz[static_cast<std::size_t>(nd[k])];
  }

  /// cornerSides of high-order triangle e with its node `local` at x (local < 0: at the
  /// current positions) and corner normals `corners` (its corners' order).
  CornerSides cornerSidesAt(std::size_t e, int local, const Vec3& x, const Vec3* corners) const {
    Vec3 xs[kMaxElementNodes];
    positions(e, local, x, xs);
    return cornerSides(mesh.elemType[e], xs, corners);
  }

  /// Normals a held element is judged by (heldNormal): every node's for a high-order
  /// triangle, the corners' for a quad8.
  int heldNormalCount(std::size_t e) const {
    return isHighOrderTriangle(mesh.elemType[e]) ? mesh.elementSize(e)
                                                 : cornerCount(mesh.elemType[e]);
  }

  /// The surface's unit normal at node k of element e (zero at a pole): cornerNormal for a
  /// corner; a high-order node's own for a Face node, else at its (u,v) in e.
  Vec3 heldNormal(std::size_t e, int k) const {
    if (k < cornerCount(mesh.elemType[e])) return cornerNormal(e, k);
    const std::size_t j = static_cast<std::size_t>(mesh.elementNodes(e)[k]);
    if (mesh.nodeKind[j] == NodeKind::Face) return nodeNormal[j];
    return mesh.referenceNormal(mesh.elemFace[e], mesh.elementUV(e)[k]);
  }

  /// Whether element e, its node `local` at x (local < 0: at the current positions), with the
  /// normals `normals` (heldNormal's, in its nodes' order) has its tangent plane wound against
  /// the surface: a quad8 at a corner (cornerSides); a high-order triangle anywhere, as its
  /// Jacobian is not proven positive against the normals interpolated from its nodes
  /// (certifyTriangleAgainstNodeNormals; at the corners that is the corner test).
  bool turnedAgainst(std::size_t e, int local, const Vec3& x, const Vec3* normals) const {
    if (!isHighOrderTriangle(mesh.elemType[e])) return cornerSidesAt(e, local, x, normals).against;
    Vec3 xs[kMaxElementNodes];
    positions(e, local, x, xs);
    return certifyTriangleAgainstNodeNormals(elementOrder(mesh.elemType[e]), xs, normals).sign !=
           JacobianSign::Positive;
  }

  /// The Jacobians of high-order triangle e at its nodes and quadrature points without the
  /// term of its node `local` (see HighOrderJacobians), at the current positions.
  void highOrderRest(std::size_t e, int local, HighOrderJacobians* out) const {
    Vec3 xs[kMaxElementNodes];
    positions(e, -1, Vec3::Zero(), xs);
    highOrderJacobians(mesh.elemType[e], xs, local, out);
  }

  /// Element e with node `local` at x (others at their positions) and reference normal n.
  /// `pre`: for a high-order triangle, highOrderRest(e, local) when the other nodes have not
  /// moved since (a line search), or null.
  /// `corners`: a linear triangle's unit corner normals in the order (local, its next corner,
  /// its previous corner), see acrossArea; a high-order triangle's or quad8's held from
  /// standing across (guarded) in its corners' order: the element counts as tangled (held) when its
  /// tangent plane at a corner is wound against the normal there. Null: no hold.
  ElemOut evalElement(std::size_t e, int local, const Vec3& x, const Vec3& n, double delta,
                      bool wantEta0, Vec3* grad, Mat3* hess,
                      const HighOrderJacobians* pre = nullptr,
                      const Vec3* corners = nullptr) const {
    const std::int32_t* nd = mesh.elementNodes(e);
    if (mesh.elemType[e] == ElementType::Tri3) {
      const int k1 = local == 2 ? 0 : local + 1, k2 = local == 0 ? 2 : local - 1;
      return triangleKernel(measure, x, xyz[static_cast<std::size_t>(nd[k1])],
                            xyz[static_cast<std::size_t>(nd[k2])], n, delta, wantEta0, grad, hess,
                            relaxTangled, corners);
    }
    const Vec3 nu = n.normalized();
    double eta0 = kInf;  // η with δ = 0, from the same pass over the element
    ElementEval ev;
    if (pre) {
      ev = highOrderTriangleDistortion(measure, *pre, x, nu, delta, grad, hess,
                                       wantEta0 ? &eta0 : nullptr);
      if (!ev.tangled) {  // valid at the samples: the certificate, as elementDistortion's
        Vec3 xs[kMaxElementNodes];
        positions(e, local, x, xs);
        markUncertifiedFold(mesh.elemType[e], xs, nu, delta, &ev, grad, hess,
                            wantEta0 ? &eta0 : nullptr, &measure, local);
      }
    } else {
      Vec3 xs[kMaxElementNodes];
      positions(e, local, x, xs);
      ev = elementDistortion(measure, mesh.elemType[e], xs, nu, delta, local, grad, hess,
                             wantEta0 ? &eta0 : nullptr);
    }
    ElemOut r;
    r.eta = ev.eta;
    r.minSigma = ev.minSigma;
    r.tangled = ev.tangled;
    if (wantEta0) r.eta0 = (ev.tangled || !std::isfinite(eta0)) ? kInf : eta0;
    if (corners && !ev.tangled && std::isfinite(ev.eta)) {
      if (turnedAgainst(e, local, x, corners)) {
        // Held from standing across: the move tangles it (a node update rejects it), while
        // its cached η and det S stay the paper's, as the quality report measures them. (Not
        // `held`: a run left with tangled elements does not start again without the hold for
        // it — the node updates only refuse moves, the whole-mesh values and the escapes do
        // not see it.)
        r.tangled = true;
        if (delta == 0.0) r.eta = kInf;
      }
    }
    return r;
  }

  /// evalElement with the Hessian projected on the tangent basis T (as (h00, h01, h11)).
  ElemOut evalElementUV(std::size_t e, int local, const Vec3& x, const Vec3& n, double delta,
                        bool wantEta0, const Tangent& T, Vec3* grad, Vec3* hessUV,
                        const HighOrderJacobians* pre = nullptr,
                        const Vec3* corners = nullptr) const {
    if (mesh.elemType[e] == ElementType::Tri3) {
      const std::int32_t* nd = mesh.elementNodes(e);
      const int k1 = local == 2 ? 0 : local + 1, k2 = local == 0 ? 2 : local - 1;
      return triangleKernelUV(measure, x, xyz[static_cast<std::size_t>(nd[k1])],
                              xyz[static_cast<std::size_t>(nd[k2])], n, delta, wantEta0, T, grad,
                              hessUV, relaxTangled, corners);
    }
    Mat3 H;
    const ElemOut r = evalElement(e, local, x, n, delta, wantEta0, grad, &H, pre, corners);
    if (std::isfinite(r.eta)) {
      const Vec3 Hdu = H * T.du, Hdv = H * T.dv;
      *hessUV = Vec3(T.du.dot(Hdu), T.du.dot(Hdv), T.dv.dot(Hdv));
    }
    return r;
  }

  /// Whole-mesh element e at the current positions.
  ElemOut evalWhole(std::size_t e, double delta) const {
    const Vec3 n = elementNormal(e, -1, Vec3::Zero(), Vec3::Zero());
    const std::int32_t* nd = mesh.elementNodes(e);
    Vec3 corners[3];
    // (A high-order triangle is held by its node updates only: the whole-mesh values are the
    // paper's measure.)
    const bool tri = mesh.elemType[e] == ElementType::Tri3 && guarded(e);
    if (tri)
      for (int k = 0; k < 3; ++k) corners[k] = cornerNormal(e, k);
    return evalElement(e, 0, xyz[static_cast<std::size_t>(nd[0])], n, delta, true, nullptr, nullptr,
                       nullptr, tri ? corners : nullptr);
  }

  /// Whether element e is held from standing across its surface (acrossArea).
  bool guarded(std::size_t e) const { return (faceCorners[e] & kAcrossGuard) != 0; }

  /// The surface's unit normal at corner k of element e (zero at a pole): the node's own for a
  /// Face node, else the one kept in cornerN.
  const Vec3& cornerNormal(std::size_t e, int k) const {
    if ((faceCorners[e] >> k) & 1u)
      return nodeNormal[static_cast<std::size_t>(mesh.elementNodes(e)[k])];
    return cornerN[static_cast<std::size_t>(cornerSlot(e) + k)];
  }

  /// First index in cornerN of element e's corner normals (−1: e is not in cornerElems).
  std::int64_t cornerSlot(std::size_t e) const {
    const auto it =
        std::lower_bound(cornerElems.begin(), cornerElems.end(), static_cast<std::int32_t>(e));
    if (it == cornerElems.end() || *it != static_cast<std::int32_t>(e)) return -1;
    return kCornerSlots * static_cast<std::int64_t>(it - cornerElems.begin());
  }
};

/// Evaluation of a node's submesh at a candidate position.
struct LocalEval {
  double f = 0.0;           // Σ (η − 1)² with the sweep's δ
  int tangled = 0;          // elements with det S ≤ 0
  double minQuality = 1.0;  // min 1/η with δ = 0 (0 when tangled); when asked
  double maxEta = 1.0;      // largest η (sweep's δ) of the submesh
  bool finite = true;
  bool byQuality = false;         // a trial rejected (at least) for lowering minQuality
  Vec3 gradWorst = Vec3::Zero();  // ∂η/∂x of the element of minQuality (with g and quality)
};

/// Per-thread scratch (allocated once, sized by the largest node degree) and statistics,
/// padded to its own cache lines.
struct alignas(64) Worker {
  explicit Worker(const State& s) : geo(s.mesh) {
    eta0.resize(s.maxDegree);
    sig.resize(s.maxDegree);
    keptEta0.resize(s.maxDegree);
    keptSig.resize(s.maxDegree);
    normals.resize(s.maxDegree);
    baseNormal.resize(s.maxDegree);
    otherNormals.resize(2 * s.maxDegree);
    if (!s.allTri3) {
      cornerNormals.resize(kHeldSlots * s.maxDegree);
      holdHere.resize(s.maxDegree);
      highOrder.resize(s.maxDegree);
    }
  }
  ThreadGeometry geo;
  std::vector<double> eta0, sig;  // trial's per-element η(δ=0) and scaled det S
  // The same of the last accepted trial (swapped in by keepTrial: later trials of the same
  // update, rejected part way, overwrite eta0/sig).
  std::vector<double> keptEta0, keptSig;
  std::vector<Vec3> normals;     // trial's corner normals of a sliding node
  std::vector<Vec3> baseNormal;  // per incident element: its normal without the free corner
  // Per incident linear triangle: the corner normals of its two other corners (acrossArea).
  std::vector<Vec3> otherNormals;
  // Per incident held high-order triangle or quad8: its node normals (a quad8's corners only;
  // the free node's replaced at each trial), kHeldSlots each.
  std::vector<Vec3> cornerNormals;
  std::vector<unsigned char> holdHere;  // whether that triangle is held in this update
  // Per incident high-order triangle: its Jacobians without the free node's term.
  std::vector<HighOrderJacobians> highOrder;
  double maxRelMove = 0.0;
  std::size_t updated = 0, moved = 0;
  bool heldAcross = false;  // an evaluation of this worker held a triangle (acrossArea)
  char pad[64];
};

class NodeUpdater {
 public:
  NodeUpdater(State& s, Worker& w) : s_(s), w_(w) {}

  /// One safeguarded Newton step (with line search) on node i; returns the 3D move.
  double update(std::size_t i) {
    if (s_.mesh.nodeKind[i] == NodeKind::Face) return updateFaceNode(i);
    if (s_.mesh.nodeKind[i] == NodeKind::Edge) return updateEdgeNode(i);
    return 0.0;
  }

  /// Escape from a local minimum of the node-by-node sweep: a tangled element can be stuck
  /// when no single node can untangle it (e.g. a fan of thin triangles between two boundary
  /// nodes whose inner nodes have swapped their order: every node's kernel is empty while the
  /// others stay). For each tangled element (in the element cache) with a movable Face node,
  /// the Face nodes of its face within 0, 1, 2, 3 rings of it are relocated together to the
  /// harmonic (uniform Tutte) embedding in (u,v) of that patch with the nodes around it held —
  /// a valid embedding whenever the patch's outline is convex in (u,v). When that does not
  /// help (a non-convex outline; or thin elements valid in (u,v) but standing across a curved
  /// surface — a stacked fan of a coarse mesh between two CAD-edge nodes over 70° of a torus
  /// fillet), the patch is untangled jointly by relaxPatch, from the harmonic layout and from
  /// its current positions (with `relax`: the sweeps have left the number of tangled elements
  /// unchanged a few times in a row — a short stall usually ends by itself; an element whose
  /// patches failed is relaxed again only after State::RelaxBackoff's wait, at `sweep` ≥ its
  /// next sweep or at another `epsilonLevel`: the joint untangling costs up to hundreds of
  /// node updates per node, and a tangle no motion repairs would pay it at every stalled
  /// sweep until the run gives up — 48 of them by default). The smallest
  /// patch that leaves fewer tangled elements among all elements of the moved nodes is kept —
  /// strict progress, so it cannot cycle. Runs on one thread between sweeps, only while
  /// tangled elements stall; returns the number of elements untangled. Before the patches,
  /// with `relax`, the element's own nodes try a joint search (widenElement), except for the
  /// elements `held` marks (held folds and the like: no motion of theirs makes them valid).
  std::size_t escapeTangledElements(const std::vector<unsigned char>& frozen, bool relax, int sweep,
                                    int epsilonLevel, const std::vector<unsigned char>& held) {
    std::size_t gained = 0;
    std::vector<std::size_t> patch, elems;
    std::vector<Vec2> uvSave, iter;
    std::vector<Vec3> xyzSave, nSave;
    std::vector<std::int64_t> nbrOffset;
    std::vector<std::int32_t> nbrIndex;  // index in the patch, −1 for a held node
    std::vector<Vec2> nbrUV;             // held neighbours: their (u,v) next to the node's
    for (std::size_t e = 0; e < s_.mesh.elementCount(); ++e) {
      if (frozen[e] || s_.minSigma[e] > 0.0) continue;
      const int face = s_.mesh.elemFace[e];
      const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
      auto inPatch = [&](std::size_t j) {
        return std::find(patch.begin(), patch.end(), j) != patch.end();
      };
      auto movableHere = [&](std::size_t j) {
        return s_.mesh.nodeKind[j] == NodeKind::Face && s_.mesh.nodeFace[j] == face;
      };
      // Adds to `nodes` the Face nodes of this face of the elements around them (one ring).
      auto growRing = [&](std::vector<std::size_t>& nodes) {
        const std::size_t n0 = nodes.size();
        for (std::size_t q = 0; q < n0; ++q)
          for (std::int64_t p = s_.begin(nodes[q]); p < s_.end(nodes[q]); ++p) {
            const std::size_t f =
                static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
            const std::int32_t* fn = s_.mesh.elementNodes(f);
            for (int k = 0; k < s_.mesh.elementSize(f); ++k) {
              const std::size_t j = static_cast<std::size_t>(fn[k]);
              if (movableHere(j) && std::find(nodes.begin(), nodes.end(), j) == nodes.end())
                nodes.push_back(j);
            }
          }
      };
      patch.clear();
      const std::int32_t* nd = s_.mesh.elementNodes(e);
      for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        if (movableHere(j) && !inPatch(j)) patch.push_back(j);
      }
      if (patch.empty()) continue;
      auto backoff = s_.relaxBackoff.find(e);
      const bool relaxHere = relax && (backoff == s_.relaxBackoff.end() ||
                                       backoff->second.epsilonLevel != epsilonLevel ||
                                       sweep >= backoff->second.nextSweep);
      auto hBackoff = s_.harmonicBackoff.find(e);
      if (!relaxHere && hBackoff != s_.harmonicBackoff.end() && sweep < hBackoff->second.nextSweep)
        continue;
      bool kept = false, relaxed = false;
      auto wBackoff = s_.widenBackoff.find(e);
      if (relaxHere && !held[e] &&  // (a held element cannot become valid)
          (wBackoff == s_.widenBackoff.end() || sweep >= wBackoff->second.nextSweep)) {
        // e's own nodes, then with the Face nodes of the elements around them
        std::size_t g = widenElement(e, patch, face, surf);
        if (g == 0) {
          std::vector<std::size_t> wider = patch;
          growRing(wider);
          if (wider.size() > patch.size() && wider.size() <= kMaxWidenNodes)
            g = widenElement(e, wider, face, surf);
        }
        if (g > 0) {
          gained += g;
          kept = true;
          if (wBackoff != s_.widenBackoff.end()) s_.widenBackoff.erase(wBackoff);
        } else {
          s_.widenBackoff[e].failed(sweep, 1 << 20);  // retried after 1, 2, 4, 8… sweeps
        }
      }
      for (int ring = 0; ring <= 3 && !kept; ++ring) {
        if (ring > 0) {  // grow by one ring of Face nodes of this face
          const std::size_t n0 = patch.size();
          growRing(patch);
          if (patch.size() == n0 || patch.size() > 256) break;
        }
        elementsAround(patch, &elems);
        auto countTangled = [&]() { return tangledAmong(elems); };
        const std::size_t t0 = countTangled();
        if (t0 == 0) continue;  // nothing to gain here (the cache is from the last sweep)
        // Neighbour lists of the patch nodes (corners of their elements).
        nbrOffset.assign(1, 0);
        nbrIndex.clear();
        nbrUV.clear();
        for (std::size_t j : patch) {
          for (std::int64_t p = s_.begin(j); p < s_.end(j); ++p) {
            const std::size_t f =
                static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
            const std::int32_t* fn = s_.mesh.elementNodes(f);
            for (int k = 0; k < cornerCount(s_.mesh.elemType[f]); ++k) {
              const std::size_t o = static_cast<std::size_t>(fn[k]);
              if (o == j) continue;
              const auto it = std::find(patch.begin(), patch.end(), o);
              nbrIndex.push_back(it == patch.end() ? -1
                                                   : static_cast<std::int32_t>(it - patch.begin()));
              nbrUV.push_back(cornerOnFace(f, k, face, surf, s_.uv[j]));
            }
          }
          nbrOffset.push_back(static_cast<std::int64_t>(nbrIndex.size()));
        }
        // Gauss–Seidel on the uniform Laplacian of the patch (its outline held).
        iter.clear();
        for (std::size_t j : patch) iter.push_back(s_.uv[j]);
        for (int sweep = 0; sweep < 200; ++sweep) {
          double change = 0.0;
          for (std::size_t q = 0; q < patch.size(); ++q) {
            Vec2 c = Vec2::Zero();
            const std::int64_t b0 = nbrOffset[q], b1 = nbrOffset[q + 1];
            for (std::int64_t r = b0; r < b1; ++r) {
              const std::int32_t o = nbrIndex[static_cast<std::size_t>(r)];
              c += o < 0 ? nbrUV[static_cast<std::size_t>(r)]
                         : surf.unwrapNear(iter[static_cast<std::size_t>(o)], iter[q]);
            }
            if (b1 > b0) {
              c /= static_cast<double>(b1 - b0);
              change = std::max(change, (c - iter[q]).lpNorm<Eigen::Infinity>());
              iter[q] = c;
            }
          }
          if (change == 0.0) break;
        }
        straightSides(patch, face, surf, &iter);
        // Place, count, keep or put back.
        save(patch, &uvSave, &xyzSave, &nSave);
        const bool ok = placeAll(patch, iter, face, surf);
        const std::size_t t1 = ok ? countTangled() : t0;
        if (ok && t1 < t0) {
          kept = true;
          gained += t0 - t1;
          continue;
        }
        // The harmonic layout did not help (a non-convex outline in (u,v), or elements valid
        // in (u,v) but not on the surface): untangle the patch by local Newton steps on f̂
        // that may pass through tangled states, from the input positions and from the
        // harmonic layout when it was placeable.
        std::size_t t2 = t0;
        if (!relaxHere || patch.size() > kMaxRelaxPatchNodes) {
          restore(patch, uvSave, xyzSave, nSave);
          continue;
        }
        if (ok && relaxTries_ < kMaxRelaxPatches) {
          ++relaxTries_;
          relaxed = true;
          t2 = relaxPatch(patch, countTangled, t0);
          if (t2 < t0) {
            kept = true;
            gained += t0 - t2;
            continue;
          }
        }
        restore(patch, uvSave, xyzSave, nSave);
        if (relaxTries_ < kMaxRelaxPatches) {
          ++relaxTries_;
          relaxed = true;
          t2 = relaxPatch(patch, countTangled, t0);
          if (t2 < t0) {
            kept = true;
            gained += t0 - t2;
            continue;
          }
          restore(patch, uvSave, xyzSave, nSave);
        }
      }
      // Last: each Face node of the element alone, at the best point of a grid over its
      // neighbours (sampleNeighbourhood).
      for (int k = 0; k < s_.mesh.elementSize(e) && !kept; ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        if (!movableHere(j)) continue;
        const std::size_t g = sampleNeighbourhood(j, face, surf);
        if (g > 0) {
          kept = true;
          gained += g;
        }
      }
      // Then, with the joint untangling allowed: a Face node of the element where the element
      // is valid (sampleNeighbourhood), the other Face nodes of its elements untangled around
      // it (relaxPatch), kept when fewer elements around them all are tangled.
      for (int k = 0; k < s_.mesh.elementSize(e) && !kept && relaxHere; ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        Vec2 target;
        if (!movableHere(j) || relaxTries_ >= kMaxRelaxPatches ||
            !sampleNeighbourhood(j, face, surf, static_cast<std::int64_t>(e), &target))
          continue;
        patch.assign(1, j);
        growRing(patch);
        if (patch.size() == 1 || patch.size() - 1 > kMaxRelaxPatchNodes) continue;
        std::rotate(patch.begin(), patch.begin() + 1, patch.end());  // j last
        elementsAround(patch, &elems);
        auto countTangled = [&]() { return tangledAmong(elems); };
        const std::size_t t0 = countTangled();
        save(patch, &uvSave, &xyzSave, &nSave);
        patch.pop_back();  // j stays at the target
        ++relaxTries_;
        relaxed = true;
        const std::size_t t1 =
            placeAll({j}, {target}, face, surf) ? relaxPatch(patch, countTangled, t0) : t0;
        patch.push_back(j);
        if (t1 < t0) {
          kept = true;
          gained += t0 - t1;
        } else {
          restore(patch, uvSave, xyzSave, nSave);
        }
      }
      if (kept && backoff != s_.relaxBackoff.end()) s_.relaxBackoff.erase(backoff);
      if (kept && hBackoff != s_.harmonicBackoff.end()) s_.harmonicBackoff.erase(hBackoff);
      if (!kept && !relaxed) s_.harmonicBackoff[e].failed(sweep, s_.opt.deltaStallSweeps);
      if (relaxed) ++s_.patchUntanglings;
      if (!kept && relaxed) {
        State::RelaxBackoff& b = s_.relaxBackoff[e];
        b.failed(sweep, s_.opt.deltaStallSweeps);
        b.epsilonLevel = epsilonLevel;
      }
    }
    return gained;
  }

  /// Straightens tangled high-order triangles and quad8 in (u,v): a curved element whose
  /// corner triangle (quad8: each corner's triangle of its corner quadrilateral) is valid but
  /// whose edge or interior nodes fold it (a mesher's second-order nodes projected across a
  /// thin or strongly curved face) gets its movable edge and interior nodes — Face nodes of the
  /// element's face — at the parametric interpolation of its corners (straight sides in (u,v),
  /// as the paper's initial high-order meshes; a quad8's side node at its side's midpoint).
  /// Kept only when fewer elements around the moved nodes are tangled than before — strict
  /// progress, like every escape. Returns the number of elements untangled.
  /// With `cached`, only the elements the element cache holds tangled are looked at.
  std::size_t straightenHighOrder(const std::vector<unsigned char>& frozen, bool cached) {
    std::size_t gained = 0;
    std::vector<std::size_t> moved, elems;
    std::vector<Vec2> uvSave, target;
    std::vector<Vec3> xyzSave, nSave;
    for (std::size_t e = 0; e < s_.mesh.elementCount(); ++e) {
      const ElementType type = s_.mesh.elemType[e];
      if (frozen[e] || !heldCurved(type)) continue;
      if ((cached && s_.minSigma[e] > 0.0) || !s_.evalWhole(e, 0.0).tangled) continue;
      const int face = s_.mesh.elemFace[e];
      const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
      const std::int32_t* nd = s_.mesh.elementNodes(e);
      const int nc = cornerCount(type);
      const Vec3 n = s_.elementNormal(e, -1, Vec3::Zero(), Vec3::Zero());
      // The corners first: a triangle's one corner triangle, each corner's of a quad.
      const int cornerTriangles = nc == 3 ? 1 : nc;
      bool cornersTangled = false;
      for (int k = 0; k < cornerTriangles && !cornersTangled; ++k) {
        const Vec3& xk = s_.xyz[static_cast<std::size_t>(nd[k])];
        Jacobian32 J;
        J.col(0) = s_.xyz[static_cast<std::size_t>(nd[(k + 1) % nc])] - xk;
        J.col(1) = s_.xyz[static_cast<std::size_t>(nd[(k + nc - 1) % nc])] - xk;
        cornersTangled = jacobianValidity(J, equilateralWinv(), n).tangled;
      }
      if (cornersTangled) continue;
      Vec2 c[4];
      c[0] = cornerOnFace(e, 0, face, surf,
                          s_.mesh.cornerUV[static_cast<std::size_t>(s_.mesh.elemOffset[e])]);
      for (int k = 1; k < nc; ++k) c[k] = cornerOnFace(e, k, face, surf, c[0]);
      moved.clear();
      target.clear();
      bool ok = true;
      for (int k = nc; k < s_.mesh.elementSize(e) && ok; ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        if (s_.mesh.nodeKind[j] != NodeKind::Face || s_.mesh.nodeFace[j] != face) continue;
        const Vec2 t = surf.wrap(straightPlace(type, k, c));
        ok = t.allFinite() && surf.containsNearBoundary(t.x(), t.y());
        moved.push_back(j);
        target.push_back(t);
      }
      if (!ok || moved.empty()) continue;
      elementsAround(moved, &elems);
      const std::size_t t0 = tangledAmong(elems);
      save(moved, &uvSave, &xyzSave, &nSave);
      const std::size_t t1 = placeAll(moved, target, face, surf) ? tangledAmong(elems) : t0;
      if (t1 < t0)
        gained += t0 - t1;
      else
        restore(moved, uvSave, xyzSave, nSave);
    }
    s_.straightened += gained;
    return gained;
  }

  /// Escape for one tangled element e whose movable nodes (`nodes`: its Face nodes on `face`)
  /// must move together: a second-order triangle with its base on a CAD edge and its apex and
  /// two side nodes inside a narrow face untangles only when the apex and both side nodes move
  /// at once, which neither the node-by-node steps nor the harmonic layout (a non-convex
  /// outline) nor the joint Newton steps on f̂ (whose δ-regularized merit may prefer a fold)
  /// find. A compass search in (u,v) over those nodes raises the smallest scaled det S over e
  /// and the valid elements around them (the validity the sweeps weigh, without the measure)
  /// until it is positive, from their positions and perturbations of them (a fixed sequence
  /// per element: the result does not depend on threads); kept only when fewer of the elements
  /// around the nodes stay tangled — strict progress, like every escape. Returns the number of
  /// elements untangled. escapeTangledElements tries e's own nodes, then those with the Face
  /// nodes of the elements around them (a neighbour in the way must give room).
  std::size_t widenElement(std::size_t e, const std::vector<std::size_t>& nodes, int face,
                           const Surface& surf) {
    std::vector<std::size_t> elems, watch;
    elementsAround(nodes, &elems);
    const std::size_t t0 = tangledAmong(elems);
    if (t0 == 0) return 0;
    watch.push_back(e);  // e and the valid elements around it: none may fold
    for (std::size_t q : elems)
      if (q != e && !s_.evalWhole(q, 0.0).tangled) watch.push_back(q);
    // Their smallest det S, kept per element: a trial move of one node evaluates only the
    // watched elements of that node (aff).
    std::vector<double> sig(watch.size());
    std::vector<std::vector<std::size_t>> aff(nodes.size());
    for (std::size_t q = 0; q < nodes.size(); ++q)
      for (std::int64_t p = s_.begin(nodes[q]); p < s_.end(nodes[q]); ++p) {
        const auto f = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
        const auto it = std::find(watch.begin(), watch.end(), f);
        if (it != watch.end()) aff[q].push_back(static_cast<std::size_t>(it - watch.begin()));
      }
    auto minSig = [&]() {
      double o = kInf;
      for (double v : sig) o = std::min(o, v);
      return o;
    };
    auto objective = [&]() {
      for (std::size_t w = 0; w < watch.size(); ++w) sig[w] = s_.evalWhole(watch[w], 0.0).minSigma;
      return minSig();
    };
    std::vector<double> sigSave;
    // Initial step: half the extent in (u,v) of e's corners.
    const Vec2 c0 = cornerOnFace(e, 0, face, surf, s_.mesh.elementUV(e)[0]);
    Vec2 lo = c0, hi = c0;
    for (int k = 1; k < cornerCount(s_.mesh.elemType[e]); ++k) {
      const Vec2 ck = cornerOnFace(e, k, face, surf, c0);
      lo = lo.cwiseMin(ck);
      hi = hi.cwiseMax(ck);
    }
    Vec2 h0 = 0.5 * (hi - lo);
    if (!(h0.maxCoeff() > 0.0) || !h0.allFinite()) return 0;
    h0 = h0.cwiseMax(Vec2::Constant(1e-3 * h0.maxCoeff()));
    std::vector<Vec2> uvSave, best, one(1);
    std::vector<Vec3> xyzSave, nSave;
    std::vector<std::size_t> single(1);
    save(nodes, &uvSave, &xyzSave, &nSave);
    const double o0 = objective();
    double bestO = o0;
    auto placeOne = [&](std::size_t j, const Vec2& uv) {
      single[0] = j;
      one[0] = uv;
      return placeAll(single, one, face, surf);
    };
    static const Vec2 kDirs[8] = {{1, 0}, {-1, 0},  {0, 1},  {0, -1},
                                  {1, 1}, {-1, -1}, {1, -1}, {-1, 1}};
    std::uint64_t seed = 0x9e3779b97f4a7c15ull * (e + 1);
    auto unit = [&]() {  // in [−1, 1), a fixed sequence per element
      seed ^= seed << 13;
      seed ^= seed >> 7;
      seed ^= seed << 17;
      return static_cast<double>(seed >> 11) * (2.0 / 9007199254740992.0) - 1.0;
    };
    for (int start = 0; start < kWidenStarts && !(bestO > 0.0); ++start) {
      if (start > 0) {
        restore(nodes, uvSave, xyzSave, nSave);
        const double r = start % 2 ? 0.5 : 1.5;
        for (std::size_t q = 0; q < nodes.size(); ++q)
          placeOne(nodes[q], uvSave[q] + r * Vec2(unit() * h0.x(), unit() * h0.y()));
      }
      double o = objective();
      Vec2 h = h0;
      // Until e and its neighbours are valid (the sweeps then smooth them), or the step is
      // 1e-4 of the first.
      for (int it = 0; it < 60 && !(o > 0.0) && h.x() > 1e-4 * h0.x(); ++it) {
        bool moved = false;
        for (std::size_t q = 0; q < nodes.size(); ++q)
          for (const Vec2& d : kDirs) {
            const std::size_t j = nodes[q];
            const Vec2 old = s_.uv[j];
            if (!placeOne(j, old + Vec2(d.x() * h.x(), d.y() * h.y()))) continue;
            sigSave.clear();
            for (std::size_t w : aff[q]) {
              sigSave.push_back(sig[w]);
              sig[w] = s_.evalWhole(watch[w], 0.0).minSigma;
            }
            const double o1 = minSig();
            if (o1 > o) {
              o = o1;
              moved = true;
            } else {
              placeOne(j, old);
              for (std::size_t k = 0; k < aff[q].size(); ++k) sig[aff[q][k]] = sigSave[k];
            }
          }
        if (!moved) h *= 0.5;
      }
      if (o > bestO) {
        bestO = o;
        best.clear();
        for (std::size_t j : nodes) best.push_back(s_.uv[j]);
      }
    }
    restore(nodes, uvSave, xyzSave, nSave);
    if (best.empty() || !placeAll(nodes, best, face, surf)) {
      restore(nodes, uvSave, xyzSave, nSave);
      return 0;
    }
    const std::size_t t1 = tangledAmong(elems);
    if (t1 < t0) return t0 - t1;
    restore(nodes, uvSave, xyzSave, nSave);
    return 0;
  }

  /// The harmonic layout of escapeTangledElements is of the corners (a node's neighbours are
  /// the corners of its elements). A side or interior node of a high-order triangle or a
  /// quad8 in `patch` (no element's corner) goes instead to its place on straight sides in
  /// (u,v) between its element's corners (straightPlace), as laid out in `uv` (the patch's
  /// corners) or where they are: the average of the corners of a side's two elements would
  /// bend that side towards one of them (a second-order element with a Face corner and two
  /// Face side nodes between two nodes on a CAD edge stayed folded after every harmonic
  /// layout).
  void straightSides(const std::vector<std::size_t>& patch, int face, const Surface& surf,
                     std::vector<Vec2>* uv) const {
    for (std::size_t q = 0; q < patch.size(); ++q) {
      const std::size_t j = patch[q];
      if (s_.begin(j) == s_.end(j)) continue;
      const std::size_t p0 = static_cast<std::size_t>(s_.begin(j));
      const std::size_t f = static_cast<std::size_t>(s_.inc.elem[p0]);
      const int local = s_.inc.local[p0];
      const ElementType type = s_.mesh.elemType[f];
      const int nc = cornerCount(type);
      if (!heldCurved(type) || local < nc) continue;
      const Vec2 ref = (*uv)[q];
      Vec2 c[4];
      for (int k = 0; k < nc; ++k) {
        const std::size_t o = static_cast<std::size_t>(s_.mesh.elementNodes(f)[k]);
        const auto it = std::find(patch.begin(), patch.end(), o);
        c[k] = it == patch.end()
                   ? cornerOnFace(f, k, face, surf, ref)
                   : surf.unwrapNear((*uv)[static_cast<std::size_t>(it - patch.begin())], ref);
      }
      (*uv)[q] = straightPlace(type, local, c);
    }
  }

  /// Patch untangling budget of one escape (per element and ring at most two attempts), and
  /// the largest patch it untangles (at most 60 sweeps over its nodes per attempt).
  static constexpr int kMaxRelaxPatches = 48;
  static constexpr std::size_t kMaxRelaxPatchNodes = 96;
  /// Starts of widenElement's search (its nodes' positions, then perturbations of them).
  static constexpr int kWidenStarts = 16;
  /// Most nodes widenElement moves (e's and one ring around them).
  static constexpr std::size_t kMaxWidenNodes = 24;

 private:
  int relaxTries_ = 0;

  /// The elements around `nodes`, sorted and without repeats.
  void elementsAround(const std::vector<std::size_t>& nodes,
                      std::vector<std::size_t>* elems) const {
    elems->clear();
    for (std::size_t j : nodes)
      for (std::int64_t p = s_.begin(j); p < s_.end(j); ++p)
        elems->push_back(static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]));
    std::sort(elems->begin(), elems->end());
    elems->erase(std::unique(elems->begin(), elems->end()), elems->end());
  }

  /// How many of `elems` are tangled at the current positions (δ = 0).
  std::size_t tangledAmong(const std::vector<std::size_t>& elems) const {
    std::size_t t = 0;
    for (std::size_t q : elems)
      if (s_.evalWhole(q, 0.0).tangled) ++t;
    return t;
  }

  void save(const std::vector<std::size_t>& nodes, std::vector<Vec2>* uv, std::vector<Vec3>* xyz,
            std::vector<Vec3>* normal) const {
    uv->clear();
    xyz->clear();
    normal->clear();
    for (std::size_t j : nodes) {
      uv->push_back(s_.uv[j]);
      xyz->push_back(s_.xyz[j]);
      normal->push_back(s_.nodeNormal[j]);
    }
  }

  /// Puts Face nodes `nodes` of `face` at the (wrapped) parameters `uv`: position, parameters
  /// and reference normal. False (some already placed) when a parameter is outside the
  /// trimmed face or at a degenerate point.
  bool placeAll(const std::vector<std::size_t>& nodes, const std::vector<Vec2>& uv, int face,
                const Surface& surf) {
    const double orient = static_cast<double>(
        s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
    for (std::size_t q = 0; q < nodes.size(); ++q) {
      const Vec2 w = surf.wrap(uv[q]);
      if (!w.allFinite() || !surf.containsNearBoundary(w.x(), w.y())) return false;
      const SurfaceD1 d = surf.d1(w.x(), w.y());
      if (isDegenerate(d)) return false;
      const std::size_t j = nodes[q];
      s_.uv[j] = w;
      s_.xyz[j] = d.p;
      const Vec3 c = d.du.cross(d.dv);
      s_.nodeNormal[j] = (orient / c.norm()) * c;
      s_.d2Valid[j] = 0;
    }
    return true;
  }

  void restore(const std::vector<std::size_t>& patch, const std::vector<Vec2>& uvSave,
               const std::vector<Vec3>& xyzSave, const std::vector<Vec3>& nSave) {
    for (std::size_t q = 0; q < patch.size(); ++q) {
      s_.uv[patch[q]] = uvSave[q];
      s_.xyz[patch[q]] = xyzSave[q];
      s_.nodeNormal[patch[q]] = nSave[q];
      s_.d2Valid[patch[q]] = 0;
    }
  }

  /// Untangles a stuck patch of Face nodes (the rest of the mesh held) by Gauss–Seidel sweeps
  /// of the local Newton steps over its nodes, with a node's move allowed to tangle elements
  /// of its submesh as long as f̂ decreases — as the paper's untangling, which the sweep's
  /// safeguard (never more tangled elements around a node) forbids. Linear triangles use the
  /// σ of their projection on the reference normal meanwhile: continuous across a triangle
  /// standing on its edge across a curved surface (where ±‖c‖ jumps, so that the barrier is
  /// invisible to the Newton steps). δ̂ follows a continuation 4, 1, 1/4, 1/16 × the sweep's,
  /// 15 sweeps each. Leaves the patch at the stage with the fewest tangled elements among
  /// `countTangled`'s (by the sweep's rule) and returns that count (`t0`, positions left as
  /// they are, when no stage beats it).
  template <class Count>
  std::size_t relaxPatch(const std::vector<std::size_t>& patch, Count& countTangled,
                         std::size_t t0) {
    const double deltaHat = s_.deltaHat;
    const bool track = s_.trackCache;
    s_.trackCache = false;
    s_.relaxTangled = true;
    std::size_t best = t0;
    std::vector<Vec2> uvBest;
    std::vector<Vec3> xyzBest, nBest;
    const double dMin = std::max(deltaHat, 1e-4);
    for (double dh = 4.0 * dMin; dh >= dMin / 20.0; dh *= 0.25) {  // 4, 1, 1/4, 1/16 × δ̂
      s_.deltaHat = dh;
      for (int sweep = 0; sweep < 15; ++sweep) {
        double mv = 0.0;
        for (std::size_t j : patch) mv += update(j);
        if (mv == 0.0) break;
      }
      s_.relaxTangled = false;  // count with the sweep's rule
      const std::size_t t = countTangled();
      s_.relaxTangled = true;
      if (t < best) {
        best = t;
        uvBest.clear();
        xyzBest.clear();
        nBest.clear();
        for (std::size_t j : patch) {
          uvBest.push_back(s_.uv[j]);
          xyzBest.push_back(s_.xyz[j]);
          nBest.push_back(s_.nodeNormal[j]);
        }
        if (t == 0) break;
      }
    }
    s_.relaxTangled = false;
    s_.deltaHat = deltaHat;
    s_.trackCache = track;
    if (best < t0) restore(patch, uvBest, xyzBest, nBest);
    return best;
  }

 public:
 private:
  State& s_;
  Worker& w_;

  /// Submesh of node i with the node at x. `nfree(j)` gives the node's corner normal in the
  /// j-th incident element, `old(j)` its normal there before the move (Edge nodes).
  /// With derivatives when g/H are non-null. A trial (`cur` non-null) stops as soon as it
  /// cannot be accepted against `cur`; its per-element values land in the worker's scratch.
  /// With a tangent basis `T` (and `HUV` non-null) the Hessian is accumulated projected on it,
  /// as (h00, h01, h11), instead of in H.
  template <class NFree, class NOld>
  LocalEval evalLocal(std::size_t i, const Vec3& x, NFree nfree, NOld old, bool wantQuality,
                      const LocalEval* cur, Vec3* g, Mat3* H, const Tangent* T = nullptr,
                      Vec3* HUV = nullptr) {
    LocalEval r;
    if (g) g->setZero();
    if (H) H->setZero();
    if (HUV) HUV->setZero();
    const std::int64_t b = s_.begin(i), en = s_.end(i);
    const bool needEta0 = wantQuality || (cur && s_.trackCache);
    Vec3* base = w_.baseNormal.data();
    for (std::int64_t p = b; p < en; ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int local = s_.inc.local[static_cast<std::size_t>(p)];
      const std::size_t j = static_cast<std::size_t>(p - b);
      const bool corner = local < cornerCount(s_.mesh.elemType[e]);
      // The element's normal without the free node's corner: the same for every trial of
      // this update (the nodes of one color share no element), so trials reuse it.
      if (!cur)
        base[j] = corner ? s_.rawNormal(e, static_cast<std::int64_t>(i), Vec3::Zero(), old(j))
                         : s_.rawNormal(e, -1, Vec3::Zero(), Vec3::Zero());
      const Vec3 nref = s_.usableNormal(e, corner ? Vec3(base[j] + nfree(j)) : base[j]);
      // A linear triangle's corner normals (acrossArea): the free node's, then its next and
      // previous corners' (the same for every trial of this update).
      bool guarded = s_.guarded(e);
      const bool tri = s_.mesh.elemType[e] == ElementType::Tri3 && guarded;
      Vec3 corners[kHeldSlots];
      if (tri) {
        Vec3* other = w_.otherNormals.data() + 2 * j;
        if (!cur) {
          other[0] = s_.cornerNormal(e, local == 2 ? 0 : local + 1);
          other[1] = s_.cornerNormal(e, local == 0 ? 2 : local - 1);
        }
        corners[0] = nfree(j);
        corners[1] = other[0];
        corners[2] = other[1];
      } else if (guarded) {
        // A held high-order triangle's or quad8's corner normals in its corners' order, the
        // free node's (when a corner) at the trial. Not held in this update when it stands
        // across already (an escape's joint move may leave it so): its nodes stay free to move.
        const int nc = s_.heldNormalCount(e);
        Vec3* kept = w_.cornerNormals.data() + kHeldSlots * j;
        if (!cur)
          for (int k = 0; k < nc; ++k) kept[k] = s_.heldNormal(e, k);
        for (int k = 0; k < nc; ++k) corners[k] = k == local ? nfree(j) : kept[k];
        if (!cur) w_.holdHere[j] = !s_.turnedAgainst(e, -1, Vec3::Zero(), corners);
        guarded = w_.holdHere[j] != 0;
      }
      // A high-order triangle's Jacobians without the free node's term: the same for every
      // trial of this update too.
      HighOrderJacobians* pre = nullptr;
      if (isHighOrderTriangle(s_.mesh.elemType[e])) {
        pre = &w_.highOrder[j];
        if (!cur) s_.highOrderRest(e, local, pre);
      }
      const double delta = s_.deltaHat * s_.deltaScale[e];
      Vec3 ge;
      Mat3 He;
      Vec3 heUV = Vec3::Zero();
      const ElemOut ev = HUV ? s_.evalElementUV(e, local, x, nref, delta, needEta0, *T, &ge, &heUV,
                                                pre, guarded ? corners : nullptr)
                             : s_.evalElement(e, local, x, nref, delta, needEta0, g ? &ge : nullptr,
                                              H ? &He : nullptr, pre, guarded ? corners : nullptr);
      if (cur) {
        w_.eta0[j] = ev.eta0;
        w_.sig[j] = ev.minSigma;
      }
      if (ev.held) w_.heldAcross = true;
      if (ev.tangled) {
        ++r.tangled;
        if (cur && r.tangled > cur->tangled && !s_.relaxTangled) return reject();
      }
      if (!std::isfinite(ev.eta)) {
        r.finite = false;
        r.f = kInf;
        if (cur) return reject();
        continue;
      }
      const double d = ev.eta - 1.0;
      r.f += d * d;
      r.maxEta = std::max(r.maxEta, ev.eta);
      if (cur && !(r.f < cur->f)) return reject();
      if (g) *g += 2.0 * d * ge;
      if (H) *H += 2.0 * (ge * ge.transpose() + d * He);
      if (HUV) {
        const Vec2 gu(T->du.dot(ge), T->dv.dot(ge));
        *HUV += 2.0 * (Vec3(gu.x() * gu.x(), gu.x() * gu.y(), gu.y() * gu.y()) + d * heUV);
      }
      if (wantQuality) {
        const double q = (ev.tangled || !std::isfinite(ev.eta0)) ? 0.0 : 1.0 / ev.eta0;
        if (q < r.minQuality) {
          r.minQuality = q;
          if (g) r.gradWorst = ge;
        }
        if (cur && q < qualityBar(*cur)) {
          LocalEval rq = reject();
          rq.byQuality = true;
          return rq;
        }
      }
    }
    return r;
  }

  static LocalEval reject() {
    LocalEval r;
    r.finite = false;
    r.f = kInf;
    return r;
  }

  /// Acceptance test of a complete trial against the current state.
  bool acceptable(const LocalEval& cur, const LocalEval& trial) const {
    if (!trial.finite) return false;
    if (trial.tangled > cur.tangled && !s_.relaxTangled) return false;
    if (!(trial.f < cur.f)) return false;
    if (s_.opt.monotone && cur.tangled == 0 && trial.minQuality < qualityBar(cur)) return false;
    return true;
  }

  /// Monotone mode: the least minimum quality of a valid submesh a move may leave — its
  /// current minimum or, when lower, the sweep's quality floor (the mesh's minimum over the
  /// elements with a movable node): no element falls below the mesh's minimum.
  double qualityBar(const LocalEval& cur) const {
    return std::min(cur.minQuality, s_.qualityFloor);
  }

  /// Keeps the element values of the trial just evaluated (and accepted) for commitElements.
  void keepTrial() {
    w_.eta0.swap(w_.keptEta0);
    w_.sig.swap(w_.keptSig);
  }

  /// Records the kept trial's element values (δ = 0 sweeps keep the cache current).
  void commitElements(std::size_t i) {
    if (!s_.trackCache) return;
    const std::int64_t b = s_.begin(i), en = s_.end(i);
    for (std::int64_t p = b; p < en; ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      s_.eta0[e] = w_.keptEta0[static_cast<std::size_t>(p - b)];
      s_.minSigma[e] = w_.keptSig[static_cast<std::size_t>(p - b)];
    }
  }

  /// Whether a smoothing sweep (δ = 0) may try ω × a step of 3D length len3 at a node of local
  /// size L (see OptimizeOptions::overRelaxation): it must stay within L.
  bool overRelaxes(double len3, double L) const {
    const double omega = s_.opt.overRelaxation;
    return omega > 1.0 && s_.deltaHat == 0.0 && omega * len3 <= L;
  }

  /// The line search's step factor at trial ls: ω at ls = −1 (an over-relaxed first trial),
  /// then 1, ½, ¼, …
  double stepFactor(int ls) const { return ls < 0 ? s_.opt.overRelaxation : std::ldexp(1.0, -ls); }

  /// Whether step b goes on the way step a went: the angle between them, measured in the
  /// surface's metric G, is below 60° (a zero step goes no way).
  static bool sameWay(const Vec2& a, const Vec2& b, const Mat2& G) {
    const double aa = a.dot(G * a), bb = b.dot(G * b);
    return aa > 0.0 && bb > 0.0 && a.dot(G * b) > 0.5 * std::sqrt(aa * bb);
  }

  double updateFaceNode(std::size_t i) {
    const int face = s_.mesh.nodeFace[i];
    const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
    if (s_.end(i) == s_.begin(i)) return 0.0;
    const double L = s_.localSize(i);
    if (!(L > 0.0)) return 0.0;
    const double orient = static_cast<double>(
        s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
    const bool monotone = s_.opt.monotone;
    auto zero = [](std::size_t) { return Vec3::Zero().eval(); };
    double moved = 0.0;
    for (int it = 0; it < s_.opt.innerIterations; ++it) {
      const Vec2 uv0 = s_.uv[i];
      if (!s_.d2Valid[i]) {
        const SurfaceD2 d = surf.d2(uv0.x(), uv0.y());
        s_.d2[i] = {d.du, d.dv, d.duu, d.duv, d.dvv};
        s_.d2Valid[i] = 1;
      }
      const NodeD2& d = s_.d2[i];
      if (isDegenerate(d.du, d.dv)) return moved;  // a pole: stays fixed
      const Vec3 n0 = s_.nodeNormal[i];
      Tangent T;
      T.du = d.du;
      T.dv = d.dv;
      T.metric(0, 0) = d.du.squaredNorm();
      T.metric(0, 1) = T.metric(1, 0) = d.du.dot(d.dv);
      T.metric(1, 1) = d.dv.squaredNorm();
      Vec3 gx, hJ;
      const Vec3 x0 = s_.xyz[i];
      const LocalEval cur = evalLocal(
          i, x0, [&](std::size_t) { return n0; }, zero, monotone, nullptr, &gx, nullptr, &T, &hJ);
      if (!cur.finite || cur.f == 0.0) return moved;
      // Chain rule to (u,v): g_u = Jᵀ g, H_u = Jᵀ H J + Σ g·∇²φ (JᵀHJ assembled in evalLocal).
      const Vec2 gu(d.du.dot(gx), d.dv.dot(gx));
      Mat2 Hu;
      Hu(0, 0) = hJ.x() + gx.dot(d.duu);
      Hu(0, 1) = Hu(1, 0) = hJ.y() + gx.dot(d.duv);
      Hu(1, 1) = hJ.z() + gx.dot(d.dvv);
      if (!gu.allFinite() || !Hu.allFinite()) return moved;
      Vec2 dir = newtonDirection(gu, Hu);
      if (gu.dot(dir) >= 0.0) dir = -gu;  // not a descent direction: use the gradient
      // Cap the step so that its first-order 3D length is at most the local size.
      double len3 = (d.du * dir.x() + d.dv * dir.y()).norm();
      if (len3 > L) {
        dir *= L / len3;
        len3 = L;
      }
      const bool wantQ = monotone && cur.tangled == 0 && !s_.relaxTangled;
      Vec2 uvNew;
      SurfaceD2 dn;
      Vec3 nn;
      LocalEval best = cur;      // acceptance threshold: a trial must beat it
      bool lostQuality = false;  // the last trial was rejected for lowering the minimum quality
      Vec2 acceptedStep = Vec2::Zero();  // the Newton step (or its multiple) accepted
      auto tryStep = [&](const Vec2& step) {
        lostQuality = false;
        const Vec2 uvT = surf.wrap(uv0 + step);
        // A node untangling a fold may go where OCC counts it on a tolerant edge of its face;
        // smoothing keeps nodes out of those zones (see OccFaceSurface::contains).
        if (!(cur.tangled > 0 ? surf.containsNearBoundary(uvT.x(), uvT.y())
                              : surf.contains(uvT.x(), uvT.y())))
          return false;
        const SurfaceD2 dT = surf.d2(uvT.x(), uvT.y());
        if (isDegenerate(dT.du, dT.dv)) return false;
        const Vec3 c = dT.du.cross(dT.dv);
        const Vec3 nT = (orient / c.norm()) * c;
        const LocalEval tr = evalLocal(
            i, dT.p, [&](std::size_t) { return nT; }, zero, wantQ, &best, nullptr, nullptr);
        lostQuality = tr.byQuality;
        if (!acceptable(best, tr)) return false;
        keepTrial();
        best = tr;
        uvNew = uvT;
        dn = dT;
        nn = nT;
        acceptedStep = step;
        return true;
      };
      bool accepted = false;
      // Smoothing sweeps (δ = 0) try the over-relaxed step ω × dir first when the node keeps
      // moving the way it did (see OptimizeOptions::overRelaxation), then the step and its
      // halvings.
      const bool over =
          overRelaxes(len3, L) && sameWay(s_.lastStep[i].cast<double>(), dir, T.metric);
      // Halvings stop below a tenth of the activity threshold moveTol × L: a shorter step
      // would not count as a move (the direction fails: e.g. it lowers the submesh's minimum
      // quality in monotone mode, or the node sits at its local minimum).
      // In monotone mode, when the submesh's minimum is the bar (qualityBar: it is at or below
      // the sweep's floor), a step that lowered it is not halved further when the worst
      // element's η grows along the direction: every shorter step lowers it too (to first
      // order). Above the floor, the element that fell below it need not be the worst.
      const double minStep = kMinStepFraction * s_.opt.moveTol * L;
      const bool worstGrows = wantQ && qualityBar(cur) == cur.minQuality &&
                              cur.gradWorst.dot(d.du * dir.x() + d.dv * dir.y()) > 0.0;
      for (int ls = over ? -1 : 0; ls < s_.opt.maxLineSearch && !accepted; ++ls) {
        const double alpha = stepFactor(ls);
        if (ls > 0 && (alpha * len3 < minStep || (lostQuality && worstGrows))) break;
        accepted = tryStep(alpha * dir);
      }
      const Vec2 newtonStep = accepted ? acceptedStep : Vec2::Zero();
      if ((!accepted || best.f > 0.5 * cur.f) && s_.deltaHat == 0.0 && cur.maxEta > kFallbackEta) {
        // A badly shaped submesh where the Newton direction fails or barely helps (e.g. three
        // nearly collinear nodes on a curved surface, whose element plane stands across the
        // surface: its orientation flips under any step along the gradient; or a needle left
        // by untangling, where the barrier's curvature makes Newton steps tiny). Try steps
        // along ±φ_u, ±φ_v and the diagonals, a quarter of the local size long, and keep the
        // best acceptable (it must beat the Newton step's result).
        const double lu = d.du.norm(), lv = d.dv.norm();
        if (lu > 0.0 && lv > 0.0) {
          const Vec2 eu(0.25 * L / lu, 0.0), ev(0.0, 0.25 * L / lv);
          const Vec2 dirs[8] = {eu,
                                -eu,
                                ev,
                                -ev,
                                (eu + ev) * 0.7071067811865476,
                                (eu - ev) * 0.7071067811865476,
                                (ev - eu) * 0.7071067811865476,
                                -(eu + ev) * 0.7071067811865476};
          for (double scale : {1.0, 0.5, 0.25})
            for (const Vec2& dd : dirs)
              if (tryStep(scale * dd)) accepted = true;
        }
      }
      const bool creeping =
          accepted && best.tangled >= cur.tangled && (dn.p - x0).norm() < s_.opt.moveTol * L;
      if (s_.deltaHat > 0.0 && cur.tangled > 0 && (!accepted || creeping)) {
        // A fold the local Newton step cannot open (every step that lowers f̂ tangles another
        // element of the submesh, or the steps only creep towards a local minimum of f̂ with
        // an element still tangled — e.g. the node pulled onto the face boundary next to a
        // tangled sliver): try the centre of the node's kernel in (u,v) (where all its
        // elements are wound right in the parameter plane) and the parametric centroid of its
        // neighbours (a Laplacian step, as Gmsh's Laplace2D), and the points halfway and a
        // quarter of the way there. The candidate leaving the fewest elements of the submesh
        // tangled (then the lowest f̂) is taken when it leaves fewer tangled than the current
        // position and the Newton step — strict progress, so it cannot cycle.
        Vec2 targets[2];
        int nt = 0;
        if (kernelCenter(i, face, surf, uv0, d, orient, &targets[nt])) ++nt;
        if (neighbourCentroid(i, face, surf, uv0, &targets[nt])) ++nt;
        int bestTangled = accepted ? best.tangled : cur.tangled;
        double bestF = kInf;
        for (int k = 0; k < nt; ++k)
          for (double a : {1.0, 0.5, 0.25}) {
            const Vec2 uvT = surf.wrap(uv0 + a * (targets[k] - uv0));
            if (!surf.containsNearBoundary(uvT.x(), uvT.y())) continue;
            const SurfaceD2 dT = surf.d2(uvT.x(), uvT.y());
            if (isDegenerate(dT.du, dT.dv)) continue;
            const Vec3 cr = dT.du.cross(dT.dv);
            const Vec3 nT = (orient / cr.norm()) * cr;
            const LocalEval tr = evalLocal(
                i, dT.p, [&](std::size_t) { return nT; }, zero, false, nullptr, nullptr, nullptr);
            if (!tr.finite) continue;
            if (tr.tangled < bestTangled ||
                (tr.tangled == bestTangled && tr.f < bestF && bestF < kInf)) {
              bestTangled = tr.tangled;
              bestF = tr.f;
              accepted = true;
              acceptedStep = Vec2::Zero();
              uvNew = uvT;
              dn = dT;
              nn = nT;
            }
          }
      }
      const bool newton = accepted && acceptedStep == newtonStep;
      s_.lastStep[i] = newton ? Eigen::Vector2f(newtonStep.cast<float>()) : Eigen::Vector2f::Zero();
      if (!accepted) return moved;
      const double step = (dn.p - x0).norm();
      moved += step;
      s_.uv[i] = uvNew;
      s_.xyz[i] = dn.p;
      s_.nodeNormal[i] = nn;
      s_.d2[i] = {dn.du, dn.dv, dn.duu, dn.duv, dn.dvv};
      commitElements(i);
      if (step < 1e-14 * L) break;
    }
    return moved;
  }

  double updateEdgeNode(std::size_t i) {
    const int edge = s_.mesh.nodeEdge[i];
    const Curve& curve = *w_.geo.curves[static_cast<std::size_t>(edge)];
    if (s_.end(i) == s_.begin(i)) return 0.0;
    const double L = s_.localSize(i);
    if (!(L > 0.0)) return 0.0;
    // The node stays between its neighbours on the same edge (and inside the edge's range).
    const double t0 = s_.t[i];
    double lo = curve.tmin(), hi = curve.tmax();
    const bool periodic = curve.isPeriodic();
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* nd = s_.mesh.elementNodes(e);
      for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
        const std::size_t j = static_cast<std::size_t>(nd[k]);
        if (j == i || s_.mesh.nodeEdge.empty() || s_.mesh.nodeEdge[j] != edge) continue;
        double tj = s_.t[j];
        if (periodic) tj = tj - std::round((tj - t0) / curve.period()) * curve.period();
        if (tj < t0) lo = std::max(lo, tj);
        if (tj > t0) hi = std::min(hi, tj);
      }
    }
    if (periodic) {
      // Without two neighbours on the edge a closed edge gives no interval: stay put.
      if (lo == curve.tmin() || hi == curve.tmax()) return 0.0;
    }
    const CurveD2 d = curve.d2(t0);
    if (!(d.dt.norm() > 0.0)) return 0.0;
    const Vec3* oldN = s_.edgeNormal.data() + s_.edgeSlot[i];
    auto old = [&](std::size_t j) { return oldN[j]; };
    Vec3 gx;
    Mat3 Hx;
    const Vec3 x0 = s_.xyz[i];
    const bool monotone = s_.opt.monotone;
    const LocalEval cur = evalLocal(i, x0, old, old, monotone, nullptr, &gx, &Hx);
    if (!cur.finite || cur.f == 0.0) return 0.0;
    double gt, Ht;
    chainToCurve(d, gx, Hx, &gt, &Ht);
    if (!std::isfinite(gt) || !std::isfinite(Ht) || gt == 0.0) return 0.0;
    double dt = (Ht > 0.0) ? -gt / Ht : -gt / (std::abs(Ht) + 1e-12);
    if (dt * gt > 0.0) dt = -dt;
    double len3 = std::abs(dt) * d.dt.norm();
    if (len3 > L) {
      dt *= L / len3;
      len3 = L;
    }
    const double margin = 1e-3 * (hi - lo);
    const bool wantQ = monotone && cur.tangled == 0;
    Vec3* trialN = w_.normals.data();
    const bool over = overRelaxes(len3, L) && s_.lastStep[i].x() * dt > 0.0;  // as for Face nodes
    s_.lastStep[i].setZero();
    const double minStep = kMinStepFraction * s_.opt.moveTol * L;  // as for Face nodes
    for (int ls = over ? -1 : 0; ls < s_.opt.maxLineSearch; ++ls) {
      const double alpha = stepFactor(ls);
      if (ls > 0 && alpha * len3 < minStep) break;
      const double tn = t0 + alpha * dt;
      if (!(tn > lo + margin && tn < hi - margin)) continue;
      const Vec3 xn = curve.value(tn);
      edgeTrialNormals(i, curve, tn);
      const LocalEval tr = evalLocal(
          i, xn, [&](std::size_t j) { return trialN[j]; }, old, wantQ, &cur, nullptr, nullptr);
      if (!acceptable(cur, tr)) continue;
      keepTrial();
      double tb = tn;
      if (s_.deltaHat > 0.0 && cur.tangled > 0 && tr.tangled >= cur.tangled &&
          (xn - x0).norm() < s_.opt.moveTol * L)
        slideEscape(i, curve, lo + margin, hi - margin, tr.tangled, &tb);
      if (tb == tn) s_.lastStep[i].x() = static_cast<float>(tn - t0);
      return commitEdgeMove(i, curve, tb, x0);
    }
    double tb = t0;
    if (s_.deltaHat > 0.0 && cur.tangled > 0 &&
        slideEscape(i, curve, lo + margin, hi - margin, cur.tangled, &tb))
      return commitEdgeMove(i, curve, tb, x0);
    return 0.0;
  }

  /// The corner normals of sliding node i in each incident element at curve parameter t, into
  /// the worker's scratch.
  void edgeTrialNormals(std::size_t i, const Curve& curve, double t) {
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t pp = static_cast<std::size_t>(p);
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[pp]);
      const std::size_t slot = static_cast<std::size_t>(s_.mesh.elemOffset[e]) + s_.inc.local[pp];
      const int f = s_.mesh.elemFace[e];
      const Vec2 uvf = curve.uvOnFace(f, t, s_.mesh.cornerUV[slot]);
      const Surface& sf = *w_.geo.surfaces[static_cast<std::size_t>(f)];
      w_.normals[static_cast<std::size_t>(p - s_.begin(i))] =
          (s_.mesh.faceOrientation[static_cast<std::size_t>(f)] * sf.normal(uvf.x(), uvf.y()))
              .eval();
    }
  }

  /// Moves sliding node i to C(t) (its corner normals swapped in its elements' fixedNormal);
  /// returns the 3D move.
  double commitEdgeMove(std::size_t i, const Curve& curve, double t, const Vec3& x0) {
    edgeTrialNormals(i, curve, t);
    const Vec3 xn = curve.value(t);
    s_.t[i] = t;
    s_.xyz[i] = xn;
    Vec3* slotN = s_.edgeNormal.data() + s_.edgeSlot[i];
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t j = static_cast<std::size_t>(p - s_.begin(i));
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int local = s_.inc.local[static_cast<std::size_t>(p)];
      if (local < cornerCount(s_.mesh.elemType[e])) {
        s_.fixedNormal[e] += w_.normals[j] - slotN[j];
        slotN[j] = w_.normals[j];
        const std::int64_t slot = s_.cornerSlot(e);
        if (slot >= 0) s_.cornerN[static_cast<std::size_t>(slot + local)] = w_.normals[j];
      }
    }
    commitElements(i);
    return (xn - x0).norm();
  }

  /// The 1-D counterpart of a Face node's escape: a sliding node whose Newton step fails or
  /// creeps while an element of its submesh (on either face of its edge) stays tangled scans
  /// its admissible interval [a, b] (uniformly, and geometrically towards both ends, where a
  /// triangle next to a CAD vertex may only be valid very close to it) and takes the point
  /// with the fewest tangled elements of its submesh (then the lowest f̂) when that is below
  /// `threshold` — strict progress, so it cannot cycle.
  bool slideEscape(std::size_t i, const Curve& curve, double a, double b, int threshold,
                   double* tOut) {
    if (!(b > a)) return false;
    const Vec3* oldN = s_.edgeNormal.data() + s_.edgeSlot[i];
    auto old = [&](std::size_t j) { return oldN[j]; };
    const Vec3* trialN = w_.normals.data();
    int bestTangled = threshold;
    double bestF = kInf;
    bool found = false;
    auto tryT = [&](double t) {
      edgeTrialNormals(i, curve, t);
      const LocalEval tr = evalLocal(
          i, curve.value(t), [&](std::size_t j) { return trialN[j]; }, old, false, nullptr, nullptr,
          nullptr);
      if (!tr.finite) return;
      if (tr.tangled < bestTangled || (found && tr.tangled == bestTangled && tr.f < bestF)) {
        bestTangled = tr.tangled;
        bestF = tr.f;
        *tOut = t;
        found = true;
      }
    };
    constexpr int kUniform = 32;
    for (int k = 1; k < kUniform; ++k) tryT(a + (b - a) * k / kUniform);
    for (double r = 1.0 / kUniform; r > 1e-4; r *= 0.3) {
      tryT(a + (b - a) * r);
      tryT(b - (b - a) * r);
    }
    return found;
  }

  /// Current (u,v) on face `face`, next to `near`, of node j at corner k of element e (on that
  /// face): Face nodes of the face at their current (u,v), sliding Edge nodes at their current
  /// curve point (through the edge's pcurve), other nodes at their corner (u,v).
  Vec2 cornerOnFace(std::size_t e, int k, int face, const Surface& surf, const Vec2& near) const {
    const std::size_t j = static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]);
    const Vec2& corner = s_.mesh.cornerUV[static_cast<std::size_t>(s_.mesh.elemOffset[e] + k)];
    Vec2 uvj = corner;
    if (s_.mesh.nodeKind[j] == NodeKind::Face && s_.mesh.nodeFace[j] == face) {
      uvj = s_.uv[j];
    } else if (s_.mesh.nodeKind[j] == NodeKind::Edge) {
      const Curve& cj = *w_.geo.curves[static_cast<std::size_t>(s_.mesh.nodeEdge[j])];
      uvj = cj.uvOnFace(face, s_.t[j], corner);
    }
    return surf.unwrapNear(uvj, near);
  }

  /// Escape of last resort for a tangled element that the Newton steps, the kernel centre, the
  /// neighbours' centroid and the patch untanglings leave: Face node i (of `face`) tries the
  /// centres of a kSampleGrid² grid over the parametric box of its elements' other corners.
  /// Without `valid`: moves to the one leaving the fewest elements of its submesh tangled (then
  /// the lowest f̂), when that is fewer than at its position — strict progress, like every
  /// escape; returns the number of elements untangled. On a thin, strongly curved face a
  /// triangle can stand across the surface with its free node far along the face from the
  /// others (the bottle's thread): the valid positions, nearer to them, lie beyond a barrier of
  /// f̂ that no local step crosses, and off the kernel (the triangle is wound right in (u,v)).
  /// With `valid` (an element of i's): sets *target to the point where that element is valid
  /// and the fewest elements of the submesh are tangled (then the lowest f̂), without moving i;
  /// returns 1 when there is one.
  std::size_t sampleNeighbourhood(std::size_t i, int face, const Surface& surf,
                                  std::int64_t valid = -1, Vec2* target = nullptr) {
    static constexpr int kSampleGrid = 16;
    const Vec2 uv0 = s_.uv[i];
    Vec2 lo = uv0, hi = uv0;
    int validAt = -1;  // valid's index in i's incidence
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int nc = cornerCount(s_.mesh.elemType[e]);
      if (s_.inc.local[static_cast<std::size_t>(p)] >= nc) return 0;  // a high-order side node
      if (static_cast<std::int64_t>(e) == valid) validAt = static_cast<int>(p - s_.begin(i));
      for (int k = 0; k < nc; ++k) {
        if (static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]) == i) continue;
        const Vec2 c = cornerOnFace(e, k, face, surf, uv0);
        lo = lo.cwiseMin(c);
        hi = hi.cwiseMax(c);
      }
    }
    if (!lo.allFinite() || !hi.allFinite() || (valid >= 0 && validAt < 0)) return 0;
    const double orient = static_cast<double>(
        s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
    auto zero = [](std::size_t) { return Vec3::Zero().eval(); };
    const Vec3 n0 = s_.nodeNormal[i];
    const LocalEval cur = evalLocal(
        i, s_.xyz[i], [&](std::size_t) { return n0; }, zero, false, nullptr, nullptr, nullptr);
    // Evaluated as a trial (against a bound no trial reaches), evalLocal keeps each element's
    // η at δ = 0 and det S in the worker's scratch.
    LocalEval any;
    any.f = kInf;
    any.tangled = std::numeric_limits<int>::max();
    const bool track = s_.trackCache;
    s_.trackCache = true;
    int bestTangled = valid >= 0 ? std::numeric_limits<int>::max() : cur.tangled;
    double bestF = kInf;
    Vec2 bestUV = uv0;
    for (int a = 0; a < kSampleGrid; ++a)
      for (int b = 0; b < kSampleGrid; ++b) {
        const Vec2 r((a + 0.5) / kSampleGrid, (b + 0.5) / kSampleGrid);
        const Vec2 uvT = surf.wrap(lo + (hi - lo).cwiseProduct(r));
        if (!uvT.allFinite() || !surf.containsNearBoundary(uvT.x(), uvT.y())) continue;
        const SurfaceD1 dT = surf.d1(uvT.x(), uvT.y());
        if (isDegenerate(dT)) continue;
        const Vec3 cr = dT.du.cross(dT.dv);
        const Vec3 nT = (orient / cr.norm()) * cr;
        const LocalEval tr = valid >= 0 ? evalLocal(
                                              i, dT.p, [&](std::size_t) { return nT; }, zero, false,
                                              &any, nullptr, nullptr)
                                        : evalLocal(
                                              i, dT.p, [&](std::size_t) { return nT; }, zero, false,
                                              nullptr, nullptr, nullptr);
        if (!tr.finite) continue;
        const std::size_t v = static_cast<std::size_t>(std::max(validAt, 0));
        if (valid >= 0 ? (w_.sig[v] <= 0.0 || !std::isfinite(w_.eta0[v]))
                       : tr.tangled >= cur.tangled)
          continue;  // `valid` still tangled, or no progress
        if (tr.tangled < bestTangled || (tr.tangled == bestTangled && tr.f < bestF)) {
          bestTangled = tr.tangled;
          bestF = tr.f;
          bestUV = uvT;
        }
      }
    s_.trackCache = track;
    if (valid >= 0) {
      if (bestTangled == std::numeric_limits<int>::max()) return 0;
      *target = bestUV;
      return 1;
    }
    if (bestTangled >= cur.tangled || !placeAll({i}, {bestUV}, face, surf)) return 0;
    return static_cast<std::size_t>(cur.tangled - bestTangled);
  }

  /// Parametric centroid, on face `face` next to uv0, of the corners of Face node i's elements
  /// other than i (a Laplacian target, as Gmsh's Laplace2D).
  bool neighbourCentroid(std::size_t i, int face, const Surface& surf, const Vec2& uv0, Vec2* c) {
    Vec2 sum = Vec2::Zero();
    int cnt = 0;
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int nc = cornerCount(s_.mesh.elemType[e]);
      for (int k = 0; k < nc; ++k) {
        if (static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]) == i) continue;
        sum += cornerOnFace(e, k, face, surf, uv0);
        ++cnt;
      }
    }
    if (cnt == 0 || !sum.allFinite()) return false;
    *c = sum / cnt;
    return true;
  }

  /// The point of Face node i's "kernel" in (u,v) farthest from its boundary: every corner
  /// triangle of node i's elements that contains i is positively wound in (u,v) (for the face's
  /// reference orientation `orient`) exactly when i lies on the inner side of the line through
  /// the triangle's other two corners. The Chebyshev centre of these half-planes, measured in
  /// the metric of the surface's first fundamental form at uv0 (so that a strongly anisotropic
  /// parameterization does not skew it), found by enumerating the triples of lines (a 2-D
  /// linear program with a handful of constraints). False when the kernel is empty.
  bool kernelCenter(std::size_t i, int face, const Surface& surf, const Vec2& uv0, const NodeD2& d,
                    double orient, Vec2* centre) {
    // Metric: q = R (uv − uv0) with RᵀR = JᵀJ (Cholesky, R upper triangular, det R > 0).
    const double g11 = d.du.squaredNorm(), g12 = d.du.dot(d.dv), g22 = d.dv.squaredNorm();
    const double r11 = std::sqrt(g11);
    if (!(r11 > 0.0)) return false;
    const double r12 = g12 / r11, r22sq = g22 - r12 * r12;
    if (!(r22sq > 0.0)) return false;
    const double r22 = std::sqrt(r22sq);
    auto toQ = [&](const Vec2& uv) {
      const Vec2 w = uv - uv0;
      return Vec2(r11 * w.x() + r12 * w.y(), r22 * w.y());
    };
    // Lines a·q ≥ b with ‖a‖ = 1 (inner side).
    constexpr int kMaxLines = 64;
    Vec2 A[kMaxLines];
    double B[kMaxLines];
    int n = 0;
    auto addLine = [&](const Vec2& x, const Vec2& y) {  // node on the left of x → y
      const Vec2 qx = toQ(x), qy = toQ(y);
      const Vec2 t = qy - qx;
      const double len = t.norm();
      if (!(len > 0.0) || n >= kMaxLines) return;
      // orient · (y − x) × (q − x) > 0  ⇔  a·q > b with a = orient · (−t_y, t_x)
      const Vec2 a = orient * Vec2(-t.y(), t.x()) / len;
      A[n] = a;
      B[n] = a.dot(qx);
      ++n;
    };
    for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int local = s_.inc.local[static_cast<std::size_t>(p)];
      const int nc = cornerCount(s_.mesh.elemType[e]);
      if (local >= nc) return false;  // an edge or interior node of a high-order element
      const Vec2 nx = cornerOnFace(e, (local + 1) % nc, face, surf, uv0);
      const Vec2 pv = cornerOnFace(e, (local + nc - 1) % nc, face, surf, uv0);
      addLine(nx, pv);  // the corner triangle at i (i, next, prev)
      if (nc == 4) {
        // The corner triangles at next (next, next², i) and at prev (prev, i, prev²).
        const Vec2 nn = cornerOnFace(e, (local + 2) % nc, face, surf, uv0);
        addLine(nx, nn);
        addLine(nn, pv);
      }
    }
    if (n < 3) return false;
    double bestR = 0.0;
    bool found = false;
    for (int a = 0; a < n; ++a)
      for (int b = a + 1; b < n; ++b)
        for (int c = b + 1; c < n; ++c) {
          // a_k·q − r = b_k for k in {a, b, c}.
          Eigen::Matrix3d M;
          M << A[a].x(), A[a].y(), -1.0, A[b].x(), A[b].y(), -1.0, A[c].x(), A[c].y(), -1.0;
          const double det = M.determinant();
          if (!(std::abs(det) > 1e-14)) continue;
          const Eigen::Vector3d x = M.partialPivLu().solve(Eigen::Vector3d(B[a], B[b], B[c]));
          const double r = x.z();
          if (!(r > bestR)) continue;
          const Vec2 q(x.x(), x.y());
          bool ok = true;
          for (int k = 0; k < n && ok; ++k) ok = A[k].dot(q) - B[k] >= r - 1e-9 * std::abs(r);
          if (!ok) continue;
          bestR = r;
          // Back to (u,v): w = R⁻¹ q.
          const double wy = q.y() / r22;
          *centre = uv0 + Vec2((q.x() - r12 * wy) / r11, wy);
          found = true;
        }
    return found && centre->allFinite();
  }
};

}  // namespace

std::vector<std::vector<std::int32_t>> colorMovableNodes(const SurfaceMesh& mesh) {
  return colorNodes(mesh, buildIncidence(mesh));
}

namespace {

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

/// Whether element e (nodes at `xyz`, reference normal n) folds where no node that may move
/// acts: at one of the points where its validity is decided, det S ≤ 0 and the Jacobian there
/// depends only on nodes that may not move (CAD vertices, fixed CAD edges, poles). No node
/// motion can repair such an element. A linear triangle: none of its nodes may move. A
/// quadrilateral: a tangled corner triangle whose three nodes may not move. A high-order
/// triangle: a tangled node or quadrature point whose shape-function gradients vanish at
/// every movable node (e.g. the corner at a CAD vertex between two element edges on fixed CAD
/// edges, where a Gmsh curved element often folds). The fold must show against the reference
/// normal n and against the surface normal at each corner: n follows the element's movable
/// corners, and a fold that a corner normal does not confirm might open as they move.
bool foldHeld(const SurfaceMesh& m, const std::vector<Vec3>& xyz, std::size_t e, const Vec3& n) {
  const std::int32_t* nd = m.elementNodes(e);
  auto movable = [&](int k) { return isMovable(m.nodeKind[static_cast<std::size_t>(nd[k])]); };
  auto at = [&](int k) { return xyz[static_cast<std::size_t>(nd[k])]; };
  const ElementType type = m.elemType[e];
  if (type == ElementType::Tri3 || n.squaredNorm() == 0.0) {
    // Without a reference normal (corner normals that cancel) the element is tangled wherever
    // its nodes are, unless a movable corner changes the normal.
    for (int k = 0; k < m.elementSize(e); ++k)
      if (movable(k)) return false;
    return true;
  }
  const int nc = cornerCount(type);
  // With no corner that may move, n (the sum of the corner normals) cannot change either: a fold
  // against it between nodes that may not move stays, whatever the corner normals say (a
  // second-order triangle on a strongly curved face, its one movable side node far from the
  // corner where it folds). With no node that may move, nothing changes.
  bool cornerMoves = false, nodeMoves = false;
  for (int k = 0; k < m.elementSize(e); ++k)
    if (movable(k)) {
      nodeMoves = true;
      cornerMoves = cornerMoves || k < nc;
    }
  if (!nodeMoves) return true;
  auto folded = [&](const Jacobian32& J, const Mat2& Winv) {
    if (!jacobianValidity(J, Winv, n).tangled) return false;
    if (!cornerMoves) return true;
    for (int k = 0; k < nc; ++k) {  // surface normals only for a fold between fixed nodes
      const Vec3 nk = m.referenceNormal(m.elemFace[e], m.elementUV(e)[k]);
      if (nk.squaredNorm() > 0.0 && !jacobianValidity(J, Winv, nk).tangled) return false;
    }
    return true;
  };
  if (type == ElementType::Quad4) {
    // A corner whose three nodes lie on one CAD edge (sliding or fixed on it, or on a CAD
    // vertex at its end) stays a triangle of three points of the edge's curve: its plane turns
    // with the curve's geodesic curvature, not with the nodes' motion (a corner of 180° on an
    // edge straight in (u,v), or bent the wrong way: Gmsh's simple recombination leaves such
    // quads along CAD edges).
    auto onEdge = [&](int k, std::int32_t edge, double tol) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (m.nodeKind[j] == NodeKind::Face) return false;
      if (m.nodeEdge[j] == edge) return true;
      if (m.nodeKind[j] != NodeKind::Fixed || m.nodeEdge[j] >= 0) return false;
      const Curve& c = *m.curves[static_cast<std::size_t>(edge)];
      return (c.value(c.tmin()) - at(k)).norm() <= tol || (c.value(c.tmax()) - at(k)).norm() <= tol;
    };
    auto alongEdge = [&](int k, int k1, int k2) {
      if (m.nodeEdge.empty() || m.curves.empty()) return false;
      std::int32_t edge = -1;
      for (int q : {k, k1, k2}) {
        const std::size_t j = static_cast<std::size_t>(nd[q]);
        if (m.nodeKind[j] == NodeKind::Edge) edge = m.nodeEdge[j];
      }
      if (edge < 0 || !m.curves[static_cast<std::size_t>(edge)]) return false;
      const double tol = 1e-3 * std::sqrt(std::max((at(k1) - at(k)).squaredNorm(),
                                                   (at(k2) - at(k)).squaredNorm()));
      return onEdge(k, edge, tol) && onEdge(k1, edge, tol) && onEdge(k2, edge, tol);
    };
    for (int k = 0; k < 4; ++k) {
      const int k1 = (k + 1) % 4, k2 = (k + 3) % 4;
      if ((movable(k) || movable(k1) || movable(k2)) && !alongEdge(k, k1, k2)) continue;
      Jacobian32 J;
      J.col(0) = at(k1) - at(k);
      J.col(1) = at(k2) - at(k);
      if (folded(J, squareCornerWinv())) return true;
    }
    return false;
  }
  if (type == ElementType::Quad8) {
    // A quad8's Jacobian from the unit square at its nodes and on a 5 × 5 grid: folded there
    // with no node that may move among those it depends on.
    auto heldAtQuad = [&](double s, double t) {
      Eigen::Vector2d grad[8];
      quad8ShapeGradients(s, t, grad);
      Jacobian32 J = Jacobian32::Zero();
      for (int i = 0; i < 8; ++i) {
        if (grad[i].squaredNorm() <= 1e-24) continue;
        if (movable(i)) return false;
        J.col(0) += grad[i].x() * at(i);
        J.col(1) += grad[i].y() * at(i);
      }
      return folded(J, squareCornerWinv());
    };
    for (int i = 0; i <= 4; ++i)
      for (int j = 0; j <= 4; ++j)
        if (heldAtQuad(0.25 * i, 0.25 * j)) return true;
    return false;
  }
  const HighOrderTriangleRule& rule = highOrderTriangleRule(elementOrder(type));
  const int nn = rule.nodes;
  auto heldAt = [&](const Eigen::Vector2d* grad) {
    Jacobian32 J = Jacobian32::Zero();
    for (int i = 0; i < nn; ++i) {
      if (grad[i].squaredNorm() <= 1e-24) continue;  // zero up to the rounding of ξ
      if (movable(i)) return false;
      J.col(0) += grad[i].x() * at(i);
      J.col(1) += grad[i].y() * at(i);
    }
    return folded(J, equilateralWinv());
  };
  for (int a = 0; a < nn; ++a)
    if (heldAt(rule.gradAtNode.data() + static_cast<std::size_t>(a * nn))) return true;
  for (std::size_t q = 0; q < rule.quadrature->points.size(); ++q)
    if (heldAt(rule.gradAtPoint.data() + q * static_cast<std::size_t>(nn))) return true;
  return false;
}

/// Per element: 1 when none of its nodes may move (it is in no node's submesh).
std::vector<unsigned char> frozenElements(const SurfaceMesh& m) {
  std::vector<unsigned char> frozen(m.elementCount(), 1);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < m.elementSize(e); ++k)
      if (isMovable(m.nodeKind[static_cast<std::size_t>(nd[k])])) frozen[e] = 0;
  }
  return frozen;
}

/// Runs `body(begin, end)` over [0, n) in chunks of fixed size taken dynamically by the team
/// (chunk boundaries do not depend on the thread count).
template <class Body>
void parallelChunks(Team& team, std::size_t n, std::size_t chunk, Body&& body,
                    std::exception_ptr& error, std::mutex& errorMutex) {
  std::atomic<std::size_t> next{0};
  auto job = [&](int) {
    try {
      for (;;) {
        const std::size_t a = next.fetch_add(chunk, std::memory_order_relaxed);
        if (a >= n) break;
        body(a, std::min(n, a + chunk));
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(errorMutex);
      if (!error) error = std::current_exception();
    }
  };
  if (n <= chunk)
    job(0);  // one chunk: no worker to wake
  else
    team.run(job);
  if (error) std::rethrow_exception(error);
}

}  // namespace

/// Sorts the elements tangled in `q` into those that fold where a movable node acts and those
/// that fold where none does (foldHeld: no node motion can repair them), with a warning for
/// each non-empty list.
void reportTangled(const SurfaceMesh& mesh, const MeshQuality& q, OptimizeResult* res) {
  res->tangledUnmovable.clear();
  res->tangledMovable.clear();
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    if (!q.tangled[e]) continue;
    const bool held = foldHeld(mesh, mesh.xyz, e, elementReferenceNormal(mesh, e));
    (held ? res->tangledUnmovable : res->tangledMovable).push_back(static_cast<std::int32_t>(e));
  }
  auto ids = [](const std::vector<std::int32_t>& v) {
    std::string t;
    const std::size_t shown = std::min<std::size_t>(v.size(), 20);
    for (std::size_t k = 0; k < shown; ++k) t += (k ? ", " : "") + std::to_string(v[k]);
    if (shown < v.size()) t += ", …";
    return t;
  };
  res->warnings.clear();
  if (!res->tangledUnmovable.empty())
    res->warnings.push_back(
        std::to_string(res->tangledUnmovable.size()) +
        " element(s) stay tangled with no node that may move where they fold (their nodes there "
        "are all on CAD vertices, fixed CAD edges or poles): moving nodes cannot repair them, "
        "the mesh must be changed there (elements " +
        ids(res->tangledUnmovable) + ")");
  if (!res->tangledMovable.empty())
    res->warnings.push_back(std::to_string(res->tangledMovable.size()) +
                            " element(s) stay tangled although some of their nodes may move "
                            "(elements " +
                            ids(res->tangledMovable) + ")");
}

namespace {

/// A mesh's node positions and parameters (see optimizeOnce's `previous`).
struct MeshPositions {
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> nodeT;
  std::vector<Vec2> cornerUV;
  /// A copy of the mesh's positions.
  static MeshPositions of(const SurfaceMesh& mesh) {
    return {mesh.xyz, mesh.uv, mesh.nodeT, mesh.cornerUV};
  }
  bool empty() const { return xyz.empty(); }
  void restore(SurfaceMesh& mesh) {
    mesh.xyz = std::move(xyz);
    mesh.uv = std::move(uv);
    if (!mesh.nodeT.empty()) mesh.nodeT = std::move(nodeT);
    mesh.cornerUV = std::move(cornerUV);
  }
};

/// `progress` for a run that follows runs of `offset` sweeps in all (read at each call):
/// sweeps counted from the first run's start, out of `total` when positive, else out of the
/// run's own maximum plus `offset`. Empty when `progress` is.
ProgressCallback afterSweeps(const ProgressCallback& progress, const int& offset, int total = 0) {
  if (!progress) return {};
  return [&progress, &offset, total](const OptimizeProgress& p) {
    OptimizeProgress q = p;
    q.sweep += offset;
    q.maxSweeps = total > 0 ? total : p.maxSweeps + offset;
    return progress(q);
  };
}

/// One run. `before`, when given, is the quality the caller already measured on this mesh
/// (the sliding phase starts from the held phase's result): it is not measured again.
/// `holdAcross`: hold linear triangles from standing across their surface (acrossArea).
/// `previous`, when given, receives the positions the mesh had before a completed run (the
/// arrays the run replaced: no copy).
OptimizeResult optimizeOnce(SurfaceMesh& mesh, const OptimizeOptions& opt,
                            const ProgressCallback& progress, const QualityStats* before,
                            bool holdAcross, MeshPositions* previous = nullptr) {
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
  res.heldAcross = res.heldAcross || first.heldAcross;
  res.initialObjective = first.initialObjective;
  if (res.reason == StopReason::NothingToDo) res.reason = first.reason;
  res.movedNodes = 0;
  for (std::size_t i = 0; !input.empty() && i < mesh.nodeCount(); ++i)
    if (mesh.xyz[i] != input.xyz[i]) ++res.movedNodes;
  return res;
}

/// optimizeOnce holding linear triangles from standing across their surface (acrossArea). Where
/// that leaves tangled elements a node may move, a second run without the hold starts from its
/// result: untangling comes first (e.g. an element folded where the surface turns too fast to
/// untangle it otherwise). A cancelled second run leaves the mesh as it was before the first.
OptimizeResult optimizeHolding(SurfaceMesh& mesh, const OptimizeOptions& opt,
                               const ProgressCallback& progress, const QualityStats* before) {
  MeshPositions input;  // kept (no copy: the arrays the first run replaced) for a second run
  int offset = 0;
  const ProgressCallback shifted = afterSweeps(progress, offset);
  OptimizeResult held = optimizeOnce(mesh, opt, shifted, before, true, &input);
  if (held.reason == StopReason::Cancelled || held.tangledMovable.empty() || !held.heldAcross)
    return held;
  offset = held.sweeps;
  OptimizeResult res = continueRun(
      mesh, held, input, [&] { return optimizeOnce(mesh, opt, shifted, &held.after, false); });
  res.seconds += held.seconds;
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
  const bool sliding =
      std::find(mesh.nodeKind.begin(), mesh.nodeKind.end(), NodeKind::Edge) != mesh.nodeKind.end();
  if (!sliding || opt.maxSweeps == 0) return optimizeHolding(mesh, opt, progress, before);
  // Sliding edge nodes: first the run with them held (the fixed boundary), then the run that
  // lets them slide from there. The second run never increases the number of tangled elements
  // and (monotone) never lowers the minimum quality of a valid mesh, so sliding never ends
  // worse than the fixed boundary would in those two respects.
  const auto t0 = std::chrono::steady_clock::now();
  MeshPositions input = MeshPositions::of(mesh);
  int offset = 0;
  const ProgressCallback phased = afterSweeps(progress, offset, 2 * opt.maxSweeps);
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
  const ProgressCallback shifted = afterSweeps(progress, offset);
  OptimizeResult first = optimizeBoundary(mesh, opt, shifted, before);
  if (first.reason == StopReason::Cancelled || first.tangledMovable.empty()) return first;
  MeshPositions reached = MeshPositions::of(mesh);
  MeshPositions(input).restore(mesh);  // the shape measure starts from the input
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
