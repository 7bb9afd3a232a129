#include "surfmesh/optimize/edge_flips.h"

#include "surfmesh/measures/element_measure.h"
#include "surfmesh/mesh/distance_to_face.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "surfmesh/mesh/quality.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace surfmesh {

double triangleScaledJacobian(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double l0 = (b - a).norm(), l1 = (c - b).norm(), l2 = (a - c).norm();
  const double twiceArea = (b - a).cross(c - a).norm();
  const double longest = std::max({l0 * l1, l1 * l2, l2 * l0});
  if (!(longest > 0.0) || !std::isfinite(twiceArea)) return 0.0;
  return std::min(1.0, twiceArea / longest * 2.0 / std::sqrt(3.0));
}

namespace {

bool flippable(ElementType t) { return t == ElementType::Tri3 || t == ElementType::Tri6; }

std::uint64_t edgeKey(std::int32_t a, std::int32_t b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

double uvCross(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 p = b - a, q = c - a;
  return p.x() * q.y() - p.y() * q.x();
}

/// What a flip weighs of one element.
struct Judged {
  double quality = 0.0;  ///< 0 when invalid
  double scaledJacobian = 0.0;
  double jacobianRatio = 1.0;
  bool invalid = true;
};

/// A linear triangle's quality in its own plane: the report's quality of a valid triangle
/// (the measure takes a linear triangle in its own plane and only its orientation from the
/// surface), computed without the surface; 0 for a degenerate one.
double planarQuality(const PlanarMeasure& m, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 x[3] = {a, b, c};
  const ElementEval ev = elementDistortion(m, ElementType::Tri3, x, (b - a).cross(c - a), 0.0);
  return ev.tangled || !std::isfinite(ev.eta) || !(ev.eta > 0.0) ? 0.0
                                                                 : std::min(1.0, 1.0 / ev.eta);
}

/// `valid`: the element is known to be valid (a linear one is then judged without the surface).
Judged judge(const SurfaceMesh& mesh, std::size_t e, const PlanarMeasure& m, bool valid = false) {
  if (valid && mesh.elemType[e] == ElementType::Tri3) {
    const std::int32_t* nd = mesh.elementNodes(e);
    const Vec3 &a = mesh.xyz[static_cast<std::size_t>(nd[0])],
               &b = mesh.xyz[static_cast<std::size_t>(nd[1])],
               &c = mesh.xyz[static_cast<std::size_t>(nd[2])];
    Judged j;
    j.quality = planarQuality(m, a, b, c);
    j.invalid = !(j.quality > 0.0);
    j.scaledJacobian = triangleScaledJacobian(a, b, c);
    return j;
  }
  const ElementQuality q = elementQuality(mesh, e, m, mesh.surfaces);
  const std::int32_t* nd = mesh.elementNodes(e);
  Judged j;
  j.invalid = q.invalid();
  j.quality = j.invalid ? 0.0 : q.quality;
  j.scaledJacobian = triangleScaledJacobian(mesh.xyz[static_cast<std::size_t>(nd[0])],
                                            mesh.xyz[static_cast<std::size_t>(nd[1])],
                                            mesh.xyz[static_cast<std::size_t>(nd[2])]);
  j.jacobianRatio = mesh.elemType[e] == ElementType::Tri3 ? 1.0 : jacobianRatioOf(mesh, e);
  return j;
}

/// An element's node list and parameters, to write and to restore.
struct ElementCopy {
  std::int32_t nodes[6];
  Vec2 uv[6];
  int size = 0;
  void read(const SurfaceMesh& m, std::size_t e) {
    size = m.elementSize(e);
    for (int k = 0; k < size; ++k) {
      nodes[k] = m.elementNodes(e)[k];
      uv[k] = m.elementUV(e)[k];
    }
  }
  void write(SurfaceMesh& m, std::size_t e) const {
    const auto o = static_cast<std::size_t>(m.elemOffset[e]);
    for (int k = 0; k < size; ++k) {
      m.elemNodes[o + static_cast<std::size_t>(k)] = nodes[k];
      m.cornerUV[o + static_cast<std::size_t>(k)] = uv[k];
    }
  }
  /// Turns the triangle so that it starts with corner r (its side nodes with it).
  void rotate(int r) {
    if (r == 0) return;
    ElementCopy c = *this;
    for (int k = 0; k < 3; ++k) {
      nodes[k] = c.nodes[(k + r) % 3];
      uv[k] = c.uv[(k + r) % 3];
      if (size == 6) {
        nodes[3 + k] = c.nodes[3 + (k + r) % 3];
        uv[3 + k] = c.uv[3 + (k + r) % 3];
      }
    }
  }
  /// Keeps `first` as the first corner when the triangle has it.
  void startWith(std::int32_t first) {
    for (int k = 0; k < 3; ++k)
      if (nodes[k] == first) return rotate(k);
  }
};

class Flipper {
 public:
  Flipper(SurfaceMesh& mesh, const PlanarMeasure& measure, const std::vector<unsigned char>& held,
          bool valid)
      : m_(mesh),
        measure_(measure),
        held_(held),
        valid_(valid),
        cornerElems_(mesh.nodeCount()),
        judged_(mesh.elementCount()),
        known_(mesh.elementCount(), 0) {
    for (std::size_t e = 0; e < m_.elementCount(); ++e)
      for (int k = 0; k < cornerCount(m_.elemType[e]); ++k)
        cornerElems_[static_cast<std::size_t>(m_.elementNodes(e)[k])].push_back(
            static_cast<std::int32_t>(e));
  }

  /// One round; returns the flips made and adds the rewired elements to `rewired`.
  std::size_t round(std::vector<std::int32_t>* rewired) {
    const std::size_t E = m_.elementCount();
    // Pairs: a corner-to-corner edge of a marked flippable element used by exactly one other
    // element (of any type), each pair once.
    struct Pair {
      double worst;
      std::uint64_t key;
      std::int32_t a, b;
      int ka, kb;
    };
    std::vector<Pair> pairs;
    for (std::size_t e = 0; e < E; ++e) {
      if ((!dirty_.empty() && !dirty_[e]) || !flippable(m_.elemType[e])) continue;
      const std::int32_t* nd = m_.elementNodes(e);
      for (int k = 0; k < 3; ++k) {
        std::int32_t other = -1;
        int ko = -1, uses = 0;
        forEdgeUse(nd[k], nd[(k + 1) % 3], [&](std::int32_t g, int kg) {
          ++uses;
          if (g != static_cast<std::int32_t>(e)) other = g, ko = kg;
        });
        // Each pair once: from its element of the smaller id when both are marked.
        if (uses != 2 || other < 0 ||
            (other < static_cast<std::int32_t>(e) &&
             (dirty_.empty() || dirty_[static_cast<std::size_t>(other)])) ||
            !candidate(static_cast<std::int32_t>(e), other))
          continue;
        const double w =
            std::min(judged(e).quality, judged(static_cast<std::size_t>(other)).quality);
        pairs.push_back(
            {w, edgeKey(nd[k], nd[(k + 1) % 3]), static_cast<std::int32_t>(e), other, k, ko});
      }
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) {
      return std::tie(x.worst, x.key) < std::tie(y.worst, y.key);
    });
    std::vector<std::int32_t> flipped;
    std::vector<unsigned char> done(E, 0);
    for (const Pair& p : pairs) {
      if (done[static_cast<std::size_t>(p.a)] || done[static_cast<std::size_t>(p.b)]) continue;
      if (!tryFlip(p.a, p.ka, p.b, p.kb)) continue;
      done[static_cast<std::size_t>(p.a)] = done[static_cast<std::size_t>(p.b)] = 1;
      flipped.push_back(p.a);
      flipped.push_back(p.b);
      rewired->push_back(p.a);
      rewired->push_back(p.b);
    }
    // The next round weighs the pairs with an element sharing a corner with one rewired now.
    dirty_.assign(E, 0);
    for (std::int32_t e : flipped)
      for (int k = 0; k < 3; ++k)
        for (std::int32_t g : cornerElems_[static_cast<std::size_t>(
                 m_.elementNodes(static_cast<std::size_t>(e))[k])])
          dirty_[static_cast<std::size_t>(g)] = 1;
    return flipped.size() / 2;
  }

  /// Only pairs with an element marked here are weighed (empty: all).
  std::vector<unsigned char> dirty_;

 private:
  const Judged& judged(std::size_t e) {
    if (!known_[e]) {
      judged_[e] = judge(m_, e, measure_, valid_);
      known_[e] = 1;
    }
    return judged_[e];
  }

  bool allHeld(std::size_t e) const {
    if (held_.empty()) return false;
    for (int k = 0; k < m_.elementSize(e); ++k)
      if (!held_[static_cast<std::size_t>(m_.elementNodes(e)[k])]) return false;
    return true;
  }

  /// The cheap tests of a pair (same face and type, not held).
  bool candidate(std::int32_t a, std::int32_t b) const {
    const auto A = static_cast<std::size_t>(a), B = static_cast<std::size_t>(b);
    return m_.elemType[A] == m_.elemType[B] && m_.elemFace[A] == m_.elemFace[B] && !allHeld(A) &&
           !allHeld(B);
  }

  /// Calls use(element, k) for every element with corners a, b as its corners k, k + 1 (in
  /// either direction).
  template <class Use>
  void forEdgeUse(std::int32_t a, std::int32_t b, Use&& use) const {
    for (std::int32_t g : cornerElems_[static_cast<std::size_t>(a)]) {
      const auto G = static_cast<std::size_t>(g);
      const int nc = cornerCount(m_.elemType[G]);
      const std::int32_t* nd = m_.elementNodes(G);
      for (int k = 0; k < nc; ++k)
        if ((nd[k] == a && nd[(k + 1) % nc] == b) || (nd[k] == b && nd[(k + 1) % nc] == a)) {
          use(g, k);
          break;
        }
    }
  }

  bool edgeExists(std::int32_t a, std::int32_t b) const {
    bool found = false;
    forEdgeUse(a, b, [&](std::int32_t, int) { found = true; });
    return found;
  }

  /// Whether a triangle of face f with corners p, q, r would be known as face f's from its
  /// corners alone, as a recovery of the mesh from its nodes finds faces: a corner inside f,
  /// or corners on CAD edges whose faces have f alone in common, and not every corner on one
  /// CAD edge (a needle along it). A triangle between nodes of one edge and its vertices, or
  /// of an edge between two faces, could be read back on the other face (where it is
  /// folded). Where the mesh has no CAD edges (nodeEdge empty), every triangle is f's.
  bool ownFace(std::int32_t p, std::int32_t q, std::int32_t r, int f) const {
    if (m_.nodeEdge.size() != m_.nodeCount()) return true;
    int common[2] = {-1, -1};  // the faces the edge corners so far have in common (≤ 2 kept)
    int edges = 0, firstEdge = -1;
    bool sameEdge = true;
    for (std::int32_t n : {p, q, r}) {
      const auto N = static_cast<std::size_t>(n);
      if (m_.nodeFace[N] == f) return true;
      const int e = m_.nodeEdge[N];
      if (e < 0 || static_cast<std::size_t>(e) >= m_.curves.size() || !m_.curves[e]) continue;
      sameEdge = sameEdge && (firstEdge < 0 || e == firstEdge);
      if (firstEdge < 0) firstEdge = e;
      const Curve& C = *m_.curves[static_cast<std::size_t>(e)];
      int faces[2] = {-1, -1}, k = 0;
      for (int j = 0; j < C.faceCount() && k < 2; ++j)
        if (C.faceId(j) != faces[0]) faces[k++] = C.faceId(j);
      if (edges++ == 0) {
        common[0] = faces[0];
        common[1] = faces[1];
      } else {
        for (int& c : common)
          if (c != faces[0] && c != faces[1]) c = -1;
      }
    }
    if (edges == 0 || sameEdge) return false;  // vertices alone, or a needle along one edge
    const bool hasF = common[0] == f || common[1] == f;
    const bool other = (common[0] >= 0 && common[0] != f) || (common[1] >= 0 && common[1] != f);
    return hasF && !other;
  }

  /// Element e's corner `from` becomes `to` (in the corner-to-elements lists).
  void moveCorner(std::int32_t e, std::int32_t from, std::int32_t to) {
    auto& v = cornerElems_[static_cast<std::size_t>(from)];
    v.erase(std::find(v.begin(), v.end(), e));
    cornerElems_[static_cast<std::size_t>(to)].push_back(e);
  }

  bool tryFlip(std::int32_t ia, int kA, std::int32_t ib, int kB) {
    const auto A = static_cast<std::size_t>(ia), B = static_cast<std::size_t>(ib);
    const int f = m_.elemFace[A];
    const Surface& S = *m_.surfaces[static_cast<std::size_t>(f)];
    const bool six = m_.elemType[A] == ElementType::Tri6;
    ElementCopy oldA, oldB;
    oldA.read(m_, A);
    oldB.read(m_, B);
    const int a1 = kA, b1 = (kA + 1) % 3, c1 = (kA + 2) % 3;  // A = (a, b, c)
    const int b2 = kB, a2 = (kB + 1) % 3, d2 = (kB + 2) % 3;  // B = (b, a, d)
    const std::int32_t a = oldA.nodes[a1], b = oldA.nodes[b1], c = oldA.nodes[c1];
    if (oldB.nodes[b2] != b || oldB.nodes[a2] != a) return false;  // wound against A
    const std::int32_t d = oldB.nodes[d2];
    if (c == d || edgeExists(c, d)) return false;
    // B's parameters onto A's: the shift of the shared nodes (whole periods).
    const Vec2 s = oldA.uv[a1] - oldB.uv[a2];
    if ((s - (oldA.uv[b1] - oldB.uv[b2])).norm() > 1e-9 * (1.0 + s.norm())) return false;
    const bool straddles = s.norm() > 1e-9 * (1.0 + oldA.uv[a1].norm());
    auto onCad = [&](std::int32_t n) { return m_.nodeFace[static_cast<std::size_t>(n)] != f; };
    if (straddles && onCad(a) && onCad(b)) return false;  // the edge lies on the seam
    const Vec2 ua = oldA.uv[a1], ub = oldA.uv[b1], uc = oldA.uv[c1], ud = oldB.uv[d2] + s;
    const double sgn = m_.faceOrientation[static_cast<std::size_t>(f)] * S.normalSign();
    if (!(sgn * uvCross(ua, ud, uc) > 0.0) || !(sgn * uvCross(ud, ub, uc) > 0.0)) return false;

    // The new elements: A' = (a, d, c), B' = (d, b, c) (tri6: sides a-d, d-c, c-a and d-b,
    // b-c, c-d), B' in B's frame of (u,v).
    ElementCopy newA = oldA, newB = oldB;
    newA.nodes[0] = a, newA.nodes[1] = d, newA.nodes[2] = c;
    newA.uv[0] = ua, newA.uv[1] = ud, newA.uv[2] = uc;
    newB.nodes[0] = d, newB.nodes[1] = b, newB.nodes[2] = c;
    newB.uv[0] = oldB.uv[d2], newB.uv[1] = oldB.uv[b2], newB.uv[2] = uc - s;
    std::int32_t mid = -1;
    Vec2 midUV;
    if (six) {
      mid = oldA.nodes[3 + a1];
      const auto M = static_cast<std::size_t>(mid);
      if (oldB.nodes[3 + b2] != mid || m_.nodeKind[M] != NodeKind::Face || m_.nodeFace[M] != f ||
          (!held_.empty() && held_[M]))
        return false;
      // The reused side node at the face's point nearest the new side's midpoint.
      const Vec2 start = 0.5 * (uc + ud);
      const Vec3 x =
          0.5 * (m_.xyz[static_cast<std::size_t>(c)] + m_.xyz[static_cast<std::size_t>(d)]);
      double dist = 0.0;
      midUV = nearestParameters(S, x, start, &dist);
      if (!std::isfinite(dist) || !midUV.allFinite() || !S.contains(midUV.x(), midUV.y())) {
        if (!S.contains(start.x(), start.y())) return false;
        midUV = start;
      }
      midUV = S.unwrapNear(midUV, start);
      newA.nodes[3] = oldB.nodes[3 + a2], newA.uv[3] = oldB.uv[3 + a2] + s;  // a-d
      newA.nodes[4] = mid, newA.uv[4] = midUV;                               // d-c
      newA.nodes[5] = oldA.nodes[3 + c1], newA.uv[5] = oldA.uv[3 + c1];      // c-a
      newB.nodes[3] = oldB.nodes[3 + d2], newB.uv[3] = oldB.uv[3 + d2];      // d-b
      newB.nodes[4] = oldA.nodes[3 + b1], newB.uv[4] = oldA.uv[3 + b1] - s;  // b-c
      newB.nodes[5] = mid, newB.uv[5] = midUV - s;                           // c-d
    }
    if (!ownFace(a, d, c, f) || !ownFace(d, b, c, f)) return false;
    newA.startWith(oldA.nodes[0]);
    newB.startWith(oldB.nodes[0]);

    const Judged jA = judged(A), jB = judged(B);
    if (!six && !jA.invalid && !jB.invalid) {
      // The new triangles' qualities if valid, without the surface: most pairs stop here.
      const Vec3 &xa = m_.xyz[static_cast<std::size_t>(a)],
                 &xb = m_.xyz[static_cast<std::size_t>(b)],
                 &xc = m_.xyz[static_cast<std::size_t>(c)],
                 &xd = m_.xyz[static_cast<std::size_t>(d)];
      if (!(std::min(planarQuality(measure_, xa, xd, xc), planarQuality(measure_, xd, xb, xc)) >
            std::min(jA.quality, jB.quality) * (1.0 + 1e-6)) ||
          std::min(triangleScaledJacobian(xa, xd, xc), triangleScaledJacobian(xd, xb, xc)) <
              std::min(jA.scaledJacobian, jB.scaledJacobian) - 1e-12)
        return false;
    }
    Vec3 midXYZ = Vec3::Zero();
    Vec2 midOld = Vec2::Zero();
    if (six) {
      const auto M = static_cast<std::size_t>(mid);
      midXYZ = m_.xyz[M];
      midOld = m_.uv[M];
      m_.uv[M] = S.wrap(midUV);
      m_.xyz[M] = S.value(midUV.x(), midUV.y());
    }
    newA.write(m_, A);
    newB.write(m_, B);
    const Judged nA = judge(m_, A, measure_), nB = judge(m_, B, measure_);
    bool keep = !nA.invalid && !nB.invalid;
    if (keep && !jA.invalid && !jB.invalid) {
      const double qOld = std::min(jA.quality, jB.quality);
      keep = std::min(nA.quality, nB.quality) > qOld * (1.0 + 1e-6) &&
             std::min(nA.scaledJacobian, nB.scaledJacobian) >=
                 std::min(jA.scaledJacobian, jB.scaledJacobian) - 1e-12 &&
             std::min(nA.jacobianRatio, nB.jacobianRatio) >=
                 std::min(jA.jacobianRatio, jB.jacobianRatio) - 1e-9;
    }
    if (!keep) {
      oldA.write(m_, A);
      oldB.write(m_, B);
      if (six) {
        m_.xyz[static_cast<std::size_t>(mid)] = midXYZ;
        m_.uv[static_cast<std::size_t>(mid)] = midOld;
      }
      return false;
    }
    judged_[A] = nA;
    judged_[B] = nB;
    moveCorner(ia, b, d);  // A = (a, d, c)
    moveCorner(ib, a, c);  // B = (d, b, c)
    return true;
  }

  SurfaceMesh& m_;
  const PlanarMeasure& measure_;
  const std::vector<unsigned char>& held_;
  const bool valid_;  // every element of the mesh is valid (flips keep them so)
  std::vector<std::vector<std::int32_t>> cornerElems_;  // node → elements with it as a corner
  std::vector<Judged> judged_;
  std::vector<unsigned char> known_;
};

}  // namespace

FlipPass flipEdges(SurfaceMesh& mesh, const PlanarMeasure& measure,
                   const std::vector<unsigned char>& heldNodes, int maxRounds,
                   const std::vector<unsigned char>& elements, bool valid) {
  if (!heldNodes.empty() && heldNodes.size() != mesh.nodeCount())
    throw std::invalid_argument("heldNodes has " + std::to_string(heldNodes.size()) +
                                " entries for " + std::to_string(mesh.nodeCount()) + " nodes");
  FlipPass out;
  if (!elements.empty() && elements.size() != mesh.elementCount())
    throw std::invalid_argument("elements has " + std::to_string(elements.size()) +
                                " entries for " + std::to_string(mesh.elementCount()) +
                                " elements");
  Flipper flipper(mesh, measure, heldNodes, valid);
  flipper.dirty_ = elements;
  for (int r = 0; r < maxRounds; ++r) {
    const std::size_t n = flipper.round(&out.rewired);
    out.flips += n;
    if (n == 0) break;
  }
  std::sort(out.rewired.begin(), out.rewired.end());
  out.rewired.erase(std::unique(out.rewired.begin(), out.rewired.end()), out.rewired.end());
  return out;
}

std::vector<std::int32_t> needleElements(const SurfaceMesh& mesh, const PlanarMeasure& measure,
                                         double below) {
  std::vector<std::int32_t> out;
  if (mesh.nodeEdge.size() != mesh.nodeCount() || mesh.curves.empty()) return out;
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    int edge = -1;
    bool one = true;
    double longest = 0.0;
    for (int k = 0; k < nc && one; ++k) {
      const auto n = static_cast<std::size_t>(nd[k]);
      longest = std::max(
          longest, (mesh.xyz[n] - mesh.xyz[static_cast<std::size_t>(nd[(k + 1) % nc])]).norm());
      if (mesh.nodeFace[n] >= 0)
        one = false;
      else if (mesh.nodeEdge[n] >= 0) {
        if (edge < 0)
          edge = mesh.nodeEdge[n];
        else if (edge != mesh.nodeEdge[n])
          one = false;
      }
    }
    if (!one || edge < 0 || static_cast<std::size_t>(edge) >= mesh.curves.size() ||
        !mesh.curves[static_cast<std::size_t>(edge)])
      continue;
    // The vertex corners must be the edge's ends.
    const Curve& C = *mesh.curves[static_cast<std::size_t>(edge)];
    const Vec3 p0 = C.value(C.tmin()), p1 = C.value(C.tmax());
    const double tol = 1e-3 * longest;
    for (int k = 0; k < nc && one; ++k) {
      const auto n = static_cast<std::size_t>(nd[k]);
      if (mesh.nodeEdge[n] >= 0) continue;
      one = std::min((mesh.xyz[n] - p0).norm(), (mesh.xyz[n] - p1).norm()) <= tol;
    }
    if (!one) continue;
    const ElementQuality q = elementQuality(mesh, e, measure, mesh.surfaces);
    if (q.invalid() || q.quality < below) out.push_back(static_cast<std::int32_t>(e));
  }
  return out;
}

}  // namespace surfmesh
