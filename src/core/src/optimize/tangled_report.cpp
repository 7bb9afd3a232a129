// Which tangled elements node motion cannot repair, and the lists and warnings of those a run
// leaves.
#include "tangled_report.h"

#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "sweep_support.h"

#include <string>

namespace surfmesh {
namespace detail {

/// Whether element e (nodes at `xyz`, reference normal n) folds where no node that may move
/// acts: at one of the points where its validity is decided, det S ≤ 0 and the Jacobian there
/// depends only on nodes that may not move (CAD vertices, fixed CAD edges, poles). No node
/// motion can repair such an element. A linear triangle: none of its nodes may move. A
/// quadrilateral: a tangled corner triangle whose three nodes may not move. A high-order
/// triangle: a tangled node or quadrature point whose shape-function gradients vanish at
/// every movable node (e.g. the corner at a CAD vertex between two element edges on fixed CAD
/// edges, where a Gmsh curved element often folds). The fold must show against the reference
/// normal n and against the surface normal at each corner: n follows the element's movable
/// corners, and a fold that a corner normal does not confirm might open as they move.
bool foldHeld(const SurfaceMesh& m, const std::vector<Vec3>& xyz, std::size_t e, const Vec3& n) {
  const std::int32_t* nd = m.elementNodes(e);
  auto movable = [&](int k) { return isMovable(m.nodeKind[static_cast<std::size_t>(nd[k])]); };
  auto at = [&](int k) { return xyz[static_cast<std::size_t>(nd[k])]; };
  const ElementType type = m.elemType[e];
  if (type == ElementType::Tri3 || n.squaredNorm() == 0.0) {
    // Without a reference normal (corner normals that cancel) the element is tangled wherever
    // its nodes are, unless a movable corner changes the normal.
    for (int k = 0; k < m.elementSize(e); ++k)
      if (movable(k)) return false;
    return true;
  }
  const int nc = cornerCount(type);
  // With no corner that may move, n (the sum of the corner normals) cannot change either: a fold
  // against it between nodes that may not move stays, whatever the corner normals say (a
  // second-order triangle on a strongly curved face, its one movable side node far from the
  // corner where it folds). With no node that may move, nothing changes.
  bool cornerMoves = false, nodeMoves = false;
  for (int k = 0; k < m.elementSize(e); ++k)
    if (movable(k)) {
      nodeMoves = true;
      cornerMoves = cornerMoves || k < nc;
    }
  if (!nodeMoves) return true;
  auto folded = [&](const Jacobian32& J, const Mat2& Winv) {
    if (!jacobianValidity(J, Winv, n).tangled) return false;
    if (!cornerMoves) return true;
    for (int k = 0; k < nc; ++k) {  // surface normals only for a fold between fixed nodes
      const Vec3 nk = m.referenceNormal(m.elemFace[e], m.elementUV(e)[k]);
      if (nk.squaredNorm() > 0.0 && !jacobianValidity(J, Winv, nk).tangled) return false;
    }
    return true;
  };
  if (type == ElementType::Quad4) {
    // A corner whose three nodes lie on one CAD edge (sliding or fixed on it, or on a CAD
    // vertex at its end) stays a triangle of three points of the edge's curve: its plane turns
    // with the curve's geodesic curvature, not with the nodes' motion (a corner of 180° on an
    // edge straight in (u,v), or bent the wrong way: Gmsh's simple recombination leaves such
    // quads along CAD edges).
    auto onEdge = [&](int k, std::int32_t edge, double tol) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (m.nodeKind[j] == NodeKind::Face) return false;
      if (m.nodeEdge[j] == edge) return true;
      if (m.nodeKind[j] != NodeKind::Fixed || m.nodeEdge[j] >= 0) return false;
      const Curve& c = *m.curves[static_cast<std::size_t>(edge)];
      return (c.value(c.tmin()) - at(k)).norm() <= tol || (c.value(c.tmax()) - at(k)).norm() <= tol;
    };
    auto alongEdge = [&](int k, int k1, int k2) {
      if (m.nodeEdge.empty() || m.curves.empty()) return false;
      std::int32_t edge = -1;
      for (int q : {k, k1, k2}) {
        const std::size_t j = static_cast<std::size_t>(nd[q]);
        if (m.nodeKind[j] == NodeKind::Edge) edge = m.nodeEdge[j];
      }
      if (edge < 0 || !m.curves[static_cast<std::size_t>(edge)]) return false;
      const double tol = 1e-3 * std::sqrt(std::max((at(k1) - at(k)).squaredNorm(),
                                                   (at(k2) - at(k)).squaredNorm()));
      return onEdge(k, edge, tol) && onEdge(k1, edge, tol) && onEdge(k2, edge, tol);
    };
    for (int k = 0; k < 4; ++k) {
      const int k1 = (k + 1) % 4, k2 = (k + 3) % 4;
      if ((movable(k) || movable(k1) || movable(k2)) && !alongEdge(k, k1, k2)) continue;
      Jacobian32 J;
      J.col(0) = at(k1) - at(k);
      J.col(1) = at(k2) - at(k);
      if (folded(J, squareCornerWinv())) return true;
    }
    return false;
  }
  if (type == ElementType::Quad8) {
    // A quad8's Jacobian from the unit square at its nodes and on a 5 × 5 grid: folded there
    // with no node that may move among those it depends on.
    auto heldAtQuad = [&](double s, double t) {
      Eigen::Vector2d grad[8];
      quad8ShapeGradients(s, t, grad);
      Jacobian32 J = Jacobian32::Zero();
      for (int i = 0; i < 8; ++i) {
        if (grad[i].squaredNorm() <= 1e-24) continue;
        if (movable(i)) return false;
        J.col(0) += grad[i].x() * at(i);
        J.col(1) += grad[i].y() * at(i);
      }
      return folded(J, squareCornerWinv());
    };
    for (int i = 0; i <= 4; ++i)
      for (int j = 0; j <= 4; ++j)
        if (heldAtQuad(0.25 * i, 0.25 * j)) return true;
    return false;
  }
  const HighOrderTriangleRule& rule = highOrderTriangleRule(elementOrder(type));
  const int nn = rule.nodes;
  auto heldAt = [&](const Eigen::Vector2d* grad) {
    Jacobian32 J = Jacobian32::Zero();
    for (int i = 0; i < nn; ++i) {
      if (grad[i].squaredNorm() <= 1e-24) continue;  // zero up to the rounding of ξ
      if (movable(i)) return false;
      J.col(0) += grad[i].x() * at(i);
      J.col(1) += grad[i].y() * at(i);
    }
    return folded(J, equilateralWinv());
  };
  for (int a = 0; a < nn; ++a)
    if (heldAt(rule.gradAtNode.data() + static_cast<std::size_t>(a * nn))) return true;
  for (std::size_t q = 0; q < rule.quadrature->points.size(); ++q)
    if (heldAt(rule.gradAtPoint.data() + q * static_cast<std::size_t>(nn))) return true;
  return false;
}

/// Per element: 1 when none of its nodes may move (it is in no node's submesh).
std::vector<unsigned char> frozenElements(const SurfaceMesh& m) {
  std::vector<unsigned char> frozen(m.elementCount(), 1);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < m.elementSize(e); ++k)
      if (isMovable(m.nodeKind[static_cast<std::size_t>(nd[k])])) frozen[e] = 0;
  }
  return frozen;
}
}  // namespace detail

/// Sorts the elements tangled in `q` into those that fold where a movable node acts and those
/// that fold where none does (foldHeld: no node motion can repair them), with a warning for
/// each non-empty list.
void reportTangled(const SurfaceMesh& mesh, const MeshQuality& q, OptimizeResult* res) {
  res->tangledUnmovable.clear();
  res->tangledMovable.clear();
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    if (!q.tangled[e]) continue;
    const bool held = detail::foldHeld(mesh, mesh.xyz, e, elementReferenceNormal(mesh, e));
    (held ? res->tangledUnmovable : res->tangledMovable).push_back(static_cast<std::int32_t>(e));
  }
  auto ids = [](const std::vector<std::int32_t>& v) {
    std::string t;
    const std::size_t shown = std::min<std::size_t>(v.size(), 20);
    for (std::size_t k = 0; k < shown; ++k) t += (k ? ", " : "") + std::to_string(v[k]);
    if (shown < v.size()) t += ", …";
    return t;
  };
  res->warnings.clear();
  if (!res->tangledUnmovable.empty())
    res->warnings.push_back(
        std::to_string(res->tangledUnmovable.size()) +
        " element(s) stay tangled with no node that may move where they fold (their nodes there "
        "are all on CAD vertices, fixed CAD edges or poles): moving nodes cannot repair them, "
        "the mesh must be changed there (elements " +
        ids(res->tangledUnmovable) + ")");
  if (!res->tangledMovable.empty())
    res->warnings.push_back(std::to_string(res->tangledMovable.size()) +
                            " element(s) stay tangled although some of their nodes may move "
                            "(elements " +
                            ids(res->tangledMovable) + ")");
}
}  // namespace surfmesh
