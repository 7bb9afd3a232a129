#include "surfmesh/optimize/edge_flips.h"

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

Judged judge(const SurfaceMesh& mesh, std::size_t e, const PlanarMeasure& m) {
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
  Flipper(SurfaceMesh& mesh, const PlanarMeasure& measure, const std::vector<unsigned char>& held)
      : m_(mesh), measure_(measure), held_(held) {}

  /// One round; returns the flips made and adds the rewired elements to `rewired`.
  std::size_t round(std::vector<std::int32_t>* rewired) {
    const std::size_t E = m_.elementCount();
    // Every mesh edge (corner to corner), and the uses of the flippable elements' edges.
    edges_.clear();
    struct Use {
      std::uint64_t key;
      std::int32_t e;
      int k;
    };
    std::vector<Use> uses;
    for (std::size_t e = 0; e < E; ++e) {
      const int nc = cornerCount(m_.elemType[e]);
      const std::int32_t* nd = m_.elementNodes(e);
      for (int k = 0; k < nc; ++k) {
        const std::uint64_t key = edgeKey(nd[k], nd[(k + 1) % nc]);
        edges_.push_back(key);
        if (flippable(m_.elemType[e])) uses.push_back({key, static_cast<std::int32_t>(e), k});
      }
    }
    std::sort(edges_.begin(), edges_.end());
    std::sort(uses.begin(), uses.end(), [](const Use& x, const Use& y) {
      return std::tie(x.key, x.e, x.k) < std::tie(y.key, y.e, y.k);
    });
    // Pairs: an edge used by exactly two flippable elements (and by no other element).
    struct Pair {
      double worst;
      std::uint64_t key;
      std::int32_t a, b;
      int ka, kb;
    };
    std::vector<Pair> pairs;
    judged_.assign(E, Judged{});
    known_.assign(E, 0);
    for (std::size_t i = 0; i < uses.size();) {
      std::size_t j = i;
      while (j < uses.size() && uses[j].key == uses[i].key) ++j;
      const auto all = std::equal_range(edges_.begin(), edges_.end(), uses[i].key);
      if (j - i == 2 && all.second - all.first == 2 &&
          (dirty_.empty() || dirty_[static_cast<std::size_t>(uses[i].e)] ||
           dirty_[static_cast<std::size_t>(uses[i + 1].e)]) &&
          candidate(uses[i].e, uses[i + 1].e)) {
        const double w = std::min(judged(static_cast<std::size_t>(uses[i].e)).quality,
                                  judged(static_cast<std::size_t>(uses[i + 1].e)).quality);
        pairs.push_back({w, uses[i].key, uses[i].e, uses[i + 1].e, uses[i].k, uses[i + 1].k});
      }
      i = j;
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) {
      return std::tie(x.worst, x.key) < std::tie(y.worst, y.key);
    });
    created_.clear();
    std::vector<unsigned char> done(E, 0);
    std::size_t flips = 0;
    for (const Pair& p : pairs) {
      if (done[static_cast<std::size_t>(p.a)] || done[static_cast<std::size_t>(p.b)]) continue;
      if (!tryFlip(p.a, p.ka, p.b, p.kb)) continue;
      done[static_cast<std::size_t>(p.a)] = done[static_cast<std::size_t>(p.b)] = 1;
      rewired->push_back(p.a);
      rewired->push_back(p.b);
      ++flips;
    }
    // The next round weighs the pairs with an element next to one rewired now.
    std::vector<unsigned char> touched(m_.nodeCount(), 0);
    for (std::size_t e = 0; e < E; ++e)
      if (done[e])
        for (int k = 0; k < m_.elementSize(e); ++k)
          touched[static_cast<std::size_t>(m_.elementNodes(e)[k])] = 1;
    dirty_.assign(E, 0);
    for (std::size_t e = 0; e < E; ++e)
      for (int k = 0; k < m_.elementSize(e) && !dirty_[e]; ++k)
        dirty_[e] = touched[static_cast<std::size_t>(m_.elementNodes(e)[k])];
    return flips;
  }

  /// Only pairs with an element marked here are weighed (empty: all).
  std::vector<unsigned char> dirty_;

 private:
  const Judged& judged(std::size_t e) {
    if (!known_[e]) {
      judged_[e] = judge(m_, e, measure_);
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

  bool edgeExists(std::uint64_t key) const {
    return std::binary_search(edges_.begin(), edges_.end(), key) ||
           std::find(created_.begin(), created_.end(), key) != created_.end();
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
    if (c == d || edgeExists(edgeKey(c, d))) return false;
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
    newA.startWith(oldA.nodes[0]);
    newB.startWith(oldB.nodes[0]);

    const Judged jA = judged(A), jB = judged(B);
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
    created_.push_back(edgeKey(c, d));
    return true;
  }

  SurfaceMesh& m_;
  const PlanarMeasure& measure_;
  const std::vector<unsigned char>& held_;
  std::vector<std::uint64_t> edges_;    // sorted, with repeats: one per use
  std::vector<std::uint64_t> created_;  // new diagonals of this round
  std::vector<Judged> judged_;
  std::vector<unsigned char> known_;
};

}  // namespace

FlipPass flipEdges(SurfaceMesh& mesh, const PlanarMeasure& measure,
                   const std::vector<unsigned char>& heldNodes, int maxRounds,
                   const std::vector<unsigned char>& elements) {
  if (!heldNodes.empty() && heldNodes.size() != mesh.nodeCount())
    throw std::invalid_argument("heldNodes has " + std::to_string(heldNodes.size()) +
                                " entries for " + std::to_string(mesh.nodeCount()) + " nodes");
  FlipPass out;
  if (!elements.empty() && elements.size() != mesh.elementCount())
    throw std::invalid_argument("elements has " + std::to_string(elements.size()) +
                                " entries for " + std::to_string(mesh.elementCount()) +
                                " elements");
  Flipper flipper(mesh, measure, heldNodes);
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
