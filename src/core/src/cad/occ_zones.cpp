// SurfMesh — the tolerance zones of a face's boundary (OccFaceSurface::inBoundaryTolerance)
// and the trimming curves that lie off their 3D edges (trimCurveGap, see occ_surface.h).
#include "occ_trim.h"

#include <BRepAdaptor_Curve.hxx>
#include <BRepBndLib.hxx>
#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Extrema_ExtPC.hxx>
#include <Extrema_LocateExtPC.hxx>
#include <Geom2d_Curve.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_Surface.hxx>
#include <Precision.hxx>
#include <Standard_Failure.hxx>
#include <TopAbs_State.hxx>
#include <TopExp.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Vertex.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Vec.hxx>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace surfmesh {

using occ_detail::include;
using occ_detail::kEmptyBox;
using occ_detail::kInf;
using occ_detail::segmentDistance2;
using occ_detail::toVec;

namespace {

/// For the polyline of trimming-curve zone `ze` on `face`: the unit vectors N × T (the
/// surface's normal by the curve's tangent) at its points, turned to point into the face as
/// an independent classifier (BRepTopAdaptor_FClass2d) says 20 strips away on either side, by
/// majority (an edge's side of its face does not change along it); none when no point
/// decides (then the whole band counts as outside).
void findInwardSide(OccFaceSurface::ToleranceZones::Edge& ze, const TopoDS_Face& face,
                    const BRepAdaptor_Curve& c, double uvTol) {
  const Handle(Geom_Surface) gs = BRep_Tool::Surface(face);
  if (gs.IsNull()) return;
  BRepTopAdaptor_FClass2d cls(face, uvTol);
  std::vector<Vec3> m(ze.x.size(), Vec3::Zero());
  int votes = 0;
  const double r = 20.0 * ze.strip;
  for (std::size_t k = 0; k < ze.x.size(); ++k) {
    try {
      const gp_Pnt X(ze.x[k].x(), ze.x[k].y(), ze.x[k].z());
      GeomAPI_ProjectPointOnSurf pr(X, gs);
      if (pr.NbPoints() == 0) continue;
      double u = 0.0, v = 0.0;
      pr.LowerDistanceParameters(u, v);
      gp_Pnt p;
      gp_Vec du, dv, T;
      gs->D1(u, v, p, du, dv);
      c.D1(ze.t[k], p, T);
      const gp_Vec n = du.Crossed(dv).Crossed(T);
      if (!(n.Magnitude() > 0.0)) continue;
      const gp_Vec mk = n.Normalized();
      m[k] = Vec3(mk.X(), mk.Y(), mk.Z());
      if (k == 0 || k + 1 == ze.x.size()) continue;  // the ends: a corner's other edge
      const double E = du.Dot(du), F = du.Dot(dv), G = dv.Dot(dv), det = E * G - F * F;
      if (!(det > 0.0)) continue;
      const double a = (G * mk.Dot(du) - F * mk.Dot(dv)) / det;
      const double b = (E * mk.Dot(dv) - F * mk.Dot(du)) / det;
      const bool plus = cls.Perform(gp_Pnt2d(u + r * a, v + r * b)) == TopAbs_IN;
      const bool minus = cls.Perform(gp_Pnt2d(u - r * a, v - r * b)) == TopAbs_IN;
      votes += plus && !minus ? 1 : !plus && minus ? -1 : 0;
    } catch (const Standard_Failure&) {
    }
  }
  if (votes == 0) return;
  for (std::size_t k = 0; k < m.size(); ++k)  // a point without a normal: its neighbour's
    if (m[k].squaredNorm() == 0.0 && k > 0) m[k] = m[k - 1];
  for (std::size_t k = m.size(); k-- > 1;)
    if (m[k - 1].squaredNorm() == 0.0) m[k - 1] = m[k];
  if (m.front().squaredNorm() == 0.0) return;
  ze.inward.resize(m.size());
  for (std::size_t k = 0; k < m.size(); ++k) ze.inward[k] = votes > 0 ? m[k] : Vec3(-m[k]);
}

}  // namespace

namespace occ_detail {

std::unique_ptr<OccFaceSurface::ToleranceZones> buildToleranceZones(const TopoDS_Face& face,
                                                                    double diag, double uvTol) {
  using Zones = OccFaceSurface::ToleranceZones;
  auto z = std::make_unique<Zones>();
  TopTools_IndexedMapOfShape vertices, edges;
  TopExp::MapShapes(face, TopAbs_VERTEX, vertices);
  TopExp::MapShapes(face, TopAbs_EDGE, edges);
  const double wide = 2.0 * BRep_Tool::Tolerance(face);
  if (!(diag > 0.0)) {
    Bnd_Box b;
    BRepBndLib::Add(face, b, Standard_False);
    diag = b.IsVoid() ? 0.0 : std::sqrt(b.SquareExtent());
  }
  for (int k = 1; k <= vertices.Extent(); ++k) {
    const TopoDS_Vertex& v = TopoDS::Vertex(vertices(k));
    if (BRep_Tool::Tolerance(v) > wide)
      z->vertices.emplace_back(toVec(BRep_Tool::Pnt(v)), BRep_Tool::Tolerance(v));
  }
  for (int k = 1; k <= edges.Extent(); ++k) {
    const TopoDS_Edge& e = TopoDS::Edge(edges(k));
    if (BRep_Tool::Degenerated(e)) continue;  // its vertex's zone covers it
    Zones::Edge ze;
    ze.edge = e;
    ze.tol = BRep_Tool::Tolerance(e) > wide ? BRep_Tool::Tolerance(e) : 0.0;
    // A trimming curve off its 3D edge: between the curve's image and the 3D edge lies a
    // strip that the 2D boundary counts in and the 3D boundary out. Every point of it is
    // within the local gap of the 3D curve, so the points within 1.25 × the largest gap a
    // dense sampling finds (plus the edge's tolerance) on the curve's outer side hold it.
    if (!BRep_Tool::IsClosed(e, face)) {
      const double gap = trimCurveGap(e, face, kTrimGapSamples);
      if (isTrimGap(gap, BRep_Tool::Tolerance(e), diag)) {
        ze.trim = true;
        ze.edgeTol = BRep_Tool::Tolerance(e);
        ze.strip = 1.25 * std::max(gap, trimCurveGap(e, face, 64, true)) + ze.edgeTol;
      }
    }
    if (!(ze.tol > 0.0) && !ze.trim) continue;
    try {
      const BRepAdaptor_Curve c(e);
      const double f = c.FirstParameter(), l = c.LastParameter();
      if (!std::isfinite(f) || !std::isfinite(l) || !(l > f)) continue;
      auto at = [&](double t) { return toVec(c.Value(t)); };
      Box3 b = kEmptyBox;
      constexpr int kStart = 8;
      std::vector<double> ts;
      std::vector<Vec3> xs;
      for (int i = 0; i <= kStart; ++i) {
        ts.push_back(f + (l - f) * i / kStart);
        xs.push_back(at(ts.back()));
        include(b, xs.back());
      }
      const double size = std::sqrt((b[3] - b[0]) * (b[3] - b[0]) + (b[4] - b[1]) * (b[4] - b[1]) +
                                    (b[5] - b[2]) * (b[5] - b[2]));
      ze.dev = std::max(0.1 * std::max(ze.tol, ze.strip), 1e-4 * size);
      const double dev2 = ze.dev * ze.dev;
      ze.x.push_back(xs[0]);
      ze.t.push_back(ts[0]);
      struct Piece {
        double t0, t1;
        Vec3 p0, p1;
        int depth;
      };
      std::vector<Piece> stack;
      for (int i = kStart; i > 0; --i)  // popped in the curve's order
        stack.push_back({ts[static_cast<std::size_t>(i - 1)], ts[static_cast<std::size_t>(i)],
                         xs[static_cast<std::size_t>(i - 1)], xs[static_cast<std::size_t>(i)], 0});
      bool ok = true;
      while (!stack.empty() && ok) {
        const Piece pc = stack.back();
        stack.pop_back();
        const double tm = 0.5 * (pc.t0 + pc.t1);
        const Vec3 pm = at(tm);
        const bool fine = segmentDistance2(pc.p0, pc.p1, pm) <= dev2 &&
                          segmentDistance2(pc.p0, pc.p1, at(0.5 * (pc.t0 + tm))) <= dev2 &&
                          segmentDistance2(pc.p0, pc.p1, at(0.5 * (tm + pc.t1))) <= dev2;
        if (!fine && pc.depth < 20) {
          stack.push_back({tm, pc.t1, pm, pc.p1, pc.depth + 1});
          stack.push_back({pc.t0, tm, pc.p0, pm, pc.depth + 1});
          continue;
        }
        ok = pc.p1.allFinite() && ze.x.size() < 1000000;
        ze.x.push_back(pc.p1);
        ze.t.push_back(pc.t1);
      }
      if (!ok) continue;
      if (ze.trim) findInwardSide(ze, face, c, uvTol);
      const double grow = std::max(ze.tol, ze.strip) + ze.dev;
      const std::size_t segments = ze.x.size() - 1, K = Zones::kChunk;
      for (std::size_t c = 0; c * K < segments; ++c) {
        Box3 cb = kEmptyBox;
        for (std::size_t k = c * K; k <= std::min(segments, (c + 1) * K); ++k)
          include(cb, ze.x[k], grow);
        include(ze.box, cb);
        ze.chunkBoxes.push_back(cb);
      }
    } catch (const Standard_Failure&) {
      continue;  // no usable 3D curve
    }
    z->hasTrim |= ze.trim;
    z->edges.push_back(std::move(ze));
  }
  return z;
}
}  // namespace occ_detail

namespace {

/// Distance from p to curve c (edge e's): the nearest of its ends and of the minima
/// Extrema_ExtPC finds (the CAD recovery's tolerance hints measure it so); `fallback` when
/// OCC fails.
double curveDistance(const BRepAdaptor_Curve& c, const gp_Pnt& P, double fallback) {
  try {
    double d2 = std::min(c.Value(c.FirstParameter()).SquareDistance(P),
                         c.Value(c.LastParameter()).SquareDistance(P));
    Extrema_ExtPC ext(P, c);
    if (ext.IsDone())
      for (int i = 1; i <= ext.NbExt(); ++i)
        if (ext.IsMin(i)) d2 = std::min(d2, ext.SquareDistance(i));
    return std::sqrt(d2);
  } catch (const Standard_Failure&) {
    return fallback;
  }
}

}  // namespace

double trimCurveGap(const TopoDS_Edge& edge, const TopoDS_Face& face, int samples, bool ends) {
  double gap = 0.0;
  try {
    double a = 0.0, b = 0.0;
    const Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(edge, face, a, b);
    const Handle(Geom_Surface) gs = BRep_Tool::Surface(face);
    if (pc.IsNull() || gs.IsNull() || BRep_Tool::Degenerated(edge)) return 0.0;
    const BRepAdaptor_Curve c(edge);
    for (int i = ends ? -1 : 0; i < samples + (ends ? 1 : 0); ++i) {
      try {
        const double t = i < 0 ? a : i >= samples ? b : a + (b - a) * (i + 0.5) / samples;
        const gp_Pnt2d uv = pc->Value(t);
        gap = std::max(gap, curveDistance(c, gs->Value(uv.X(), uv.Y()), 0.0));
      } catch (const Standard_Failure&) {
      }
    }
  } catch (const Standard_Failure&) {
  }
  return gap;
}

bool isTrimGap(double gap, double edgeTolerance, double diag) {
  return gap > std::max(2.0 * edgeTolerance, 1e-6 * diag);
}
void OccFaceSurface::setShapeDiagonal(double diag) { trim_->shapeDiagonal = diag; }

bool OccFaceSurface::hasTrimGaps() const { return zones().hasTrim; }

bool OccFaceSurface::inBoundaryTolerance(const Vec3& p, bool trimOnly) const {
  const ToleranceZones& z = zones();
  if (!trimOnly)
    for (const auto& [x, tol] : z.vertices)
      if ((x - p).squaredNorm() <= tol * tol) return true;
  constexpr std::size_t K = ToleranceZones::kChunk;
  for (std::size_t ei = 0; ei < z.edges.size(); ++ei) {
    const ToleranceZones::Edge& e = z.edges[ei];
    if (trimOnly && !e.trim) continue;
    if (boxDistance2(e.box, p) > 0.0) continue;
    // The nearest polyline segment.
    double best2 = kInf;
    std::size_t seg = 0;
    const std::size_t segments = e.x.size() - 1;
    for (std::size_t c = 0; c < e.chunkBoxes.size(); ++c) {
      if (boxDistance2(e.chunkBoxes[c], p) > 0.0) continue;
      for (std::size_t k = c * K; k < std::min(segments, (c + 1) * K); ++k) {
        const double d2 = segmentDistance2(e.x[k], e.x[k + 1], p);
        if (d2 < best2) {
          best2 = d2;
          seg = k;
        }
      }
    }
    const double tolZone = trimOnly ? 0.0 : e.tol;  // the tolerance zone's radius asked
    const double reach = std::max(tolZone, e.strip) + e.dev;
    if (best2 > reach * reach) continue;  // farther than tol (and the strip) from the curve
    const double dp = std::sqrt(best2);
    if (dp + e.dev <= tolZone) return true;  // nearer than tol
    // In between: the curve decides, by a local search from the nearest segment (the curve
    // is within dev of the polyline there), the segment's ends (points of the curve) bound
    // it; the whole curve (the hints' distance) when the local search fails.
    if (!zoneCurves_) zoneCurves_ = std::make_unique<ZoneCurves>();
    auto& slot = zoneCurves_->curves;
    if (slot.size() < z.edges.size()) slot.resize(z.edges.size());
    if (!slot[ei]) slot[ei] = std::make_unique<BRepAdaptor_Curve>(e.edge);
    const BRepAdaptor_Curve& c = *slot[ei];
    const gp_Pnt P(p.x(), p.y(), p.z());
    double d = std::sqrt(std::min((e.x[seg] - p).squaredNorm(), (e.x[seg + 1] - p).squaredNorm()));
    bool located = false;
    double tl = 0.0, s = 0.0;
    gp_Pnt Q;
    try {
      const Vec3 a = e.x[seg], ab = e.x[seg + 1] - e.x[seg];
      const double l2 = ab.squaredNorm();
      s = l2 > 0.0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
      const double t0 = e.t[seg] + s * (e.t[seg + 1] - e.t[seg]);
      Extrema_LocateExtPC loc(P, c, t0, Precision::PConfusion());
      if (loc.IsDone() && loc.IsMin()) {
        tl = loc.Point().Parameter();
        if (tl >= e.t[seg] - (e.t[seg + 1] - e.t[seg]) &&
            tl <= e.t[seg + 1] + (e.t[seg + 1] - e.t[seg])) {
          d = std::min(d, std::sqrt(loc.SquareDistance()));
          Q = loc.Point().Value();
          located = true;
        }
      }
    } catch (const Standard_Failure&) {
    }
    if (!located) d = std::min(d, curveDistance(c, P, dp));
    if (d <= tolZone) return true;
    if (!e.trim || !(d <= e.strip)) continue;
    // The strip: outside when p lies on the curve's outer side, farther than the edge's
    // tolerance from it; beyond the curve's ends the neighbouring edges and the 2D boundary
    // judge. Without an inward side (or a located nearest point) the whole band is out.
    if (e.inward.empty() || !located) return true;
    const double f = c.FirstParameter(), l = c.LastParameter(), eps = 1e-9 * (l - f);
    if (tl <= f + eps || tl >= l - eps) continue;
    const Vec3 m = ((1.0 - s) * e.inward[seg] + s * e.inward[seg + 1]).normalized();
    const Vec3 q(Q.X(), Q.Y(), Q.Z());
    if ((p - q).dot(m) < 0.0 && d > e.edgeTol) return true;
  }
  return false;
}
}  // namespace surfmesh
