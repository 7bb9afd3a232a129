// Curved elements measured against their straight-sided counterpart on the surface
// (OptimizeOptions::highOrder = "reference"; optimizer.h).
//
// A FEM solver judges a curved element by how far its map departs from that of its
// straight-sided counterpart: the same corners, the high-order nodes where interpolating the
// face puts them (Toulorge, Geuzaine, Remacle, Lambrechts, "Robust untangling of curvilinear
// meshes", JCP 254, 2013; Gargallo-Peiró, Roca, Peraire, Sarrate, IJNME 2016). The optimum of
// that distortion is the counterpart itself: on a plane an affine element, on a curved face
// only the curving the face asks for. The corners keep the paper's linear measure. So:
//   1. the corners are optimized as the linear mesh they span (tri3 / quad4 on the same faces,
//      the same options and boundary mode): the paper's method on the corner triangles;
//   2. every high-order node that lies inside its element's face (a Face node, not held by the
//      caller) goes to its straight-sided place on the face: the point of the face nearest to
//      the straight-sided element's node (the corners' interpolation in 3D; a side node: its
//      side's midpoint), searched from the corners' interpolation in (u,v) — independent of
//      the parametrization, as Gmsh's setOrder places them; with a sliding boundary, a
//      high-order node on a CAD edge whose side lies along that edge goes to the edge's point
//      nearest the straight side's node (the corners slid in step 1);
//   3. the elements left invalid (tangled, or standing across the surface) and the high-order
//      nodes sliding along CAD edges are optimized with the paper's Definition-4 measure
//      ("integral" mode) with the nodes of the elements within one ring around them, every
//      other node held; within three rings when that makes an element of the input invalid;
//   4. never worse: when an element valid in the input is invalid in the result, or the result
//      has a lower minimum quality where the input has no tangled element, or, on a valid
//      input, a lower minimum Jacobian ratio (elementJacobianRatio) or corner quality, the
//      result is cut back (keepNoWorse: every node the same share of its move, or element by
//      element the moves of the elements at fault halved then undone) until none of that
//      holds; when that leaves the input as it was, more invalid elements than the input,
//      or an element the run had untangled tangled again, the integral mode instead (cut
//      back the same way on a valid input);
//   5. where elements stay invalid (some where a node may move), the integral mode on them and
//      the elements within three rings around them, from the input's positions there, every
//      other node held where step 3 left it: its result when it leaves fewer, with the
//      straight-sided result put back away from the elements it left invalid when that keeps
//      as few (mergeAroundInvalid);
//   6. straightened: the high-order nodes inside the faces, with the corners, the nodes on CAD
//      edges and those of invalid elements held, optimized against each element's
//      straight-sided triangle on its corners, shape and size (straightenCurved), kept face
//      by face where that raises the mean Jacobian ratio and keeps validity and the minima
//      (the moves of the elements that would not, cut back first).
#include "reference_mode.h"

#include "progress_relay.h"
#include "straight_sided.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/distance_to_face.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "sweep.h"
#include "sweep_support.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace surfmesh {

namespace {

ElementType linearOf(ElementType t) { return isQuad(t) ? ElementType::Quad4 : ElementType::Tri3; }

double smallest(const std::vector<double>& v) {
  double m = std::numeric_limits<double>::infinity();
  for (double x : v) m = std::min(m, x);
  return m;
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

/// The linear mesh of the corners of `mesh`: the same nodes (the others held), each element's
/// corners as a tri3 or quad4 on the same face with the same corner parameters.
SurfaceMesh cornerMesh(const SurfaceMesh& mesh) {
  SurfaceMesh L;
  L.surfaces = mesh.surfaces;
  L.faceOrientation = mesh.faceOrientation;
  L.curves = mesh.curves;
  L.xyz = mesh.xyz;
  L.uv = mesh.uv;
  L.nodeFace = mesh.nodeFace;
  L.nodeEdge = mesh.nodeEdge;
  L.nodeT = mesh.nodeT;
  L.nodeKind = mesh.nodeKind;
  std::vector<unsigned char> corner(mesh.nodeCount(), 0);
  L.elemOffset.push_back(0);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    const Vec2* uv = mesh.elementUV(e);
    L.elemType.push_back(linearOf(mesh.elemType[e]));
    L.elemFace.push_back(mesh.elemFace[e]);
    for (int k = 0; k < nc; ++k) {
      L.elemNodes.push_back(nd[k]);
      L.cornerUV.push_back(uv[k]);
      corner[static_cast<std::size_t>(nd[k])] = 1;
    }
    L.elemOffset.push_back(static_cast<std::int64_t>(L.elemNodes.size()));
  }
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
    if (!corner[i]) L.nodeKind[i] = NodeKind::Fixed;
  return L;
}

/// The quality of each element's corner triangle or quadrilateral (the paper's linear
/// measure on the corners' mesh).
std::vector<double> cornerQuality(const SurfaceMesh& mesh, const PlanarMeasure& measure) {
  return measureQuality(cornerMesh(mesh), measure).quality;
}

/// The parameter of the point of curve c nearest to x: damped Newton steps on
/// C'(t)·(C(t) − x) = 0 from t, within the curve's range unless it is periodic, each kept only
/// when it comes closer.
double nearestCurveParameter(const Curve& c, const Vec3& x, double t) {
  double d = (c.value(t) - x).squaredNorm();
  for (int it = 0; it < 30 && std::isfinite(d); ++it) {
    const CurveD2 g = c.d2(t);
    const Vec3 r = g.p - x;
    const double slope = g.dt.dot(r), curv = g.dtt.dot(r) + g.dt.squaredNorm();
    double step = curv > 0.0 ? -slope / curv : -slope / std::max(g.dt.squaredNorm(), 1e-300);
    bool closer = false;
    for (int half = 0; half < 30 && !closer; ++half, step *= 0.5) {
      double tn = t + step;
      if (!c.isPeriodic()) tn = std::clamp(tn, c.tmin(), c.tmax());
      const double dn = (c.value(tn) - x).squaredNorm();
      if (dn < d) {
        closer = tn != t;
        t = tn;
        d = dn;
      }
    }
    if (!closer || std::abs(step) <= 1e-14 * (std::abs(t) + 1.0)) break;
  }
  return t;
}

/// Steps 1's result copied back and step 2 (see the file comment).
void placeStraightSided(SurfaceMesh& mesh, const SurfaceMesh& L) {
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    const Vec2* luv = L.elementUV(e);
    Vec2* cuv = mesh.cornerUV.data() + mesh.elemOffset[e];
    for (int k = 0; k < nc; ++k) {
      const std::size_t i = static_cast<std::size_t>(nd[k]);
      mesh.xyz[i] = L.xyz[i];
      mesh.uv[i] = L.uv[i];
      if (!mesh.nodeT.empty()) mesh.nodeT[i] = L.nodeT[i];
      cuv[k] = luv[k];
    }
  }
  std::vector<unsigned char> placed(mesh.nodeCount(), 0);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const ElementType type = mesh.elemType[e];
    if (type == ElementType::Tri3 || type == ElementType::Quad4) continue;
    const int f = mesh.elemFace[e];
    const Surface& s = *mesh.surfaces[static_cast<std::size_t>(f)];
    const std::int32_t* nd = mesh.elementNodes(e);
    Vec2* cuv = mesh.cornerUV.data() + mesh.elemOffset[e];
    for (int k = cornerCount(type); k < mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (mesh.nodeKind[j] != NodeKind::Face || mesh.nodeFace[j] != f) continue;
      // The point of the face nearest to the straight-sided element's node (the corners'
      // interpolation in 3D), from the corners' interpolation in (u,v): independent of the
      // parametrization (Gmsh's setOrder projects so too).
      Vec3 corners[4];
      for (int c = 0; c < cornerCount(type); ++c)
        corners[c] = mesh.xyz[static_cast<std::size_t>(nd[c])];
      const Vec2 start = straightPlace(type, k, cuv);
      double dist = 0.0;
      Vec2 t = nearestParameters(s, straightPlace(type, k, corners), start, &dist);
      if (!std::isfinite(dist) || !t.allFinite()) t = start;
      const Vec2 w = s.wrap(t);
      if (!w.allFinite() || !s.contains(w.x(), w.y())) continue;
      mesh.uv[j] = w;
      mesh.xyz[j] = s.value(w.x(), w.y());
      cuv[k] = t;
      placed[j] = 1;
    }
  }
  // A high-order node sliding along a CAD edge (boundary "slide") on a side whose corners lie
  // on that edge (or at its vertices): the point of the edge nearest to the straight side's
  // node. Left where it was, it would stay behind the corners that slid in step 1 and fold
  // its elements at a corner.
  for (std::size_t e = 0; e < mesh.elementCount() && !mesh.nodeT.empty(); ++e) {
    const ElementType type = mesh.elemType[e];
    if (type == ElementType::Tri3 || type == ElementType::Quad4) continue;
    const std::int32_t* nd = mesh.elementNodes(e);
    const int nc = cornerCount(type), p = elementOrder(type);
    Vec3 corners[4];
    for (int c = 0; c < nc; ++c) corners[c] = mesh.xyz[static_cast<std::size_t>(nd[c])];
    for (int k = nc; k < nc * p && k < mesh.elementSize(e); ++k) {  // the side nodes
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (placed[j] || mesh.nodeKind[j] != NodeKind::Edge) continue;
      const int side = (k - nc) / (p - 1);
      const std::int32_t curve = mesh.nodeEdge[j];
      bool along = true;
      for (int c : {side, (side + 1) % nc}) {
        const std::size_t q = static_cast<std::size_t>(nd[c]);
        along = along && (mesh.nodeKind[q] == NodeKind::Fixed || mesh.nodeEdge[q] == curve);
      }
      if (!along) continue;
      const Curve& cv = *mesh.curves[static_cast<std::size_t>(curve)];
      const double t = nearestCurveParameter(cv, straightPlace(type, k, corners), mesh.nodeT[j]);
      if (!std::isfinite(t) || t == mesh.nodeT[j]) continue;
      mesh.nodeT[j] = t;
      mesh.xyz[j] = cv.value(t);
      placed[j] = 2;
    }
  }
  // The placed nodes' parameters in the other elements around them, unwrapped there.
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const std::int32_t* nd = mesh.elementNodes(e);
    Vec2* cuv = mesh.cornerUV.data() + mesh.elemOffset[e];
    const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.elemFace[e])];
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (placed[j] == 1 && mesh.nodeFace[j] == mesh.elemFace[e])
        cuv[k] = s.unwrapNear(mesh.uv[j], cuv[0]);
      else if (placed[j] == 2)
        cuv[k] = s.unwrapNear(mesh.curves[static_cast<std::size_t>(mesh.nodeEdge[j])]->uvOnFace(
                                  mesh.elemFace[e], mesh.nodeT[j], cuv[k]),
                              cuv[k]);
    }
  }
}

/// Each high-order triangle's straight-sided triangle on its corners where they are now, as
/// its ideal (OptimizeOptions::highOrderTargets); the equilateral (a zero entry) where that
/// triangle is degenerate or wound against the element's normal.
std::vector<Mat2> straightSidedTargets(const SurfaceMesh& mesh) {
  std::vector<Mat2> targets(mesh.elementCount(), Mat2::Zero());
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    if (!isHighOrderTriangle(mesh.elemType[e])) continue;
    const std::int32_t* nd = mesh.elementNodes(e);
    const Vec3 n = elementReferenceNormal(mesh, e);
    if (!(n.squaredNorm() > 0.0)) continue;
    Mat2 Winv;
    if (straightSidedTarget(mesh.xyz[static_cast<std::size_t>(nd[0])],
                            mesh.xyz[static_cast<std::size_t>(nd[1])],
                            mesh.xyz[static_cast<std::size_t>(nd[2])], n, &Winv))
      targets[e] = Winv;
  }
  return targets;
}

/// Stage 3's fixedNodes: every node held (1) but those of the elements invalid in q1 (tangled
/// or standing across) and of the elements within `rings` rings around them, and the
/// high-order nodes on CAD edges. *any: whether a freed node may move.
std::vector<unsigned char> heldOutside(const SurfaceMesh& mesh, const MeshQuality& q1, int rings,
                                       bool* any) {
  std::vector<unsigned char> invalid(mesh.elementCount(), 0);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) invalid[e] = q1.invalid(e) ? 1 : 0;
  const std::vector<unsigned char> region = detail::widenByRings(mesh, std::move(invalid), rings);
  std::vector<unsigned char> held(mesh.nodeCount(), 1);
  *any = false;
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const std::int32_t* nd = mesh.elementNodes(e);
    const int nc = cornerCount(mesh.elemType[e]);
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (region[e] || (k >= nc && mesh.nodeKind[j] == NodeKind::Edge)) {
        held[j] = 0;
        *any = *any || mesh.nodeKind[j] != NodeKind::Fixed;
      }
    }
  }
  return held;
}

/// The nodes i with which[i] == take put where `from` has them, with their parameters in
/// every element they are in; the others left where they are.
void takePositions(SurfaceMesh& mesh, const detail::MeshPositions& from,
                   const std::vector<unsigned char>& which, unsigned char take) {
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
    if (which[i] == take) {
      mesh.xyz[i] = from.xyz[i];
      mesh.uv[i] = from.uv[i];
      if (!mesh.nodeT.empty()) mesh.nodeT[i] = from.nodeT[i];
    }
  for (std::size_t k = 0; k < mesh.elemNodes.size(); ++k)
    if (which[static_cast<std::size_t>(mesh.elemNodes[k])] == take)
      mesh.cornerUV[k] = from.cornerUV[k];
}

/// Per element: 1 when it is valid in q (neither tangled nor standing across).
std::vector<unsigned char> validIn(const MeshQuality& q) {
  std::vector<unsigned char> valid(q.tangled.size(), 0);
  for (std::size_t e = 0; e < valid.size(); ++e) valid[e] = q.invalid(e) ? 0 : 1;
  return valid;
}

/// Whether every element invalid in q is tangled where no node that may move acts (r, the run
/// that left q, lists them): no run can change those.
bool allHeld(const MeshQuality& q, const OptimizeResult& r) {
  std::vector<unsigned char> held(q.tangled.size(), 0);
  for (std::int32_t e : r.tangledUnmovable) held[static_cast<std::size_t>(e)] = 1;
  for (std::size_t e = 0; e < q.tangled.size(); ++e)
    if (q.invalid(e) && !held[e]) return false;
  return true;
}

/// Whether an element valid in the input (q0) is invalid in q, and how many are (*invalid).
bool judge(const SurfaceMesh& mesh, const MeshQuality& q0, const MeshQuality& q,
           std::size_t* invalid) {
  *invalid = invalidCount(q);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e)
    if (q.invalid(e) && !q0.invalid(e)) return true;
  return false;
}

/// The nodes of `mesh` not where `original` has them.
std::size_t movedCount(const SurfaceMesh& mesh, const detail::MeshPositions& original) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i) n += mesh.xyz[i] != original.xyz[i] ? 1 : 0;
  return n;
}

/// Drops from r's lists of tangled elements those no longer tangled in q (after a cut-back or
/// a merge that tangles none anew).
void keepStillTangled(OptimizeResult& r, const MeshQuality& q) {
  for (auto* v : {&r.tangledUnmovable, &r.tangledMovable})
    v->erase(
        std::remove_if(v->begin(), v->end(),
                       [&](std::int32_t e) { return !q.tangled[static_cast<std::size_t>(e)]; }),
        v->end());
}

/// The integral mode's result (in `mesh`) where `mine`, the reference result of quality
/// qMine, has invalid elements, widened by `rings` rings of elements; `mine` everywhere else.
/// The corner parameters of the nodes taken from the integral result are put in the period of
/// `mine`'s, so each element's parameters stay in one chart.
void mergeAroundInvalid(SurfaceMesh& mesh, const detail::MeshPositions& mine,
                        const MeshQuality& qMine, int rings) {
  const std::size_t N = mesh.nodeCount(), E = mesh.elementCount();
  std::vector<unsigned char> invalid(E, 0);
  for (std::size_t e = 0; e < E; ++e) invalid[e] = qMine.invalid(e) ? 1 : 0;
  const std::vector<unsigned char> region = detail::widenByRings(mesh, std::move(invalid), rings);
  std::vector<unsigned char> theirs(N, 0);
  for (std::size_t e = 0; e < E; ++e) {
    if (!region[e]) continue;
    const std::int32_t* nd = mesh.elementNodes(e);
    for (int k = 0; k < mesh.elementSize(e); ++k) theirs[static_cast<std::size_t>(nd[k])] = 1;
  }
  for (std::size_t i = 0; i < N; ++i)
    if (!theirs[i]) {
      mesh.xyz[i] = mine.xyz[i];
      mesh.uv[i] = mine.uv[i];
      if (!mesh.nodeT.empty()) mesh.nodeT[i] = mine.nodeT[i];
    }
  for (std::size_t e = 0; e < E; ++e) {
    const std::size_t off = static_cast<std::size_t>(mesh.elemOffset[e]);
    const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.elemFace[e])];
    const std::int32_t* nd = mesh.elementNodes(e);
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      Vec2& c = mesh.cornerUV[off + k];
      c = theirs[static_cast<std::size_t>(nd[k])] ? s.unwrapNear(c, mine.cornerUV[off + k])
                                                  : mine.cornerUV[off + k];
    }
  }
}

/// Never worse: cuts back the moves from `input` to `mesh` (the result) until no element valid
/// in the input (`wasValid`) is invalid, and none is below `ratioFloor` by its Jacobian ratio,
/// below `qualityFloor` by its quality or below `cornerFloor` by the quality of its corner
/// triangle (cornerQuality). Two ways, the one with fewer invalid elements kept, then the one
/// with the higher mean Jacobian ratio:
///  * every node the same share of its move, 7/8, 6/8, … 1/8 (in (u,v) on its face; a node on
///    a CAD edge or of an element on another face, or one whose share leaves the face, goes
///    back): the elements keep the shape the result gave them, only less of it;
///  * element by element from the whole result: the nodes of every element below have their
///    share halved, four times at most, then go back; and so on until no element is below (a
///    local backtracking). An element whose every node is back is the input's, so this ends.
/// With `uniformToo` false, only the second. Returns the number of nodes not where the result had
/// them; *q is the quality of the mesh as it ends.
std::size_t keepNoWorse(SurfaceMesh& mesh, const detail::MeshPositions& input,
                        const std::vector<unsigned char>& wasValid, double ratioFloor,
                        double qualityFloor, double cornerFloor, const PlanarMeasure& measure,
                        MeshQuality* q, bool uniformToo = true) {
  const std::size_t N = mesh.nodeCount(), E = mesh.elementCount();
  const detail::MeshPositions result = detail::MeshPositions::of(mesh);
  // A node takes a share of its move in (u,v) when it is a face node and every element
  // around it lies on its face (an element on another face holds the node's parameters on
  // that face); the others go back whole.
  std::vector<unsigned char> blend(N, 0);
  for (std::size_t i = 0; i < N; ++i) blend[i] = mesh.nodeKind[i] == NodeKind::Face ? 1 : 0;
  for (std::size_t e = 0; e < E; ++e) {
    const std::int32_t* nd = mesh.elementNodes(e);
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const std::size_t i = static_cast<std::size_t>(nd[k]);
      if (mesh.nodeFace[i] != mesh.elemFace[e]) blend[i] = 0;
    }
  }
  std::vector<Vec2> move(N, Vec2::Zero());
  for (std::size_t i = 0; i < N; ++i)
    if (blend[i]) {
      const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.nodeFace[i])];
      move[i] = s.unwrapNear(result.uv[i], input.uv[i]) - input.uv[i];
    }
  std::vector<double> share(N, 1.0);
  // Puts node i at `share[i]` of its move (0 when it cannot be).
  auto place = [&](std::size_t i) {
    if (share[i] >= 1.0) {
      mesh.xyz[i] = result.xyz[i];
      mesh.uv[i] = result.uv[i];
      if (!mesh.nodeT.empty()) mesh.nodeT[i] = result.nodeT[i];
      return;
    }
    if (share[i] > 0.0 && blend[i]) {
      const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.nodeFace[i])];
      const Vec2 w = s.wrap(input.uv[i] + share[i] * move[i]);
      if (w.allFinite() && s.contains(w.x(), w.y())) {
        mesh.uv[i] = w;
        mesh.xyz[i] = s.value(w.x(), w.y());
        return;
      }
    }
    share[i] = 0.0;
    mesh.xyz[i] = input.xyz[i];
    mesh.uv[i] = input.uv[i];
    if (!mesh.nodeT.empty()) mesh.nodeT[i] = input.nodeT[i];
  };
  auto cornerParameters = [&] {
    for (std::size_t e = 0; e < E; ++e) {
      const std::size_t off = static_cast<std::size_t>(mesh.elemOffset[e]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const std::size_t i = static_cast<std::size_t>(nd[k]);
        mesh.cornerUV[off + k] = share[i] >= 1.0 ? result.cornerUV[off + k]
                                                 : input.cornerUV[off + k] + share[i] * move[i];
      }
    }
  };
  // (No corner floor: no corner measure.)
  const bool cornersCount = cornerFloor > -std::numeric_limits<double>::infinity();
  auto cornersOf = [&] {
    return cornersCount ? cornerQuality(mesh, measure) : std::vector<double>(E, 0.0);
  };
  auto isBelow = [&](const MeshQuality& mq, const std::vector<double>& ratio,
                     const std::vector<double>& corners, std::size_t e) {
    return (wasValid[e] && mq.invalid(e)) || ratio[e] < ratioFloor ||
           mq.quality[e] < qualityFloor || corners[e] < cornerFloor;
  };
  auto anyBelow = [&](const MeshQuality& mq) {
    const std::vector<double> ratio = elementJacobianRatio(mesh);
    const std::vector<double> corners = cornersOf();
    for (std::size_t e = 0; e < E; ++e)
      if (isBelow(mq, ratio, corners, e)) return true;
    return false;
  };
  *q = measureQuality(mesh, measure);
  if (!anyBelow(*q)) return 0;

  // The same share for every node.
  detail::MeshPositions uniform;
  MeshQuality qUniform;
  for (int eighths = uniformToo ? 7 : 0; eighths > 0; --eighths) {
    std::fill(share.begin(), share.end(), eighths / 8.0);
    for (std::size_t i = 0; i < N; ++i) place(i);
    cornerParameters();
    qUniform = measureQuality(mesh, measure);
    if (!anyBelow(qUniform)) {
      uniform = detail::MeshPositions::of(mesh);
      break;
    }
  }
  const double meanUniform = uniform.empty() ? -1.0 : mean(elementJacobianRatio(mesh));

  // Element by element.
  std::fill(share.begin(), share.end(), 1.0);
  result.copyTo(mesh);
  *q = measureQuality(mesh, measure);
  std::vector<double> ratio = elementJacobianRatio(mesh);
  std::vector<double> corners = cornersOf();
  // The elements of each node: after a cut only theirs are measured again.
  const detail::Incidence inc = detail::buildIncidence(mesh);
  bool cutAny = false;
  std::vector<unsigned char> again(E, 0);
  for (;;) {
    std::vector<unsigned char> cut(N, 0);
    bool any = false;
    for (std::size_t e = 0; e < E; ++e) {
      if (!isBelow(*q, ratio, corners, e)) continue;
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const std::size_t i = static_cast<std::size_t>(nd[k]);
        if (share[i] > 0.0 && !cut[i]) cut[i] = 1, any = true;
      }
    }
    if (!any) break;
    cutAny = true;
    std::fill(again.begin(), again.end(), 0);
    for (std::size_t i = 0; i < N; ++i)
      if (cut[i]) {
        share[i] = share[i] > 0.1 ? 0.5 * share[i] : 0.0;
        place(i);
        for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p)
          again[static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)])] = 1;
      }
    cornerParameters();
    for (std::size_t e = 0; e < E; ++e) {
      if (!again[e]) continue;
      storeElementQuality(*q, e, elementQuality(mesh, e, measure, mesh.surfaces));
      ratio[e] = jacobianRatioOf(mesh, e);
    }
    if (cornersCount) corners = cornersOf();
  }
  if (cutAny) *q = measureQuality(mesh, measure);  // (its statistics)
  const std::size_t invalidLocal = invalidCount(*q);
  if (!uniform.empty() &&
      (invalidCount(qUniform) < invalidLocal || (invalidCount(qUniform) == invalidLocal &&
                                                 meanUniform > mean(elementJacobianRatio(mesh))))) {
    uniform.copyTo(mesh);
    *q = qUniform;
  }
  std::size_t changed = 0;
  for (std::size_t i = 0; i < N; ++i) changed += result.xyz[i] != mesh.xyz[i] ? 1 : 0;
  return changed;
}

}  // namespace

/// What straightenCurved did: its run's sweeps, how many faces took its result (0: the mesh
/// is as it was) and the quality of the mesh it leaves.
struct Straightened {
  int sweeps = 0;
  bool cancelled = false;  // (the mesh as it was)
  std::size_t faces = 0;
  MeshQuality quality;
};

/// The high-order nodes inside the faces moved towards the straight-sided triangles on the
/// elements' corners (straightSidedTargets: the distortion of each high-order triangle against
/// its straight-sided one, size included), with the corners, the nodes on CAD edges and the
/// nodes of invalid elements and of elements without such a target (quad8) held. The integral
/// measure and the untangling curve elements further than the surface asks; this takes it back
/// where it can. A face takes the result when none of its elements valid before is invalid
/// after, none is tangled that was not, its mean Jacobian ratio rises and its smallest ratio
/// and quality stay above the mesh's smallest before; the other
/// faces' nodes go back (a node inside a face moves the elements of that face only). Where a
/// face's mean ratio rose but the rest did not hold, the moves are cut back element by
/// element first (keepNoWorse).
Straightened straightenCurved(SurfaceMesh& mesh, const OptimizeOptions& inner,
                              const PlanarMeasure& measure, const ProgressCallback& progress) {
  Straightened out;
  const MeshQuality qa = measureQuality(mesh, measure);
  OptimizeOptions run = inner;
  run.topology = "none";  // (the faces' results are merged node by node)
  run.highOrderTargets = straightSidedTargets(mesh);
  // Held: corners, nodes not inside a face, and every node of an invalid element or of an
  // element without a straight-sided target (quad8, or a triangle whose corners are degenerate
  // or wound against its normal: the measure would be the equilateral's).
  run.fixedNodes.assign(mesh.nodeCount(), 0);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const std::int32_t* nd = mesh.elementNodes(e);
    const bool hold = qa.invalid(e) || !isHighOrderTriangle(mesh.elemType[e]) ||
                      run.highOrderTargets[e](0, 0) == 0.0;
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (hold || k < cornerCount(mesh.elemType[e]) || mesh.nodeKind[j] != NodeKind::Face)
        run.fixedNodes[j] = 1;
    }
  }
  bool any = false;
  for (std::size_t i = 0; i < mesh.nodeCount() && !any; ++i) any = !run.fixedNodes[i];
  if (!any) return out;
  const detail::MeshPositions before = detail::MeshPositions::of(mesh);
  const std::vector<double> ratioA = elementJacobianRatio(mesh);
  const OptimizeResult r = optimizeMesh(mesh, run, progress, &qa.stats);
  out.sweeps = r.sweeps;
  if (r.reason == StopReason::Cancelled) {
    before.copyTo(mesh);
    out.cancelled = true;
    return out;
  }
  // Face by face. (A face's smallest ratio and quality may drop, not below the mesh's smallest
  // before: a face's own smallest is never lower than that.)
  const std::size_t nf = mesh.surfaces.size();
  const double lowestRatio = smallest(ratioA), lowestQ = smallest(qa.quality);
  std::vector<double> sumA(nf, 0.0);
  for (std::size_t e = 0; e < mesh.elementCount(); ++e)
    sumA[static_cast<std::size_t>(mesh.elemFace[e])] += ratioA[e];
  std::vector<unsigned char> take(nf, 0);
  // Which faces take the mesh as it is; whether a face whose mean ratio rose does not.
  auto decide = [&] {
    const MeshQuality qp = measureQuality(mesh, measure);
    const std::vector<double> ratioP = elementJacobianRatio(mesh);
    std::vector<double> sumP(nf, 0.0);
    std::vector<unsigned char> refuse(nf, 0);
    for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
      const std::size_t f = static_cast<std::size_t>(mesh.elemFace[e]);
      const bool invalidA = qa.invalid(e), invalidP = qp.invalid(e);
      if ((invalidP && !invalidA) || (qp.tangled[e] && !qa.tangled[e]) || ratioP[e] < lowestRatio ||
          qp.quality[e] < lowestQ)
        refuse[f] = 1;
      sumP[f] += ratioP[e];
    }
    bool refusedGain = false;
    out.faces = 0;
    for (std::size_t f = 0; f < nf; ++f) {
      take[f] = !refuse[f] && sumP[f] > sumA[f];
      refusedGain = refusedGain || (refuse[f] && sumP[f] > sumA[f]);
      out.faces += take[f];
    }
    return refusedGain;
  };
  // A face whose ratios rose but where an element fell below the floors or became invalid:
  // the moves at fault are cut back element by element (keepNoWorse), then the faces decide
  // again. (One element kept a face from taking the result: on Gmsh's raw order-2 propeller,
  // 21 of 76 faces, mean ratio 0.768; cut back, 67 faces take it, 0.787.)
  if (decide()) {
    MeshQuality qc;
    keepNoWorse(mesh, before, validIn(qa), lowestRatio, lowestQ,
                -std::numeric_limits<double>::infinity(), measure, &qc, false);
    decide();
  }
  // The positions: the run's for a node whose elements all lie on faces that take it (a node
  // inside a face is only in elements of that face, as a rule), the ones before elsewhere.
  std::vector<unsigned char> moved(mesh.nodeCount(), 0);
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i) moved[i] = !run.fixedNodes[i];
  for (std::size_t e = 0; e < mesh.elementCount(); ++e)
    if (!take[static_cast<std::size_t>(mesh.elemFace[e])])
      for (int k = 0; k < mesh.elementSize(e); ++k)
        moved[static_cast<std::size_t>(mesh.elementNodes(e)[k])] = 0;
  takePositions(mesh, before, moved, 0);
  if (out.faces == 0) {
    out.quality = qa;
    return out;
  }
  // What is returned is checked whole: no element valid before invalid or newly tangled, no
  // smaller ratio or quality than the smallest before; else the mesh as it was.
  out.quality = measureQuality(mesh, measure);
  const MeshQuality& qm = out.quality;
  std::size_t invalidM = 0;
  bool ok = !judge(mesh, qa, qm, &invalidM) &&
            smallest(elementJacobianRatio(mesh)) >= lowestRatio && smallest(qm.quality) >= lowestQ;
  for (std::size_t e = 0; e < mesh.elementCount() && ok; ++e) ok = !qm.tangled[e] || qa.tangled[e];
  if (!ok) {
    before.copyTo(mesh);
    out.faces = 0;
    out.quality = qa;
  }
  return out;
}

bool hasCurvedElements(const SurfaceMesh& mesh) {
  for (ElementType t : mesh.elemType)
    if (t != ElementType::Tri3 && t != ElementType::Quad4) return true;
  return false;
}

/// The repair runs (steps 3 and 5) give up untangling after one cycle of ε without progress
/// (OptimizeOptions::giveUpStallCycles), not two: they start from corners the linear run
/// untangled with the full patience, and on Gmsh's raw order-3 propeller and nist_pmi_1 and
/// order-2 solid56 the second cycle took a quarter to a half of the sweeps and repaired
/// nothing (bench/history/2026-12.md).
constexpr int kRepairStallCycles = 3;

OptimizeResult optimizeReference(SurfaceMesh& mesh, const OptimizeOptions& opt,
                                 const ProgressCallback& progress, const QualityStats* before) {
  const auto t0 = std::chrono::steady_clock::now();
  const PlanarMeasure& measure = measureByName(opt.measure);
  mesh.validate();
  const MeshQuality q0 = measureQuality(mesh, measure);
  const double ratio0 = smallest(elementJacobianRatio(mesh));
  const double corner0 = smallest(cornerQuality(mesh, measure));
  const std::size_t invalid0 = invalidCount(q0);
  const detail::MeshPositions original = detail::MeshPositions::of(mesh);
  OptimizeOptions inner = opt;
  inner.highOrder = "integral";
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  // The stages report their sweeps one after the other: sweep numbers go on from the sweeps
  // of the stages before.
  int done = 0, stage = 0;
  const ProgressCallback staged =
      detail::renumbered(progress, done, 0, [&stage](int) { return stage; });
  auto integral = [&] {
    ++stage;
    original.copyTo(mesh);
    OptimizeResult r = optimizeMesh(mesh, inner, staged, &q0.stats);
    if (before) r.before = *before;
    r.sweeps += done;
    done = r.sweeps;
    r.seconds = seconds();
    return r;
  };

  // 1. The corners.
  SurfaceMesh L = cornerMesh(mesh);
  const OptimizeResult r1 = optimizeMesh(L, inner, staged);
  done += r1.sweeps;
  OptimizeResult res;
  res.before = before ? *before : q0.stats;
  res.threadsUsed = r1.threadsUsed;
  if (r1.reason == StopReason::Cancelled) {
    res.after = q0.stats;
    res.sweeps = done;
    res.reason = StopReason::Cancelled;
    res.seconds = seconds();
    return res;
  }
  // 2. The high-order nodes at their straight-sided places.
  placeStraightSided(mesh, L);
  // 3. What that leaves invalid (and the high-order nodes on CAD edges), with the nodes of
  // the elements within `rings` rings around them; a second try with 3 rings when the first
  // makes an element of the input invalid.
  const MeshQuality q1 = measureQuality(mesh, measure);
  const detail::MeshPositions placed = detail::MeshPositions::of(mesh);
  OptimizeResult r2;
  bool ran2 = false;
  MeshQuality q2 = q1;
  std::size_t invalid2 = 0;
  bool madeInvalid = judge(mesh, q0, q2, &invalid2);
  for (int rings : {1, 3}) {
    if (ran2 && !madeInvalid) break;
    bool any = false;
    OptimizeOptions rest = inner;
    rest.giveUpStallCycles = kRepairStallCycles;
    rest.fixedNodes = heldOutside(mesh, q1, rings, &any);
    if (!any) break;
    placed.copyTo(mesh);
    try {
      ++stage;
      r2 = optimizeMesh(mesh, rest, staged, &q1.stats);
    } catch (...) {
      original.copyTo(mesh);
      throw;
    }
    ran2 = true;
    done += r2.sweeps;
    if (r2.reason == StopReason::Cancelled) {
      original.copyTo(mesh);
      res.after = q0.stats;
      res.sweeps = done;
      res.reason = StopReason::Cancelled;
      res.seconds = seconds();
      return res;
    }
    q2 = measureQuality(mesh, measure);
    madeInvalid = judge(mesh, q0, q2, &invalid2);
  }
  // 4. Never worse: no element valid in the input invalid, no more invalid elements, no lower
  // minimum quality without tangled elements in the input (the monotone mode's guarantee), on
  // a valid input no lower minimum Jacobian ratio — else the integral mode. Where
  // elements stay invalid, the integral mode's result when it leaves fewer.
  const double ratio2 = smallest(elementJacobianRatio(mesh));
  // (Rounding aside: an affine element's Jacobian ratio is 1 within 1e-15 or so.)
  constexpr double kRounding = 1e-9;
  const bool worse =
      madeInvalid || invalid2 > invalid0 ||
      (q0.stats.tangled == 0 && q2.stats.min < q0.stats.min - kRounding) ||
      (invalid0 == 0 && (ratio2 < ratio0 - kRounding ||
                         smallest(cornerQuality(mesh, measure)) < corner0 - kRounding));
  // On a valid input, a result worse than it is cut back (keepNoWorse): what it makes invalid,
  // or lowers below the input's smallest Jacobian ratio or quality, takes less of its move or
  // goes back. Only when that leaves the input as it was is the integral mode tried, cut back
  // the same way (it keeps the minimum quality and every valid element valid, not the
  // Jacobian ratio). On an invalid input, the integral mode's result.
  std::size_t backRef = 0;
  bool retangled = false;
  if (worse) {
    const std::vector<unsigned char> tangledBefore = q2.tangled;
    const std::vector<unsigned char> wasValid = validIn(q0);
    constexpr double kNone = -std::numeric_limits<double>::infinity();
    const bool valid = invalid0 == 0;
    backRef = keepNoWorse(mesh, original, wasValid, valid ? ratio0 - kRounding : kNone,
                          q0.stats.tangled == 0 ? q0.stats.min - kRounding : kNone,
                          valid ? corner0 - kRounding : kNone, measure, &q2);
    invalid2 = invalidCount(q2);
    // (An element the cut-back tangles again, as in the input, was not weighed by the run:
    // the integral mode's result instead.)
    for (std::size_t e = 0; e < mesh.elementCount() && !retangled; ++e)
      retangled = q2.tangled[e] && !tangledBefore[e];
  }
  const bool moved = movedCount(mesh, original) > 0;
  // The integral mode's result (in `mesh`, `alt` its result, qI its quality) with the reference
  // result `mine` (quality qMine) put back away from mine's invalid elements (mergeAroundInvalid,
  // 1, 2 then 3 rings): kept when no element valid in the input is invalid, the elements
  // tangled are some of the integral result's, no more are invalid, and the minimum quality
  // holds where the input has no tangled element. The integral mode curves every element;
  // this keeps the straight-sided reference wherever it did as well.
  auto preferMerged = [&](OptimizeResult& alt, const detail::MeshPositions& mine,
                          const MeshQuality& qMine, const MeshQuality& qI) {
    const detail::MeshPositions theirs = detail::MeshPositions::of(mesh);
    const std::size_t invalidI = invalidCount(qI);
    for (int rings = 1; rings <= 3; ++rings) {
      mergeAroundInvalid(mesh, mine, qMine, rings);
      const MeshQuality qm = measureQuality(mesh, measure);
      std::size_t invalidM = 0;
      bool ok = !judge(mesh, q0, qm, &invalidM) && invalidM <= invalidI &&
                (q0.stats.tangled != 0 || qm.stats.min >= q0.stats.min - kRounding);
      for (std::size_t e = 0; e < mesh.elementCount() && ok; ++e)
        ok = !qm.tangled[e] || qI.tangled[e];
      if (ok) {
        alt.after = qm.stats;
        alt.movedNodes = movedCount(mesh, original);
        keepStillTangled(alt, qm);
        return;
      }
      theirs.copyTo(mesh);
    }
  };
  // 6. The high-order nodes of a result moved towards the straight-sided triangles of its
  // corners, face by face where that keeps every element's validity and raises the face's
  // mean Jacobian ratio without lowering the minimum ratio or quality (straightenCurved).
  auto straighten = [&](OptimizeResult& r) {
    ++stage;
    const Straightened st = straightenCurved(mesh, inner, measure, staged);
    done += st.sweeps;
    r.sweeps = done;
    r.seconds = seconds();
    if (st.cancelled) {  // the input, unchanged, as every cancelled run leaves it
      original.copyTo(mesh);
      r.after = q0.stats;
      r.reason = StopReason::Cancelled;
      r.movedNodes = 0;
      return;
    }
    if (st.faces == 0) return;
    r.after = st.quality.stats;
    r.movedNodes = movedCount(mesh, original);
    keepStillTangled(r, st.quality);
  };
  if (worse && (invalid2 > invalid0 || !moved || retangled)) {
    const detail::MeshPositions mine = detail::MeshPositions::of(mesh);
    OptimizeResult alt = integral();
    if (alt.reason == StopReason::Cancelled) return alt;
    if (invalid0 > 0) {
      preferMerged(alt, mine, q2, measureQuality(mesh, measure));
      straighten(alt);
      return alt;
    }
    MeshQuality qa;
    const std::size_t back = keepNoWorse(
        mesh, original, std::vector<unsigned char>(mesh.elementCount(), 1), ratio0 - kRounding,
        q0.stats.min - kRounding, corner0 - kRounding, measure, &qa);
    if (back > 0) {
      alt.after = qa.stats;
      alt.restoredNodes += back;
      alt.movedNodes = movedCount(mesh, original);
    }
    straighten(alt);
    return alt;
  }
  // 5. Where elements stay invalid, the integral mode on them and the elements within
  // kStep5Rings rings around them, from the input's positions there, the rest held where step 3
  // left it; kept when it leaves fewer. (Not when every element left invalid folds where no
  // node may move: nothing can change those.)
  constexpr int kStep5Rings = 3;
  OptimizeOptions around = inner;
  around.giveUpStallCycles = kRepairStallCycles;
  bool anyAround = false;
  if (invalid2 > 0 && ran2 && !allHeld(q2, r2))
    around.fixedNodes = heldOutside(mesh, q2, kStep5Rings, &anyAround);
  if (anyAround) {
    const detail::MeshPositions mine = detail::MeshPositions::of(mesh);
    takePositions(mesh, original, around.fixedNodes, 0);  // (the free nodes: the input's)
    ++stage;
    OptimizeResult alt = optimizeMesh(mesh, around, staged);
    alt.before = res.before;
    alt.sweeps += done;
    alt.seconds = seconds();
    alt.movedNodes = movedCount(mesh, original);
    done = alt.sweeps;
    if (alt.reason == StopReason::Cancelled) {  // the input, unchanged
      original.copyTo(mesh);
      alt.after = q0.stats;
      alt.movedNodes = 0;
      return alt;
    }
    const MeshQuality qI = measureQuality(mesh, measure);
    if (invalidCount(qI) < invalid2) {
      preferMerged(alt, mine, q2, qI);
      straighten(alt);
      return alt;
    }
    mine.copyTo(mesh);
  }

  res.after = q2.stats;
  res.sweeps = done;
  res.reason = ran2 ? r2.reason : r1.reason;
  res.initialObjective = r1.initialObjective;
  res.finalObjective = ran2 ? r2.finalObjective : r1.finalObjective;
  res.movedNodes = movedCount(mesh, original);
  res.patchUntanglings = r1.patchUntanglings + (ran2 ? r2.patchUntanglings : 0);
  res.straightenedElements = ran2 ? r2.straightenedElements : 0;
  res.restoredNodes = r1.restoredNodes + (ran2 ? r2.restoredNodes : 0) + backRef;
  res.heldAcross = r1.heldAcross || (ran2 && r2.heldAcross);
  if (ran2) {
    res.tangledUnmovable = r2.tangledUnmovable;
    res.tangledMovable = r2.tangledMovable;
    res.warnings = r2.warnings;
  }
  if (backRef > 0) keepStillTangled(res, q2);  // (the cut-back tangles none anew)
  res.seconds = seconds();
  straighten(res);
  return res;
}

}  // namespace surfmesh
