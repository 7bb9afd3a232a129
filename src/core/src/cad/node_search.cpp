// SurfMesh — the CAD recovery: step 1, the faces near every node (hints first), the nodes of no
// element and the nodes off the shape (see cad_bridge.h).
#include "recovery.h"

#include <BRep_Tool.hxx>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace surfmesh::cad_detail {

namespace {

/// Tolerance hints (BridgeOptions::toleranceHints): the vertices' and edges' tolerance zones.
struct HintZones {
  std::vector<double> vertexTol, edgeTol;
  std::unique_ptr<BoxGrid> vertexGrid, edgeGrid;
};

HintZones hintZones(const Recovery& r) {
  const CadShape& S = r.S;
  const BridgeOptions& options = r.options;
  const int NE = r.NE, NV = r.NV;
  const std::vector<Box>& edgeBoxes = r.edgeBoxes;
  HintZones z;
  std::vector<double>& vertexTol = z.vertexTol;
  std::vector<double>& edgeTol = z.edgeTol;
  std::unique_ptr<BoxGrid>& vertexGrid = z.vertexGrid;
  std::unique_ptr<BoxGrid>& edgeGrid = z.edgeGrid;
  if (options.toleranceHints) {
    std::vector<Box> vb(static_cast<std::size_t>(NV)), eb(static_cast<std::size_t>(NE));
    for (int v = 0; v < NV; ++v) {
      const double t = S.vertexTolerance(v);
      const Vec3 c = S.vertexPoint(v);
      vertexTol.push_back(t);
      vb[static_cast<std::size_t>(v)] = {c.x() - t, c.y() - t, c.z() - t,
                                         c.x() + t, c.y() + t, c.z() + t};
    }
    for (int e = 0; e < NE; ++e) {
      const double t = BRep_Tool::Tolerance(S.edge(e));
      edgeTol.push_back(t);
      Box b = edgeBoxes[static_cast<std::size_t>(e)];
      for (std::size_t i = 0; i < 3; ++i) {
        b[i] -= t;
        b[i + 3] += t;
      }
      eb[static_cast<std::size_t>(e)] = b;
    }
    vertexGrid = std::make_unique<BoxGrid>(std::move(vb));
    edgeGrid = std::make_unique<BoxGrid>(std::move(eb));
  }
  return z;
}

/// Step 1 for node n: its hint when it checks out, else the faces near it.
void searchNode(const Recovery& r, const HintZones& z, bool anyHints, NodeSearch& s, std::size_t n,
                Projector& pr) {
  const CadShape& S = r.S;
  const MeshInput& input = r.input;
  const BridgeOptions& options = r.options;
  const double diag = r.diag, tol = r.tol;
  const std::vector<double>& faceSlack = r.faceSlack;
  const std::vector<double>& vertexTol = z.vertexTol;
  const std::vector<double>& edgeTol = z.edgeTol;
  const std::unique_ptr<BoxGrid>& vertexGrid = z.vertexGrid;
  const std::unique_ptr<BoxGrid>& edgeGrid = z.edgeGrid;
  auto& hits = s.hits;
  auto& forced = s.forced;
  auto& forcedId = s.forcedId;
  auto& forcedT = s.forcedT;
  auto& hintRejected = s.hintRejected;
  const double close = 1e-6 * diag;  // a node this near an entity lies on it
  const Vec3& p = input.nodes[n];
  auto& h = hits[n];
  if (anyHints) {
    int hv = input.hintVertex.empty() ? -1 : input.hintVertex[n];
    int he = input.hintEdge.empty() ? -1 : input.hintEdge[n];
    const int hf = input.hintFace.empty() ? -1 : input.hintFace[n];
    const bool given = givenHint(input, n);
    if (!given && options.toleranceHints)
      pr.toleranceHint(p, *vertexGrid, vertexTol, *edgeGrid, edgeTol, &hv, &he);
    // A hint is taken when the node lies on its entity (within `close`), or within the
    // tolerance and no other entity of its kind is nearer: the mesher's own queries accept
    // a node within the entity's tolerance, which at a CAD feature smaller than that
    // tolerance also names a neighbouring vertex or edge (its element would then lie on
    // no single face).
    if (hv >= 0) {
      const double d = (S.vertexPoint(hv) - p).norm();
      if (d <= tol && (d <= close || !pr.vertexNearerThan(p, d - close, hv))) {
        for (int f : S.vertexFaces(hv)) h.push_back(FaceHit{f, d, Vec2::Zero(), false, false});
        forced[n] = Forced::Vertex;
        forcedId[n] = hv;
        if (!h.empty()) return;
      }
      hintRejected[n] = given;
    } else if (he >= 0) {
      double t = 0.0;
      const double d = pr.edgeDistance(he, p, &t);
      if (d <= tol && (d <= close || !pr.edgeNearerThan(p, d - close, he))) {
        for (int f : S.edgeFaces(he)) h.push_back(FaceHit{f, d, Vec2::Zero(), false, false});
        forced[n] = Forced::Edge;
        forcedId[n] = he;
        forcedT[n] = t;
        if (!h.empty()) return;
      }
      hintRejected[n] = given;
    } else if (hf >= 0) {
      const FaceHit fh = pr.faceDistance(hf, p, tol);
      bool take = fh.dist <= tol;
      if (take && fh.dist > close) {
        pr.facesNear(p, tol, &h);
        for (const FaceHit& x : h)
          if (x.face != hf && x.dist < fh.dist - close) take = false;
        h.clear();
      }
      if (take) {
        h.push_back(fh);
        forced[n] = Forced::Face;
        forcedId[n] = hf;
        return;
      }
      hintRejected[n] = given;
    }
    forced[n] = Forced::None;
    h.clear();
  }
  const double base = 1e-6 * diag;
  pr.facesNear(p, tol, &h, base);
  // Keep the faces as close as the nearest one up to the tolerance of their boundary near
  // the node (a node near a tangent edge, or on a thin wall, is within `tol` of the
  // neighbouring face too, but not on it).
  double dmin = kInf;
  for (const FaceHit& x : h) dmin = std::min(dmin, x.dist);
  h.erase(std::remove_if(h.begin(), h.end(),
                         [&](const FaceHit& x) {
                           if (x.dist <= dmin + base) return false;
                           if (x.dist > dmin + faceSlack[static_cast<std::size_t>(x.face)])
                             return true;
                           return x.dist > dmin + pr.boundarySlack(x.face, p, base);
                         }),
          h.end());
}

}  // namespace

std::shared_ptr<const NodeSearch> searchNodes(const Recovery& r) {
  const MeshInput& input = r.input;
  const BridgeOptions& options = r.options;
  const std::size_t N = r.N;
  const double tol = r.tol;
  ProjectorPool& projectors = *r.projectors;
  const bool givenHints =
      !input.hintFace.empty() || !input.hintEdge.empty() || !input.hintVertex.empty();
  const bool anyHints = givenHints || options.toleranceHints;
  auto fresh = std::make_shared<NodeSearch>();
  auto& hits = fresh->hits;
  auto& forced = fresh->forced;
  auto& forcedId = fresh->forcedId;
  auto& forcedT = fresh->forcedT;
  auto& hintRejected = fresh->hintRejected;
  hits.resize(N);
  forced.assign(N, Forced::None);
  forcedId.assign(N, -1);
  forcedT.assign(N, kNaN);
  hintRejected.assign(N, 0);
  const HintZones zones = hintZones(r);
  parallelFor(N, projectors,
              [&](std::size_t n, Projector& pr) { searchNode(r, zones, anyHints, *fresh, n, pr); });
  if (options.keepNodeSearch) {
    fresh->nodes = input.nodes;
    fresh->hintFace = input.hintFace;
    fresh->hintEdge = input.hintEdge;
    fresh->hintVertex = input.hintVertex;
    fresh->tol = tol;
    fresh->toleranceHints = options.toleranceHints;
  }
  return fresh;
}

void farHighOrderNodes(Recovery& r) {
  const MeshInput& input = r.input;
  const std::size_t N = r.N;
  const double diag = r.diag;
  const std::vector<double>& reach = r.reach;
  const std::shared_ptr<const NodeSearch>& search = r.search;
  ProjectorPool& projectors = *r.projectors;
  std::vector<std::vector<FaceHit>>& withFar = r.withFar;
  std::vector<std::size_t> far;
  for (std::size_t n = 0; n < N; ++n)
    if (search->hits[n].empty() && reach[n] > 0.0) far.push_back(n);
  if (!far.empty()) {
    withFar = search->hits;
    parallelFor(far.size(), projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = far[k];
      pr.facesNear(input.nodes[n], reach[n], &withFar[n], 1e-6 * diag);
    });
  }
}

void locateNodes(const Recovery& r, BridgeReport& report) {
  const MeshInput& input = r.input;
  const std::size_t N = r.N;
  const double diag = r.diag, tol = r.tol;
  const std::vector<std::vector<FaceHit>>& hits = r.hits();
  ProjectorPool& projectors = *r.projectors;
  report.tolerance = tol;
  report.nodeDistance.assign(N, kInf);
  for (std::size_t n = 0; n < N; ++n)
    for (const FaceHit& h : hits[n])
      report.nodeDistance[n] = std::min(report.nodeDistance[n], h.dist);
  // Nodes of no element (a FEM mesh's nodes of edge or vertex elements alone: on a free edge,
  // a beam in a shell mesh): located on the whole shape — a CAD vertex or edge within its
  // tolerance, else the nearest face, free edge or lone vertex — and kept fixed.
  std::vector<unsigned char> inElement(N, 0);
  for (std::int32_t n : input.conn) inElement[static_cast<std::size_t>(n)] = 1;
  for (std::size_t n = 0; n < N; ++n)
    if (!inElement[n]) report.looseNodes.push_back(static_cast<std::int32_t>(n));
  {
    const std::size_t L = report.looseNodes.size();
    report.looseClass.assign(L, NodeClass::None);
    report.looseEntity.assign(L, -1);
    report.looseDistance.assign(L, kInf);
    parallelFor(L, projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = static_cast<std::size_t>(report.looseNodes[k]);
      double t = 0.0;
      report.looseDistance[k] =
          pr.locate(input.nodes[n], 1e-6 * diag, &report.looseClass[k], &report.looseEntity[k], &t);
    });
    for (std::size_t k = 0; k < L; ++k) {
      const std::size_t n = static_cast<std::size_t>(report.looseNodes[k]);
      report.nodeDistance[n] = std::min(report.nodeDistance[n], report.looseDistance[k]);
    }
  }
  std::vector<std::size_t> offNodes;
  for (std::size_t n = 0; n < N; ++n)
    if (hits[n].empty() && (inElement[n] || !(report.nodeDistance[n] <= tol)))
      offNodes.push_back(n);
  if (!offNodes.empty()) {
    const std::size_t checked = std::min<std::size_t>(offNodes.size(), 1000);
    std::vector<NodeClass> nearKind(checked, NodeClass::None);
    std::vector<int> nearId(checked, -1);
    parallelFor(checked, projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = offNodes[k];
      report.nodeDistance[n] = pr.wholeShapeDistance(input.nodes[n], &nearKind[k], &nearId[k]);
    });
    std::size_t worst = 0;
    for (std::size_t k = 0; k < checked; ++k)
      if (report.nodeDistance[offNodes[k]] > report.nodeDistance[offNodes[worst]]) worst = k;
    const std::size_t wn = offNodes[worst];
    const double wd = report.nodeDistance[wn];
    Diagnostic d;
    d.code = wd <= tol ? code::kNodesOnNoFace : code::kNodesOffShape;
    d.count = static_cast<std::int64_t>(offNodes.size());
    d.nodes = {static_cast<std::int64_t>(wn)};
    for (std::size_t k = 0; k < std::min<std::size_t>(offNodes.size(), 5); ++k)
      d.nodes.push_back(static_cast<std::int64_t>(offNodes[k]));
    d.values = {{"total", static_cast<double>(N)},
                {"distance", wd},
                {"tolerance", tol},
                {"relative", wd / diag},
                {"checked", static_cast<double>(checked)}};
    const std::string entity = nameEntity(d, nearKind[worst], nearId[worst]);
    if (wd <= tol)
      // Every such node is an element's node on a free edge or a lone vertex (else the worst
      // would be farther): an element there lies on no face.
      d.format =
          "{count} of {total} nodes are nodes of face elements but lie on no face: node "
          "{node} lies {distance} from " +
          entity + ", which bounds no face";
    else
      d.format =
          "{count} of {total} nodes are farther than the tolerance {tolerance} from the "
          "shape (its faces, edges and vertices); worst: node {node} at distance "
          "{distance} ({relative} x diagonal) from " +
          entity + ", the nearest";
    if (checked < offNodes.size()) d.format += " among the first {checked} checked";
    d.format += "; e.g. nodes {nodes1}";
    if (wd <= tol)
      d.format +=
          ". Face elements must lie on the shape's faces: give the face elements only, "
          "or the shape the mesh was made on.";
    else
      d.format +=
          ". Check that the mesh belongs to this shape (same placement), or pass a "
          "larger tolerance.";
    fail(std::move(d));
  }
}

void reportHints(const Recovery& r, BridgeReport& report) {
  const auto& forced = r.search->forced;
  const auto& hintRejected = r.search->hintRejected;
  std::size_t rejected = 0;
  for (unsigned char x : hintRejected) rejected += x;
  report.hintsRejected = rejected;
  for (Forced f : forced) report.hintsTaken += f != Forced::None;
  if (rejected) {
    std::size_t first = 0;
    while (!hintRejected[first]) ++first;
    report.warn(nodesNote(code::kHintsRejected, rejected, first,
                          "{count} node hints were farther than the tolerance from their "
                          "entity, or farther than another entity of its kind, and were "
                          "ignored (e.g. node {node})"));
  }
}

}  // namespace surfmesh::cad_detail
