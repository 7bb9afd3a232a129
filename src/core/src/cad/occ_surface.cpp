// SurfMesh — OpenCASCADE face and edge adapters (see occ_surface.h).
#include "surfmesh/cad/occ_surface.h"

#include <BRepTools.hxx>
#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Tool.hxx>
#include <Geom2d_Curve.hxx>
#include <Precision.hxx>
#include <Standard_Failure.hxx>
#include <TopAbs_State.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Vertex.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Vec.hxx>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

namespace {

Vec3 toVec(const gp_Pnt& p) { return Vec3(p.X(), p.Y(), p.Z()); }
Vec3 toVec(const gp_Vec& v) { return Vec3(v.X(), v.Y(), v.Z()); }

const char* surfaceTypeName(GeomAbs_SurfaceType t) {
  switch (t) {
    case GeomAbs_Plane:
      return "Plane";
    case GeomAbs_Cylinder:
      return "Cylinder";
    case GeomAbs_Cone:
      return "Cone";
    case GeomAbs_Sphere:
      return "Sphere";
    case GeomAbs_Torus:
      return "Torus";
    case GeomAbs_BezierSurface:
      return "BezierSurface";
    case GeomAbs_BSplineSurface:
      return "BSplineSurface";
    case GeomAbs_SurfaceOfRevolution:
      return "SurfaceOfRevolution";
    case GeomAbs_SurfaceOfExtrusion:
      return "SurfaceOfExtrusion";
    case GeomAbs_OffsetSurface:
      return "OffsetSurface";
    default:
      return "OtherSurface";
  }
}

const char* curveTypeName(GeomAbs_CurveType t) {
  switch (t) {
    case GeomAbs_Line:
      return "Line";
    case GeomAbs_Circle:
      return "Circle";
    case GeomAbs_Ellipse:
      return "Ellipse";
    case GeomAbs_Hyperbola:
      return "Hyperbola";
    case GeomAbs_Parabola:
      return "Parabola";
    case GeomAbs_BezierCurve:
      return "BezierCurve";
    case GeomAbs_BSplineCurve:
      return "BSplineCurve";
    case GeomAbs_OffsetCurve:
      return "OffsetCurve";
    default:
      return "OtherCurve";
  }
}

// Shifts x by whole periods p to be as close as possible to ref.
double unwrapCoord(double x, double ref, double p) {
  if (p <= 0.0) return x;
  return x + p * std::round((ref - x) / p);
}

}  // namespace

std::string occSurfaceTypeName(const TopoDS_Face& face) {
  BRepAdaptor_Surface ad(face, Standard_False);
  return surfaceTypeName(ad.GetType());
}

// ---- OccFaceSurface ------------------------------------------------------------------------

OccFaceSurface::OccFaceSurface(const TopoDS_Face& face, int faceId)
    : face_(face), faceId_(faceId), adaptor_(face, Standard_True) {
  if (face.IsNull()) throw std::invalid_argument("OccFaceSurface: null face");
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  BRepTools::UVBounds(face_, u0, u1, v0, v1);
  faceBounds_ = {u0, u1, v0, v1};
  bounds_ = faceBounds_;
  uPeriodic_ = adaptor_.IsUPeriodic();
  vPeriodic_ = adaptor_.IsVPeriodic();
  const double ptol = 1e-6;
  if (uPeriodic_) {
    uPeriod_ = adaptor_.UPeriod();
    if (u1 - u0 > uPeriod_ * (1.0 + ptol)) {  // more than one turn: not periodic for us
      uTurn_ = uPeriod_;
      uPeriodic_ = false;
      uPeriod_ = 0.0;
    } else {
      const double c = 0.5 * (u0 + u1);
      bounds_.umin = (u1 - u0 >= uPeriod_ * (1.0 - ptol)) ? u0 : c - 0.5 * uPeriod_;
      bounds_.umax = bounds_.umin + uPeriod_;
    }
  }
  if (vPeriodic_) {
    vPeriod_ = adaptor_.VPeriod();
    if (v1 - v0 > vPeriod_ * (1.0 + ptol)) {
      vTurn_ = vPeriod_;
      vPeriodic_ = false;
      vPeriod_ = 0.0;
    } else {
      const double c = 0.5 * (v0 + v1);
      bounds_.vmin = (v1 - v0 >= vPeriod_ * (1.0 - ptol)) ? v0 : c - 0.5 * vPeriod_;
      bounds_.vmax = bounds_.vmin + vPeriod_;
    }
  }
  normalSign_ = face_.Orientation() == TopAbs_REVERSED ? -1 : 1;
  // (u,v) tolerance of the classifier: the resolution of the face's 3D tolerance.
  const double tol3d = std::max(BRep_Tool::Tolerance(face_), Precision::Confusion());
  double ures = 0.0, vres = 0.0;
  try {
    ures = adaptor_.UResolution(tol3d);
    vres = adaptor_.VResolution(tol3d);
  } catch (const Standard_Failure&) {
  }
  uvTol_ = std::max({ures, vres, Precision::PConfusion()});
  if (!std::isfinite(uvTol_)) uvTol_ = Precision::PConfusion();
}

OccFaceSurface::~OccFaceSurface() = default;

Vec3 OccFaceSurface::value(double u, double v) const {
  gp_Pnt p;
  adaptor_.D0(u, v, p);
  return toVec(p);
}

SurfaceD1 OccFaceSurface::d1(double u, double v) const {
  gp_Pnt p;
  gp_Vec du, dv;
  adaptor_.D1(u, v, p, du, dv);
  return {toVec(p), toVec(du), toVec(dv)};
}

SurfaceD2 OccFaceSurface::d2(double u, double v) const {
  gp_Pnt p;
  gp_Vec du, dv, duu, dvv, duv;
  adaptor_.D2(u, v, p, du, dv, duu, dvv, duv);
  return {toVec(p), toVec(du), toVec(dv), toVec(duu), toVec(duv), toVec(dvv)};
}

struct OccFaceSurface::TrimGrid {
  static constexpr int kCells = 48;
  double u0 = 0.0, v0 = 0.0, du = 1.0, dv = 1.0;
  enum : std::uint8_t { Unknown = 0, In = 1, Out = 2, Boundary = 3 };
  std::vector<std::uint8_t> state = std::vector<std::uint8_t>(kCells * kCells, Unknown);

  /// Cell index of (u,v), −1 outside the grid.
  int cell(double u, double v) const {
    const double x = (u - u0) / du, y = (v - v0) / dv;
    if (!(x >= 0.0 && x < kCells && y >= 0.0 && y < kCells)) return -1;
    return static_cast<int>(y) * kCells + static_cast<int>(x);
  }

  /// Marks as Boundary every cell within a quarter cell (plus tol) of the segment's box.
  void mark(const gp_Pnt2d& a, const gp_Pnt2d& b, double tol) {
    const double mu = 0.25 * du + tol, mv = 0.25 * dv + tol;
    auto clampIdx = [](double x) {
      return static_cast<int>(std::min<double>(kCells - 1, std::max(0.0, std::floor(x))));
    };
    const int i0 = clampIdx((std::min(a.X(), b.X()) - mu - u0) / du);
    const int i1 = clampIdx((std::max(a.X(), b.X()) + mu - u0) / du);
    const int j0 = clampIdx((std::min(a.Y(), b.Y()) - mv - v0) / dv);
    const int j1 = clampIdx((std::max(a.Y(), b.Y()) + mv - v0) / dv);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) state[static_cast<std::size_t>(j * kCells + i)] = Boundary;
  }
};

namespace {

/// The grid of OccFaceSurface::contains: every pcurve of the face is sampled finely enough
/// (pieces at most one cell long, chord midpoints within 1/20 cell of the curve) and the
/// cells around each piece are marked Boundary. Null when a pcurve is missing or infinite.
std::unique_ptr<OccFaceSurface::TrimGrid> buildTrimGrid(const TopoDS_Face& face,
                                                        const ParamBounds& b, double tol) {
  using Grid = OccFaceSurface::TrimGrid;
  const double W = b.umax - b.umin, H = b.vmax - b.vmin;
  if (!(W > 0.0) || !(H > 0.0) || !std::isfinite(W) || !std::isfinite(H)) return nullptr;
  auto g = std::make_unique<Grid>();
  g->u0 = b.umin - tol;
  g->v0 = b.vmin - tol;
  g->du = (W + 2.0 * tol) / Grid::kCells;
  g->dv = (H + 2.0 * tol) / Grid::kCells;
  auto cells = [&](const gp_Pnt2d& p, const gp_Pnt2d& q) {
    return std::hypot((p.X() - q.X()) / g->du, (p.Y() - q.Y()) / g->dv);
  };
  for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
    const TopoDS_Edge& e = TopoDS::Edge(ex.Current());
    double f = 0.0, l = 0.0;
    const Handle(Geom2d_Curve) c = BRep_Tool::CurveOnSurface(e, face, f, l);
    if (c.IsNull() || !std::isfinite(f) || !std::isfinite(l)) return nullptr;
    struct Piece {
      double t0, t1;
      gp_Pnt2d p0, p1;
      int depth;
    };
    std::vector<Piece> stack;
    constexpr int kStart = 8;
    gp_Pnt2d prev = c->Value(f);
    for (int k = 1; k <= kStart; ++k) {
      const double t = f + (l - f) * k / kStart;
      const gp_Pnt2d p = c->Value(t);
      stack.push_back({f + (l - f) * (k - 1) / kStart, t, prev, p, 0});
      prev = p;
    }
    std::size_t pieces = 0;
    while (!stack.empty()) {
      const Piece pc = stack.back();
      stack.pop_back();
      const double tm = 0.5 * (pc.t0 + pc.t1);
      const gp_Pnt2d pm = c->Value(tm);
      const gp_Pnt2d mid(0.5 * (pc.p0.X() + pc.p1.X()), 0.5 * (pc.p0.Y() + pc.p1.Y()));
      const bool fine = cells(pc.p0, pc.p1) <= 1.0 && cells(pm, mid) <= 0.05;
      if (!fine && pc.depth < 16) {
        stack.push_back({pc.t0, tm, pc.p0, pm, pc.depth + 1});
        stack.push_back({tm, pc.t1, pm, pc.p1, pc.depth + 1});
        continue;
      }
      if (!fine || ++pieces > 2000000) return nullptr;  // a pathological pcurve
      g->mark(pc.p0, pm, tol);
      g->mark(pm, pc.p1, tol);
    }
  }
  return g;
}

}  // namespace

bool OccFaceSurface::classifyWithClassifier(double u, double v) const {
  const TopAbs_State st = classifier_->Perform(
      gp_Pnt2d(u, v), uTurn_ == 0.0 && vTurn_ == 0.0 ? Standard_True : Standard_False);
  return st == TopAbs_IN || st == TopAbs_ON;
}

bool OccFaceSurface::contains(double u, double v) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return false;
  const Vec2 w = wrap(Vec2(u, v));
  // Quick rejection outside the face's parameter box (non-periodic directions).
  const double tol = uvTol_;
  if (!uPeriodic_ && (w.x() < faceBounds_.umin - tol || w.x() > faceBounds_.umax + tol))
    return false;
  if (!vPeriodic_ && (w.y() < faceBounds_.vmin - tol || w.y() > faceBounds_.vmax + tol))
    return false;
  if (!classifier_) {
    classifier_ = std::make_unique<BRepTopAdaptor_FClass2d>(face_, tol);
    try {
      grid_ = buildTrimGrid(face_, faceBounds_, tol);
    } catch (const Standard_Failure&) {
      grid_.reset();
    }
  }
  if (grid_) {
    const int k = grid_->cell(w.x(), w.y());
    if (k >= 0) {
      std::uint8_t& st = grid_->state[static_cast<std::size_t>(k)];
      if (st == TrimGrid::Unknown) {
        // No trimming loop comes near this cell: the whole cell is where its centre is.
        const int i = k % TrimGrid::kCells, j = k / TrimGrid::kCells;
        st = classifyWithClassifier(grid_->u0 + (i + 0.5) * grid_->du,
                                    grid_->v0 + (j + 0.5) * grid_->dv)
                 ? TrimGrid::In
                 : TrimGrid::Out;
      }
      if (st != TrimGrid::Boundary) return st == TrimGrid::In;
    }
  }
  return classifyWithClassifier(w.x(), w.y());
}

std::unique_ptr<Surface> OccFaceSurface::clone() const {
  return std::make_unique<OccFaceSurface>(face_, faceId_);
}

std::string OccFaceSurface::describe() const {
  std::ostringstream os;
  os << "OCC face " << faceId_ << " (" << surfaceTypeName(adaptor_.GetType()) << ")";
  return os.str();
}

// ---- OccEdgeCurve --------------------------------------------------------------------------

OccEdgeCurve::OccEdgeCurve(const TopoDS_Edge& edge, int edgeId, std::vector<EdgeFaceUse> faces)
    : edge_(edge), edgeId_(edgeId), faces_(std::move(faces)) {
  if (edge.IsNull()) throw std::invalid_argument("OccEdgeCurve: null edge");
  degenerated_ = BRep_Tool::Degenerated(edge_);
  double f = 0.0, l = 0.0;
  BRep_Tool::Range(edge_, f, l);
  tmin_ = std::min(f, l);
  tmax_ = std::max(f, l);
  if (degenerated_) {
    TopoDS_Vertex v1, v2;
    TopExp::Vertices(edge_, v1, v2);
    if (!v1.IsNull()) degeneratePoint_ = toVec(BRep_Tool::Pnt(v1));
  } else {
    adaptor_.Initialize(edge_);
    tmin_ = adaptor_.FirstParameter();
    tmax_ = adaptor_.LastParameter();
    if (adaptor_.IsPeriodic() && BRep_Tool::IsClosed(edge_)) {
      const double p = adaptor_.Period();
      if (std::abs((tmax_ - tmin_) - p) <= 1e-9 * std::max(1.0, p)) {
        periodic_ = true;
        period_ = p;
      }
    }
  }
}

Vec3 OccEdgeCurve::value(double t) const {
  if (degenerated_) return degeneratePoint_;
  gp_Pnt p;
  adaptor_.D0(t, p);
  return toVec(p);
}

CurveD2 OccEdgeCurve::d2(double t) const {
  if (degenerated_) return {degeneratePoint_, Vec3::Zero(), Vec3::Zero()};
  gp_Pnt p;
  gp_Vec d1, d2;
  adaptor_.D2(t, p, d1, d2);
  return {toVec(p), toVec(d1), toVec(d2)};
}

const EdgeFaceUse& OccEdgeCurve::use(int faceId) const {
  for (const EdgeFaceUse& u : faces_)
    if (u.faceId == faceId) return u;
  std::ostringstream os;
  os << "OccEdgeCurve::uvOnFace: edge " << edgeId_ << " does not bound face " << faceId;
  throw std::invalid_argument(os.str());
}

bool OccEdgeCurve::isSeamOf(int faceId) const {
  for (const EdgeFaceUse& u : faces_)
    if (u.faceId == faceId) return !u.pcurve2.IsNull();
  return false;
}

Vec2 OccEdgeCurve::uvOnFace(int faceId, double t, const Vec2& near) const {
  const EdgeFaceUse& u = use(faceId);
  auto eval = [&](const Handle(Geom2d_Curve) & c) {
    const gp_Pnt2d p = c->Value(t);
    return Vec2(unwrapCoord(p.X(), near.x(), u.uPeriod), unwrapCoord(p.Y(), near.y(), u.vPeriod));
  };
  if (u.pcurve.IsNull()) {
    std::ostringstream os;
    os << "OccEdgeCurve::uvOnFace: edge " << edgeId_ << " has no pcurve on face " << faceId;
    throw std::invalid_argument(os.str());
  }
  const Vec2 a = eval(u.pcurve);
  if (u.pcurve2.IsNull()) return a;
  const Vec2 b = eval(u.pcurve2);
  return (a - near).squaredNorm() <= (b - near).squaredNorm() ? a : b;
}

std::unique_ptr<Curve> OccEdgeCurve::clone() const {
  return std::make_unique<OccEdgeCurve>(edge_, edgeId_, faces_);
}

std::string OccEdgeCurve::describe() const {
  std::ostringstream os;
  os << "OCC edge " << edgeId_ << " ("
     << (degenerated_ ? "Degenerated" : curveTypeName(adaptor_.GetType())) << ")";
  return os.str();
}

}  // namespace surfmesh
