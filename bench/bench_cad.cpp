// SurfMesh benchmark helper for the comparison with Gmsh (bench/gmsh_compare.py): reads a
// shape and a triangle mesh dump, recovers the mesh on the shape (CadMesh) and either
// optimizes it or only measures it. The same measuring code is applied to every tool's output.
//
//   bench_cad measure  SHAPE MESH.bin
//   bench_cad optimize SHAPE MESH.bin OUT.bin THREADS
//
// MESH.bin: int64 N, int64 E, N×3 float64 node positions, E×3 int32 0-based triangles.
// OUT.bin: the same layout with the optimized positions. Prints one JSON object.
#include "bench_common.h"

#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

using namespace surfmesh;
using namespace surfmesh::bench;

namespace {

struct Dump {
  std::vector<double> xyz;
  std::vector<std::int32_t> tris;
};

Dump readDump(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::int64_t n = 0, e = 0;
  in.read(reinterpret_cast<char*>(&n), 8);
  in.read(reinterpret_cast<char*>(&e), 8);
  Dump d;
  d.xyz.resize(static_cast<std::size_t>(3 * n));
  d.tris.resize(static_cast<std::size_t>(3 * e));
  in.read(reinterpret_cast<char*>(d.xyz.data()), static_cast<std::streamsize>(8 * d.xyz.size()));
  in.read(reinterpret_cast<char*>(d.tris.data()), static_cast<std::streamsize>(4 * d.tris.size()));
  if (!in) throw std::runtime_error("truncated " + path);
  return d;
}

void writeDump(const std::string& path, const SurfaceMesh& m, const Dump& d) {
  std::ofstream out(path, std::ios::binary);
  const std::int64_t n = static_cast<std::int64_t>(m.nodeCount());
  const std::int64_t e = static_cast<std::int64_t>(d.tris.size() / 3);
  out.write(reinterpret_cast<const char*>(&n), 8);
  out.write(reinterpret_cast<const char*>(&e), 8);
  for (const Vec3& p : m.xyz) out.write(reinterpret_cast<const char*>(p.data()), 24);
  out.write(reinterpret_cast<const char*>(d.tris.data()),
            static_cast<std::streamsize>(4 * d.tris.size()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_cad measure|optimize SHAPE MESH.bin [OUT.bin THREADS]\n");
    return 2;
  }
  const std::string mode = argv[1];
  try {
    const double t0 = now();
    auto shape = CadShape::fromFile(argv[2]);
    const double tShape = now() - t0;
    Dump d = readDump(argv[3]);
    const double t1 = now();
    CadMesh cm(shape, triangleMeshInput(d.xyz, d.tris));
    const double tBridge = now() - t1;
    SurfaceMesh& m = cm.mesh();
    const PlanarMeasure& shapeMeasure = measureByName("shape");
    const BridgeReport& rep = cm.report();
    if (mode == "measure") {
      const QualityStats q = measureQuality(m, shapeMeasure).stats;
      std::printf("{\"elements\": %zu, \"nodes\": %zu, \"min\": %.6f, \"mean\": %.6f, "
                  "\"tangled\": %zu, \"max_distance\": %.3e, \"bridge_s\": %.3f, "
                  "\"face_nodes\": %zu}\n",
                  q.elements, m.nodeCount(), q.min, q.mean, q.tangled, rep.maxDistance, tBridge,
                  rep.faceNodes);
      return 0;
    }
    if (mode != "optimize" || argc < 6) throw std::runtime_error("bad arguments");
    OptimizeOptions opt;
    opt.threads = std::atoi(argv[5]);
    const OptimizeResult r = optimizeMesh(m, opt);
    writeDump(argv[4], m, d);
    std::printf("{\"seconds\": %.4f, \"sweeps\": %d, \"reason\": \"%s\", \"threads\": %d, "
                "\"bridge_s\": %.3f, \"shape_s\": %.3f, \"min\": %.6f, \"mean\": %.6f, "
                "\"tangled\": %zu, \"before_tangled\": %zu, \"peak_mb\": %.1f}\n",
                r.seconds, r.sweeps, stopReasonName(r.reason), r.threadsUsed, tBridge, tShape,
                r.after.min, r.after.mean, r.after.tangled, r.before.tangled,
                peakRssBytes() / 1e6);
  } catch (const std::exception& ex) {
    std::printf("{\"error\": \"%s\"}\n", ex.what());
    return 1;
  }
  return 0;
}
