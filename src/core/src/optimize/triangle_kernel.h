// The linear triangle's distortion and its derivatives with respect to one free corner in
// closed form, the across-the-surface hold, and the safeguarded 2×2 Newton direction: the hot
// path of the node updates (optimizer internals, inline).
#pragma once

#include "surfmesh/measures/element_measure.h"

#include <algorithm>
#include <cmath>
#include <limits>

/// The hot path's small functions that were file-local before the optimizer was split: GCC
/// inlined them into their one caller then, and keeps them out of line at -O2 now that they
/// have (vague) external linkage; this keeps them inlined.
#define SURFMESH_HOT_INLINE [[gnu::always_inline]] inline

namespace surfmesh {
namespace detail {

constexpr double kInf = std::numeric_limits<double>::infinity();

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
constexpr double kAcrossSlope = kEdgeOnSlope;  // the same 84°: a run stands none edge-on

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
SURFMESH_HOT_INLINE ElemOut triangleKernelUV(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1,
                                             const Vec3& x2, const Vec3& n, double delta,
                                             bool wantEta0, const Tangent& T, Vec3* grad,
                                             Vec3* hessUV, bool projected = false,
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
SURFMESH_HOT_INLINE Vec2 newtonDirection(const Vec2& g, const Mat2& Hin) {
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
}  // namespace detail
}  // namespace surfmesh
