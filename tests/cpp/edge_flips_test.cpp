// Edge flips on the CAD faces (OptimizeOptions::topology = "flip", edge_flips.h), judged by
// code written here: the planar shape quality 4√3·A/Σl² and orientations by hand, the
// cylinder's outward normal in closed form, midpoints of straight sides.
#include "surfmesh/optimize/edge_flips.h"

#include "fixture_meshes.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A node on a CAD edge or vertex (fixed, on no face) at (u,v) of face 0.
std::int32_t cadNode(SurfaceMesh& m, const Surface& s, const Vec2& uv) {
  m.xyz.push_back(s.value(uv.x(), uv.y()));
  m.uv.push_back(s.wrap(uv));
  m.nodeFace.push_back(-1);
  m.nodeKind.push_back(NodeKind::Fixed);
  return static_cast<std::int32_t>(m.xyz.size() - 1);
}

/// A node inside face 0 that may move.
std::int32_t faceNode(SurfaceMesh& m, const Surface& s, const Vec2& uv) {
  const std::int32_t n = cadNode(m, s, uv);
  m.nodeFace.back() = 0;
  m.nodeKind.back() = NodeKind::Face;
  return n;
}

SurfaceMesh emptyMesh(const Surface& s) {
  SurfaceMesh m;
  m.surfaces = {&s};
  m.faceOrientation = {1};
  return m;
}

/// Planar shape quality of a triangle, by hand: 4√3·A / Σ l² (1 for an equilateral one).
double handQuality(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double area = 0.5 * (b - a).cross(c - a).norm();
  return 4.0 * std::sqrt(3.0) * area /
         ((b - a).squaredNorm() + (c - b).squaredNorm() + (a - c).squaredNorm());
}

double smallestHandQuality(const SurfaceMesh& m) {
  double q = 1.0;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    q = std::min(q, handQuality(m.xyz[nd[0]], m.xyz[nd[1]], m.xyz[nd[2]]));
  }
  return q;
}

/// Mesh edges (corner to corner) with the number of elements using each.
std::map<std::pair<int, int>, int> edgeUses(const SurfaceMesh& m) {
  std::map<std::pair<int, int>, int> uses;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < 3; ++k) {
      const int a = nd[k], b = nd[(k + 1) % 3];
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  }
  return uses;
}

/// The square [0,10]² of the plane meshed as two fans of slivers: 11 nodes on each of the
/// edges y = 0 and y = 10, every bottom node joined to the top-left corner and every top node
/// to the bottom-right one. Every node is on a CAD edge: no motion can improve it.
SurfaceMesh fanOfSlivers(const Surface& plane) {
  SurfaceMesh m = emptyMesh(plane);
  std::vector<std::int32_t> bottom, top;
  for (int i = 0; i <= 10; ++i) bottom.push_back(cadNode(m, plane, Vec2(i, 0.0)));
  for (int i = 0; i <= 10; ++i) top.push_back(cadNode(m, plane, Vec2(i, 10.0)));
  for (int i = 0; i < 10; ++i) {
    const std::int32_t t[3] = {bottom[i], bottom[i + 1], top[0]};
    m.addElement(ElementType::Tri3, t, 0);
  }
  for (int j = 0; j < 10; ++j) {
    const std::int32_t t[3] = {bottom[10], top[j + 1], top[j]};
    m.addElement(ElementType::Tri3, t, 0);
  }
  m.validate();
  return m;
}

bool onSquareBoundary(const Vec3& a, const Vec3& b) {
  auto same = [](double x, double y) { return std::abs(x - y) < 1e-12; };
  for (double v : {0.0, 10.0})
    if ((same(a.x(), v) && same(b.x(), v)) || (same(a.y(), v) && same(b.y(), v))) return true;
  return false;
}

}  // namespace

TEST(EdgeFlips, FanOfSliversBecomesAStripWithIdsFacesAndBoundaryKept) {
  const PlaneSurface plane;
  SurfaceMesh m = fanOfSlivers(plane);
  const SurfaceMesh input = m;
  const double q0 = smallestHandQuality(m);
  ASSERT_LT(q0, 0.1);
  const FlipPass pass = flipEdges(m, measureByName("shape"), {});
  m.validate();
  EXPECT_GT(pass.flips, 5u);
  EXPECT_EQ(m.elementCount(), input.elementCount());
  EXPECT_EQ(m.nodeCount(), input.nodeCount());
  EXPECT_EQ(m.xyz, input.xyz);  // every node is where it was
  EXPECT_EQ(m.elemFace, input.elemFace);
  EXPECT_EQ(m.elemType, input.elemType);
  // The elements rewired are exactly those whose node lists differ.
  std::vector<std::int32_t> changed;
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    if (!std::equal(m.elementNodes(e), m.elementNodes(e) + 3, input.elementNodes(e)))
      changed.push_back(static_cast<std::int32_t>(e));
  EXPECT_EQ(changed, pass.rewired);
  // A triangulation of the square: counter-clockwise, every edge used twice inside and once on
  // the square's boundary, the boundary's edges unchanged.
  double area = 0.0;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    const double z = (m.xyz[nd[1]] - m.xyz[nd[0]]).cross(m.xyz[nd[2]] - m.xyz[nd[0]]).z();
    EXPECT_GT(z, 0.0) << "element " << e;
    area += 0.5 * z;
  }
  EXPECT_NEAR(area, 100.0, 1e-9);
  std::set<std::pair<int, int>> boundary0, boundary1;
  for (const auto& [edge, n] : edgeUses(input))
    if (onSquareBoundary(input.xyz[edge.first], input.xyz[edge.second])) boundary0.insert(edge);
  for (const auto& [edge, n] : edgeUses(m)) {
    const bool onB = onSquareBoundary(m.xyz[edge.first], m.xyz[edge.second]);
    EXPECT_EQ(n, onB ? 1 : 2);
    if (onB) boundary1.insert(edge);
  }
  EXPECT_EQ(boundary0, boundary1);
  // The best triangulation of these nodes: each unit-by-ten cell cut by a diagonal, whose
  // triangles (sides 1, 10, √101) have quality 4√3·5 / (1 + 100 + 101), against 0.09 before.
  EXPECT_NEAR(smallestHandQuality(m), 20.0 * std::sqrt(3.0) / 202.0, 1e-12);
  // The core's report agrees with the hand quality (a plane: the paper's measure is planar).
  const MeshQuality q = measureQuality(m, measureByName("shape"));
  EXPECT_NEAR(q.stats.min, smallestHandQuality(m), 1e-12);
  EXPECT_EQ(q.stats.tangled, 0u);
}

TEST(EdgeFlips, OptimizeWithFlipsReportsTheRewiredElementsAndNeverLowersTheMinimum) {
  const PlaneSurface plane;
  SurfaceMesh none = fanOfSlivers(plane), flip = none;
  OptimizeOptions o;
  o.threads = 1;
  const OptimizeResult r0 = optimizeMesh(none, o);
  o.topology = "flip";
  const OptimizeResult r1 = optimizeMesh(flip, o);
  EXPECT_EQ(r0.flips, 0u);
  EXPECT_TRUE(r0.rewiredElements.empty());
  EXPECT_GT(r1.flips, 0u);
  EXPECT_FALSE(r1.rewiredElements.empty());
  EXPECT_TRUE(std::is_sorted(r1.rewiredElements.begin(), r1.rewiredElements.end()));
  EXPECT_GE(r1.after.min, r1.before.min);
  EXPECT_GT(r1.after.min, r0.after.min);
  EXPECT_NEAR(r1.after.min, smallestHandQuality(flip), 1e-12);
  EXPECT_EQ(r1.after.tangled, 0u);
  EXPECT_THROW(
      [&] {
        OptimizeOptions bad;
        bad.topology = "swap";
        SurfaceMesh copy = none;
        optimizeMesh(copy, bad);
      }(),
      std::invalid_argument);
}

namespace {

/// The torus's grid of periodicGridMesh (odd rows shifted by half a cell) with the long
/// diagonal of every cell of the even rows (a–d, where the shift makes b–c the short one),
/// its interior nodes moved at random by up to a fifth of a cell: a valid mesh that node
/// motion smooths but only flips make well shaped.
SurfaceMesh longDiagonalTorus(const TorusSurface& torus) {
  const int nu = 24, nv = 10;
  GridMesh g = periodicGridMesh(nu, nv, 0, 2 * kPi, 0, 2 * kPi, true);
  auto id = [&](int i, int j) { return (j % nv) * nu + (i % nu); };
  g.conn.clear();
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i, j + 1), d = id(i + 1, j + 1);
      g.conn.insert(g.conn.end(), {a, b, d, a, d, c});
    }
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  for (Vec2& p : g.uv) p += Vec2(u(rng) * 2 * kPi / nu, u(rng) * 2 * kPi / nv);
  return makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
}

}  // namespace

TEST(EdgeFlips, CancellingAfterFlipsLeavesNodeListsAsTheyWere) {
  const TorusSurface torus(10.0, 4.0);
  SurfaceMesh m = longDiagonalTorus(torus);
  const SurfaceMesh input = m;
  OptimizeOptions o;
  o.topology = "flip";
  o.threads = 1;
  // Cancelled in the first run after a flip pass (stage 1 and on).
  const OptimizeResult r =
      optimizeMesh(m, o, [&](const OptimizeProgress& p) { return p.stage < 1; });
  ASSERT_EQ(r.reason, StopReason::Cancelled);
  EXPECT_EQ(m.elemNodes, input.elemNodes);
  EXPECT_EQ(m.xyz, input.xyz);
  EXPECT_EQ(m.cornerUV, input.cornerUV);
  EXPECT_EQ(r.flips, 0u);
  EXPECT_TRUE(r.rewiredElements.empty());
}

namespace {

/// A rhombus on the cylinder r = 1 across its seam u = 0: the diagonal a–b runs along the seam
/// (v from 0.2 to 0.8), the apexes c and d lie 0.15 rad to either side. Flipping a–b to the
/// short diagonal c–d would raise the quality; a and b are on the seam's CAD edge when
/// `onSeamEdge`, else inside the face (a mesh that does not follow the seam).
SurfaceMesh rhombusAcrossTheSeam(const Surface& cyl, bool onSeamEdge) {
  SurfaceMesh m = emptyMesh(cyl);
  auto node = [&](const Vec2& uv) {
    return onSeamEdge ? cadNode(m, cyl, uv) : faceNode(m, cyl, uv);
  };
  const std::int32_t a = node(Vec2(0.0, 0.2)), b = node(Vec2(0.0, 0.8));
  const std::int32_t c = faceNode(m, cyl, Vec2(2 * kPi - 0.15, 0.5));
  const std::int32_t d = faceNode(m, cyl, Vec2(0.15, 0.5));
  const std::int32_t A[3] = {a, b, c}, B[3] = {b, a, d};
  const Vec2 uvA[3] = {Vec2(2 * kPi, 0.2), Vec2(2 * kPi, 0.8), Vec2(2 * kPi - 0.15, 0.5)};
  const Vec2 uvB[3] = {Vec2(0.0, 0.8), Vec2(0.0, 0.2), Vec2(0.15, 0.5)};
  m.addElement(ElementType::Tri3, A, 0, uvA);
  m.addElement(ElementType::Tri3, B, 0, uvB);
  m.validate();
  return m;
}

/// Whether triangle e is wound along the cylinder's outward normal at its centroid.
bool outward(const SurfaceMesh& m, std::size_t e) {
  const std::int32_t* nd = m.elementNodes(e);
  const Vec3 c = (m.xyz[nd[0]] + m.xyz[nd[1]] + m.xyz[nd[2]]) / 3.0;
  const Vec3 n(c.x(), c.y(), 0.0);
  return (m.xyz[nd[1]] - m.xyz[nd[0]]).cross(m.xyz[nd[2]] - m.xyz[nd[0]]).dot(n) > 0.0;
}

}  // namespace

TEST(EdgeFlips, AnEdgeBetweenTwoFacesIsNeverFlipped) {
  // The rhombus of the plane a (0,−2), b (0,2), c (−0.5,0), d (0.5,0): flipping a–b to the
  // short diagonal c–d would raise the quality, but a–b is the CAD edge between face 0 (A)
  // and face 1 (B).
  const PlaneSurface plane;
  SurfaceMesh m = emptyMesh(plane);
  m.surfaces = {&plane, &plane};
  m.faceOrientation = {1, 1};
  const std::int32_t a = cadNode(m, plane, Vec2(0, -2)), b = cadNode(m, plane, Vec2(0, 2));
  const std::int32_t c = cadNode(m, plane, Vec2(-0.5, 0)), d = cadNode(m, plane, Vec2(0.5, 0));
  const std::int32_t A[3] = {a, b, c}, B[3] = {b, a, d};
  m.addElement(ElementType::Tri3, A, 0);
  m.addElement(ElementType::Tri3, B, 1);
  m.validate();
  const SurfaceMesh input = m;
  EXPECT_EQ(flipEdges(m, measureByName("shape"), {}).flips, 0u);
  EXPECT_EQ(m.elemNodes, input.elemNodes);
  // The same two elements on one face flip.
  m.elemFace = {0, 0};
  EXPECT_EQ(flipEdges(m, measureByName("shape"), {}).flips, 1u);
}

TEST(EdgeFlips, AnEdgeOnTheSeamIsNeverFlipped) {
  const CylinderSurface cyl(1.0, 0.0, 1.0);
  SurfaceMesh m = rhombusAcrossTheSeam(cyl, true);
  const SurfaceMesh input = m;
  const FlipPass pass = flipEdges(m, measureByName("shape"), {});
  EXPECT_EQ(pass.flips, 0u);
  EXPECT_EQ(m.elemNodes, input.elemNodes);
}

TEST(EdgeFlips, APairStraddlingTheSeamFlipsInUnwrappedParameters) {
  const CylinderSurface cyl(1.0, 0.0, 1.0);
  SurfaceMesh m = rhombusAcrossTheSeam(cyl, false);
  const double q0 = smallestHandQuality(m);
  const FlipPass pass = flipEdges(m, measureByName("shape"), {});
  m.validate();
  ASSERT_EQ(pass.flips, 1u);
  EXPECT_EQ(pass.rewired, (std::vector<std::int32_t>{0, 1}));
  EXPECT_GT(smallestHandQuality(m), q0);
  for (std::size_t e = 0; e < 2; ++e) {
    EXPECT_TRUE(outward(m, e)) << "element " << e;
    // Unwrapped: an element's corners are close in (u,v), not a period apart.
    const Vec2* uv = m.elementUV(e);
    for (int k = 1; k < 3; ++k) EXPECT_LT((uv[k] - uv[0]).norm(), 1.0);
  }
  // The new diagonal joins the apexes.
  const auto uses = edgeUses(m);
  EXPECT_EQ(uses.count({2, 3}), 1u);
  EXPECT_EQ(uses.at({2, 3}), 2);
  EXPECT_EQ(uses.count({0, 1}), 0u);
}

namespace {

/// A tri6 rhombus on the plane: corners a (0,−2), b (0,2), c (−1,0.5), d (1,0.5) on CAD edges,
/// the side nodes at their sides' midpoints; the shared side a–b's node m may move when
/// `movable`.
SurfaceMesh tri6Rhombus(const Surface& plane, bool movable) {
  SurfaceMesh m = emptyMesh(plane);
  const Vec2 pa(0, -2), pb(0, 2), pc(-1, 0.5), pd(1, 0.5);
  const std::int32_t a = cadNode(m, plane, pa), b = cadNode(m, plane, pb);
  const std::int32_t c = cadNode(m, plane, pc), d = cadNode(m, plane, pd);
  const std::int32_t mid =
      movable ? faceNode(m, plane, 0.5 * (pa + pb)) : cadNode(m, plane, 0.5 * (pa + pb));
  const std::int32_t bc = cadNode(m, plane, 0.5 * (pb + pc)),
                     ca = cadNode(m, plane, 0.5 * (pc + pa));
  const std::int32_t ad = cadNode(m, plane, 0.5 * (pa + pd)),
                     db = cadNode(m, plane, 0.5 * (pd + pb));
  const std::int32_t A[6] = {a, b, c, mid, bc, ca}, B[6] = {b, a, d, mid, ad, db};
  m.addElement(ElementType::Tri6, A, 0);
  m.addElement(ElementType::Tri6, B, 0);
  m.validate();
  return m;
}

}  // namespace

TEST(EdgeFlips, Tri6FlipPutsTheSharedSideNodeOnTheNewSide) {
  const PlaneSurface plane;
  SurfaceMesh m = tri6Rhombus(plane, true);
  const SurfaceMesh input = m;
  const FlipPass pass = flipEdges(m, measureByName("shape"), {});
  m.validate();
  ASSERT_EQ(pass.flips, 1u);
  // The same nodes, one of them moved: the shared side node, now at the midpoint of c–d.
  std::set<int> n0(input.elemNodes.begin(), input.elemNodes.end()),
      n1(m.elemNodes.begin(), m.elemNodes.end());
  EXPECT_EQ(n0, n1);
  EXPECT_NEAR((m.xyz[4] - Vec3(0.0, 0.5, 0.0)).norm(), 0.0, 1e-12);
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (i != 4) {
      EXPECT_EQ(m.xyz[i], input.xyz[i]) << "node " << i;
    }
  EXPECT_EQ(m.uv[4], Vec2(0.0, 0.5));
  // Every side node at its side's midpoint, every element counter-clockwise.
  for (std::size_t e = 0; e < 2; ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR((m.xyz[nd[3 + k]] - 0.5 * (m.xyz[nd[k]] + m.xyz[nd[(k + 1) % 3]])).norm(), 0.0,
                  1e-12)
          << "element " << e << " side " << k;
    EXPECT_GT((m.xyz[nd[1]] - m.xyz[nd[0]]).cross(m.xyz[nd[2]] - m.xyz[nd[0]]).z(), 0.0);
  }
}

TEST(EdgeFlips, Tri6PairWhoseSharedSideNodeMayNotMoveIsNotFlipped) {
  const PlaneSurface plane;
  SurfaceMesh m = tri6Rhombus(plane, false);
  const SurfaceMesh input = m;
  EXPECT_EQ(flipEdges(m, measureByName("shape"), {}).flips, 0u);
  EXPECT_EQ(m.elemNodes, input.elemNodes);
  // Held by the caller: not flipped either.
  SurfaceMesh h = tri6Rhombus(plane, true);
  std::vector<unsigned char> held(h.nodeCount(), 1);
  EXPECT_EQ(flipEdges(h, measureByName("shape"), held).flips, 0u);
}

TEST(EdgeFlips, SameResultOnOneAndTwoThreads) {
  const TorusSurface torus(10.0, 4.0);
  const SurfaceMesh base = longDiagonalTorus(torus);
  SurfaceMesh one = base, two = base;
  OptimizeOptions o;
  o.topology = "flip";
  o.threads = 1;
  const OptimizeResult r1 = optimizeMesh(one, o);
  o.threads = 2;
  const OptimizeResult r2 = optimizeMesh(two, o);
  EXPECT_EQ(one.elemNodes, two.elemNodes);
  EXPECT_EQ(one.xyz, two.xyz);
  EXPECT_EQ(r1.rewiredElements, r2.rewiredElements);
  EXPECT_EQ(r1.flips, r2.flips);
  EXPECT_GT(r1.flips, 0u);
  EXPECT_EQ(r1.after.tangled, 0u);
  EXPECT_LE(maxDistanceToSurface(one), 1e-12);
}
