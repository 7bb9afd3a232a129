#pragma once
// Meshes shared by the C++ tests: linear (u,v) grids elevated to order p, and periodic
// second-order (tri6 / tri10, quad8 and tri6 + quad8) meshes of a torus.

#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/mesh/surface_mesh.h"
#include "test_meshes.h"

#include <algorithm>
#include <map>
#include <utility>
#include <vector>

namespace surfmesh::testmesh {

constexpr double kTestPi = 3.14159265358979323846;

/// A linear (u,v) triangulation elevated to order p with every new node at its straight (u,v)
/// position ("edges correspond to straight segments on the parametric space", paper §6.4).
/// Edge nodes are shared by the two triangles of an edge; nodes on boundary edges (edges of a
/// single triangle) are fixed, as are the given fixed corners.
inline GridMesh elevate(const Surface& s, const GridMesh& lin, int p) {
  GridMesh h;
  h.uv = lin.uv;
  h.fixed = lin.fixed;
  const LagrangeTriangle& lt = lagrangeTriangle(p);
  const int nn = lt.nodeCount();
  const std::size_t E = lin.conn.size() / 3;
  auto key = [](std::int32_t a, std::int32_t b) {
    return std::make_pair(std::min(a, b), std::max(a, b));
  };
  std::map<std::pair<std::int32_t, std::int32_t>, int> uses;
  for (std::size_t e = 0; e < E; ++e)
    for (int a = 0; a < 3; ++a) ++uses[key(lin.conn[3 * e + a], lin.conn[3 * e + (a + 1) % 3])];
  std::map<std::pair<std::int32_t, std::int32_t>, std::vector<std::int32_t>> edgeNodes;
  for (std::size_t e = 0; e < E; ++e) {
    const std::int32_t* c = lin.conn.data() + 3 * e;
    Vec2 cu[3];
    cu[0] = lin.uv[static_cast<std::size_t>(c[0])];
    for (int k = 1; k < 3; ++k) cu[k] = s.unwrapNear(lin.uv[static_cast<std::size_t>(c[k])], cu[0]);
    auto at = [&](const Eigen::Vector2d& xi) {
      return Vec2((1 - xi.x() - xi.y()) * cu[0] + xi.x() * cu[1] + xi.y() * cu[2]);
    };
    auto newNode = [&](const Vec2& uv, bool fixed) {
      const auto id = static_cast<std::int32_t>(h.uv.size());
      h.uv.push_back(s.wrap(uv));
      if (fixed) h.fixed.push_back(id);
      return id;
    };
    std::vector<std::int32_t> el(static_cast<std::size_t>(nn));
    for (int k = 0; k < 3; ++k) el[static_cast<std::size_t>(k)] = c[k];
    for (int ed = 0; ed < 3; ++ed) {
      const std::int32_t ga = c[ed], gb = c[(ed + 1) % 3];
      const auto kk = key(ga, gb);
      auto it = edgeNodes.find(kk);
      if (it == edgeNodes.end()) {
        std::vector<std::int32_t> ids;
        for (int j = 0; j < p - 1; ++j)
          ids.push_back(newNode(at(lt.nodes()[static_cast<std::size_t>(3 + ed * (p - 1) + j)]),
                                uses[kk] == 1));
        if (ga != kk.first) std::reverse(ids.begin(), ids.end());
        it = edgeNodes.emplace(kk, ids).first;
      }
      std::vector<std::int32_t> ids = it->second;  // from kk.first to kk.second
      if (ga != kk.first) std::reverse(ids.begin(), ids.end());
      for (int j = 0; j < p - 1; ++j) el[static_cast<std::size_t>(3 + ed * (p - 1) + j)] = ids[j];
    }
    for (int k = 3 + 3 * (p - 1); k < nn; ++k)
      el[static_cast<std::size_t>(k)] = newNode(at(lt.nodes()[static_cast<std::size_t>(k)]), false);
    h.conn.insert(h.conn.end(), el.begin(), el.end());
  }
  return h;
}

/// A 24 × 10 periodic grid of the whole torus elevated to order p (2 or 3), nodes at their
/// straight (u,v) positions.
inline SurfaceMesh torusMeshOfOrder(const TorusSurface& torus, int p) {
  const GridMesh lin = periodicGridMesh(24, 10, 0, 2 * kTestPi, 0, 2 * kTestPi, true);
  const GridMesh g = elevate(torus, lin, p);
  return makeSingleSurfaceMesh(torus, g.uv, p == 2 ? ElementType::Tri6 : ElementType::Tri10, g.conn,
                               g.fixed);
}

/// A periodic quad8 mesh of the torus: nu × nv cells, corner (i, j) at (i du, j dv), side nodes
/// at the (u,v) midpoints; with `triRows`, every odd row of cells split into two tri6.
inline SurfaceMesh torusQuad8(const Surface& torus, int nu, int nv, bool triRows) {
  const double du = 2 * kTestPi / nu, dv = 2 * kTestPi / nv;
  // nodes on the doubled grid (2nu × 2nv), those at (odd, odd) unused except by split cells
  std::vector<Vec2> uv;
  auto id = [&](int i, int j) {
    i = ((i % (2 * nu)) + 2 * nu) % (2 * nu);
    j = ((j % (2 * nv)) + 2 * nv) % (2 * nv);
    return static_cast<std::int32_t>(i * 2 * nv + j);
  };
  for (int i = 0; i < 2 * nu; ++i)
    for (int j = 0; j < 2 * nv; ++j) uv.emplace_back(0.5 * i * du, 0.5 * j * dv);
  SurfaceMesh m = makeSingleSurfaceMesh(torus, uv, ElementType::Tri3, {}, {});
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const int a = 2 * i, b = 2 * j;
      if (triRows && j % 2 == 1) {
        // the cell's diagonal from (a, b) to (a+2, b+2), its middle (a+1, b+1)
        const std::int32_t t1[6] = {id(a, b),     id(a + 2, b),     id(a + 2, b + 2),
                                    id(a + 1, b), id(a + 2, b + 1), id(a + 1, b + 1)};
        const std::int32_t t2[6] = {id(a, b),         id(a + 2, b + 2), id(a, b + 2),
                                    id(a + 1, b + 1), id(a + 1, b + 2), id(a, b + 1)};
        m.addElement(ElementType::Tri6, t1, 0);
        m.addElement(ElementType::Tri6, t2, 0);
        continue;
      }
      const std::int32_t q[8] = {id(a, b),     id(a + 2, b),     id(a + 2, b + 2), id(a, b + 2),
                                 id(a + 1, b), id(a + 2, b + 1), id(a + 1, b + 2), id(a, b + 1)};
      m.addElement(ElementType::Quad8, q, 0);
    }
  // the unused cell centres stay where they are
  std::vector<unsigned char> used(m.nodeCount(), 0);
  for (std::int32_t k : m.elemNodes) used[static_cast<std::size_t>(k)] = 1;
  for (std::size_t k = 0; k < m.nodeCount(); ++k)
    if (!used[k]) m.nodeKind[k] = NodeKind::Fixed;
  m.validate();
  return m;
}

}  // namespace surfmesh::testmesh
