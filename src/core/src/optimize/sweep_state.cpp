#include "sweep_state.h"

namespace surfmesh {
namespace detail {

State::State(const SurfaceMesh& m, const PlanarMeasure& pm, const OptimizeOptions& o,
             HoldAcross holdAcross)
    : mesh(m), measure(pm), opt(o), inc(buildIncidence(m)), xyz(m.xyz), uv(m.uv), t(m.nodeT) {
  const std::size_t N = m.nodeCount(), E = m.elementCount();
  for (std::size_t e = 0; e < E; ++e)
    if (m.elemType[e] != ElementType::Tri3) allTri3 = false;
  for (std::size_t i = 0; i < N; ++i)
    maxDegree = std::max(maxDegree, static_cast<std::size_t>(inc.offset[i + 1] - inc.offset[i]));
  nodeNormal.assign(N, Vec3::Zero());
  d2.resize(N);
  d2Valid.assign(N, 0);
  lastVisit.assign(N, 0);
  movedAt.assign(N, 0);
  lastStep.assign(N, Eigen::Vector2f::Zero());
  bool anyEdge = false;
  for (std::size_t i = 0; i < N; ++i) {
    if (m.nodeKind[i] == NodeKind::Face) nodeNormal[i] = m.referenceNormal(m.nodeFace[i], uv[i]);
    if (m.nodeKind[i] == NodeKind::Edge) anyEdge = true;
  }
  fixedNormal.assign(E, Vec3::Zero());
  faceCorners.assign(E, 0);
  for (std::size_t e = 0; e < E; ++e) {
    const int nc = cornerCount(m.elemType[e]);
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < nc; ++k) {
      if (m.nodeKind[static_cast<std::size_t>(nd[k])] != NodeKind::Face) {
        const Vec3 nk = m.referenceNormal(m.elemFace[e], m.elementUV(e)[k]);
        fixedNormal[e] += nk;
        if (m.elemType[e] == ElementType::Tri3 || heldCurved(m.elemType[e])) {
          if (cornerElems.empty() || cornerElems.back() != static_cast<std::int32_t>(e)) {
            cornerElems.push_back(static_cast<std::int32_t>(e));
            cornerN.resize(cornerN.size() + kCornerSlots, Vec3::Zero());
          }
          cornerN[cornerN.size() - kCornerSlots + static_cast<std::size_t>(k)] = nk;
        }
      } else {
        faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | (1u << k));
      }
    }
  }
  // Linear triangles not standing across their surface at the start are held so
  // (kAcrossGuard, acrossArea).
  const bool hold = holdAcross != HoldAcross::None;
  for (std::size_t e = 0; hold && e < E; ++e) {
    if (m.elemType[e] != ElementType::Tri3) continue;
    const std::int32_t* nd = m.elementNodes(e);
    Vec3 corners[3];
    for (int k = 0; k < 3; ++k) corners[k] = cornerNormal(e, k);
    const Vec3 x[3] = {xyz[static_cast<std::size_t>(nd[0])], xyz[static_cast<std::size_t>(nd[1])],
                       xyz[static_cast<std::size_t>(nd[2])]};
    const Vec3 c = (x[1] - x[0]).cross(x[2] - x[0]);
    const double cn = c.norm();
    const CornerSides sides = cornerSides(ElementType::Tri3, x, corners);
    const bool along = sides.along, against = sides.against;
    int which;
    double slope;
    // Valid, not standing across and not leaning; or tangled (wound against every corner)
    // with a corner free on the face: untangling must not turn it over the top of the
    // surface into standing across. Not held: a tangled one whose corners all lie on CAD
    // edges, and a tangled one with a node sliding along a CAD edge — where the surface turns
    // by more than a right angle between two edges (BRepMesh's coarse blade edges), standing
    // across can be the only valid state there is, and sliding nodes reach it through their
    // elements; with ExceptSliding, a valid one with a sliding node neither (the run that
    // follows a held one that left tangled elements a node may move: optimizeHolding).
    bool sliding = false;
    for (int k = 0; k < 3; ++k)
      sliding = sliding || m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Edge;
    const bool guard = along ? (!sliding || holdAcross == HoldAcross::All) && !against &&
                                   acrossArea(c, cn, corners, &which, &slope) == cn && which < 0
                             : !sliding && against && (faceCorners[e] & 0x7u) != 0;
    if (cn > 0.0 && guard)
      faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | kAcrossGuard);
  }
  // High-order triangles and quad8 whose tangent plane at every corner is wound along the
  // surface's normal there are held so too: a move that turns the plane at a corner against
  // the normal (the curved element then leaves the surface at that corner, standing across
  // it, while the measure, which orients the element by the sum of its corner normals, can
  // still find it valid and well shaped) counts as tangling it. Not held: those with a
  // sliding node.
  for (std::size_t e = 0; hold && e < E; ++e) {
    if (!heldCurved(m.elemType[e])) continue;
    const std::int32_t* nd = m.elementNodes(e);
    bool sliding = false;
    for (int k = 0; k < m.elementSize(e); ++k)
      sliding = sliding || m.nodeKind[static_cast<std::size_t>(nd[k])] == NodeKind::Edge;
    Vec3 corners[kHeldSlots];
    const Surface& surf = *m.surfaces[static_cast<std::size_t>(m.elemFace[e])];
    for (int k = 0; k < heldNormalCount(e); ++k) corners[k] = heldNormal(e, k, surf);
    const CornerSides sides = cornerSidesAt(e, -1, Vec3::Zero(), corners);
    if (!sliding && sides.along && !turnedAgainstNow(e, corners, surf))
      faceCorners[e] = static_cast<std::uint8_t>(faceCorners[e] | kAcrossGuard);
  }
  if (anyEdge) {
    edgeSlot.assign(N, -1);
    for (std::size_t i = 0; i < N; ++i) {
      if (m.nodeKind[i] != NodeKind::Edge) continue;
      edgeSlot[i] = static_cast<std::int64_t>(edgeNormal.size());
      for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p) {
        const std::size_t e = static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)]);
        const int k = inc.local[static_cast<std::size_t>(p)];
        edgeNormal.push_back(k < cornerCount(m.elemType[e])
                                 ? m.referenceNormal(m.elemFace[e], m.elementUV(e)[k])
                                 : Vec3::Zero());
      }
    }
  }
  elemSize.assign(E, 1.0);
  eta0.assign(E, 1.0);
  minSigma.assign(E, 1.0);
}

}  // namespace detail
}  // namespace surfmesh
