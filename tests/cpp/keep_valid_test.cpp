// Never worse, element by element (keep_valid.h): an element valid in a run's input ends
// valid, and one untangled in it ends untangled, by putting back the nodes of the elements a
// run made worse, and nothing else.
#include "../../src/core/src/optimize/keep_valid.h"

#include "../../src/core/src/optimize/sweep.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// The nodes of the elements around node i.
std::set<std::size_t> neighbours(const SurfaceMesh& m, std::size_t i) {
  std::set<std::size_t> out;
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    bool has = false;
    for (int k = 0; k < m.elementSize(e); ++k) has = has || static_cast<std::size_t>(nd[k]) == i;
    if (has)
      for (int k = 0; k < m.elementSize(e); ++k) out.insert(static_cast<std::size_t>(nd[k]));
  }
  return out;
}

/// MeshQuality::grade of every element of q (keepValidElements' grade0).
std::vector<unsigned char> grades(const MeshQuality& q) {
  std::vector<unsigned char> g(q.tangled.size());
  for (std::size_t e = 0; e < g.size(); ++e) g[e] = q.grade(e);
  return g;
}

/// A face node of m and the run that pushes it three cells across its neighbours in (u,v):
/// its elements fold.
std::size_t foldAFaceNode(SurfaceMesh& m, int nu, int nv) {
  std::size_t a = 0;
  while (m.nodeKind[a] != NodeKind::Face) ++a;
  m.uv[a] += Vec2(3 * 2 * kPi / nu, 0.4 * 2 * kPi / nv);
  syncFaceNodes(m);
  return a;
}

}  // namespace

TEST(KeepValid, PutsBackTheNodesOfElementsMadeInvalidAndNothingElse) {
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(16, 10, 0, 2 * kPi, 0, 2 * kPi, true);
  SurfaceMesh m = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
  const PlanarMeasure& shape = measureByName("shape");
  const detail::MeshPositions input = detail::MeshPositions::of(m);
  const MeshQuality q0 = measureQuality(m, shape);
  ASSERT_EQ(q0.stats.tangled, 0u);
  // A "run" that pushes node a three cells across its neighbours (its elements fold) and
  // moves node b, away from a, by a tenth of a cell (its elements stay valid).
  std::size_t a = 0;
  while (m.nodeKind[a] != NodeKind::Face) ++a;
  const std::set<std::size_t> nearA = neighbours(m, a);
  std::size_t b = a + 1;
  while (m.nodeKind[b] != NodeKind::Face || nearA.count(b) || [&] {
    for (std::size_t j : neighbours(m, b))
      if (nearA.count(j)) return true;
    return false;
  }())
    ++b;
  const double du = 2 * kPi / 16, dv = 2 * kPi / 10;
  m.uv[a] += Vec2(3 * du, 0.4 * dv);
  m.uv[b] += Vec2(0.1 * du, 0.05 * dv);
  syncFaceNodes(m);
  ASSERT_GT(measureQuality(m, shape).stats.tangled, 0u);
  const Vec3 bMoved = m.xyz[b];
  const detail::MeshPositions run = detail::MeshPositions::of(m);

  MeshQuality q = measureQuality(m, shape);
  detail::PutBack undo;
  const std::size_t restored = detail::keepValidElements(
      m, {input.xyz, input.uv, input.nodeT, input.cornerUV}, grades(q0), shape, &q, &undo);
  EXPECT_EQ(restored, 1u);  // node a only: the other nodes of its elements never moved
  EXPECT_EQ(q.stats.tangled, 0u);
  EXPECT_EQ(measureQuality(m, shape).stats.tangled, 0u);  // *q is the mesh's
  EXPECT_EQ(m.xyz[a], input.xyz[a]);
  EXPECT_EQ(m.uv[a], input.uv[a]);
  EXPECT_EQ(m.xyz[b], bMoved);  // kept: its elements are valid
  for (std::size_t c = 0; c < m.cornerUV.size(); ++c)
    if (m.elemNodes[c] == static_cast<std::int32_t>(a)) EXPECT_EQ(m.cornerUV[c], input.cornerUV[c]);
  // Undone: the run's positions again, to the bit.
  undo.undo(m);
  EXPECT_EQ(m.xyz, run.xyz);
  EXPECT_EQ(m.uv, run.uv);
  EXPECT_EQ(m.cornerUV, run.cornerUV);
}

TEST(KeepValid, ElementsTangledInTheInputMayStayTangled) {
  // Nothing to put back when the only invalid elements were invalid in the input.
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(16, 10, 0, 2 * kPi, 0, 2 * kPi, true);
  SurfaceMesh m = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
  const PlanarMeasure& shape = measureByName("shape");
  perturbUntilTangled(m, torus, 6, 0.25, 0.4, 7);
  const detail::MeshPositions input = detail::MeshPositions::of(m);
  const MeshQuality q0 = measureQuality(m, shape);
  ASSERT_GE(q0.stats.tangled, 6u);
  MeshQuality q = q0;
  EXPECT_EQ(detail::keepValidElements(m, {input.xyz, input.uv, input.nodeT, input.cornerUV},
                                      grades(q0), shape, &q),
            0u);
  EXPECT_EQ(q.stats.tangled, q0.stats.tangled);
}

TEST(KeepValid, AnElementStandingAcrossThatARunTanglesGoesBack) {
  // By the grade (valid, standing across, tangled): an element standing across in the input
  // (its quality positive) that the run tangles is worse, and its nodes go back; one tangled
  // in the input may stay tangled. (The input's grades are given: no element of a torus grid
  // stands across.)
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(16, 10, 0, 2 * kPi, 0, 2 * kPi, true);
  const PlanarMeasure& shape = measureByName("shape");
  for (const unsigned char given : {1, 2}) {
    SurfaceMesh m = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
    const detail::MeshPositions input = detail::MeshPositions::of(m);
    const std::size_t a = foldAFaceNode(m, 16, 10);
    MeshQuality q = measureQuality(m, shape);
    ASSERT_GT(q.stats.tangled, 0u);
    std::vector<unsigned char> grade0(m.elementCount(), 0);
    for (std::size_t e = 0; e < m.elementCount(); ++e)
      if (q.tangled[e]) grade0[e] = given;  // the folded ones: across (1) or tangled (2) before
    const std::size_t tangledRun = q.stats.tangled;
    const std::size_t restored = detail::keepValidElements(
        m, {input.xyz, input.uv, input.nodeT, input.cornerUV}, grade0, shape, &q);
    if (given == 1) {
      EXPECT_EQ(restored, 1u);
      EXPECT_EQ(q.stats.tangled, 0u);
      EXPECT_EQ(m.xyz[a], input.xyz[a]);
    } else {
      EXPECT_EQ(restored, 0u);
      EXPECT_EQ(q.stats.tangled, tangledRun);
      EXPECT_NE(m.xyz[a], input.xyz[a]);
    }
  }
}

TEST(KeepValid, NoRunMakesAnElementOfAValidInputInvalid) {
  // Valid but poor meshes of a torus (nodes moved at random in (u,v), none tangled), runs of
  // 1 to 8 sweeps with either measure: no element ends invalid, the result's counts are the
  // mesh's.
  const TorusSurface torus(10, 4);
  const GridMesh g = periodicGridMesh(24, 14, 0, 2 * kPi, 0, 2 * kPi, true);
  int runs = 0;
  for (const char* name : {"shape", "oddy"})
    for (unsigned seed = 1; seed <= 4; ++seed)
      for (int sweeps : {1, 2, 4, 8}) {
        SurfaceMesh m = makeSingleSurfaceMesh(torus, g.uv, ElementType::Tri3, g.conn, g.fixed);
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> unif(-1.0, 1.0);
        for (std::size_t i = 0; i < m.nodeCount(); ++i)
          if (m.nodeKind[i] == NodeKind::Face)
            m.uv[i] += Vec2(0.3 * unif(rng) * 2 * kPi / 24, 0.3 * unif(rng) * 2 * kPi / 14);
        syncFaceNodes(m);
        const PlanarMeasure& measure = measureByName(name);
        if (measureQuality(m, measure).stats.tangled != 0) continue;
        ++runs;
        OptimizeOptions opt;
        opt.measure = name;
        opt.maxSweeps = sweeps;
        const OptimizeResult r = optimizeMesh(m, opt);
        const MeshQuality q = measureQuality(m, measure);
        EXPECT_EQ(q.stats.tangled, 0u) << name << ", seed " << seed << ", " << sweeps;
        EXPECT_EQ(r.after.tangled, q.stats.tangled);
        EXPECT_NEAR(r.after.min, q.stats.min, 1e-12);
      }
  EXPECT_GE(runs, 24);
}
