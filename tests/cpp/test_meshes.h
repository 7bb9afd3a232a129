// Test meshes on analytic surfaces, generated in the tests themselves.
#pragma once

#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace surfmesh::testmesh {

/// A triangulated (u,v) layout: parameters, connectivity and the nodes to keep fixed.
struct GridMesh {
  std::vector<Vec2> uv;
  std::vector<std::int32_t> conn;
  std::vector<std::int32_t> fixed;
};

/// Triangulates the strip between two rows of node ids sorted by u (non-periodic), advancing
/// along u; counter-clockwise when `top` lies at larger v than `bottom`.
inline void triangulateStrip(const std::vector<Vec2>& uv, const std::vector<std::int32_t>& bottom,
                             const std::vector<std::int32_t>& top,
                             std::vector<std::int32_t>& conn) {
  std::size_t i = 0, j = 0;
  while (i + 1 < bottom.size() || j + 1 < top.size()) {
    const bool advanceBottom = j + 1 >= top.size() || (i + 1 < bottom.size() &&
                                                       uv[bottom[i + 1]].x() <= uv[top[j + 1]].x());
    if (advanceBottom) {
      conn.insert(conn.end(), {bottom[i], bottom[i + 1], top[j]});
      ++i;
    } else {
      conn.insert(conn.end(), {bottom[i], top[j + 1], top[j]});
      ++j;
    }
  }
}

/// Planar square [0,1]² (or any rectangle), rows of near-equilateral triangles: even rows have
/// n+1 nodes, odd rows n+2 (half-shifted, with the two boundary nodes). Boundary nodes fixed.
inline GridMesh squareMesh(int n, double width = 1.0, double height = 1.0) {
  GridMesh g;
  const double h = width / n;
  const int rows = std::max(2, static_cast<int>(std::lround(height / (h * std::sqrt(3.0) / 2.0))));
  std::vector<std::vector<std::int32_t>> ids(static_cast<std::size_t>(rows + 1));
  for (int j = 0; j <= rows; ++j) {
    const double v = height * j / rows;
    std::vector<double> us;
    if (j % 2 == 0) {
      for (int i = 0; i <= n; ++i) us.push_back(i * h);
    } else {
      us.push_back(0.0);
      for (int i = 0; i < n; ++i) us.push_back((i + 0.5) * h);
      us.push_back(width);
    }
    for (std::size_t k = 0; k < us.size(); ++k) {
      ids[static_cast<std::size_t>(j)].push_back(static_cast<std::int32_t>(g.uv.size()));
      g.uv.emplace_back(us[k], v);
      if (j == 0 || j == rows || k == 0 || k + 1 == us.size())
        g.fixed.push_back(static_cast<std::int32_t>(g.uv.size() - 1));
    }
  }
  for (int j = 0; j < rows; ++j)
    triangulateStrip(g.uv, ids[static_cast<std::size_t>(j)], ids[static_cast<std::size_t>(j + 1)],
                     g.conn);
  return g;
}

/// Structured triangulation periodic in u: nv rows (vPer) or nv+1 rows of nu nodes, odd rows
/// shifted by half a cell so that the triangles interlock. Rows on non-periodic v boundaries
/// are fixed.
inline GridMesh periodicGridMesh(int nu, int nv, double u0, double u1, double v0, double v1,
                                 bool vPer) {
  GridMesh g;
  const int cv = vPer ? nv : nv + 1;
  const double du = (u1 - u0) / nu, dv = (v1 - v0) / nv;
  auto id = [&](int i, int j) { return ((j % cv + cv) % cv) * nu + ((i % nu) + nu) % nu; };
  for (int j = 0; j < cv; ++j)
    for (int i = 0; i < nu; ++i) {
      g.uv.emplace_back(u0 + (i + 0.5 * (j % 2)) * du, v0 + j * dv);
      if (!vPer && (j == 0 || j == nv))
        g.fixed.push_back(static_cast<std::int32_t>(g.uv.size() - 1));
    }
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i, j + 1), d = id(i + 1, j + 1);
      if (j % 2 == 0)
        g.conn.insert(g.conn.end(), {a, b, c, b, d, c});
      else
        g.conn.insert(g.conn.end(), {a, b, d, a, d, c});
    }
  return g;
}

/// Latitude–longitude sphere mesh: nv−1 rings of nu nodes plus the two poles (fixed), odd rings
/// shifted by half a cell, fans at the poles.
inline GridMesh sphereMesh(int nu, int nv) {
  const double pi = 3.14159265358979323846;
  GridMesh g =
      periodicGridMesh(nu, nv - 2, 0.0, 2 * pi, -pi / 2 + pi / nv, pi / 2 - pi / nv, false);
  g.fixed.clear();
  const std::int32_t south = static_cast<std::int32_t>(g.uv.size());
  g.uv.emplace_back(0.0, -pi / 2);
  const std::int32_t north = south + 1;
  g.uv.emplace_back(0.0, pi / 2);
  g.fixed = {south, north};
  const int rings = nv - 1;
  for (int i = 0; i < nu; ++i) {
    g.conn.insert(g.conn.end(), {south, (i + 1) % nu, i});
    const int top = (rings - 1) * nu;
    g.conn.insert(g.conn.end(), {top + i, top + (i + 1) % nu, north});
  }
  return g;
}

/// Perturbs (u,v) of random free nodes until at least `target` elements are tangled (or the
/// attempts run out). Nodes stay on the surface: positions are re-evaluated from (u,v).
inline std::size_t perturbUntilTangled(SurfaceMesh& m, const Surface& s, std::size_t target,
                                       double amplitudeU, double amplitudeV, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::size_t> freeNodes;
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (m.nodeKind[i] == NodeKind::Face) freeNodes.push_back(i);
  std::uniform_int_distribution<std::size_t> pick(0, freeNodes.size() - 1);
  std::uniform_real_distribution<double> unif(-1.0, 1.0);
  const PlanarMeasure& shape = measureByName("shape");
  std::size_t tangled = measureQuality(m, shape).stats.tangled;
  for (int attempt = 0; attempt < 100000 && tangled < target; ++attempt) {
    for (int k = 0; k < 5; ++k) {
      const std::size_t i = freeNodes[pick(rng)];
      Vec2 uv = m.uv[i] + Vec2(amplitudeU * unif(rng), amplitudeV * unif(rng));
      uv = s.clampToBounds(uv);
      m.uv[i] = uv;
    }
    syncFaceNodes(m);
    tangled = measureQuality(m, shape).stats.tangled;
  }
  return tangled;
}

/// Largest ‖x − φ(u,v)‖ over the Face nodes.
inline double maxDistanceToSurface(const SurfaceMesh& m) {
  double d = 0.0;
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    if (m.nodeKind[i] == NodeKind::Face) {
      const Surface& s = *m.surfaces[static_cast<std::size_t>(m.nodeFace[i])];
      d = std::max(d, (m.xyz[i] - s.value(m.uv[i].x(), m.uv[i].y())).norm());
    }
  return d;
}

inline void printTableRow(const std::string& label, const QualityStats& s) {
  std::printf("  %-28s  min %.3f  max %.3f  mean %.3f  std %.3f  tangled %zu  (of %zu)\n",
              label.c_str(), s.min, s.max, s.mean, s.stddev, s.tangled, s.elements);
}

}  // namespace surfmesh::testmesh
