// elementJacobianRatio against hand-computed elements: a straight triangle, a parallelogram,
// a trapezoid (corner areas 2, 2, 1, 1), and a tri6 whose side node slides along its side by
// d, where J = 1 + 4d(1 − 2ξ − η) on the reference triangle: ratio (1 − 4|d|)/(1 + 4|d|);
// on a cylinder, against a dense lattice signed by the cylinder's normal.
#include "surfmesh/mesh/jacobian_ratio.h"

#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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

TEST(JacobianRatio, TangledTriangleIsMinusOneAndCollinearIsZero) {
  // the sign is taken along the face's normal: a triangle wound against it has J = −|J|
  EXPECT_NEAR(ratioOf({{0, 0}, {0, 1}, {1, 0}}, ElementType::Tri3), -1.0, 1e-14);
  EXPECT_EQ(ratioOf({{0, 0}, {1, 0}, {2, 0}}, ElementType::Tri3), 0.0);
}

// A tri6 on the unit cylinder, thin and long round its circumference (1.25 rad), its side
// nodes at the (u,v) midpoints of its sides: it follows the cylinder, and its Jacobian is
// along the cylinder's normal everywhere. The plane of its corners is tilted so far from the
// normal at its middle that Gmsh's convention (J along the corner triangle's normal) finds a
// fold there. The ratio is checked against a 40-step lattice of ±|x_ξ × x_η| signed by the
// cylinder's radial normal at the mapped point x(ξ) itself.
TEST(JacobianRatio, CurvedTriangleRoundACylinderIsSignedByTheFacesNormal) {
  const CylinderSurface cylinder(1.0, -1.0, 1.0);
  const Vec2 c0(1.45, 0.14), c1(2.15, 0.10), c2(0.9, 0.22);
  const std::vector<Vec2> uv = {c0, c1, c2, (c0 + c1) / 2, (c1 + c2) / 2, (c2 + c0) / 2};
  const SurfaceMesh m =
      makeSingleSurfaceMesh(cylinder, uv, ElementType::Tri6, {0, 1, 2, 3, 4, 5}, {});
  const LagrangeTriangle& L = lagrangeTriangle(2);
  const Vec3 corner = (m.xyz[1] - m.xyz[0]).cross(m.xyz[2] - m.xyz[0]).normalized();
  double lo = 1e300, hi = 0.0, loCorner = 1e300, hiCorner = 0.0;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; i + j <= 40; ++j) {
      Eigen::Vector2d g[6];
      double N[6];
      L.gradients(Eigen::Vector2d(i / 40.0, j / 40.0), g);
      L.shape(Eigen::Vector2d(i / 40.0, j / 40.0), N);
      Vec3 xs = Vec3::Zero(), xe = Vec3::Zero(), x = Vec3::Zero();
      for (std::size_t k = 0; k < 6; ++k) {
        xs += g[k].x() * m.xyz[k];
        xe += g[k].y() * m.xyz[k];
        x += N[k] * m.xyz[k];
      }
      const Vec3 c = xs.cross(xe);
      const Vec3 radial(x.x(), x.y(), 0.0);
      const double J = c.dot(radial) > 0.0 ? c.norm() : -c.norm();
      lo = std::min(lo, J);
      hi = std::max(hi, std::abs(J));
      loCorner = std::min(loCorner, c.dot(corner));
      hiCorner = std::max(hiCorner, std::abs(c.dot(corner)));
    }
  ASSERT_LT(loCorner / hiCorner, 0.0) << "Gmsh's convention sees a fold";
  ASSERT_GT(lo / hi, 0.4) << "valid against the cylinder";
  const double r = elementJacobianRatio(m)[0];
  EXPECT_NEAR(r, lo / hi, 0.01);
  EXPECT_NEAR(elementJacobianRatio(m, 40)[0], lo / hi, 1e-9);

  // A straight triangle on the cylinder: 1 (the plane of its corners is not the face's
  // tangent plane, which does not matter), −1 wound against the face.
  const std::vector<Vec2> flat = {{0.0, 0.0}, {0.8, 0.0}, {0.4, 0.5}};
  EXPECT_NEAR(elementJacobianRatio(
                  makeSingleSurfaceMesh(cylinder, flat, ElementType::Tri3, {0, 1, 2}, {}))[0],
              1.0, 1e-14);
  EXPECT_NEAR(elementJacobianRatio(
                  makeSingleSurfaceMesh(cylinder, flat, ElementType::Tri3, {0, 2, 1}, {}))[0],
              -1.0, 1e-14);
}

TEST(JacobianRatio, RejectsNoDivisions) {
  const PlaneSurface plane;
  const SurfaceMesh m =
      makeSingleSurfaceMesh(plane, {{0, 0}, {1, 0}, {0, 1}}, ElementType::Tri3, {0, 1, 2}, {});
  EXPECT_THROW(elementJacobianRatio(m, 0), std::invalid_argument);
}
