// SurfMesh benchmark helper for the comparison with Gmsh (bench/gmsh_compare.py): reads a
// shape and a mesh dump (triangles, or triangles and quadrilaterals), recovers the mesh on the
// shape (CadMesh) and either optimizes it or only measures it. The same measuring code is applied
// to every tool's output.
//
//   bench_cad measure  SHAPE MESH.bin
//   bench_cad optimize SHAPE MESH.bin OUT.bin THREADS
//   bench_cad escapes          (the escapes' names, kEscapeNames, as a JSON list)
//
// MESH.bin: int64 N, int64 E, N×3 float64 node positions, E×3 int32 0-based triangles; or,
// when E is written negative, |E|×4 int32 0-based elements: quadrilaterals, and triangles with
// a fourth id of −1 (a recombined mesh; its elements are taken as they are).
// Pairs of duplicate triangles (the same three corners) are left out of the recovery, the
// measure and the optimization, as SurfMesh.optimize leaves them out ("duplicates_left_out").
// OUT.bin: the same layout with the optimized positions. Prints one JSON object (optimize: also
// the floor of the speed issue — one first-derivative evaluation per Face node —, the value
// floor — that plus one shape value of each triangle around each Face node — and the time of
// sweep 1 and of the mean later sweep). Environment for experiments: BENCH_RELTOL,
// BENCH_SWEEPS, BENCH_MEASURE, BENCH_MONOTONE (0/1), BENCH_MOVETOL, BENCH_OMEGA override relTol,
// maxSweeps, the measure, the monotone option, moveTol and overRelaxation; BENCH_REPEAT=n optimizes
// n − 1 copies of the mesh first (profiling); BENCH_BOUNDARY ("fixed" or "slide") the boundary mode
// of the CAD recovery; BENCH_TRACE=1 prints each sweep's progress on stderr; BENCH_TOPOLOGY=flip
// adds edge flips (OUT.bin then has the rewired elements' node lists); BENCH_WITHOUT=widen,relax
// turns those escapes off (kEscapeNames; "all": every one), for ablations; BENCH_WORST=k (measure)
// prints the k worst elements on stderr with where their nodes lie.
#include "bench_common.h"
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

using namespace surfmesh;
using namespace surfmesh::bench;

namespace {

struct Dump {
  std::vector<double> xyz;
  std::vector<std::int32_t> tris;
  bool mixed = false;  // tris holds 4 ids per element (−1 last: a triangle)
};

Dump readDump(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::int64_t n = 0, e = 0;
  in.read(reinterpret_cast<char*>(&n), 8);
  in.read(reinterpret_cast<char*>(&e), 8);
  Dump d;
  d.mixed = e < 0;
  d.xyz.resize(static_cast<std::size_t>(3 * n));
  d.tris.resize(static_cast<std::size_t>(d.mixed ? -4 * e : 3 * e));
  in.read(reinterpret_cast<char*>(d.xyz.data()), static_cast<std::streamsize>(8 * d.xyz.size()));
  in.read(reinterpret_cast<char*>(d.tris.data()), static_cast<std::streamsize>(4 * d.tris.size()));
  if (!in) throw std::runtime_error("truncated " + path);
  return d;
}

void writeDump(const std::string& path, const SurfaceMesh& m, const Dump& d) {
  std::ofstream out(path, std::ios::binary);
  const std::int64_t n = static_cast<std::int64_t>(m.nodeCount());
  const std::int64_t e = d.mixed ? -static_cast<std::int64_t>(d.tris.size() / 4)
                                 : static_cast<std::int64_t>(d.tris.size() / 3);
  out.write(reinterpret_cast<const char*>(&n), 8);
  out.write(reinterpret_cast<const char*>(&e), 8);
  for (const Vec3& p : m.xyz) out.write(reinterpret_cast<const char*>(p.data()), 24);
  out.write(reinterpret_cast<const char*>(d.tris.data()),
            static_cast<std::streamsize>(4 * d.tris.size()));
}

/// The mesh's triangles as CadMesh input, without the pairs of duplicate triangles (the same
/// three corners as another triangle: one of the two is always inverted), as SurfMesh.optimize
/// leaves them out; their nodes are marked as bordering the holes they leave. `leftOut`
/// receives how many triangles were left out. The same rule for every tool's mesh, so that all
/// are measured on the same triangles.
MeshInput inputWithoutDuplicates(const Dump& d, std::size_t* leftOut,
                                 std::vector<std::size_t>* keptElements) {
  *leftOut = 0;
  keptElements->clear();
  if (d.mixed) {  // a recombined mesh: its elements as they are
    MeshInput in = triangleMeshInput(d.xyz, {});
    for (std::size_t e = 0; 4 * e < d.tris.size(); ++e) {
      const bool tri = d.tris[4 * e + 3] < 0;
      in.types.push_back(tri ? ElementType::Tri3 : ElementType::Quad4);
      keptElements->push_back(e);
      in.conn.insert(in.conn.end(), d.tris.begin() + static_cast<std::ptrdiff_t>(4 * e),
                     d.tris.begin() + static_cast<std::ptrdiff_t>(4 * e + (tri ? 3 : 4)));
    }
    return in;
  }
  const std::size_t E = d.tris.size() / 3;
  std::vector<std::array<std::int32_t, 4>> keys(E);  // sorted corners, triangle index
  for (std::size_t e = 0; e < E; ++e) {
    std::array<std::int32_t, 3> c = {d.tris[3 * e], d.tris[3 * e + 1], d.tris[3 * e + 2]};
    std::sort(c.begin(), c.end());
    keys[e] = {c[0], c[1], c[2], static_cast<std::int32_t>(e)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<unsigned char> dup(E, 0);
  for (std::size_t k = 1; k < E; ++k)
    if (std::equal(keys[k].begin(), keys[k].begin() + 3, keys[k - 1].begin()))
      dup[static_cast<std::size_t>(keys[k][3])] = dup[static_cast<std::size_t>(keys[k - 1][3])] = 1;
  std::vector<std::int32_t> kept;
  kept.reserve(d.tris.size());
  std::vector<unsigned char> border(d.xyz.size() / 3, 0);
  *leftOut = 0;
  for (std::size_t e = 0; e < E; ++e) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t v = d.tris[3 * e + static_cast<std::size_t>(k)];
      if (dup[e])
        border[static_cast<std::size_t>(v)] = 1;
      else
        kept.push_back(v);
    }
    *leftOut += dup[e];
    if (!dup[e]) keptElements->push_back(e);
  }
  MeshInput in = triangleMeshInput(d.xyz, kept);
  if (*leftOut > 0) in.leftOutNeighbour = std::move(border);
  return in;
}

}  // namespace

/// The Escape bits named in a comma-separated list of kEscapeNames ("all": every escape).
unsigned escapeBits(const std::string& list) {
  unsigned bits = 0;
  std::size_t a = 0;
  while (a <= list.size()) {
    const std::size_t b = std::min(list.find(',', a), list.size());
    const std::string name = list.substr(a, b - a);
    a = b + 1;
    if (name.empty()) continue;
    if (name == "all") {
      bits |= kAllEscapes;
      continue;
    }
    const auto* it = std::find_if(std::begin(kEscapeNames), std::end(kEscapeNames),
                                  [&](const char* n) { return name == n; });
    if (it == std::end(kEscapeNames)) throw std::invalid_argument("unknown escape: " + name);
    bits |= 1u << (it - std::begin(kEscapeNames));
  }
  return bits;
}

int main(int argc, char** argv) {
  if (argc == 2 && std::string(argv[1]) == "escapes") {  // the names BENCH_WITHOUT takes
    std::printf("[");
    for (std::size_t k = 0; k < std::size(kEscapeNames); ++k)
      std::printf("%s\"%s\"", k ? ", " : "", kEscapeNames[k]);
    std::printf("]\n");
    return 0;
  }
  if (argc < 4) {
    std::fprintf(stderr,
                 "usage: bench_cad measure|optimize SHAPE MESH.bin [OUT.bin THREADS] | escapes\n");
    return 2;
  }
  const std::string mode = argv[1];
  try {
    const double t0 = now();
    auto shape = CadShape::fromFile(argv[2]);
    const double tShape = now() - t0;
    Dump d = readDump(argv[3]);
    const double t1 = now();
    BridgeOptions bopt;
    if (const char* v = std::getenv("BENCH_BOUNDARY")) bopt.boundary = v;
    // The CAD recovery runs on as many threads as the optimization (measure: all cores).
    if (mode == "optimize" && argc > 5) bopt.threads = std::atoi(argv[5]);
    std::size_t leftOut = 0;
    std::vector<std::size_t> keptElements;  // dump element of each mesh element
    CadMesh cm(shape, inputWithoutDuplicates(d, &leftOut, &keptElements), bopt);
    const double tBridge = now() - t1;
    SurfaceMesh& m = cm.mesh();
    const PlanarMeasure& shapeMeasure = measureByName("shape");
    const BridgeReport& rep = cm.report();
    if (mode == "measure") {
      const MeshQuality mq = measureQuality(m, shapeMeasure);
      const QualityStats& q = mq.stats;
      std::size_t poor = 0;  // valid elements of quality below 0.2 (tangled ones apart)
      // Minimum quality of the elements with a Face node (those smoothing can change; the
      // others lie between nodes on CAD edges and vertices).
      double minFree = 1.0;
      for (std::size_t e = 0; e < mq.quality.size(); ++e) {
        if (!mq.tangled[e] && mq.quality[e] < 0.2) ++poor;
        const std::int32_t* nd = m.elementNodes(e);
        for (int k = 0; k < m.elementSize(e); ++k)
          if (m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Face) {
            minFree = std::min(minFree, mq.quality[e]);
            break;
          }
      }
      // BENCH_WORST=k: the k worst elements on stderr, with where their nodes lie.
      if (const char* v = std::getenv("BENCH_WORST")) {
        std::vector<std::size_t> order(mq.quality.size());
        for (std::size_t e = 0; e < order.size(); ++e) order[e] = e;
        std::sort(order.begin(), order.end(),
                  [&](std::size_t a, std::size_t b) { return mq.quality[a] < mq.quality[b]; });
        for (int k = 0; k < std::atoi(v) && k < static_cast<int>(order.size()); ++k) {
          const std::size_t e = order[static_cast<std::size_t>(k)];
          std::fprintf(stderr, "element %zu q %.4f face %d:", e, mq.quality[e], m.elemFace[e]);
          const std::int32_t* nd = m.elementNodes(e);
          for (int j = 0; j < m.elementSize(e); ++j) {
            const auto n = static_cast<std::size_t>(nd[j]);
            std::fprintf(stderr, "  n%d kind %d face %d edge %d", nd[j], int(m.nodeKind[n]),
                         m.nodeFace[n], m.nodeEdge[n]);
          }
          std::fprintf(stderr, "\n");
        }
      }
      std::printf(
          "{\"elements\": %zu, \"nodes\": %zu, \"min\": %.6f, \"min_with_face_node\": %.6f, "
          "\"max\": %.6f, "
          "\"mean\": %.6f, \"std\": %.6f, \"tangled\": %zu, \"below_0_2\": %zu, "
          "\"max_distance\": %.3e, \"bridge_s\": %.3f, \"face_nodes\": %zu, "
          "\"duplicates_left_out\": %zu, \"across\": %zu}\n",
          q.elements, m.nodeCount(), q.min, minFree, q.max, q.mean, q.stddev, q.tangled, poor,
          rep.maxDistance, tBridge, rep.faceNodes, leftOut, q.across);
      return 0;
    }
    if (mode != "optimize" || argc < 6) throw std::runtime_error("bad arguments");
    OptimizeOptions opt;
    opt.threads = std::atoi(argv[5]);
    if (const char* v = std::getenv("BENCH_RELTOL")) opt.relTol = std::atof(v);
    if (const char* v = std::getenv("BENCH_SWEEPS")) opt.maxSweeps = std::atoi(v);
    if (const char* v = std::getenv("BENCH_MEASURE")) opt.measure = v;
    if (const char* v = std::getenv("BENCH_MONOTONE")) opt.monotone = std::atoi(v) != 0;
    if (const char* v = std::getenv("BENCH_MOVETOL")) opt.moveTol = std::atof(v);
    if (const char* v = std::getenv("BENCH_OMEGA")) opt.overRelaxation = std::atof(v);
    if (const char* v = std::getenv("BENCH_TOPOLOGY")) opt.topology = v;
    if (const char* v = std::getenv("BENCH_WITHOUT")) opt.escapes &= ~escapeBits(v);
    // Floors of the speed issue (bench_common.h): one first-derivative evaluation per Face
    // node, and that plus one value of each triangle around it.
    const Floors floors = measureFloors(m);
    // BENCH_REPEAT=n (profiling): n − 1 runs on copies of the mesh first.
    if (const char* v = std::getenv("BENCH_REPEAT"))
      for (int k = 1; k < std::atoi(v); ++k) {
        SurfaceMesh copy = m;
        optimizeMesh(copy, opt);
      }
    std::vector<double> stamps;
    const bool trace = std::getenv("BENCH_TRACE") != nullptr;
    const double tOpt = now();
    const OptimizeResult r = optimizeMesh(m, opt, [&](const OptimizeProgress& p) {
      stamps.push_back(now());
      if (trace)  // BENCH_TRACE=1: one line per sweep on stderr
        std::fprintf(stderr, "sweep %3d  f %.9e  tangled %zu  min q %.6f  delta %.3g\n", p.sweep,
                     p.objective, p.tangled, p.minQuality, p.delta);
      return true;
    });
    // Sweep 1 visits every movable node (its time includes the setup: an upper bound); the
    // later sweeps only the nodes whose submesh changed.
    const double sweep1 = stamps.empty() ? 0.0 : stamps.front() - tOpt;
    const double meanSweep =
        stamps.size() >= 2 ? (stamps.back() - stamps.front()) / (stamps.size() - 1) : sweep1;
    // Edge flips rewired some elements: the dump gets their new node lists.
    Dump out = d;
    const std::size_t stride = d.mixed ? 4 : 3;
    for (std::int32_t e : r.rewiredElements) {
      const std::int32_t* nd = m.elementNodes(static_cast<std::size_t>(e));
      for (int k = 0; k < m.elementSize(static_cast<std::size_t>(e)); ++k)
        out.tris[stride * keptElements[static_cast<std::size_t>(e)] + static_cast<std::size_t>(k)] =
            nd[k];
    }
    writeDump(argv[4], m, out);
    std::string movableIds;  // the tangled elements left with a movable node
    for (std::int32_t e : r.tangledMovable)
      movableIds += (movableIds.empty() ? "" : ", ") + std::to_string(e);
    std::printf(
        "{\"seconds\": %.4f, \"sweeps\": %d, \"reason\": \"%s\", \"threads\": %d, "
        "\"bridge_s\": %.3f, \"shape_s\": %.3f, \"min\": %.6f, \"mean\": %.6f, "
        "\"tangled\": %zu, \"tangled_unmovable\": %zu, \"before_tangled\": %zu, "
        "\"peak_mb\": %.1f, "
        "\"floor_s\": %.6f, \"value_floor_s\": %.6f, \"sweep1_s\": %.6f, "
        "\"mean_sweep_s\": %.6f, \"tangled_movable_ids\": [%s], \"flips\": %zu, "
        "\"needles\": %zu}\n",
        r.seconds, r.sweeps, stopReasonName(r.reason), r.threadsUsed, tBridge, tShape, r.after.min,
        r.after.mean, r.after.tangled, r.tangledUnmovable.size(), r.before.tangled,
        peakRssBytes() / 1e6, floors.d1, floors.value, sweep1, meanSweep, movableIds.c_str(),
        r.flips, r.needles.size());
  } catch (const std::exception& ex) {
    std::printf("{\"error\": \"%s\"}\n", ex.what());
    return 1;
  }
  return 0;
}
