// SurfMesh — the CAD recovery: the input checked (options, sizes, ids, hints), the reach of
// high-order nodes, and a fast failure on a mesh of another shape (see cad_bridge.h).
#include "../common/threads.h"
#include "recovery.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace surfmesh::cad_detail {

void validateInput(Recovery& r) {
  const MeshInput& input = r.input;
  const BridgeOptions& options = r.options;
  const std::size_t N = r.N, E = r.E;
  const int NF = r.NF, NE = r.NE, NV = r.NV;
  const double diag = r.diag;

  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance))
    fail(code::kBadOption, "tolerance must be >= 0 (0 = 1e-3 x shape diagonal), got " +
                               std::to_string(options.tolerance));
  const double tol = options.tolerance > 0.0 ? options.tolerance : 1e-3 * diag;
  if (options.boundary != "fixed" && options.boundary != "slide")
    fail(code::kBadOption,
         "unknown boundary mode '" + options.boundary + "' (expected \"fixed\" or \"slide\")");
  const bool slide = options.boundary == "slide";
  const int threads = detail::resolveThreads(options.threads);
  if (N == 0) fail(code::kEmptyMesh, "the mesh has no nodes");
  if (!input.leftOutNeighbour.empty() && input.leftOutNeighbour.size() != N)
    fail(code::kBadLayout, "leftOutNeighbour has " + std::to_string(input.leftOutNeighbour.size()) +
                               " entries for " + std::to_string(N) + " nodes");
  if (E == 0) fail(code::kEmptyMesh, "the mesh has no elements");
  for (std::size_t i = 0; i < N; ++i)
    if (!input.nodes[i].allFinite())
      failAt(code::kNonFiniteNode, "node {node} has a non-finite coordinate (NaN or inf)", -1,
             static_cast<std::int64_t>(i));
  std::vector<std::int64_t> offsets = input.offsets;
  if (offsets.empty()) {
    offsets.resize(E + 1);
    offsets[0] = 0;
    for (std::size_t e = 0; e < E; ++e) offsets[e + 1] = offsets[e] + nodeCount(input.types[e]);
  }
  if (offsets.size() != E + 1)
    fail(code::kBadLayout, "offsets must have " + std::to_string(E + 1) +
                               " entries (elements + 1), got " + std::to_string(offsets.size()));
  if (offsets[0] != 0) fail(code::kBadLayout, "offsets[0] must be 0");
  for (std::size_t e = 0; e < E; ++e) {
    const std::int64_t n = offsets[e + 1] - offsets[e];
    if (n != nodeCount(input.types[e]))
      failAt(code::kBadLayout,
             "element {element} has " + std::to_string(n) + " nodes, expected " +
                 std::to_string(nodeCount(input.types[e])) + " for " +
                 elementTypeName(input.types[e]),
             static_cast<std::int64_t>(e));
  }
  if (static_cast<std::size_t>(offsets[E]) != input.conn.size())
    fail(code::kBadLayout, "connectivity has " + std::to_string(input.conn.size()) +
                               " entries, offsets say " + std::to_string(offsets[E]));
  for (std::size_t e = 0; e < E; ++e)
    for (std::int64_t k = offsets[e]; k < offsets[e + 1]; ++k) {
      const std::int32_t n = input.conn[static_cast<std::size_t>(k)];
      if (n < 0 || static_cast<std::size_t>(n) >= N)
        failAt(code::kNodeOutOfRange,
               "element {element} references node " + std::to_string(n) + ", out of range [0, " +
                   std::to_string(N) + ")",
               static_cast<std::int64_t>(e));
      for (std::int64_t j = offsets[e]; j < k; ++j)
        if (input.conn[static_cast<std::size_t>(j)] == n)
          failAt(code::kRepeatedNode, "element {element} repeats node {node}",
                 static_cast<std::int64_t>(e), n);
    }
  auto checkHints = [&](const std::vector<std::int32_t>& h, int count, const char* name) {
    if (h.empty()) return;
    if (h.size() != N)
      fail(code::kBadLayout, std::string(name) + " must be empty or have one entry per node (" +
                                 std::to_string(N) + "), got " + std::to_string(h.size()));
    for (std::size_t i = 0; i < N; ++i)
      if (h[i] < -1 || h[i] >= count)
        failAt(code::kBadHint,
               std::string(name) + "[{node}] = " + std::to_string(h[i]) + " out of range [-1, " +
                   std::to_string(count) + ")",
               -1, static_cast<std::int64_t>(i));
  };
  checkHints(input.hintFace, NF, "hintFace");
  checkHints(input.hintEdge, NE, "hintEdge");
  checkHints(input.hintVertex, NV, "hintVertex");
  r.tol = tol;
  r.slide = slide;
  r.threads = threads;
  r.offsets = std::move(offsets);
}

void highOrderReach(Recovery& r) {
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const std::size_t N = r.N, E = r.E;
  const double tol = r.tol;
  std::vector<double> reach(N, 0.0);
  {
    std::vector<unsigned char> corner(N, 0);
    for (std::size_t e = 0; e < E; ++e) {
      const std::int32_t* nd = input.conn.data() + offsets[e];
      const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
      const int nc = elementEdges(input.types[e]).corners;
      double side = 0.0;
      for (int k = 0; k < nc; ++k)
        side = std::max(side, (input.nodes[static_cast<std::size_t>(nd[k])] -
                               input.nodes[static_cast<std::size_t>(nd[(k + 1) % nc])])
                                  .norm());
      for (int k = 0; k < nn; ++k) {
        const std::size_t n = static_cast<std::size_t>(nd[k]);
        if (k < nc)
          corner[n] = 1;
        else
          reach[n] = std::max(reach[n], kHighOrderReach * side);
      }
    }
    for (std::size_t n = 0; n < N; ++n)
      if (corner[n] || !(reach[n] > tol)) reach[n] = 0.0;
  }
  r.reach = std::move(reach);
}

void checkMeshOnShape(const Recovery& r) {
  const CadShape& S = r.S;
  const MeshInput& input = r.input;
  const std::size_t N = r.N;
  const double tol = r.tol;
  ProjectorPool& projectors = *r.projectors;
  Box mb = {kInf, kInf, kInf, -kInf, -kInf, -kInf};
  for (const Vec3& p : input.nodes)
    for (int i = 0; i < 3; ++i) {
      mb[static_cast<std::size_t>(i)] = std::min(mb[static_cast<std::size_t>(i)], p[i]);
      mb[static_cast<std::size_t>(i) + 3] = std::max(mb[static_cast<std::size_t>(i) + 3], p[i]);
    }
  const Box sb = toBox(S.boundingBox());
  auto boxText = [](const Box& b) {
    std::ostringstream os;
    os << "[" << b[0] << ", " << b[1] << ", " << b[2] << "] - [" << b[3] << ", " << b[4] << ", "
       << b[5] << "]";
    return os.str();
  };
  // A mesh many times larger or smaller than the shape was most likely written in other
  // units (the shape's box may be loose, up to about twice the tight one: only a factor of
  // 8 or more is taken as a sign).
  auto unitHint = [&]() -> std::string {
    auto diag = [](const Box& b) {
      return std::sqrt((b[3] - b[0]) * (b[3] - b[0]) + (b[4] - b[1]) * (b[4] - b[1]) +
                       (b[5] - b[2]) * (b[5] - b[2]));
    };
    const double ds = diag(sb), dm = diag(mb);
    if (!(ds > 0.0) || !(dm > 0.0) || !std::isfinite(dm)) return "";
    const double ratio = dm / ds;
    if (ratio < 8.0 && ratio > 1.0 / 8.0) return "";
    std::ostringstream os;
    os.precision(2);
    os << " (the mesh's bounding box is about " << (ratio >= 1.0 ? ratio : 1.0 / ratio)
       << (ratio >= 1.0 ? " times larger" : " times smaller")
       << " than the shape's: a unit mismatch, e.g. mm and m or inches? Scale the mesh or "
          "the shape)";
    return os.str();
  };
  bool disjoint = false;
  for (std::size_t i = 0; i < 3; ++i)
    if (mb[i] > sb[i + 3] + tol || mb[i + 3] < sb[i] - tol) disjoint = true;
  if (disjoint)
    fail(code::kMeshOffShape, "the mesh does not lie on this shape: its bounding box " +
                                  boxText(mb) + " does not meet the shape's " + boxText(sb) +
                                  unitHint());
  const std::size_t samples = std::min<std::size_t>(N, 64);
  std::vector<double> sd(samples);
  std::vector<int> sf(samples, -1);
  parallelFor(samples, projectors, [&](std::size_t k, Projector& pr) {
    const std::size_t n = k * N / samples;
    std::vector<FaceHit> hits;
    pr.facesNear(input.nodes[n], tol, &hits);
    NodeClass kind;
    int id = -1;
    sd[k] = hits.empty() ? pr.wholeShapeDistance(input.nodes[n], &kind, &id) : 0.0;
  });
  std::size_t off = 0, worst = 0;
  for (std::size_t k = 0; k < samples; ++k)
    if (sd[k] > tol) {
      ++off;
      if (sd[k] > sd[worst] || sd[worst] <= tol) worst = k;
    }
  if (off * 2 > samples) {
    Diagnostic d;
    d.code = code::kMeshOffShape;
    d.count = static_cast<std::int64_t>(off);
    d.nodes = {static_cast<std::int64_t>(worst * N / samples)};
    d.values = {
        {"samples", static_cast<double>(samples)}, {"tolerance", tol}, {"distance", sd[worst]}};
    d.format =
        "the mesh does not lie on this shape: {count} of {samples} sampled nodes are "
        "farther than the tolerance {tolerance} from the shape (e.g. node {node} at "
        "distance {distance}); mesh bounding box " +
        boxText(mb) + ", shape bounding box " + boxText(sb) + unitHint();
    fail(std::move(d));
  }
}

}  // namespace surfmesh::cad_detail
