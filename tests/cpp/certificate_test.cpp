// The certificate of a curved triangle's Jacobian sign (issue #39, points 1 and 7): hand-made
// P2/P3 elements (valid, folded at a corner, folded between the sampled points), flat and on a
// sphere and a cylinder, and random perturbations of P2…P5 elements, every verdict checked
// against a dense sampling of det J written here from the textbook Lagrange functions (not
// SurfMesh's), plus order 1 against the plain orientation test.
#include "surfmesh/measures/certificate.h"

#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

using namespace surfmesh;

namespace {

const double kPi = 3.14159265358979323846;

const ElementType kTypes[] = {ElementType::Tri3, ElementType::Tri6, ElementType::Tri10,
                              ElementType::Tri15, ElementType::Tri21};
ElementType typeOf(int p) { return kTypes[p - 1]; }

// ---- an independent Lagrange triangle ---------------------------------------------------------

/// Barycentric multi-indices (λ0, λ1, λ2)·p of the nodes, Gmsh order, written out by hand:
/// corners, edges 0→1, 1→2, 2→0, then the interior (a triangle of order p − 3, same order).
std::vector<std::array<int, 3>> gmshNodes(int p) {
  switch (p) {
    case 1:
      return {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    case 2:
      return {{2, 0, 0}, {0, 2, 0}, {0, 0, 2}, {1, 1, 0}, {0, 1, 1}, {1, 0, 1}};
    case 3:
      return {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 1, 0}, {1, 2, 0},
              {0, 2, 1}, {0, 1, 2}, {1, 0, 2}, {2, 0, 1}, {1, 1, 1}};
    case 4:
      return {{4, 0, 0}, {0, 4, 0}, {0, 0, 4}, {3, 1, 0}, {2, 2, 0},
              {1, 3, 0}, {0, 3, 1}, {0, 2, 2}, {0, 1, 3}, {1, 0, 3},
              {2, 0, 2}, {3, 0, 1}, {2, 1, 1}, {1, 2, 1}, {1, 1, 2}};
    default:  // 5
      return {{5, 0, 0}, {0, 5, 0}, {0, 0, 5}, {4, 1, 0}, {3, 2, 0}, {2, 3, 0}, {1, 4, 0},
              {0, 4, 1}, {0, 3, 2}, {0, 2, 3}, {0, 1, 4}, {1, 0, 4}, {2, 0, 3}, {3, 0, 2},
              {4, 0, 1}, {3, 1, 1}, {1, 3, 1}, {1, 1, 3}, {2, 2, 1}, {1, 2, 2}, {2, 1, 2}};
  }
}

/// Reference coordinates (ξ, η) = (λ1, λ2) of node i of order p.
Eigen::Vector2d nodeXi(int p, int i) {
  const auto m = gmshNodes(p)[static_cast<std::size_t>(i)];
  return Eigen::Vector2d(static_cast<double>(m[1]) / p, static_cast<double>(m[2]) / p);
}

/// The Lagrange polynomial of the node with index m: Π_c Π_{s < m_c} (λ_c − s/p) / (m_c/p − s/p),
/// and its derivative with respect to λ_c (product rule), c = 0, 1, 2.
struct Lagrange {
  int p;
  std::vector<std::array<int, 3>> nodes;
  explicit Lagrange(int order) : p(order), nodes(gmshNodes(order)) {}
  /// ∂N_i/∂ξ, ∂N_i/∂η at (ξ, η) for every node.
  void derivatives(double xi, double eta, std::vector<Eigen::Vector2d>* g) const {
    const double l[3] = {1 - xi - eta, xi, eta};
    g->resize(nodes.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      double f[3], df[3];
      for (int c = 0; c < 3; ++c) {
        // f = Π_{s<m} (λ − s/p)/(m/p − s/p); df/dλ = Σ_t Π_{s≠t} … / (m/p − t/p).
        const int m = nodes[i][static_cast<std::size_t>(c)];
        f[c] = 1.0;
        df[c] = 0.0;
        for (int t = 0; t < m; ++t) {
          double term = 1.0 / ((m - t) / static_cast<double>(p));
          for (int s = 0; s < m; ++s)
            if (s != t)
              term *= (l[c] - s / static_cast<double>(p)) / ((m - s) / static_cast<double>(p));
          df[c] += term;
          f[c] *= (l[c] - t / static_cast<double>(p)) / ((m - t) / static_cast<double>(p));
        }
      }
      const double d0 = df[0] * f[1] * f[2], d1 = f[0] * df[1] * f[2], d2 = f[0] * f[1] * df[2];
      (*g)[i] = Eigen::Vector2d(d1 - d0, d2 - d0);  // λ0 = 1 − ξ − η
    }
  }
  /// N_i(ξ, η) for every node.
  void values(double xi, double eta, std::vector<double>* N) const {
    const double l[3] = {1 - xi - eta, xi, eta};
    N->resize(nodes.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      double f = 1.0;
      for (int c = 0; c < 3; ++c) {
        const int m = nodes[i][static_cast<std::size_t>(c)];
        for (int t = 0; t < m; ++t)
          f *= (l[c] - t / static_cast<double>(p)) / ((m - t) / static_cast<double>(p));
      }
      (*N)[i] = f;
    }
  }
  /// D_h(ξ) = (x_ξ × x_η)·Σ N_i(ξ) n_i against normals given at the nodes.
  double detAgainst(const std::vector<Vec3>& x, const std::vector<Vec3>& nodeNormals, double xi,
                    double eta) const {
    std::vector<double> N;
    values(xi, eta, &N);
    Vec3 n = Vec3::Zero();
    for (std::size_t i = 0; i < N.size(); ++i) n += N[i] * nodeNormals[i];
    return det(x, n, xi, eta);
  }
  /// x_ξ and x_η at (ξ, η).
  void tangents(const std::vector<Vec3>& x, double xi, double eta, Vec3* a, Vec3* b) const {
    std::vector<Eigen::Vector2d> g;
    derivatives(xi, eta, &g);
    *a = Vec3::Zero(), *b = Vec3::Zero();
    for (std::size_t i = 0; i < g.size(); ++i) {
      *a += g[i].x() * x[i];
      *b += g[i].y() * x[i];
    }
  }
  /// x(ξ), and the unit normal of the element's tangent plane there, x_ξ × x_η normalized.
  Vec3 point(const std::vector<Vec3>& x, double xi, double eta, Vec3* planeNormal) const {
    std::vector<double> N;
    values(xi, eta, &N);
    Vec3 p = Vec3::Zero();
    for (std::size_t i = 0; i < N.size(); ++i) p += N[i] * x[i];
    Vec3 a, b;
    tangents(x, xi, eta, &a, &b);
    *planeNormal = a.cross(b).normalized();
    return p;
  }
  /// D(ξ) = (x_ξ × x_η)·n.
  double det(const std::vector<Vec3>& x, const Vec3& n, double xi, double eta) const {
    Vec3 a, b;
    tangents(x, xi, eta, &a, &b);
    return a.cross(b).dot(n);
  }
};

/// Smallest D over the barycentric grid (i/N, j/N), i + j ≤ N, with the derivatives of the
/// shape functions at the grid computed once per order and N.
struct DenseGrid {
  int p, N;
  std::vector<Eigen::Vector2d> points;
  std::vector<std::vector<Eigen::Vector2d>> grad;
  DenseGrid(int order, int divisions) : p(order), N(divisions) {
    const Lagrange L(order);
    for (int j = 0; j <= N; ++j)
      for (int i = 0; i + j <= N; ++i) {
        points.emplace_back(static_cast<double>(i) / N, static_cast<double>(j) / N);
        grad.emplace_back();
        L.derivatives(points.back().x(), points.back().y(), &grad.back());
      }
  }
  /// min D and where.
  double min(const std::vector<Vec3>& x, const Vec3& n, Eigen::Vector2d* at = nullptr) const {
    double lo = INFINITY;
    for (std::size_t q = 0; q < points.size(); ++q) {
      Vec3 a = Vec3::Zero(), b = Vec3::Zero();
      for (std::size_t i = 0; i < x.size(); ++i) {
        a += grad[q][i].x() * x[i];
        b += grad[q][i].y() * x[i];
      }
      const double d = a.cross(b).dot(n);
      if (d < lo) {
        lo = d;
        if (at) *at = points[q];
      }
    }
    return lo;
  }
};

const DenseGrid& dense200(int p) {
  static const DenseGrid g[5] = {DenseGrid(1, 200), DenseGrid(2, 200), DenseGrid(3, 200),
                                 DenseGrid(4, 200), DenseGrid(5, 200)};
  return g[p - 1];
}

// ---- hand-made elements -----------------------------------------------------------------------

/// The order-p element whose nodes are φ at the reference nodes (every node exactly on the
/// surface φ), with n = the sum of the corner normals ν (as elementReferenceNormal).
struct Element {
  int p = 2;
  std::vector<Vec3> x;
  Vec3 n;
};

template <class Phi, class Nu>
Element onSurface(int p, Phi phi, Nu nu) {
  Element e;
  e.p = p;
  const int count = (p + 1) * (p + 2) / 2;
  for (int i = 0; i < count; ++i) e.x.push_back(phi(nodeXi(p, i)));
  e.n = (nu(nodeXi(p, 0)) + nu(nodeXi(p, 1)) + nu(nodeXi(p, 2))).normalized();
  return e;
}

/// A flat element: the reference triangle mapped affinely to (0,0,0), (2,0.3,0), (0.5,1.7,0),
/// tilted out of the xy plane.
Element flat(int p) {
  const Vec3 o(0.2, -0.1, 0.4), e1(2.0, 0.3, 0.5), e2(0.5, 1.7, -0.3);
  const Vec3 nu = e1.cross(e2).normalized();
  return onSurface(
      p, [&](const Eigen::Vector2d& s) { return Vec3(o + s.x() * e1 + s.y() * e2); },
      [&](const Eigen::Vector2d&) { return nu; });
}

/// On the unit sphere: the flat triangle (0.6,0,1), (0,0.6,1)… projected radially (a spherical
/// triangle of about 50°, outward normals).
Element sphere(int p) {
  const Vec3 a(-0.5, -0.4, 1.0), b(0.6, -0.3, 1.0), c(0.0, 0.6, 1.0);
  auto phi = [&](const Eigen::Vector2d& s) {
    return Vec3((a + s.x() * (b - a) + s.y() * (c - a)).normalized());
  };
  return onSurface(p, phi, phi);
}

/// On the cylinder of radius 1 about z: θ = 1.4 ξ + 0.3 η, z = 0.2 ξ + 1.1 η (outward normals).
Element cylinder(int p) {
  auto theta = [](const Eigen::Vector2d& s) { return 1.4 * s.x() + 0.3 * s.y(); };
  return onSurface(
      p,
      [&](const Eigen::Vector2d& s) {
        return Vec3(std::cos(theta(s)), std::sin(theta(s)), 0.2 * s.x() + 1.1 * s.y());
      },
      [&](const Eigen::Vector2d& s) { return Vec3(std::cos(theta(s)), std::sin(theta(s)), 0); });
}

/// The current sampled check (quality report, optimizer): det S ≤ 0 at a node or at a
/// quadrature point.
/// The sampled check alone: det S at the element's nodes and quadrature points (the measure's
/// evaluation from precomputed Jacobians, which leaves the certificate to its caller).
bool sampledTangled(const Element& e) {
  if (e.p == 1)
    return elementDistortion(measureByName("shape"), typeOf(e.p), e.x.data(), e.n, 0.0).tangled;
  HighOrderJacobians pre;
  highOrderJacobians(typeOf(e.p), e.x.data(), -1, &pre);
  return highOrderTriangleDistortion(measureByName("shape"), pre, Vec3::Zero(), e.n, 0.0, nullptr,
                                     nullptr, nullptr)
      .tangled;
}

/// The measures' verdict (elementDistortion: the samples, then the certificate).
bool measureTangled(const Element& e) {
  return elementDistortion(measureByName("shape"), typeOf(e.p), e.x.data(), e.n, 0.0).tangled;
}

JacobianCertificate certify(const Element& e) {
  return certifyElementJacobian(typeOf(e.p), e.x.data(), e.n);
}

/// (d): a verdict checked against the dense grid and the independent determinant.
void expectAgreesWithDenseSampling(const Element& e, const JacobianCertificate& c,
                                   const char* what) {
  const double dmin = dense200(e.p).min(e.x, e.n);
  if (c.sign == JacobianSign::Positive) {
    EXPECT_GT(dmin, 0.0) << what;
    EXPECT_LE(c.lowerBound, dmin * (1 + 1e-9)) << what;  // a lower bound indeed
  }
  if (c.sign == JacobianSign::NonPositive) {
    const double v = Lagrange(e.p).det(e.x, e.n, c.point.x(), c.point.y());
    EXPECT_LE(v, c.tolerance) << what << " at (" << c.point.transpose() << ")";
    EXPECT_NEAR(v, c.value, std::max(c.tolerance, 1e-300)) << what;
    EXPECT_GE(c.point.x(), -1e-15);
    EXPECT_GE(c.point.y(), -1e-15);
    EXPECT_LE(c.point.x() + c.point.y(), 1 + 1e-15);
  }
  // The first expansion bounds D from below (Bernstein hull).
  EXPECT_LE(c.minCoefficient, dmin + c.tolerance) << what;
}

/// Searches random perturbations of `base` (every node moved in 3D by up to `amp` of its size,
/// fixed seed) for an element folded only between the points the sampled check looks at: the
/// sampled check says valid while the dense grid finds D < −0.1 % of the element's scale.
bool findHiddenFold(const Element& base, double amp, unsigned seed, Element* out, int* tried) {
  std::mt19937 rng(seed);
  const double size = (base.x[1] - base.x[0]).norm();
  std::uniform_real_distribution<double> u(-amp * size, amp * size);
  const DenseGrid grid(base.p, 60);
  const double scale = (base.x[1] - base.x[0]).cross(base.x[2] - base.x[0]).norm();
  for (int trial = 0; trial < 100000; ++trial) {
    Element e = base;
    for (Vec3& xi : e.x) xi += Vec3(u(rng), u(rng), u(rng));
    if (sampledTangled(e)) continue;
    if (grid.min(e.x, e.n) < -1e-3 * scale) {
      *out = e;
      *tried = trial + 1;
      return true;
    }
  }
  return false;
}

}  // namespace

// ---- (a) valid curved elements -----------------------------------------------------------------

TEST(JacobianCertificate, ValidCurvedElementsAreCertifiedPositive) {
  for (int p : {2, 3}) {
    for (const Element& e : {flat(p), sphere(p), cylinder(p)}) {
      const JacobianCertificate c = certify(e);
      EXPECT_EQ(c.sign, JacobianSign::Positive) << "p = " << p;
      EXPECT_FALSE(sampledTangled(e));
      EXPECT_GT(c.lowerBound, 0.0);
      EXPECT_GE(c.ratio, 0.0);
      EXPECT_LE(c.ratio, 1.0 + 1e-12);
      expectAgreesWithDenseSampling(e, c, "valid");
    }
  }
  // A straight-sided element: D constant, the first expansion is exact (ratio 1, one piece).
  for (int p = 1; p <= 5; ++p) {
    const JacobianCertificate c = certify(flat(p));
    EXPECT_EQ(c.sign, JacobianSign::Positive);
    EXPECT_NEAR(c.ratio, 1.0, 1e-12);
    EXPECT_EQ(c.pieces, 1);
    EXPECT_EQ(c.depth, 0);
  }
}

TEST(JacobianCertificate, ReversedNormalOrZeroNormalOrNonFiniteNodesAreNotCertified) {
  for (int p : {2, 3})
    for (Element e : {sphere(p), cylinder(p)}) {
      e.n = -e.n;
      const JacobianCertificate c = certify(e);
      EXPECT_EQ(c.sign, JacobianSign::NonPositive);
      expectAgreesWithDenseSampling(e, c, "reversed");
      // Corner normals that cancel: n = 0 (kNormalCancelTol), invalid.
      e.n = Vec3::Zero();
      EXPECT_EQ(certify(e).sign, JacobianSign::NonPositive);
      e.n = Vec3(0, 0, 1);
      e.x[4].x() = NAN;
      EXPECT_EQ(certify(e).sign, JacobianSign::Undecided);
      EXPECT_FALSE(elementCertifiedValid(typeOf(p), e.x.data(), e.n));
    }
}

// ---- (b) folded at a corner --------------------------------------------------------------------

TEST(JacobianCertificate, SideNodeBeyondTheQuarterPointFoldsTheCorner) {
  // P2: x_ξ(0) along edge 0-1 is −3x0 + 4x3 − x1, reversed once x3 is nearer x0 than ¼ of the
  // edge. P3: x_ξ(0) = (−11x0 + 18x3 − 9x4 + 2x1)/2, reversed for x3 below 2/9.
  for (int p : {2, 3}) {
    const double s = 0.15;  // below ¼ (P2) and 2/9 (P3)
    const Element bases[3] = {flat(p), sphere(p), cylinder(p)};
    for (const Element& base : bases) {
      Element e = base;
      // Node 3 at the fraction s of edge 0-1 (on the chord, and projected back to the sphere /
      // cylinder position by keeping its offset from the chord).
      const Vec3 chord = base.x[0] + (base.x[1] - base.x[0]) / p;
      e.x[3] = base.x[3] - chord + base.x[0] + s * (base.x[1] - base.x[0]);
      const JacobianCertificate c = certify(e);
      ASSERT_EQ(c.sign, JacobianSign::NonPositive) << "p = " << p;
      EXPECT_LT(c.value, 0.0);
      EXPECT_LT(c.point.norm(), 0.2) << "near corner 0: " << c.point.transpose();
      EXPECT_TRUE(sampledTangled(e));  // a node sees this one
      expectAgreesWithDenseSampling(e, c, "corner fold");
    }
    // Exactly at the quarter point (P2), flat: D = 0 at the corner, counted as a fold.
    if (p == 2) {
      Element e = flat(2);
      e.x[3] = e.x[0] + 0.25 * (e.x[1] - e.x[0]);
      const JacobianCertificate c = certify(e);
      EXPECT_EQ(c.sign, JacobianSign::NonPositive);
      EXPECT_NEAR(c.point.norm(), 0.0, 1e-12);
      EXPECT_LE(std::abs(c.value), c.tolerance);
    }
  }
}

// ---- (c) folded between the sampled points -----------------------------------------------------

TEST(JacobianCertificate, FoldBetweenNodesAndQuadraturePointsIsFound) {
  struct Case {
    const char* name;
    Element base;
    double amp;
  };
  for (int p : {2, 3}) {
    const Case cases[] = {
        {"flat", flat(p), 0.15}, {"sphere", sphere(p), 0.15}, {"cylinder", cylinder(p), 0.15}};
    for (const Case& k : cases) {
      Element e;
      int tried = 0;
      ASSERT_TRUE(findHiddenFold(k.base, k.amp, 11u + static_cast<unsigned>(p), &e, &tried))
          << k.name << " p = " << p;
      // The sampled check (nodes + the quadrature points of highOrderJacobians) says valid…
      EXPECT_FALSE(sampledTangled(e));
      // …and the measures, which certify what the samples find valid, call it tangled.
      EXPECT_TRUE(measureTangled(e));
      HighOrderJacobians pre;
      highOrderJacobians(typeOf(p), e.x.data(), -1, &pre);
      const auto& rule = highOrderTriangleRule(p);
      for (int q = 0; q < rule.nodes; ++q)
        EXPECT_GT(pre.atNode[q].col(0).cross(pre.atNode[q].col(1)).dot(e.n), 0.0);
      for (std::size_t q = 0; q < rule.quadrature->points.size(); ++q)
        EXPECT_GT(pre.atPoint[q].col(0).cross(pre.atPoint[q].col(1)).dot(e.n), 0.0);
      // …and the independent determinant agrees at those points,
      const Lagrange L(p);
      for (int q = 0; q < rule.nodes; ++q)
        EXPECT_GT(L.det(e.x, e.n, nodeXi(p, q).x(), nodeXi(p, q).y()), 0.0);
      for (const auto& xq : rule.quadrature->points)
        EXPECT_GT(L.det(e.x, e.n, xq.x(), xq.y()), 0.0);
      // …while the certificate proves the fold.
      const JacobianCertificate c = certify(e);
      EXPECT_EQ(c.sign, JacobianSign::NonPositive) << k.name << " p = " << p;
      EXPECT_LT(c.value, 0.0);
      expectAgreesWithDenseSampling(e, c, "hidden fold");
      Eigen::Vector2d at;
      const double dmin = dense200(p).min(e.x, e.n, &at);
      std::printf(
          "p = %d %-8s hidden fold (trial %d): dense min %.4g at (%.3f, %.3f), certificate %.4g "
          "at (%.3f, %.3f), depth %d, %d pieces\n",
          p, k.name, tried, dmin, at.x(), at.y(), c.value, c.point.x(), c.point.y(), c.depth,
          c.pieces);
    }
  }
}

// ---- (e) random perturbations ------------------------------------------------------------------

TEST(JacobianCertificate, RandomPerturbationsAgreeWithDenseSampling) {
  // Every node of a flat, spherical or cylindrical element moved by up to `amp` of the element's
  // size in 3D (fixed seeds): a Positive verdict never where the grid finds D ≤ 0; every
  // NonPositive point really has D ≤ τ; Undecided rare.
  for (int p : {2, 3, 4, 5}) {
    const DenseGrid grid(p, p <= 3 ? 100 : 60);
    const Lagrange L(p);
    std::mt19937 rng(1000u + static_cast<unsigned>(p));
    const int trials = p <= 4 ? 3000 : 600;
    int positive = 0, nonPositive = 0, undecided = 0;
    int gridNegative = 0, missedByGrid = 0, hiddenFromSampling = 0, sampledTangledCount = 0;
    int maxPieces = 0, subdivided = 0;
    bool depthLimitChecked = false;
    for (int t = 0; t < trials; ++t) {
      const int kind = t % 3;
      Element e = kind == 0 ? flat(p) : kind == 1 ? sphere(p) : cylinder(p);
      const double size = (e.x[1] - e.x[0]).norm();
      const double amp = (t % 5 + 1) * 0.08 * size / p;
      std::uniform_real_distribution<double> u(-amp, amp);
      for (std::size_t i = 0; i < e.x.size(); ++i) e.x[i] += Vec3(u(rng), u(rng), u(rng));
      const JacobianCertificate c = certify(e);
      const double dmin = grid.min(e.x, e.n);
      const bool sampled = sampledTangled(e);
      sampledTangledCount += sampled;
      // The measures' verdict: tangled when the samples or the certificate say so.
      EXPECT_EQ(measureTangled(e), sampled || c.sign != JacobianSign::Positive)
          << "p = " << p << " trial " << t;
      gridNegative += dmin <= 0.0;
      maxPieces = std::max(maxPieces, c.pieces);
      EXPECT_LE(c.minCoefficient, dmin + c.tolerance) << "p = " << p << " trial " << t;
      switch (c.sign) {
        case JacobianSign::Positive:
          ++positive;
          if (c.depth > 0) {
            ++subdivided;
            // Proven only by subdivision: without it, Undecided (never a wrong verdict).
            if (!depthLimitChecked) {
              const JacobianCertificate c0 = certifyTriangleJacobian(p, e.x.data(), e.n, 0);
              EXPECT_EQ(c0.sign, JacobianSign::Undecided);
              EXPECT_LE(c0.minCoefficient, c0.tolerance);
              depthLimitChecked = true;
            }
          }
          EXPECT_GT(dmin, 0.0) << "p = " << p << " trial " << t;
          EXPECT_LE(c.lowerBound, dmin * (1 + 1e-9) + c.tolerance);
          EXPECT_FALSE(sampled) << "certified but the samples see a fold: p = " << p << " " << t;
          break;
        case JacobianSign::NonPositive: {
          ++nonPositive;
          const double v = L.det(e.x, e.n, c.point.x(), c.point.y());
          EXPECT_LE(v, c.tolerance) << "p = " << p << " trial " << t;
          missedByGrid += dmin > 0.0;
          hiddenFromSampling += !sampled;
          break;
        }
        case JacobianSign::Undecided:
          ++undecided;
          break;
      }
    }
    std::printf(
        "p = %d, %d elements: certificate %d positive, %d non-positive, %d undecided; "
        "grid D <= 0 in %d; sampled check tangled %d; folds the sampled check misses %d; "
        "folds the grid misses %d; positive by subdivision %d; most pieces %d\n",
        p, trials, positive, nonPositive, undecided, gridNegative, sampledTangledCount,
        hiddenFromSampling, missedByGrid, subdivided, maxPieces);
    EXPECT_GT(positive, trials / 10);
    EXPECT_GT(nonPositive, trials / 10);
    EXPECT_LE(undecided, trials / 200);
  }
}

// ---- against the surface's normal inside the element ------------------------------------------

namespace {

/// The cylinder of radius 1 about z at (θ, z), and its outward normal.
Vec3 cylinderPoint(double theta, double z) { return Vec3(std::cos(theta), std::sin(theta), z); }
/// The cylinder's normal at the point closest to x: the horizontal direction of x.
Vec3 cylinderNormalNear(const Vec3& x) { return Vec3(x.x(), x.y(), 0).normalized(); }

/// A P-order element on the cylinder with its nodes at reference node ξ_i mapped to
/// (θ, z) = (a ξ + b η, c ξ + d η) plus per-node offsets in (θ, z) (nodes stay on the surface).
struct CylinderElement {
  Element e;
  std::vector<Vec3> normals;  ///< the cylinder's normal at every node
};

CylinderElement onCylinder(int p, double a, double b, double c, double d, std::mt19937* rng,
                           double jitter) {
  std::uniform_real_distribution<double> u(-jitter, jitter);
  CylinderElement r;
  r.e.p = p;
  const int count = (p + 1) * (p + 2) / 2;
  Vec3 sum = Vec3::Zero();
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d s = nodeXi(p, i);
    const double th = a * s.x() + b * s.y() + u(*rng), z = c * s.x() + d * s.y() + u(*rng);
    r.e.x.push_back(cylinderPoint(th, z));
    r.normals.push_back(cylinderNormalNear(r.e.x.back()));
    if (i < 3) sum += r.normals.back();
  }
  r.e.n = sum.normalized();
  return r;
}

}  // namespace

TEST(JacobianCertificate, AgainstNodeNormalsAgreesWithDenseSampling) {
  // Random elements of order 1…5 on the cylinder, wide in θ (up to 1.8 rad) and with their
  // nodes moved on the surface: the certificate of D_h = (x_ξ × x_η)·Σ N_i n_i against a dense
  // grid of D_h computed here from the textbook Lagrange functions — a Positive verdict never
  // where the grid finds D_h ≤ 0, a lower bound below the grid's minimum, every NonPositive
  // point confirmed; and both verdicts occur.
  for (int p : {1, 2, 3, 4, 5}) {
    std::mt19937 rng(77u + static_cast<unsigned>(p));
    std::uniform_real_distribution<double> wide(0.3, 1.8), tall(0.3, 1.2);
    const Lagrange L(p);
    const int N = p <= 3 ? 60 : 30;
    const int trials = p <= 3 ? 600 : 200;
    int positive = 0, nonPositive = 0, undecided = 0;
    for (int t = 0; t < trials; ++t) {
      const CylinderElement ce = onCylinder(p, wide(rng), 0.2 * wide(rng), 0.1 * tall(rng),
                                            tall(rng), &rng, (t % 4) * 0.1 / p);
      const JacobianCertificate c =
          certifyTriangleAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data());
      double dmin = INFINITY;
      for (int j = 0; j <= N; ++j)
        for (int i = 0; i + j <= N; ++i)
          dmin = std::min(dmin, L.detAgainst(ce.e.x, ce.normals, static_cast<double>(i) / N,
                                             static_cast<double>(j) / N));
      switch (c.sign) {
        case JacobianSign::Positive:
          ++positive;
          EXPECT_GT(dmin, 0.0) << "p = " << p << " trial " << t;
          EXPECT_LE(c.lowerBound, dmin * (1 + 1e-9) + c.tolerance) << "p = " << p << " " << t;
          break;
        case JacobianSign::NonPositive:
          ++nonPositive;
          EXPECT_LE(L.detAgainst(ce.e.x, ce.normals, c.point.x(), c.point.y()), c.tolerance)
              << "p = " << p << " trial " << t;
          break;
        case JacobianSign::Undecided:
          ++undecided;
          break;
      }
      // At the corners D_h is the corner test of standsAcross.
      Vec3 corners[3] = {ce.normals[0], ce.normals[1], ce.normals[2]};
      if (cornerSides(typeOf(p), ce.e.x.data(), corners).against)
        EXPECT_NE(c.sign, JacobianSign::Positive) << "p = " << p << " trial " << t;
    }
    std::printf(
        "p = %d, %d elements against their node normals: %d positive, %d non-positive, "
        "%d undecided\n",
        p, trials, positive, nonPositive, undecided);
    EXPECT_GT(positive, trials / 10);
    if (p > 1) EXPECT_GT(nonPositive, trials / 25);
    EXPECT_LE(undecided, trials / 100);
  }
}

TEST(JacobianCertificate, TurnedAcrossTheSurfaceInsideIsNotCertified) {
  // Elements on the cylinder that the certificate against their fixed reference normal calls
  // valid, wound along the surface at every corner, but whose tangent plane turns against the
  // cylinder's normal inside: the certificate against the node normals finds them, and its
  // point is confirmed with the cylinder's own normal at the closest point of the surface (not
  // the interpolated one). Searched among random on-surface elements (fixed seed).
  for (int p : {2, 3}) {
    std::mt19937 rng(5u + static_cast<unsigned>(p));
    std::uniform_real_distribution<double> wide(p == 2 ? 2.0 : 1.2, p == 2 ? 3.0 : 2.2),
        tall(0.2, 0.8);
    const Lagrange L(p);
    int found = 0, tried = 0;
    for (; tried < 20000 && found < 5; ++tried) {
      const CylinderElement ce =
          onCylinder(p, wide(rng), 0.1 * wide(rng), 0.05, tall(rng), &rng, p == 2 ? 0.3 : 0.125);
      if (certify(ce.e).sign != JacobianSign::Positive) continue;
      Vec3 corners[3] = {ce.normals[0], ce.normals[1], ce.normals[2]};
      if (cornerSides(typeOf(p), ce.e.x.data(), corners).against) continue;
      const JacobianCertificate c =
          certifyTriangleAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data());
      if (c.sign == JacobianSign::Positive) continue;
      ASSERT_EQ(c.sign, JacobianSign::NonPositive);
      // The independent judge: det J against the cylinder's normal at the projection of x(ξ),
      // at the certificate's point or next to it (a 1 % neighbourhood on a fine grid).
      double worst = INFINITY;
      for (int dj = -5; dj <= 5; ++dj)
        for (int di = -5; di <= 5; ++di) {
          const double xi = c.point.x() + di * 0.002, eta = c.point.y() + dj * 0.002;
          if (xi < 0 || eta < 0 || xi + eta > 1) continue;
          Vec3 plane;
          const Vec3 x = L.point(ce.e.x, xi, eta, &plane);
          worst = std::min(worst, plane.dot(cylinderNormalNear(x)));
        }
      EXPECT_LT(worst, 0.02) << "p = " << p;
      ++found;
    }
    std::printf(
        "p = %d: %d elements valid against their reference normal but turned across the "
        "cylinder inside, in %d tried\n",
        p, found, tried);
    EXPECT_EQ(found, 5) << "p = " << p;
  }
}

TEST(JacobianCertificate, OnPiecesTheFacesOwnNormalsDecide) {
  // (1) A plane element, valid against the plane's normal, whose node normals say otherwise
  // at one corner (a normal turned by 150°, as at a B-spline patch's nearly collapsed corner):
  // the interpolation of the node normals cannot prove it; on pieces, with the face's own
  // normal, it is proven at once; with the opposite one it is not.
  const Element plane = flat(2);
  std::vector<Vec3> normals(plane.x.size(), plane.n);
  const Vec3 t = (plane.x[1] - plane.x[0]).normalized();
  normals[2] = std::cos(2.6) * plane.n + std::sin(2.6) * t;
  ASSERT_FALSE(triangleJacobianPositiveAgainstNodeNormals(2, plane.x.data(), normals.data()));
  const FaceNormalAt up = [&](const Eigen::Vector2d&) { return plane.n; };
  const FaceNormalAt down = [&](const Eigen::Vector2d&) { return Vec3(-plane.n); };
  EXPECT_TRUE(triangleJacobianPositiveOnPieces(2, plane.x.data(), normals.data(), up));
  EXPECT_FALSE(triangleJacobianPositiveOnPieces(2, plane.x.data(), normals.data(), down));
  EXPECT_FALSE(triangleJacobianPositiveOnPieces(2, plane.x.data(), normals.data(), up, 0));
  // (2) Elements on the cylinder that the node normals cannot prove, among random ones (fixed
  // seed), decided on pieces with the cylinder's normal at the closest point of x(ξ), each
  // verdict checked against det J with that normal on a dense grid (positive: positive at
  // every grid point; refused: not above 2 % of the element's scale somewhere). On the
  // cylinder, whose normal turns slowly, the interpolation of the node normals is right: all
  // are refused, as they are turned across the cylinder inside.
  for (int p : {2, 3}) {
    std::mt19937 rng(11u + static_cast<unsigned>(p));
    std::uniform_real_distribution<double> wide(1.0, 3.2), tall(0.2, 0.8);
    const Lagrange L(p);
    int proven = 0, refused = 0, tried = 0;
    for (; tried < 20000 && refused < 20; ++tried) {
      const CylinderElement ce =
          onCylinder(p, wide(rng), 0.1 * wide(rng), 0.05, tall(rng), &rng, p == 2 ? 0.3 : 0.125);
      if (certify(ce.e).sign != JacobianSign::Positive) continue;
      if (triangleJacobianPositiveAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data())) continue;
      const FaceNormalAt cylinderNormal = [&](const Eigen::Vector2d& xi) {
        Vec3 plane;
        return cylinderNormalNear(L.point(ce.e.x, xi.x(), xi.y(), &plane));
      };
      const bool positive =
          triangleJacobianPositiveOnPieces(p, ce.e.x.data(), ce.normals.data(), cylinderNormal);
      double worst = INFINITY;
      const int n = 60;
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i + j <= n; ++i) {
          Vec3 plane;
          const Vec3 x = L.point(ce.e.x, double(i) / n, double(j) / n, &plane);
          worst = std::min(worst, plane.dot(cylinderNormalNear(x)));
        }
      if (positive) {
        EXPECT_GT(worst, 0.0) << "p = " << p;
        ++proven;
      } else {
        EXPECT_LT(worst, 0.02) << "p = " << p;
        ++refused;
      }
    }
    std::printf(
        "p = %d: of the elements the node normals cannot prove, %d proven on pieces and "
        "%d refused, in %d tried\n",
        p, proven, refused, tried);
    EXPECT_EQ(refused, 20) << "p = " << p;
  }
}

TEST(JacobianCertificate, AgainstNodeNormalsAtAPoleAndWithoutNormals) {
  // A zero normal (a node at a pole) takes the others' direction; no normal at all: D_h ≡ 0.
  const Element s = sphere(2);
  std::vector<Vec3> normals;
  for (const Vec3& x : s.x) normals.push_back(x.normalized());
  EXPECT_EQ(certifyTriangleAgainstNodeNormals(2, s.x.data(), normals.data()).sign,
            JacobianSign::Positive);
  normals[0] = Vec3::Zero();
  EXPECT_EQ(certifyTriangleAgainstNodeNormals(2, s.x.data(), normals.data()).sign,
            JacobianSign::Positive);
  for (Vec3& n : normals) n = -n;
  EXPECT_EQ(certifyTriangleAgainstNodeNormals(2, s.x.data(), normals.data()).sign,
            JacobianSign::NonPositive);
  for (Vec3& n : normals) n = Vec3::Zero();
  EXPECT_EQ(certifyTriangleAgainstNodeNormals(2, s.x.data(), normals.data()).sign,
            JacobianSign::NonPositive);
  normals[1] = Vec3(NAN, 0, 0);
  EXPECT_EQ(certifyTriangleAgainstNodeNormals(2, s.x.data(), normals.data()).sign,
            JacobianSign::Undecided);
}

TEST(JacobianCertificate, BezierBoundIsTheFirstExpansionAndTheVerdictIsTheCertificates) {
  // The Bernstein coefficients from the Bézier control points (products of Bernstein
  // polynomials) against the certificate's from its samples: the same smallest coefficient up
  // to rounding, a margin at least the certificate's, the same verdict through
  // triangleJacobianPositive…; and the quick proof concludes on most valid elements.
  for (int p : {1, 2, 3, 4, 5}) {
    std::mt19937 rng(4242u + static_cast<unsigned>(p));
    const int trials = p <= 3 ? 1500 : 600;
    int positive = 0, quick = 0, other = 0;
    for (int t = 0; t < trials; ++t) {
      const int kind = t % 3;
      Element e = kind == 0 ? flat(p) : kind == 1 ? sphere(p) : cylinder(p);
      const double size = (e.x[1] - e.x[0]).norm();
      std::uniform_real_distribution<double> u(-1.0, 1.0);
      const double amp = (t % 5 + 1) * 0.08 * size / p;
      for (Vec3& x : e.x) x += amp * Vec3(u(rng), u(rng), u(rng));
      const JacobianCertificate c = certifyTriangleJacobian(p, e.x.data(), e.n);
      const CoefficientBound b = bezierCoefficientBound(p, e.x.data(), e.n);
      EXPECT_NEAR(b.minCoefficient, c.minCoefficient, 0.1 * b.tolerance)
          << "p = " << p << " trial " << t;
      EXPECT_GE(b.tolerance, c.tolerance * (1 - 1e-12)) << "p = " << p << " trial " << t;
      const bool certified = c.sign == JacobianSign::Positive;
      EXPECT_EQ(triangleJacobianPositive(p, e.x.data(), e.n), certified)
          << "p = " << p << " trial " << t;
      EXPECT_EQ(elementCertifiedValid(typeOf(p), e.x.data(), e.n), certified);
      positive += certified;
      quick += b.minCoefficient > b.tolerance;
      other += !certified;
    }
    std::printf("p = %d: %d of %d certified positive, %d of them by the Bezier bound alone\n", p,
                positive, trials, quick);
    if (p > 1) EXPECT_GT(other, 0) << "p = " << p;
    EXPECT_LE(quick, positive);
    // Curved elements as a smoothed mesh has them (every node moved by up to 0.05 size / p²):
    // the first expansion decides.
    int mild = 0, mildQuick = 0;
    for (int t = 0; t < 300; ++t) {
      Element e = t % 2 ? sphere(p) : cylinder(p);
      const double size = (e.x[1] - e.x[0]).norm(), amp = 0.05 * size / (p * p);
      std::uniform_real_distribution<double> u(-amp, amp);
      for (Vec3& x : e.x) x += Vec3(u(rng), u(rng), u(rng));
      mild += triangleJacobianPositive(p, e.x.data(), e.n);
      const CoefficientBound b = bezierCoefficientBound(p, e.x.data(), e.n);
      mildQuick += b.minCoefficient > b.tolerance;
    }
    EXPECT_EQ(mild, 300) << "p = " << p;
    EXPECT_EQ(mildQuick, 300) << "p = " << p;
  }
  // Against the nodes' normals, on the cylinder.
  for (int p : {1, 2, 3, 4, 5}) {
    std::mt19937 rng(99u + static_cast<unsigned>(p));
    std::uniform_real_distribution<double> wide(0.3, 1.8), tall(0.3, 1.2);
    const int trials = p <= 3 ? 600 : 200;
    int positive = 0, quick = 0;
    for (int t = 0; t < trials; ++t) {
      const CylinderElement ce = onCylinder(p, wide(rng), 0.2 * wide(rng), 0.1 * tall(rng),
                                            tall(rng), &rng, (t % 4) * 0.1 / p);
      const JacobianCertificate c =
          certifyTriangleAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data());
      const CoefficientBound b =
          bezierCoefficientBoundAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data());
      EXPECT_NEAR(b.minCoefficient, c.minCoefficient, 0.1 * b.tolerance)
          << "p = " << p << " trial " << t;
      EXPECT_GE(b.tolerance, c.tolerance * (1 - 1e-12)) << "p = " << p << " trial " << t;
      const bool certified = c.sign == JacobianSign::Positive;
      EXPECT_EQ(triangleJacobianPositiveAgainstNodeNormals(p, ce.e.x.data(), ce.normals.data()),
                certified)
          << "p = " << p << " trial " << t;
      positive += certified;
      quick += b.minCoefficient > b.tolerance;
    }
    std::printf("p = %d against node normals: %d of %d positive, %d by the Bezier bound\n", p,
                positive, trials, quick);
    EXPECT_GT(quick, positive / 2) << "p = " << p;
    EXPECT_LE(quick, positive);
  }
  // A pole's zero normal, no normal at all, a non-finite one: the certificate's verdicts.
  const Element s = sphere(3);
  std::vector<Vec3> normals;
  for (const Vec3& x : s.x) normals.push_back(x.normalized());
  normals[0] = Vec3::Zero();
  EXPECT_TRUE(triangleJacobianPositiveAgainstNodeNormals(3, s.x.data(), normals.data()));
  EXPECT_GT(bezierCoefficientBoundAgainstNodeNormals(3, s.x.data(), normals.data()).minCoefficient,
            0.0);
  for (Vec3& n : normals) n = Vec3::Zero();
  EXPECT_FALSE(triangleJacobianPositiveAgainstNodeNormals(3, s.x.data(), normals.data()));
  normals[1] = Vec3(NAN, 0, 0);
  EXPECT_FALSE(triangleJacobianPositiveAgainstNodeNormals(3, s.x.data(), normals.data()));
  EXPECT_FALSE(triangleJacobianPositive(3, s.x.data(), Vec3(NAN, 0, 1)));
  EXPECT_FALSE(triangleJacobianPositive(3, s.x.data(), Vec3::Zero()));
  EXPECT_THROW(triangleJacobianPositive(6, s.x.data(), s.n), std::invalid_argument);
}

// ---- (f) order 1 --------------------------------------------------------------------------------

TEST(JacobianCertificate, OrderOneIsThePlainOrientationTest) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  int agree = 0;
  for (int t = 0; t < 5000; ++t) {
    Element e;
    e.p = 1;
    e.x = {Vec3(g(rng), g(rng), g(rng)), Vec3(g(rng), g(rng), g(rng)),
           Vec3(g(rng), g(rng), g(rng))};
    e.n = Vec3(g(rng), g(rng), g(rng));
    const Vec3 c = (e.x[1] - e.x[0]).cross(e.x[2] - e.x[0]);
    const double o = c.dot(e.n);
    if (std::abs(o) < 1e-6 * c.norm() * e.n.norm()) continue;  // leave out the near-perpendicular
    const JacobianCertificate r = certify(e);
    EXPECT_EQ(r.sign, o > 0 ? JacobianSign::Positive : JacobianSign::NonPositive);
    EXPECT_EQ(r.sign == JacobianSign::Positive, !sampledTangled(e));
    EXPECT_EQ(r.sign == JacobianSign::Positive,
              elementCertifiedValid(ElementType::Tri3, e.x.data(), e.n));
    if (r.sign == JacobianSign::NonPositive) {
      EXPECT_NEAR(r.value, o, 1e-12 * std::abs(o) + 1e-14);
    }
    ++agree;
  }
  EXPECT_GT(agree, 4900);
}

// ---- the dispatcher for quadrilaterals ----------------------------------------------------------

TEST(JacobianCertificate, QuadrilateralsKeepTheirOwnProofs) {
  const Vec3 kZ(0, 0, 1);
  std::vector<Vec3> q8 = {{0, 0, 0},   {1, 0, 0},   {1, 1, 0},   {0, 1, 0},
                          {0.5, 0, 0}, {1, 0.5, 0}, {0.5, 1, 0}, {0, 0.5, 0}};
  EXPECT_TRUE(elementCertifiedValid(ElementType::Quad8, q8.data(), kZ));
  EXPECT_TRUE(elementCertifiedValid(ElementType::Quad4, q8.data(), kZ));
  EXPECT_FALSE(elementCertifiedValid(ElementType::Quad8, q8.data(), -kZ));
  q8[4] = Vec3(0.5, 1.2, 0);  // a side node across the opposite side
  EXPECT_FALSE(elementCertifiedValid(ElementType::Quad8, q8.data(), kZ));
  EXPECT_THROW(certifyElementJacobian(ElementType::Quad8, q8.data(), kZ), std::invalid_argument);
  // Triangles through the dispatcher: the certificate.
  const Element s = sphere(3);
  EXPECT_TRUE(elementCertifiedValid(ElementType::Tri10, s.x.data(), s.n));
  EXPECT_FALSE(elementCertifiedValid(ElementType::Tri10, s.x.data(), -s.n));
  (void)kPi;
}

// ---- the untangling sees a fold between the samples ---------------------------------------------

TEST(JacobianCertificate, UntanglingSeesAFoldBetweenTheSamples) {
  // With δ > 0 the measures add the pointwise distortion at the certificate's fold point to the
  // element's mean: the value rises above the samples' alone, its gradient with respect to a
  // node matches central differences, and gradient steps on the nodes open the fold.
  const PlanarMeasure& m = measureByName("shape");
  for (int p : {2, 3}) {
    Element e;
    int tried = 0;
    ASSERT_TRUE(findHiddenFold(flat(p), 0.15, 11u + static_cast<unsigned>(p), &e, &tried));
    const ElementType t = typeOf(p);
    const double size2 = (e.x[1] - e.x[0]).squaredNorm();
    const double delta = 1e-3 * size2;
    HighOrderJacobians pre;
    highOrderJacobians(t, e.x.data(), -1, &pre);
    const ElementEval samples =
        highOrderTriangleDistortion(m, pre, Vec3::Zero(), e.n, delta, nullptr, nullptr, nullptr);
    ASSERT_FALSE(samples.tangled);
    const ElementEval whole = elementDistortion(m, t, e.x.data(), e.n, delta);
    EXPECT_TRUE(whole.tangled);
    EXPECT_GT(whole.eta, samples.eta) << "p = " << p;
    // Gradient and Hessian with respect to each node, against central differences.
    for (int k = 0; k < static_cast<int>(e.x.size()); ++k) {
      Vec3 g;
      Mat3 H;
      const ElementEval ev = elementDistortion(m, t, e.x.data(), e.n, delta, k, &g, &H);
      ASSERT_TRUE(std::isfinite(ev.eta));
      const double h = 1e-6 * std::sqrt(size2);
      for (int d = 0; d < 3; ++d) {
        std::vector<Vec3> xp = e.x, xm = e.x;
        xp[static_cast<std::size_t>(k)][d] += h;
        xm[static_cast<std::size_t>(k)][d] -= h;
        Vec3 gp, gm;
        Mat3 Hp, Hm;
        const double fp = elementDistortion(m, t, xp.data(), e.n, delta, k, &gp, &Hp).eta;
        const double fm = elementDistortion(m, t, xm.data(), e.n, delta, k, &gm, &Hm).eta;
        EXPECT_NEAR(g[d], (fp - fm) / (2 * h), 1e-5 * (1.0 + g.norm())) << "p " << p << " k " << k;
        EXPECT_LE((H.col(d) - (gp - gm) / (2 * h)).norm(), 1e-4 * (1.0 + H.norm()))
            << "p " << p << " k " << k;
      }
    }
    // Steepest descent with backtracking on the side and interior nodes (corners fixed):
    // the fold opens.
    const int nc = 3;
    bool opened = false;
    for (int it = 0; it < 400 && !opened; ++it) {
      for (int k = nc; k < static_cast<int>(e.x.size()); ++k) {
        Vec3 g;
        Mat3 H;
        const double f0 = elementDistortion(m, t, e.x.data(), e.n, delta, k, &g, &H).eta;
        g -= g.dot(e.n) * e.n;  // in the element's plane
        double step = 0.05 * size2 / (g.norm() + 1e-300);
        for (int ls = 0; ls < 30; ++ls, step *= 0.5) {
          std::vector<Vec3> xt = e.x;
          xt[static_cast<std::size_t>(k)] -= step * g;
          if (elementDistortion(m, t, xt.data(), e.n, delta).eta < f0) {
            e.x = xt;
            break;
          }
        }
      }
      opened = certify(e).sign == JacobianSign::Positive;
    }
    EXPECT_TRUE(opened) << "p = " << p;
    EXPECT_FALSE(elementDistortion(m, t, e.x.data(), e.n, 0.0).tangled);
  }
}
