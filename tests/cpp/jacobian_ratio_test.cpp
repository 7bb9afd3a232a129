// elementJacobianRatio against hand-computed elements: a straight triangle, a parallelogram,
// a trapezoid (corner areas 2, 2, 1, 1), and a tri6 whose side node slides along its side by
// d, where J = 1 + 4d(1 − 2ξ − η) on the reference triangle: ratio (1 − 4|d|)/(1 + 4|d|).
#include "surfmesh/mesh/jacobian_ratio.h"

#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

using namespace surfmesh;

namespace {

double ratioOf(const std::vector<Vec2>& uv, ElementType t) {
  const PlaneSurface plane;
  std::vector<std::int32_t> conn(uv.size());
  for (std::size_t i = 0; i < uv.size(); ++i) conn[i] = static_cast<std::int32_t>(i);
  return elementJacobianRatio(makeSingleSurfaceMesh(plane, uv, t, conn, {}))[0];
}

}  // namespace

TEST(JacobianRatio, StraightTriangleAndParallelogramAreOne) {
  EXPECT_NEAR(ratioOf({{0, 0}, {3, 0.5}, {1, 2}}, ElementType::Tri3), 1.0, 1e-14);
  EXPECT_NEAR(ratioOf({{0, 0}, {2, 0}, {3, 1}, {1, 1}}, ElementType::Quad4), 1.0, 1e-14);
}

TEST(JacobianRatio, TrapezoidIsItsSmallestOverLargestCornerArea) {
  EXPECT_NEAR(ratioOf({{0, 0}, {2, 0}, {1.5, 1}, {0.5, 1}}, ElementType::Quad4), 0.5, 1e-14);
}

TEST(JacobianRatio, Tri6WithASideNodeMovedAlongItsSide) {
  auto tri6 = [](double m) {
    return ratioOf({{0, 0}, {1, 0}, {0, 1}, {m, 0}, {0.5, 0.5}, {0, 0.5}}, ElementType::Tri6);
  };
  EXPECT_NEAR(tri6(0.5), 1.0, 1e-14);
  EXPECT_NEAR(tri6(0.6), 0.6 / 1.4, 1e-14);
  EXPECT_NEAR(tri6(0.4), 0.6 / 1.4, 1e-14);
  EXPECT_NEAR(tri6(0.8), -0.2 / 2.2, 1e-14);  // J < 0 near corner 1: folded
}

TEST(JacobianRatio, TangledTriangleIsStillOneAndCollinearIsZero) {
  // the sign is taken along the element's own normal: a triangle has one J, so 1
  EXPECT_NEAR(ratioOf({{0, 0}, {0, 1}, {1, 0}}, ElementType::Tri3), 1.0, 1e-14);
  EXPECT_EQ(ratioOf({{0, 0}, {1, 0}, {2, 0}}, ElementType::Tri3), 0.0);
}

TEST(JacobianRatio, RejectsNoDivisions) {
  const PlaneSurface plane;
  const SurfaceMesh m =
      makeSingleSurfaceMesh(plane, {{0, 0}, {1, 0}, {0, 1}}, ElementType::Tri3, {0, 1, 2}, {});
  EXPECT_THROW(elementJacobianRatio(m, 0), std::invalid_argument);
}
