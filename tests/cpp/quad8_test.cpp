// Serendipity quadrilaterals (quad8, CalculiX's S8, FreeCAD's and Gmsh's 8-node quads) on
// surfaces: hand values, validity against an independent dense sampling of the Jacobian's
// determinant, derivatives, mixed tri6/quad8 meshes, and optimization on a torus.
#include "element_fd.h"
#include "fixture_meshes.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

const double kPi = 3.14159265358979323846;
const Vec3 kZ(0, 0, 1);

/// A quad8 with straight sides: the corners, then the midpoints of sides 0-1, 1-2, 2-3, 3-0.
std::vector<Vec3> straightQuad8(const Vec3 c[4]) {
  std::vector<Vec3> x(c, c + 4);
  for (int k = 0; k < 4; ++k) x.push_back(0.5 * (c[k] + c[(k + 1) % 4]));
  return x;
}

/// Smallest determinant of the map of a planar (xy) quad8, on an n × n grid of [−1, 1]² and at
/// its nodes, written here from the textbook serendipity functions (Zienkiewicz) without
/// SurfMesh: N_i = ¼(1 + r r_i)(1 + s s_i)(r r_i + s s_i − 1) at the corners, ½(1 − r²)(1 + s s_i)
/// and ½(1 + r r_i)(1 − s²) at the side nodes.
double minDetSampled(const std::vector<Vec3>& x, int n) {
  const double ri[8] = {-1, 1, 1, -1, 0, 1, 0, -1}, si[8] = {-1, -1, 1, 1, -1, 0, 1, 0};
  auto det = [&](double r, double s) {
    double xr = 0, xs = 0, yr = 0, ys = 0;
    for (int i = 0; i < 8; ++i) {
      double dr, ds;
      if (i < 4) {
        dr = 0.25 * ri[i] * (1 + s * si[i]) * (2 * r * ri[i] + s * si[i]);
        ds = 0.25 * si[i] * (1 + r * ri[i]) * (r * ri[i] + 2 * s * si[i]);
      } else if (ri[i] == 0) {
        dr = -r * (1 + s * si[i]);
        ds = 0.5 * (1 - r * r) * si[i];
      } else {
        dr = 0.5 * ri[i] * (1 - s * s);
        ds = -(1 + r * ri[i]) * s;
      }
      xr += dr * x[static_cast<std::size_t>(i)].x();
      xs += ds * x[static_cast<std::size_t>(i)].x();
      yr += dr * x[static_cast<std::size_t>(i)].y();
      ys += ds * x[static_cast<std::size_t>(i)].y();
    }
    return xr * ys - xs * yr;
  };
  double lo = INFINITY;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) lo = std::min(lo, det(-1 + 2.0 * i / n, -1 + 2.0 * j / n));
  for (int i = 0; i < 8; ++i) lo = std::min(lo, det(ri[i], si[i]));
  return lo;
}

/// Smallest (x_r × x_s)·n of a quad8 on the torus with centre circle radius R about the z axis,
/// on an (n + 1)² grid of [−1, 1]²: the serendipity functions and derivatives written here as
/// in minDetSampled, n the torus's outward normal at the mapped point (closed form).
double minDetOnTorus(const std::vector<Vec3>& x, double R, int n) {
  const double ri[8] = {-1, 1, 1, -1, 0, 1, 0, -1}, si[8] = {-1, -1, 1, 1, -1, 0, 1, 0};
  double lo = INFINITY;
  for (int a = 0; a <= n; ++a)
    for (int b = 0; b <= n; ++b) {
      const double r = -1 + 2.0 * a / n, s = -1 + 2.0 * b / n;
      Vec3 p = Vec3::Zero(), xr = Vec3::Zero(), xs = Vec3::Zero();
      for (int i = 0; i < 8; ++i) {
        double N, dr, ds;
        if (i < 4) {
          N = 0.25 * (1 + r * ri[i]) * (1 + s * si[i]) * (r * ri[i] + s * si[i] - 1);
          dr = 0.25 * ri[i] * (1 + s * si[i]) * (2 * r * ri[i] + s * si[i]);
          ds = 0.25 * si[i] * (1 + r * ri[i]) * (r * ri[i] + 2 * s * si[i]);
        } else if (ri[i] == 0) {
          N = 0.5 * (1 - r * r) * (1 + s * si[i]);
          dr = -r * (1 + s * si[i]);
          ds = 0.5 * (1 - r * r) * si[i];
        } else {
          N = 0.5 * (1 + r * ri[i]) * (1 - s * s);
          dr = 0.5 * ri[i] * (1 - s * s);
          ds = -(1 + r * ri[i]) * s;
        }
        p += N * x[static_cast<std::size_t>(i)];
        xr += dr * x[static_cast<std::size_t>(i)];
        xs += ds * x[static_cast<std::size_t>(i)];
      }
      const double rho = std::hypot(p.x(), p.y());
      const Vec3 centre(R * p.x() / rho, R * p.y() / rho, 0.0);
      lo = std::min(lo, xr.cross(xs).dot((p - centre).normalized()));
    }
  return lo;
}

}  // namespace

TEST(Quad8Measure, StraightSidedParallelogramsHaveTheQualityOfTheirQuad4) {
  // A square (quality 1), a 2 × 1 rectangle (shape: ‖S‖²/(2 det S) = (4 + 1)/4 → q = 0.8), a
  // parallelogram: constant Jacobian, so the quad8 is its quad4 for every measure.
  const Vec3 square[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const Vec3 rect[4] = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}};
  const Vec3 para[4] = {{0, 0, 0}, {2, 0, 0}, {2.7, 1.2, 0}, {0.7, 1.2, 0}};
  const PlanarMeasure& shape = measureByName("shape");
  EXPECT_NEAR(elementDistortion(shape, ElementType::Quad8, straightQuad8(square).data(), kZ, 0).eta,
              1.0, 1e-12);
  EXPECT_NEAR(
      1.0 / elementDistortion(shape, ElementType::Quad8, straightQuad8(rect).data(), kZ, 0).eta,
      0.8, 1e-12);
  for (const auto& name : measureNames())
    for (const Vec3* c : {square, rect, para}) {
      const PlanarMeasure& m = measureByName(name);
      const ElementEval q8 =
          elementDistortion(m, ElementType::Quad8, straightQuad8(c).data(), kZ, 0);
      const ElementEval q4 = elementDistortion(m, ElementType::Quad4, c, kZ, 0);
      EXPECT_NEAR(q8.eta, q4.eta, 1e-12 * q4.eta) << name;
      EXPECT_FALSE(q8.tangled);
    }
}

TEST(Quad8Measure, ValidityAgreesWithADenseSamplingOfTheDeterminant) {
  // Random side-node displacements of the unit square (up to 0.4 of a side): tangled exactly
  // where the determinant sampled densely by independent code goes negative (clear cases:
  // |min det| above 2 % of the square's).
  const Vec3 square[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  int valid = 0, folded = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    std::vector<Vec3> x = straightQuad8(square);
    for (int k = 4; k < 8; ++k) x[static_cast<std::size_t>(k)] += Vec3(u(rng), u(rng), 0);
    const double d = minDetSampled(x, 60) * 4.0;  // in the unit square's (s,t): det × 4
    if (std::abs(d) < 0.02) continue;
    const ElementEval e =
        elementDistortion(measureByName("shape"), ElementType::Quad8, x.data(), kZ, 0);
    EXPECT_EQ(e.tangled, d < 0) << "trial " << trial << " min det " << d;
    (d < 0 ? folded : valid)++;
    // the reversed normal: every valid one is tangled
    if (d > 0) {
      EXPECT_TRUE(
          elementDistortion(measureByName("shape"), ElementType::Quad8, x.data(), -kZ, 0).tangled);
    }
  }
  std::printf("%d valid, %d folded\n", valid, folded);
  EXPECT_GT(valid, 50);
  EXPECT_GT(folded, 50);
  // A side node pushed across the opposite side: folded.
  std::vector<Vec3> x = straightQuad8(square);
  x[4] = Vec3(0.5, 1.2, 0);
  EXPECT_TRUE(
      elementDistortion(measureByName("shape"), ElementType::Quad8, x.data(), kZ, 0).tangled);
}

TEST(Quad8Measure, DerivativesOnTorusConvergeAtRateTwoForEveryNode) {
  const TorusSurface torus(10, 4);
  // Corners and side nodes near the (u,v) midpoints, slightly off them (curved sides).
  const std::vector<Vec2> uv = {{0.30, 1.20},  {0.42, 1.22},  {0.44, 1.36},  {0.31, 1.33},
                                {0.36, 1.205}, {0.435, 1.29}, {0.375, 1.35}, {0.305, 1.265}};
  Vec3 n = Vec3::Zero();
  for (int k = 0; k < 4; ++k) n += torus.normal(uv[k].x(), uv[k].y());
  n.normalize();
  for (const auto& name : measureNames())
    for (int k = 0; k < 8; ++k)
      checkElementDerivatives(measureByName(name), torus, ElementType::Quad8, uv, k, n, 0.0, 2e-4,
                              "quad8 " + name + " node " + std::to_string(k));
}

TEST(Quad8Optimize, Quad8AndMixedTri6Quad8MeshesOfATorusAreUntangledOnTheSurface) {
  const TorusSurface torus(10, 4);
  for (bool mixed : {false, true}) {
    SurfaceMesh m = torusQuad8(torus, 24, 10, mixed);
    const QualityStats ideal = measureQuality(m, measureByName("shape")).stats;
    EXPECT_EQ(ideal.tangled, 0u);
    const std::size_t tangled = perturbUntilTangled(m, torus, 20, 0.1, 0.25, 3);
    ASSERT_GE(tangled, 20u);
    const std::vector<Vec3> before = m.xyz;
    OptimizeOptions opt;
    opt.maxSweeps = 200;
    const OptimizeResult r = optimizeMesh(m, opt);
    printTableRow(mixed ? "tri6 + quad8, before" : "quad8, before", r.before);
    printTableRow(mixed ? "tri6 + quad8, after" : "quad8, after", r.after);
    EXPECT_EQ(r.after.tangled, 0u);
    EXPECT_GT(r.after.min, 0.3);
    EXPECT_LE(maxDistanceToSurface(m), 1e-12);
    // the result's figures are those of the mesh returned
    const QualityStats again = measureQuality(m, measureByName("shape")).stats;
    EXPECT_EQ(again.tangled, r.after.tangled);
    EXPECT_DOUBLE_EQ(again.min, r.after.min);
    // fixed nodes (the unused cell centres) stayed
    for (std::size_t k = 0; k < m.nodeCount(); ++k)
      if (m.nodeKind[k] == NodeKind::Fixed) {
        EXPECT_EQ(m.xyz[k], before[k]);
      }
  }
}

TEST(Quad8Optimize, SmoothingAValidQuad8MeshNeverLowersItsWorstElement) {
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusQuad8(torus, 20, 8, true);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  for (std::size_t k = 0; k < m.nodeCount(); ++k)
    if (m.nodeKind[k] == NodeKind::Face)
      m.uv[k] += Vec2(u(rng) * 2 * kPi / 40, u(rng) * 2 * kPi / 16);
  syncFaceNodes(m);
  const MeshQuality q0 = measureQuality(m, measureByName("shape"));
  ASSERT_EQ(q0.stats.tangled, 0u);
  OptimizeOptions opt;
  const OptimizeResult r = optimizeMesh(m, opt);
  const MeshQuality q1 = measureQuality(m, measureByName("shape"));
  EXPECT_GE(q1.stats.min, q0.stats.min);
  EXPECT_EQ(q1.stats.tangled, 0u);
  EXPECT_GE(q1.stats.mean, q0.stats.mean);
  EXPECT_EQ(r.after.tangled, 0u);
}

TEST(Quad8Optimize, FoldedSideNodesAreStraightenedInParameterSpace) {
  // A mesher's side nodes projected across a strongly curved face fold quad8 whose corners
  // are fine. Such an element gets its side nodes at the parametric midpoints of its sides
  // (straight sides in (u,v)) when that leaves fewer elements tangled around them.
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusQuad8(torus, 24, 10, false);
  ASSERT_EQ(measureQuality(m, measureByName("shape")).stats.tangled, 0u);
  // Throw the side nodes of every other element (a checkerboard: no two share a side) across
  // it: towards and past the opposite side's midpoint, 1.4 × the distance (the corners stay).
  std::vector<unsigned char> thrown(m.nodeCount(), 0);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    if (((e / 10) + (e % 10)) % 2 != 0) continue;  // cell (i, j) = (e / nv, e % nv)
    for (int k = 4; k < 8; ++k) {
      const std::size_t j = static_cast<std::size_t>(m.elementNodes(e)[k]);
      const Vec2 mid = m.elementUV(e)[k];
      const Vec2 opposite = m.elementUV(e)[4 + (k - 4 + 2) % 4];
      m.uv[j] = mid + 1.4 * (opposite - mid);
      thrown[j] = 1;
    }
  }
  syncFaceNodes(m);  // positions, and every element's parameters next to where they were
  const QualityStats folded = measureQuality(m, measureByName("shape")).stats;
  ASSERT_GE(folded.tangled, m.elementCount() / 2);
  OptimizeOptions opt;
  opt.maxSweeps = 1;
  opt.highOrder = "integral";  // the integral mode's escape (the reference mode places them)
  const OptimizeResult r = optimizeMesh(m, opt);
  std::printf("quad8 torus mesh with folded side nodes, 1 sweep (%zu elements straightened)\n",
              r.straightenedElements);
  printTableRow("before", r.before);
  printTableRow("after", r.after);
  EXPECT_EQ(r.after.tangled, 0u);
  EXPECT_EQ(r.straightenedElements, folded.tangled);
  EXPECT_LE(maxDistanceToSurface(m), 1e-12);
  // Checked independently: every element's determinant on a dense grid, its points mapped to
  // the torus's normal by the closed form (x, y scaled to the tube's centre circle).
  std::size_t foldedAfter = 0;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    std::vector<Vec3> x;
    for (int k = 0; k < 8; ++k) x.push_back(m.xyz[static_cast<std::size_t>(m.elementNodes(e)[k])]);
    if (minDetOnTorus(x, 10.0, 12) <= 0.0) ++foldedAfter;
  }
  EXPECT_EQ(foldedAfter, 0u);
}
