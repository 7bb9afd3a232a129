// SurfMesh fuzz target: the CAD bridge's mesh input and node classification (CadMesh) on
// small shapes, then quality and a short optimization.
//
// Shapes (made once): a box and a cylinder (BRepPrimAPI), a sphere (two poles: degenerated
// edges), a single planar face (free face, no solid), a box with a free edge beside it (a
// wire of no face: the nodes a FEM mesh's edge elements have there belong to no face element),
// tests/data/occt_screw.step, and the face of tests/data/nist_pmi_2.step (a STEP file of
// another CAD system) whose trimming curve lies farthest off its 3D edge. The input
// bytes pick a shape and either mutate a coarse BRepMesh triangulation of it (node positions
// moved a little, a lot, or to NaN/inf; connectivity entries; element type codes, including
// invalid ones; offsets; hints; dropped or added elements; nodes of no element added on a CAD
// edge, free or not) or build a small random mesh (tri3, quad4, tri6, tri10, quad8) from
// points on the shape. Options (tolerance, boundary mode) are fuzzed too. Contract checked:
//   * CadMesh either succeeds or throws std::invalid_argument (anything else, a crash or a
//     sanitizer report is a bug);
//   * on success: the SurfaceMesh validates, the report has one entry per node, qualities are
//     in [0, 1], and a short optimization runs with the fixed nodes untouched and the moved
//     face nodes on their surfaces and inside their faces' 3D boundaries (out of the strips
//     between trimming curves and their 3D edges); the nodes of no element are listed with
//     where they lie (within the tolerance) and stay where they are.
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/cad/occ_mesher.h"
#include "surfmesh/cad/occ_surface.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRep_Builder.hxx>
#include <TopoDS_Compound.hxx>
#include <fuzzer/FuzzedDataProvider.h>
#include <gp_Pln.hxx>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

using namespace surfmesh;

namespace {

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "contract violated: %s\n", what);
  std::abort();
}

struct Part {
  std::shared_ptr<CadShape> shape;
  MeshInput mesh;  // coarse BRepMesh triangulation
};

std::vector<Part> makeParts() {
  std::vector<Part> parts;
  auto add = [&](std::shared_ptr<CadShape> s, double relDeflection) {
    Part p;
    p.shape = std::move(s);
    p.mesh = meshWithBRepMesh(*p.shape, relDeflection * p.shape->diagonal(), 0.8).input;
    parts.push_back(std::move(p));
  };
  add(std::make_shared<CadShape>(BRepPrimAPI_MakeBox(10.0, 6.0, 4.0).Shape()), 0.05);
  add(std::make_shared<CadShape>(BRepPrimAPI_MakeCylinder(3.0, 8.0).Shape()), 0.05);
  add(std::make_shared<CadShape>(BRepPrimAPI_MakeSphere(4.0).Shape()), 0.05);
  add(std::make_shared<CadShape>(
          BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 0, 10, 0, 6).Face()),
      0.05);
  {
    BRep_Builder b;
    TopoDS_Compound c;
    b.MakeCompound(c);
    b.Add(c, BRepPrimAPI_MakeBox(10.0, 6.0, 4.0).Shape());
    b.Add(c, BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 7), gp_Pnt(10, 0, 7)).Edge());
    add(std::make_shared<CadShape>(c), 0.05);
  }
  try {
    add(CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/occt_screw.step"), 0.03);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz_cad_mesh: screw not loaded: %s\n", e.what());
  }
  try {  // a face whose 2D and 3D boundaries disagree, on its own
    const auto pmi = CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/nist_pmi_2.step");
    int best = -1;
    double worst = 0.0;
    for (int f = 0; f < pmi->faceCount(); ++f)
      for (int e : pmi->faceEdges(f)) {
        const double gap = trimCurveGap(pmi->edge(e), pmi->face(f), kTrimGapSamples);
        if (gap > worst) {
          worst = gap;
          best = f;
        }
      }
    if (best >= 0) add(std::make_shared<CadShape>(pmi->face(best)), 0.03);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz_cad_mesh: nist_pmi_2 not loaded: %s\n", e.what());
  }
  return parts;
}

double special(FuzzedDataProvider& fdp) {
  switch (fdp.ConsumeIntegralInRange<int>(0, 4)) {
    case 0:
      return std::numeric_limits<double>::quiet_NaN();
    case 1:
      return std::numeric_limits<double>::infinity();
    case 2:
      return -1e300;
    default:
      return fdp.ConsumeFloatingPointInRange<double>(-20.0, 20.0);
  }
}

void mutate(FuzzedDataProvider& fdp, MeshInput& in, const CadShape& shape) {
  const int count = fdp.ConsumeIntegralInRange<int>(0, 8);
  const double diag = shape.diagonal();
  for (int k = 0; k < count && fdp.remaining_bytes() > 0; ++k) {
    const std::size_t N = in.nodes.size(), E = in.types.size(), C = in.conn.size();
    if (N == 0 || E == 0 || C == 0) return;
    const std::size_t n = fdp.ConsumeIntegralInRange<std::size_t>(0, N - 1);
    const std::size_t e = fdp.ConsumeIntegralInRange<std::size_t>(0, E - 1);
    const std::size_t c = fdp.ConsumeIntegralInRange<std::size_t>(0, C - 1);
    switch (fdp.ConsumeIntegralInRange<int>(0, 15)) {
      case 0:
      case 1: {  // small move (within or near the tolerance)
        const double a = diag * 1e-3 * fdp.ConsumeFloatingPointInRange<double>(-3.0, 3.0);
        in.nodes[n][fdp.ConsumeIntegralInRange<int>(0, 2)] += a;
        break;
      }
      case 2:  // large move (off the shape, or onto another face)
        in.nodes[n][fdp.ConsumeIntegralInRange<int>(0, 2)] +=
            diag * fdp.ConsumeFloatingPointInRange<double>(-0.5, 0.5);
        break;
      case 3:
        in.nodes[n][fdp.ConsumeIntegralInRange<int>(0, 2)] = special(fdp);
        break;
      case 4:  // move onto another node (duplicate position)
        in.nodes[n] = in.nodes[fdp.ConsumeIntegralInRange<std::size_t>(0, N - 1)];
        break;
      case 5:
        in.conn[c] = fdp.ConsumeIntegralInRange<std::int32_t>(-2, static_cast<int>(N) + 2);
        break;
      case 6:
        in.conn[c] = in.conn[fdp.ConsumeIntegralInRange<std::size_t>(0, C - 1)];
        break;
      case 7:
        in.types[e] = static_cast<ElementType>(fdp.ConsumeIntegralInRange<int>(0, 9));
        break;
      case 8:  // explicit offsets, maybe wrong
        if (in.offsets.empty()) {
          in.offsets.push_back(0);
          for (ElementType t : in.types) {
            const int code = static_cast<int>(t);
            in.offsets.push_back(in.offsets.back() + (isElementTypeCode(code) ? nodeCount(t) : 3));
          }
        }
        in.offsets[fdp.ConsumeIntegralInRange<std::size_t>(0, in.offsets.size() - 1)] +=
            fdp.ConsumeIntegralInRange<int>(-3, 3);
        break;
      case 9: {  // hints, sometimes wrong
        auto& h =
            fdp.ConsumeBool() ? in.hintFace : (fdp.ConsumeBool() ? in.hintEdge : in.hintVertex);
        const int limit = &h == &in.hintFace   ? shape.faceCount()
                          : &h == &in.hintEdge ? shape.edgeCount()
                                               : shape.vertexCount();
        if (h.empty()) h.assign(N, -1);
        // The array may already be one short (below) or the nodes more (crash-269d252c: a
        // write past its end, in this harness).
        const std::int32_t hint = fdp.ConsumeIntegralInRange<std::int32_t>(-2, limit + 1);
        if (n < h.size()) h[n] = hint;
        if (fdp.ConsumeIntegralInRange<int>(0, 15) == 0) h.pop_back();
        break;
      }
      case 10:  // drop an element
        if (in.offsets.empty()) {
          const int code = static_cast<int>(in.types[e]);
          const int size = isElementTypeCode(code) ? nodeCount(in.types[e]) : 3;
          std::size_t begin = 0;
          for (std::size_t j = 0; j < e; ++j) {
            const int cj = static_cast<int>(in.types[j]);
            begin += isElementTypeCode(cj) ? static_cast<std::size_t>(nodeCount(in.types[j])) : 3;
          }
          if (begin + static_cast<std::size_t>(size) <= C) {
            in.conn.erase(in.conn.begin() + static_cast<std::ptrdiff_t>(begin),
                          in.conn.begin() + static_cast<std::ptrdiff_t>(begin + size));
            in.types.erase(in.types.begin() + static_cast<std::ptrdiff_t>(e));
          }
        }
        break;
      case 11:  // add an element from existing nodes
        in.types.push_back(ElementType::Tri3);
        for (int j = 0; j < 3; ++j)
          in.conn.push_back(fdp.ConsumeIntegralInRange<std::int32_t>(0, static_cast<int>(N) - 1));
        if (!in.offsets.empty()) in.offsets.push_back(in.offsets.back() + 3);
        break;
      case 12:  // add an unused node somewhere
        in.nodes.push_back(Vec3(special(fdp), special(fdp), special(fdp)));
        break;
      case 13:  // flip an element
        if (3 * e + 1 < C) std::swap(in.conn[3 * e], in.conn[3 * e + 1]);
        break;
      case 14: {  // a node of no element on a CAD edge (a free one too): an edge element's
        const int edge = fdp.ConsumeIntegralInRange<int>(0, shape.edgeCount() - 1);
        const OccEdgeCurve& cv = shape.curve(edge);
        const double t = fdp.ConsumeFloatingPointInRange<double>(0.0, 1.0);
        in.nodes.push_back(cv.value(cv.tmin() + t * (cv.tmax() - cv.tmin())));
        for (auto* h : {&in.hintFace, &in.hintEdge, &in.hintVertex})
          if (!h->empty()) h->push_back(-1);
        if (!in.leftOutNeighbour.empty()) in.leftOutNeighbour.push_back(0);
        break;
      }
      default:  // truncate the connectivity
        in.conn.resize(C - 1);
        break;
    }
  }
}

MeshInput randomMesh(FuzzedDataProvider& fdp, const MeshInput& pool) {
  MeshInput in;
  const int N = fdp.ConsumeIntegralInRange<int>(0, 12);
  for (int i = 0; i < N && !pool.nodes.empty(); ++i)
    in.nodes.push_back(
        pool.nodes[fdp.ConsumeIntegralInRange<std::size_t>(0, pool.nodes.size() - 1)]);
  const int E = fdp.ConsumeIntegralInRange<int>(0, 10);
  for (int e = 0; e < E; ++e) {
    const int codes[5] = {0, 1, 2, 3, 6};  // tri3, quad4, tri6, tri10, quad8
    const int code = codes[fdp.ConsumeIntegralInRange<int>(0, 4)];
    in.types.push_back(static_cast<ElementType>(code));
    for (int j = 0; j < nodeCount(in.types.back()); ++j)
      in.conn.push_back(fdp.ConsumeIntegralInRange<std::int32_t>(0, std::max(0, N - 1)));
  }
  return in;
}

void checkAccepted(FuzzedDataProvider& fdp, CadMesh& cm, std::size_t N) {
  SurfaceMesh& m = cm.mesh();
  m.validate();
  const BridgeReport& r = cm.report();
  if (r.nodeClass.size() != N || r.nodeEntity.size() != N || r.nodeDistance.size() != N)
    violated("report sizes differ from the node count");
  const std::size_t L = r.looseNodes.size();
  if (r.looseClass.size() != L || r.looseEntity.size() != L || r.looseDistance.size() != L ||
      L != r.unusedNodes)
    violated("the nodes of no element are not all listed with where they lie");
  for (std::size_t k = 0; k < L; ++k)
    if (!(r.looseDistance[k] <= r.tolerance) ||
        m.nodeKind[static_cast<std::size_t>(r.looseNodes[k])] != NodeKind::Fixed)
      violated("a node of no element is off the shape or not fixed");
  const MeshQuality q = measureQuality(m, measureByName("shape"));
  for (double v : q.quality)
    if (!(v >= 0.0 && v <= 1.0)) violated("quality outside [0, 1]");
  OptimizeOptions o;
  o.maxSweeps = fdp.ConsumeIntegralInRange<int>(0, 2);
  o.threads = 1;
  const std::vector<Vec3> x0 = m.xyz;
  try {
    optimizeMesh(m, o);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "optimizeMesh rejected a CadMesh: %s\n", e.what());
    violated("optimizeMesh threw on a mesh CadMesh built");
  }
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    if (m.nodeKind[i] == NodeKind::Fixed && m.xyz[i] != x0[i]) violated("a fixed node moved");
    if (m.nodeKind[i] == NodeKind::Face && m.xyz[i] != x0[i]) {
      const Surface& s = *m.surfaces[static_cast<std::size_t>(m.nodeFace[i])];
      if ((s.value(m.uv[i].x(), m.uv[i].y()) - m.xyz[i]).norm() > 1e-9 * cm.shape().diagonal())
        violated("a moved face node is off its surface");
      const auto* os = dynamic_cast<const OccFaceSurface*>(&s);
      if (os != nullptr && os->inTrimStrip(m.uv[i].x(), m.uv[i].y()))
        violated("a moved face node is outside its face's 3D boundary");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::vector<Part> parts = makeParts();
  FuzzedDataProvider fdp(data, size);
  const Part& part = parts[fdp.ConsumeIntegralInRange<std::size_t>(0, parts.size() - 1)];
  MeshInput in;
  if (fdp.ConsumeIntegralInRange<int>(0, 3) > 0) {
    in = part.mesh;
    mutate(fdp, in, *part.shape);
  } else {
    in = randomMesh(fdp, part.mesh);
  }
  BridgeOptions opt;
  opt.threads = 1;
  switch (fdp.ConsumeIntegralInRange<int>(0, 7)) {
    case 0:
      opt.tolerance = -1.0;
      break;
    case 1:
      opt.tolerance = std::numeric_limits<double>::quiet_NaN();
      break;
    case 2:
      opt.tolerance = part.shape->diagonal() * fdp.ConsumeFloatingPointInRange<double>(0.0, 0.2);
      break;
    default:
      break;  // automatic
  }
  const int b = fdp.ConsumeIntegralInRange<int>(0, 8);
  opt.boundary = b == 0 ? "sliding" : (b < 4 ? "slide" : "fixed");
  std::unique_ptr<CadMesh> cm;
  try {
    cm = std::make_unique<CadMesh>(part.shape, in, opt);
  } catch (const std::invalid_argument&) {
    return 0;
  }
  if (fdp.ConsumeIntegralInRange<int>(0, 3) == 0) checkAccepted(fdp, *cm, in.nodes.size());
  return 0;
}
