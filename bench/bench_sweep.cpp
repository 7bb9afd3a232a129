// SurfMesh benchmark — one optimization run on a structured mesh of an analytic or OCC surface:
// time per sweep, sweeps to convergence, the surface-evaluation floor (one first-derivative
// evaluation per free node), the value floor (that plus one shape value of each triangle around
// each free node) and peak memory per element. One run per process, so that the
// peak memory belongs to this mesh size only; bench/run.sh drives the sizes and thread counts.
//
//   bench_sweep --surface torus|occ-torus|occ-bspline --elements 100000 --threads 2
//               [--tangled-fraction 0.02] [--max-sweeps 100] [--omega 1.9] [--header]
//
// Prints one '|'-separated table row (see --header for the columns).
#include "bench_common.h"
#include "surfmesh/cad/occ_surface.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/mesh/quality.h"
#include "surfmesh/optimize/optimizer.h"

#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepPrimAPI_MakeTorus.hxx>
#include <Geom_BSplineSurface.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

using namespace surfmesh;
using namespace surfmesh::bench;

namespace {

const double kPi = 3.14159265358979323846;

std::unique_ptr<Surface> makeSurface(const std::string& kind) {
  if (kind == "torus") return std::make_unique<TorusSurface>(10.0, 4.0);
  if (kind == "occ-torus") {
    BRepPrimAPI_MakeTorus mk(10.0, 4.0);
    TopExp_Explorer ex(mk.Shape(), TopAbs_FACE);
    return std::make_unique<OccFaceSurface>(TopoDS::Face(ex.Current()), 0);
  }
  if (kind == "occ-bspline") {
    // A wavy bicubic B-spline patch over [0,40] × [0,40] (10 × 10 poles).
    const int n = 10;
    TColgp_Array2OfPnt poles(1, n, 1, n);
    for (int i = 1; i <= n; ++i)
      for (int j = 1; j <= n; ++j)
        poles.SetValue(i, j,
                       gp_Pnt(40.0 * (i - 1) / (n - 1), 40.0 * (j - 1) / (n - 1),
                              3.0 * std::sin(0.9 * i) * std::cos(0.7 * j)));
    TColStd_Array1OfReal knots(1, n - 2);
    TColStd_Array1OfInteger mults(1, n - 2);
    for (int k = 1; k <= n - 2; ++k) {
      knots.SetValue(k, static_cast<double>(k - 1) / (n - 3));
      mults.SetValue(k, (k == 1 || k == n - 2) ? 4 : 1);
    }
    Handle(Geom_BSplineSurface) bs =
        new Geom_BSplineSurface(poles, knots, knots, mults, mults, 3, 3);
    BRepBuilderAPI_MakeFace mf(bs, 1e-7);
    return std::make_unique<OccFaceSurface>(mf.Face(), 0);
  }
  std::fprintf(stderr, "unknown surface '%s'\n", kind.c_str());
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  std::string kind = "torus", measureName = "shape";
  double elements = 1e5, tangledFraction = 0.02;
  int threads = 1, maxSweeps = 100;
  double omega = OptimizeOptions().overRelaxation;
  bool header = false, trace = false;
  for (int a = 1; a < argc; ++a) {
    const std::string k = argv[a];
    auto next = [&]() { return a + 1 < argc ? std::string(argv[++a]) : std::string(); };
    if (k == "--surface")
      kind = next();
    else if (k == "--elements")
      elements = std::atof(next().c_str());
    else if (k == "--threads")
      threads = std::atoi(next().c_str());
    else if (k == "--tangled-fraction")
      tangledFraction = std::atof(next().c_str());
    else if (k == "--max-sweeps")
      maxSweeps = std::atoi(next().c_str());
    else if (k == "--omega")
      omega = std::atof(next().c_str());
    else if (k == "--header")
      header = true;
    else if (k == "--trace")
      trace = true;
    else if (k == "--measure")
      measureName = next();
    else {
      std::fprintf(stderr, "unknown argument %s\n", k.c_str());
      return 2;
    }
  }
  if (header) {
    std::printf(
        "| surface | elements | threads | tangled in→out | min q in→out | mean q out | "
        "sweeps | stop | optimize s | setup s | sweep 2 s | mean sweep s | floor s | "
        "sweep2/floor | mean/floor | value floor s | mean/value floor | peak MB | bytes/elem |\n");
    std::printf(
        "|---|---:|---:|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        "---:|\n");
    return 0;
  }
  const std::unique_ptr<Surface> surf = makeSurface(kind);
  const ParamBounds b = surf->bounds();
  const bool uPer = surf->isUPeriodic(), vPer = surf->isVPeriodic();
  // Cells: aspect so that 3D cells are roughly square (torus: 2π·10 × 2π·4 → nu/nv = 2.5).
  const double aspect = kind == "occ-bspline" ? 1.0 : 2.5;
  const int nv = std::max(4, static_cast<int>(std::lround(std::sqrt(elements / 2.0 / aspect))));
  const int nu = std::max(4, static_cast<int>(std::lround(elements / 2.0 / nv)));
  SurfaceMesh mesh;
  {
    Grid g = structuredGrid(nu, nv, b.umin, uPer ? b.umin + surf->uPeriod() : b.umax, b.vmin,
                            vPer ? b.vmin + surf->vPeriod() : b.vmax, uPer, vPer);
    mesh = makeSingleSurfaceMesh(*surf, g.uv, ElementType::Tri3, g.conn, g.fixed);
  }
  const double cellU = ((uPer ? surf->uPeriod() : b.umax - b.umin)) / nu;
  const double cellV = ((vPer ? surf->vPeriod() : b.vmax - b.vmin)) / nv;
  perturb(mesh, *surf, cellU, cellV, 0.3, tangledFraction, 1.3, 7);

  // Floors (bench_common.h): one first-derivative evaluation per free node, and that plus one
  // shape value of each triangle around it.
  const Floors floors = measureFloors(mesh);
  const double floorSec = floors.d1;

  OptimizeOptions opt;
  opt.threads = threads;
  opt.measure = measureName;
  opt.maxSweeps = maxSweeps;
  opt.overRelaxation = omega;
  std::vector<double> stamps;
  stamps.reserve(static_cast<std::size_t>(maxSweeps) + 1);
  const double tStart = now();
  const OptimizeResult r = optimizeMesh(mesh, opt, [&](const OptimizeProgress& p) {
    stamps.push_back(now());
    if (trace)
      std::fprintf(stderr, "sweep %3d  f %.9e  tangled %zu  min q %.6f  delta %.3g\n", p.sweep,
                   p.objective, p.tangled, p.minQuality, p.delta);
    return true;
  });
  const double tEnd = now();
  // Setup ≈ optimize time − time of the sweeps measured between callbacks (sweep 1 included
  // in the setup estimate, so "setup" is an upper bound).
  const double sweep2 = stamps.size() >= 2 ? stamps[1] - stamps[0] : tEnd - tStart;
  const double meanSweep =
      stamps.size() >= 2 ? (stamps.back() - stamps.front()) / (stamps.size() - 1) : tEnd - tStart;
  const double setup = (stamps.empty() ? tEnd : stamps.front()) - tStart - meanSweep;
  if (trace) {
    const MeshQuality mq = measureQuality(mesh, measureByName("shape"));
    std::size_t w = 0;
    for (std::size_t e = 0; e < mq.quality.size(); ++e)
      if (mq.quality[e] < mq.quality[w]) w = e;
    std::fprintf(stderr, "worst element %zu q %.4f\n", w, mq.quality[w]);
    for (int k = 0; k < 3; ++k) {
      const std::size_t i = static_cast<std::size_t>(mesh.elementNodes(w)[k]);
      std::fprintf(stderr, "  node %zu uv %.5f %.5f  corner uv %.5f %.5f  xyz %.4f %.4f %.4f\n", i,
                   mesh.uv[i].x(), mesh.uv[i].y(), mesh.elementUV(w)[k].x(),
                   mesh.elementUV(w)[k].y(), mesh.xyz[i].x(), mesh.xyz[i].y(), mesh.xyz[i].z());
    }
  }
  const double peak = peakRssBytes();
  std::printf(
      "| %s | %zu | %d | %zu→%zu | %.3f→%.3f | %.4f | %d | %s | %.3f | %.3f | %.4f | "
      "%.4f | %.5f | %.2f | %.2f | %.5f | %.2f | %.0f | %.0f |\n",
      kind.c_str(), mesh.elementCount(), r.threadsUsed, r.before.tangled, r.after.tangled,
      r.before.min, r.after.min, r.after.mean, r.sweeps, stopReasonName(r.reason), r.seconds, setup,
      sweep2, meanSweep, floorSec, sweep2 / floorSec, meanSweep / floorSec, floors.value,
      meanSweep / floors.value, peak / 1e6, peak / mesh.elementCount());
  return 0;
}
