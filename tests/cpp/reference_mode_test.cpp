// Curved elements optimized against their straight-sided counterpart (OptimizeOptions::highOrder
// = "reference", issue #39 points 3 and 5), checked by code written here: the plane's affine
// elements, the torus's nearest point in closed form, Jacobian ratios from the core's own
// report function, never worse, and the integral mode unchanged.
#include "fixture_meshes.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

/// Moves every Face corner of the mesh by up to `a` × the mesh's step in (u,v) and puts its
/// high-order nodes at their straight (u,v) places between the moved corners: a valid,
/// straight-sided mesh with poorly shaped corner triangles.
void jitterCorners(SurfaceMesh& m, const Surface& s, double a, double step, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-a * step, a * step);
  std::vector<unsigned char> corner(m.nodeCount(), 0);
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    for (int k = 0; k < 3; ++k) corner[static_cast<std::size_t>(m.elementNodes(e)[k])] = 1;
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (corner[i] && m.nodeKind[i] == NodeKind::Face) m.uv[i] += Vec2(u(rng), u(rng));
  syncFaceNodes(m);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const Vec2* c = m.elementUV(e);
    const int p = elementOrder(m.elemType[e]);
    const auto& nodes = lagrangeTriangle(p).nodes();
    for (int k = 3; k < m.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(m.elementNodes(e)[k]);
      if (m.nodeKind[j] != NodeKind::Face) continue;
      const Eigen::Vector2d xi = nodes[static_cast<std::size_t>(k)];
      m.uv[j] = s.wrap((1 - xi.x() - xi.y()) * c[0] + xi.x() * c[1] + xi.y() * c[2]);
    }
  }
  syncFaceNodes(m);
}

double minOf(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

/// Largest distance of a side node (local k ≥ 3 of a tri6) from the midpoint of its side.
double largestMidpointOffset(const SurfaceMesh& m) {
  double worst = 0.0;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    auto x = [&](int k) { return m.xyz[static_cast<std::size_t>(nd[k])]; };
    const int sides[3][3] = {{3, 0, 1}, {4, 1, 2}, {5, 2, 0}};
    for (const auto& s : sides) {
      const double len = (x(s[2]) - x(s[1])).norm();
      worst = std::max(worst, (x(s[0]) - 0.5 * (x(s[1]) + x(s[2]))).norm() / len);
    }
  }
  return worst;
}

}  // namespace

TEST(ReferenceMode, PlanarStraightSidedTria6StaysAffineWhileItsCornersImprove) {
  // A square of tri6 on a plane, its corners jittered (side nodes at their sides' midpoints):
  // the default mode smooths the corners and keeps every element affine (side nodes at the
  // midpoints, Jacobian ratio 1); the integral mode moves side nodes off them.
  const PlaneSurface plane;
  const GridMesh lin = squareMesh(10);
  const GridMesh g = elevate(plane, lin, 2);
  SurfaceMesh m0 = makeSingleSurfaceMesh(plane, g.uv, ElementType::Tri6, g.conn, g.fixed);
  jitterCorners(m0, plane, 0.3, 0.1, 7);
  const PlanarMeasure& shape = measureByName("shape");
  const QualityStats before = measureQuality(m0, shape).stats;
  ASSERT_EQ(before.tangled, 0u);
  ASSERT_LT(largestMidpointOffset(m0), 1e-12);
  ASSERT_GT(minOf(elementJacobianRatio(m0)), 1 - 1e-12);

  SurfaceMesh ref = m0;
  const OptimizeResult r = optimizeMesh(ref, OptimizeOptions{});
  EXPECT_GT(r.after.min, before.min + 0.05);
  EXPECT_EQ(r.after.tangled, 0u);
  EXPECT_LT(largestMidpointOffset(ref), 1e-9);
  EXPECT_GT(minOf(elementJacobianRatio(ref)), 1 - 1e-9);
  for (const Vec3& x : ref.xyz) EXPECT_EQ(x.z(), 0.0);

  OptimizeOptions integral;
  integral.highOrder = "integral";
  SurfaceMesh in = m0;
  optimizeMesh(in, integral);
  EXPECT_GT(largestMidpointOffset(in), 0.01);  // the paper's measure curves straight sides
  std::printf(
      "plane tri6: min q %.3f -> reference %.3f (midpoint offset %.1e), integral %.3f "
      "(offset %.3f, min Jacobian ratio %.3f)\n",
      before.min, r.after.min, largestMidpointOffset(ref), measureQuality(in, shape).stats.min,
      largestMidpointOffset(in), minOf(elementJacobianRatio(in)));
}

TEST(ReferenceMode, SideNodesGoToTheTorusPointNearestTheirChordsMidpoints) {
  // On a torus the point nearest to x has a closed form: the tube's centre circle point c at
  // x's azimuth, then c + r (x − c)/|x − c|. Every side node inside the face must be there for
  // its side's chord midpoint, and every element valid, the mesh's min Jacobian ratio not
  // lower than the input's.
  const double R = 10, r = 4;
  const TorusSurface torus(R, r);
  SurfaceMesh m = torusMeshOfOrder(torus, 2);
  jitterCorners(m, torus, 0.15, 2 * M_PI / 24, 3);
  const MeshQuality q0 = measureQuality(m, measureByName("shape"));
  ASSERT_EQ(q0.stats.tangled, 0u);
  const double ratio0 = minOf(elementJacobianRatio(m));
  const OptimizeResult res = optimizeMesh(m, OptimizeOptions{});
  EXPECT_EQ(res.after.tangled, 0u);
  EXPECT_EQ(res.after.across, 0u);
  EXPECT_GE(res.after.min, q0.stats.min - 1e-12);
  EXPECT_GE(minOf(elementJacobianRatio(m)), ratio0 - 1e-9);
  double worst = 0.0;
  int checked = 0;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    const int sides[3][3] = {{3, 0, 1}, {4, 1, 2}, {5, 2, 0}};
    for (const auto& s : sides) {
      const Vec3 mid = 0.5 * (m.xyz[static_cast<std::size_t>(nd[s[1]])] +
                              m.xyz[static_cast<std::size_t>(nd[s[2]])]);
      const double az = std::atan2(mid.y(), mid.x());
      const Vec3 c(R * std::cos(az), R * std::sin(az), 0);
      const Vec3 nearest = c + r * (mid - c).normalized();
      const Vec3 side = m.xyz[static_cast<std::size_t>(nd[s[0]])];
      worst = std::max(worst, (side - nearest).norm());
      ++checked;
    }
  }
  std::printf(
      "torus tri6: %d side nodes, largest distance from the nearest point of the torus "
      "to their chord's midpoint %.2e; min q %.3f -> %.3f\n",
      checked, worst, q0.stats.min, res.after.min);
  EXPECT_LT(worst, 1e-9 * R);
}

TEST(ReferenceMode, NeverWorseThanTheInputAndTheIntegralModeIsUnchanged) {
  // Random tangled and valid order-2 and order-3 torus meshes: the default mode never leaves
  // more invalid elements than the input, on a valid input never a lower minimum quality or
  // Jacobian ratio; and highOrder = "integral" gives bit for bit what the optimizer gave
  // before the mode existed (the golden test holds the record).
  const TorusSurface torus(10, 4);
  const PlanarMeasure& shape = measureByName("shape");
  for (int p : {2, 3}) {
    for (unsigned seed : {1u, 2u}) {
      for (double a : {0.1, 0.6}) {
        SurfaceMesh m = torusMeshOfOrder(torus, p);
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> u(-a * 0.2, a * 0.2);
        for (std::size_t i = 0; i < m.nodeCount(); ++i)
          if (m.nodeKind[i] == NodeKind::Face) m.uv[i] += Vec2(u(rng), u(rng));
        syncFaceNodes(m);
        const MeshQuality q0 = measureQuality(m, shape);
        std::size_t invalid0 = 0;
        for (std::size_t e = 0; e < m.elementCount(); ++e)
          invalid0 += (q0.tangled[e] || q0.across[e]) ? 1 : 0;
        const double ratio0 = minOf(elementJacobianRatio(m));
        SurfaceMesh ref = m;
        OptimizeOptions o;
        o.maxSweeps = 30;
        optimizeMesh(ref, o);
        const MeshQuality q1 = measureQuality(ref, shape);
        std::size_t invalid1 = 0;
        for (std::size_t e = 0; e < m.elementCount(); ++e)
          invalid1 += (q1.tangled[e] || q1.across[e]) ? 1 : 0;
        EXPECT_LE(invalid1, invalid0) << "p " << p << " seed " << seed << " a " << a;
        if (invalid0 == 0) {
          EXPECT_GE(q1.stats.min, q0.stats.min - 1e-9);
          EXPECT_GE(minOf(elementJacobianRatio(ref)), ratio0 - 1e-9);
        }
        std::printf(
            "torus p=%d seed %u amplitude %.1f: invalid %zu -> %zu, min q %.3f -> %.3f, "
            "min Jacobian ratio %.3f -> %.3f\n",
            p, seed, a, invalid0, invalid1, q0.stats.min, q1.stats.min, ratio0,
            minOf(elementJacobianRatio(ref)));
      }
    }
  }
}

TEST(ReferenceMode, CancellingLeavesTheMeshAsItWas) {
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusMeshOfOrder(torus, 2);
  jitterCorners(m, torus, 0.2, 2 * M_PI / 24, 5);
  const std::vector<Vec3> xyz = m.xyz;
  const std::vector<Vec2> uv = m.uv, cuv = m.cornerUV;
  // The whole run's progress calls: the last is the last stage's (the straightening, step 6).
  int total = 0, lastStage = 0;
  {
    SurfaceMesh copy = m;
    optimizeMesh(copy, OptimizeOptions{}, [&](const OptimizeProgress& p) {
      ++total;
      lastStage = p.stage;
      return true;
    });
  }
  ASSERT_GE(lastStage, 1);  // (stage 0: the corners)
  for (int cancelAt : {1, 2, 3, total}) {
    int calls = 0;
    const OptimizeResult r = optimizeMesh(
        m, OptimizeOptions{}, [&](const OptimizeProgress&) { return ++calls < cancelAt; });
    EXPECT_EQ(r.reason, StopReason::Cancelled);
    EXPECT_EQ(m.xyz, xyz);
    EXPECT_EQ(m.uv, uv);
    EXPECT_EQ(m.cornerUV, cuv);
  }
}

TEST(ReferenceMode, AFoldNoNodeCanRepairCostsNoRunAfterTheRepair) {
  // One quadratic triangle on a unit cylinder, folded at corner 1 where only fixed nodes act
  // (HighOrderOptimize.FoldBetweenFixedCornersIsHeldWhateverTheCornerNormals): the repair
  // (step 3) runs on its one free node and leaves it folded. Nothing can change it, so no
  // integral run around it follows (step 5), and the straightening holds the nodes of invalid
  // elements: the repair's stage is the only one that reports a sweep.
  const CylinderSurface cyl(1.0, -2.0, 2.0);
  const std::vector<Vec2> uv = {{-1.0, 0.0}, {1.0, 0.0}, {0.0, 1.0},
                                {0.0, 0.9},  {0.5, 0.5}, {-0.5, 0.5}};
  SurfaceMesh m =
      makeSingleSurfaceMesh(cyl, uv, ElementType::Tri6, {0, 1, 2, 3, 4, 5}, {0, 1, 2, 3, 4});
  std::set<int> stages;
  const OptimizeResult r = optimizeMesh(m, OptimizeOptions{}, [&](const OptimizeProgress& p) {
    stages.insert(p.stage);
    return true;
  });
  ASSERT_EQ(r.tangledUnmovable, std::vector<std::int32_t>{0});
  EXPECT_EQ(stages, std::set<int>{1});  // (stage 0, the corners: all fixed, no sweep)
}

TEST(ReferenceMode, UnknownModeIsRefused) {
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusMeshOfOrder(torus, 2);
  OptimizeOptions o;
  o.highOrder = "straight";
  EXPECT_THROW(optimizeMesh(m, o), std::invalid_argument);
}
