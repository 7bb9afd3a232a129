// Conformance of every registered planar measure, and of the surface extension (paper §3).
#include "surfmesh/measures/measure.h"

#include "fd_check.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "surfmesh/mesh/quality.h"
#include "test_meshes.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace surfmesh;

namespace {

const double kPi = 3.14159265358979323846;

Mat2 rotation(double a) {
  Mat2 R;
  R << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  return R;
}

Mat2 randomS(std::mt19937& rng, bool positive) {
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (;;) {
    Mat2 S;
    S << u(rng), u(rng), u(rng), u(rng);
    const double d = S.determinant();
    if (positive ? d > 0.2 : std::abs(d) > 0.2) return S;
  }
}

// Planar triangle → S with the equilateral ideal, straight from the definition.
Mat2 planarS(const Vec2& y0, const Vec2& y1, const Vec2& y2) {
  Mat2 A;
  A.col(0) = y1 - y0;
  A.col(1) = y2 - y0;
  return A * equilateralWinv();
}

// Verdict tri_shape: 4√3·A / Σ l² (unsigned), computed independently.
double verdictTriShape(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double area = 0.5 * (b - a).cross(c - a).norm();
  const double l2 = (b - a).squaredNorm() + (c - b).squaredNorm() + (a - c).squaredNorm();
  return 4.0 * std::sqrt(3.0) * area / l2;
}

class MeasureConformance : public ::testing::TestWithParam<std::string> {};

TEST_P(MeasureConformance, IdealElementIsOne) {
  const PlanarMeasure& m = measureByName(GetParam());
  const Vec2 y0(0, 0), y1(1, 0), y2(0.5, std::sqrt(3.0) / 2);
  EXPECT_NEAR(m.value(planarS(y0, y1, y2), 0.0), 1.0, 1e-14);
  // Square corner ideal for quads.
  EXPECT_NEAR(m.value(Mat2::Identity() * squareCornerWinv(), 0.0), 1.0, 1e-14);
}

TEST_P(MeasureConformance, InvariantUnderRotationTranslationScaling) {
  const PlanarMeasure& m = measureByName(GetParam());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 200; ++trial) {
    Vec2 y[3] = {{u(rng), u(rng)}, {u(rng), u(rng)}, {u(rng), u(rng)}};
    Mat2 A;
    A.col(0) = y[1] - y[0];
    A.col(1) = y[2] - y[0];
    if (A.determinant() < 0) std::swap(y[1], y[2]);
    if (std::abs(A.determinant()) < 0.1) continue;
    const double ref = m.value(planarS(y[0], y[1], y[2]), 0.0);
    ASSERT_TRUE(std::isfinite(ref));
    ASSERT_GE(ref, 1.0 - 1e-12);
    const Mat2 R = rotation(u(rng));
    const Vec2 t(u(rng), u(rng));
    const double s = std::exp(u(rng));
    Vec2 z[3];
    for (int k = 0; k < 3; ++k) z[k] = s * (R * y[k]) + t;
    EXPECT_NEAR(m.value(planarS(z[0], z[1], z[2]), 0.0), ref, 1e-10 * ref);
    // A reflected (clockwise) triangle is tangled: η = ∞.
    EXPECT_TRUE(std::isinf(m.value(planarS(y[0], y[2], y[1]), 0.0)));
  }
}

// Finite-difference checks in the manner of MFEM's tmop-check-metric: the error of the
// central difference falls at rate 2 when h is halved.
double fdGradError(const PlanarMeasure& m, const Mat2& S, double delta, double h) {
  Mat2 g;
  m.evaluate(S, delta, &g, nullptr);
  double err = 0.0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      Mat2 Sp = S, Sm = S;
      Sp(i, j) += h;
      Sm(i, j) -= h;
      const double fd = (m.value(Sp, delta) - m.value(Sm, delta)) / (2 * h);
      err = std::max(err, std::abs(fd - g(i, j)));
    }
  return err;
}

double fdHessError(const PlanarMeasure& m, const Mat2& S, double delta, double h) {
  Mat4 H;
  m.evaluate(S, delta, nullptr, &H);
  double err = 0.0;
  for (int a = 0; a < 4; ++a) {
    Mat2 Sp = S, Sm = S;
    Sp(a / 2, a % 2) += h;
    Sm(a / 2, a % 2) -= h;
    Mat2 gp, gm;
    m.evaluate(Sp, delta, &gp, nullptr);
    m.evaluate(Sm, delta, &gm, nullptr);
    for (int b = 0; b < 4; ++b) {
      const double fd = (gp(b / 2, b % 2) - gm(b / 2, b % 2)) / (2 * h);
      err = std::max(err, std::abs(fd - H(a, b)));
    }
  }
  return err;
}

// Gradient and Hessian errors of central differences fall at rate two on 20 random S with
// δ = 0 and δ = 0.3, and are small; `hessPower`: the Hessian's error at h = 1e-3 is bounded by
// 1e-2 (1 + η)^hessPower (the size term is steeper than the registered measures).
void expectDerivativesAtRateTwo(const PlanarMeasure& m, unsigned seed, double hessPower) {
  std::mt19937 rng(seed);
  for (double delta : {0.0, 0.3}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Mat2 S = randomS(rng, delta == 0.0);
      const double h = 1e-3;
      const double e1 = fdGradError(m, S, delta, h), e2 = fdGradError(m, S, delta, h / 2);
      const double h1 = fdHessError(m, S, delta, h), h2 = fdHessError(m, S, delta, h / 2);
      if (e1 > 1e-9) {
        EXPECT_NEAR(e1 / e2, 4.0, 0.5) << m.name() << " gradient, delta=" << delta;
      }
      if (h1 > 1e-9) {
        EXPECT_NEAR(h1 / h2, 4.0, 0.5) << m.name() << " Hessian, delta=" << delta;
      }
      EXPECT_LT(e1, 1e-3 * (1 + m.value(S, delta)));
      EXPECT_LT(h1, 1e-2 * std::pow(1 + m.value(S, delta), hessPower));
    }
  }
}

TEST_P(MeasureConformance, DerivativesConvergeAtRateTwo) {
  const PlanarMeasure& m = measureByName(GetParam());
  ASSERT_TRUE(m.hasHessian());
  expectDerivativesAtRateTwo(m, 11, 1.0);
}

TEST_P(MeasureConformance, RegularizedIsFiniteForTangledAndTendsToBarrier) {
  const PlanarMeasure& m = measureByName(GetParam());
  Mat2 S;
  S << 1.0, 0.3, 0.2, -0.8;  // det < 0
  EXPECT_TRUE(std::isinf(m.value(S, 0.0)));
  EXPECT_TRUE(std::isfinite(m.value(S, 0.1)));
  S(1, 1) = 0.9;  // valid: σ* → σ as δ → 0
  EXPECT_NEAR(m.value(S, 1e-9), m.value(S, 0.0), 1e-8);
}

INSTANTIATE_TEST_SUITE_P(AllMeasures, MeasureConformance, ::testing::ValuesIn(measureNames()));

// The size term of the straight-sided reference (SizedMeasure): 1 exactly on rotations, above
// 1 on a scaled copy (where the base measure is 1), and its partials in F and σ, through
// PlanarMeasure::evaluate, converge at rate two like the registered measures'.
TEST(SizedMeasure, OneOnRotationsAboveOneOnScaledCopiesDerivativesAtRateTwo) {
  for (const std::string& name : measureNames()) {
    const PlanarMeasure& base = measureByName(name);
    const SizedMeasure m(base);
    EXPECT_FALSE(m.scaleInvariant());
    for (double a : {0.0, 0.7, 2.5}) {
      EXPECT_NEAR(m.value(rotation(a), 0.0), 1.0, 1e-14) << name;
      for (double s : {0.5, 1.5, 3.0}) {
        const Mat2 S = s * rotation(a);
        EXPECT_NEAR(base.value(S, 0.0), 1.0, 1e-12) << name;
        // (σ + 1/σ)/2 with σ = s²
        EXPECT_NEAR(m.value(S, 0.0), 0.5 * (s * s + 1.0 / (s * s)), 1e-12) << name;
      }
    }
    Mat2 S;
    S << 1.0, 0.3, 0.2, -0.8;
    EXPECT_TRUE(std::isinf(m.value(S, 0.0)));  // tangled: the base's barrier
    EXPECT_TRUE(std::isfinite(m.value(S, 0.1)));
    expectDerivativesAtRateTwo(m, 13, 2.0);
  }
}

// A quadratic triangle measured against its straight-sided triangle (straightSidedTarget):
// η = 1 with a zero gradient where every side node is at its side's midpoint, in any plane and
// whatever the corners' shape; a side node moved off it raises η (shape and size), with the
// gradient of finite differences; a triangle wound against the normal or degenerate is no
// target.
TEST(StraightSidedTarget, AffineTria6IsOptimalAndMovesAreMeasured) {
  const PlanarMeasure& m = measureByName("shape");
  const Mat3 R = Eigen::AngleAxisd(0.6, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 c0 = R * Vec3(0, 0, 0), c1 = R * Vec3(3, 0.3, 0), c2 = R * Vec3(0.4, 1.2, 0);
  const Vec3 n = R * Vec3(0, 0, 1);
  const Vec3 x[6] = {c0, c1, c2, (c0 + c1) / 2, (c1 + c2) / 2, (c2 + c0) / 2};
  Mat2 W;
  ASSERT_TRUE(straightSidedTarget(c0, c1, c2, n, &W));
  Mat2 unused;
  EXPECT_FALSE(straightSidedTarget(c0, c2, c1, n, &unused));
  EXPECT_FALSE(straightSidedTarget(c0, c1, (c0 + c1) / 2, n, &unused));
  // Against the equilateral the same element is not ideal (its corners are not equilateral).
  EXPECT_GT(elementDistortion(m, ElementType::Tri6, x, n, 0.0).eta, 1.1);
  for (int k = 3; k < 6; ++k) {
    HighOrderJacobians pre;
    highOrderJacobians(ElementType::Tri6, x, k, &pre);
    Vec3 g;
    Mat3 H;
    const ElementEval e = highOrderTriangleDistortion(m, pre, x[k], n, 0.0, &g, &H, nullptr, &W);
    EXPECT_NEAR(e.eta, 1.0, 1e-13);
    EXPECT_LT(g.norm(), 1e-12);
    EXPECT_FALSE(e.tangled);
    // In the plane and out of it (where the measure changes at second order only).
    for (const Vec3& d : {Vec3(0.05, 0.02, 0.0), Vec3(-0.03, 0.04, 0.01)}) {
      const Vec3 y = x[k] + R * d;
      const ElementEval moved = highOrderTriangleDistortion(m, pre, y, n, 0.0, &g, &H, nullptr, &W);
      EXPECT_GT(moved.eta, 1.0 + 1e-4);
      const double h = 1e-6;
      for (int c = 0; c < 3; ++c) {
        Vec3 yp = y, ym = y;
        yp[c] += h;
        ym[c] -= h;
        const double fd =
            (highOrderTriangleDistortion(m, pre, yp, n, 0.0, nullptr, nullptr, nullptr, &W).eta -
             highOrderTriangleDistortion(m, pre, ym, n, 0.0, nullptr, nullptr, nullptr, &W).eta) /
            (2 * h);
        EXPECT_NEAR(g[c], fd, 1e-7 * (1 + std::abs(fd))) << "node " << k << " axis " << c;
      }
    }
  }
  // The whole element scaled about c0 keeps its shape: η = 1 against a target of its own
  // size, (σ + 1/σ)/2 with σ = 4 against the original's.
  Vec3 big[6];
  for (int i = 0; i < 6; ++i) big[i] = c0 + 2.0 * (x[i] - c0);
  HighOrderJacobians pre;
  highOrderJacobians(ElementType::Tri6, big, -1, &pre);
  EXPECT_NEAR(
      highOrderTriangleDistortion(m, pre, Vec3::Zero(), n, 0.0, nullptr, nullptr, nullptr, &W).eta,
      0.5 * (4.0 + 0.25), 1e-12);
}

TEST(MeasureRegistry, KnowsShapeAndOddyAndRejectsUnknown) {
  const auto names = measureNames();
  EXPECT_NE(std::find(names.begin(), names.end(), "shape"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "oddy"), names.end());
  try {
    measureByName("nope");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("shape"), std::string::npos);
  }
}

TEST(ShapeMeasure, HandComputedValues) {
  const PlanarMeasure& shape = measureByName("shape");
  const PlanarMeasure& oddy = measureByName("oddy");
  // Right isosceles triangle (0,0),(1,0),(0,1): tri_shape = 4√3·½ / 4 = √3/2.
  const Mat2 S = planarS({0, 0}, {1, 0}, {0, 1});
  EXPECT_NEAR(1.0 / shape.value(S, 0.0), std::sqrt(3.0) / 2, 1e-14);
  // Oddy of the same: S = A W⁻¹ with A = I; F = ‖W⁻¹‖² = 1 + 1/3 + 4/3 = 8/3, σ = 2/√3:
  // η = (F² − 3σ²)/σ² = (64/9 − 4)/(4/3) = 7/3.
  EXPECT_NEAR(oddy.value(S, 0.0), 7.0 / 3.0, 1e-13);
}

// ---- surface extension ---------------------------------------------------------------------

TEST(SurfaceMeasure, PlanarConsistencyWithPlanarMeasureAndVerdict) {
  const PlaneSurface plane;  // φ(u,v) = (u, v, 0)
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  int checked = 0;
  for (int trial = 0; trial < 500; ++trial) {
    Vec2 p[3] = {{u(rng), u(rng)}, {u(rng), u(rng)}, {u(rng), u(rng)}};
    Vec3 x[3];
    for (int k = 0; k < 3; ++k) x[k] = plane.value(p[k].x(), p[k].y());
    const Vec3 n = plane.normal(0, 0);
    for (const auto& name : measureNames()) {
      const PlanarMeasure& m = measureByName(name);
      const ElementEval ev = triangleDistortion(m, x[0], x[1], x[2], n, 0.0, equilateralWinv());
      const double planar = m.value(planarS(p[0], p[1], p[2]), 0.0);
      if (std::isinf(planar)) {
        EXPECT_TRUE(ev.tangled);
        continue;
      }
      EXPECT_NEAR(ev.eta, planar, 1e-13 * planar);
      if (name == "shape") {
        EXPECT_NEAR(1.0 / ev.eta, verdictTriShape(x[0], x[1], x[2]), 1e-13);
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 300);
}

TEST(SurfaceMeasure, FlippedTriangleIsTangledOnCurvedSurfaces) {
  const TorusSurface torus(10, 4);
  const SphereSurface sphere(3);
  const CylinderSurface cyl(2, 0, 5);
  const Surface* surfaces[] = {&torus, &sphere, &cyl};
  for (const Surface* s : surfaces) {
    // A small counter-clockwise triangle in (u,v) around (0.7, 0.3).
    const Vec2 c(0.7, 0.3);
    const double h = 0.05;
    Vec3 x[3] = {s->value(c.x(), c.y()), s->value(c.x() + h, c.y()),
                 s->value(c.x() + h / 2, c.y() + h)};
    const Vec3 n = s->normal(c.x(), c.y());
    for (const auto& name : measureNames()) {
      const PlanarMeasure& m = measureByName(name);
      const ElementEval good = triangleDistortion(m, x[0], x[1], x[2], n, 0, equilateralWinv());
      const ElementEval flip = triangleDistortion(m, x[0], x[2], x[1], n, 0, equilateralWinv());
      EXPECT_FALSE(good.tangled) << s->describe();
      EXPECT_GT(good.minSigma, 0.0);
      EXPECT_TRUE(flip.tangled) << s->describe();
      EXPECT_EQ(1.0 / flip.eta, 0.0);
      // A reversed face flips what tangled means.
      const ElementEval rev = triangleDistortion(m, x[0], x[1], x[2], -n, 0, equilateralWinv());
      EXPECT_TRUE(rev.tangled);
    }
  }
}

// A triangle standing edge-on to its surface (standsEdgeOn): the case of a cylinder's triangle
// whose corners slid onto the circle at its end, so that it lies flat in the end cap's plane.
// Cylinder of radius 1 about z; corners at angles 0°, 120°, 240° on the circle z = 0, the
// third lifted by h. By hand for h = 0: c = (0, 0, 3√3/2) and c·n_k = 0 at every corner (the
// normals n_k are radial). Lifting the third corner tilts c towards the side: still edge-on
// for h = 0.01, leaning well within 84° at a corner for h = 0.5.
TEST(SurfaceMeasure, TriangleEdgeOnToItsSurface) {
  const double deg = kPi / 180.0;
  auto corner = [&](double a, double z) { return Vec3(std::cos(a * deg), std::sin(a * deg), z); };
  auto radial = [&](double a) { return Vec3(std::cos(a * deg), std::sin(a * deg), 0); };
  const Vec3 n[3] = {radial(0), radial(120), radial(240)};
  const Vec3 flat[3] = {corner(0, 0), corner(120, 0), corner(240, 0)};
  const Vec3 c = (flat[1] - flat[0]).cross(flat[2] - flat[0]);
  EXPECT_NEAR(c.z(), 1.5 * std::sqrt(3.0), 1e-12);
  for (const Vec3& nk : n) EXPECT_NEAR(c.dot(nk), 0.0, 1e-12);
  EXPECT_TRUE(standsEdgeOn(ElementType::Tri3, flat, n));
  EXPECT_FALSE(standsAcross(ElementType::Tri3, flat, n)) << "the sign test cannot see it";
  const Vec3 lifted[3] = {corner(0, 0), corner(120, 0), corner(240, 0.01)};
  EXPECT_TRUE(standsEdgeOn(ElementType::Tri3, lifted, n));
  const Vec3 leaning[3] = {corner(0, 0), corner(120, 0), corner(240, 0.5)};
  EXPECT_FALSE(standsEdgeOn(ElementType::Tri3, leaning, n));
  // A triangle on the cylinder's side (corners at 0°, 30°, heights 0, 0, 1): along the normals.
  const Vec3 side[3] = {corner(0, 0), corner(30, 0), corner(15, 1)};
  const Vec3 ns[3] = {radial(0), radial(30), radial(15)};
  EXPECT_FALSE(standsEdgeOn(ElementType::Tri3, side, ns));
  // No normal at any corner (poles): no verdict; other element types: never.
  const Vec3 none[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  EXPECT_FALSE(standsEdgeOn(ElementType::Tri3, flat, none));
  const Vec3 x6[6] = {flat[0],
                      flat[1],
                      flat[2],
                      0.5 * (flat[0] + flat[1]),
                      0.5 * (flat[1] + flat[2]),
                      0.5 * (flat[2] + flat[0])};
  EXPECT_FALSE(standsEdgeOn(ElementType::Tri6, x6, n));
  // measureQuality flags it (MeshQuality::edgeOn), grades it as standing across (what a run
  // may not make of a valid triangle), and leaves the report's counts as they were.
  const CylinderSurface cyl(1, 0, 1);
  const std::vector<Vec2> uv = {{0, 0},   {120 * deg, 0},  {240 * deg, 0.01},
                                {0, 0.5}, {30 * deg, 0.5}, {15 * deg, 1}};
  const SurfaceMesh m =
      makeSingleSurfaceMesh(cyl, uv, ElementType::Tri3, {0, 1, 2, 3, 4, 5}, {0, 1, 2, 3, 4, 5});
  const MeshQuality mq = measureQuality(m, measureByName("shape"));
  ASSERT_EQ(mq.edgeOn.size(), 2u);
  EXPECT_EQ(mq.edgeOn[0], 1);
  EXPECT_EQ(mq.edgeOn[1], 0);
  EXPECT_EQ(mq.grade(0), mq.tangled[0] ? 2 : 1);
  EXPECT_EQ(mq.grade(1), 0);
  EXPECT_EQ(mq.stats.across, static_cast<std::size_t>(mq.across[0]));
}

// Elements standing across their surface (standsAcross): on a cylinder of radius 1, corners
// at angles 0°, 100°, 200° (heights 0, 0, 1). By hand, with n_k = (cos θ_k, sin θ_k, 0):
// c·n = 0.985, 0.985, −1.327 and c·(n_0 + n_1 + n_2) = 0.643 — valid by the paper's measure
// (the sum of the corner normals), its plane wound against the surface at the third corner.
TEST(SurfaceMeasure, ElementsStandingAcrossTheSurfaceAreCounted) {
  const CylinderSurface cyl(1, 0, 1);
  const double deg = kPi / 180.0;
  const std::vector<Vec2> uv = {{0, 0},   {100 * deg, 0},  {200 * deg, 1},    // across
                                {0, 0.5}, {30 * deg, 0.5}, {15 * deg, 1},     // small, valid
                                {0, 0.2}, {15 * deg, 0.4}, {30 * deg, 0.2}};  // flipped
  const std::vector<std::int32_t> conn = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  const SurfaceMesh m =
      makeSingleSurfaceMesh(cyl, uv, ElementType::Tri3, conn, {0, 1, 2, 3, 4, 5, 6, 7, 8});
  // The reference, from the definition: signs of c·n_k and of c·Σn_k.
  const Vec3 p0(1, 0, 0), p1(std::cos(100 * deg), std::sin(100 * deg), 0),
      p2(std::cos(200 * deg), std::sin(200 * deg), 1);
  const Vec3 c = (p1 - p0).cross(p2 - p0);
  const Vec3 n0(1, 0, 0), n1(p1.x(), p1.y(), 0), n2(p2.x(), p2.y(), 0);
  EXPECT_NEAR(c.dot(n0), 0.985, 1e-3);
  EXPECT_NEAR(c.dot(n1), 0.985, 1e-3);
  EXPECT_NEAR(c.dot(n2), -1.327, 1e-3);
  EXPECT_NEAR(c.dot(n0 + n1 + n2), 0.643, 1e-3);
  const MeshQuality mq = measureQuality(m, measureByName("shape"));
  ASSERT_EQ(mq.across.size(), 3u);
  EXPECT_EQ(mq.across[0], 1);
  EXPECT_EQ(mq.tangled[0], 0) << "valid by the paper's measure";
  EXPECT_GT(mq.quality[0], 0.0);
  EXPECT_EQ(mq.across[1], 0);
  EXPECT_EQ(mq.tangled[1], 0);
  EXPECT_EQ(mq.across[2], 0) << "wound against every corner: tangled, not across";
  EXPECT_EQ(mq.tangled[2], 1);
  EXPECT_EQ(mq.stats.across, 1u);
  EXPECT_EQ(mq.stats.tangled, 1u);
  // The same triangle as a corner of a quadrilateral, and a straight-sided second-order one.
  const Vec3 x[3] = {p0, p1, p2};
  const Vec3 nk[4] = {n0, n1, n2, Vec3::Zero()};
  EXPECT_TRUE(standsAcross(ElementType::Tri3, x, nk));
  const Vec3 x6[6] = {p0, p1, p2, 0.5 * (p0 + p1), 0.5 * (p1 + p2), 0.5 * (p2 + p0)};
  EXPECT_TRUE(standsAcross(ElementType::Tri6, x6, nk));
  const Vec3 none[3] = {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  EXPECT_FALSE(standsAcross(ElementType::Tri3, x, none)) << "no normal (poles): no verdict";
  // A planar square on the plane z = 0 with the normal +z: no corner against.
  const Vec3 q[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const Vec3 up[4] = {Vec3::UnitZ(), Vec3::UnitZ(), Vec3::UnitZ(), Vec3::UnitZ()};
  EXPECT_FALSE(standsAcross(ElementType::Quad4, q, up));
  // With the normal turned over at corner 2 only, the corner triangle there is wound against
  // it and the others along theirs.
  const Vec3 upDown[4] = {Vec3::UnitZ(), Vec3::UnitZ(), -Vec3::UnitZ(), Vec3::UnitZ()};
  EXPECT_TRUE(standsAcross(ElementType::Quad4, q, upDown));
  // Which ways: along only, against only (the flipped square), both, neither.
  const Vec3 down[4] = {-Vec3::UnitZ(), -Vec3::UnitZ(), -Vec3::UnitZ(), -Vec3::UnitZ()};
  const CornerSides s1 = cornerSides(ElementType::Quad4, q, up),
                    s2 = cornerSides(ElementType::Quad4, q, down),
                    s3 = cornerSides(ElementType::Tri3, x, nk),
                    s4 = cornerSides(ElementType::Tri3, x, none);
  EXPECT_TRUE(s1.along && !s1.against);
  EXPECT_TRUE(!s2.along && s2.against);
  EXPECT_TRUE(s3.along && s3.against);
  EXPECT_TRUE(!s4.along && !s4.against);
}

// A sharp cone whose tip is a pole only to within `gap`: φ(u,v) = ((v + gap) k cos u,
// (v + gap) k sin u, v), v ∈ [0, 1]. At v = 0, ‖φ_u‖ = gap·k: a CAD face's row of control
// points that meets in a point only to within the model's tolerance (a vertex of its
// degenerated edge lies there). The normal on the line v = 0 turns with u, by up to 180°.
class NearlyPointedCone final : public Surface {
 public:
  NearlyPointedCone(double k, double gap) : k_(k), gap_(gap) {}
  Vec3 value(double u, double v) const override {
    const double r = (v + gap_) * k_;
    return {r * std::cos(u), r * std::sin(u), v};
  }
  SurfaceD1 d1(double u, double v) const override {
    const SurfaceD2 d = d2(u, v);
    return {d.p, d.du, d.dv};
  }
  SurfaceD2 d2(double u, double v) const override {
    const double c = std::cos(u), s = std::sin(u), r = (v + gap_) * k_;
    SurfaceD2 d;
    d.p = {r * c, r * s, v};
    d.du = {-r * s, r * c, 0.0};
    d.dv = {k_ * c, k_ * s, 1.0};
    d.duu = {-r * c, -r * s, 0.0};
    d.duv = {-k_ * s, k_ * c, 0.0};
    d.dvv = Vec3::Zero();
    return d;
  }
  ParamBounds bounds() const override { return {0.0, 2 * kPi, 0.0, 1.0}; }
  bool isUPeriodic() const override { return true; }
  double uPeriod() const override { return 2 * kPi; }
  std::unique_ptr<Surface> clone() const override {
    return std::make_unique<NearlyPointedCone>(k_, gap_);
  }
  std::string describe() const override { return "nearly pointed cone"; }

 private:
  double k_, gap_;
};

// An element with a corner on the tip is judged by its inside, not by the normal on the
// meridian its tip's (u,v) happens to name (the vertex's parameters on the face: u = 1 here,
// while the element lies around u = 3.2, 126° away). There the element's plane is wound
// against that meridian's normal; the face's normals inside the element (by dense sampling
// below) are all along its Jacobian. Linear, second and third order.
TEST(SurfaceMeasure, ACornerOnANearlyPointedTipIsJudgedByTheElementsInside) {
  for (double gap : {0.0, 1e-9}) {
    const NearlyPointedCone cone(0.2, gap);
    const SurfaceD1 tip = cone.d1(1.0, 0.0);
    EXPECT_EQ(cone.normal(1.0, 0.0).norm(), 0.0) << "gap " << gap << ": no normal on the tip";
    if (gap > 0.0) {
      EXPECT_GT(tip.du.cross(tip.dv).norm(), 0.0) << "nearly, not exactly, a pole";
      EXPECT_FALSE(isDegenerate(tip)) << "not a pole to the optimizer";
    }
    for (int p = 1; p <= 3; ++p) {
      // Corners (u,v): (3.4, 1), (3.0, 1) and the tip (1.0, 0); the other nodes at the
      // straight-sided element's points mapped through the surface along the sides' own
      // meridians (a side from the tip runs along its far corner's meridian).
      const LagrangeTriangle& L = lagrangeTriangle(p);
      const Vec3 a = cone.value(3.4, 1.0), b = cone.value(3.0, 1.0), t = cone.value(1.0, 0.0);
      std::vector<Vec2> uv;
      for (const Eigen::Vector2d& r : L.nodes()) {
        const Vec3 x = (1 - r.x() - r.y()) * a + r.x() * b + r.y() * t;
        const double v = std::max(0.0, x.z());
        const double u = r.y() == 1.0 ? 1.0 : std::atan2(x.y(), x.x()) + (x.y() < 0 ? 2 * kPi : 0);
        uv.emplace_back(u, v);
      }
      const ElementType type = p == 1   ? ElementType::Tri3
                               : p == 2 ? ElementType::Tri6
                                        : ElementType::Tri10;
      std::vector<std::int32_t> conn(L.nodeCount());
      for (int i = 0; i < L.nodeCount(); ++i) conn[static_cast<std::size_t>(i)] = i;
      const SurfaceMesh m = makeSingleSurfaceMesh(cone, uv, type, conn, conn);
      // The face's normal inside, densely: along the element's Jacobian everywhere but on the
      // tip's point itself, and its plane against the normal on the tip's meridian.
      // x_ξ × x_η and the point x(ξ), from the element's own Lagrange interpolant.
      auto mapAt = [&](const Eigen::Vector2d& xi, Vec3* point) {
        Eigen::Vector2d g[kMaxElementNodes];
        double N[kMaxElementNodes];
        L.gradients(xi, g);
        L.shape(xi, N);
        Vec3 xs = Vec3::Zero(), xe = Vec3::Zero(), pt = Vec3::Zero();
        for (int k = 0; k < L.nodeCount(); ++k) {
          xs += g[k].x() * m.xyz[static_cast<std::size_t>(k)];
          xe += g[k].y() * m.xyz[static_cast<std::size_t>(k)];
          pt += N[k] * m.xyz[static_cast<std::size_t>(k)];
        }
        *point = pt;
        return Vec3(xs.cross(xe));
      };
      double lowest = 1.0;
      for (int i = 0; i <= 40; ++i)
        for (int j = 0; i + j <= 40; ++j) {
          if (j == 40) continue;  // the tip itself: no normal
          Vec3 pt;
          const Vec3 c = mapAt(Eigen::Vector2d(i / 40.0, j / 40.0), &pt);
          const Vec3 n = cone.normal(std::atan2(pt.y(), pt.x()), pt.z());
          lowest = std::min(lowest, c.normalized().dot(n));
        }
      EXPECT_GT(lowest, 0.5) << "order " << p << ": valid against the face's own normals";
      const Vec3 meridian = cone.normal(1.0, 1e-3);  // the tip's (u,v)'s meridian
      Vec3 tipPoint;
      EXPECT_LT(mapAt(L.nodes()[2], &tipPoint).dot(meridian), 0.0) << "order " << p;
      const MeshQuality mq = measureQuality(m, measureByName("shape"));
      EXPECT_EQ(mq.across[0], 0) << "gap " << gap << ", order " << p;
      EXPECT_EQ(mq.tangled[0], 0) << "gap " << gap << ", order " << p;
      EXPECT_GT(jacobianRatioOf(m, 0), 0.0) << "gap " << gap << ", order " << p;
    }
  }
}

TEST(SurfaceMeasure, RestrictedDerivativesOnTorusMatchFiniteDifferences) {
  const TorusSurface torus(10, 4);
  const Vec2 uv[3] = {{0.31, 1.2}, {0.45, 1.25}, {0.36, 1.42}};
  testmesh::checkRestrictedDerivatives(torus, uv, 0.0);
  // A tangled configuration with the regularized measure.
  const Vec2 tangled[3] = {{0.31, 1.2}, {0.36, 1.42}, {0.45, 1.25}};
  testmesh::checkRestrictedDerivatives(torus, tangled, 0.05);
}

TEST(SurfaceMeasure, RestrictedDerivativesOnPolynomialPatchMatchFiniteDifferences) {
  PolynomialPatch::Coeffs c;
  for (auto& row : c)
    for (auto& v : row) v = Vec3::Zero();
  c[1][0] = {1, 0, 0.2};
  c[0][1] = {0, 1, -0.1};
  c[2][0] = {0, 0, 0.7};
  c[1][1] = {0.1, 0, 0.5};
  c[0][2] = {0, 0.2, -0.4};
  const PolynomialPatch patch(c);
  const Vec2 uv[3] = {{0.3, 0.3}, {0.5, 0.35}, {0.38, 0.55}};
  testmesh::checkRestrictedDerivatives(patch, uv, 0.0);
}

TEST(SurfaceMeasure, ChainRulesForAnalyticSurfaces) {
  // d2 of every analytic surface against finite differences of d1.
  const TorusSurface torus(10, 4);
  const SphereSurface sphere(2);
  const CylinderSurface cyl(1.5, -1, 1);
  const PolynomialPatch bil =
      PolynomialPatch::bilinear({0, 0, 0}, {1, 0, 0.3}, {0, 1, -0.2}, {1.2, 1.1, 0.5});
  const Surface* ss[] = {&torus, &sphere, &cyl, &bil};
  for (const Surface* s : ss) {
    const double u = 0.4, v = 0.3, h = 1e-6;
    const SurfaceD2 d = s->d2(u, v);
    const SurfaceD1 up = s->d1(u + h, v), um = s->d1(u - h, v), vp = s->d1(u, v + h),
                    vm = s->d1(u, v - h);
    EXPECT_LT(((up.p - um.p) / (2 * h) - d.du).norm(), 1e-7) << s->describe();
    EXPECT_LT(((vp.p - vm.p) / (2 * h) - d.dv).norm(), 1e-7) << s->describe();
    EXPECT_LT(((up.du - um.du) / (2 * h) - d.duu).norm(), 1e-6) << s->describe();
    EXPECT_LT(((vp.du - vm.du) / (2 * h) - d.duv).norm(), 1e-6) << s->describe();
    EXPECT_LT(((vp.dv - vm.dv) / (2 * h) - d.dvv).norm(), 1e-6) << s->describe();
  }
}

TEST(SurfaceMeasure, OutwardNormalsAndPeriodicity) {
  const TorusSurface torus(10, 4);
  const Vec3 p = torus.value(0.0, 0.0);  // outer equator (14, 0, 0)
  EXPECT_NEAR(torus.normal(0.0, 0.0).dot(Vec3(1, 0, 0)), 1.0, 1e-14);
  EXPECT_NEAR(p.x(), 14.0, 1e-14);
  const SphereSurface sphere(2);
  EXPECT_NEAR(sphere.normal(1.0, 0.2).dot(sphere.value(1.0, 0.2).normalized()), 1.0, 1e-14);
  EXPECT_EQ(sphere.normal(1.0, kPi / 2).norm(), 0.0);  // pole: degenerate
  const Vec2 w = torus.wrap({-0.1, 7.0});
  EXPECT_NEAR(w.x(), 2 * kPi - 0.1, 1e-14);
  EXPECT_NEAR(w.y(), 7.0 - 2 * kPi, 1e-14);
  const Vec2 un = torus.unwrapNear({6.2, 0.1}, {0.05, 0.1});
  EXPECT_NEAR(un.x(), 6.2 - 2 * kPi, 1e-14);
  const ReversedSurface rev(torus.clone());
  EXPECT_NEAR(rev.normal(0.0, 0.0).dot(Vec3(1, 0, 0)), -1.0, 1e-14);
}

TEST(QualityStats, MatchHandComputedValues) {
  const std::vector<double> q = {0.0, 0.5, 1.0, 0.5};
  const std::vector<unsigned char> t = {1, 0, 0, 0};
  const QualityStats s = computeStats(q, t);
  EXPECT_EQ(s.min, 0.0);
  EXPECT_EQ(s.max, 1.0);
  EXPECT_DOUBLE_EQ(s.mean, 0.5);
  EXPECT_DOUBLE_EQ(s.stddev, std::sqrt(0.125));
  EXPECT_EQ(s.tangled, 1u);
  EXPECT_EQ(s.elements, 4u);
}

TEST(QualityStats, PaperTable1PlanarSquareSurfaceEqualsPlanar) {
  const PlaneSurface plane;
  const auto g = testmesh::squareMesh(12);
  const SurfaceMesh m = makeSingleSurfaceMesh(plane, g.uv, ElementType::Tri3, g.conn, g.fixed);
  const MeshQuality mq = measureQuality(m, measureByName("shape"));
  // Planar reference: Verdict's formula on the same triangles.
  std::vector<double> planar;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const auto* nd = m.elementNodes(e);
    planar.push_back(verdictTriShape(m.xyz[nd[0]], m.xyz[nd[1]], m.xyz[nd[2]]));
    EXPECT_NEAR(mq.quality[e], planar.back(), 1e-13);
  }
  const QualityStats ref = computeStats(planar, std::vector<unsigned char>(planar.size(), 0));
  testmesh::printTableRow("planar shape (Verdict)", ref);
  testmesh::printTableRow("surface shape", mq.stats);
  EXPECT_NEAR(mq.stats.mean, ref.mean, 1e-13);
  EXPECT_EQ(mq.stats.tangled, 0u);
}

}  // namespace
