// SurfMesh — bad input at the core's entry points (SurfaceMesh::validate, CadShape, CadMesh,
// optimizeMesh) and faults during optimization: every bad input gives std::invalid_argument
// whose message names the problem and the offending ids/counts, and nothing is left modified.
// Regressions found by the fuzz targets (fuzz/) are at the end.
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/cad/occ_mesher.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCone.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRepTools.hxx>
#include <TopoDS_Shape.hxx>
#include <gp_Ax2.hxx>
#include <gp_Pln.hxx>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();
const double kPi = 3.14159265358979323846;

/// Runs f, expects std::invalid_argument, and returns its message ("" if none was thrown).
std::string invalidArgument(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected std::invalid_argument, got another exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected std::invalid_argument, nothing was thrown";
  return "";
}

#define EXPECT_MESSAGE_HAS(msg, text) \
  EXPECT_NE((msg).find(text), std::string::npos) << "message: " << (msg) << "\nexpected: " << (text)

/// A planar 6×6 mesh of the unit square (boundary fixed) on `plane`.
SurfaceMesh planarMesh(const Surface& plane, int n = 6) {
  const GridMesh g = squareMesh(n);
  return makeSingleSurfaceMesh(plane, g.uv, ElementType::Tri3, g.conn, g.fixed);
}

/// First element that does not touch node i, and an interior node.
std::size_t firstFreeNode(const SurfaceMesh& m) {
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (m.nodeKind[i] == NodeKind::Face) return i;
  return 0;
}

void expectSameMesh(const SurfaceMesh& a, const SurfaceMesh& b) {
  EXPECT_TRUE(a.xyz == b.xyz) << "node positions changed";
  EXPECT_TRUE(a.uv == b.uv) << "node (u,v) changed";
  EXPECT_TRUE(a.nodeT == b.nodeT) << "node t changed";
  EXPECT_TRUE(a.cornerUV == b.cornerUV) << "corner (u,v) changed";
  EXPECT_TRUE(a.elemNodes == b.elemNodes) << "connectivity changed";
  EXPECT_TRUE(a.nodeKind == b.nodeKind) << "node kinds changed";
}

// ---- SurfaceMesh::validate ---------------------------------------------------------------------

TEST(ValidateMesh, AcceptsAGoodMesh) {
  const PlaneSurface plane;
  EXPECT_NO_THROW(planarMesh(plane).validate());
}

TEST(ValidateMesh, EmptyMesh) {
  SurfaceMesh m;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "no nodes");
  const PlaneSurface plane;
  SurfaceMesh n =
      makeSingleSurfaceMesh(plane, {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, ElementType::Tri3, {}, {});
  EXPECT_MESSAGE_HAS(invalidArgument([&] { n.validate(); }), "no elements");
}

TEST(ValidateMesh, NonFiniteCoordinatesNameTheNode) {
  const PlaneSurface plane;
  for (double bad : {kNaN, kInf, -kInf}) {
    SurfaceMesh m = planarMesh(plane);
    m.xyz[5].y() = bad;
    const std::string msg = invalidArgument([&] { m.validate(); });
    EXPECT_MESSAGE_HAS(msg, "node 5");
    EXPECT_MESSAGE_HAS(msg, "non-finite");
  }
  SurfaceMesh m = planarMesh(plane);
  const std::size_t i = firstFreeNode(m);
  m.uv[i].x() = kNaN;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }),
                     "face node " + std::to_string(i) + " has non-finite (u,v)");
}

TEST(ValidateMesh, ElementIndicesOutOfRange) {
  const PlaneSurface plane;
  for (std::int32_t bad : {-1, 99999}) {
    SurfaceMesh m = planarMesh(plane);
    m.elemNodes[3 * 4 + 1] = bad;  // element 4, local node 1
    const std::string msg = invalidArgument([&] { m.validate(); });
    EXPECT_MESSAGE_HAS(msg, "element 4 references node " + std::to_string(bad));
    EXPECT_MESSAGE_HAS(msg, "out of range [0, " + std::to_string(m.nodeCount()) + ")");
  }
}

TEST(ValidateMesh, RepeatedNodeInOneElement) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  m.elemNodes[3 * 2 + 2] = m.elemNodes[3 * 2];
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "element 2 repeats node " + std::to_string(m.elemNodes[6]));
}

TEST(ValidateMesh, DuplicateNodesAreReportedWithCountAndExamplePair) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  // Give element 7 its own copy of one of its nodes: a crack in the mesh.
  const std::int32_t old = m.elemNodes[3 * 7];
  const std::int32_t copy = static_cast<std::int32_t>(m.nodeCount());
  m.xyz.push_back(m.xyz[static_cast<std::size_t>(old)]);
  m.uv.push_back(m.uv[static_cast<std::size_t>(old)]);
  m.nodeFace.push_back(0);
  m.nodeKind.push_back(m.nodeKind[static_cast<std::size_t>(old)]);
  m.elemNodes[3 * 7] = copy;
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "1 duplicate node");
  EXPECT_MESSAGE_HAS(msg, "nodes " + std::to_string(old) + " and " + std::to_string(copy));
  EXPECT_MESSAGE_HAS(msg, "not conforming");

  // The same copy in no element is harmless (an unused node).
  m.elemNodes[3 * 7] = old;
  EXPECT_NO_THROW(m.validate());
}

TEST(ValidateMesh, NonManifoldEdgeNamesItsNodesAndElements) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  // Find an interior edge (a, b) shared by two elements and hang a third element on it.
  const std::int32_t* nd = m.elementNodes(10);
  const std::int32_t a = nd[0], b = nd[1];
  std::int32_t c = -1;
  for (std::int32_t i = 0; i < static_cast<std::int32_t>(m.nodeCount()) && c < 0; ++i)
    if (i != a && i != b && i != nd[2] && (m.xyz[i] - m.xyz[a]).norm() > 0.5) c = i;
  const std::int32_t tri[3] = {a, b, c};
  m.addElement(ElementType::Tri3, tri, 0);
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "non-manifold");
  EXPECT_MESSAGE_HAS(msg, "between nodes " + std::to_string(std::min(a, b)) + " and " +
                              std::to_string(std::max(a, b)));
  EXPECT_MESSAGE_HAS(msg, "3 elements");
  EXPECT_MESSAGE_HAS(msg, std::to_string(m.elementCount() - 1) + ")");
}

TEST(ValidateMesh, ElementsOfThreeFacesMayShareAnEdge) {
  // A non-manifold B-rep edge: three faces (fins) meeting along the segment (0,0,0)-(1,0,0).
  const PlaneSurface f0(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitY());
  const PlaneSurface f1(Vec3::Zero(), Vec3::UnitX(), Vec3::UnitZ());
  const PlaneSurface f2(Vec3::Zero(), Vec3::UnitX(), Vec3(0, -1, -1).normalized());
  SurfaceMesh m;
  m.surfaces = {&f0, &f1, &f2};
  m.faceOrientation = {1, 1, 1};
  m.xyz = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 1, 0), Vec3(0.5, 0, 1), f2.value(0.5, 1.0)};
  m.uv = {Vec2(0, 0), Vec2(1, 0), Vec2(0.5, 1), Vec2(0.5, 1), Vec2(0.5, 1)};
  m.nodeFace = {-1, -1, 0, 1, 2};
  m.nodeKind = {NodeKind::Fixed, NodeKind::Fixed, NodeKind::Face, NodeKind::Face, NodeKind::Face};
  const std::int32_t t0[3] = {0, 1, 2}, t1[3] = {0, 1, 3}, t2[3] = {0, 1, 4};
  m.addElement(ElementType::Tri3, t0, 0, nullptr);
  m.addElement(ElementType::Tri3, t1, 1, nullptr);
  m.addElement(ElementType::Tri3, t2, 2, nullptr);
  EXPECT_NO_THROW(m.validate());
}

TEST(ValidateMesh, DuplicateElement) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  // Element 0 again, its nodes rotated: same corners.
  const std::int32_t* nd = m.elementNodes(0);
  const std::int32_t again[3] = {nd[1], nd[2], nd[0]};
  m.addElement(ElementType::Tri3, again, 0);
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "1 duplicate element");
  EXPECT_MESSAGE_HAS(msg, "elements 0 and " + std::to_string(m.elementCount() - 1));
}

TEST(ValidateMesh, UnsupportedElementTypeCode) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  m.elemType[3] = static_cast<ElementType>(9);
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "element 3 has an unsupported element type (code 9");
  EXPECT_MESSAGE_HAS(invalidArgument([] { nodeCount(static_cast<ElementType>(7)); }),
                     "unsupported element type code 7");
  EXPECT_FALSE(isElementTypeCode(7));
  EXPECT_TRUE(isElementTypeCode(6));  // quad8
  EXPECT_EQ(elementTypeFromName("quad8"), ElementType::Quad8);
  EXPECT_MESSAGE_HAS(invalidArgument([] { elementTypeFromName("tri7"); }),
                     "unknown element type 'tri7'");
}

TEST(ValidateMesh, MixedOrders) {
  const PlaneSurface plane;
  // Two triangles sharing the diagonal: one tri3, one tri6 (mid-edge nodes added).
  std::vector<Vec2> uv = {Vec2(0, 0),   Vec2(1, 0),   Vec2(1, 1),    Vec2(0, 1),
                          Vec2(0.5, 1), Vec2(0, 0.5), Vec2(0.5, 0.5)};
  SurfaceMesh m = makeSingleSurfaceMesh(plane, uv, ElementType::Tri3, {0, 1, 2}, {});
  const std::int32_t t6[6] = {0, 2, 3, 6, 4, 5};
  m.addElement(ElementType::Tri6, t6, 0);
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(msg, "mixes element orders");
  EXPECT_MESSAGE_HAS(msg, "element 0 is tri3 (order 1), element 1 is tri6 (order 2)");

  // tri3 and quad4 are both linear: accepted.
  SurfaceMesh q = makeSingleSurfaceMesh(plane, uv, ElementType::Tri3, {0, 1, 6}, {});
  const std::int32_t quad[4] = {1, 2, 4, 6};
  q.addElement(ElementType::Quad4, quad, 0);
  EXPECT_NO_THROW(q.validate());

  // quad8 is of order 2: with tri6 accepted, with tri3 refused, naming both.
  // The unit square split at x = 0.5: a quad8 on the left, two tri6 on the right.
  const std::vector<Vec2> uv2 = {{0, 0},     {0.5, 0},  {0.5, 1},    {0, 1},   {0.25, 0},
                                 {0.5, 0.5}, {0.25, 1}, {0, 0.5},    {1, 0},   {1, 1},
                                 {0.75, 0},  {1, 0.5},  {0.75, 0.5}, {0.75, 1}};
  SurfaceMesh mixed =
      makeSingleSurfaceMesh(plane, uv2, ElementType::Quad8, {0, 1, 2, 3, 4, 5, 6, 7}, {});
  const std::int32_t a[6] = {1, 8, 9, 10, 11, 12}, b[6] = {1, 9, 2, 12, 13, 5};
  mixed.addElement(ElementType::Tri6, a, 0);
  mixed.addElement(ElementType::Tri6, b, 0);
  EXPECT_NO_THROW(mixed.validate());
  SurfaceMesh bad =
      makeSingleSurfaceMesh(plane, uv2, ElementType::Quad8, {0, 1, 2, 3, 4, 5, 6, 7}, {});
  const std::int32_t t3[3] = {1, 8, 9};
  bad.addElement(ElementType::Tri3, t3, 0);
  EXPECT_MESSAGE_HAS(invalidArgument([&] { bad.validate(); }),
                     "element 0 is quad8 (order 2), element 1 is tri3 (order 1)");
}

TEST(ValidateMesh, BrokenArraysNeverReadOutOfBounds) {
  const PlaneSurface plane;
  {
    SurfaceMesh m = planarMesh(plane);
    std::swap(m.elemOffset[2], m.elemOffset[3]);
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "offsets decrease at element");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.elemOffset.back() += 3;
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "element offsets end at");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.elemOffset[0] = 1;
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "elemOffset[0] must be 0");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.elemFace[1] = 3;
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "element 1 has no valid face");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.faceOrientation[0] = 0;
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "faceOrientation[0]");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.uv.pop_back();
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "inconsistent sizes");
  }
  {
    SurfaceMesh m = planarMesh(plane);
    m.nodeKind[firstFreeNode(m)] = NodeKind::Edge;  // no curve
    EXPECT_MESSAGE_HAS(invalidArgument([&] { m.validate(); }), "edge nodes need nodeEdge");
  }
  EXPECT_MESSAGE_HAS(invalidArgument([&] {
                       makeSingleSurfaceMesh(plane, {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)},
                                             ElementType::Tri3, {0, 1, 5}, {});
                     }),
                     "element 0 references node 5 out of range");
  EXPECT_MESSAGE_HAS(invalidArgument([&] {
                       makeSingleSurfaceMesh(plane, {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)},
                                             ElementType::Tri3, {0, 1}, {});
                     }),
                     "not a multiple");
}

// ---- degenerate elements: tangled for quality, fine to untangle ---------------------------------

TEST(DegenerateElements, AreTangledForQualityAndUntangledByTheOptimizer) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  // Put a free node on the line through two of its element's other nodes: zero area.
  const std::size_t e = 12;
  const std::int32_t* nd = m.elementNodes(e);
  std::size_t freeLocal = 3;
  for (int k = 0; k < 3; ++k)
    if (m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Face) freeLocal = k;
  ASSERT_LT(freeLocal, 3u);
  const std::size_t i = static_cast<std::size_t>(nd[freeLocal]);
  const Vec2 a = m.uv[static_cast<std::size_t>(nd[(freeLocal + 1) % 3])];
  const Vec2 b = m.uv[static_cast<std::size_t>(nd[(freeLocal + 2) % 3])];
  m.uv[i] = 0.5 * (a + b);
  syncFaceNodes(m);
  EXPECT_NO_THROW(m.validate());
  const MeshQuality q = measureQuality(m, measureByName("shape"));
  EXPECT_EQ(q.tangled[e], 1);
  EXPECT_EQ(q.quality[e], 0.0);
  const OptimizeResult r = optimizeMesh(m, {});
  EXPECT_GE(r.before.tangled, 1u);
  EXPECT_EQ(r.after.tangled, 0u);
  EXPECT_GT(r.after.min, 0.0);

  // All nodes fixed: nothing can move, no error, the element stays tangled.
  SurfaceMesh f = planarMesh(plane);
  f.uv[i] = 0.5 * (a + b);
  syncFaceNodes(f);
  for (auto& k : f.nodeKind) k = NodeKind::Fixed;
  const SurfaceMesh before = f;
  const OptimizeResult rf = optimizeMesh(f, {});
  EXPECT_EQ(rf.reason, StopReason::NothingToDo);
  EXPECT_GE(rf.after.tangled, 1u);
  expectSameMesh(f, before);
}

// ---- optimizer options -----------------------------------------------------------------------

TEST(OptimizerInput, UnknownMeasureListsTheKnownOnes) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  OptimizeOptions o;
  o.measure = "aspect";
  const std::string msg = invalidArgument([&] { optimizeMesh(m, o); });
  EXPECT_MESSAGE_HAS(msg, "aspect");
  EXPECT_MESSAGE_HAS(msg, "shape");
  EXPECT_MESSAGE_HAS(msg, "oddy");
  EXPECT_MESSAGE_HAS(invalidArgument([] { measureByName(""); }), "shape");
}

TEST(OptimizerInput, NegativeOrNonFiniteTolerancesAndBadOptions) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  const SurfaceMesh copy = m;
  std::vector<std::function<void(OptimizeOptions&)>> bad = {
      [](OptimizeOptions& o) { o.relTol = -1e-5; },
      [](OptimizeOptions& o) { o.moveTol = -1.0; },
      [](OptimizeOptions& o) { o.relTol = kNaN; },
      [](OptimizeOptions& o) { o.delta = 0.0; },
      [](OptimizeOptions& o) { o.deltaEpsilon = -1.0; },
      [](OptimizeOptions& o) { o.delta = kNaN; },
      [](OptimizeOptions& o) { o.maxSweeps = -1; },
      [](OptimizeOptions& o) { o.innerIterations = 0; },
      [](OptimizeOptions& o) { o.maxLineSearch = 0; },
      [](OptimizeOptions& o) { o.threads = -2; },
      [](OptimizeOptions& o) { o.deltaPolicy = "never"; },
  };
  for (std::size_t k = 0; k < bad.size(); ++k) {
    OptimizeOptions o;
    bad[k](o);
    SCOPED_TRACE("bad option " + std::to_string(k));
    EXPECT_FALSE(invalidArgument([&] { optimizeMesh(m, o); }).empty());
    expectSameMesh(m, copy);
  }
  // Zero tolerances are allowed (run to maxSweeps).
  OptimizeOptions o;
  o.relTol = 0.0;
  o.moveTol = 0.0;
  o.maxSweeps = 2;
  EXPECT_NO_THROW(optimizeMesh(m, o));
}

TEST(OptimizerInput, InvalidMeshIsRejectedAndLeftUnchanged) {
  const PlaneSurface plane;
  SurfaceMesh m = planarMesh(plane);
  m.elemNodes[5] = 10000;
  const SurfaceMesh copy = m;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { optimizeMesh(m, {}); }), "references node 10000");
  expectSameMesh(m, copy);
}

// ---- faults: an exception inside the core leaves the mesh unchanged --------------------------

/// Wraps a surface; d1/d2 throw std::runtime_error once a shared budget of calls (counted
/// over all clones) is used up.
class ThrowingSurface final : public Surface {
 public:
  ThrowingSurface(const Surface& inner, std::shared_ptr<std::atomic<long>> budget)
      : inner_(inner.clone()), budget_(std::move(budget)) {}
  Vec3 value(double u, double v) const override {
    spend();
    return inner_->value(u, v);
  }
  SurfaceD1 d1(double u, double v) const override {
    spend();
    return inner_->d1(u, v);
  }
  SurfaceD2 d2(double u, double v) const override {
    spend();
    return inner_->d2(u, v);
  }
  ParamBounds bounds() const override { return inner_->bounds(); }
  bool isUPeriodic() const override { return inner_->isUPeriodic(); }
  bool isVPeriodic() const override { return inner_->isVPeriodic(); }
  double uPeriod() const override { return inner_->uPeriod(); }
  double vPeriod() const override { return inner_->vPeriod(); }
  std::unique_ptr<Surface> clone() const override {
    return std::make_unique<ThrowingSurface>(*inner_, budget_);
  }
  std::string describe() const override { return "throwing " + inner_->describe(); }

 private:
  void spend() const {
    if (budget_->fetch_sub(1) <= 0) throw std::runtime_error("injected surface failure");
  }
  std::unique_ptr<Surface> inner_;
  std::shared_ptr<std::atomic<long>> budget_;
};

TEST(Faults, ExceptionDuringOptimizationLeavesTheMeshUnchanged) {
  const TorusSurface torus(10, 4);
  auto budget = std::make_shared<std::atomic<long>>(std::numeric_limits<long>::max());
  const ThrowingSurface surf(torus, budget);
  const GridMesh g = periodicGridMesh(16, 10, 0, 2 * kPi, 0, 2 * kPi, true);
  SurfaceMesh base = makeSingleSurfaceMesh(surf, g.uv, ElementType::Tri3, g.conn, g.fixed);
  perturbUntilTangled(base, surf, 6, 0.25, 0.4, 11);
  OptimizeOptions opt;
  opt.maxSweeps = 4;
  for (int threads : {1, 2}) {
    opt.threads = threads;
    // Count the surface calls of a complete run.
    SurfaceMesh probe = base;
    budget->store(std::numeric_limits<long>::max());
    optimizeMesh(probe, opt);
    const long total = std::numeric_limits<long>::max() - budget->load();
    ASSERT_GT(total, 100);
    // Fail at 40 points spread over the run, including the very first and last calls.
    int thrown = 0;
    for (int k = 0; k <= 40; ++k) {
      const long n = k == 40 ? total - 1 : total * k / 40;
      SurfaceMesh m = base;
      budget->store(n);
      SCOPED_TRACE("threads " + std::to_string(threads) + ", failing after " + std::to_string(n) +
                   " of " + std::to_string(total) + " surface calls");
      try {
        optimizeMesh(m, opt);
      } catch (const std::runtime_error& e) {
        ++thrown;
        EXPECT_STREQ(e.what(), "injected surface failure");
      }
      expectSameMesh(m, base);
    }
    EXPECT_GE(thrown, 40);
  }
}

TEST(Faults, CancellationAtEverySweepLeavesTheMeshUnchanged) {
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(16, 10, 0, 2 * kPi, 0, 2 * kPi, true);
  SurfaceMesh base = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
  perturbUntilTangled(base, torus, 6, 0.25, 0.4, 11);
  for (int stopAt = 1; stopAt <= 3; ++stopAt) {
    SurfaceMesh m = base;
    int calls = 0;
    const OptimizeResult r =
        optimizeMesh(m, {}, [&](const OptimizeProgress&) { return ++calls < stopAt; });
    EXPECT_EQ(r.reason, StopReason::Cancelled);
    expectSameMesh(m, base);
  }
}

// ---- CAD shapes --------------------------------------------------------------------------------

std::shared_ptr<CadShape> boxShape() {
  static auto s = std::make_shared<CadShape>(BRepPrimAPI_MakeBox(10.0, 10.0, 10.0).Shape());
  return s;
}

/// Structured triangulation of the surface of the box [0,10]³: an n×n grid on every face,
/// nodes shared along the box's edges, triangles wound along the outward normals.
MeshInput boxInput(int n = 5) {
  MeshInput in;
  std::map<std::array<int, 3>, std::int32_t> ids;
  auto node = [&](std::array<int, 3> g) {
    auto it = ids.find(g);
    if (it != ids.end()) return it->second;
    const std::int32_t id = static_cast<std::int32_t>(in.nodes.size());
    in.nodes.push_back(Vec3(g[0], g[1], g[2]) * (10.0 / n));
    ids[g] = id;
    return id;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // (a, b, axis) is right-handed
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          auto at = [&](int di, int dj) {
            std::array<int, 3> g{};
            g[static_cast<std::size_t>(axis)] = side * n;
            g[static_cast<std::size_t>(a)] = i + di;
            g[static_cast<std::size_t>(b)] = j + dj;
            return node(g);
          };
          const std::int32_t p = at(0, 0), q = at(1, 0), r = at(1, 1), t = at(0, 1);
          // Outward normal +axis on side 1 (a×b = axis): counter-clockwise in (a, b).
          if (side == 1)
            in.conn.insert(in.conn.end(), {p, q, r, p, r, t});
          else
            in.conn.insert(in.conn.end(), {p, r, q, p, t, r});
          in.types.insert(in.types.end(), {ElementType::Tri3, ElementType::Tri3});
        }
    }
  return in;
}

/// An element of the box mesh whose nodes all lie strictly inside face `f`'s plane region
/// (not on the box's edges), or −1.
int interiorNodeOf(const MeshInput& in) {
  for (std::size_t i = 0; i < in.nodes.size(); ++i) {
    const Vec3& p = in.nodes[i];
    int inside = 0;
    for (int c = 0; c < 3; ++c) inside += (p[c] > 1e-6 && p[c] < 10 - 1e-6) ? 1 : 0;
    if (inside == 2) return static_cast<int>(i);
  }
  return -1;
}

TEST(CadInput, AGoodBoxMeshIsAccepted) {
  const MeshInput in = boxInput();
  ASSERT_GT(in.nodes.size(), 20u);
  ASSERT_GE(interiorNodeOf(in), 0);
  CadMesh cm(boxShape(), in);
  EXPECT_EQ(cm.report().facesUsed, 6u);
  EXPECT_NO_THROW(cm.mesh().validate());
}

TEST(CadInput, EmptyMesh) {
  MeshInput in;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "no nodes");
  in = boxInput();
  in.types.clear();
  in.conn.clear();
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "no elements");
}

TEST(CadInput, NonFiniteCoordinates) {
  for (double bad : {kNaN, kInf}) {
    MeshInput in = boxInput();
    in.nodes[7].z() = bad;
    const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
    EXPECT_MESSAGE_HAS(msg, "node 7");
    EXPECT_MESSAGE_HAS(msg, "non-finite");
  }
}

TEST(CadInput, IndexOutOfRangeAndRepeatedNode) {
  MeshInput in = boxInput();
  in.conn[3 * 5 + 2] = static_cast<std::int32_t>(in.nodes.size());
  std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
  EXPECT_MESSAGE_HAS(msg, "element 5 references node " + std::to_string(in.nodes.size()));
  in = boxInput();
  in.conn[3 * 5 + 2] = -3;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }),
                     "element 5 references node -3");
  in = boxInput();
  in.conn[3 * 5 + 2] = in.conn[3 * 5];
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "element 5 repeats node");
}

TEST(CadInput, UnsupportedElementTypeCode) {
  for (bool withOffsets : {false, true}) {
    MeshInput in = boxInput();
    if (withOffsets) {
      in.offsets.resize(in.types.size() + 1);
      for (std::size_t e = 0; e <= in.types.size(); ++e)
        in.offsets[e] = static_cast<std::int64_t>(3 * e);
    }
    in.types[4] = static_cast<ElementType>(7);
    const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
    EXPECT_MESSAGE_HAS(msg, "unsupported element type");
    EXPECT_MESSAGE_HAS(msg, "7");
  }
  // A quad8 given three nodes' offsets: refused, naming the element and both counts.
  MeshInput in = boxInput();
  in.offsets.resize(in.types.size() + 1);
  for (std::size_t e = 0; e <= in.types.size(); ++e)
    in.offsets[e] = static_cast<std::int64_t>(3 * e);
  in.types[4] = ElementType::Quad8;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }),
                     "element 4 has 3 nodes, expected 8 for quad8");
}

TEST(CadInput, BadOffsets) {
  MeshInput in = boxInput();
  in.offsets = {0, 3};
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "offsets must have");
  in = boxInput();
  in.conn.pop_back();
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "connectivity has");
}

TEST(CadInput, DuplicateNodes) {
  MeshInput in = boxInput();
  const int i = interiorNodeOf(in);
  ASSERT_GE(i, 0);
  // Give one element that uses node i its own copy of it.
  std::size_t k = 0;
  while (in.conn[k] != i) ++k;
  in.nodes.push_back(in.nodes[static_cast<std::size_t>(i)]);
  in.conn[k] = static_cast<std::int32_t>(in.nodes.size() - 1);
  const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
  EXPECT_MESSAGE_HAS(msg, "1 duplicate node");
  EXPECT_MESSAGE_HAS(msg,
                     "nodes " + std::to_string(i) + " and " + std::to_string(in.nodes.size() - 1));
}

// An element across a CAD edge (one node on each face, one on the edge) is an error when its
// nodes are farther than the tolerance from every common face; within the tolerance (nodes a
// mesher left off both faces of an edge as sloppy as the elements) it goes on one of the
// edge's faces, with a warning.
TEST(CadInput, AnElementAcrossACadEdge) {
  for (double s : {0.005, 0.05}) {  // the tolerance is 1e-3 x diagonal = 0.0173
    MeshInput in = boxInput();
    std::int32_t corner = -1;  // a node on the edge x = y = 0, inside it
    for (std::size_t n = 0; n < in.nodes.size() && corner < 0; ++n)
      if (in.nodes[n].x() == 0.0 && in.nodes[n].y() == 0.0 && in.nodes[n].z() > 1.0 &&
          in.nodes[n].z() < 9.0)
        corner = static_cast<std::int32_t>(n);
    ASSERT_GE(corner, 0);
    const Vec3 c = in.nodes[static_cast<std::size_t>(corner)];
    const std::int32_t a = static_cast<std::int32_t>(in.nodes.size());
    in.nodes.push_back(c + Vec3(0.0, s, 0.5 * s));  // on the face x = 0
    in.nodes.push_back(c + Vec3(s, 0.0, 0.5 * s));  // on the face y = 0
    in.types.push_back(ElementType::Tri3);
    in.conn.insert(in.conn.end(), {corner, a, a + 1});
    if (s > 0.0173) {
      const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
      EXPECT_MESSAGE_HAS(
          msg, "element " + std::to_string(in.types.size() - 1) + " lies on no single face");
      continue;
    }
    CadMesh cm(boxShape(), in);
    const std::size_t e = in.types.size() - 1;
    const int f = cm.mesh().elemFace[e];
    const auto& report = cm.report();
    ASSERT_EQ(report.nodeClass[static_cast<std::size_t>(corner)], NodeClass::Edge);
    const auto& faces = boxShape()->edgeFaces(report.nodeEntity[static_cast<std::size_t>(corner)]);
    EXPECT_NE(std::find(faces.begin(), faces.end(), f), faces.end());
    bool warned = false;
    for (const auto& w : report.warnings)
      warned = warned || (w.find("put on the face") != std::string::npos &&
                          w.find("element " + std::to_string(e)) != std::string::npos);
    EXPECT_TRUE(warned);
  }
}

TEST(CadInput, NonManifoldEdge) {
  MeshInput in = boxInput();
  const int i = interiorNodeOf(in);
  ASSERT_GE(i, 0);
  // An element (a, b, c) with a = i; hang a third element on its edge (a, b) whose third node
  // is another node of the same face, not adjacent.
  std::size_t e = 0;
  while (in.conn[3 * e] != i && in.conn[3 * e + 1] != i && in.conn[3 * e + 2] != i) ++e;
  const std::int32_t a = in.conn[3 * e], b = in.conn[3 * e + 1], c = in.conn[3 * e + 2];
  int axis = -1;  // the coordinate constant on i's face
  for (int d = 0; d < 3; ++d) {
    const double x = in.nodes[static_cast<std::size_t>(i)][d];
    if (x < 1e-6 || x > 10 - 1e-6) axis = d;
  }
  ASSERT_GE(axis, 0);
  const double plane = in.nodes[static_cast<std::size_t>(i)][axis];
  std::int32_t far = -1;
  for (std::size_t n = 0; n < in.nodes.size() && far < 0; ++n)
    if (std::abs(in.nodes[n][axis] - plane) < 1e-9 &&
        (in.nodes[n] - in.nodes[static_cast<std::size_t>(i)]).norm() > 4.0 &&
        static_cast<std::int32_t>(n) != c)
      far = static_cast<std::int32_t>(n);
  ASSERT_GE(far, 0);
  in.types.push_back(ElementType::Tri3);
  in.conn.insert(in.conn.end(), {a, b, far});
  const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
  EXPECT_MESSAGE_HAS(msg, "non-manifold");
  EXPECT_MESSAGE_HAS(msg, "between nodes " + std::to_string(std::min(a, b)) + " and " +
                              std::to_string(std::max(a, b)));
}

TEST(CadInput, MixedOrders) {
  MeshInput in = boxInput();
  // Element e lies inside one face (all of the box's faces are planar): make it a tri6 with
  // its mid-edge nodes, the rest stay tri3.
  const std::size_t e = 0;
  const std::int32_t nd[3] = {in.conn[0], in.conn[1], in.conn[2]};
  std::vector<std::int32_t> six(nd, nd + 3);
  for (int k = 0; k < 3; ++k) {
    in.nodes.push_back(0.5 * (in.nodes[static_cast<std::size_t>(nd[k])] +
                              in.nodes[static_cast<std::size_t>(nd[(k + 1) % 3])]));
    six.push_back(static_cast<std::int32_t>(in.nodes.size() - 1));
  }
  in.types[e] = ElementType::Tri6;
  in.conn.erase(in.conn.begin(), in.conn.begin() + 3);
  in.conn.insert(in.conn.begin(), six.begin(), six.end());
  const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
  EXPECT_MESSAGE_HAS(msg, "mixes element orders");
  EXPECT_MESSAGE_HAS(msg, "tri6");
}

TEST(CadInput, NodesOffTheShapeAreCountedAndNamed) {
  MeshInput in = boxInput();
  const int i = interiorNodeOf(in);
  ASSERT_GE(i, 0);
  // Push the node 1.0 out of its face (tolerance: 1e-3 · diagonal ≈ 0.017).
  for (int d = 0; d < 3; ++d) {
    double& x = in.nodes[static_cast<std::size_t>(i)][d];
    if (x < 1e-6) x = -1.0;
    if (x > 10 - 1e-6) x = 11.0;
  }
  const std::string msg = invalidArgument([&] { CadMesh(boxShape(), in); });
  EXPECT_MESSAGE_HAS(msg, "1 of " + std::to_string(in.nodes.size()) + " nodes are farther");
  EXPECT_MESSAGE_HAS(msg, "node " + std::to_string(i) + " at distance 1");
  // A larger tolerance accepts it.
  BridgeOptions o;
  o.tolerance = 1.5;
  EXPECT_NO_THROW(CadMesh(boxShape(), in, o));
}

TEST(CadInput, MeshOfAnotherShape) {
  // Far away: bounding boxes disjoint.
  auto cyl = std::make_shared<CadShape>(
      BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(100, 0, 0), gp_Dir(0, 0, 1)), 3.0, 8.0).Shape());
  std::string msg = invalidArgument([&] { CadMesh(cyl, boxInput()); });
  EXPECT_MESSAGE_HAS(msg, "does not lie on this shape");
  EXPECT_MESSAGE_HAS(msg, "bounding box");
  // Overlapping boxes, but another shape: a sphere inside the box.
  auto sph = std::make_shared<CadShape>(BRepPrimAPI_MakeSphere(gp_Pnt(5, 5, 5), 5.0).Shape());
  msg = invalidArgument([&] { CadMesh(sph, boxInput()); });
  EXPECT_MESSAGE_HAS(msg, "does not lie on this shape");
  EXPECT_MESSAGE_HAS(msg, "sampled nodes are farther");
}

TEST(CadInput, ToleranceAndBoundaryOptions) {
  for (double bad : {-1.0, -1e-300, kNaN, kInf}) {
    BridgeOptions o;
    o.tolerance = bad;
    EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), boxInput(), o); }),
                       "tolerance must be >= 0");
  }
  BridgeOptions o;
  o.tolerance = 0.0;  // automatic: 1e-3 x diagonal
  CadMesh cm(boxShape(), boxInput(), o);
  EXPECT_NEAR(cm.report().tolerance, 1e-3 * boxShape()->diagonal(), 1e-12);
  o.boundary = "glue";
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), boxInput(), o); }),
                     "unknown boundary mode 'glue'");
}

TEST(CadInput, BadHints) {
  MeshInput in = boxInput();
  in.hintFace.assign(in.nodes.size() - 1, -1);
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "hintFace must be");
  // Hint arrays one short of the nodes, or made before a node was added (the input of
  // fuzz_cad_mesh crash-269d252c, whose harness itself wrote past such an array).
  in = boxInput();
  in.hintEdge.assign(in.nodes.size() - 1, -1);
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "hintEdge must be");
  in = boxInput();
  in.hintVertex.assign(in.nodes.size(), -1);
  in.nodes.push_back(in.nodes[0]);
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }), "hintVertex must be");
  in = boxInput();
  in.hintEdge.assign(in.nodes.size(), -1);
  in.hintEdge[4] = 12;  // the box has 12 edges: 0..11
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(boxShape(), in); }),
                     "hintEdge[4] = 12 out of range");
  // A wrong but in-range hint is ignored with a warning.
  in = boxInput();
  in.hintVertex.assign(in.nodes.size(), -1);
  const int i = interiorNodeOf(in);
  in.hintVertex[static_cast<std::size_t>(i)] = 0;
  CadMesh cm(boxShape(), in);
  EXPECT_EQ(cm.report().hintsRejected, 1u);
}

TEST(CadInput, InvalidOrEmptyShape) {
  EXPECT_MESSAGE_HAS(invalidArgument([] { CadShape s{TopoDS_Shape()}; }), "");
  EXPECT_FALSE(invalidArgument([] { CadShape::fromBrepString(""); }).empty());
  EXPECT_FALSE(invalidArgument([] { CadShape::fromBrepString("this is not a BREP"); }).empty());
  // Edges but no face.
  const TopoDS_Shape wire =
      BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(1, 0, 0)).Edge())
          .Wire();
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadShape s{wire}; }), "face");
  std::ostringstream os;
  BRepTools::Write(wire, os);
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadShape::fromBrepString(os.str()); }), "face");
  EXPECT_MESSAGE_HAS(invalidArgument([&] { CadMesh(nullptr, boxInput()); }), "no shape");
}

TEST(CadInput, FilesThatAreMissingOrNotShapes) {
  const std::string dir = std::string(SURFMESH_TEST_DATA_DIR) + "/bad/";
  for (const char* f : {"does_not_exist.step", "not_a_shape.step", "not_a_shape.brep", "empty.brep",
                        "empty.step", "square.msh"}) {
    SCOPED_TRACE(f);
    const std::string msg = invalidArgument([&] { CadShape::fromFile(dir + f); });
    EXPECT_MESSAGE_HAS(msg, f);
  }
}

TEST(CadInput, AShapeWithFreeFacesOnlyWorks) {
  // A surface mesh is often made on a face or an open shell, not a solid.
  const TopoDS_Shape face =
      BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 0.0, 10.0, 0.0, 6.0).Face();
  auto shape = std::make_shared<CadShape>(face);
  MeshInput grid;
  {
    const GridMesh g = squareMesh(8, 10.0, 6.0);
    for (const Vec2& p : g.uv) grid.nodes.push_back(Vec3(p.x(), p.y(), 0.0));
    grid.conn = g.conn;
    grid.types.assign(g.conn.size() / 3, ElementType::Tri3);
  }
  CadMesh cm(shape, grid);
  EXPECT_EQ(cm.report().facesUsed, 1u);
  EXPECT_GT(cm.report().faceNodes, 0u);
  // Perturb the interior nodes in the plane and optimize: the boundary stays.
  SurfaceMesh& m = cm.mesh();
  for (std::size_t n = 0; n < m.nodeCount(); ++n)
    if (m.nodeKind[n] == NodeKind::Face)
      m.uv[n] += Vec2(0.3 * std::sin(7.0 * n), 0.3 * std::cos(5.0 * n));
  syncFaceNodes(m);
  const std::vector<Vec3> before = m.xyz;
  const OptimizeResult r = optimizeMesh(m, {});
  EXPECT_EQ(r.after.tangled, 0u);
  for (std::size_t n = 0; n < m.nodeCount(); ++n)
    if (m.nodeKind[n] == NodeKind::Fixed) {
      EXPECT_EQ(m.xyz[n], before[n]);
    }
  // An open cylinder (lateral face only, with its seam).
  const TopoDS_Shape cylFace = BRepPrimAPI_MakeCylinder(3.0, 8.0).Cylinder().LateralFace();
  auto cshape = std::make_shared<CadShape>(cylFace);
  const OccMesh cmesh = meshWithBRepMesh(*cshape, 0.05, 0.5);
  CadMesh cc(cshape, cmesh.input);
  EXPECT_EQ(cc.report().facesUsed, 1u);
  EXPECT_NO_THROW(optimizeMesh(cc.mesh(), {}));
}

/// Checks the invariants of an optimization on a real shape: nodes on their faces, tangled
/// count not increased, minimum quality not lowered (monotone mode).
void expectInvariants(const CadMesh& cm, const OptimizeResult& r, const std::vector<Vec3>& x0) {
  const SurfaceMesh& m = cm.mesh();
  EXPECT_LE(r.after.tangled, r.before.tangled);
  if (r.before.tangled == 0) {
    EXPECT_GE(r.after.min, r.before.min - 1e-12);
  }
  double worst = 0.0;
  for (std::size_t n = 0; n < m.nodeCount(); ++n) {
    if (m.nodeKind[n] == NodeKind::Fixed) {
      EXPECT_EQ(m.xyz[n], x0[n]) << "fixed node " << n << " moved";
    } else if (m.nodeKind[n] == NodeKind::Face) {
      const Surface& s = *m.surfaces[static_cast<std::size_t>(m.nodeFace[n])];
      worst = std::max(worst, (s.value(m.uv[n].x(), m.uv[n].y()) - m.xyz[n]).norm());
      // A node left where it was may lie within an edge's tolerance (its input position).
      if (m.xyz[n] != x0[n])
        EXPECT_TRUE(s.contains(m.uv[n].x(), m.uv[n].y())) << "node " << n << " left its face";
    }
  }
  EXPECT_LE(worst, 1e-9 * cm.shape().diagonal());
}

TEST(CadInput, SphereWithPolesWorks) {
  // OCC's sphere has two degenerated edges (poles): their nodes are fixed vertex nodes.
  auto shape = std::make_shared<CadShape>(BRepPrimAPI_MakeSphere(4.0).Shape());
  const OccMesh om = meshWithBRepMesh(*shape, 0.05, 0.3);
  CadMesh cm(shape, om.input);
  EXPECT_GE(cm.report().poleNodes, 2u);
  const std::vector<Vec3> x0 = cm.mesh().xyz;
  OptimizeOptions o;
  o.maxSweeps = 10;
  const OptimizeResult r = optimizeMesh(cm.mesh(), o);
  expectInvariants(cm, r, x0);
}

/// Edge use counts of an all-Tri3 MeshInput: {boundary edges (1 use), non-manifold edges (> 2),
/// coincident triangles (same three nodes)}.
std::array<std::size_t, 3> triangleTopology(const MeshInput& in) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> uses;
  std::set<std::array<std::int32_t, 3>> seen;
  std::size_t coincident = 0;
  for (std::size_t e = 0; e < in.types.size(); ++e) {
    std::array<std::int32_t, 3> k = {in.conn[3 * e], in.conn[3 * e + 1], in.conn[3 * e + 2]};
    std::sort(k.begin(), k.end());
    if (!seen.insert(k).second) ++coincident;
    ++uses[{k[0], k[1]}];
    ++uses[{k[1], k[2]}];
    ++uses[{k[0], k[2]}];
  }
  std::array<std::size_t, 3> r = {0, 0, coincident};
  for (const auto& u : uses) {
    if (u.second == 1) ++r[0];
    if (u.second > 2) ++r[1];
  }
  return r;
}

TEST(CadInput, CoincidentTrianglesOfAMergedPoleAreDropped) {
  // A fan around a pole P = node 0 (ring 1..6), as meshWithBRepMesh builds it once a pole's
  // nodes are merged, plus what BRepMesh leaves where an interior edge sees both ends of a
  // degenerated edge: a triangle of the fan once more with each winding (a fold), and another
  // one copied with the same winding.
  MeshInput in;
  for (int k = 0; k <= 6; ++k)
    in.nodes.emplace_back(k == 0 ? 0.0 : std::cos(k), k == 0 ? 0.0 : std::sin(k), 0.0);
  std::vector<std::int32_t> fan;
  for (int k = 1; k <= 6; ++k) fan.insert(fan.end(), {0, k, k % 6 + 1});
  std::vector<std::int32_t> faces = {0, 0, 0, 0, 0, 0};
  // A fold: (0, 3, 4) wound both ways (face 7), and a same-winding copy of (0, 5, 6) (face 8).
  in.conn = fan;
  in.conn.insert(in.conn.end(), {4, 3, 0, 3, 4, 0, 5, 6, 0});
  faces.insert(faces.end(), {7, 7, 8});
  in.types.assign(in.conn.size() / 3, ElementType::Tri3);
  std::array<std::size_t, 3> topo = triangleTopology(in);
  EXPECT_EQ(topo[1], 5u);  // (0,3), (0,4): 4 uses; (3,4), (0,5), (0,6): 3 uses
  EXPECT_EQ(topo[2], 3u);
  // (0,3,4) appears 3 times: +1 (fan), −1, +1 → net +1, one stays (the fan's); (0,5,6) twice
  // with the same winding → one stays.
  EXPECT_EQ(dropCoincidentTriangles(in, &faces), 3u);
  EXPECT_EQ(in.conn, fan);
  EXPECT_EQ(faces, std::vector<std::int32_t>(6, 0));
  EXPECT_EQ(in.types.size(), 6u);
  topo = triangleTopology(in);
  EXPECT_EQ(topo[1], 0u);
  EXPECT_EQ(topo[2], 0u);
  // A balanced pair alone goes entirely; a clean mesh is left as it is.
  MeshInput pair = in;
  pair.conn = {0, 1, 2, 2, 1, 0, 0, 2, 3};
  pair.types.assign(3, ElementType::Tri3);
  EXPECT_EQ(dropCoincidentTriangles(pair, nullptr), 2u);
  EXPECT_EQ(pair.conn, (std::vector<std::int32_t>{0, 2, 3}));
  MeshInput clean = in;
  EXPECT_EQ(dropCoincidentTriangles(clean, nullptr), 0u);
  EXPECT_EQ(clean.conn, in.conn);
  // Only for tri3 meshes.
  MeshInput quad = in;
  quad.types[0] = ElementType::Quad4;
  EXPECT_MESSAGE_HAS(invalidArgument([&] { dropCoincidentTriangles(quad, nullptr); }),
                     "element 0 is not a tri3");
}

TEST(CadInput, BRepMeshOfShapesWithPolesIsAClosedManifold) {
  // Spheres, cones and their B-spline versions (degenerated edges on B-spline faces, as in
  // STEP files from other systems): the merged BRepMesh triangulation of each closed solid
  // uses every edge exactly twice, and CadMesh takes it as it is.
  std::vector<std::pair<std::string, TopoDS_Shape>> shapes;
  const TopoDS_Shape sphere = BRepPrimAPI_MakeSphere(4.0).Shape();
  const TopoDS_Shape cone = BRepPrimAPI_MakeCone(3.0, 0.0, 5.0).Shape();
  shapes.emplace_back("sphere", sphere);
  shapes.emplace_back("cone", cone);
  shapes.emplace_back("B-spline sphere", BRepBuilderAPI_NurbsConvert(sphere).Shape());
  shapes.emplace_back("B-spline cone", BRepBuilderAPI_NurbsConvert(cone).Shape());
  for (const auto& [name, s] : shapes) {
    auto shape = std::make_shared<CadShape>(s);
    for (const double rel : {1e-2, 2e-3}) {
      SCOPED_TRACE(name + " deflection " + std::to_string(rel));
      const OccMesh om = meshWithBRepMesh(*shape, rel * shape->diagonal(), 0.5);
      EXPECT_GT(om.droppedTriangles, 0u);  // the pole's collapsed triangles
      const std::array<std::size_t, 3> topo = triangleTopology(om.input);
      EXPECT_EQ(topo, (std::array<std::size_t, 3>{0, 0, 0}));
      EXPECT_EQ(om.elemFace.size(), om.input.types.size());
      CadMesh cm(shape, om.input);
      EXPECT_GE(cm.report().poleNodes, 1u);
    }
  }
}

TEST(Benchmark, UJointWithDegeneratedEdges) {
  // Third-party GPL part, used from ../shared only (never copied into the repository). Its
  // B-spline faces with degenerated edges are where BRepMesh made triangles that coincide
  // once the poles' nodes are merged: meshWithBRepMesh drops them, and the result is a closed
  // manifold mesh that SurfMesh measures and optimizes with its invariants.
  const std::string path = std::string(SURFMESH_SHARED_DATA_DIR) + "/gmsh_u_joint.step";
  if (!std::ifstream(path).good()) GTEST_SKIP() << "absent: " << path;
  auto shape = CadShape::fromFile(path);
  const OccMesh om = meshWithBRepMesh(*shape, 2e-3 * shape->diagonal(), 0.5);
  std::printf("u-joint: %zu nodes, %zu triangles, %zu collapsed and %zu coincident dropped\n",
              om.input.nodes.size(), om.input.types.size(), om.droppedTriangles,
              om.droppedCoincident);
  EXPECT_GT(om.droppedCoincident, 0u);
  EXPECT_EQ(triangleTopology(om.input), (std::array<std::size_t, 3>{0, 0, 0}));
  CadMesh cm(shape, om.input);
  std::printf("%s", cm.report().summary().c_str());
  EXPECT_GT(cm.report().poleNodes, 0u);
  const std::vector<Vec3> x0 = cm.mesh().xyz;
  OptimizeOptions o;
  o.maxSweeps = 5;
  const OptimizeResult r = optimizeMesh(cm.mesh(), o);
  printTableRow("u-joint before", r.before);
  printTableRow("u-joint after", r.after);
  expectInvariants(cm, r, x0);
}

// ---- regressions found by fuzzing (fuzz/) ------------------------------------------------------

TEST(FuzzRegression, ElementNodeReplacedWithoutItsCornerUVIsRejected) {
  // fuzz_surface_mesh crash-f2308ab2: on a 6×4 torus grid, element 0's first node was replaced
  // (0 → 16) while its corner (u,v) stayed those of node 0. validate() accepted it, and the
  // optimizer (which takes reference normals from the corner (u,v)) then lowered the minimum
  // quality in monotone mode. Such a mesh is corrupt: validate() must reject it.
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(6, 4, 0, 2 * kPi, 0, 2 * kPi, true);
  SurfaceMesh m = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
  ASSERT_NO_THROW(m.validate());
  const std::int32_t other = m.elemNodes[0] == 16 ? 17 : 16;
  m.elemNodes[0] = other;
  const std::string msg = invalidArgument([&] { m.validate(); });
  EXPECT_MESSAGE_HAS(
      msg, "element 0: the corner (u,v) of node " + std::to_string(other) + " does not match");
  // Shifted by a whole period it is the same point: accepted.
  SurfaceMesh p = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
  for (int k = 0; k < 3; ++k) p.cornerUV[static_cast<std::size_t>(k)].x() += 2 * kPi;
  EXPECT_NO_THROW(p.validate());
}

TEST(FuzzRegression, ElementStandingAcrossItsSurfaceKeepsTheMonotoneInvariant) {
  // fuzz_surface_mesh crash-3fe80200: one triangle spanning half a torus (R = 10, r = 4), a
  // fixed corner at (u,v) = (3π/4, 7π/4) and two face nodes at (7π/4, 3π/8) and (7π/4, 0). By
  // symmetry its plane contains its reference normal (c·n = 0: it stands across the surface).
  // The quality report (normals at the corner (u,v), unwrapped) called it valid (min quality
  // 0.019) by rounding while the optimizer (normals at the wrapped (u,v)) saw it tangled, so
  // in monotone mode with the Oddy measure it was flattened to quality 0.0025. An element
  // perpendicular to its normal within kPerpendicularTol is now tangled for both.
  const TorusSurface torus(10.0, 4.0);
  const double q1 = 0x1.2d97c7f3321d2p+1, q7 = 0x1.5fdbbe9bba775p+2, e8 = 0x1.2d97c7f3321d2p+0;
  const auto mesh = [&](double du) {
    return makeSingleSurfaceMesh(torus, {{q1, q7}, {q7 + du, e8}, {q7, 0.0}}, ElementType::Tri3,
                                 {0, 1, 2}, {0});
  };
  for (const char* name : {"oddy", "shape"}) {
    const SurfaceMesh m = mesh(0.0);
    const MeshQuality q = measureQuality(m, measureByName(name));
    EXPECT_EQ(q.tangled[0], 1) << name << ": perpendicular element reported valid";
    EXPECT_EQ(q.quality[0], 0.0) << name;
  }
  // The invariant on the element and on nearby ones (tilted by du in u: from rounding noise to
  // clearly oriented), for both measures and a few sweep counts: in monotone mode a valid
  // input's minimum quality never drops and the tangled count never grows, as measured by the
  // quality report itself.
  int checkedValid = 0;
  for (const double du : {0.0, 1e-15, -1e-15, 1e-13, -1e-11, 1e-8, -1e-6, 1e-3, -0.05, 0.2})
    for (const char* name : {"oddy", "shape"})
      for (const int sweeps : {1, 3}) {
        SurfaceMesh m = mesh(du);
        OptimizeOptions o;
        o.measure = name;
        o.maxSweeps = sweeps;
        o.monotone = true;
        o.threads = 1;
        const QualityStats before = measureQuality(m, measureByName(name)).stats;
        const OptimizeResult r = optimizeMesh(m, o);
        const QualityStats after = measureQuality(m, measureByName(name)).stats;
        SCOPED_TRACE(std::string(name) + " du " + std::to_string(du) + " sweeps " +
                     std::to_string(sweeps));
        EXPECT_EQ(r.before.tangled, before.tangled);
        EXPECT_EQ(r.after.tangled, after.tangled);
        EXPECT_LE(after.tangled, before.tangled);
        if (before.tangled == 0) {
          ++checkedValid;
          EXPECT_GE(after.min, before.min - 1e-12);
        }
      }
  EXPECT_GT(checkedValid, 0);  // the clearly oriented ones
}

TEST(FuzzRegression, ElementWhoseCornerNormalsCancelIsTangled) {
  // Three corners 120° apart on the equator of a sphere: their normals sum to rounding noise,
  // whose direction used to decide the orientation. No reference normal: tangled, for the
  // quality report and the optimizer alike; optimizing does not make things worse.
  const SphereSurface sphere(3.0);
  const std::vector<Vec2> uv = {{0.0, 0.0}, {2 * kPi / 3, 0.0}, {4 * kPi / 3, 0.0}};
  for (const bool flip : {false, true}) {
    SurfaceMesh m = makeSingleSurfaceMesh(
        sphere, uv, ElementType::Tri3,
        flip ? std::vector<std::int32_t>{0, 2, 1} : std::vector<std::int32_t>{0, 1, 2}, {0});
    EXPECT_EQ(elementReferenceNormal(m, 0), Vec3::Zero());
    for (const char* name : {"oddy", "shape"}) {
      const MeshQuality q = measureQuality(m, measureByName(name));
      EXPECT_EQ(q.tangled[0], 1) << name;
      SurfaceMesh w = m;
      OptimizeOptions o;
      o.measure = name;
      o.maxSweeps = 3;
      o.threads = 1;
      const OptimizeResult r = optimizeMesh(w, o);
      EXPECT_EQ(r.before.tangled, 1u) << name;
      EXPECT_LE(r.after.tangled, r.before.tangled) << name;
      EXPECT_EQ(measureQuality(w, measureByName(name)).stats.tangled, r.after.tangled) << name;
    }
  }
}

}  // namespace
