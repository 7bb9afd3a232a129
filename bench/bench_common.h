// SurfMesh benchmarks — shared helpers: scalable structured meshes on analytic and OCC
// surfaces, a perturbation that keeps nodes on the surface, timing and peak memory.
#pragma once

#include "surfmesh/geometry/surface.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

namespace surfmesh::bench {

inline double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Peak resident set size of this process in bytes (VmHWM from /proc/self/status).
inline double peakRssBytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return 1024.0 * std::atof(line.c_str() + 6);
  return 0.0;
}

/// Current resident set size in bytes (VmRSS).
inline double rssBytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return 1024.0 * std::atof(line.c_str() + 6);
  return 0.0;
}

/// Structured triangulation of [u0,u1] × [v0,v1] with nu × nv cells (2 triangles each),
/// periodic in u and/or v (then the last row/column is identified with the first), odd rows
/// shifted by half a cell. Nodes on non-periodic borders are listed in `fixed`.
struct Grid {
  std::vector<Vec2> uv;
  std::vector<std::int32_t> conn;
  std::vector<std::int32_t> fixed;
};

inline Grid structuredGrid(int nu, int nv, double u0, double u1, double v0, double v1, bool uPer,
                           bool vPer) {
  Grid g;
  const int cu = uPer ? nu : nu + 1, cv = vPer ? nv : nv + 1;
  const double du = (u1 - u0) / nu, dv = (v1 - v0) / nv;
  g.uv.reserve(static_cast<std::size_t>(cu) * cv);
  g.conn.reserve(static_cast<std::size_t>(nu) * nv * 6);
  auto id = [&](int i, int j) {
    const int ii = uPer ? ((i % cu) + cu) % cu : i;
    const int jj = vPer ? ((j % cv) + cv) % cv : j;
    return static_cast<std::int32_t>(jj * cu + ii);
  };
  for (int j = 0; j < cv; ++j)
    for (int i = 0; i < cu; ++i) {
      const bool border = (!uPer && (i == 0 || i == nu)) || (!vPer && (j == 0 || j == nv));
      const double shift = (uPer && vPer) || !border ? 0.5 * (j % 2) : 0.0;
      g.uv.emplace_back(u0 + (i + ((!uPer && (i == 0 || i == nu)) ? 0.0 : shift)) * du,
                        v0 + j * dv);
      if (border) g.fixed.push_back(static_cast<std::int32_t>(g.uv.size() - 1));
    }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const std::int32_t a = id(i, j), b = id(i + 1, j), c = id(i, j + 1), d = id(i + 1, j + 1);
      if (j % 2 == 0)
        g.conn.insert(g.conn.end(), {a, b, c, b, d, c});
      else
        g.conn.insert(g.conn.end(), {a, b, d, a, d, c});
    }
  return g;
}

/// Moves every free node by a uniform random offset of `amp` cells in (u,v) and a fraction
/// `bigFraction` of them by `bigAmp` cells (to tangle elements); positions stay φ(u,v).
inline void perturb(SurfaceMesh& m, const Surface& s, double cellU, double cellV, double amp,
                    double bigFraction, double bigAmp, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unif(-1.0, 1.0), pick(0.0, 1.0);
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    if (m.nodeKind[i] != NodeKind::Face) continue;
    const double a = pick(rng) < bigFraction ? bigAmp : amp;
    m.uv[i] = s.clampToBounds(m.uv[i] + Vec2(a * cellU * unif(rng), a * cellV * unif(rng)));
  }
  syncFaceNodes(m);
}

}  // namespace surfmesh::bench
