// SurfMesh — OpenCASCADE face and edge adapters (see occ_surface.h); the trimming loops and
// tolerance zones of contains() are in occ_trim.cpp and occ_zones.cpp.
#include "surfmesh/cad/occ_surface.h"

#include "occ_trim.h"

#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom_Surface.hxx>
#include <Precision.hxx>
#include <Standard_Failure.hxx>
#include <TopExp.hxx>
#include <TopoDS_Vertex.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Vec.hxx>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

using occ_detail::include;
using occ_detail::kEmptyBox;
using occ_detail::kInf;
using occ_detail::toVec;

namespace {

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

std::vector<Box3> surfacePatchBoxes(const Adaptor3d_Surface& s, const ParamBounds& b, int cells,
                                    double grow) {
  std::vector<Box3> out;
  if (cells < 1) return out;
  const int m = 2 * cells + 1;
  std::vector<Vec3> grid(static_cast<std::size_t>(m * m));
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = b.umin + (b.umax - b.umin) * i / (m - 1);
      const double v = b.vmin + (b.vmax - b.vmin) * j / (m - 1);
      const gp_Pnt q = s.Value(u, v);
      const Vec3 x(q.X(), q.Y(), q.Z());
      if (!x.allFinite()) return out;
      grid[static_cast<std::size_t>(i * m + j)] = x;
    }
  out.reserve(static_cast<std::size_t>(cells * cells));
  for (int ci = 0; ci < cells; ++ci)
    for (int cj = 0; cj < cells; ++cj) {
      auto at = [&](int a, int c) -> const Vec3& {
        return grid[static_cast<std::size_t>((2 * ci + a) * m + 2 * cj + c)];
      };
      Box3 box = kEmptyBox;
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c) include(box, at(a, c));
      double bulge = (at(1, 1) - 0.25 * (at(0, 0) + at(2, 0) + at(0, 2) + at(2, 2))).norm();
      for (int k = 0; k < 3; ++k) {
        bulge = std::max(bulge, (at(1, k) - 0.5 * (at(0, k) + at(2, k))).norm());
        bulge = std::max(bulge, (at(k, 1) - 0.5 * (at(k, 0) + at(k, 2))).norm());
      }
      for (std::size_t k = 0; k < 3; ++k) {
        box[k] -= bulge + grow;
        box[k + 3] += bulge + grow;
      }
      out.push_back(box);
    }
  return out;
}

double boxDistance2(const Box3& b, const Vec3& p) {
  if (b[0] > b[3]) return kInf;
  double d2 = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double lo = b[static_cast<std::size_t>(i)] - p[i];
    const double hi = p[i] - b[static_cast<std::size_t>(i) + 3];
    const double d = std::max({lo, hi, 0.0});
    d2 += d * d;
  }
  return d2;
}

double boxDistance(const Box3& b, const Vec3& p) { return std::sqrt(boxDistance2(b, p)); }

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
  // The underlying surface's range in the directions that are not periodic for us.
  surfaceBounds_ = {-kInf, kInf, -kInf, kInf};
  TopLoc_Location loc;
  if (const Handle(Geom_Surface)& g = BRep_Tool::Surface(face_, loc); !g.IsNull()) {
    double su0 = 0, su1 = 0, sv0 = 0, sv1 = 0;
    g->Bounds(su0, su1, sv0, sv1);
    if (!uPeriodic_ && uTurn_ == 0.0 && !g->IsUPeriodic() && std::isfinite(su0) &&
        std::isfinite(su1) && su0 < su1)
      surfaceBounds_.umin = su0, surfaceBounds_.umax = su1;
    if (!vPeriodic_ && vTurn_ == 0.0 && !g->IsVPeriodic() && std::isfinite(sv0) &&
        std::isfinite(sv1) && sv0 < sv1)
      surfaceBounds_.vmin = sv0, surfaceBounds_.vmax = sv1;
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
  trim_ = std::make_shared<TrimShared>();
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
OccFaceSurface::OccFaceSurface(const OccFaceSurface& o)
    : Surface(),
      face_(o.face_),
      faceId_(o.faceId_),
      adaptor_(o.face_, Standard_True),  // its own evaluation caches (not shared)
      bounds_(o.bounds_),
      faceBounds_(o.faceBounds_),
      surfaceBounds_(o.surfaceBounds_),
      uPeriodic_(o.uPeriodic_),
      vPeriodic_(o.vPeriodic_),
      uPeriod_(o.uPeriod_),
      vPeriod_(o.vPeriod_),
      uTurn_(o.uTurn_),
      vTurn_(o.vTurn_),
      normalSign_(o.normalSign_),
      uvTol_(o.uvTol_),
      trim_(o.trim_),
      cells_(o.cells_ ? std::make_unique<TrimCells>(*o.cells_) : nullptr) {}

std::unique_ptr<Surface> OccFaceSurface::clone() const {
  return std::unique_ptr<Surface>(new OccFaceSurface(*this));
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
