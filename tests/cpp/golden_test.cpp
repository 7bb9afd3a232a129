// Golden runs of the optimizer and the CAD bridge: a guard for changes meant to keep behaviour
// bit-identical (splitting the optimizer and the bridge into files of one responsibility).
//
// Each case hashes (FNV-1a, 64 bits) every bit of what a run gives: the node positions and
// parameters, every progress record and the result's counters, lists and warnings (not the
// time); a bridge case hashes the mesh the CAD bridge recovers (node classes, faces, edges,
// parameters) and its report's counts. The hashes are compared with those recorded in
// tests/data/golden/<platform>.txt, where <platform> names the compiler and the OCCT and Eigen
// versions (another toolchain rounds differently). A change that is meant to alter results
// records them again:
//
//     SURFMESH_GOLDEN_WRITE=1 build/tests/cpp/golden_test
//
// and says so in its commit. Without a record for this platform the test is skipped, saying
// which file is missing.
#include "fixture_meshes.h"
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/occ_mesher.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"
#include "test_meshes.h"

#include <Eigen/Core>
#include <Standard_Version.hxx>
#include <gtest/gtest.h>

#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace surfmesh;
using namespace surfmesh::testmesh;

namespace {

/// FNV-1a over raw bytes.
struct Hash {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= c[i];
      h *= 1099511628211ull;
    }
  }
  template <typename T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable<T>::value, "plain data only");
    bytes(&v, sizeof v);
  }
  void d(double v) { pod(v); }
  void u(std::uint64_t v) { pod(v); }
  void s(const std::string& v) {
    u(v.size());
    bytes(v.data(), v.size());
  }
  void vec2(const std::vector<Vec2>& v) {
    u(v.size());
    for (const Vec2& x : v) {
      d(x.x());
      d(x.y());
    }
  }
  void vec3(const std::vector<Vec3>& v) {
    u(v.size());
    for (const Vec3& x : v) {
      d(x.x());
      d(x.y());
      d(x.z());
    }
  }
  template <typename T>
  void ints(const std::vector<T>& v) {
    u(v.size());
    for (const T& x : v) u(static_cast<std::uint64_t>(static_cast<std::int64_t>(x)));
  }
  void stats(const QualityStats& q) {
    d(q.min);
    d(q.max);
    d(q.mean);
    d(q.stddev);
    u(q.tangled);
    u(q.elements);
  }
  std::string hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
  }
};

/// The mesh's geometry and classification, as the optimizer reads and writes it.
void hashMesh(Hash& h, const SurfaceMesh& m) {
  h.vec2(m.uv);
  h.vec3(m.xyz);
  h.vec2(m.cornerUV);
  h.ints(m.nodeKind);
  h.ints(m.nodeFace);
  h.ints(m.nodeEdge);
  h.ints(m.elemNodes);
  h.ints(m.elemFace);
  h.u(m.nodeT.size());
  for (double t : m.nodeT) h.d(t);
}

/// One optimizer run: the mesh after it, every progress record and the result.
std::string runAndHash(SurfaceMesh& m, const OptimizeOptions& opt, std::string* summary) {
  Hash h;
  const OptimizeResult r = optimizeMesh(m, opt, [&h](const OptimizeProgress& p) {
    h.u(static_cast<std::uint64_t>(p.sweep));
    h.u(static_cast<std::uint64_t>(p.maxSweeps));
    h.d(p.objective);
    h.u(p.tangled);
    h.d(p.minQuality);
    h.d(p.delta);
    return true;
  });
  hashMesh(h, m);
  h.stats(r.before);
  h.stats(r.after);
  h.u(static_cast<std::uint64_t>(r.sweeps));
  h.u(static_cast<std::uint64_t>(r.reason));
  h.d(r.initialObjective);
  h.d(r.finalObjective);
  h.u(r.movedNodes);
  h.u(static_cast<std::uint64_t>(r.threadsUsed));
  h.u(r.patchUntanglings);
  h.u(r.straightenedElements);
  h.u(r.heldAcross ? 1 : 0);
  h.ints(r.tangledUnmovable);
  h.ints(r.tangledMovable);
  h.u(r.warnings.size());
  for (const std::string& w : r.warnings) h.s(w);
  char buf[160];
  std::snprintf(buf, sizeof buf, "sweeps %d, tangled %zu -> %zu, min %.4f -> %.4f", r.sweeps,
                r.before.tangled, r.after.tangled, r.before.min, r.after.min);
  *summary = buf;
  return h.hex();
}

std::string platform() {
  std::string compiler;
#if defined(__clang__)
  compiler = "clang-" + std::to_string(__clang_major__) + "." + std::to_string(__clang_minor__) +
             "." + std::to_string(__clang_patchlevel__);
#elif defined(__GNUC__)
  compiler = "gcc-" + std::to_string(__GNUC__) + "." + std::to_string(__GNUC_MINOR__) + "." +
             std::to_string(__GNUC_PATCHLEVEL__);
#else
  compiler = "cc";
#endif
  const std::string eigen = std::to_string(EIGEN_WORLD_VERSION) + "." +
                            std::to_string(EIGEN_MAJOR_VERSION) + "." +
                            std::to_string(EIGEN_MINOR_VERSION);
  return compiler + "_occt-" + OCC_VERSION_COMPLETE + "_eigen-" + eigen;
}

std::string goldenPath() {
  return std::string(SURFMESH_TEST_DATA_DIR) + "/golden/" + platform() + ".txt";
}

// ---- the cases ------------------------------------------------------------------------------

const double kPi = 3.14159265358979323846;

/// A periodic quad4 mesh of the torus: nu × nv cells.
SurfaceMesh torusQuad4(const Surface& torus, int nu, int nv) {
  std::vector<Vec2> uv;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) uv.emplace_back(2 * kPi * i / nu, 2 * kPi * j / nv);
  auto id = [&](int i, int j) { return static_cast<std::int32_t>((i % nu) * nv + (j % nv)); };
  std::vector<std::int32_t> conn;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j)
      conn.insert(conn.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  return makeSingleSurfaceMesh(torus, uv, ElementType::Quad4, conn, {});
}

/// Face nodes moved at random in (u,v) by up to (du, dv) until `tangled` elements are tangled
/// (0: one such move of every Face node, a small perturbation of a valid mesh).
void perturb(SurfaceMesh& m, const Surface& s, std::size_t tangled, double du, double dv,
             unsigned seed) {
  if (tangled > 0) {
    perturbUntilTangled(m, s, tangled, du, dv, seed);
    return;
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t k = 0; k < m.nodeCount(); ++k)
    if (m.nodeKind[k] == NodeKind::Face)
      m.uv[k] = s.clampToBounds(m.uv[k] + Vec2(du * u(rng), dv * u(rng)));
  syncFaceNodes(m);
}

struct Case {
  std::string name;
  std::function<std::string(std::string*)> run;  // returns the hash, fills a summary
};

std::shared_ptr<CadShape> part(const std::string& name) {
  static std::map<std::string, std::shared_ptr<CadShape>> cache;
  auto& s = cache[name];
  if (!s) s = CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/" + name);
  return s;
}

std::vector<Case> cases() {
  std::vector<Case> out;
  static const TorusSurface torus(10, 4);
  static const SphereSurface sphere(5);
  static const PlaneSurface plane;
  auto analytic = [&](const std::string& name, std::function<SurfaceMesh()> make, const Surface& s,
                      std::size_t tangled, double du, double dv, const std::string& measure,
                      int sweeps) {
    for (int threads : {1, 2}) {
      out.push_back({name + " / " + std::to_string(threads) + " thread" + (threads > 1 ? "s" : ""),
                     [=, &s](std::string* summary) {
                       SurfaceMesh m = make();
                       perturb(m, s, tangled, du, dv, 5);
                       OptimizeOptions opt;
                       // The record is of the paper's integral mode for curved elements (the
                       // mode every node of these fixtures went through when it was made).
                       opt.highOrder = "integral";
                       opt.measure = measure;
                       opt.maxSweeps = sweeps;
                       opt.threads = threads;
                       return runAndHash(m, opt, summary);
                     }});
    }
  };
  auto grid = [](const Surface& s, const GridMesh& g, ElementType t) {
    return makeSingleSurfaceMesh(s, g.uv, t, g.conn, g.fixed);
  };
  const GridMesh torusGrid = periodicGridMesh(40, 16, 0, 2 * kPi, 0, 2 * kPi, true);
  analytic(
      "torus tri3 tangled, shape", [=] { return grid(torus, torusGrid, ElementType::Tri3); }, torus,
      40, 0.2, 0.5, "shape", 60);
  analytic(
      "torus tri3 tangled, oddy", [=] { return grid(torus, torusGrid, ElementType::Tri3); }, torus,
      40, 0.2, 0.5, "oddy", 60);
  analytic(
      "sphere tri3 tangled", [=] { return grid(sphere, sphereMesh(32, 16), ElementType::Tri3); },
      sphere, 30, 0.15, 0.15, "shape", 60);
  analytic(
      "square tri3 smoothed", [=] { return grid(plane, squareMesh(16), ElementType::Tri3); }, plane,
      0, 0.02, 0.02, "shape", 40);
  analytic(
      "torus tri6 tangled", [=] { return torusMeshOfOrder(torus, 2); }, torus, 30, 0.1, 0.25,
      "shape", 60);
  analytic(
      "torus tri10 tangled", [=] { return torusMeshOfOrder(torus, 3); }, torus, 30, 0.1, 0.25,
      "shape", 40);
  analytic(
      "torus quad4 tangled", [=] { return torusQuad4(torus, 30, 12); }, torus, 20, 0.1, 0.25,
      "shape", 60);
  analytic(
      "torus quad8 tangled", [=] { return torusQuad8(torus, 24, 10, false); }, torus, 20, 0.1, 0.25,
      "shape", 60);
  analytic(
      "torus tri6 + quad8 tangled", [=] { return torusQuad8(torus, 24, 10, true); }, torus, 20, 0.1,
      0.25, "shape", 60);

  // CAD parts: BRepMesh's mesh, the bridge's recovery, and a run on it.
  const char* parts[] = {"occt_propeller.brep", "occt_housing_bottom.brep", "occt_crankarm.brep",
                         "occt_bottle.brep",    "occt_screw.step",          "nist_pmi_1.step"};
  for (const char* p : parts) {
    const std::string name(p);
    out.push_back({"bridge " + name, [name](std::string* summary) {
                     auto shape = part(name);
                     const OccMesh om = meshWithBRepMesh(*shape, 2e-3 * shape->diagonal(), 0.5);
                     CadMesh cm(shape, om.input);
                     Hash h;
                     hashMesh(h, cm.mesh());
                     const BridgeReport& r = cm.report();
                     h.u(r.slidingNodes);
                     *summary = std::to_string(cm.mesh().nodeCount()) + " nodes, " +
                                std::to_string(cm.mesh().elementCount()) + " elements";
                     return h.hex();
                   }});
    for (const char* boundary : {"fixed", "slide"}) {
      const std::string b(boundary);
      for (int threads : {1, 2}) {
        if (threads == 2 && name != "occt_propeller.brep" && name != "occt_bottle.brep") continue;
        if (b == "slide" && name != "occt_propeller.brep" && name != "occt_crankarm.brep") continue;
        out.push_back({"optimize " + name + " " + b + " / " + std::to_string(threads) + " thread" +
                           (threads > 1 ? "s" : ""),
                       [name, b, threads](std::string* summary) {
                         auto shape = part(name);
                         const OccMesh om = meshWithBRepMesh(*shape, 2e-3 * shape->diagonal(), 0.5);
                         BridgeOptions bo;
                         bo.boundary = b;
                         CadMesh cm(shape, om.input, bo);
                         OptimizeOptions opt;
                         opt.maxSweeps = 20;
                         opt.threads = threads;
                         return runAndHash(cm.mesh(), opt, summary);
                       }});
      }
    }
  }
  return out;
}

std::map<std::string, std::string> readGolden(const std::string& path) {
  std::map<std::string, std::string> g;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t bar = line.find(" | ");
    if (bar == std::string::npos || bar < 17) continue;
    g[line.substr(17, bar - 17)] = line.substr(0, 16);
  }
  return g;
}

}  // namespace

TEST(Golden, OptimizerAndBridgeRunsAreBitIdenticalToTheRecord) {
  const std::string path = goldenPath();
  const char* write = std::getenv("SURFMESH_GOLDEN_WRITE");
  const bool recording = write && std::strcmp(write, "1") == 0;
  std::map<std::string, std::string> golden;
  if (!recording) {
    golden = readGolden(path);
    if (golden.empty())
      GTEST_SKIP() << "no golden record for this platform (" << path
                   << "); record one with SURFMESH_GOLDEN_WRITE=1";
  }
  std::ostringstream record;
  record << "# SurfMesh golden runs, " << platform() << ": hash | case | summary\n";
  std::size_t compared = 0;
  for (const Case& c : cases()) {
    std::string summary;
    const std::string hash = c.run(&summary);
    record << hash << " " << c.name << " | " << summary << "\n";
    std::printf("%s  %-52s %s\n", hash.c_str(), c.name.c_str(), summary.c_str());
    if (recording) continue;
    const auto it = golden.find(c.name);
    ASSERT_NE(it, golden.end()) << "case " << c.name << " has no record in " << path;
    EXPECT_EQ(hash, it->second) << c.name << " (" << summary << ") differs from the record";
    ++compared;
  }
  if (recording) {
    std::ofstream out(path);
    ASSERT_TRUE(out.good()) << "cannot write " << path;
    out << record.str();
    std::printf("recorded %s\n", path.c_str());
  } else {
    EXPECT_EQ(compared, golden.size()) << "the record has cases this test no longer runs";
  }
}
