// Distortion of high-order triangles on a surface (paper §5, Definition 4).
//
// For a triangle of order p with nodes x_1…x_n (Gmsh ordering, equispaced Lagrange shape
// functions N_i), the Jacobian of the map from the reference triangle at ξ is the 3×2 matrix
//     J(ξ) = Σ_i x_i ∇N_i(ξ)ᵀ,
// and the pointwise distortion η(ξ) is that of S = T J W⁻¹ (jacobianDistortion: T projects onto
// the plane of J oriented by the element's reference normal n, W⁻¹ the equilateral ideal).
//
// Integration measure. We take the mean over the REFERENCE triangle:
//     η̂² = (1/|T̂|) ∫_T̂ η²(ξ) dξ ≈ Σ_q w_q η²(ξ_q),   Σ_q w_q = 1,
// instead of the mean over the physical element (1/|t_Σ|) ∫_{t_Σ} η² dx of Definition 4. Both
// coincide for straight-sided elements (constant J, so the element has exactly the quality of
// its linear triangle); the reference measure keeps positive weights when the element is
// tangled (a physical area weight ‖J₁ × J₂‖ vanishes exactly where η blows up and would hide
// folds from the untangling), and its derivatives are plain sums over the quadrature points.
//
// Quadrature: Dunavant's symmetric rule of degree 2p (lagrange_triangle.h). For a planar
// element with affine ideal, ‖S‖² is a polynomial of degree 2(p − 1) in ξ; the rule integrates
// it, plus two more degrees of the rational η², exactly enough for the element to be ranked
// reliably (6, 12, 16, 25 points for p = 2, 3, 4, 5).
//
// Validity: the element is tangled when det S ≤ 0 at any quadrature point or at any of its
// nodes (corners, edge and interior nodes: the points where a fold first shows), and, when
// those samples are all positive, unless the certificate (certificate.h) proves det J > 0 on
// the whole element: a fold between the samples is a fold (markUncertifiedFold; the overload
// from precomputed Jacobians leaves that to its caller, which has the nodes). minSigma is the
// smallest signed shape quality 2σ/‖S‖² over those points (the scaled Jacobian used for linear
// triangles, so the optimizer's δ policy treats every element type alike), 0 at most for a fold
// only the certificate finds.
//
// Derivatives with respect to the free node k: J depends on x_k through x_k ∇N_k(ξ)ᵀ, so
// jacobianDistortion gives ∂η_q/∂x_k and ∂²η_q/∂x_k² with b = ∇N_k(ξ_q), and
//     ∇η̂ = Σ_q w_q η_q ∇η_q / η̂,
//     ∇²η̂ = Σ_q w_q (∇η_q ∇η_qᵀ + η_q ∇²η_q) / η̂ − ∇η̂ ∇η̂ᵀ / η̂.
#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace surfmesh {

namespace {
/// Σ_i x_i ∇N_i(ξ)ᵀ over the element's N nodes (N known at compile time: unrolled), row by
/// row: row r of J accumulates x_i[r] ∇N_i (one packed operation).
template <int N>
Jacobian32 jacobianAt(const Vec3* x, const Eigen::Vector2d* grad, int n) {
  const int count = N > 0 ? N : n;
  Eigen::Vector2d r0 = Eigen::Vector2d::Zero(), r1 = r0, r2 = r0;
  for (int i = 0; i < count; ++i) {
    r0 += x[i].x() * grad[i];
    r1 += x[i].y() * grad[i];
    r2 += x[i].z() * grad[i];
  }
  Jacobian32 J;
  J.row(0) = r0.transpose();
  J.row(1) = r1.transpose();
  J.row(2) = r2.transpose();
  return J;
}

/// Fills `out` with the Jacobians of nodes x (the free node's entry already zero).
template <int N>
void restJacobians(const HighOrderTriangleRule& rule, const Vec3* x, HighOrderJacobians* out) {
  const int nn = rule.nodes;
  for (int k = 0; k < nn; ++k)
    out->atNode[k] =
        jacobianAt<N>(x, rule.gradAtNode.data() + static_cast<std::size_t>(k) * nn, nn);
  const std::size_t nq = rule.quadrature->points.size();
  for (std::size_t q = 0; q < nq; ++q)
    out->atPoint[q] =
        jacobianAt<N>(x, rule.gradAtPoint.data() + q * static_cast<std::size_t>(nn), nn);
}

const HighOrderTriangleRule& ruleOf(ElementType type) {
  if (isQuad(type))
    throw std::invalid_argument(std::string("highOrderTriangleDistortion: ") +
                                elementTypeName(type) + " is not a triangle");
  const HighOrderTriangleRule& rule = highOrderTriangleRule(elementOrder(type));
  if (rule.quadrature->points.size() > static_cast<std::size_t>(kMaxQuadraturePoints) ||
      rule.nodes > kMaxElementNodes)
    throw std::logic_error("highOrderTriangleDistortion: rule larger than its scratch");
  return rule;
}
}  // namespace

Jacobian32 highOrderJacobianAtNode(ElementType type, const Vec3* x, int k) {
  const HighOrderTriangleRule& rule = ruleOf(type);
  const int nn = rule.nodes;
  return jacobianAt<0>(x, rule.gradAtNode.data() + static_cast<std::size_t>(k) * nn, nn);
}

void highOrderJacobians(ElementType type, const Vec3* x, int freeLocal, HighOrderJacobians* out) {
  const HighOrderTriangleRule& rule = ruleOf(type);
  const int nn = rule.nodes;
  out->type = type;
  out->freeLocal = freeLocal >= 0 && freeLocal < nn ? freeLocal : -1;
  // The free node's term left out as a zero term: the same sums as skipping it.
  Vec3 xs[kMaxElementNodes];
  for (int i = 0; i < nn; ++i) xs[i] = i == out->freeLocal ? Vec3::Zero() : x[i];
  switch (nn) {
    case 6:
      return restJacobians<6>(rule, xs, out);
    case 10:
      return restJacobians<10>(rule, xs, out);
    case 15:
      return restJacobians<15>(rule, xs, out);
    case 21:
      return restJacobians<21>(rule, xs, out);
    default:
      return restJacobians<0>(rule, xs, out);
  }
}

ElementEval highOrderTriangleDistortion(const PlanarMeasure& m, ElementType type, const Vec3* x,
                                        const Vec3& n, double delta, int freeLocal, Vec3* grad,
                                        Mat3* hess, double* eta0, const Mat2* target) {
  HighOrderJacobians pre;
  // Without derivatives the Jacobians are summed over every node, in node order.
  const int k = (grad || hess) ? freeLocal : -1;
  highOrderJacobians(type, x, k, &pre);
  ElementEval r =
      highOrderTriangleDistortion(m, pre, pre.freeLocal >= 0 ? x[pre.freeLocal] : Vec3::Zero(), n,
                                  delta, grad, hess, eta0, target);
  // Valid at the samples: valid only where det J is proven positive on the whole element.
  markUncertifiedFold(type, x, n, delta, &r, grad, hess, eta0, &m, k, target);
  return r;
}

ElementEval highOrderTriangleDistortion(const PlanarMeasure& base, const HighOrderJacobians& pre,
                                        const Vec3& xFree, const Vec3& n, double delta, Vec3* grad,
                                        Mat3* hess, double* eta0, const Mat2* target) {
  const HighOrderTriangleRule& rule = ruleOf(pre.type);
  const int nn = rule.nodes;
  const int k = pre.freeLocal;
  const bool derivs = k >= 0 && (grad || hess);
  const Mat2& Winv = target ? *target : equilateralWinv();
  // Against the straight-sided triangle: its size too.
  const SizedMeasure sized(base);
  const PlanarMeasure& m = target ? static_cast<const PlanarMeasure&>(sized) : base;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // J at a point: the fixed nodes' part plus the free node's term.
  auto jacobian = [&](const Jacobian32& rest, const Eigen::Vector2d* g) {
    if (k < 0) return rest;
    Jacobian32 J = rest;
    J.col(0) += g[k].x() * xFree;
    J.col(1) += g[k].y() * xFree;
    return J;
  };

  ElementEval r;
  r.minSigma = kInf;
  bool infinite = false;

  // Validity at the element's nodes.
  for (int q = 0; q < nn; ++q) {
    const Jacobian32 J =
        jacobian(pre.atNode[q], rule.gradAtNode.data() + static_cast<std::size_t>(q) * nn);
    const ElementEval e = jacobianValidity(J, Winv, n);
    r.minSigma = std::min(r.minSigma, e.minSigma);
    r.tangled = r.tangled || e.tangled;
  }

  // Mean of η² over the reference triangle.
  const TriangleQuadrature& quad = *rule.quadrature;
  double sum = 0.0, sum0 = 0.0;  // Σ w η² (with δ, and with δ = 0 when eta0 is asked)
  double e0 = kInf;
  double* e0p = eta0 ? &e0 : nullptr;
  Vec3 gsum = Vec3::Zero();
  Mat3 Hsum = Mat3::Zero();
  for (std::size_t q = 0; q < quad.points.size(); ++q) {
    const Eigen::Vector2d* gq = rule.gradAtPoint.data() + q * static_cast<std::size_t>(nn);
    const Jacobian32 J = jacobian(pre.atPoint[q], gq);
    Vec3 g = Vec3::Zero();
    Mat3 H = Mat3::Zero();
    const ElementEval e =
        derivs ? jacobianDistortion(m, J, Winv, n, delta, gq + k, &g, hess ? &H : nullptr, e0p)
               : jacobianDistortion(m, J, Winv, n, delta, nullptr, nullptr, nullptr, e0p);
    r.minSigma = std::min(r.minSigma, e.minSigma);
    r.tangled = r.tangled || e.tangled;
    const double w = quad.weights[q];
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

bool straightSidedTarget(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& n,
                         Mat2* Winv) {
  const Vec3 a = x1 - x0, b = x2 - x0;
  const Vec3 axb = a.cross(b);
  const double la = a.norm(), area2 = axb.norm();
  if (!(la > 0.0) || !(area2 > 0.0) || !(axb.dot(n) > 0.0)) return false;
  Mat2 W;
  W << la, a.dot(b) / la, 0.0, area2 / la;
  *Winv = W.inverse();
  return Winv->allFinite();
}

}  // namespace surfmesh
