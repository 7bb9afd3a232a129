// SurfMesh — the CAD bridge (see cad_bridge.h for the algorithm).
#include "surfmesh/cad/cad_bridge.h"

#include "../common/threads.h"
#include "recovery.h"
#include "winding.h"

#include <BRep_Tool.hxx>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace surfmesh {

using cad_detail::assignElementFaces;
using cad_detail::Box;
using cad_detail::checkMeshOnShape;
using cad_detail::classifyNodes;
using cad_detail::cornerUVs;
using cad_detail::EdgePair;
using cad_detail::faceName;
using cad_detail::faceWindingSigns;
using cad_detail::fail;
using cad_detail::farHighOrderNodes;
using cad_detail::highOrderReach;
using cad_detail::kHighOrderReach;
using cad_detail::kInf;
using cad_detail::kNaN;
using cad_detail::locateNodes;
using cad_detail::looseNodesNote;
using cad_detail::meshTopology;
using cad_detail::miswoundElements;
using cad_detail::parallelFor;
using cad_detail::Projector;
using cad_detail::projectorGeometry;
using cad_detail::ProjectorPool;
using cad_detail::Recovery;
using cad_detail::reportHints;
using cad_detail::searchNodes;
using cad_detail::validateInput;

namespace {

/// Step 4: the SurfaceMesh's surfaces, curves and nodes.
void buildMeshNodes(const Recovery& r, BridgeReport& report,
                    std::vector<std::unique_ptr<Surface>>& surfaces,
                    std::vector<std::unique_ptr<Curve>>& curves, SurfaceMesh& M) {
  const CadShape& S = r.S;
  const MeshInput& input = r.input;
  const std::size_t N = r.N;
  const int NF = r.NF, NE = r.NE;
  const bool slide = r.slide;
  const std::vector<std::vector<int>>& elemFacesOfNode = r.elemFacesOfNode;
  const std::vector<Vec2>& nodeUV = r.nodeUV;
  const std::vector<unsigned char>& isPole = r.isPole;
  surfaces.reserve(static_cast<std::size_t>(NF));
  for (int f = 0; f < NF; ++f) surfaces.push_back(S.surface(f).clone());
  curves.reserve(static_cast<std::size_t>(NE));
  for (int e = 0; e < NE; ++e) curves.push_back(S.curve(e).clone());
  for (auto& s : surfaces) M.surfaces.push_back(s.get());
  for (auto& c : curves) M.curves.push_back(c.get());
  M.faceOrientation.assign(static_cast<std::size_t>(NF), 1);
  M.xyz = input.nodes;
  M.uv.assign(N, Vec2::Zero());
  M.nodeFace.assign(N, -1);
  M.nodeEdge.assign(N, -1);
  M.nodeT.assign(N, 0.0);
  M.nodeKind.assign(N, NodeKind::Fixed);
  for (std::size_t n = 0; n < N; ++n) {
    const NodeClass c = report.nodeClass[n];
    const bool inElements = !elemFacesOfNode[n].empty();
    if (c == NodeClass::Face) {
      M.nodeFace[n] = report.nodeEntity[n];
      M.uv[n] = nodeUV[n];
      M.nodeKind[n] = NodeKind::Face;
      ++report.faceNodes;
    } else if (c == NodeClass::Edge) {
      M.nodeEdge[n] = report.nodeEntity[n];
      M.nodeT[n] = report.nodeParam[n];
      if (slide) M.nodeKind[n] = NodeKind::Edge;
      ++report.edgeNodes;
    } else if (c == NodeClass::Vertex) {
      ++report.vertexNodes;
      if (isPole[n]) ++report.poleNodes;
    } else if (!inElements) {
      ++report.unusedNodes;
    }
    if (M.nodeKind[n] == NodeKind::Fixed) ++report.fixedNodes;
    if (M.nodeKind[n] == NodeKind::Edge) ++report.slidingNodes;
  }
}

/// High-order nodes beyond the tolerance (kHighOrderReach) go to their nearest point on their
/// face, edge or vertex: the run must start, and end, with every node on the shape.
void placeHighOrderNodes(const Recovery& r, BridgeReport& report,
                         const std::vector<std::unique_ptr<Surface>>& surfaces,
                         const std::vector<std::unique_ptr<Curve>>& curves, SurfaceMesh& M) {
  const CadShape& S = r.S;
  const MeshInput& input = r.input;
  const std::size_t N = r.N;
  const double diag = r.diag, tol = r.tol;
  const std::vector<double>& reach = r.reach;
  std::size_t worst = 0;
  double worstD = -1.0;
  for (std::size_t n = 0; n < N; ++n) {
    if (!(reach[n] > 0.0)) continue;
    const NodeClass c = report.nodeClass[n];
    Vec3 x;
    if (c == NodeClass::Face)
      x = surfaces[static_cast<std::size_t>(M.nodeFace[n])]->value(M.uv[n].x(), M.uv[n].y());
    else if (c == NodeClass::Edge)
      x = curves[static_cast<std::size_t>(M.nodeEdge[n])]->value(M.nodeT[n]);
    else if (c == NodeClass::Vertex)
      x = S.vertexPoint(report.nodeEntity[n]);
    else
      continue;
    const double d = (x - input.nodes[n]).norm();
    if (!(d > tol)) continue;
    M.xyz[n] = x;
    report.placedNodes.push_back(static_cast<std::int32_t>(n));
    if (d > worstD) {
      worstD = d;
      worst = n;
    }
  }
  if (!report.placedNodes.empty()) {
    Diagnostic d;
    d.code = code::kHighOrderNodesPlaced;
    d.count = static_cast<std::int64_t>(report.placedNodes.size());
    d.nodes = {static_cast<std::int64_t>(worst)};
    d.values = {{"tolerance", tol}, {"distance", worstD}, {"relative", worstD / diag}};
    d.format = std::string(
                   "{count} high-order node(s) lie farther than the tolerance {tolerance} from "
                   "their face, within their element's longest side (worst: node {node} at "
                   "{distance}, {relative} x diagonal); they are taken at their nearest point "
                   "on their ") +
               nodeClassName(report.nodeClass[worst]) +
               " (a mesher that curves elements places a side node at the midpoint of its ends "
               "in (u,v), outside the face where its boundary is concave)";
    report.warn(std::move(d));
  }
}

/// Step 5: the faces meshed with the opposite winding, and the elements wound against their
/// face's mesh.
void orientFaces(const Recovery& r, BridgeReport& report, SurfaceMesh& M) {
  const std::size_t E = r.E;
  const int NF = r.NF;
  const std::vector<std::int32_t>& elemFace = r.elemFace;
  const std::vector<signed char>& vote = r.vote;
  const std::vector<EdgePair>& manifoldEdges = r.manifoldEdges;
  std::vector<std::int64_t> agree(static_cast<std::size_t>(NF), 0),
      disagree(static_cast<std::size_t>(NF), 0);
  report.faceElements.assign(static_cast<std::size_t>(NF), 0);
  for (std::size_t e = 0; e < E; ++e) {
    const std::size_t f = static_cast<std::size_t>(elemFace[e]);
    ++report.faceElements[f];
    if (vote[e] > 0) ++agree[f];
    if (vote[e] < 0) ++disagree[f];
  }

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
    report.miswoundElements = miswoundElements(manifoldEdges, elemFace);
  }
  if (!report.miswoundElements.empty()) {
    const std::int32_t e0 = report.miswoundElements[0];
    Diagnostic d;
    d.code = code::kMiswoundElements;
    d.count = static_cast<std::int64_t>(report.miswoundElements.size());
    d.elements = {e0};
    d.faces = {elemFace[static_cast<std::size_t>(e0)]};
    d.format =
        "{count} element(s) are wound against the rest of their face's mesh (their nodes listed "
        "in the opposite order, e.g. element {element} on {face}): they are tangled whatever "
        "their node positions, and moving nodes would only fold the mesh over them. Reverse "
        "their node order (e.g. FreeCAD's Mesh > Analyze > Evaluate and repair > Orientation)";
    report.warn(std::move(d));
  }
  report.faceFlipped.assign(static_cast<std::size_t>(NF), 0);
  for (int f = 0; f < NF; ++f) {
    const std::size_t fi = static_cast<std::size_t>(f);
    if (report.faceElements[fi] > 0) ++report.facesUsed;
    if (windingSign[fi] < 0) {
      M.faceOrientation[fi] = -1;
      report.faceFlipped[fi] = 1;
      report.flippedFaces.push_back(f);
    }
  }
}

/// Trimming curves off their 3D edges (imported B-reps). On the faces carrying elements: the
/// largest distance from the surface's image of each edge's pcurve to the edge's 3D curve
/// (trimCurveGap). Beyond twice the edge's tolerance (and 1e-6·diag: isTrimGap) the face's 2D
/// domain is not the face its 3D edges bound; the face's contains() keeps moves out of the
/// strip between them (OccFaceSurface).
void reportTrimGaps(const Recovery& r, BridgeReport& report) {
  const CadShape& S = r.S;
  const int NF = r.NF;
  const double diag = r.diag;
  ProjectorPool& projectors = *r.projectors;
  std::vector<std::pair<int, int>> uses;  // (face, edge)
  for (int f = 0; f < NF; ++f)
    if (report.faceElements[static_cast<std::size_t>(f)] > 0)
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
    report.trimGaps.push_back({uses[k].first, uses[k].second, gap[k], tolE});
    if (gap[k] > report.trimGaps[worst].gap) worst = report.trimGaps.size() - 1;
  }
  if (!report.trimGaps.empty()) {
    const BridgeReport::TrimGap& w = report.trimGaps[worst];
    Diagnostic d;
    d.code = code::kTrimGaps;
    d.count = static_cast<std::int64_t>(report.trimGaps.size());
    d.edges = {w.edge};
    d.faces = {w.face};
    d.values = {{"gap", w.gap}, {"relative", w.gap / diag}, {"tolerance", w.tolerance}};
    d.format =
        "{count} trimming curve(s) of faces with elements lie off their 3D edges by more than "
        "twice the edges' tolerance (an imported B-rep whose 2D and 3D boundaries disagree): up "
        "to {gap} ({relative} x diagonal), the trimming curve of {edge} on {face} (tolerance "
        "{tolerance}). Moves keep nodes out of the strip between such a trimming curve and its "
        "3D edge, so they stay inside the face's 3D boundary (nodes the mesh put in that strip "
        "move only out of it)";
    report.warn(std::move(d));
  }
}

/// The SurfaceMesh's elements, and the totals of the report.
void addElements(const Recovery& r, BridgeReport& report, SurfaceMesh& M) {
  const MeshInput& input = r.input;
  const std::vector<std::int64_t>& offsets = r.offsets;
  const std::size_t N = r.N, E = r.E;
  const std::vector<std::int32_t>& elemFace = r.elemFace;
  const std::vector<Vec2>& allCornerUV = r.allCornerUV;
  M.elemType.reserve(E);
  M.elemFace.reserve(E);
  M.elemOffset.reserve(E + 1);
  M.elemNodes.reserve(input.conn.size());
  M.cornerUV.reserve(input.conn.size());
  for (std::size_t e = 0; e < E; ++e)
    M.addElement(input.types[e], input.conn.data() + offsets[e], elemFace[e],
                 allCornerUV.data() + offsets[e]);
  M.validate();

  report.maxDistance = 0.0;
  for (std::size_t n = 0; n < N; ++n)
    if (report.nodeDistance[n] > report.maxDistance || report.worstNode < 0) {
      report.maxDistance = report.nodeDistance[n];
      report.worstNode = static_cast<std::int32_t>(n);
    }
}

}  // namespace

void CadMesh::distancesToShape(const std::vector<Vec3>& points,
                               const std::vector<std::int32_t>& faces, std::vector<double>* toFace,
                               std::vector<double>* toShape) const {
  const CadShape& S = *shape_;
  if (faces.size() != points.size())
    fail(code::kBadLayout, "distancesToShape: " + std::to_string(faces.size()) + " faces for " +
                               std::to_string(points.size()) + " points");
  for (std::size_t k = 0; k < faces.size(); ++k)
    if (faces[k] < -1 || faces[k] >= S.faceCount())
      fail(code::kBadLayout, "distancesToShape: face " + std::to_string(faces[k]) + " of point " +
                                 std::to_string(k) + " out of range [-1, " +
                                 std::to_string(S.faceCount()) + ")");
  std::vector<Box> faceBoxes, edgeBoxes;
  std::vector<double> faceSlack;
  const double tol = report_.tolerance > 0.0 ? report_.tolerance : 1e-3 * S.diagonal();
  projectorGeometry(S, tol, &faceBoxes, &edgeBoxes, &faceSlack);
  const int threads = detail::resolveThreads(options_.threads);
  ProjectorPool projectors(threads, S, faceBoxes, edgeBoxes, faceSlack);
  toFace->assign(points.size(), kNaN);
  toShape->assign(points.size(), kNaN);
  // Below this a node is on the shape (what OCC's projections reach: 1e-14 to 1e-13 of the
  // diagonal); above it the edges' 3D curves are measured too.
  const double onShape = 1e-12 * S.diagonal();
  parallelFor(points.size(), projectors, [&](std::size_t k, Projector& pr) {
    if (!points[k].allFinite()) return;
    pr.resultDistances(faces[k], points[k], onShape, &(*toFace)[k], &(*toShape)[k]);
  });
}

MeshInput triangleMeshInput(const std::vector<double>& xyz, const std::vector<std::int32_t>& tris) {
  if (xyz.size() % 3 != 0) fail(code::kBadLayout, "xyz must hold 3 values per node");
  if (tris.size() % 3 != 0) fail(code::kBadLayout, "triangles must hold 3 node ids each");
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
  if (!shape_) fail(code::kBadOption, "no shape given");
  Recovery r(*shape_, input, options);
  validateInput(r);
  projectorGeometry(r.S, r.tol, &r.faceBoxes, &r.edgeBoxes, &r.faceSlack);
  r.projectors =
      std::make_unique<ProjectorPool>(r.threads, r.S, r.faceBoxes, r.edgeBoxes, r.faceSlack);
  highOrderReach(r);
  checkMeshOnShape(r);
  // 1. faces near every node (hints first), or those a recovery of the same nodes found
  if (sameNodes && sameNodes->nodeSearch_ &&
      sameNodes->nodeSearch_->matches(input, r.tol, options.toleranceHints))
    r.search = sameNodes->nodeSearch_;
  else
    r.search = searchNodes(r);
  if (options.keepNodeSearch) nodeSearch_ = r.search;
  farHighOrderNodes(r);
  locateNodes(r, report_);
  reportHints(r, report_);
  assignElementFaces(r, report_);  // 2. element faces
  meshTopology(r);                 // 3. node classes
  classifyNodes(r, report_);
  buildMeshNodes(r, report_, surfaces_, curves_, mesh_);  // 4. the SurfaceMesh
  if (!report_.looseNodes.empty()) report_.warn(looseNodesNote(report_));
  placeHighOrderNodes(r, report_, surfaces_, curves_, mesh_);
  cornerUVs(r, report_);
  orientFaces(r, report_, mesh_);  // 5. orientation
  reportTrimGaps(r, report_);
  addElements(r, report_, mesh_);
  report_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace surfmesh
