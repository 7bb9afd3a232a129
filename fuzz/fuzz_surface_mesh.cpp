// SurfMesh fuzz target: SurfaceMesh arrays on analytic surfaces → validate() → quality →
// optimizer.
//
// The input bytes choose a surface (plane, cylinder, sphere with poles, torus), either a valid
// structured mesh followed by a list of mutations of its raw arrays (node positions and (u,v),
// NaN/inf, connectivity, element types and offsets, faces, node kinds, corner (u,v), swapped
// nodes = tangled elements), or fully random arrays. Contract checked:
//   * validate() either accepts the mesh or throws std::invalid_argument (any other exception
//     or a sanitizer report is a bug);
//   * on an accepted mesh, measureQuality gives q ∈ [0, 1] for every element and optimizeMesh
//     runs without error; afterwards the mesh is still valid, face nodes lie on their surface,
//     fixed nodes did not move, and in monotone mode a valid mesh's minimum quality did not
//     decrease.
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"
#include "surfmesh/optimize/optimizer.h"

#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <vector>

using namespace surfmesh;

namespace {

const double kPi = 3.14159265358979323846;

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "contract violated: %s\n", what);
  std::abort();
}

double special(FuzzedDataProvider& fdp) {
  switch (fdp.ConsumeIntegralInRange<int>(0, 5)) {
    case 0:
      return std::numeric_limits<double>::quiet_NaN();
    case 1:
      return std::numeric_limits<double>::infinity();
    case 2:
      return -std::numeric_limits<double>::infinity();
    case 3:
      return 1e300;
    case 4:
      return 0.0;
    default:
      return fdp.ConsumeFloatingPoint<double>();
  }
}

struct Grid {
  std::vector<Vec2> uv;
  std::vector<std::int32_t> conn;
  std::vector<std::int32_t> fixed;
};

/// Structured triangulation of [u0,u1]×[v0,v1] with nu×nv cells; periodic in u (and v)
/// when asked; non-periodic boundary nodes fixed.
Grid grid(int nu, int nv, double u0, double u1, double v0, double v1, bool uPer, bool vPer) {
  Grid g;
  const int cu = uPer ? nu : nu + 1, cv = vPer ? nv : nv + 1;
  for (int j = 0; j < cv; ++j)
    for (int i = 0; i < cu; ++i) {
      g.uv.emplace_back(u0 + (u1 - u0) * i / nu, v0 + (v1 - v0) * j / nv);
      if ((!uPer && (i == 0 || i == nu)) || (!vPer && (j == 0 || j == nv)))
        g.fixed.push_back(static_cast<std::int32_t>(g.uv.size() - 1));
    }
  auto id = [&](int i, int j) { return (j % cv) * cu + (i % cu); };
  for (int j = 0; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i, j + 1), d = id(i + 1, j + 1);
      g.conn.insert(g.conn.end(), {a, b, d, a, d, c});
    }
  return g;
}

void mutate(FuzzedDataProvider& fdp, SurfaceMesh& m, const Surface& s) {
  // Phase 1, on a valid mesh: move nodes in (u,v) on the surface (tangles elements).
  const int moves = fdp.ConsumeIntegralInRange<int>(0, 8);
  for (int k = 0; k < moves && !m.xyz.empty(); ++k) {
    const std::size_t n = fdp.ConsumeIntegralInRange<std::size_t>(0, m.xyz.size() - 1);
    const double du = fdp.ConsumeFloatingPointInRange<double>(-1.0, 1.0);
    const double dv = fdp.ConsumeFloatingPointInRange<double>(-1.0, 1.0);
    m.uv[n] = s.clampToBounds(s.wrap(m.uv[n] + Vec2(du, dv)));
  }
  if (moves > 0) syncFaceNodes(m);
  // Phase 2: corrupt the raw arrays.
  const int count = fdp.ConsumeIntegralInRange<int>(0, 12);
  for (int k = 0; k < count && fdp.remaining_bytes() > 0; ++k) {
    const std::size_t N = m.xyz.size(), E = m.elemType.size(), C = m.elemNodes.size();
    if (N == 0 || E == 0 || C == 0) return;
    const std::size_t n = fdp.ConsumeIntegralInRange<std::size_t>(0, N - 1);
    const std::size_t e = fdp.ConsumeIntegralInRange<std::size_t>(0, E - 1);
    const std::size_t c = fdp.ConsumeIntegralInRange<std::size_t>(0, C - 1);
    switch (fdp.ConsumeIntegralInRange<int>(0, 17)) {
      case 0:
      case 1:
      case 2:  // the node's (u,v) alone (position no longer φ(u,v))
        m.uv[n] += Vec2(fdp.ConsumeFloatingPointInRange<double>(-1.0, 1.0), 0.0);
        break;
      case 3:
        m.xyz[n][fdp.ConsumeIntegralInRange<int>(0, 2)] = special(fdp);
        break;
      case 4:
        m.uv[n][fdp.ConsumeIntegralInRange<int>(0, 1)] = special(fdp);
        break;
      case 5:
        m.elemNodes[c] = fdp.ConsumeIntegralInRange<std::int32_t>(-3, static_cast<int>(N) + 3);
        break;
      case 6:
        m.elemNodes[c] = m.elemNodes[fdp.ConsumeIntegralInRange<std::size_t>(0, C - 1)];
        break;
      case 7:
        m.elemType[e] = static_cast<ElementType>(fdp.ConsumeIntegral<std::uint8_t>());
        break;
      case 8:
        m.elemOffset[fdp.ConsumeIntegralInRange<std::size_t>(0, E)] =
            fdp.ConsumeIntegralInRange<std::int64_t>(-2, static_cast<std::int64_t>(C) + 2);
        break;
      case 9:
        m.elemFace[e] = fdp.ConsumeIntegralInRange<std::int32_t>(-2, 2);
        break;
      case 10:
        m.nodeKind[n] = static_cast<NodeKind>(fdp.ConsumeIntegralInRange<int>(0, 3));
        break;
      case 11:
        m.nodeFace[n] = fdp.ConsumeIntegralInRange<std::int32_t>(-2, 2);
        break;
      case 12:
        m.cornerUV[c][fdp.ConsumeIntegralInRange<int>(0, 1)] = special(fdp);
        break;
      case 13: {  // swap two nodes of an element (inverts it)
        const std::int64_t b = m.elemOffset[e];
        if (b >= 0 && b + 1 < static_cast<std::int64_t>(C))
          std::swap(m.elemNodes[static_cast<std::size_t>(b)],
                    m.elemNodes[static_cast<std::size_t>(b + 1)]);
        break;
      }
      case 14:  // a node's position off its (u,v)
        m.xyz[n] += Vec3(fdp.ConsumeFloatingPointInRange<double>(-1, 1), 0.0, 0.0);
        break;
      case 15:  // duplicate a node: a copy that takes over one element use
        m.xyz.push_back(m.xyz[n]);
        m.uv.push_back(m.uv[n]);
        m.nodeFace.push_back(m.nodeFace[n]);
        m.nodeKind.push_back(m.nodeKind[n]);
        m.elemNodes[c] = static_cast<std::int32_t>(N);
        break;
      case 16:  // drop the last element (arrays made inconsistent or not)
        m.elemType.pop_back();
        m.elemFace.pop_back();
        if (fdp.ConsumeBool()) m.elemOffset.pop_back();
        break;
      default:
        m.faceOrientation[0] = fdp.ConsumeIntegralInRange<int>(-2, 2);
        break;
    }
  }
}

/// With SURFMESH_FUZZ_DUMP set (replaying a reproducer), prints the mesh and the options
/// exactly (hex floats), ready to become a regression test.
void dump(const SurfaceMesh& m, const OptimizeOptions& o) {
  if (!std::getenv("SURFMESH_FUZZ_DUMP")) return;
  std::setvbuf(stdout, nullptr, _IONBF, 0);
  std::printf("options: measure %s maxSweeps %d monotone %d deltaPolicy %s\n", o.measure.c_str(),
              o.maxSweeps, o.monotone ? 1 : 0, o.deltaPolicy.c_str());
  std::printf("surface: %s\n", m.surfaces[0]->describe().c_str());
  std::printf("faceOrientation %d\n", m.faceOrientation[0]);
  for (std::size_t i = 0; i < m.nodeCount(); ++i)
    std::printf("node %zu kind %d face %d uv {%a, %a} xyz {%a, %a, %a}\n", i,
                static_cast<int>(m.nodeKind[i]), m.nodeFace[i], m.uv[i].x(), m.uv[i].y(),
                m.xyz[i].x(), m.xyz[i].y(), m.xyz[i].z());
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    std::printf("element %zu type %d face %d nodes", e, static_cast<int>(m.elemType[e]),
                m.elemFace[e]);
    for (int k = 0; k < m.elementSize(e); ++k) std::printf(" %d", m.elementNodes(e)[k]);
    std::printf(" cornerUV");
    for (int k = 0; k < m.elementSize(e); ++k)
      std::printf(" {%a, %a}", m.elementUV(e)[k].x(), m.elementUV(e)[k].y());
    std::printf("\n");
  }
}

void checkAccepted(FuzzedDataProvider& fdp, SurfaceMesh& m) {
  for (const char* name : {"shape", "oddy"}) {
    const MeshQuality q = measureQuality(m, measureByName(name));
    for (double v : q.quality)
      if (!(v >= 0.0 && v <= 1.0)) violated("quality outside [0, 1]");
  }
  OptimizeOptions o;
  o.measure = fdp.ConsumeBool() ? "shape" : "oddy";
  o.maxSweeps = fdp.ConsumeIntegralInRange<int>(0, 2);
  o.monotone = fdp.ConsumeBool();
  o.deltaPolicy = fdp.ConsumeBool() ? "auto" : "fixed";
  o.threads = 1;
  const SurfaceMesh before = m;
  dump(m, o);
  OptimizeResult r;
  try {
    r = optimizeMesh(m, o);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "optimizeMesh rejected a valid mesh: %s\n", e.what());
    violated("optimizeMesh threw on a mesh validate() accepted");
  }
  m.validate();  // must not throw
  for (std::size_t i = 0; i < m.nodeCount(); ++i) {
    if (m.nodeKind[i] == NodeKind::Fixed && m.xyz[i] != before.xyz[i])
      violated("a fixed node moved");
    if (m.nodeKind[i] == NodeKind::Face) {
      const Surface& s = *m.surfaces[static_cast<std::size_t>(m.nodeFace[i])];
      if (m.xyz[i] != before.xyz[i] &&
          (s.value(m.uv[i].x(), m.uv[i].y()) - m.xyz[i]).norm() > 1e-9 * (1 + m.xyz[i].norm()))
        violated("a moved face node is off its surface");
    }
  }
  if (std::getenv("SURFMESH_FUZZ_DUMP"))
    std::printf("before: min %.17g tangled %zu; after: min %.17g tangled %zu; %d sweeps (%s)\n",
                r.before.min, r.before.tangled, r.after.min, r.after.tangled, r.sweeps,
                stopReasonName(r.reason));
  if (o.monotone && r.before.tangled == 0 && r.after.min < r.before.min - 1e-9)
    violated("monotone mode lowered the minimum quality of a valid mesh");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const PlaneSurface plane;
  static const CylinderSurface cylinder(2.0, 0.0, 4.0);
  static const SphereSurface sphere(3.0);
  static const TorusSurface torus(10.0, 4.0);
  FuzzedDataProvider fdp(data, size);
  const int which = fdp.ConsumeIntegralInRange<int>(0, 3);
  const Surface& s = which == 0   ? static_cast<const Surface&>(plane)
                     : which == 1 ? static_cast<const Surface&>(cylinder)
                     : which == 2 ? static_cast<const Surface&>(sphere)
                                  : static_cast<const Surface&>(torus);
  SurfaceMesh m;
  try {
    if (fdp.ConsumeIntegralInRange<int>(0, 3) > 0) {
      // A valid structured mesh, then mutations.
      const int nu = fdp.ConsumeIntegralInRange<int>(1, 5);
      const int nv = fdp.ConsumeIntegralInRange<int>(1, 5);
      Grid g;
      switch (which) {
        case 0:
          g = grid(nu, nv, 0, 1, 0, 1, false, false);
          break;
        case 1:
          g = grid(nu + 2, nv, 0, 2 * kPi, 0, 4, true, false);
          break;
        case 2: {  // rings + fixed poles
          g = grid(nu + 2, nv + 1, 0, 2 * kPi, -1.2, 1.2, true, false);
          g.fixed.clear();
          const int cu = nu + 2, rings = nv + 2;
          const std::int32_t south = static_cast<std::int32_t>(g.uv.size());
          g.uv.emplace_back(0.0, -kPi / 2);
          g.uv.emplace_back(0.0, kPi / 2);
          g.fixed = {south, south + 1};
          for (int i = 0; i < cu; ++i) {
            g.conn.insert(g.conn.end(), {south, (i + 1) % cu, i});
            const int top = (rings - 1) * cu;
            g.conn.insert(g.conn.end(), {top + i, top + (i + 1) % cu, south + 1});
          }
          break;
        }
        default:
          g = grid(nu + 2, nv + 2, 0, 2 * kPi, 0, 2 * kPi, true, true);
          break;
      }
      m = makeSingleSurfaceMesh(s, g.uv, ElementType::Tri3, g.conn, g.fixed);
      mutate(fdp, m, s);
    } else {
      // Random arrays.
      const int N = fdp.ConsumeIntegralInRange<int>(0, 24);
      std::vector<Vec2> uv;
      for (int i = 0; i < N; ++i) {
        const ParamBounds b = s.bounds();
        const double lu = std::max(b.umin, -2.0), hu = std::min(b.umax, 2.0 * kPi);
        const double lv = std::max(b.vmin, -2.0), hv = std::min(b.vmax, 2.0 * kPi);
        uv.emplace_back(lu + (hu - lu) * fdp.ConsumeIntegralInRange<int>(0, 16) / 16.0,
                        lv + (hv - lv) * fdp.ConsumeIntegralInRange<int>(0, 16) / 16.0);
      }
      const int codes[4] = {0, 1, 2, 6};  // tri3, quad4, tri6, quad8
      const ElementType t = static_cast<ElementType>(codes[fdp.ConsumeIntegralInRange<int>(0, 3)]);
      const int k = nodeCount(t);
      std::vector<std::int32_t> conn;
      const int E = fdp.ConsumeIntegralInRange<int>(0, 16);
      for (int e = 0; e < E * k; ++e) conn.push_back(fdp.ConsumeIntegralInRange<int>(0, N));
      std::vector<std::int32_t> fixed;
      for (int i = 0; i < N; ++i)
        if (fdp.ConsumeBool()) fixed.push_back(i);
      m = makeSingleSurfaceMesh(s, uv, t, conn, fixed);
      mutate(fdp, m, s);
    }
  } catch (const std::invalid_argument&) {
    return 0;  // rejected while building: fine
  }
  try {
    m.validate();
  } catch (const std::invalid_argument&) {
    return 0;
  }
  // The optimizer is the slow part: run it on one accepted mesh in four.
  if (fdp.ConsumeIntegralInRange<int>(0, 3) == 0) {
    checkAccepted(fdp, m);
  } else {
    for (double v : measureQuality(m, measureByName("shape")).quality)
      if (!(v >= 0.0 && v <= 1.0)) violated("quality outside [0, 1]");
  }
  return 0;
}
