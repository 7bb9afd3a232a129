#include "surfmesh/measures/lagrange_triangle.h"

#include <array>
#include <stdexcept>
#include <string>

namespace surfmesh {

namespace {

/// One orbit of a symmetric rule: the centroid, the 3 permutations of (a, a, 1 − 2a), or the
/// 6 permutations of (a, b, 1 − a − b); w is the weight of each point (Σ over all points = 1).
struct Orbit {
  int size;
  double a, b, w;
};

TriangleQuadrature makeRule(int degree, std::initializer_list<Orbit> orbits) {
  TriangleQuadrature q;
  q.degree = degree;
  auto add = [&q](double l0, double l1, double l2, double w) {
    (void)l0;
    q.points.emplace_back(l1, l2);
    q.weights.push_back(w);
  };
  for (const Orbit& o : orbits) {
    if (o.size == 1) {
      add(1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, o.w);
    } else if (o.size == 3) {
      const double a = o.a, c = 1.0 - 2.0 * o.a;
      add(c, a, a, o.w);
      add(a, c, a, o.w);
      add(a, a, c, o.w);
    } else {
      const double a = o.a, b = o.b, c = 1.0 - o.a - o.b;
      add(a, b, c, o.w);
      add(a, c, b, o.w);
      add(b, a, c, o.w);
      add(b, c, a, o.w);
      add(c, a, b, o.w);
      add(c, b, a, o.w);
    }
  }
  // Normalize exactly (the tabulated weights sum to 1 within a few ulps).
  double s = 0.0;
  for (double w : q.weights) s += w;
  for (double& w : q.weights) w /= s;
  return q;
}

const std::array<TriangleQuadrature, 6>& rules() {
  static const std::array<TriangleQuadrature, 6> r = {
      makeRule(1, {{1, 0, 0, 1.0}}),
      makeRule(2, {{3, 1.0 / 6.0, 0, 1.0 / 3.0}}),
      makeRule(4, {{3, 0.44594849091596483, 0, 0.22338158967801131},
                   {3, 0.091576213509770826, 0, 0.10995174365532201}}),
      makeRule(6, {{3, 0.24928674517085891, 0, 0.11678627572646653},
                   {3, 0.063089014491513024, 0, 0.050844906370222064},
                   {6, 0.053145049844780322, 0.31035245103382381, 0.082851075618322376}}),
      makeRule(8, {{1, 0, 0, 0.14431560767774379},
                   {3, 0.45929258829269376, 0, 0.09509163426731386},
                   {3, 0.17056930775172699, 0, 0.10321737053472058},
                   {3, 0.050547228317031123, 0, 0.032458497623201035},
                   {6, 0.0083947774099181541, 0.26311282963473193, 0.02723031417442497}}),
      makeRule(10, {{1, 0, 0, 0.090817990384986988},
                    {3, 0.4855776333843726, 0, 0.036725957755490667},
                    {3, 0.10948157548454752, 0, 0.045321059435250569},
                    {6, 0.14170721941288156, 0.30793983876451042, 0.072757916846291779},
                    {6, 0.025003534762174495, 0.24667256063840176, 0.028327242530565695},
                    {6, 0.009540815400364595, 0.066803251011596843, 0.00942166696360742}}),
  };
  return r;
}

/// Barycentric multi-indices of the nodes of a triangle of order q, Gmsh ordering.
std::vector<Eigen::Vector3i> gmshMultiIndices(int q) {
  std::vector<Eigen::Vector3i> r;
  if (q == 0) {
    r.emplace_back(0, 0, 0);
    return r;
  }
  const Eigen::Vector3i c[3] = {{q, 0, 0}, {0, q, 0}, {0, 0, q}};
  for (const auto& v : c) r.push_back(v);
  for (int e = 0; e < 3; ++e) {
    const int a = e, b = (e + 1) % 3;
    for (int s = 1; s < q; ++s) {
      Eigen::Vector3i m = Eigen::Vector3i::Zero();
      m(a) = q - s;
      m(b) = s;
      r.push_back(m);
    }
  }
  if (q >= 3)
    for (const auto& m : gmshMultiIndices(q - 3)) r.push_back(m + Eigen::Vector3i(1, 1, 1));
  return r;
}

/// R_m(λ) = Π_{s<m} (pλ − s)/(s + 1) and its derivative in λ.
void silvester(int m, int p, double lambda, double& R, double& dR) {
  R = 1.0;
  dR = 0.0;
  for (int s = 0; s < m; ++s) {
    const double f = (p * lambda - s) / (s + 1);
    const double df = static_cast<double>(p) / (s + 1);
    dR = dR * f + R * df;
    R *= f;
  }
}

}  // namespace

const TriangleQuadrature& triangleQuadrature(int degree) {
  for (const auto& r : rules())
    if (r.degree >= degree) return r;
  throw std::invalid_argument("no triangle quadrature of degree " + std::to_string(degree) +
                              " (maximum 10)");
}

LagrangeTriangle::LagrangeTriangle(int order) : p_(order) {
  if (order < 1 || order > 5)
    throw std::invalid_argument("Lagrange triangle order must be 1..5, got " +
                                std::to_string(order));
  index_ = gmshMultiIndices(order);
  for (const auto& m : index_)
    nodes_.emplace_back(static_cast<double>(m(1)) / p_, static_cast<double>(m(2)) / p_);
}

void LagrangeTriangle::shape(const Eigen::Vector2d& xi, double* N) const {
  const double l[3] = {1.0 - xi.x() - xi.y(), xi.x(), xi.y()};
  for (std::size_t n = 0; n < index_.size(); ++n) {
    double v = 1.0;
    for (int c = 0; c < 3; ++c) {
      double R, dR;
      silvester(index_[n](c), p_, l[c], R, dR);
      v *= R;
    }
    N[n] = v;
  }
}

void LagrangeTriangle::gradients(const Eigen::Vector2d& xi, Eigen::Vector2d* grad) const {
  const double l[3] = {1.0 - xi.x() - xi.y(), xi.x(), xi.y()};
  for (std::size_t n = 0; n < index_.size(); ++n) {
    double R[3], dR[3];
    for (int c = 0; c < 3; ++c) silvester(index_[n](c), p_, l[c], R[c], dR[c]);
    // ∂λ0/∂ξ = ∂λ0/∂η = −1, ∂λ1/∂ξ = 1, ∂λ2/∂η = 1.
    const double d0 = dR[0] * R[1] * R[2];
    grad[n] = Eigen::Vector2d(-d0 + R[0] * dR[1] * R[2], -d0 + R[0] * R[1] * dR[2]);
  }
}

const LagrangeTriangle& lagrangeTriangle(int order) {
  static const LagrangeTriangle t[5] = {LagrangeTriangle(1), LagrangeTriangle(2),
                                        LagrangeTriangle(3), LagrangeTriangle(4),
                                        LagrangeTriangle(5)};
  if (order < 1 || order > 5)
    throw std::invalid_argument("Lagrange triangle order must be 1..5, got " +
                                std::to_string(order));
  return t[order - 1];
}

namespace {
HighOrderTriangleRule makeHighOrderRule(int order) {
  HighOrderTriangleRule r;
  const LagrangeTriangle& lt = lagrangeTriangle(order);
  r.order = order;
  r.nodes = lt.nodeCount();
  r.quadrature = &triangleQuadrature(2 * order);
  const std::size_t n = static_cast<std::size_t>(r.nodes);
  r.gradAtPoint.resize(r.quadrature->points.size() * n);
  for (std::size_t q = 0; q < r.quadrature->points.size(); ++q)
    lt.gradients(r.quadrature->points[q], r.gradAtPoint.data() + q * n);
  r.gradAtNode.resize(n * n);
  for (std::size_t k = 0; k < n; ++k) lt.gradients(lt.nodes()[k], r.gradAtNode.data() + k * n);
  return r;
}
}  // namespace

const HighOrderTriangleRule& highOrderTriangleRule(int order) {
  static const HighOrderTriangleRule r[5] = {makeHighOrderRule(1), makeHighOrderRule(2),
                                             makeHighOrderRule(3), makeHighOrderRule(4),
                                             makeHighOrderRule(5)};
  if (order < 1 || order > 5)
    throw std::invalid_argument("triangle order must be 1..5, got " + std::to_string(order));
  return r[order - 1];
}

}  // namespace surfmesh
