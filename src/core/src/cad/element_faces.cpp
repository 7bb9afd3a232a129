// SurfMesh — the CAD recovery: step 2, the face of every element (see cad_bridge.h).
#include "recovery.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace surfmesh::cad_detail {

namespace {

/// Step 2 for element e: the face shared by all its nodes (the nearest when several are), else
/// the face its nodes are each within the tolerance (or reach) of.
void chooseElementFace(Recovery& r, const std::vector<std::vector<int>>& nodeFaces, std::size_t e,
                       Projector& pr, std::vector<unsigned char>& offFace,
                       std::vector<std::vector<int>>& doubtfulFaces) {
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const double tol = r.tol;
  const std::vector<double>& reach = r.reach;
  const std::vector<std::vector<FaceHit>>& hits = r.hits();
  std::vector<std::int32_t>& elemFace = r.elemFace;
  // Kept from element to element (no allocation). cornerFaces: the faces every corner is
  // near, for an element with side or interior nodes (empty otherwise).
  thread_local std::vector<int> common, tmp, cornerFaces;
  const std::int32_t* nd = input.conn.data() + offsets[e];
  const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
  const int nc = cornerCount(input.types[e]);
  cornerFaces.clear();
  common = nodeFaces[static_cast<std::size_t>(nd[0])];
  for (int k = 1; k < nn && !common.empty(); ++k) {
    if (k == nc) cornerFaces = common;
    const auto& f = nodeFaces[static_cast<std::size_t>(nd[k])];
    tmp.clear();
    std::set_intersection(common.begin(), common.end(), f.begin(), f.end(),
                          std::back_inserter(tmp));
    common.swap(tmp);
  }
  if (common.empty()) {
    // No face is among every node's nearest ones: next to a CAD edge whose tolerance is as
    // large as the elements, the mesher's nodes may sit off both faces, some nearer to
    // one, some to the other. The element goes on the face of its nodes' candidates
    // farthest from none of them by more than the tolerance (nearest in its worst node).
    // A high-order side or interior node may be as far as its reach (kHighOrderReach):
    // outside its face's trimmed domain, it may be nearer to another face. Such an element
    // goes on a face its corners share when there is one: the corners are where the
    // mesher put the element, a side node off its face is nearer to some other face
    // (Gmsh's second-order triangle along a CAD edge of a propeller blade, with a side node
    // across a concave boundary, went on the face beyond that edge and moved its edge
    // nodes into it).
    double bestWorst = kInf;
    bool bestWithinTol = false;
    auto pick = [&](const std::vector<int>& faces) {
      for (int f : faces) {
        double worst = 0.0;
        bool ok = true, withinTol = true;
        for (int k = 0; k < nn && ok; ++k) {
          const std::size_t n = static_cast<std::size_t>(nd[k]);
          const double bound = std::max(tol, reach[n]);
          const double d = pr.faceDistance(f, input.nodes[n], bound).dist;
          ok = d <= bound;
          withinTol = withinTol && d <= tol;
          worst = std::max(worst, d);
        }
        if (ok && worst < bestWorst) {
          bestWorst = worst;
          bestWithinTol = withinTol;
          elemFace[e] = f;
        }
      }
    };
    pick(cornerFaces);
    if (elemFace[e] < 0) {  // no face the corners share holds the side nodes within reach
      tmp.clear();
      for (int k = 0; k < nn; ++k) {
        const auto& f = nodeFaces[static_cast<std::size_t>(nd[k])];
        tmp.insert(tmp.end(), f.begin(), f.end());
      }
      std::sort(tmp.begin(), tmp.end());
      tmp.erase(std::unique(tmp.begin(), tmp.end()), tmp.end());
      pick(tmp);
    }
    offFace[e] = elemFace[e] >= 0 && bestWithinTol;
    return;
  }
  if (common.size() == 1) {
    elemFace[e] = common[0];
    return;
  }
  // Several faces qualify (small elements at an edge, faces tangent to each other, thin
  // walls): the face nearest to the element's nodes and to its centroid, until the mesh's
  // winding says otherwise (settleDoubtfulFaces). But where the element's plane stands across
  // that face's normal (|cos| < 0.5 at the centroid's projection) and lies along another
  // candidate's (|cos| ≥ 0.9), it goes on that one: an element with its corners on the CAD edge
  // between two faces at an angle (and on its vertices) can have its centroid nearer the face
  // it stands across, where it would be tangled (Gmsh's curvature-sized mesh of the bottle, as
  // meshed and after sliding). A flat element (no plane) keeps the nearest face.
  doubtfulFaces[e] = common;
  Vec3 c = Vec3::Zero();
  for (int k = 0; k < nn; ++k) c += input.nodes[static_cast<std::size_t>(nd[k])];
  c /= nn;
  auto X = [&](int k) { return input.nodes[static_cast<std::size_t>(nd[k])]; };
  const Vec3 g = cornerPlaneNormal(input, nd, nc);
  double side2 = 0.0;
  for (int k = 0; k < nc; ++k) side2 = std::max(side2, (X((k + 1) % nc) - X(k)).squaredNorm());
  const bool hasPlane = g.allFinite() && g.norm() > 1e-8 * side2;
  double best = kInf, bestAlong = kInf, bestCos = kNaN;
  int along = -1;
  for (int f : common) {
    const FaceHit hc = pr.faceDistance(f, c, kInf);
    double d = hc.dist;
    for (int k = 0; k < nn; ++k)
      for (const FaceHit& h : hits[static_cast<std::size_t>(nd[k])])
        if (h.face == f) d += h.dist;
    double cosAbs = kNaN;
    if (hasPlane && hc.hasUV) {
      const Vec3 n = pr.surfaceCopy(f).normal(hc.uv.x(), hc.uv.y());
      if (n.allFinite() && n.norm() > 0.0) cosAbs = std::abs(g.dot(n)) / (g.norm() * n.norm());
    }
    if (d < best) {
      best = d;
      bestCos = cosAbs;
      elemFace[e] = f;
    }
    if (cosAbs >= 0.9 && d < bestAlong) {
      bestAlong = d;
      along = f;
    }
  }
  if (bestCos < 0.5 && along >= 0) elemFace[e] = along;
  if (elemFace[e] < 0) elemFace[e] = common[0];
}

}  // namespace

void assignElementFaces(Recovery& r, BridgeReport& report) {
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const std::size_t N = r.N, E = r.E;
  const std::vector<std::vector<FaceHit>>& hits = r.hits();
  ProjectorPool& projectors = *r.projectors;
  std::vector<std::vector<int>> nodeFaces(N);  // C(n), sorted
  for (std::size_t n = 0; n < N; ++n) {
    for (const FaceHit& h : hits[n]) nodeFaces[n].push_back(h.face);
    std::sort(nodeFaces[n].begin(), nodeFaces[n].end());
    nodeFaces[n].erase(std::unique(nodeFaces[n].begin(), nodeFaces[n].end()), nodeFaces[n].end());
  }
  r.elemFace.assign(E, -1);
  std::vector<std::int32_t>& elemFace = r.elemFace;
  // In parallel (the distances of several faces to an element's nodes and centroid may need
  // global projections). offFace marks an element put on a face its nodes are each within the
  // tolerance of; one left on no face (elemFace −1) is an error, reported below for the first.
  std::vector<unsigned char> offFace(E, 0);
  // The faces of an element whose nodes are all within the tolerance of several (settled by
  // the mesh's winding below); empty for the others.
  std::vector<std::vector<int>> doubtfulFaces(E);
  parallelFor(E, projectors, [&](std::size_t e, Projector& pr) {
    chooseElementFace(r, nodeFaces, e, pr, offFace, doubtfulFaces);
  });
  std::size_t offFaceElements = 0, firstOffFace = 0;
  for (std::size_t e = 0; e < E; ++e) {
    if (elemFace[e] < 0) {
      const std::int32_t* nd = input.conn.data() + offsets[e];
      const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
      Diagnostic d;
      d.code = code::kElementOnNoFace;
      d.count = 1;
      d.elements = {static_cast<std::int64_t>(e)};
      d.format = "element {element} lies on no single face of the shape (its nodes share no face):";
      for (int k = 0; k < nn; ++k) {
        d.nodes.push_back(nd[k]);
        d.format += " node {node" + std::to_string(k) + "} on " +
                    faceNames(nodeFaces[static_cast<std::size_t>(nd[k])]) + (k + 1 < nn ? ";" : "");
      }
      d.format += ". The mesh must conform to the B-rep faces (no element across a CAD edge).";
      fail(std::move(d));
    }
    if (offFace[e] && offFaceElements++ == 0) firstOffFace = e;
  }
  r.manifoldEdges = manifoldEdgePairs(input, offsets);
  settleDoubtfulFaces(r.manifoldEdges, doubtfulFaces, elemFace);
  if (offFaceElements) {
    Diagnostic d;
    d.code = code::kElementsOffFace;
    d.count = static_cast<std::int64_t>(offFaceElements);
    d.elements = {static_cast<std::int64_t>(firstOffFace)};
    d.faces = {elemFace[firstOffFace]};
    d.format =
        "{count} element(s) whose nodes are each nearest to another face (next to a CAD edge "
        "with a tolerance as large as the elements) were put on the face all their nodes are "
        "within the tolerance of (e.g. element {element} on {face})";
    report.warn(std::move(d));
  }
}

}  // namespace surfmesh::cad_detail
