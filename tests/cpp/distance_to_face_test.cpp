// elementDistanceToFace against distances computed in closed form: planar elements, straight
// sides across a cylinder (the chord's sagitta), a curved tri6 on a cylinder (its quadratic
// side against the circle, with explicit P2 shape functions), and bad input.
#include "surfmesh/mesh/distance_to_face.h"

#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

using namespace surfmesh;

namespace {

SurfaceMesh oneElement(const Surface& s, const std::vector<Vec2>& uv, ElementType t) {
  std::vector<std::int32_t> conn(uv.size());
  for (std::size_t i = 0; i < uv.size(); ++i) conn[i] = static_cast<std::int32_t>(i);
  return makeSingleSurfaceMesh(s, uv, t, conn, {});
}

}  // namespace

TEST(DistanceToFace, PlanarElementsLieOnTheirFace) {
  const PlaneSurface plane(Vec3(1, 2, 3), Vec3(1, 1, 0).normalized(), Vec3(0, 0, 1));
  const SurfaceMesh tri = oneElement(plane, {{0, 0}, {2, 0.5}, {0.3, 1.7}}, ElementType::Tri3);
  const SurfaceMesh quad =
      oneElement(plane, {{0, 0}, {2, 0}, {2.5, 1}, {-0.2, 1.4}}, ElementType::Quad4);
  EXPECT_LT(elementDistanceToFace(tri)[0], 1e-12);
  EXPECT_LT(elementDistanceToFace(quad)[0], 1e-12);
}

TEST(DistanceToFace, StraightSideAcrossACylinderIsItsSagitta) {
  const double R = 2.0, theta = 0.6, h = 1.5;
  const CylinderSurface cyl(R, -5.0, 5.0);
  const double sagitta = R * (1.0 - std::cos(theta / 2));  // at the chord's middle
  const SurfaceMesh tri = oneElement(cyl, {{0, 0}, {theta, 0}, {0, h}}, ElementType::Tri3);
  const SurfaceMesh quad =
      oneElement(cyl, {{0, 0}, {theta, 0}, {theta, h}, {0, h}}, ElementType::Quad4);
  EXPECT_NEAR(elementDistanceToFace(tri)[0], sagitta, 1e-12);
  EXPECT_NEAR(elementDistanceToFace(quad)[0], sagitta, 1e-12);
  // an odd number of steps misses the middle: the largest sample is below the sagitta
  const double coarse = elementDistanceToFace(tri, 3)[0];
  EXPECT_LT(coarse, sagitta - 1e-6);
  const double s = 1.0 / 3.0;  // the chord's point a third of the way: |(1 − s)a + s b| < R
  EXPECT_NEAR(coarse,
              R - R * std::sqrt((1 - s) * (1 - s) + s * s + 2 * s * (1 - s) * std::cos(theta)),
              1e-12);
}

TEST(DistanceToFace, CurvedTri6FollowsItsQuadraticSides) {
  const double R = 1.0, theta = 1.2, h = 0.8;
  const CylinderSurface cyl(R, -5.0, 5.0);
  const std::vector<Vec2> uv = {{0, 0},         {theta, 0},         {0, h},
                                {theta / 2, 0}, {theta / 2, h / 2}, {0, h / 2}};
  const SurfaceMesh m = oneElement(cyl, uv, ElementType::Tri6);
  // the same grid, mapped by P2 shape functions written out, measured radially
  const int n = 8;
  double expected = 0.0;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j + i <= n; ++j) {
      const double xi = double(i) / n, eta = double(j) / n, l = 1 - xi - eta;
      const double N[6] = {l * (2 * l - 1), xi * (2 * xi - 1), eta * (2 * eta - 1),
                           4 * l * xi,      4 * xi * eta,      4 * eta * l};
      Vec3 x = Vec3::Zero();
      for (int a = 0; a < 6; ++a) x += N[a] * cyl.value(uv[a].x(), uv[a].y());
      expected = std::max(expected, std::abs(R - std::hypot(x.x(), x.y())));
    }
  }
  const double got = elementDistanceToFace(m, n)[0];
  EXPECT_NEAR(got, expected, 1e-12);
  EXPECT_GT(got, 1e-4);                                 // the element is not on the surface,
  EXPECT_LT(got, 0.1 * R * (1 - std::cos(theta / 2)));  // but far nearer than straight sides
}

TEST(DistanceToFace, RejectsNoDivisions) {
  const PlaneSurface plane;
  const SurfaceMesh tri = oneElement(plane, {{0, 0}, {1, 0}, {0, 1}}, ElementType::Tri3);
  EXPECT_THROW(elementDistanceToFace(tri, 0), std::invalid_argument);
}
