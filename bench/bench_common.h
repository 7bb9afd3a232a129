// SurfMesh benchmarks — shared helpers: scalable structured meshes on analytic and OCC
// surfaces, a perturbation that keeps nodes on the surface, timing and peak memory.
#pragma once

#include "surfmesh/geometry/surface.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
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

/// The floors a sweep's time is compared with (seconds, min of 3 runs, on clones of the
/// surfaces, in the mesh's node order, over its Face nodes):
///   d1     one first-derivative evaluation per node (the speed issue's floor);
///   value  that plus the shape measure's value of every triangle around the node with the
///          node at φ(u,v): the least any method does that checks a move of each node
///          against its elements (a Newton step with a line search does it at least once,
///          plus the gradient and Hessian of the same elements).
struct Floors {
  double d1 = 0.0, value = 0.0;
};

inline Floors measureFloors(const SurfaceMesh& m) {
  std::vector<std::unique_ptr<Surface>> clones;
  for (const Surface* s : m.surfaces) clones.push_back(s ? s->clone() : nullptr);
  const std::size_t N = m.nodeCount();
  // Node → triangles (CSR), outside the timing.
  std::vector<std::size_t> off(N + 1, 0), tri;
  for (std::size_t e = 0; e < m.elementCount(); ++e)
    if (m.elemType[e] == ElementType::Tri3)
      for (int k = 0; k < 3; ++k) ++off[static_cast<std::size_t>(m.elementNodes(e)[k]) + 1];
  for (std::size_t i = 0; i < N; ++i) off[i + 1] += off[i];
  tri.resize(off[N]);
  {
    std::vector<std::size_t> fill(off.begin(), off.end() - 1);
    for (std::size_t e = 0; e < m.elementCount(); ++e)
      if (m.elemType[e] == ElementType::Tri3)
        for (int k = 0; k < 3; ++k) tri[fill[static_cast<std::size_t>(m.elementNodes(e)[k])]++] = e;
  }
  const PlanarMeasure& shape = measureByName("shape");
  const double s3 = 1.0 / std::sqrt(3.0);
  Floors f{1e300, 1e300};
  double sink = 0.0;
  for (int pass = 0; pass < 2; ++pass)
    for (int rep = 0; rep < 3; ++rep) {
      const double t0 = now();
      for (std::size_t i = 0; i < N; ++i) {
        if (m.nodeKind[i] != NodeKind::Face) continue;
        const Surface& sf = *clones[static_cast<std::size_t>(m.nodeFace[i])];
        const SurfaceD1 d = sf.d1(m.uv[i].x(), m.uv[i].y());
        if (pass == 0) {
          sink += d.du.x() + d.dv.y();
          continue;
        }
        const Vec3 n = d.du.cross(d.dv);
        for (std::size_t p = off[i]; p < off[i + 1]; ++p) {
          const std::int32_t* nd = m.elementNodes(tri[p]);
          Vec3 x[3];
          for (int k = 0; k < 3; ++k)
            x[k] =
                static_cast<std::size_t>(nd[k]) == i ? d.p : m.xyz[static_cast<std::size_t>(nd[k])];
          const Vec3 J0 = x[1] - x[0], J1 = x[2] - x[0];
          const Vec3 K1 = (2.0 * J1 - J0) * s3;
          const Vec3 c = J0.cross(J1);
          const double sigma = (c.dot(n) > 0.0 ? 2.0 : -2.0) * s3 * c.norm();
          sink += shape.invariantValue(J0.squaredNorm() + K1.squaredNorm(), sigma, sigma);
        }
      }
      double& best = pass == 0 ? f.d1 : f.value;
      best = std::min(best, now() - t0);
    }
  if (sink == 12345.678) std::printf("%g", sink);
  return f;
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
