// Tangled elements of Gmsh's recombined (quadrilateral) meshes on CAD parts that the
// optimizer left with a movable node (bench/quads_compare.py): one that only a move of its free
// node far across a thin, strongly curved face untangles, and quads folded at a corner on one
// CAD edge, which no sliding of its nodes repairs.
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/optimize/optimizer.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

using namespace surfmesh;

namespace {

/// A mesh in tests/data: "N E", N lines of x y z, E lines of 3 (triangle) or 4 (quad) 0-based
/// node ids.
MeshInput readMixedMesh(const std::string& name) {
  std::ifstream in(std::string(SURFMESH_TEST_DATA_DIR) + "/" + name);
  MeshInput m;
  std::size_t n = 0, e = 0;
  in >> n >> e;
  m.nodes.resize(n);
  for (Vec3& p : m.nodes) in >> p.x() >> p.y() >> p.z();
  std::string line;
  std::getline(in, line);
  for (std::size_t k = 0; k < e && std::getline(in, line); ++k) {
    std::istringstream row(line);
    std::int32_t id;
    int count = 0;
    while (row >> id) {
      m.conn.push_back(id);
      ++count;
    }
    m.types.push_back(count == 4 ? ElementType::Quad4 : ElementType::Tri3);
  }
  EXPECT_EQ(m.types.size(), e) << name;
  return m;
}

std::shared_ptr<CadShape> load(const std::string& name) {
  return CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/" + name);
}

}  // namespace

// The bottle's thread face (a thin B-spline band whose normal turns by more than 90° across
// it) in Gmsh's Blossom mesh (Frontal-Delaunay, diagonal / 21), perturbed: a triangle between a
// CAD vertex, a fixed edge node and a Face node a third of the face away stands across the
// surface. Its valid positions lie nearer to the other two nodes, beyond a barrier no Newton
// step crosses, and off its kernel in (u,v); the run gave up on it after 103 sweeps.
TEST(CadQuadUntangle, TriangleAcrossAThinCurvedFaceIsUntangledBySampling) {
  const MeshInput in = readMixedMesh("occt_bottle_thread_blossom.txt");
  CadMesh cm(load("occt_bottle.brep"), in);
  SurfaceMesh& m = cm.mesh();
  const OptimizeResult r = optimizeMesh(m, OptimizeOptions{});
  EXPECT_EQ(r.before.tangled, 11u);
  EXPECT_TRUE(r.tangledMovable.empty()) << r.tangledMovable.size() << " left, first "
                                        << (r.tangledMovable.empty() ? -1 : r.tangledMovable[0]);
  // What is left folds between fixed nodes (Gmsh's own mesh has those).
  EXPECT_EQ(r.after.tangled, r.tangledUnmovable.size());
  EXPECT_LE(r.after.tangled, 8u);
  EXPECT_LT(r.sweeps, 50);
}

// A face of the housing in Gmsh's quads by simple recombination (Frontal-Delaunay, diagonal /
// 21): two quads each have a corner on the one node of a CAD edge between its two vertices, a
// 180° corner (det S = 0 up to rounding). Sliding that node along its edge keeps the corner a
// triangle of three points of the edge's curve: no motion repairs it. It is held like a corner
// between fixed nodes, instead of keeping the run in untangling sweeps until it gives up and
// being reported as movable.
TEST(CadQuadUntangle, QuadCornerOnOneCadEdgeIsHeldWhenSliding) {
  const MeshInput in = readMixedMesh("occt_housing_bottom_simple_quads.txt");
  auto shape = load("occt_housing_bottom.brep");
  BridgeOptions bo;
  bo.boundary = "slide";
  CadMesh slide(shape, in, bo);
  ASSERT_GT(slide.report().slidingNodes, 0u);
  const OptimizeResult rs = optimizeMesh(slide.mesh(), OptimizeOptions{});
  EXPECT_EQ(rs.before.tangled, 2u);
  EXPECT_EQ(rs.after.tangled, 2u);
  EXPECT_TRUE(rs.tangledMovable.empty()) << rs.tangledMovable.size();
  EXPECT_EQ(rs.tangledUnmovable.size(), 2u);
  EXPECT_LT(rs.sweeps, 10);
  // As good as with the boundary fixed (the same two quads held there).
  CadMesh fixed(shape, in);
  const OptimizeResult rf = optimizeMesh(fixed.mesh(), OptimizeOptions{});
  EXPECT_EQ(rf.tangledUnmovable.size(), 2u);
  EXPECT_GE(rs.after.mean, rf.after.mean - 1e-6);
}
