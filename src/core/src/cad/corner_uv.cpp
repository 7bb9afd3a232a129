// SurfMesh — the CAD recovery: the (u,v) of every element's corners on its face, and the
// elements' votes on their faces' winding (see cad_bridge.h).
#include "recovery.h"

#include <BRep_Tool.hxx>
#include <Standard_Failure.hxx>
#include <gp_Pnt2d.hxx>

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace surfmesh::cad_detail {

namespace {

/// A pole's (u,v) moved onto the surface's singular line, where a first derivative vanishes:
/// a face's degenerated edge may lie a little off it (a cone's apex at v = −6e−11 where the
/// surface's is at v = 0), and there the normal is the other nappe's, turned over. The
/// coordinate across the line takes Gauss–Newton steps on ‖φ_u‖² (or ‖φ_v‖²); `uv` itself
/// when the surface is not nearly singular there or the line is farther than `reach` in space.
Vec2 ontoSingularity(const Surface& surf, const Vec2& uv, double reach) {
  SurfaceD2 d = surf.d2(uv.x(), uv.y());
  const bool uCollapses = d.du.norm() <= d.dv.norm();
  const double big = uCollapses ? d.dv.norm() : d.du.norm();
  auto small = [&](const SurfaceD2& s) { return uCollapses ? s.du.norm() : s.dv.norm(); };
  if (!(big > 0.0) || !(small(d) <= 1e-3 * big)) return uv;
  Vec2 c = uv;
  for (int it = 0; it < 4 && small(d) > 0.0; ++it) {
    const Vec3& a = uCollapses ? d.du : d.dv;  // the vanishing derivative
    const Vec3& b = d.duv;                     // its derivative across the line
    const double bb = b.squaredNorm();
    if (!(bb > 0.0)) break;
    Vec2 next = c;
    (uCollapses ? next.y() : next.x()) -= a.dot(b) / bb;
    const SurfaceD2 dn = surf.d2(next.x(), next.y());
    if (!(small(dn) < small(d)) || !dn.p.allFinite()) break;
    c = next;
    d = dn;
  }
  return (d.p - surf.value(uv.x(), uv.y())).norm() <= reach ? c : uv;
}

/// The corners' (u,v) of element e on its face, and its vote: its winding against the surface
/// normal.
void elementCorners(Recovery& r, const BridgeReport& report, std::size_t e, Projector& pr) {
  const CadShape& S = r.S;
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const std::vector<std::int32_t>& elemFace = r.elemFace;
  const std::vector<Vec2>& nodeUV = r.nodeUV;
  std::vector<Vec2>& allCornerUV = r.allCornerUV;
  std::vector<signed char>& vote = r.vote;
  const int f = elemFace[e];
  const Surface& surf = pr.surfaceCopy(f);
  const std::int32_t* nd = input.conn.data() + offsets[e];
  const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
  std::array<Vec2, kMaxElementNodes> corner;
  std::array<unsigned char, kMaxElementNodes> known{};
  std::array<SurfaceD1, kMaxElementNodes> cornerD1;
  corner.fill(Vec2::Zero());
  Vec2 ref = Vec2::Zero();
  bool haveRef = false;
  for (int k = 0; k < nn; ++k) {
    const std::size_t n = static_cast<std::size_t>(nd[k]);
    if (report.nodeClass[n] == NodeClass::Face && report.nodeEntity[n] == f) {
      corner[static_cast<std::size_t>(k)] = haveRef ? surf.unwrapNear(nodeUV[n], ref) : nodeUV[n];
      known[static_cast<std::size_t>(k)] = 1;
      if (!haveRef) {
        ref = nodeUV[n];
        haveRef = true;
      }
    }
  }
  for (int k = 0; k < nn; ++k) {
    if (known[static_cast<std::size_t>(k)]) continue;
    const std::size_t n = static_cast<std::size_t>(nd[k]);
    Vec2 uv = Vec2::Zero();
    bool ok = false;
    const NodeClass c = report.nodeClass[n];
    try {
      if (c == NodeClass::Edge) {
        const int ed = report.nodeEntity[n];
        const auto& ef = S.edgeFaces(ed);
        if (std::binary_search(ef.begin(), ef.end(), f)) {
          uv = pr.curveCopy(ed).uvOnFace(f, report.nodeParam[n], haveRef ? ref : Vec2::Zero());
          ok = uv.allFinite();
        }
      } else if (c == NodeClass::Vertex) {
        const int v = report.nodeEntity[n];
        const auto& vf = S.vertexFaces(v);
        if (std::binary_search(vf.begin(), vf.end(), f)) {
          const gp_Pnt2d q = BRep_Tool::Parameters(S.vertex(v), S.face(f));
          uv = Vec2(q.X(), q.Y());
          ok = uv.allFinite();
        }
      }
    } catch (const Standard_Failure&) {
      ok = false;
    }
    if (!ok) uv = pr.faceDistance(f, input.nodes[n], kInf).uv;
    if (haveRef) {
      uv = surf.unwrapNear(uv, ref);
    } else {
      ref = uv;
      haveRef = true;
    }
    corner[static_cast<std::size_t>(k)] = uv;
  }
  // Corners on a pole: the free coordinate follows the element's other corners. The first
  // derivatives at the corners are kept (cornerD1[k] is at the current corner[k]).
  for (int k = 0; k < nn; ++k) {
    Vec2& c = corner[static_cast<std::size_t>(k)];
    if (r.isPole[static_cast<std::size_t>(nd[k])]) c = ontoSingularity(surf, c, 1e-6 * r.diag);
    cornerD1[static_cast<std::size_t>(k)] = surf.d1(c.x(), c.y());
  }
  for (int k = 0; k < nn; ++k) {
    const SurfaceD1& d = cornerD1[static_cast<std::size_t>(k)];
    if (!isDegenerate(d)) continue;
    const bool uFree = d.du.norm() <= d.dv.norm();
    double sum = 0.0;
    int cnt = 0;
    for (int j = 0; j < nn; ++j) {
      if (j == k) continue;
      const Vec2& o = corner[static_cast<std::size_t>(j)];
      if (isDegenerate(cornerD1[static_cast<std::size_t>(j)])) continue;
      sum += uFree ? o.x() : o.y();
      ++cnt;
    }
    if (cnt == 0) continue;
    Vec2& c = corner[static_cast<std::size_t>(k)];
    if (uFree)
      c.x() = sum / cnt;
    else
      c.y() = sum / cnt;
    cornerD1[static_cast<std::size_t>(k)] = surf.d1(c.x(), c.y());
  }
  std::copy(corner.begin(), corner.begin() + nn, allCornerUV.begin() + offsets[e]);

  // ---- 5. orientation (votes): the element's winding against the surface normal ----
  const int nc = cornerCount(input.types[e]);
  const Vec3 g = cornerPlaneNormal(input, nd, nc);
  Vec3 nsum = Vec3::Zero();
  for (int k = 0; k < nc; ++k) nsum += surf.normalOf(cornerD1[static_cast<std::size_t>(k)]);
  const double sd = g.dot(nsum);
  vote[e] = sd > 0 ? 1 : sd < 0 ? -1 : 0;
}

}  // namespace

void cornerUVs(Recovery& r, const BridgeReport& report) {
  const MeshInput& input = r.input;
  const std::size_t E = r.E;
  ProjectorPool& projectors = *r.projectors;
  // Corner (u,v) of every element node on the element's face, in parallel over the elements
  // (each thread with its own copies of the surfaces and curves). The orientation votes
  // (section 5) are taken in the same pass, from the same first derivatives at the corners.
  r.allCornerUV.assign(input.conn.size(), Vec2::Zero());
  r.vote.assign(E, 0);  // +1: winding along the surface normal, −1: against
  parallelFor(E, projectors,
              [&](std::size_t e, Projector& pr) { elementCorners(r, report, e, pr); });
}

}  // namespace surfmesh::cad_detail
