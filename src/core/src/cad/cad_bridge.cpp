// SurfMesh — the CAD bridge (see cad_bridge.h for the algorithm).
#include "surfmesh/cad/cad_bridge.h"

#include "recovery.h"
#include "winding.h"

#include <BRep_Tool.hxx>
#include <Standard_Failure.hxx>
#include <gp_Pnt2d.hxx>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace surfmesh {

using cad_detail::Box;
using cad_detail::BoxGrid;
using cad_detail::EdgePair;
using cad_detail::ElementEdges;
using cad_detail::elementEdges;
using cad_detail::FaceHit;
using cad_detail::faceName;
using cad_detail::faceNames;
using cad_detail::faceWindingSigns;
using cad_detail::fail;
using cad_detail::givenHint;
using cad_detail::includesAll;
using cad_detail::kHighOrderReach;
using cad_detail::kInf;
using cad_detail::kNaN;
using cad_detail::looseNodesNote;
using cad_detail::manifoldEdgePairs;
using cad_detail::miswoundElements;
using cad_detail::parallelFor;
using cad_detail::Projector;
using cad_detail::projectorGeometry;
using cad_detail::ProjectorPool;
using cad_detail::settleDoubtfulFaces;
using cad_detail::toBox;

void CadMesh::distancesToShape(const std::vector<Vec3>& points,
                               const std::vector<std::int32_t>& faces, std::vector<double>* toFace,
                               std::vector<double>* toShape) const {
  const CadShape& S = *shape_;
  if (faces.size() != points.size())
    fail("distancesToShape: " + std::to_string(faces.size()) + " faces for " +
         std::to_string(points.size()) + " points");
  for (std::size_t k = 0; k < faces.size(); ++k)
    if (faces[k] < -1 || faces[k] >= S.faceCount())
      fail("distancesToShape: face " + std::to_string(faces[k]) + " of point " + std::to_string(k) +
           " out of range [-1, " + std::to_string(S.faceCount()) + ")");
  std::vector<Box> faceBoxes, edgeBoxes;
  std::vector<double> faceSlack;
  const double tol = report_.tolerance > 0.0 ? report_.tolerance : 1e-3 * S.diagonal();
  projectorGeometry(S, tol, &faceBoxes, &edgeBoxes, &faceSlack);
  const int threads = options_.threads > 0
                          ? options_.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  ProjectorPool projectors(threads, S, faceBoxes, edgeBoxes, faceSlack);
  toFace->assign(points.size(), kNaN);
  toShape->assign(points.size(), kNaN);
  parallelFor(points.size(), projectors, [&](std::size_t k, Projector& pr) {
    if (!points[k].allFinite()) return;
    if (faces[k] >= 0) (*toFace)[k] = pr.faceDistance(faces[k], points[k], kInf).dist;
    NodeClass kind;
    int id = -1;
    (*toShape)[k] = pr.wholeShapeDistance(points[k], &kind, &id);
  });
}

MeshInput triangleMeshInput(const std::vector<double>& xyz, const std::vector<std::int32_t>& tris) {
  if (xyz.size() % 3 != 0) fail("xyz must hold 3 values per node");
  if (tris.size() % 3 != 0) fail("triangles must hold 3 node ids each");
  MeshInput in;
  in.nodes.resize(xyz.size() / 3);
  for (std::size_t i = 0; i < in.nodes.size(); ++i)
    in.nodes[i] = Vec3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
  in.types.assign(tris.size() / 3, ElementType::Tri3);
  in.conn = tris;
  return in;
}

CadMesh::~CadMesh() = default;

CadMesh::CadMesh(std::shared_ptr<const CadShape> shape, const MeshInput& input,
                 const BridgeOptions& options, const CadMesh* sameNodes)
    : shape_(std::move(shape)), options_(options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!shape_) fail("no shape given");
  const CadShape& S = *shape_;
  const std::size_t N = input.nodes.size();
  const std::size_t E = input.types.size();
  const int NF = S.faceCount(), NE = S.edgeCount(), NV = S.vertexCount();
  const double diag = S.diagonal();

  // ---- options and input validation ---------------------------------------------------------
  if (!(options.tolerance >= 0.0) || !std::isfinite(options.tolerance))
    fail("tolerance must be >= 0 (0 = 1e-3 x shape diagonal), got " +
         std::to_string(options.tolerance));
  const double tol = options.tolerance > 0.0 ? options.tolerance : 1e-3 * diag;
  if (options.boundary != "fixed" && options.boundary != "slide")
    fail("unknown boundary mode '" + options.boundary + "' (expected \"fixed\" or \"slide\")");
  const bool slide = options.boundary == "slide";
  const int threads = options.threads > 0
                          ? options.threads
                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  if (N == 0) fail("the mesh has no nodes");
  if (!input.leftOutNeighbour.empty() && input.leftOutNeighbour.size() != N)
    fail("leftOutNeighbour has " + std::to_string(input.leftOutNeighbour.size()) + " entries for " +
         std::to_string(N) + " nodes");
  if (E == 0) fail("the mesh has no elements");
  for (std::size_t i = 0; i < N; ++i)
    if (!input.nodes[i].allFinite())
      fail("node " + std::to_string(i) + " has a non-finite coordinate (NaN or inf)");
  std::vector<std::int64_t> offsets = input.offsets;
  if (offsets.empty()) {
    offsets.resize(E + 1);
    offsets[0] = 0;
    for (std::size_t e = 0; e < E; ++e) offsets[e + 1] = offsets[e] + nodeCount(input.types[e]);
  }
  if (offsets.size() != E + 1)
    fail("offsets must have " + std::to_string(E + 1) + " entries (elements + 1), got " +
         std::to_string(offsets.size()));
  if (offsets[0] != 0) fail("offsets[0] must be 0");
  for (std::size_t e = 0; e < E; ++e) {
    const std::int64_t n = offsets[e + 1] - offsets[e];
    if (n != nodeCount(input.types[e]))
      fail("element " + std::to_string(e) + " has " + std::to_string(n) + " nodes, expected " +
           std::to_string(nodeCount(input.types[e])) + " for " + elementTypeName(input.types[e]));
  }
  if (static_cast<std::size_t>(offsets[E]) != input.conn.size())
    fail("connectivity has " + std::to_string(input.conn.size()) + " entries, offsets say " +
         std::to_string(offsets[E]));
  for (std::size_t e = 0; e < E; ++e)
    for (std::int64_t k = offsets[e]; k < offsets[e + 1]; ++k) {
      const std::int32_t n = input.conn[static_cast<std::size_t>(k)];
      if (n < 0 || static_cast<std::size_t>(n) >= N)
        fail("element " + std::to_string(e) + " references node " + std::to_string(n) +
             ", out of range [0, " + std::to_string(N) + ")");
      for (std::int64_t j = offsets[e]; j < k; ++j)
        if (input.conn[static_cast<std::size_t>(j)] == n)
          fail("element " + std::to_string(e) + " repeats node " + std::to_string(n));
    }
  auto checkHints = [&](const std::vector<std::int32_t>& h, int count, const char* name) {
    if (h.empty()) return;
    if (h.size() != N)
      fail(std::string(name) + " must be empty or have one entry per node (" + std::to_string(N) +
           "), got " + std::to_string(h.size()));
    for (std::size_t i = 0; i < N; ++i)
      if (h[i] < -1 || h[i] >= count)
        fail(std::string(name) + "[" + std::to_string(i) + "] = " + std::to_string(h[i]) +
             " out of range [-1, " + std::to_string(count) + ")");
  };
  checkHints(input.hintFace, NF, "hintFace");
  checkHints(input.hintEdge, NE, "hintEdge");
  checkHints(input.hintVertex, NV, "hintVertex");

  std::vector<Box> faceBoxes, edgeBoxes;
  std::vector<double> faceSlack;
  projectorGeometry(S, tol, &faceBoxes, &edgeBoxes, &faceSlack);
  ProjectorPool projectors(threads, S, faceBoxes, edgeBoxes, faceSlack);

  // Reach of each high-order node that is no element's corner (kHighOrderReach), 0 otherwise.
  std::vector<double> reach(N, 0.0);
  {
    std::vector<unsigned char> corner(N, 0);
    for (std::size_t e = 0; e < E; ++e) {
      const std::int32_t* nd = input.conn.data() + offsets[e];
      const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
      const int nc = elementEdges(input.types[e]).corners;
      double side = 0.0;
      for (int k = 0; k < nc; ++k)
        side = std::max(side, (input.nodes[static_cast<std::size_t>(nd[k])] -
                               input.nodes[static_cast<std::size_t>(nd[(k + 1) % nc])])
                                  .norm());
      for (int k = 0; k < nn; ++k) {
        const std::size_t n = static_cast<std::size_t>(nd[k]);
        if (k < nc)
          corner[n] = 1;
        else
          reach[n] = std::max(reach[n], kHighOrderReach * side);
      }
    }
    for (std::size_t n = 0; n < N; ++n)
      if (corner[n] || !(reach[n] > tol)) reach[n] = 0.0;
  }

  // ---- fail fast on a mesh of another shape ---------------------------------------------------
  {
    Box mb = {kInf, kInf, kInf, -kInf, -kInf, -kInf};
    for (const Vec3& p : input.nodes)
      for (int i = 0; i < 3; ++i) {
        mb[static_cast<std::size_t>(i)] = std::min(mb[static_cast<std::size_t>(i)], p[i]);
        mb[static_cast<std::size_t>(i) + 3] = std::max(mb[static_cast<std::size_t>(i) + 3], p[i]);
      }
    const Box sb = toBox(S.boundingBox());
    auto boxText = [](const Box& b) {
      std::ostringstream os;
      os << "[" << b[0] << ", " << b[1] << ", " << b[2] << "] - [" << b[3] << ", " << b[4] << ", "
         << b[5] << "]";
      return os.str();
    };
    // A mesh many times larger or smaller than the shape was most likely written in other
    // units (the shape's box may be loose, up to about twice the tight one: only a factor of
    // 8 or more is taken as a sign).
    auto unitHint = [&]() -> std::string {
      auto diag = [](const Box& b) {
        return std::sqrt((b[3] - b[0]) * (b[3] - b[0]) + (b[4] - b[1]) * (b[4] - b[1]) +
                         (b[5] - b[2]) * (b[5] - b[2]));
      };
      const double ds = diag(sb), dm = diag(mb);
      if (!(ds > 0.0) || !(dm > 0.0) || !std::isfinite(dm)) return "";
      const double ratio = dm / ds;
      if (ratio < 8.0 && ratio > 1.0 / 8.0) return "";
      std::ostringstream os;
      os.precision(2);
      os << " (the mesh's bounding box is about " << (ratio >= 1.0 ? ratio : 1.0 / ratio)
         << (ratio >= 1.0 ? " times larger" : " times smaller")
         << " than the shape's: a unit mismatch, e.g. mm and m or inches? Scale the mesh or "
            "the shape)";
      return os.str();
    };
    bool disjoint = false;
    for (std::size_t i = 0; i < 3; ++i)
      if (mb[i] > sb[i + 3] + tol || mb[i + 3] < sb[i] - tol) disjoint = true;
    if (disjoint)
      fail("the mesh does not lie on this shape: its bounding box " + boxText(mb) +
           " does not meet the shape's " + boxText(sb) + unitHint());
    const std::size_t samples = std::min<std::size_t>(N, 64);
    std::vector<double> sd(samples);
    std::vector<int> sf(samples, -1);
    parallelFor(samples, projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = k * N / samples;
      std::vector<FaceHit> hits;
      pr.facesNear(input.nodes[n], tol, &hits);
      NodeClass kind;
      int id = -1;
      sd[k] = hits.empty() ? pr.wholeShapeDistance(input.nodes[n], &kind, &id) : 0.0;
    });
    std::size_t off = 0, worst = 0;
    for (std::size_t k = 0; k < samples; ++k)
      if (sd[k] > tol) {
        ++off;
        if (sd[k] > sd[worst] || sd[worst] <= tol) worst = k;
      }
    if (off * 2 > samples) {
      std::ostringstream os;
      os << "the mesh does not lie on this shape: " << off << " of " << samples
         << " sampled nodes are farther than the tolerance " << tol << " from the shape (e.g. node "
         << worst * N / samples << " at distance " << sd[worst] << "); mesh bounding box "
         << boxText(mb) << ", shape bounding box " << boxText(sb) << unitHint();
      fail(os.str());
    }
  }

  // ---- 1. faces near every node (hints first) -----------------------------------------------
  const bool givenHints =
      !input.hintFace.empty() || !input.hintEdge.empty() || !input.hintVertex.empty();
  const bool anyHints = givenHints || options.toleranceHints;
  std::shared_ptr<const NodeSearch> search;
  if (sameNodes && sameNodes->nodeSearch_ &&
      sameNodes->nodeSearch_->matches(input, tol, options.toleranceHints)) {
    search = sameNodes->nodeSearch_;
  } else {
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
    // Tolerance hints (BridgeOptions::toleranceHints): the vertices' and edges' tolerance zones.
    std::vector<double> vertexTol, edgeTol;
    std::unique_ptr<BoxGrid> vertexGrid, edgeGrid;
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
    const double close = 1e-6 * diag;  // a node this near an entity lies on it
    parallelFor(N, projectors, [&](std::size_t n, Projector& pr) {
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
    });
    if (options.keepNodeSearch) {
      fresh->nodes = input.nodes;
      fresh->hintFace = input.hintFace;
      fresh->hintEdge = input.hintEdge;
      fresh->hintVertex = input.hintVertex;
      fresh->tol = tol;
      fresh->toleranceHints = options.toleranceHints;
    }
    search = std::move(fresh);
  }
  if (options.keepNodeSearch) nodeSearch_ = search;
  // High-order nodes beyond the tolerance: every face within their reach (kHighOrderReach),
  // not only the nearest (off its trimmed domain, a node may be nearer to another face than to
  // its element's). Searched on a copy of the hits, so that a kept node search (which depends
  // on the nodes alone, not on the elements that set the reach) stays as it was.
  std::vector<std::vector<FaceHit>> withFar;
  {
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
  const auto& hits = withFar.empty() ? search->hits : withFar;
  const auto& forced = search->forced;
  const auto& forcedId = search->forcedId;
  const auto& forcedT = search->forcedT;
  const auto& hintRejected = search->hintRejected;

  report_.tolerance = tol;
  report_.nodeDistance.assign(N, kInf);
  for (std::size_t n = 0; n < N; ++n)
    for (const FaceHit& h : hits[n])
      report_.nodeDistance[n] = std::min(report_.nodeDistance[n], h.dist);
  // Nodes of no element (a FEM mesh's nodes of edge or vertex elements alone: on a free edge,
  // a beam in a shell mesh): located on the whole shape — a CAD vertex or edge within its
  // tolerance, else the nearest face, free edge or lone vertex — and kept fixed.
  std::vector<unsigned char> inElement(N, 0);
  for (std::int32_t n : input.conn) inElement[static_cast<std::size_t>(n)] = 1;
  for (std::size_t n = 0; n < N; ++n)
    if (!inElement[n]) report_.looseNodes.push_back(static_cast<std::int32_t>(n));
  {
    const std::size_t L = report_.looseNodes.size();
    report_.looseClass.assign(L, NodeClass::None);
    report_.looseEntity.assign(L, -1);
    report_.looseDistance.assign(L, kInf);
    parallelFor(L, projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = static_cast<std::size_t>(report_.looseNodes[k]);
      double t = 0.0;
      report_.looseDistance[k] = pr.locate(input.nodes[n], 1e-6 * diag, &report_.looseClass[k],
                                           &report_.looseEntity[k], &t);
    });
    for (std::size_t k = 0; k < L; ++k) {
      const std::size_t n = static_cast<std::size_t>(report_.looseNodes[k]);
      report_.nodeDistance[n] = std::min(report_.nodeDistance[n], report_.looseDistance[k]);
    }
  }
  std::vector<std::size_t> offNodes;
  for (std::size_t n = 0; n < N; ++n)
    if (hits[n].empty() && (inElement[n] || !(report_.nodeDistance[n] <= tol)))
      offNodes.push_back(n);
  if (!offNodes.empty()) {
    const std::size_t checked = std::min<std::size_t>(offNodes.size(), 1000);
    std::vector<NodeClass> nearKind(checked, NodeClass::None);
    std::vector<int> nearId(checked, -1);
    parallelFor(checked, projectors, [&](std::size_t k, Projector& pr) {
      const std::size_t n = offNodes[k];
      report_.nodeDistance[n] = pr.wholeShapeDistance(input.nodes[n], &nearKind[k], &nearId[k]);
    });
    std::size_t worst = 0;
    for (std::size_t k = 0; k < checked; ++k)
      if (report_.nodeDistance[offNodes[k]] > report_.nodeDistance[offNodes[worst]]) worst = k;
    const std::size_t wn = offNodes[worst];
    const double wd = report_.nodeDistance[wn];
    std::ostringstream os;
    if (wd <= tol) {
      // Every such node is an element's node on a free edge or a lone vertex (else the worst
      // would be farther): an element there lies on no face.
      os << offNodes.size() << " of " << N << " nodes are nodes of face elements but lie on no "
         << "face: node " << wn << " lies " << wd << " from " << nodeClassName(nearKind[worst])
         << " " << nearId[worst] << ", which bounds no face";
    } else {
      os << offNodes.size() << " of " << N << " nodes are farther than the tolerance " << tol
         << " from the shape (its faces, edges and vertices); worst: node " << wn << " at distance "
         << wd << " (" << wd / diag << " x diagonal) from " << nodeClassName(nearKind[worst]) << " "
         << nearId[worst] << ", the nearest";
    }
    if (checked < offNodes.size()) os << " among the first " << checked << " checked";
    os << "; e.g. nodes";
    for (std::size_t k = 0; k < std::min<std::size_t>(offNodes.size(), 5); ++k)
      os << " " << offNodes[k];
    if (wd <= tol)
      os << ". Face elements must lie on the shape's faces: give the face elements only, or the "
            "shape the mesh was made on.";
    else
      os << ". Check that the mesh belongs to this shape (same placement), or pass a larger "
            "tolerance.";
    fail(os.str());
  }
  std::size_t rejected = 0;
  for (unsigned char r : hintRejected) rejected += r;
  report_.hintsRejected = rejected;
  for (Forced f : forced) report_.hintsTaken += f != Forced::None;
  if (rejected) {
    std::size_t first = 0;
    while (!hintRejected[first]) ++first;
    report_.warnings.push_back(std::to_string(rejected) +
                               " node hints were farther than the tolerance from their entity, "
                               "or farther than another entity of its kind, and were ignored "
                               "(e.g. node " +
                               std::to_string(first) + ")");
  }

  // Single-threaded tools for the rest.
  Projector& proj = projectors.slot(0);

  // ---- 2. element faces ---------------------------------------------------------------------
  std::vector<std::vector<int>> nodeFaces(N);  // C(n), sorted
  for (std::size_t n = 0; n < N; ++n) {
    for (const FaceHit& h : hits[n]) nodeFaces[n].push_back(h.face);
    std::sort(nodeFaces[n].begin(), nodeFaces[n].end());
    nodeFaces[n].erase(std::unique(nodeFaces[n].begin(), nodeFaces[n].end()), nodeFaces[n].end());
  }
  std::vector<std::int32_t> elemFace(E, -1);
  // In parallel (the distances of several faces to an element's nodes and centroid may need
  // global projections). offFace marks an element put on a face its nodes are each within the
  // tolerance of; one left on no face (elemFace −1) is an error, reported below for the first.
  std::vector<unsigned char> offFace(E, 0);
  // The faces of an element whose nodes are all within the tolerance of several (settled by
  // the mesh's winding below); empty for the others.
  std::vector<std::vector<int>> doubtfulFaces(E);
  parallelFor(E, projectors, [&](std::size_t e, Projector& pr) {
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
    // winding says otherwise (settleDoubtfulFaces).
    doubtfulFaces[e] = common;
    Vec3 c = Vec3::Zero();
    for (int k = 0; k < nn; ++k) c += input.nodes[static_cast<std::size_t>(nd[k])];
    c /= nn;
    double best = kInf;
    for (int f : common) {
      double d = pr.faceDistance(f, c, kInf).dist;
      for (int k = 0; k < nn; ++k)
        for (const FaceHit& h : hits[static_cast<std::size_t>(nd[k])])
          if (h.face == f) d += h.dist;
      if (d < best) {
        best = d;
        elemFace[e] = f;
      }
    }
    if (elemFace[e] < 0) elemFace[e] = common[0];
  });
  std::size_t offFaceElements = 0, firstOffFace = 0;
  for (std::size_t e = 0; e < E; ++e) {
    if (elemFace[e] < 0) {
      const std::int32_t* nd = input.conn.data() + offsets[e];
      const int nn = static_cast<int>(offsets[e + 1] - offsets[e]);
      std::ostringstream os;
      os << "element " << e << " lies on no single face of the shape (its nodes share no face):";
      for (int k = 0; k < nn; ++k)
        os << " node " << nd[k] << " on " << faceNames(nodeFaces[static_cast<std::size_t>(nd[k])])
           << (k + 1 < nn ? ";" : "");
      os << ". The mesh must conform to the B-rep faces (no element across a CAD edge).";
      fail(os.str());
    }
    if (offFace[e] && offFaceElements++ == 0) firstOffFace = e;
  }
  const std::vector<EdgePair> manifoldEdges = manifoldEdgePairs(input, offsets);
  settleDoubtfulFaces(manifoldEdges, doubtfulFaces, elemFace);
  doubtfulFaces = std::vector<std::vector<int>>();
  if (offFaceElements)
    report_.warnings.push_back(
        std::to_string(offFaceElements) +
        " element(s) whose nodes are each nearest to another face (next to a CAD edge with a "
        "tolerance as large as the elements) were put on the face all their nodes are within "
        "the tolerance of (e.g. element " +
        std::to_string(firstOffFace) + " on " + faceName(elemFace[firstOffFace]) + ")");

  // ---- 3. node classes ----------------------------------------------------------------------
  // Faces of each node's elements, mesh boundary nodes, shortest incident mesh edge.
  std::vector<std::vector<int>> elemFacesOfNode(N);
  std::vector<double> hmin(N, kInf);
  std::vector<unsigned char> onMeshBoundary(N, 0);
  // Per node: bit 0 a corner of some element, bit 1 a high-order node of some element.
  std::vector<unsigned char> nodeRoles(N, 0);
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

  report_.nodeClass.assign(N, NodeClass::None);
  report_.nodeEntity.assign(N, -1);
  report_.nodeParam.assign(N, kNaN);
  std::vector<Vec2> nodeUV(N, Vec2::Zero());
  std::vector<unsigned char> isPole(N, 0);
  std::size_t unplaced = 0, boundaryNoEdge = 0;
  std::size_t firstUnplaced = 0, firstBoundaryNoEdge = 0;

  auto hitOn = [&](std::size_t n, int f) -> const FaceHit* {
    for (const FaceHit& h : hits[n])
      if (h.face == f) return &h;
    return nullptr;
  };
  auto setVertex = [&](std::size_t n, int v) {
    report_.nodeClass[n] = NodeClass::Vertex;
    report_.nodeEntity[n] = v;
    for (int e : S.vertexEdges(v))
      if (S.isDegeneratedEdge(e)) isPole[n] = 1;
  };
  auto setFace = [&](std::size_t n, int f) {
    report_.nodeClass[n] = NodeClass::Face;
    report_.nodeEntity[n] = f;
    const FaceHit* h = hitOn(n, f);
    if (h && h->hasUV && h->uv.allFinite()) {
      nodeUV[n] = h->uv;
    } else {
      nodeUV[n] = proj.faceDistance(f, input.nodes[n], kInf).uv;
    }
  };
  // Edge node (or vertex node when at an end of the edge / on a degenerated edge).
  auto setEdge = [&](std::size_t n, int e, double t) {
    const double vs = std::min(tol, std::max(0.1 * hmin[n], 1e-9 * diag));
    for (int v : S.edgeVertices(e))
      if ((S.vertexPoint(v) - input.nodes[n]).norm() <= vs || S.isDegeneratedEdge(e)) {
        setVertex(n, v);
        return;
      }
    const auto& ef = S.edgeFaces(e);
    if (ef.size() == 1 && S.isSeam(e, ef[0])) {  // a seam is inside its face
      setFace(n, ef[0]);
      return;
    }
    report_.nodeClass[n] = NodeClass::Edge;
    report_.nodeEntity[n] = e;
    report_.nodeParam[n] = t;
  };

  for (std::size_t n = 0; n < N; ++n) {
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
      continue;
    }
    // A tolerance hint (not a given one) on a CAD edge is not taken for a high-order side node
    // that lies on the edge but inside one face's mesh (all its elements on that face, none
    // with a side on the mesh's boundary): a mesher that curves an element across a corner of
    // its face puts the side node at its nearest point of the face, on the CAD edge (Gmsh's
    // second-order meshes); held there, such elements could not be repaired. Corners and nodes
    // merely within an edge's tolerance keep the rule (the nodes of a face narrower than its
    // edges' tolerance, the bottle's thread, must stay where FreeCAD's queries put them).
    const bool sideOnEdgeInside = forced[n] == Forced::Edge && !givenHint(input, n) &&
                                  nodeRoles[n] == 2u && F.size() == 1 && !onMeshBoundary[n] &&
                                  !hits[n].empty() && hits[n].front().dist <= 1e-6 * diag;
    if (forced[n] == Forced::Vertex && includesAll(S.vertexFaces(forcedId[n]), F)) {
      setVertex(n, forcedId[n]);
      continue;
    }
    if (forced[n] == Forced::Edge && includesAll(S.edgeFaces(forcedId[n]), F) &&
        !sideOnEdgeInside) {
      setEdge(n, forcedId[n], forcedT[n]);
      continue;
    }
    if (forced[n] == Forced::Face && F.size() == 1 && F[0] == forcedId[n] && !onMeshBoundary[n]) {
      setFace(n, F[0]);
      continue;
    }
    const double vs = std::min(tol, std::max(0.1 * hmin[n], 1e-9 * diag));
    if (F.size() == 1) {
      const int f = F[0];
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
      if (pole) continue;
      if (!onMeshBoundary[n]) {
        setFace(n, f);
        continue;
      }
      // On the mesh's boundary: the nearest CAD edge of f (not a seam of f).
      int be = -1;
      double bd = kInf, bt = 0.0;
      for (int e : S.faceEdges(f)) {
        if (S.isDegeneratedEdge(e) || S.isSeam(e, f)) continue;
        if (boxDistance(edgeBoxes[static_cast<std::size_t>(e)], p) > std::min(bd, tol)) continue;
        double t = 0.0;
        const double d = proj.edgeDistance(e, p, &t);
        if (d < bd) {
          bd = d;
          be = e;
          bt = t;
        }
      }
      const bool hole = !input.leftOutNeighbour.empty() && input.leftOutNeighbour[n];
      const double reach =
          hole && be >= 0 ? std::max(2.0 * BRep_Tool::Tolerance(S.edge(be)), 1e-6 * diag) : tol;
      if (be >= 0 && bd <= reach) {
        setEdge(n, be, bt);
      } else if (hole) {
        setFace(n, f);  // inside the face, next to a left-out element: moves in the face
      } else {
        setFace(n, f);
        report_.nodeClass[n] = NodeClass::None;  // fixed below
        if (!boundaryNoEdge++) firstBoundaryNoEdge = n;
      }
      continue;
    }
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
      continue;
    }
    int be = -1;
    double bed = kInf, bt = 0.0;
    for (int e : S.faceEdges(F[0])) {
      if (!includesAll(S.edgeFaces(e), F)) continue;
      double t = 0.0;
      const double d = proj.edgeDistance(e, p, &t);
      if (d < bed) {
        bed = d;
        be = e;
        bt = t;
      }
    }
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
  if (boundaryNoEdge)
    report_.warnings.push_back(
        std::to_string(boundaryNoEdge) +
        " nodes on the mesh's boundary lie on no CAD edge of their face; they are kept fixed "
        "(e.g. node " +
        std::to_string(firstBoundaryNoEdge) + ")");
  if (unplaced)
    report_.warnings.push_back(
        std::to_string(unplaced) +
        " nodes touch elements of several faces but lie on none of their common CAD edges or "
        "vertices; they are kept fixed (e.g. node " +
        std::to_string(firstUnplaced) + ")");

  // ---- 4. the SurfaceMesh -------------------------------------------------------------------
  surfaces_.reserve(static_cast<std::size_t>(NF));
  for (int f = 0; f < NF; ++f) surfaces_.push_back(S.surface(f).clone());
  curves_.reserve(static_cast<std::size_t>(NE));
  for (int e = 0; e < NE; ++e) curves_.push_back(S.curve(e).clone());
  SurfaceMesh& M = mesh_;
  for (auto& s : surfaces_) M.surfaces.push_back(s.get());
  for (auto& c : curves_) M.curves.push_back(c.get());
  M.faceOrientation.assign(static_cast<std::size_t>(NF), 1);
  M.xyz = input.nodes;
  M.uv.assign(N, Vec2::Zero());
  M.nodeFace.assign(N, -1);
  M.nodeEdge.assign(N, -1);
  M.nodeT.assign(N, 0.0);
  M.nodeKind.assign(N, NodeKind::Fixed);
  for (std::size_t n = 0; n < N; ++n) {
    const NodeClass c = report_.nodeClass[n];
    const bool inElements = !elemFacesOfNode[n].empty();
    if (c == NodeClass::Face) {
      M.nodeFace[n] = report_.nodeEntity[n];
      M.uv[n] = nodeUV[n];
      M.nodeKind[n] = NodeKind::Face;
      ++report_.faceNodes;
    } else if (c == NodeClass::Edge) {
      M.nodeEdge[n] = report_.nodeEntity[n];
      M.nodeT[n] = report_.nodeParam[n];
      if (slide) M.nodeKind[n] = NodeKind::Edge;
      ++report_.edgeNodes;
    } else if (c == NodeClass::Vertex) {
      ++report_.vertexNodes;
      if (isPole[n]) ++report_.poleNodes;
    } else if (!inElements) {
      ++report_.unusedNodes;
    }
    if (M.nodeKind[n] == NodeKind::Fixed) ++report_.fixedNodes;
    if (M.nodeKind[n] == NodeKind::Edge) ++report_.slidingNodes;
  }
  if (!report_.looseNodes.empty()) report_.warnings.push_back(looseNodesNote(report_));
  // High-order nodes beyond the tolerance (kHighOrderReach) go to their nearest point on their
  // face, edge or vertex: the run must start, and end, with every node on the shape.
  {
    std::size_t worst = 0;
    double worstD = -1.0;
    for (std::size_t n = 0; n < N; ++n) {
      if (!(reach[n] > 0.0)) continue;
      const NodeClass c = report_.nodeClass[n];
      Vec3 x;
      if (c == NodeClass::Face)
        x = surfaces_[static_cast<std::size_t>(M.nodeFace[n])]->value(M.uv[n].x(), M.uv[n].y());
      else if (c == NodeClass::Edge)
        x = curves_[static_cast<std::size_t>(M.nodeEdge[n])]->value(M.nodeT[n]);
      else if (c == NodeClass::Vertex)
        x = S.vertexPoint(report_.nodeEntity[n]);
      else
        continue;
      const double d = (x - input.nodes[n]).norm();
      if (!(d > tol)) continue;
      M.xyz[n] = x;
      report_.placedNodes.push_back(static_cast<std::int32_t>(n));
      if (d > worstD) {
        worstD = d;
        worst = n;
      }
    }
    if (!report_.placedNodes.empty()) {
      std::ostringstream os;
      os << report_.placedNodes.size() << " high-order node(s) lie farther than the tolerance "
         << tol << " from their face, within their element's longest side (worst: node " << worst
         << " at " << worstD << ", " << worstD / diag
         << " x diagonal); they are taken at their nearest point on their "
         << nodeClassName(report_.nodeClass[worst])
         << " (a mesher that curves elements places a side node at the midpoint of its ends "
            "in (u,v), outside the face where its boundary is concave)";
      report_.warnings.push_back(os.str());
    }
  }

  // Corner (u,v) of every element node on the element's face, in parallel over the elements
  // (each thread with its own copies of the surfaces and curves). The orientation votes
  // (section 5) are taken in the same pass, from the same first derivatives at the corners.
  std::vector<Vec2> allCornerUV(input.conn.size());
  std::vector<signed char> vote(E, 0);  // +1: winding along the surface normal, −1: against
  parallelFor(E, projectors, [&](std::size_t e, Projector& pr) {
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
      if (report_.nodeClass[n] == NodeClass::Face && report_.nodeEntity[n] == f) {
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
      const NodeClass c = report_.nodeClass[n];
      try {
        if (c == NodeClass::Edge) {
          const int ed = report_.nodeEntity[n];
          const auto& ef = S.edgeFaces(ed);
          if (std::binary_search(ef.begin(), ef.end(), f)) {
            uv = pr.curveCopy(ed).uvOnFace(f, report_.nodeParam[n], haveRef ? ref : Vec2::Zero());
            ok = uv.allFinite();
          }
        } else if (c == NodeClass::Vertex) {
          const int v = report_.nodeEntity[n];
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
      const Vec2& c = corner[static_cast<std::size_t>(k)];
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
    auto X = [&](int k) { return input.nodes[static_cast<std::size_t>(nd[k])]; };
    const Vec3 g =
        nc == 4 ? Vec3((X(2) - X(0)).cross(X(3) - X(1))) : Vec3((X(1) - X(0)).cross(X(2) - X(0)));
    Vec3 nsum = Vec3::Zero();
    for (int k = 0; k < nc; ++k) nsum += surf.normalOf(cornerD1[static_cast<std::size_t>(k)]);
    const double sd = g.dot(nsum);
    vote[e] = sd > 0 ? 1 : sd < 0 ? -1 : 0;
  });
  std::vector<std::int64_t> agree(static_cast<std::size_t>(NF), 0),
      disagree(static_cast<std::size_t>(NF), 0);
  report_.faceElements.assign(static_cast<std::size_t>(NF), 0);
  for (std::size_t e = 0; e < E; ++e) {
    const std::size_t f = static_cast<std::size_t>(elemFace[e]);
    ++report_.faceElements[f];
    if (vote[e] > 0) ++agree[f];
    if (vote[e] < 0) ++disagree[f];
  }

  // ---- 5. orientation: faces meshed with the opposite winding ---------------------------------
  // A face's winding is not decided by its own elements alone: on a small face, tangled
  // elements can outvote the rest (a perturbed 9-element face with 5 inverted read as flipped,
  // then untangled towards its mirror image). Two faces meeting along a mesh edge are related
  // whatever the node positions: if the two elements there run along the edge in opposite
  // directions (the mesh is wound consistently across it), both faces have the same winding
  // against their outward normals, else opposite ones. Those relations (a majority over each
  // pair's shared edges) tie the faces of a connected part of the mesh together, and all the
  // elements of that part vote once for its winding. A part whose relations contradict each
  // other (a mesh not wound consistently, or a shell whose faces are not oriented alike) keeps
  // the per-face votes.
  std::vector<int> windingSign;
  {
    windingSign = faceWindingSigns(manifoldEdges, elemFace, NF, agree, disagree);
    report_.miswoundElements = miswoundElements(manifoldEdges, elemFace);
  }
  if (!report_.miswoundElements.empty()) {
    const std::int32_t e0 = report_.miswoundElements[0];
    report_.warnings.push_back(
        std::to_string(report_.miswoundElements.size()) +
        " element(s) are wound against the rest of their face's mesh (their nodes listed in "
        "the opposite order, e.g. element " +
        std::to_string(e0) + " on " + faceName(elemFace[static_cast<std::size_t>(e0)]) +
        "): they are tangled whatever their node positions, and moving nodes would only fold "
        "the mesh over them. Reverse their node order (e.g. FreeCAD's Mesh > Analyze > "
        "Evaluate and repair > Orientation)");
  }
  report_.faceFlipped.assign(static_cast<std::size_t>(NF), 0);
  for (int f = 0; f < NF; ++f) {
    const std::size_t fi = static_cast<std::size_t>(f);
    if (report_.faceElements[fi] > 0) ++report_.facesUsed;
    if (windingSign[fi] < 0) {
      M.faceOrientation[fi] = -1;
      report_.faceFlipped[fi] = 1;
      report_.flippedFaces.push_back(f);
    }
  }

  // ---- trimming curves off their 3D edges (imported B-reps) ----------------------------------
  // On the faces carrying elements: the largest distance from the surface's image of each
  // edge's pcurve to the edge's 3D curve (trimCurveGap). Beyond twice the edge's tolerance
  // (and 1e-6·diag: isTrimGap) the face's 2D domain is not the face its 3D edges bound; the
  // face's contains() keeps moves out of the strip between them (OccFaceSurface).
  {
    std::vector<std::pair<int, int>> uses;  // (face, edge)
    for (int f = 0; f < NF; ++f)
      if (report_.faceElements[static_cast<std::size_t>(f)] > 0)
        for (int e : S.faceEdges(f))
          if (!S.isDegeneratedEdge(e) && !S.isSeam(e, f)) uses.emplace_back(f, e);
    std::vector<double> gap(uses.size(), 0.0);
    parallelFor(uses.size(), projectors, [&](std::size_t k, Projector&) {
      const auto [f, e] = uses[k];
      gap[k] = trimCurveGap(S.edge(e), S.face(f), kTrimGapSamples);
    });
    std::size_t worst = 0;
    for (std::size_t k = 0; k < uses.size(); ++k) {
      const double tolE = BRep_Tool::Tolerance(S.edge(uses[k].second));
      if (!isTrimGap(gap[k], tolE, diag)) continue;
      report_.trimGaps.push_back({uses[k].first, uses[k].second, gap[k], tolE});
      if (gap[k] > report_.trimGaps[worst].gap) worst = report_.trimGaps.size() - 1;
    }
    if (!report_.trimGaps.empty()) {
      const BridgeReport::TrimGap& w = report_.trimGaps[worst];
      std::ostringstream os;
      os << report_.trimGaps.size()
         << " trimming curve(s) of faces with elements lie off their 3D edges by more than twice "
            "the edges' tolerance (an imported B-rep whose 2D and 3D boundaries disagree): up "
            "to "
         << w.gap << " (" << w.gap / diag << " x diagonal), the trimming curve of edge " << w.edge
         << " on face " << w.face << " (tolerance " << w.tolerance
         << "). Moves keep nodes out of the strip between such a trimming curve and its 3D "
            "edge, so they stay inside the face's 3D boundary (nodes the mesh put in that "
            "strip move only out of it)";
      report_.warnings.push_back(os.str());
    }
  }

  // ---- elements -------------------------------------------------------------------------------
  M.elemType.reserve(E);
  M.elemFace.reserve(E);
  M.elemOffset.reserve(E + 1);
  M.elemNodes.reserve(input.conn.size());
  M.cornerUV.reserve(input.conn.size());
  for (std::size_t e = 0; e < E; ++e)
    M.addElement(input.types[e], input.conn.data() + offsets[e], elemFace[e],
                 allCornerUV.data() + offsets[e]);
  M.validate();

  report_.maxDistance = 0.0;
  for (std::size_t n = 0; n < N; ++n)
    if (report_.nodeDistance[n] > report_.maxDistance || report_.worstNode < 0) {
      report_.maxDistance = report_.nodeDistance[n];
      report_.worstNode = static_cast<std::int32_t>(n);
    }
  report_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace surfmesh
