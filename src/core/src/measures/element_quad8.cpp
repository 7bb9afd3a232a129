// Distortion of serendipity quadrilaterals (Quad8: 4 corners, then the middle of sides 0-1,
// 1-2, 2-3, 3-0 — Gmsh's and FreeCAD's/SMESH's order; CalculiX's S8) on a surface.
//
// The map from the unit square (s,t) ∈ [0,1]² is x(s,t) = Σ_i x_i N_i(s,t) with the
// serendipity shape functions; in r = 2s − 1, q = 2t − 1 and the nodes' (r_i, q_i):
//     corners:            N_i = ¼ (1 + r r_i)(1 + q q_i)(r r_i + q q_i − 1),
//     sides with r_i = 0: N_i = ½ (1 − r²)(1 + q q_i),
//     sides with q_i = 0: N_i = ½ (1 + r r_i)(1 − q²).
// As for curved triangles (element_high_order.cpp), the pointwise distortion is that of
// S = T J(ξ) W⁻¹ with J = Σ_i x_i ∇N_i(ξ)ᵀ (T onto the plane of J, oriented by the element's
// reference normal n), here with the square as ideal (W = I, squareCornerWinv): a straight-sided
// parallelogram quad8 with its side nodes at the midpoints has constant J = [x1 − x0, x3 − x0],
// the Jacobian of the quad4 corner triangles, so both types give a square the quality 1.
//     η̂² = mean over the square of η² ≈ Σ_q w_q η²(ξ_q)   (3 × 3 Gauss points, Σ w = 1).
// Tangled when det S ≤ 0 at a quadrature point or at any of the 8 nodes, or when its
// determinant is not proven positive on the whole square (Bernstein bounds, below). Derivatives
// with respect to one free node k: J depends on x_k through x_k ∇N_k(ξ)ᵀ, then as for triangles.
#include "surfmesh/measures/element_measure.h"

#include <array>
#include <cmath>
#include <limits>

namespace surfmesh {

namespace {

constexpr int kQuad8Nodes = 8;
/// The nodes in (r, q) ∈ [−1, 1]².
constexpr double kR[kQuad8Nodes] = {-1, 1, 1, -1, 0, 1, 0, -1};
constexpr double kQ[kQuad8Nodes] = {-1, -1, 1, 1, -1, 0, 1, 0};

/// Gradients (∂/∂s, ∂/∂t) of the 8 shape functions at (s, t) of the unit square.
void gradients(double s, double t, Eigen::Vector2d* g) {
  const double r = 2.0 * s - 1.0, q = 2.0 * t - 1.0;
  for (int i = 0; i < kQuad8Nodes; ++i) {
    const double ri = kR[i], qi = kQ[i];
    double dr = 0.0, dq = 0.0;  // ∂N/∂r, ∂N/∂q
    if (i < 4) {
      dr = 0.25 * ri * (1 + q * qi) * (2 * r * ri + q * qi);
      dq = 0.25 * qi * (1 + r * ri) * (r * ri + 2 * q * qi);
    } else if (ri == 0.0) {
      dr = -r * (1 + q * qi);
      dq = 0.5 * (1 - r * r) * qi;
    } else {
      dr = 0.5 * ri * (1 - q * q);
      dq = -(1 + r * ri) * q;
    }
    g[i] = Eigen::Vector2d(2.0 * dr, 2.0 * dq);  // d/ds = 2 d/dr
  }
}

/// The 3 × 3 Gauss rule on the unit square, and the shape gradients at its points and at the
/// element's nodes.
struct Quad8Rule {
  std::array<Eigen::Vector2d, 9> points;
  std::array<double, 9> weights;
  std::array<std::array<Eigen::Vector2d, kQuad8Nodes>, 9> gradAtPoint;
  std::array<std::array<Eigen::Vector2d, kQuad8Nodes>, kQuad8Nodes> gradAtNode;
  Quad8Rule() {
    const double a = 0.5 * std::sqrt(0.6);
    const double p[3] = {0.5 - a, 0.5, 0.5 + a}, w[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const std::size_t k = static_cast<std::size_t>(3 * i + j);
        points[k] = Eigen::Vector2d(p[i], p[j]);
        weights[k] = w[i] * w[j];
        gradients(p[i], p[j], gradAtPoint[k].data());
      }
    for (std::size_t k = 0; k < kQuad8Nodes; ++k)
      gradients(0.5 * (kR[k] + 1.0), 0.5 * (kQ[k] + 1.0), gradAtNode[k].data());
  }
};

const Quad8Rule& rule() {
  static const Quad8Rule r;
  return r;
}

Jacobian32 jacobianAt(const Vec3* x, const std::array<Eigen::Vector2d, kQuad8Nodes>& g) {
  Jacobian32 J = Jacobian32::Zero();
  for (std::size_t i = 0; i < kQuad8Nodes; ++i) J += x[i] * g[i].transpose();
  return J;
}

// ---- certified validity -----------------------------------------------------------------------
// D(s,t) = (∂x/∂s × ∂x/∂t)·n is a polynomial of degree 3 in s and 3 in t (∂N/∂s has degree
// (1, 2), ∂N/∂t degree (2, 1)). Its tensor-product Bernstein coefficients bound it on the
// square (D's range lies within theirs; the corner coefficients are its corner values), and
// de Casteljau subdivision sharpens the bound (Johnen, Remacle, Geuzaine 2013): D > 0 on the
// whole square is proven when every coefficient of every piece is positive; a piece with a
// non-positive corner value proves a fold.

using Coeffs = Eigen::Matrix4d;  // (i, j): Bernstein coefficient of s-degree i, t-degree j

/// Bernstein coefficients from the values at (i/3, j/3): V⁻¹ D V⁻ᵀ, V(i, j) = b_j(i/3).
const Eigen::Matrix4d& bernsteinFromValues() {
  static const Eigen::Matrix4d inv = [] {
    Eigen::Matrix4d V;
    for (int i = 0; i < 4; ++i) {
      const double t = i / 3.0;
      const double c[4] = {1, 3, 3, 1};
      for (int j = 0; j < 4; ++j) V(i, j) = c[j] * std::pow(t, j) * std::pow(1 - t, 3 - j);
    }
    return Eigen::Matrix4d(V.inverse());
  }();
  return inv;
}

/// The two halves of cubic Bernstein coefficients (the rows of `c`, one per column) at 1/2.
void split(const Coeffs& c, Coeffs* lo, Coeffs* hi) {
  for (int k = 0; k < 4; ++k) {
    const double c0 = c(0, k), c1 = c(1, k), c2 = c(2, k), c3 = c(3, k);
    const double m = (c0 + 3 * c1 + 3 * c2 + c3) / 8;
    (*lo)(0, k) = c0;
    (*lo)(1, k) = (c0 + c1) / 2;
    (*lo)(2, k) = (c0 + 2 * c1 + c2) / 4;
    (*lo)(3, k) = m;
    (*hi)(0, k) = m;
    (*hi)(1, k) = (c1 + 2 * c2 + c3) / 4;
    (*hi)(2, k) = (c2 + c3) / 2;
    (*hi)(3, k) = c3;
  }
}

/// Whether D > 0 on the piece with coefficients c is proven within `depth` subdivisions.
bool provenPositive(const Coeffs& c, int depth) {
  if (c.minCoeff() > 0.0) return true;
  if (!(c(0, 0) > 0.0) || !(c(3, 0) > 0.0) || !(c(0, 3) > 0.0) || !(c(3, 3) > 0.0)) return false;
  if (depth == 0) return false;  // not proven: counted as folded
  Coeffs lo, hi;
  split(c, &lo, &hi);  // in s
  for (const Coeffs* half : {&lo, &hi}) {
    Coeffs a, b;
    split(half->transpose(), &a, &b);  // in t
    if (!provenPositive(a.transpose(), depth - 1) || !provenPositive(b.transpose(), depth - 1))
      return false;
  }
  return true;
}

/// Whether the quad8 with nodes x is valid against n everywhere on the square (proven).
bool provenValid(const Vec3* x, const Vec3& n) {
  Eigen::Matrix4d values;
  Eigen::Vector2d g[kQuad8Nodes];
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      gradients(i / 3.0, j / 3.0, g);
      Vec3 a = Vec3::Zero(), b = Vec3::Zero();
      for (int k = 0; k < kQuad8Nodes; ++k) {
        a += g[k].x() * x[k];
        b += g[k].y() * x[k];
      }
      values(i, j) = a.cross(b).dot(n);
    }
  const Eigen::Matrix4d& M = bernsteinFromValues();
  const Coeffs c = M * values * M.transpose();
  return provenPositive(c, 8);
}

}  // namespace

Jacobian32 quad8JacobianAtNode(const Vec3* x, int k) {
  return jacobianAt(x, rule().gradAtNode[static_cast<std::size_t>(k)]);
}

void quad8ShapeGradients(double s, double t, Eigen::Vector2d* grad) { gradients(s, t, grad); }

void quad8ShapeValues(double s, double t, double* N) {
  const double r = 2.0 * s - 1.0, q = 2.0 * t - 1.0;
  for (int i = 0; i < kQuad8Nodes; ++i) {
    const double ri = kR[i], qi = kQ[i];
    if (i < 4)
      N[i] = 0.25 * (1 + r * ri) * (1 + q * qi) * (r * ri + q * qi - 1);
    else if (ri == 0.0)
      N[i] = 0.5 * (1 - r * r) * (1 + q * qi);
    else
      N[i] = 0.5 * (1 + r * ri) * (1 - q * q);
  }
}

ElementEval quad8Distortion(const PlanarMeasure& m, const Vec3* x, const Vec3& n, double delta,
                            int freeLocal, Vec3* grad, Mat3* hess, double* eta0) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Quad8Rule& R = rule();
  const Mat2& Winv = squareCornerWinv();
  const int k = freeLocal >= 0 && freeLocal < kQuad8Nodes ? freeLocal : -1;
  const bool derivs = k >= 0 && (grad || hess);
  ElementEval r;
  r.minSigma = kInf;
  for (std::size_t q = 0; q < kQuad8Nodes; ++q) {
    const ElementEval e = jacobianValidity(jacobianAt(x, R.gradAtNode[q]), Winv, n);
    r.minSigma = std::min(r.minSigma, e.minSigma);
    r.tangled = r.tangled || e.tangled;
  }
  double sum = 0.0, sum0 = 0.0, e0 = kInf;
  double* e0p = eta0 ? &e0 : nullptr;
  bool infinite = false;
  Vec3 gsum = Vec3::Zero();
  Mat3 Hsum = Mat3::Zero();
  for (std::size_t q = 0; q < R.points.size(); ++q) {
    const Jacobian32 J = jacobianAt(x, R.gradAtPoint[q]);
    Vec3 g = Vec3::Zero();
    Mat3 H = Mat3::Zero();
    const Eigen::Vector2d* b = derivs ? &R.gradAtPoint[q][static_cast<std::size_t>(k)] : nullptr;
    const ElementEval e = jacobianDistortion(m, J, Winv, n, delta, b, derivs ? &g : nullptr,
                                             derivs && hess ? &H : nullptr, e0p);
    r.minSigma = std::min(r.minSigma, e.minSigma);
    r.tangled = r.tangled || e.tangled;
    const double w = R.weights[q];
    if (eta0) sum0 += w * e0 * e0;
    if (!std::isfinite(e.eta)) {
      infinite = true;
      continue;
    }
    sum += w * e.eta * e.eta;
    if (derivs) {
      gsum += w * e.eta * g;
      if (hess) Hsum += w * (g * g.transpose() + e.eta * H);
    }
  }
  // Between the points: folded unless proven valid on the whole square.
  if (!r.tangled && !provenValid(x, n)) {
    r.tangled = true;
    r.minSigma = std::min(r.minSigma, 0.0);
  }
  if (eta0) *eta0 = (r.tangled || !std::isfinite(sum0)) ? kInf : std::sqrt(sum0);
  if (infinite || (r.tangled && delta == 0.0) || !std::isfinite(sum)) {
    r.eta = kInf;
    r.tangled = true;
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return r;
  }
  r.eta = std::sqrt(sum);
  if (derivs) {
    const Vec3 g = gsum / r.eta;
    if (grad) *grad = g;
    if (hess) *hess = Hsum / r.eta - g * g.transpose() / r.eta;
  }
  return r;
}

}  // namespace surfmesh
