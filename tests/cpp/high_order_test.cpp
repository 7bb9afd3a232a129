// High-order triangles (p = 2…5) on surfaces: Lagrange basis in Gmsh ordering, quadrature,
// the distortion of paper Definition 4 and its derivatives, and the paper's Table 4 cases
// (an order-2 mesh of a revolution surface untangled, an order-5 mesh of a propeller blade
// smoothed).
#include "element_fd.h"
#include "fixture_meshes.h"
#include "surfmesh/cad/occ_surface.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <BRepAdaptor_Surface.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepGProp.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRepPrimAPI_MakeRevol.hxx>
#include <BRepTools.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <GProp_GProps.hxx>
#include <GeomAPI_Interpolate.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Poly_Triangulation.hxx>
#include <TColgp_HArray1OfPnt.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <gp_Ax1.hxx>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <utility>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

const double kPi = 3.14159265358979323846;

const ElementType kHighOrder[] = {ElementType::Tri6, ElementType::Tri10, ElementType::Tri15,
                                  ElementType::Tri21};

double factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }

// ---- meshes ---------------------------------------------------------------------------------

/// Mean parametric edge length of the corner triangles (for perturbation amplitudes).
Vec2 meanParamEdge(const SurfaceMesh& m) {
  Vec2 l = Vec2::Zero();
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const Vec2* uv = m.elementUV(e);
    for (int k = 0; k < 3; ++k) l += (uv[(k + 1) % 3] - uv[k]).cwiseAbs();
  }
  return l / (3.0 * m.elementCount());
}

/// Moves every free node once by a uniform random offset in [−a, a]·l (l the mean parametric
/// edge), growing a from 0.05 until more than `target` elements are tangled. Returns a.
double perturbAll(SurfaceMesh& m, const Surface& s, std::size_t target, unsigned seed) {
  const Vec2 l = meanParamEdge(m);
  const std::vector<Vec2> uv0 = m.uv;
  const PlanarMeasure& shape = measureByName("shape");
  for (double a = 0.05;; a += 0.025) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    m.uv = uv0;
    for (std::size_t i = 0; i < m.nodeCount(); ++i)
      if (m.nodeKind[i] == NodeKind::Face)
        m.uv[i] = s.clampToBounds(m.uv[i] + Vec2(a * l.x() * u(rng), a * l.y() * u(rng)));
    syncFaceNodes(m);
    if (measureQuality(m, shape).stats.tangled > target || a > 2) return a;
  }
}

void printTable(const std::string& title, const QualityStats& before, const QualityStats& after) {
  std::printf("%s\n", title.c_str());
  std::printf("  %-28s  %6s %6s %6s %6s  %s\n", "", "Min.Q", "Max.Q", "MeanQ", "Std", "Tang.el");
  std::printf("  %-28s  %6.2f %6.2f %6.2f %6.2f  %zu (of %zu)\n", "Initial", before.min, before.max,
              before.mean, before.stddev, before.tangled, before.elements);
  std::printf("  %-28s  %6.2f %6.2f %6.2f %6.2f  %zu (of %zu)\n", "Smoothed", after.min, after.max,
              after.mean, after.stddev, after.tangled, after.elements);
}

/// The face of revolution (a vase) swept by a B-spline profile in the xz plane around z.
TopoDS_Face revolutionFace() {
  const double rz[][2] = {{3.0, 0.0}, {3.5, 1.2}, {3.4, 2.4}, {2.8, 3.6}, {2.7, 4.8}, {3.1, 6.0}};
  const int n = 6;
  Handle(TColgp_HArray1OfPnt) pts = new TColgp_HArray1OfPnt(1, n);
  for (int i = 0; i < n; ++i) pts->SetValue(i + 1, gp_Pnt(rz[i][0], 0.0, rz[i][1]));
  GeomAPI_Interpolate interp(pts, false, 1e-9);
  interp.Perform();
  const TopoDS_Edge edge = BRepBuilderAPI_MakeEdge(interp.Curve());
  BRepPrimAPI_MakeRevol revol(edge, gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 2 * kPi);
  TopExp_Explorer ex(revol.Shape(), TopAbs_FACE);
  return TopoDS::Face(ex.Current());
}

// ---- Lagrange basis and quadrature ----------------------------------------------------------

TEST(LagrangeTriangle, NodeOrderingIsGmshs) {
  // gmsh.model.mesh.getElementProperties(9/21/23/25) local node coordinates (Gmsh 4.8.4).
  const std::vector<std::vector<double>> gmsh = {
      {0, 0, 1, 0, 0, 1, .5, 0, .5, .5, 0, .5},
      {0,      0,      1,      0,      0, 1,      1. / 3, 0,      2. / 3, 0,
       2. / 3, 1. / 3, 1. / 3, 2. / 3, 0, 2. / 3, 0,      1. / 3, 1. / 3, 1. / 3},
      {0,  0,   1,   0, 0,   1, .25, 0, .5,  0,   .75, 0,  .75, .25, .5,
       .5, .25, .75, 0, .75, 0, .5,  0, .25, .25, .25, .5, .25, .25, .5},
      {0,  0, 1,  0, 0,  1, .2, 0, .4, 0,  .6, 0,  .8, 0,  .8, .2, .6, .4, .4, .6, .2,
       .8, 0, .8, 0, .6, 0, .4, 0, .2, .2, .2, .6, .2, .2, .6, .4, .2, .4, .4, .2, .4}};
  for (int p = 2; p <= 5; ++p) {
    const LagrangeTriangle& lt = lagrangeTriangle(p);
    ASSERT_EQ(lt.nodeCount(), (p + 1) * (p + 2) / 2);
    ASSERT_EQ(lt.nodeCount(), nodeCount(triangleOfOrder(p)));
    const auto& g = gmsh[static_cast<std::size_t>(p - 2)];
    ASSERT_EQ(g.size(), 2u * lt.nodeCount());
    for (int i = 0; i < lt.nodeCount(); ++i) {
      EXPECT_NEAR(lt.nodes()[i].x(), g[2 * i], 1e-15) << "p=" << p << " node " << i;
      EXPECT_NEAR(lt.nodes()[i].y(), g[2 * i + 1], 1e-15) << "p=" << p << " node " << i;
    }
  }
}

TEST(LagrangeTriangle, KroneckerPartitionOfUnityAndGradients) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int p = 1; p <= 5; ++p) {
    const LagrangeTriangle& lt = lagrangeTriangle(p);
    const int n = lt.nodeCount();
    std::vector<double> N(n), Np(n), Nm(n);
    std::vector<Eigen::Vector2d> G(n);
    for (int j = 0; j < n; ++j) {
      lt.shape(lt.nodes()[j], N.data());
      for (int i = 0; i < n; ++i) EXPECT_NEAR(N[i], i == j ? 1.0 : 0.0, 1e-13) << p;
    }
    for (int t = 0; t < 20; ++t) {
      double a = u(rng), b = u(rng);
      if (a + b > 1) a = 1 - a, b = 1 - b;
      const Eigen::Vector2d xi(a, b);
      lt.shape(xi, N.data());
      lt.gradients(xi, G.data());
      double s = 0;
      Eigen::Vector2d gs = Eigen::Vector2d::Zero();
      for (int i = 0; i < n; ++i) s += N[i], gs += G[i];
      EXPECT_NEAR(s, 1.0, 1e-13);
      EXPECT_LT(gs.norm(), 1e-11);
      // Reproduces every polynomial of degree ≤ p: ξ^a η^b and its gradient.
      for (int da = 0; da <= p; ++da)
        for (int db = 0; db + da <= p; ++db) {
          double f = 0;
          Eigen::Vector2d df = Eigen::Vector2d::Zero();
          for (int i = 0; i < n; ++i) {
            const double v = std::pow(lt.nodes()[i].x(), da) * std::pow(lt.nodes()[i].y(), db);
            f += v * N[i];
            df += v * G[i];
          }
          EXPECT_NEAR(f, std::pow(a, da) * std::pow(b, db), 1e-12);
          EXPECT_NEAR(df.x(), da ? da * std::pow(a, da - 1) * std::pow(b, db) : 0.0, 1e-10);
          EXPECT_NEAR(df.y(), db ? db * std::pow(a, da) * std::pow(b, db - 1) : 0.0, 1e-10);
        }
    }
  }
}

TEST(TriangleQuadrature, DunavantRulesAreExactPositiveAndInside) {
  const int expectedPoints[] = {1, 3, 6, 12, 16, 25};
  const int degrees[] = {1, 2, 4, 6, 8, 10};
  for (int r = 0; r < 6; ++r) {
    const TriangleQuadrature& q = triangleQuadrature(degrees[r]);
    EXPECT_EQ(q.degree, degrees[r]);
    EXPECT_EQ(static_cast<int>(q.points.size()), expectedPoints[r]);
    double ws = 0;
    for (std::size_t k = 0; k < q.points.size(); ++k) {
      EXPECT_GT(q.weights[k], 0.0);
      EXPECT_GT(q.points[k].minCoeff(), 0.0);
      EXPECT_LT(q.points[k].sum(), 1.0);
      ws += q.weights[k];
    }
    EXPECT_NEAR(ws, 1.0, 1e-15);
    // Mean of ξ^a η^b over the reference triangle: 2 a! b! / (a + b + 2)!.
    for (int a = 0; a <= q.degree; ++a)
      for (int b = 0; a + b <= q.degree; ++b) {
        double s = 0;
        for (std::size_t k = 0; k < q.points.size(); ++k)
          s += q.weights[k] * std::pow(q.points[k].x(), a) * std::pow(q.points[k].y(), b);
        EXPECT_NEAR(s, 2 * factorial(a) * factorial(b) / factorial(a + b + 2), 1e-15)
            << "degree " << q.degree << " monomial " << a << "," << b;
      }
  }
  EXPECT_EQ(triangleQuadrature(3).degree, 4);  // the cheapest rule of degree ≥ 3
  EXPECT_THROW(triangleQuadrature(11), std::invalid_argument);
  EXPECT_THROW(lagrangeTriangle(6), std::invalid_argument);
  // The rule used by the measure of order p has degree 2p.
  for (int p = 1; p <= 5; ++p) EXPECT_EQ(highOrderTriangleRule(p).quadrature->degree, 2 * p);
}

// ---- the measure ------------------------------------------------------------------------------

/// Nodes of an order-p element at the straight positions between three points.
std::vector<Vec3> straightNodes(int p, const Vec3& a, const Vec3& b, const Vec3& c) {
  std::vector<Vec3> x;
  for (const auto& xi : lagrangeTriangle(p).nodes())
    x.push_back((1 - xi.x() - xi.y()) * a + xi.x() * b + xi.y() * c);
  return x;
}

TEST(HighOrderMeasure, StraightSidedElementHasTheQualityOfItsLinearTriangle) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  int tangled = 0;
  for (int t = 0; t < 200; ++t) {
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const Vec3 n = Vec3(u(rng), u(rng), u(rng)).normalized();
    for (const auto& name : measureNames()) {
      const PlanarMeasure& m = measureByName(name);
      for (double delta : {0.0, 0.1}) {
        const ElementEval lin = triangleDistortion(m, a, b, c, n, delta, equilateralWinv());
        for (ElementType type : kHighOrder) {
          const auto x = straightNodes(elementOrder(type), a, b, c);
          const ElementEval ho = elementDistortion(m, type, x.data(), n, delta);
          EXPECT_EQ(ho.tangled, lin.tangled);
          EXPECT_NEAR(ho.minSigma, lin.minSigma, 1e-12);
          if (std::isinf(lin.eta)) {
            EXPECT_TRUE(std::isinf(ho.eta));
          } else {
            EXPECT_NEAR(ho.eta, lin.eta, 1e-12 * lin.eta) << name << " " << elementTypeName(type);
          }
        }
        tangled += lin.tangled ? 1 : 0;
      }
    }
  }
  EXPECT_GT(tangled, 50);  // both valid and tangled triangles were compared
}

TEST(HighOrderMeasure, StraightSidedMeshOfAPlaneHasTheStatisticsOfTheLinearMesh) {
  const PlaneSurface plane;
  const GridMesh lin = squareMesh(6);
  const SurfaceMesh m1 =
      makeSingleSurfaceMesh(plane, lin.uv, ElementType::Tri3, lin.conn, lin.fixed);
  const QualityStats s1 = measureQuality(m1, measureByName("shape")).stats;
  for (int p = 2; p <= 5; ++p) {
    const GridMesh g = elevate(plane, lin, p);
    const SurfaceMesh mp = makeSingleSurfaceMesh(plane, g.uv, triangleOfOrder(p), g.conn, g.fixed);
    const QualityStats sp = measureQuality(mp, measureByName("shape")).stats;
    EXPECT_NEAR(sp.min, s1.min, 1e-12);
    EXPECT_NEAR(sp.max, s1.max, 1e-12);
    EXPECT_NEAR(sp.mean, s1.mean, 1e-12);
    EXPECT_NEAR(sp.stddev, s1.stddev, 1e-12);
    EXPECT_EQ(sp.tangled, 0u);
  }
}

TEST(HighOrderMeasure, IdealCurvedElementsAndFoldsAreRecognized) {
  const PlanarMeasure& shape = measureByName("shape");
  const Vec3 n = Vec3::UnitZ();
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0.5, std::sqrt(3.0) / 2, 0);
  // The equilateral tri6: η = 1.
  auto x = straightNodes(2, a, b, c);
  EXPECT_NEAR(elementDistortion(shape, ElementType::Tri6, x.data(), n, 0).eta, 1.0, 1e-14);
  // Quarter-point rule: the edge node of edge 0–1 at 1/5 of the edge makes det J < 0 at
  // corner 0 (at 1/4 it vanishes) although the linear triangle is ideal.
  x[3] = a + 0.2 * (b - a);
  ElementEval e = elementDistortion(shape, ElementType::Tri6, x.data(), n, 0);
  EXPECT_TRUE(e.tangled);
  EXPECT_LE(e.minSigma, 0.0);
  EXPECT_TRUE(std::isinf(e.eta));
  // At 0.3 the element is valid but worse than the ideal one.
  x[3] = a + 0.3 * (b - a);
  e = elementDistortion(shape, ElementType::Tri6, x.data(), n, 0);
  EXPECT_FALSE(e.tangled);
  EXPECT_GT(e.eta, 1.0);
  EXPECT_GT(e.minSigma, 0.0);
  // A mid-edge node pushed across the opposite corner folds the element.
  x = straightNodes(2, a, b, c);
  x[4] = Vec3(-0.2, 0.1, 0);
  e = elementDistortion(shape, ElementType::Tri6, x.data(), n, 0);
  EXPECT_TRUE(e.tangled);
  // With δ > 0 the folded element has a finite value and finite derivatives for every node.
  for (int k = 0; k < 6; ++k) {
    Vec3 g;
    Mat3 H;
    e = elementDistortion(shape, ElementType::Tri6, x.data(), n, 0.05, k, &g, &H);
    EXPECT_TRUE(std::isfinite(e.eta));
    EXPECT_TRUE(g.allFinite() && H.allFinite());
  }
  // Measures are invariant under rotation, translation and scaling of a curved element.
  x = straightNodes(3, a, b, c);
  x[5] += Vec3(0.05, 0.04, 0);
  x[9] += Vec3(-0.03, 0.02, 0);
  const double ref = elementDistortion(shape, ElementType::Tri10, x.data(), n, 0).eta;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  for (auto& p : x) p = 2.5 * (R * p) + Vec3(1, -2, 3);
  EXPECT_NEAR(elementDistortion(shape, ElementType::Tri10, x.data(), R * n, 0).eta, ref, 1e-12);
  EXPECT_THROW(
      highOrderTriangleDistortion(shape, ElementType::Quad4, x.data(), n, 0, -1, nullptr, nullptr),
      std::invalid_argument);
}

/// Curved element of order p on the torus: straight (u,v) nodes, perturbed in (u,v).
std::vector<Vec2> curvedElementUV(int p, const Vec2 c[3], double amp, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amp, amp);
  std::vector<Vec2> uv;
  for (const auto& xi : lagrangeTriangle(p).nodes()) {
    Vec2 q = (1 - xi.x() - xi.y()) * c[0] + xi.x() * c[1] + xi.y() * c[2];
    if (uv.size() >= 3) q += Vec2(u(rng), u(rng));
    uv.push_back(q);
  }
  return uv;
}

TEST(HighOrderMeasure, DerivativesOnTorusConvergeAtRateTwoForCornerEdgeAndInteriorNodes) {
  const TorusSurface torus(10, 4);
  const Vec2 valid[3] = {{0.31, 1.2}, {0.45, 1.25}, {0.36, 1.42}};
  const Vec2 flipped[3] = {{0.31, 1.2}, {0.36, 1.42}, {0.45, 1.25}};
  int checked = 0, rateSeen = 0;
  for (ElementType type : kHighOrder) {
    const int p = elementOrder(type);
    for (int variant = 0; variant < 2; ++variant) {
      const bool tangled = variant == 1;
      const auto uv = curvedElementUV(p, tangled ? flipped : valid, 0.04 / (p * p), 3 + p);
      const Vec3 n = ((torus.normal(uv[0].x(), uv[0].y()) + torus.normal(uv[1].x(), uv[1].y()) +
                       torus.normal(uv[2].x(), uv[2].y())))
                         .normalized();
      const double delta = tangled ? 0.2 : 0.0;
      std::vector<int> nodes = {0, 1, 3, 3 + (p - 1) + (p - 2) / 2};  // corners, edge nodes
      if (p >= 3) nodes.push_back(3 * p);                             // first interior node
      if (p >= 4) nodes.push_back(nodeCount(type) - 1);               // last interior node
      for (const auto& name : measureNames())
        for (int k : nodes) {
          std::vector<Vec3> x(uv.size());
          for (std::size_t i = 0; i < uv.size(); ++i) x[i] = torus.value(uv[i].x(), uv[i].y());
          const ElementEval e = elementDistortion(measureByName(name), type, x.data(), n, delta);
          EXPECT_EQ(e.tangled, tangled) << elementTypeName(type);
          const FdErrors fe =
              checkElementDerivatives(measureByName(name), torus, type, uv, k, n, delta, 2e-4 / p,
                                      std::string(elementTypeName(type)) + " " + name + " node " +
                                          std::to_string(k) + (tangled ? " (tangled, δ>0)" : ""));
          ++checked;
          if (fe.grad[0] > 1e-7 * (1 + fe.gradNorm) && fe.hess[0] > 1e-7 * (1 + fe.hessNorm))
            ++rateSeen;
        }
    }
  }
  EXPECT_GT(checked, 60);
  EXPECT_GT(rateSeen, checked / 2);  // most errors are above rounding: the rate was checked
  std::printf("%d finite-difference checks, %d with the rate-2 convergence visible\n", checked,
              rateSeen);
}

TEST(HighOrderMeasure, EtaWithoutDeltaFromTheSamePassEqualsASeparateEvaluation) {
  // elementDistortion(…, eta0) gives η at δ = 0 from the Jacobians of the δ > 0 evaluation
  // (what untangling sweeps need for the quality cache): it must be the δ = 0 evaluation's η,
  // +∞ for a tangled element, with or without the derivatives of a free node. And the
  // validity check of the nodes (jacobianValidity) must give jacobianDistortion's minSigma.
  const TorusSurface torus(10, 4);
  const Vec2 valid[3] = {{0.31, 1.2}, {0.45, 1.25}, {0.36, 1.42}};
  const Vec2 flipped[3] = {{0.31, 1.2}, {0.36, 1.42}, {0.45, 1.25}};
  std::vector<ElementType> types(std::begin(kHighOrder), std::end(kHighOrder));
  types.push_back(ElementType::Tri3);
  types.push_back(ElementType::Quad4);
  int finite = 0, infinite = 0;
  for (ElementType type : types) {
    const int p = type == ElementType::Quad4 ? 1 : elementOrder(type);
    for (int variant = 0; variant < 2; ++variant) {
      std::vector<Vec2> uv;
      if (type == ElementType::Quad4) {
        uv = {{0.31, 1.2}, {0.45, 1.21}, {0.47, 1.36}, {0.30, 1.33}};
        if (variant == 1) std::swap(uv[1], uv[3]);
      } else {
        uv = curvedElementUV(p, variant == 1 ? flipped : valid, 0.04 / (p * p), 3 + p);
      }
      std::vector<Vec3> x(uv.size());
      for (std::size_t i = 0; i < uv.size(); ++i) x[i] = torus.value(uv[i].x(), uv[i].y());
      const Vec3 n = torus.normal(uv[0].x(), uv[0].y());
      for (const auto& name : measureNames()) {
        const PlanarMeasure& m = measureByName(name);
        const ElementEval ref = elementDistortion(m, type, x.data(), n, 0.0);
        for (double delta : {0.0, 0.05}) {
          for (int k : {-1, 0, static_cast<int>(uv.size()) - 1}) {
            Vec3 g;
            Mat3 H;
            double eta0 = -1.0;
            const ElementEval e =
                elementDistortion(m, type, x.data(), n, delta, k, k >= 0 ? &g : nullptr,
                                  k >= 0 ? &H : nullptr, &eta0);
            const std::string what = std::string(elementTypeName(type)) + " " + name + " delta " +
                                     std::to_string(delta) + " node " + std::to_string(k);
            EXPECT_EQ(e.tangled, variant == 1) << what;
            EXPECT_NEAR(e.minSigma, ref.minSigma, 1e-14) << what;  // tri3: relabelled corners
            if (std::isfinite(ref.eta)) {
              ++finite;
              EXPECT_NEAR(eta0, ref.eta, 1e-14 * ref.eta) << what;
            } else {
              ++infinite;
              EXPECT_TRUE(std::isinf(eta0)) << what;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(finite, 30);
  EXPECT_GT(infinite, 30);
  // Validity alone, at random Jacobians (both orientations, nearly degenerate ones).
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int t = 0; t < 200; ++t) {
    Jacobian32 J;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 2; ++c) J(r, c) = u(rng);
    if (t % 10 == 0) J.col(1) = J.col(0) * 0.5;  // degenerate
    const Vec3 n(u(rng), u(rng), u(rng));
    const ElementEval full = jacobianDistortion(measureByName("shape"), J, equilateralWinv(), n,
                                                0.0, nullptr, nullptr, nullptr);
    const ElementEval v = jacobianValidity(J, equilateralWinv(), n);
    EXPECT_EQ(v.minSigma, full.minSigma);
    EXPECT_EQ(v.tangled, full.tangled);
  }
}

TEST(HighOrderMeasure, JacobiansPreparedForAFreeNodeGiveTheFreshEvaluationWhereverItMoves) {
  // A line search moves one node of an element and keeps the others: the Jacobians without the
  // free node's term (highOrderJacobians) are prepared once and the element evaluated at each
  // trial position. η, validity and η at δ = 0 must be those of a fresh evaluation of the
  // element with the node moved there (every node's term summed, up to the order of the sums),
  // and the derivatives elementDistortion's, for corner, edge and interior nodes, valid and
  // folded positions.
  const TorusSurface torus(10, 4);
  const Vec2 valid[3] = {{0.31, 1.2}, {0.45, 1.25}, {0.36, 1.42}};
  int compared = 0, folded = 0;
  for (ElementType type : kHighOrder) {
    const int p = elementOrder(type);
    const std::vector<Vec2> uv = curvedElementUV(p, valid, 0.04 / (p * p), 11 + p);
    std::vector<Vec3> x(uv.size());
    for (std::size_t i = 0; i < uv.size(); ++i) x[i] = torus.value(uv[i].x(), uv[i].y());
    const Vec3 n = torus.normal(uv[0].x(), uv[0].y());
    const int nn = static_cast<int>(uv.size());
    for (int k : {0, 3, nn - 1}) {
      HighOrderJacobians pre;
      highOrderJacobians(type, x.data(), k, &pre);
      ASSERT_EQ(pre.freeLocal, k);
      // Steps towards the opposite corner: small ones keep the element valid, the longest
      // folds it.
      const Vec2 target = uv[static_cast<std::size_t>(k == 0 ? 1 : 0)];
      for (double a : {0.0, 0.1, 0.4, 2.5}) {
        const Vec2 t =
            uv[static_cast<std::size_t>(k)] + a * (target - uv[static_cast<std::size_t>(k)]);
        std::vector<Vec3> y = x;
        y[static_cast<std::size_t>(k)] = torus.value(t.x(), t.y());
        for (double delta : {0.0, 0.05}) {
          Vec3 g, gRef;
          Mat3 H, HRef;
          double e0 = -1.0, e0Ref = -1.0;
          const ElementEval e = highOrderTriangleDistortion(
              measureByName("shape"), pre, y[static_cast<std::size_t>(k)], n, delta, &g, &H, &e0);
          // The reference sums every node's term (no free node); its derivatives come from
          // elementDistortion, checked against finite differences above.
          const ElementEval ref = elementDistortion(measureByName("shape"), type, y.data(), n,
                                                    delta, -1, nullptr, nullptr, &e0Ref);
          elementDistortion(measureByName("shape"), type, y.data(), n, delta, k, &gRef, &HRef);
          const std::string what = std::string(elementTypeName(type)) + " node " +
                                   std::to_string(k) + " step " + std::to_string(a) + " delta " +
                                   std::to_string(delta);
          EXPECT_EQ(e.tangled, ref.tangled) << what;
          EXPECT_NEAR(e.minSigma, ref.minSigma, 1e-12) << what;
          if (ref.tangled) ++folded;
          if (!std::isfinite(ref.eta)) {
            EXPECT_TRUE(std::isinf(e.eta)) << what;
            continue;
          }
          ++compared;
          EXPECT_NEAR(e.eta, ref.eta, 1e-12 * ref.eta) << what;
          if (std::isfinite(e0Ref)) {
            EXPECT_NEAR(e0, e0Ref, 1e-12 * e0Ref) << what;
          }
          EXPECT_LE((g - gRef).norm(), 1e-10 * (1.0 + gRef.norm())) << what;
          EXPECT_LE((H - HRef).norm(), 1e-10 * (1.0 + HRef.norm())) << what;
        }
      }
    }
  }
  EXPECT_GT(compared, 60);
  EXPECT_GT(folded, 4);
  // Without a free node the prepared Jacobians are the whole element's.
  const std::vector<Vec2> uv = curvedElementUV(3, valid, 0.004, 7);
  std::vector<Vec3> x(uv.size());
  for (std::size_t i = 0; i < uv.size(); ++i) x[i] = torus.value(uv[i].x(), uv[i].y());
  const Vec3 n = torus.normal(uv[0].x(), uv[0].y());
  HighOrderJacobians all;
  highOrderJacobians(ElementType::Tri10, x.data(), -1, &all);
  EXPECT_EQ(all.freeLocal, -1);
  EXPECT_EQ(highOrderTriangleDistortion(measureByName("oddy"), all, Vec3(1e9, 0, 0), n, 0.0,
                                        nullptr, nullptr)
                .eta,
            elementDistortion(measureByName("oddy"), ElementType::Tri10, x.data(), n, 0.0).eta);
  EXPECT_THROW(highOrderJacobians(ElementType::Quad4, x.data(), 0, &all), std::invalid_argument);
}

// ---- optimization -----------------------------------------------------------------------------

TEST(HighOrderOptimize, CubicMeshOnTorusIsUntangledWithNodesOnTheSurface) {
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusMeshOfOrder(torus, 3);
  const QualityStats unperturbed = measureQuality(m, measureByName("shape")).stats;
  EXPECT_EQ(unperturbed.tangled, 0u);
  perturbAll(m, torus, 120, 7);
  OptimizeOptions opt;
  opt.maxSweeps = 60;
  const OptimizeResult r = optimizeMesh(m, opt);
  printTable("Order-3 mesh of a torus (" + std::to_string(m.nodeCount()) + " nodes), " +
                 std::to_string(r.sweeps) + " sweeps, " + std::to_string(r.seconds) + " s",
             r.before, r.after);
  EXPECT_GT(r.before.tangled, 120u);
  EXPECT_EQ(r.after.tangled, 0u);
  EXPECT_GT(r.after.min, 0.5);
  EXPECT_LE(maxDistanceToSurface(m), 1e-12);
}

TEST(HighOrderOptimize, FoldedSecondOrderNodesAreStraightenedInParameterSpace) {
  // A mesher's second-order nodes projected across a thin or strongly curved face fold
  // elements whose corners are fine. Such an element gets its edge nodes at the parametric
  // midpoints of its corners (straight sides in (u,v)) when that leaves fewer elements
  // tangled around them.
  const TorusSurface torus(10, 4);
  SurfaceMesh m = torusMeshOfOrder(torus, 2);
  const QualityStats straight = measureQuality(m, measureByName("shape")).stats;
  ASSERT_EQ(straight.tangled, 0u);
  // Throw the edge nodes of every other element across it: towards and past the opposite
  // corner, 1.6 × the distance (the corners do not move).
  std::vector<unsigned char> thrown(m.nodeCount(), 0);
  for (std::size_t e = 0; e < m.elementCount(); e += 2) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 3; k < 6; ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (thrown[j] || m.nodeKind[j] != NodeKind::Face) continue;
      const Vec2 opposite = m.elementUV(e)[(k - 3 + 2) % 3];
      const Vec2 mid = m.elementUV(e)[k];
      m.uv[j] = mid + 1.6 * (opposite - mid);
      thrown[j] = 1;
    }
  }
  syncFaceNodes(m);  // positions, and every element's parameters next to where they were
  const QualityStats folded = measureQuality(m, measureByName("shape")).stats;
  ASSERT_GT(folded.tangled, m.elementCount() / 3);
  OptimizeOptions opt;
  opt.maxSweeps = 1;
  opt.highOrder = "integral";  // the integral mode's escape (the reference mode places them)
  const OptimizeResult r = optimizeMesh(m, opt);
  printTable("Order-2 torus mesh with folded edge nodes, 1 sweep (" +
                 std::to_string(r.straightenedElements) + " elements straightened)",
             r.before, r.after);
  EXPECT_EQ(r.after.tangled, 0u);
  // Every folded element was straightened (the sweep alone needed 40× the time here).
  EXPECT_EQ(r.straightenedElements, folded.tangled);
  EXPECT_LE(maxDistanceToSurface(m), 1e-12);
}

TEST(HighOrderOptimize, ElementFoldedBetweenFixedNodesIsHeldAndTheRestUntangled) {
  // A quadratic triangle at a corner of the square, both its sides there on the fixed
  // boundary, whose mid-side node is moved along the boundary beyond the corner: at that
  // corner ∂x/∂ξ = −3 x0 + 4 x3 − x1 (Gmsh order: x3 the mid-side node of side 0–1) points
  // backwards, the element folds there, and only fixed nodes act on that Jacobian. No motion
  // of its free (interior mid-side) node repairs it; the run must hold it from the start and
  // still untangle what elsewhere can be untangled, without the stalled sweeps that end in
  // giving up.
  const PlaneSurface plane;
  const GridMesh lin = squareMesh(5);
  GridMesh g = elevate(plane, lin, 2);
  const std::size_t E = g.conn.size() / 6;
  std::vector<int> uses(g.uv.size(), 0);
  for (std::int32_t id : g.conn) ++uses[static_cast<std::size_t>(id)];
  // The element holding a corner of the square alone, with the corner as its node k.
  std::size_t corner = E;
  int k = -1;
  for (std::size_t e = 0; e < E && corner == E; ++e)
    for (int a = 0; a < 3; ++a)
      if (uses[static_cast<std::size_t>(g.conn[6 * e + a])] == 1) {
        corner = e;
        k = a;
      }
  ASSERT_LT(corner, E);
  // Relabel the element's corners cyclically so that the square's corner is node 0.
  std::int32_t* c = g.conn.data() + 6 * corner;
  std::int32_t el[6] = {c[k],     c[(k + 1) % 3],     c[(k + 2) % 3],
                        c[3 + k], c[3 + (k + 1) % 3], c[3 + (k + 2) % 3]};
  std::copy(el, el + 6, c);
  const std::set<std::int32_t> fixedSet(g.fixed.begin(), g.fixed.end());
  for (int a : {0, 1, 2, 3, 5}) ASSERT_TRUE(fixedSet.count(c[a])) << "node " << a;
  ASSERT_FALSE(fixedSet.count(c[4]));
  const Vec2 x0 = g.uv[static_cast<std::size_t>(c[0])], x1 = g.uv[static_cast<std::size_t>(c[1])];
  g.uv[static_cast<std::size_t>(c[3])] =
      x0 - 0.1 * (x1 - x0);  // −3 x0 + 4 x3 − x1 = −1.4 (x1 − x0)
  SurfaceMesh m = makeSingleSurfaceMesh(plane, g.uv, ElementType::Tri6, g.conn, g.fixed);
  // A repairable fold elsewhere: an interior corner node moved across a neighbour.
  std::size_t inner = m.nodeCount();
  for (std::size_t i = 0; i < lin.uv.size() && inner == m.nodeCount(); ++i)
    if (!fixedSet.count(static_cast<std::int32_t>(i)) && std::abs(lin.uv[i].x() - 0.5) < 0.2 &&
        std::abs(lin.uv[i].y() - 0.5) < 0.2)
      inner = i;
  ASSERT_LT(inner, m.nodeCount());
  const Vec2 moved = m.uv[inner] + Vec2(0.3, 0.05);
  m.uv[inner] = moved;
  syncFaceNodes(m);
  const MeshQuality q0 = measureQuality(m, measureByName("shape"));
  ASSERT_TRUE(q0.tangled[corner]);
  ASSERT_GT(q0.stats.tangled, 1u);

  OptimizeOptions opt;
  opt.maxSweeps = 200;
  const OptimizeResult r = optimizeMesh(m, opt);
  std::printf("%zu tangled → %zu in %d sweeps\n", q0.stats.tangled, r.after.tangled, r.sweeps);
  EXPECT_EQ(r.after.tangled, 1u);
  EXPECT_EQ(r.tangledUnmovable, std::vector<std::int32_t>{static_cast<std::int32_t>(corner)});
  EXPECT_TRUE(r.tangledMovable.empty());
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings[0].find("no node that may move where they fold"), std::string::npos);
  // Held from the start: the run never waits for the give-up of a stalled untangling.
  EXPECT_LT(r.sweeps, 6 * opt.deltaStallSweeps);
  EXPECT_LE(maxDistanceToSurface(m), 1e-12);
}

/// Optimizes `m` in high-order `mode` with at most `sweeps` sweeps and prints the paper's
/// table under `title` (with the mesh's size, the mode, sweeps and seconds).
OptimizeResult runTable4(SurfaceMesh& m, const char* mode, int sweeps, const std::string& title) {
  OptimizeOptions opt;
  opt.maxSweeps = sweeps;
  opt.highOrder = mode;
  const OptimizeResult r = optimizeMesh(m, opt);
  printTable(title + ", " + std::to_string(m.elementCount()) + " elements, " +
                 std::to_string(m.nodeCount()) + " nodes, " + mode + " (" +
                 std::to_string(r.sweeps) + " sweeps, " + std::to_string(r.seconds) + " s)",
             r.before, r.after);
  return r;
}

TEST(HighOrderOptimize, PaperTable4RevolutionSurfaceOrder2IsUntangled) {
  const TopoDS_Face face = revolutionFace();
  const OccFaceSurface surf(face);
  ASSERT_TRUE(surf.isUPeriodic());
  const ParamBounds b = surf.bounds();
  // 29 × 9 cells, boundary circles fixed: 522 triangles as in the paper (Fig. 8).
  const GridMesh lin = periodicGridMesh(29, 9, b.umin, b.umin + 2 * kPi, b.vmin, b.vmax, false);
  const GridMesh g = elevate(surf, lin, 2);
  SurfaceMesh m = makeSingleSurfaceMesh(surf, g.uv, ElementType::Tri6, g.conn, g.fixed);
  m.faceOrientation[0] = surf.normalSign();  // elements are counter-clockwise in (u,v)
  const QualityStats unperturbed = measureQuality(m, measureByName("shape")).stats;
  ASSERT_EQ(m.elementCount(), 522u);
  EXPECT_EQ(unperturbed.tangled, 0u);
  // Mid-edge nodes lie on the surface at the parametric midpoints.
  EXPECT_LE(maxDistanceToSurface(m), 1e-12);

  const double amp = perturbAll(m, surf, m.elementCount() / 2, 2013);
  std::printf("Perturbation: ±%.3f of the mean parametric edge\n", amp);
  const QualityStats perturbed = measureQuality(m, measureByName("shape")).stats;
  ASSERT_GT(perturbed.tangled, m.elementCount() / 2);

  std::printf("Unperturbed order-2 mesh: min %.2f mean %.2f\n", unperturbed.min, unperturbed.mean);
  // The paper's method (the integral mode) and the default straight-sided reference.
  const SurfaceMesh input = m;
  for (const char* mode : {"integral", "reference"}) {
    m = input;
    const OptimizeResult r = runTable4(m, mode, 200, "Table 4 — revolution surface, order 2");
    EXPECT_EQ(r.after.tangled, 0u) << mode;
    EXPECT_GE(r.after.min, 0.7) << mode;
    EXPECT_GT(r.after.mean, r.before.mean) << mode;
    EXPECT_LE(maxDistanceToSurface(m), 1e-9) << mode;
  }
}

TEST(HighOrderOptimize, PaperTable4PropellerBladeOrder5IsSmoothed) {
  const std::string path = std::string(SURFMESH_TEST_DATA_DIR) + "/occt_propeller.brep";
  TopoDS_Shape shape;
  BRep_Builder builder;
  ASSERT_TRUE(BRepTools::Read(shape, path.c_str(), builder)) << path;
  TopTools_IndexedMapOfShape faces;
  TopExp::MapShapes(shape, TopAbs_FACE, faces);
  // The largest four-sided B-spline face: a blade (the six-sided ones have a sharp corner whose
  // sliver, all nodes on the boundary, no smoothing can improve).
  TopoDS_Face blade;
  double bestArea = 0;
  for (int i = 1; i <= faces.Extent(); ++i) {
    const TopoDS_Face f = TopoDS::Face(faces(i));
    if (BRepAdaptor_Surface(f).GetType() != GeomAbs_BSplineSurface) continue;
    TopTools_IndexedMapOfShape edges;
    TopExp::MapShapes(f, TopAbs_EDGE, edges);
    if (edges.Extent() != 4) continue;
    GProp_GProps props;
    BRepGProp::SurfaceProperties(f, props);
    if (props.Mass() > bestArea) bestArea = props.Mass(), blade = f;
  }
  ASSERT_FALSE(blade.IsNull());
  // A linear triangulation of the face's (u,v) domain by BRepMesh, ~500 triangles (the paper's
  // order-5 mesh has 532).
  Handle(Poly_Triangulation) tri;
  for (double defl : {8.0, 4.0, 2.0, 1.0, 0.5, 0.25}) {
    BRepTools::Clean(blade);
    BRepMesh_IncrementalMesh mesher(blade, defl, false, 0.5);
    TopLoc_Location loc;
    tri = BRep_Tool::Triangulation(blade, loc);
    if (!tri.IsNull() && tri->NbTriangles() >= 400) break;
  }
  ASSERT_FALSE(tri.IsNull());
  GridMesh lin;
  for (int i = 1; i <= tri->NbNodes(); ++i) {
    const gp_Pnt2d p = tri->UVNode(i);
    lin.uv.emplace_back(p.X(), p.Y());
  }
  for (int i = 1; i <= tri->NbTriangles(); ++i) {
    int n1, n2, n3;
    tri->Triangle(i).Get(n1, n2, n3);
    std::int32_t c[3] = {n1 - 1, n2 - 1, n3 - 1};
    const Vec2 e1 = lin.uv[c[1]] - lin.uv[c[0]], e2 = lin.uv[c[2]] - lin.uv[c[0]];
    if (e1.x() * e2.y() - e1.y() * e2.x() < 0) std::swap(c[1], c[2]);  // counter-clockwise in (u,v)
    lin.conn.insert(lin.conn.end(), c, c + 3);
  }
  // Nodes on the face boundary (on edges of a single triangle) stay fixed.
  std::map<std::pair<std::int32_t, std::int32_t>, int> uses;
  for (std::size_t k = 0; k < lin.conn.size(); k += 3)
    for (int a = 0; a < 3; ++a) {
      const std::int32_t i = lin.conn[k + a], j = lin.conn[k + (a + 1) % 3];
      ++uses[{std::min(i, j), std::max(i, j)}];
    }
  std::vector<char> isFixed(lin.uv.size(), 0);
  for (const auto& [e, count] : uses)
    if (count == 1) isFixed[e.first] = isFixed[e.second] = 1;
  for (std::size_t i = 0; i < isFixed.size(); ++i)
    if (isFixed[i]) lin.fixed.push_back(static_cast<std::int32_t>(i));

  const OccFaceSurface surf(blade);
  const GridMesh g = elevate(surf, lin, 5);
  SurfaceMesh m = makeSingleSurfaceMesh(surf, g.uv, ElementType::Tri21, g.conn, g.fixed);
  m.faceOrientation[0] = surf.normalSign();

  // The paper's method (the integral mode, its Table 4) smooths the blade; the default
  // straight-sided reference never leaves it worse by quality or Jacobian ratio.
  const SurfaceMesh input = m;
  const std::vector<double> inputRatio = elementJacobianRatio(input);
  const double ratio0 = *std::min_element(inputRatio.begin(), inputRatio.end());
  for (const char* mode : {"integral", "reference"}) {
    m = input;
    const OptimizeResult r =
        runTable4(m, mode, 40, "Table 4 — propeller blade (" + surf.describe() + "), order 5");
    EXPECT_GT(m.elementCount(), 300u);
    EXPECT_EQ(r.before.tangled, 0u) << mode;
    EXPECT_EQ(r.after.tangled, 0u) << mode;
    EXPECT_GT(r.after.min, r.before.min + 0.01) << mode;
    EXPECT_GE(r.after.mean, r.before.mean) << mode;
    EXPECT_LE(r.after.stddev, r.before.stddev) << mode;
    if (std::string(mode) == "reference") {  // cut back to the input's minimum ratio at most
      const std::vector<double> ratio = elementJacobianRatio(m);
      EXPECT_GE(*std::min_element(ratio.begin(), ratio.end()), ratio0 - 1e-9);
    }
    EXPECT_LE(maxDistanceToSurface(m), 1e-9) << mode;
  }
  EXPECT_LE(maxDistanceToSurface(m), 1e-9);
}

}  // namespace

TEST(HighOrderOptimize, FoldBetweenFixedCornersIsHeldWhateverTheCornerNormals) {
  // One quadratic triangle on a unit cylinder spanning 115° of it: corners 0 and 1 at u = ∓1,
  // corner 2 at u = 0 higher up, all three fixed, as are the side nodes of sides 0–1 and 1–2;
  // only the side node of side 2–0 may move. Side 0–1's node is raised towards corner 2, so at
  // corner 1 the side 1→0 turns past side 1→2: the element folds there, where the free node's
  // shape function has no gradient. The element's normal (the sum of its corner normals) cannot
  // change since no corner moves, so no motion repairs it — yet the surface normal at corner 0,
  // 115° away, does not see the fold, which the check for a fold between fixed nodes asked of
  // every corner normal. The element must be reported with those no motion repairs.
  const CylinderSurface cyl(1.0, -2.0, 2.0);
  const std::vector<Vec2> uv = {{-1.0, 0.0}, {1.0, 0.0}, {0.0, 1.0},
                                {0.0, 0.9},  {0.5, 0.5}, {-0.5, 0.5}};
  const std::vector<std::int32_t> conn = {0, 1, 2, 3, 4, 5};
  SurfaceMesh m = makeSingleSurfaceMesh(cyl, uv, ElementType::Tri6, conn, {0, 1, 2, 3, 4});
  ASSERT_EQ(m.nodeKind[5], NodeKind::Face);
  const Vec3 n = elementReferenceNormal(m, 0);
  const Jacobian32 J1 = highOrderJacobianAtNode(ElementType::Tri6, m.xyz.data(), 1);
  ASSERT_TRUE(jacobianValidity(J1, equilateralWinv(), n).tangled);  // the fold at corner 1
  ASSERT_FALSE(jacobianValidity(J1, equilateralWinv(), m.referenceNormal(0, uv[0])).tangled);
  ASSERT_TRUE(measureQuality(m, measureByName("shape")).tangled[0]);

  const OptimizeResult r = optimizeMesh(m, OptimizeOptions{});
  EXPECT_EQ(r.after.tangled, 1u);
  EXPECT_EQ(r.tangledUnmovable, std::vector<std::int32_t>{0});
  EXPECT_TRUE(r.tangledMovable.empty());
}
