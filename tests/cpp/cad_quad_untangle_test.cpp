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
