// SurfMesh — end to end on real parts: BRepMesh mesh → CAD bridge → optimizer. The optimized
// nodes must stay on their CAD faces (checked with OCC's own Geom surfaces and
// BRepClass_FaceClassifier), nothing that a node move can repair may end tangled, and quality
// must not drop; sliding edge nodes must never end worse than fixed ones.
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/occ_mesher.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepClass_FaceClassifier.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_Curve.hxx>
#include <Geom_Surface.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>

using namespace surfmesh;

namespace {

std::shared_ptr<CadShape> load(const std::string& name) {
  static std::map<std::string, std::shared_ptr<CadShape>> cache;
  auto& s = cache[name];
  if (!s) s = CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/" + name);
  return s;
}

struct OnShapeCheck {
  double worstSurface = 0.0;     ///< |Geom_Surface(u,v) − x| over moved face nodes
  double worstProjection = 0.0;  ///< GeomAPI distance to the face's surface
  std::size_t outside = 0;       ///< moved face nodes outside their trimmed face
  /// moved face nodes within the tolerance of an edge or vertex of their face (OCC counts
  /// them ON it; re-read with tolerance hints they are edge or vertex nodes)
  std::size_t inToleranceZone = 0;
  double worstCurve = 0.0;  ///< |Geom_Curve(t) − x| over moved edge nodes
  std::size_t moved = 0;
};

/// Independent OCC checks of every node that moved.
OnShapeCheck checkMovedNodes(const CadShape& shape, const SurfaceMesh& m,
                             const std::vector<Vec3>& before) {
  OnShapeCheck c;
  for (std::size_t n = 0; n < m.nodeCount(); ++n) {
    if ((m.xyz[n] - before[n]).norm() == 0.0) continue;
    ++c.moved;
    const Vec3& p = m.xyz[n];
    if (m.nodeKind[n] == NodeKind::Face) {
      const int f = m.nodeFace[n];
      const Handle(Geom_Surface) g = BRep_Tool::Surface(shape.face(f));
      const gp_Pnt q = g->Value(m.uv[n].x(), m.uv[n].y());
      c.worstSurface = std::max(c.worstSurface, (Vec3(q.X(), q.Y(), q.Z()) - p).norm());
      GeomAPI_ProjectPointOnSurf pr(gp_Pnt(p.x(), p.y(), p.z()), g);
      if (pr.NbPoints() > 0) c.worstProjection = std::max(c.worstProjection, pr.LowerDistance());
      // Strictly inside: within the surface's range (a B-spline is extrapolated beyond its
      // knots) and IN by OCC's exact classifier (ON, within the tolerance of a loop, would
      // let Face.distToShape measure the node to the loop's 3D edge).
      const OccFaceSurface& s = shape.surface(f);
      double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
      g->Bounds(u0, u1, v0, v1);
      const Vec2 w = s.wrap(m.uv[n]);
      const bool inRange = (s.isUPeriodic() || s.uTurnPeriod() != 0.0 || g->IsUPeriodic() ||
                            (w.x() >= u0 && w.x() <= u1)) &&
                           (s.isVPeriodic() || s.vTurnPeriod() != 0.0 || g->IsVPeriodic() ||
                            (w.y() >= v0 && w.y() <= v1));
      BRepClass_FaceClassifier cl(shape.face(f), gp_Pnt2d(m.uv[n].x(), m.uv[n].y()),
                                  s.uvTolerance());
      if (!inRange || cl.State() != TopAbs_IN) ++c.outside;
      const gp_Pnt P(p.x(), p.y(), p.z());
      bool inZone = false;
      for (int e : shape.faceEdges(f)) {
        for (int v : shape.edgeVertices(e))
          inZone = inZone || (shape.vertexPoint(v) - p).norm() <= shape.vertexTolerance(v);
        const TopoDS_Edge& edge = shape.edge(e);
        if (inZone || BRep_Tool::Degenerated(edge)) continue;
        const double tol = BRep_Tool::Tolerance(edge);
        Bnd_Box b = shape.edgeBox(e);
        b.Enlarge(tol);
        if (b.IsOut(P)) continue;
        BRepExtrema_DistShapeShape d(BRepBuilderAPI_MakeVertex(P).Vertex(), edge);
        inZone = d.IsDone() && d.Value() <= tol;
      }
      if (inZone) ++c.inToleranceZone;
    } else if (m.nodeKind[n] == NodeKind::Edge) {
      double a = 0, b = 0;
      const Handle(Geom_Curve) g = BRep_Tool::Curve(shape.edge(m.nodeEdge[n]), a, b);
      const gp_Pnt q = g->Value(m.nodeT[n]);
      c.worstCurve = std::max(c.worstCurve, (Vec3(q.X(), q.Y(), q.Z()) - p).norm());
    }
  }
  return c;
}

std::string statsText(const QualityStats& s) {
  std::ostringstream os;
  os << "min " << s.min << " mean " << s.mean << " tangled " << s.tangled;
  return os.str();
}

/// Elements tangled in `q` none of whose nodes may move.
std::set<std::size_t> unmovableTangled(const SurfaceMesh& m, const MeshQuality& q) {
  std::set<std::size_t> r;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    if (!q.tangled[e]) continue;
    bool movable = false;
    for (int k = 0; k < m.elementSize(e); ++k)
      movable =
          movable || m.nodeKind[static_cast<std::size_t>(m.elementNodes(e)[k])] != NodeKind::Fixed;
    if (!movable) r.insert(e);
  }
  return r;
}

const char* kParts[] = {"occt_propeller.brep", "occt_housing_bottom.brep", "occt_crankarm.brep",
                        "occt_bottle.brep",    "occt_screw.step",          "nist_pmi_1.step"};

class CadOptimizePart : public ::testing::TestWithParam<const char*> {};

TEST_P(CadOptimizePart, FixedBoundaryKeepsNodesOnTheirFacesAndImprovesQuality) {
  auto shape = load(GetParam());
  const double diag = shape->diagonal();
  const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * diag, 0.5);
  CadMesh cm(shape, om.input);
  SurfaceMesh& m = cm.mesh();
  const std::vector<Vec3> before = m.xyz;
  OptimizeOptions opt;
  opt.maxSweeps = 30;
  const OptimizeResult r = optimizeMesh(m, opt);
  std::cout << GetParam() << ": " << m.nodeCount() << " nodes, before " << statsText(r.before)
            << ", after " << statsText(r.after) << ", " << r.sweeps << " sweeps, " << r.seconds
            << " s\n";
  // Everything a node move can repair is repaired: the tangled elements left are exactly the
  // input's tangled elements without a movable node (on the propeller: two triangles with all
  // three nodes on CAD vertices and a fixed CAD edge), and the result reports them.
  const MeshQuality q0 = measureQuality(CadMesh(shape, om.input).mesh(), measureByName("shape"));
  const std::set<std::size_t> stuck = unmovableTangled(m, q0);
  const MeshQuality q1 = measureQuality(m, measureByName("shape"));
  EXPECT_EQ(q1.stats.tangled, r.after.tangled);
  std::set<std::size_t> tangledAfter;
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    if (q1.tangled[e]) tangledAfter.insert(e);
  EXPECT_EQ(tangledAfter, stuck);
  EXPECT_TRUE(r.tangledMovable.empty());
  EXPECT_EQ(std::set<std::size_t>(r.tangledUnmovable.begin(), r.tangledUnmovable.end()), stuck);
  EXPECT_EQ(r.warnings.empty(), stuck.empty());
  if (!stuck.empty()) {
    EXPECT_NE(r.warnings[0].find(std::to_string(stuck.size()) + " element"), std::string::npos);
    EXPECT_NE(r.warnings[0].find(std::to_string(*stuck.begin())), std::string::npos);
  }
  // Quality: the minimum over the elements that can change never drops, the mean rises.
  if (r.before.tangled == 0) {
    EXPECT_GE(r.after.min, r.before.min - 1e-12);
  }
  EXPECT_GE(r.after.mean, r.before.mean);
  const OnShapeCheck c = checkMovedNodes(*shape, m, before);
  std::cout << "  moved " << c.moved << " nodes: surface " << c.worstSurface / diag
            << " diag, GeomAPI projection " << c.worstProjection / diag << " diag, outside "
            << c.outside << "\n";
  EXPECT_GT(c.moved, 0u);
  EXPECT_LE(c.worstSurface, 1e-9 * diag);
  EXPECT_EQ(c.outside, 0u);
  EXPECT_EQ(c.inToleranceZone, 0u);
  // Nodes never moved keep their exact input position.
  for (std::size_t n = 0; n < m.nodeCount(); ++n)
    if (m.nodeKind[n] == NodeKind::Fixed) {
      ASSERT_EQ(m.xyz[n], before[n]) << "node " << n;
    }
}

INSTANTIATE_TEST_SUITE_P(Parts, CadOptimizePart, ::testing::ValuesIn(kParts),
                         [](const ::testing::TestParamInfo<const char*>& i) {
                           std::string s = i.param;
                           for (char& ch : s)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return s;
                         });

struct PerturbCase {
  const char* part;
  double amplitude;  // step bound, in units of the distance to the nearest neighbour
  unsigned seed;     // of the random steps
  int parity = 0;    // faces perturbed: those with index % 2 == parity
};

/// Moves the Face nodes of every second face (those with nodeFace % 2 == parity) in (u,v) by up
/// to `amp` times their distance to the nearest neighbour, staying inside the trimmed face.
void perturbFaceNodes(SurfaceMesh& m, double amp, unsigned seed, int parity) {
  std::vector<std::vector<std::int32_t>> nbr(m.nodeCount());
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (a != b)
          nbr[static_cast<std::size_t>(m.elementNodes(e)[a])].push_back(m.elementNodes(e)[b]);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (std::size_t n = 0; n < m.nodeCount(); ++n) {
    if (m.nodeKind[n] != NodeKind::Face || m.nodeFace[n] % 2 != parity) continue;
    const Surface& s = *m.surfaces[static_cast<std::size_t>(m.nodeFace[n])];
    double h = INFINITY;
    for (std::int32_t j : nbr[n]) {
      const Vec3 d = m.xyz[static_cast<std::size_t>(j)] - m.xyz[n];
      h = std::min(h, d.norm());
    }
    const SurfaceD1 d1 = s.d1(m.uv[n].x(), m.uv[n].y());
    const Vec2 step(amp * h * U(rng) / std::max(d1.du.norm(), 1e-300),
                    amp * h * U(rng) / std::max(d1.dv.norm(), 1e-300));
    const Vec2 uv = s.wrap(m.uv[n] + step);
    if (!s.contains(uv.x(), uv.y())) continue;
    m.uv[n] = uv;
  }
}

class CadPerturbed : public ::testing::TestWithParam<PerturbCase> {};

TEST_P(CadPerturbed, InteriorNodesPerturbedOnSeveralFacesAreUntangled) {
  const char* part = GetParam().part;
  const double amp = GetParam().amplitude;
  const unsigned seed = GetParam().seed;
  auto shape = load(part);
  const double diag = shape->diagonal();
  const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * diag, 0.5);
  CadMesh cm(shape, om.input);
  SurfaceMesh& m = cm.mesh();
  perturbFaceNodes(m, amp, seed, GetParam().parity);
  syncFaceNodes(m);
  const MeshQuality q0 = measureQuality(m, measureByName("shape"));
  std::set<int> tangledFaces;
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    if (q0.tangled[e]) tangledFaces.insert(m.elemFace[e]);
  std::cout << "perturbed " << part << " (amplitude " << amp << ", seed " << seed
            << "): " << statsText(q0.stats) << " on " << tangledFaces.size() << " faces\n";
  ASSERT_GE(tangledFaces.size(), 2u);
  const std::vector<Vec3> before = m.xyz;
  OptimizeOptions opt;
  opt.maxSweeps = 100;
  const OptimizeResult r = optimizeMesh(m, opt);
  std::cout << "  untangled: " << statsText(r.after) << ", " << r.sweeps << " sweeps, " << r.seconds
            << " s\n";
  // Nothing a node move can repair is left tangled (the propeller keeps the two input
  // triangles whose nodes are all on CAD vertices and edges).
  EXPECT_TRUE(r.tangledMovable.empty());
  EXPECT_EQ(r.after.tangled, r.tangledUnmovable.size());
  const OnShapeCheck c = checkMovedNodes(*shape, m, before);
  EXPECT_LE(c.worstSurface, 1e-9 * diag);
  EXPECT_EQ(c.outside, 0u);
  EXPECT_EQ(c.inToleranceZone, 0u);
}

// The crank arm: Gmsh itself leaves tangled elements on it (FREECAD_NOTES.md); steps of 0.9·h
// tangle about 70–90 elements on 5 faces, 0.5·h about 10. The node-by-node sweep used to end
// in a local minimum with one element tangled for several of these seeds (0.7 with seeds 2
// and 7, 0.9 with seed 2): the escapes for stuck elements (kernel centre, harmonic patch)
// free them. The bottle (cylinder/sphere/torus fillets), the screw and the housing (tori,
// spheres, B-spline blends; 160 elements).

INSTANTIATE_TEST_SUITE_P(
    Parts, CadPerturbed,
    ::testing::Values(
        PerturbCase{"occt_crankarm.brep", 0.5, 3}, PerturbCase{"occt_crankarm.brep", 0.7, 2},
        PerturbCase{"occt_crankarm.brep", 0.7, 7}, PerturbCase{"occt_crankarm.brep", 0.9, 2},
        PerturbCase{"occt_crankarm.brep", 0.9, 7}, PerturbCase{"occt_crankarm.brep", 0.9, 11},
        PerturbCase{"occt_bottle.brep", 0.7, 7}, PerturbCase{"occt_bottle.brep", 0.9, 3},
        PerturbCase{"occt_screw.step", 0.9, 1}, PerturbCase{"occt_screw.step", 0.9, 7},
        PerturbCase{"occt_housing_bottom.brep", 0.7, 7},
        // Stuck until the patch untangling (relaxPatch): on the housing, a stacked fan of thin
        // triangles between two CAD-edge nodes over 70° of a torus fillet with two of its
        // nodes out of order (both kernels empty; the harmonic layout in (u,v) tangles the
        // triangles standing across the surface); on the propeller, a triangle with one Face
        // node next to the blade corners where the surface normal turns by more than 100°.
        PerturbCase{"occt_housing_bottom.brep", 0.7, 3},
        PerturbCase{"occt_housing_bottom.brep", 0.7, 11},
        PerturbCase{"occt_housing_bottom.brep", 0.9, 4},
        PerturbCase{"occt_housing_bottom.brep", 0.7, 9, 1},
        PerturbCase{"occt_propeller.brep", 0.7, 1}, PerturbCase{"occt_propeller.brep", 0.5, 5, 1}),
    [](const ::testing::TestParamInfo<PerturbCase>& i) {
      std::string s = i.param.part;
      s = s.substr(5, s.find('.') - 5) + "_" +
          std::to_string(static_cast<int>(std::lround(10 * i.param.amplitude))) + "_seed" +
          std::to_string(i.param.seed) + (i.param.parity ? "_odd" : "");
      return s;
    });

// The escapes can be turned off (OptimizeOptions::escapes, for ablation studies): three of the
// cases above end with no element left tangled that a node may repair with them, and with
// elements stuck without them (measured with OCCT 7.6's meshes: 1 on the crank arm, 2 on the
// bottle, 5 on the housing; other OCCT versions mesh the parts differently, so the check
// without them is over the three together).
TEST(CadOptimize, EscapesTurnedOffLeaveStuckElementsTangled) {
  struct Ablation {
    const char* part;
    double amplitude;
    unsigned seed;
  };
  std::size_t stuckWithout = 0;
  for (const Ablation& a :
       {Ablation{"occt_crankarm.brep", 0.7, 2}, Ablation{"occt_bottle.brep", 0.9, 3},
        Ablation{"occt_housing_bottom.brep", 0.9, 4}}) {
    auto shape = load(a.part);
    const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * shape->diagonal(), 0.5);
    CadMesh cm(shape, om.input);
    perturbFaceNodes(cm.mesh(), a.amplitude, a.seed, 0);
    syncFaceNodes(cm.mesh());
    for (unsigned escapes : {static_cast<unsigned>(kAllEscapes), 0u}) {
      SurfaceMesh m = cm.mesh();
      OptimizeOptions opt;
      opt.maxSweeps = 100;
      opt.escapes = escapes;
      const OptimizeResult r = optimizeMesh(m, opt);
      std::cout << a.part << (escapes ? " with" : " without")
                << " the escapes: " << statsText(r.after) << ", " << r.tangledMovable.size()
                << " movable left\n";
      if (escapes == kAllEscapes) EXPECT_TRUE(r.tangledMovable.empty()) << a.part;
      if (escapes == 0u) stuckWithout += r.tangledMovable.size();
      // Never more tangled than the input, with or without them.
      EXPECT_LE(r.after.tangled, r.before.tangled) << a.part;
    }
  }
  EXPECT_GT(stuckWithout, 0u);
}

// Exploration over a grid of perturbations (not part of the suite): one line per run with the
// tangled elements left, and the ones with a movable node listed. Options (environment):
//   SURFMESH_GRID_PARTS=a.brep,b.step  SURFMESH_GRID_AMPS=0.5,0.7,0.9  SURFMESH_GRID_SEEDS=1-11
//   SURFMESH_GRID_PARITY=0,1  SURFMESH_GRID_CASES="0.7:2:0 0.9:4:1" (amp:seed:parity subset)
//   SURFMESH_GRID_THREADS=1  SURFMESH_GRID_SLIDE=1 (rerun failures with sliding edge nodes)
//   cad_optimize_test --gtest_also_run_disabled_tests --gtest_filter='*PerturbationGrid*'
std::vector<std::string> splitEnv(const char* name, const char* dflt) {
  const char* v = std::getenv(name);
  std::string s = v ? v : dflt;
  std::vector<std::string> r;
  std::size_t a = 0;
  while (a <= s.size()) {
    const std::size_t b = std::min(s.find(',', a), s.size());
    if (b > a) r.push_back(s.substr(a, b - a));
    a = b + 1;
  }
  return r;
}

TEST(CadOptimize, DISABLED_PerturbationGrid) {
  const auto parts = splitEnv("SURFMESH_GRID_PARTS", "occt_housing_bottom.brep");
  const auto amps = splitEnv("SURFMESH_GRID_AMPS", "0.5,0.7,0.9");
  const auto seedsS = splitEnv("SURFMESH_GRID_SEEDS", "1-11");
  const auto par = splitEnv("SURFMESH_GRID_PARITY", "0");
  const bool slide = std::getenv("SURFMESH_GRID_SLIDE") != nullptr;
  std::vector<unsigned> seeds;
  for (const auto& t : seedsS) {
    const std::size_t d = t.find('-');
    if (d == std::string::npos) {
      seeds.push_back(static_cast<unsigned>(std::stoul(t)));
    } else {
      for (unsigned k = static_cast<unsigned>(std::stoul(t.substr(0, d)));
           k <= static_cast<unsigned>(std::stoul(t.substr(d + 1))); ++k)
        seeds.push_back(k);
    }
  }
  for (const auto& part : parts) {
    auto shape = load(part);
    const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * shape->diagonal(), 0.5);
    for (const auto& pS : par)
      for (const auto& aS : amps)
        for (unsigned seed : seeds) {
          const double amp = std::stod(aS);
          const int parity = std::stoi(pS);
          if (const char* only = std::getenv("SURFMESH_GRID_CASES")) {
            // "amp:seed:parity" items separated by spaces
            char key[64];
            std::snprintf(key, sizeof key, " %s:%u:%d ", aS.c_str(), seed, parity);
            if ((" " + std::string(only) + " ").find(key) == std::string::npos) continue;
          }
          CadMesh cm(shape, om.input);
          SurfaceMesh& m = cm.mesh();
          perturbFaceNodes(m, amp, seed, parity);
          syncFaceNodes(m);
          const MeshQuality q0 = measureQuality(m, measureByName("shape"));
          OptimizeOptions opt;
          opt.maxSweeps = 100;
          if (const char* th = std::getenv("SURFMESH_GRID_THREADS")) opt.threads = std::atoi(th);
          const OptimizeResult r = optimizeMesh(m, opt);
          std::printf(
              "GRID %s amp %.1f seed %u parity %d: before %zu tangled (min %.4f) -> after %zu "
              "(movable %zu unmovable %zu) min %.4f mean %.4f, %d sweeps %.2f s",
              part.c_str(), amp, seed, parity, q0.stats.tangled, q0.stats.min, r.after.tangled,
              r.tangledMovable.size(), r.tangledUnmovable.size(), r.after.min, r.after.mean,
              r.sweeps, r.seconds);
          if (slide && !r.tangledMovable.empty()) {
            BridgeOptions bo;
            bo.boundary = "slide";
            CadMesh cs(shape, om.input, bo);
            perturbFaceNodes(cs.mesh(), amp, seed, parity);
            syncFaceNodes(cs.mesh());
            const OptimizeResult rs = optimizeMesh(cs.mesh(), opt);
            std::printf(" | slide: after %zu (movable %zu)", rs.after.tangled,
                        rs.tangledMovable.size());
          }
          std::printf("\n");
          for (std::int32_t e : r.tangledMovable) {
            const std::size_t ee = static_cast<std::size_t>(e);
            std::printf("  elem %d face %d (%s) nodes", e, m.elemFace[ee],
                        shape->faceType(m.elemFace[ee]).c_str());
            for (int k = 0; k < m.elementSize(ee); ++k) {
              const std::size_t j = static_cast<std::size_t>(m.elementNodes(ee)[k]);
              std::printf(" %zu:%s", j, m.nodeKind[j] == NodeKind::Face ? "F" : "X");
            }
            const Vec2* uv = m.elementUV(ee);
            const Vec2 a = uv[1] - uv[0], b = uv[2] - uv[0];
            std::printf(" uvCross %.3g\n", a.x() * b.y() - a.y() * b.x());
          }
          std::fflush(stdout);
        }
  }
}

// Boundary "slide" against "fixed" on every part: never more tangled elements, never a lower
// minimum quality, no tangled element with a movable node left. Prints the gains (one table
// row per part).
TEST(CadOptimize, SlidingEdgeNodesNeverEndWorseThanFixedOnes) {
  std::printf("%-26s | %-28s | %-28s | %-28s | %s\n", "part", "before: min mean tangled",
              "fixed: min mean tangled", "slide: min mean tangled", "slide - fixed: min mean");
  for (const char* part : kParts) {
    auto shape = load(part);
    const double diag = shape->diagonal();
    const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * diag, 0.5);
    OptimizeOptions opt;
    opt.maxSweeps = 30;
    CadMesh fixed(shape, om.input);
    const OptimizeResult rf = optimizeMesh(fixed.mesh(), opt);
    BridgeOptions bo;
    bo.boundary = "slide";
    CadMesh slide(shape, om.input, bo);
    ASSERT_GT(slide.report().slidingNodes, 0u) << part;
    const std::vector<Vec3> before = slide.mesh().xyz;
    const OptimizeResult rs = optimizeMesh(slide.mesh(), opt);
    std::printf(
        "%-26s | %.4f %.4f %-12zu | %.4f %.4f %-12zu | %.4f %.4f %-12zu | %+.4f %+.4f   (%zu "
        "sliding nodes, %.2f s / %.2f s)\n",
        part, rf.before.min, rf.before.mean, rf.before.tangled, rf.after.min, rf.after.mean,
        rf.after.tangled, rs.after.min, rs.after.mean, rs.after.tangled,
        rs.after.min - rf.after.min, rs.after.mean - rf.after.mean, slide.report().slidingNodes,
        rf.seconds, rs.seconds);
    EXPECT_LE(rs.after.tangled, rf.after.tangled) << part;
    EXPECT_GE(rs.after.min, rf.after.min - 1e-12) << part;
    EXPECT_GE(rs.after.mean, rf.before.mean) << part;
    const MeshQuality q = measureQuality(slide.mesh(), measureByName("shape"));
    EXPECT_EQ(q.stats.tangled, rs.after.tangled);
    // No element valid in the input (neither tangled nor standing across) is invalid in the
    // result, and no more are invalid than with the boundary fixed. On the propeller, the two
    // triangles on CAD vertices and a fixed edge are untangled by sliding their edge node
    // close to the CAD vertex, except one, whose untangling would stand valid triangles
    // across the blade (the run without the last check's across test: 0 tangled, 24 invalid;
    // with it: 1 tangled, 7 invalid, as many as with the boundary fixed).
    const CadMesh input(shape, om.input, bo);
    const MeshQuality q0 = measureQuality(input.mesh(), measureByName("shape"));
    std::size_t madeInvalid = 0;
    for (std::size_t e = 0; e < q.tangled.size(); ++e)
      madeInvalid += !(q0.tangled[e] || q0.across[e]) && (q.tangled[e] || q.across[e]) ? 1 : 0;
    EXPECT_EQ(madeInvalid, 0u) << part;
    // Nor does sliding stand a triangle edge-on to its face (its plane more than ~84° from
    // the face's normal at every corner, computed here from the faces' normals): on the
    // propeller, runs before this rule made some at the blades' edges, counted valid.
    auto edgeOn = [](const SurfaceMesh& m) {
      std::vector<unsigned char> r(m.elementCount(), 0);
      for (std::size_t e = 0; e < m.elementCount(); ++e) {
        if (m.elemType[e] != ElementType::Tri3) continue;
        const std::int32_t* nd = m.elementNodes(e);
        const Vec3 c =
            (m.xyz[static_cast<std::size_t>(nd[1])] - m.xyz[static_cast<std::size_t>(nd[0])])
                .cross(m.xyz[static_cast<std::size_t>(nd[2])] -
                       m.xyz[static_cast<std::size_t>(nd[0])]);
        const Surface& sf = *m.surfaces[static_cast<std::size_t>(m.elemFace[e])];
        bool all = c.norm() > 0.0;
        for (int k = 0; k < 3 && all; ++k) {
          const Vec2 w = m.elementUV(e)[k];
          const Vec3 n = sf.normal(w.x(), w.y());
          all = n.norm() > 0.0 && std::abs(c.dot(n)) < 0.1 * c.norm() * n.norm();
        }
        r[e] = all ? 1 : 0;
      }
      return r;
    };
    const std::vector<unsigned char> on0 = edgeOn(input.mesh()), on1 = edgeOn(slide.mesh());
    std::size_t madeEdgeOn = 0;
    for (std::size_t e = 0; e < on0.size(); ++e) madeEdgeOn += !on0[e] && on1[e] ? 1 : 0;
    EXPECT_EQ(madeEdgeOn, 0u) << part;
    EXPECT_LE(invalidCount(q), invalidCount(measureQuality(fixed.mesh(), measureByName("shape"))))
        << part;
    EXPECT_LE(rs.tangledMovable.size(), rf.after.tangled) << part;
    EXPECT_EQ(unmovableTangled(slide.mesh(), q).size(), rs.tangledUnmovable.size()) << part;
    EXPECT_EQ(rs.tangledMovable.size() + rs.tangledUnmovable.size(), rs.after.tangled);
    const OnShapeCheck c = checkMovedNodes(*shape, slide.mesh(), before);
    EXPECT_LE(c.worstCurve, 1e-9 * diag) << part;
    EXPECT_LE(c.worstSurface, 1e-9 * diag) << part;
    EXPECT_EQ(c.outside, 0u) << part;
    EXPECT_EQ(c.inToleranceZone, 0u) << part;
  }
}

// The triangles BRepMesh leaves tangled on the propeller's blade patches are really flipped:
// positively wound in (u,v), but their 3-D plane faces against the surface normal at their
// parametric centroid and at two of their three corners — the patch turns its normal by more
// than 100° across one triangle (a corner where φ_u and φ_v are 5–10° apart), so the linear
// triangle cannot follow it. Not an artefact of the reference normal.
TEST(CadOptimize, PropellerTangledTrianglesAreFlippedAgainstTheSurface) {
  auto shape = load("occt_propeller.brep");
  const OccMesh om = meshWithBRepMesh(*shape, 1e-3 * shape->diagonal(), 0.5);
  CadMesh cm(shape, om.input);
  const SurfaceMesh& m = cm.mesh();
  const MeshQuality q = measureQuality(m, measureByName("shape"));
  ASSERT_GT(q.stats.tangled, 0u);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    if (!q.tangled[e]) continue;
    const int f = m.elemFace[e];
    const Surface& s = *m.surfaces[static_cast<std::size_t>(f)];
    const Vec2* uv = m.elementUV(e);
    const std::int32_t* nd = m.elementNodes(e);
    const Vec3 x0 = m.xyz[static_cast<std::size_t>(nd[0])],
               x1 = m.xyz[static_cast<std::size_t>(nd[1])],
               x2 = m.xyz[static_cast<std::size_t>(nd[2])];
    const Vec3 c = (x1 - x0).cross(x2 - x0).normalized();
    const Vec2 a = uv[1] - uv[0], b = uv[2] - uv[0];
    const double uvCross = a.x() * b.y() - a.y() * b.x();
    EXPECT_GT(uvCross * s.normalSign() * m.faceOrientation[static_cast<std::size_t>(f)], 0.0)
        << "element " << e;
    const Vec2 centroid = (uv[0] + uv[1] + uv[2]) / 3.0;
    EXPECT_LT(c.dot(m.referenceNormal(f, centroid)), -0.3) << "element " << e;
    int against = 0;
    double minSin = 1.0;
    for (int k = 0; k < 3; ++k) {
      if (c.dot(m.referenceNormal(f, uv[k])) < 0.0) ++against;
      const SurfaceD1 d = s.d1(uv[k].x(), uv[k].y());
      minSin = std::min(minSin, d.du.cross(d.dv).norm() / (d.du.norm() * d.dv.norm()));
    }
    EXPECT_GE(against, 2) << "element " << e;
    double minDot = 1.0;  // the surface normal turns by more than 100° across the triangle
    for (int k = 0; k < 3; ++k)
      minDot =
          std::min(minDot, m.referenceNormal(f, uv[k]).dot(m.referenceNormal(f, uv[(k + 1) % 3])));
    EXPECT_LT(minDot, std::cos(100.0 * M_PI / 180.0)) << "element " << e;
    EXPECT_FALSE(isDegenerate(s.d1(centroid.x(), centroid.y()))) << "element " << e;
    EXPECT_LT(elementReferenceNormal(m, e).dot(c), 0.0) << "element " << e;
    std::printf(
        "propeller element %zu on face %d (%s): centroid normal · triangle normal %.3f, "
        "%d of 3 corners against, smallest sin(φu, φv) at a corner %.3f\n",
        e, f, shape->faceType(f).c_str(), c.dot(m.referenceNormal(f, centroid)), against, minSin);
  }
}

}  // namespace
