// SurfMesh — the CAD recovery: step 3, the class of every node (vertex, edge or face; see
// cad_bridge.h).
#include "recovery.h"

#include <BRep_Tool.hxx>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace surfmesh::cad_detail {

void meshTopology(Recovery& r) {
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const std::size_t N = r.N, E = r.E;
  const std::vector<std::int32_t>& elemFace = r.elemFace;
  // Faces of each node's elements, mesh boundary nodes, shortest incident mesh edge.
  std::vector<std::vector<int>> elemFacesOfNode(N);
  std::vector<double> hmin(N, kInf);
  std::vector<unsigned char> onMeshBoundary(N, 0);
  // Per node: bit 0 a corner of some element, bit 1 a high-order node of some element.
  std::vector<unsigned char> nodeRoles(N, 0);
  std::vector<std::array<std::int32_t, 2>> sideEnds(N, {-1, -1});
  {
    // Mesh edges (corner to corner) counted through buckets by their smaller node: an edge
    // used by one element only is on the mesh's boundary.
    struct EdgeRef {
      std::int32_t other;  // the larger node
      std::int32_t elem;
      std::int32_t side;  // k: the edge from corner k to corner k + 1
    };
    std::vector<std::size_t> start(N + 1, 0);
    for (std::size_t e = 0; e < E; ++e) {
      const std::int32_t* nd = input.conn.data() + offsets[e];
      const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
      const ElementEdges ee = elementEdges(input.types[e]);
      for (int k = 0; k < nn; ++k) {
        // Each face once per node (consecutive elements mostly share their face).
        auto& l = elemFacesOfNode[static_cast<std::size_t>(nd[k])];
        if (l.empty() || l.back() != elemFace[e]) l.push_back(elemFace[e]);
        nodeRoles[static_cast<std::size_t>(nd[k])] |= k < ee.corners ? 1u : 2u;
      }
      for (int k = 0; k < ee.corners; ++k) {
        const std::int32_t a = nd[k], b = nd[(k + 1) % ee.corners];
        ++start[static_cast<std::size_t>(std::min(a, b)) + 1];
        const double len =
            (input.nodes[static_cast<std::size_t>(a)] - input.nodes[static_cast<std::size_t>(b)])
                .norm() /
            (ee.perEdge + 1);
        hmin[static_cast<std::size_t>(a)] = std::min(hmin[static_cast<std::size_t>(a)], len);
        hmin[static_cast<std::size_t>(b)] = std::min(hmin[static_cast<std::size_t>(b)], len);
        for (int j = 0; j < ee.perEdge; ++j) {
          const std::size_t m = static_cast<std::size_t>(nd[ee.corners + k * ee.perEdge + j]);
          hmin[m] = std::min(hmin[m], len);
          if (sideEnds[m][0] < 0) sideEnds[m] = {a, b};
        }
      }
    }
    for (std::size_t i = 0; i < N; ++i) start[i + 1] += start[i];
    std::vector<EdgeRef> refs(start[N]);
    {
      std::vector<std::size_t> fill(start.begin(), start.end() - 1);
      for (std::size_t e = 0; e < E; ++e) {
        const std::int32_t* nd = input.conn.data() + offsets[e];
        const int nc = elementEdges(input.types[e]).corners;
        for (int k = 0; k < nc; ++k) {
          const std::int32_t a = nd[k], b = nd[(k + 1) % nc];
          refs[fill[static_cast<std::size_t>(std::min(a, b))]++] = {
              std::max(a, b), static_cast<std::int32_t>(e), k};
        }
      }
    }
    for (std::size_t a = 0; a < N; ++a) {
      const auto first = refs.begin() + static_cast<std::ptrdiff_t>(start[a]);
      const auto last = refs.begin() + static_cast<std::ptrdiff_t>(start[a + 1]);
      std::sort(first, last, [](const EdgeRef& x, const EdgeRef& y) { return x.other < y.other; });
      for (auto it = first; it != last;) {
        auto run = it + 1;
        while (run != last && run->other == it->other) ++run;
        if (run - it == 1) {  // used once: a boundary edge
          const std::size_t e = static_cast<std::size_t>(it->elem);
          const std::int32_t* nd = input.conn.data() + offsets[e];
          const ElementEdges ee = elementEdges(input.types[e]);
          onMeshBoundary[a] = 1;
          onMeshBoundary[static_cast<std::size_t>(it->other)] = 1;
          for (int j = 0; j < ee.perEdge; ++j)
            onMeshBoundary[static_cast<std::size_t>(nd[ee.corners + it->side * ee.perEdge + j])] =
                1;
        }
        it = run;
      }
    }
    for (auto& l : elemFacesOfNode) {
      std::sort(l.begin(), l.end());
      l.erase(std::unique(l.begin(), l.end()), l.end());
    }
  }
  r.elemFacesOfNode = std::move(elemFacesOfNode);
  r.hmin = std::move(hmin);
  r.onMeshBoundary = std::move(onMeshBoundary);
  r.nodeRoles = std::move(nodeRoles);
  r.sideEnds = std::move(sideEnds);
}

namespace {

/// Step 3: the class of each node (vertex, edge or face) from the faces of its elements, its
/// hint and the mesh's boundary, with what the rules for one node share.
struct NodeClassifier {
  NodeClassifier(Recovery& r, BridgeReport& report)
      : S(r.S),
        input(r.input),
        tol(r.tol),
        diag(r.diag),
        hits(r.hits()),
        forced(r.search->forced),
        forcedId(r.search->forcedId),
        forcedT(r.search->forcedT),
        edgeBoxes(r.edgeBoxes),
        hmin(r.hmin),
        onMeshBoundary(r.onMeshBoundary),
        nodeRoles(r.nodeRoles),
        sideEnds(r.sideEnds),
        elemFacesOfNode(r.elemFacesOfNode),
        nodeUV(r.nodeUV),
        isPole(r.isPole),
        proj(r.projectors->slot(0)),  // single-threaded tools for the rest
        report_(report) {}

  const FaceHit* hitOn(std::size_t n, int f) const {
    for (const FaceHit& h : hits[n])
      if (h.face == f) return &h;
    return nullptr;
  }

  void setVertex(std::size_t n, int v) {
    report_.nodeClass[n] = NodeClass::Vertex;
    report_.nodeEntity[n] = v;
    for (int e : S.vertexEdges(v))
      if (S.isDegeneratedEdge(e)) isPole[n] = 1;
  }

  void setFace(std::size_t n, int f) {
    report_.nodeClass[n] = NodeClass::Face;
    report_.nodeEntity[n] = f;
    const FaceHit* h = hitOn(n, f);
    if (h && h->hasUV && h->uv.allFinite()) {
      nodeUV[n] = h->uv;
    } else {
      nodeUV[n] = proj.faceDistance(f, input.nodes[n], kInf).uv;
    }
  }

  /// setFace, but a node whose (u,v) on f lies where the parameterization is degenerate is at
  /// a pole farther than vs from its vertex (Gmsh's curvature-sized meshes put nodes within
  /// 5e-6 of a B-spline's apex, among elements smaller than that, and within 3e-6 of a surface
  /// of revolution's tip next to its seam): on that vertex, fixed where it is as every pole,
  /// whose corner (u,v) each element takes along its other corners. As a face node its (u,v)
  /// there is any point of the singular line, which its elements' corners would not share.
  void setFaceOrPole(std::size_t n, int f) {
    setFace(n, f);
    // (The vertex first: most faces have no degenerated edge, and need no derivative here.)
    const Vec3& p = input.nodes[n];
    int bv = -1;
    double bd = tol;
    for (int e : S.faceEdges(f)) {
      if (!S.isDegeneratedEdge(e)) continue;
      for (int v : S.edgeVertices(e)) {
        const double d = (S.vertexPoint(v) - p).norm();
        if (d <= bd) bv = v, bd = d;
      }
    }
    const Vec2& uv = nodeUV[n];
    if (bv >= 0 && uv.allFinite() && isDegenerate(proj.surfaceCopy(f).d1(uv.x(), uv.y())))
      setVertex(n, bv);
  }

  /// The CAD edge of face f nearest to p among those `accept` takes: its id (−1: none), the
  /// distance and the curve parameter. With a finite `cap`, an edge whose box is farther than
  /// the best so far or than cap is not measured.
  struct NearEdge {
    int edge = -1;
    double distance = kInf, t = 0.0;
  };
  template <class Accept>
  NearEdge nearestEdge(int f, const Vec3& p, Accept accept, double cap = kInf) {
    NearEdge best;
    for (int e : S.faceEdges(f)) {
      if (!accept(e)) continue;
      if (cap < kInf &&
          boxDistance(edgeBoxes[static_cast<std::size_t>(e)], p) > std::min(best.distance, cap))
        continue;
      double t = 0.0;
      const double d = proj.edgeDistance(e, p, &t);
      if (d < best.distance) best = {e, d, t};
    }
    return best;
  }

  // Edge node (or vertex node when at an end of the edge / on a degenerated edge).
  void setEdge(std::size_t n, int e, double t) {
    const double vs = std::min(tol, std::max(0.1 * hmin[n], 1e-9 * diag));
    for (int v : S.edgeVertices(e))
      if ((S.vertexPoint(v) - input.nodes[n]).norm() <= vs || S.isDegeneratedEdge(e)) {
        setVertex(n, v);
        return;
      }
    const auto& ef = S.edgeFaces(e);
    if (ef.size() == 1 && S.isSeam(e, ef[0])) {  // a seam is inside its face
      setFaceOrPole(n, ef[0]);
      return;
    }
    report_.nodeClass[n] = NodeClass::Edge;
    report_.nodeEntity[n] = e;
    report_.nodeParam[n] = t;
  }

  /// Node n (at p): in no element, on the entity of its hint, else by the faces of its
  /// elements.
  void classify(std::size_t n);
  /// A node whose elements all lie on face f: a pole, a face node, or on the mesh's boundary
  /// the nearest CAD edge of f (`vs`: the distance within which it is at a vertex).
  void onOneFace(std::size_t n, int f, const Vec3& p, double vs);
  /// A node of elements on the faces F: their common vertex, else their nearest common edge.
  void onSeveralFaces(std::size_t n, const std::vector<int>& F, const Vec3& p, double vs);
  /// The warnings on the nodes left fixed.
  void warn();
  /// Whether both corners at the ends of high-order node n's side are hinted to CAD edge e or
  /// to one of its vertices (false for an element's interior node).
  bool sideAlongEdge(std::size_t n, int e) const {
    for (std::int32_t c : sideEnds[n]) {
      if (c < 0) return false;
      const std::size_t q = static_cast<std::size_t>(c);
      const bool onEdge = forced[q] == Forced::Edge && forcedId[q] == e;
      const auto& ev = S.edgeVertices(e);
      const bool atVertex =
          forced[q] == Forced::Vertex && std::find(ev.begin(), ev.end(), forcedId[q]) != ev.end();
      if (!onEdge && !atVertex) return false;
    }
    return true;
  }

  const CadShape& S;
  const MeshInput& input;
  const double tol, diag;
  const std::vector<std::vector<FaceHit>>& hits;
  const std::vector<Forced>& forced;
  const std::vector<std::int32_t>& forcedId;
  const std::vector<double>& forcedT;
  const std::vector<Box>& edgeBoxes;
  const std::vector<double>& hmin;
  const std::vector<unsigned char>& onMeshBoundary;
  const std::vector<unsigned char>& nodeRoles;
  const std::vector<std::array<std::int32_t, 2>>& sideEnds;
  const std::vector<std::vector<int>>& elemFacesOfNode;
  std::vector<Vec2>& nodeUV;
  std::vector<unsigned char>& isPole;
  Projector& proj;
  BridgeReport& report_;
  std::size_t unplaced = 0, boundaryNoEdge = 0;
  std::size_t firstUnplaced = 0, firstBoundaryNoEdge = 0;
};

void NodeClassifier::classify(std::size_t n) {
  const auto& F = elemFacesOfNode[n];
  const Vec3& p = input.nodes[n];
  if (F.empty()) {  // in no element
    report_.nodeClass[n] = NodeClass::None;
    int best = -1;
    double bd = kInf;
    for (const FaceHit& h : hits[n])
      if (h.dist < bd) {
        bd = h.dist;
        best = h.face;
      }
    report_.nodeEntity[n] = best;
    return;
  }
  // A tolerance hint (not a given one) on a CAD edge is not taken for a high-order node inside
  // one face's mesh (all its elements on that face, none with a side on the mesh's boundary)
  // that lies on the edge, or whose side does not lie along the edge (a corner at its ends
  // neither hinted to the edge nor to one of its vertices; an element's interior node has no
  // side). A mesher that curves an element across a corner of its face puts the side node at
  // its nearest point of the face, on the CAD edge (Gmsh's second-order meshes); on a face
  // narrower than its edges' tolerance (the bottle's thread) every side across the face has
  // its node within that tolerance. Held there, such elements could not be repaired, and no
  // conforming mesh has a node on a CAD edge that its side does not follow. Corners, and side
  // nodes of sides along the edge, keep the rule (they stay where FreeCAD's queries put them).
  const bool sideOffEdge =
      forced[n] == Forced::Edge && !givenHint(input, n) && nodeRoles[n] == 2u && F.size() == 1 &&
      !onMeshBoundary[n] &&
      ((!hits[n].empty() && hits[n].front().dist <= 1e-6 * diag) || !sideAlongEdge(n, forcedId[n]));
  if (forced[n] == Forced::Vertex && includesAll(S.vertexFaces(forcedId[n]), F)) {
    setVertex(n, forcedId[n]);
    return;
  }
  if (forced[n] == Forced::Edge && includesAll(S.edgeFaces(forcedId[n]), F) && !sideOffEdge) {
    setEdge(n, forcedId[n], forcedT[n]);
    return;
  }
  if (forced[n] == Forced::Face && F.size() == 1 && F[0] == forcedId[n] && !onMeshBoundary[n]) {
    setFaceOrPole(n, F[0]);
    return;
  }
  const double vs = std::min(tol, std::max(0.1 * hmin[n], 1e-9 * diag));
  if (F.size() == 1) {
    onOneFace(n, F[0], p, vs);
    return;
  }
  onSeveralFaces(n, F, p, vs);
}

void NodeClassifier::onOneFace(std::size_t n, int f, const Vec3& p, double vs) {
  // Pole: on the vertex of a degenerated edge of f.
  bool pole = false;
  for (int e : S.faceEdges(f)) {
    if (!S.isDegeneratedEdge(e)) continue;
    for (int v : S.edgeVertices(e))
      if ((S.vertexPoint(v) - p).norm() <= vs) {
        setVertex(n, v);
        pole = true;
      }
    if (pole) break;
  }
  if (pole) return;
  if (!onMeshBoundary[n]) {
    setFaceOrPole(n, f);
    return;
  }
  // On the mesh's boundary: the nearest CAD edge of f (not a seam of f).
  const NearEdge near = nearestEdge(
      f, p, [&](int e) { return !S.isDegeneratedEdge(e) && !S.isSeam(e, f); }, tol);
  const int be = near.edge;
  const double bd = near.distance, bt = near.t;
  const bool hole = !input.leftOutNeighbour.empty() && input.leftOutNeighbour[n];
  const double reach =
      hole && be >= 0 ? std::max(2.0 * BRep_Tool::Tolerance(S.edge(be)), 1e-6 * diag) : tol;
  if (be >= 0 && bd <= reach) {
    setEdge(n, be, bt);
  } else if (hole) {
    setFaceOrPole(n, f);  // inside the face, next to a left-out element: moves in the face
  } else {
    setFace(n, f);
    report_.nodeClass[n] = NodeClass::None;  // fixed below
    if (!boundaryNoEdge++) firstBoundaryNoEdge = n;
  }
}

void NodeClassifier::onSeveralFaces(std::size_t n, const std::vector<int>& F, const Vec3& p,
                                    double vs) {
  // Several faces: a common vertex, else a common edge.
  int bv = -1;
  double bvd = kInf;
  for (int e : S.faceEdges(F[0]))
    for (int v : S.edgeVertices(e)) {
      if (!includesAll(S.vertexFaces(v), F)) continue;
      const double d = (S.vertexPoint(v) - p).norm();
      if (d < bvd) {
        bvd = d;
        bv = v;
      }
    }
  if (bv >= 0 && bvd <= vs) {
    setVertex(n, bv);
    return;
  }
  const NearEdge near = nearestEdge(F[0], p, [&](int e) { return includesAll(S.edgeFaces(e), F); });
  const int be = near.edge;
  const double bed = near.distance, bt = near.t;
  if (be >= 0 && bed <= tol) {
    setEdge(n, be, bt);
  } else if (bv >= 0 && bvd <= tol) {
    setVertex(n, bv);
  } else {
    report_.nodeClass[n] = NodeClass::None;
    report_.nodeEntity[n] = -1;
    if (!unplaced++) firstUnplaced = n;
  }
}

void NodeClassifier::warn() {
  if (boundaryNoEdge)
    report_.warn(nodesNote(code::kBoundaryNodesOffEdges, boundaryNoEdge, firstBoundaryNoEdge,
                           "{count} nodes on the mesh's boundary lie on no CAD edge of their "
                           "face; they are kept fixed (e.g. node {node})"));
  if (unplaced)
    report_.warn(nodesNote(code::kNodesBetweenFaces, unplaced, firstUnplaced,
                           "{count} nodes touch elements of several faces but lie on none of "
                           "their common CAD edges or vertices; they are kept fixed (e.g. node "
                           "{node})"));
}

}  // namespace

void classifyNodes(Recovery& r, BridgeReport& report) {
  const std::size_t N = r.N;
  report.nodeClass.assign(N, NodeClass::None);
  report.nodeEntity.assign(N, -1);
  report.nodeParam.assign(N, kNaN);
  r.nodeUV.assign(N, Vec2::Zero());
  r.isPole.assign(N, 0);
  NodeClassifier c(r, report);
  for (std::size_t n = 0; n < N; ++n) c.classify(n);
  c.warn();
}

}  // namespace surfmesh::cad_detail
