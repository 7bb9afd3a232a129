// SurfMesh — OpenCASCADE face and edge adapters (see occ_surface.h).
#include "surfmesh/cad/occ_surface.h"

#include <BRepBndLib.hxx>
#include <BRepTools.hxx>
#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Extrema_ExtPC.hxx>
#include <Extrema_LocateExtPC.hxx>
#include <Geom2dAdaptor_Curve.hxx>
#include <Geom2d_Curve.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_Surface.hxx>
#include <Precision.hxx>
#include <Standard_Failure.hxx>
#include <TopAbs_State.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Vertex.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Vec.hxx>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// A box that contains nothing (grown by include()).
constexpr Box3 kEmptyBox = {kInf, kInf, kInf, -kInf, -kInf, -kInf};

/// Grows b to take in the ball of radius r around p.
void include(Box3& b, const Vec3& p, double r = 0.0) {
  for (std::size_t k = 0; k < 3; ++k) {
    b[k] = std::min(b[k], p[static_cast<int>(k)] - r);
    b[k + 3] = std::max(b[k + 3], p[static_cast<int>(k)] + r);
  }
}

/// Grows b to take in box c.
void include(Box3& b, const Box3& c) {
  for (std::size_t k = 0; k < 3; ++k) {
    b[k] = std::min(b[k], c[k]);
    b[k + 3] = std::max(b[k + 3], c[k + 3]);
  }
}

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

/// Squared distance from point (px, py) to the segment (ax, ay)–(bx, by).
double segmentDistance2(double ax, double ay, double bx, double by, double px, double py) {
  const double ex = bx - ax, ey = by - ay, l2 = ex * ex + ey * ey;
  const double t = l2 > 0.0 ? std::clamp(((px - ax) * ex + (py - ay) * ey) / l2, 0.0, 1.0) : 0.0;
  const double dx = ax + t * ex - px, dy = ay + t * ey - py;
  return dx * dx + dy * dy;
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

/// Two levels of cells over the face's (u,v) box: kCells² cells, and kSub² sub-cells in each
/// cell that a pcurve comes near. A (sub-)cell that no pcurve comes near lies entirely on one
/// side of the trimming loops: it is classified once, at its centre, and answers every later
/// query in it. Only sub-cells a pcurve passes through go to the classifier each time.
struct OccFaceSurface::TrimGrid {
  static constexpr int kCells = 48, kSub = 16;
  enum : std::uint8_t { Unknown = 0, In = 1, Out = 2, Boundary = 3 };
  double u0 = 0.0, v0 = 0.0, du = 1.0, dv = 1.0, tol = 0.0;
  /// Boundary where a pcurve comes near the cell, Unknown elsewhere (not classified yet).
  std::vector<std::uint8_t> state = std::vector<std::uint8_t>(kCells * kCells, Unknown);
  /// The pcurves as pieces (u0, v0, u1, v1) and the pieces near each cell (CSR).
  std::vector<std::array<double, 4>> pieces;
  std::vector<int> cellStart, cellPieces;

  /// Index range [i0, i1] × [j0, j1] of the cells (n per unit of du, dv) within `margin`
  /// cells of the piece's box, clamped to [0, n).
  static void span(const std::array<double, 4>& q, double x0, double y0, double hx, double hy,
                   double mx, double my, int n, int* r) {
    auto clampIdx = [n](double x) {
      // max/min first: the truncation of a value in [0, n − 1] is its floor (and no libm call).
      return static_cast<int>(std::min<double>(n - 1, std::max(0.0, x)));
    };
    r[0] = clampIdx((std::min(q[0], q[2]) - mx - x0) / hx);
    r[1] = clampIdx((std::max(q[0], q[2]) + mx - x0) / hx);
    r[2] = clampIdx((std::min(q[1], q[3]) - my - y0) / hy);
    r[3] = clampIdx((std::max(q[1], q[3]) + my - y0) / hy);
  }

  /// Sub-cell size; a piece marks the (sub-)cells within a quarter sub-cell plus the
  /// classifier's tolerance of its box.
  double subDu() const { return du / kSub; }
  double subDv() const { return dv / kSub; }

  void buildBuckets() {
    // Two passes (count, then fill): no per-cell lists.
    const double mu = 0.25 * subDu() + tol, mv = 0.25 * subDv() + tol;
    cellStart.assign(kCells * kCells + 1, 0);
    for (const auto& q : pieces) {
      int r[4];
      span(q, u0, v0, du, dv, mu, mv, kCells, r);
      for (int j = r[2]; j <= r[3]; ++j)
        for (int i = r[0]; i <= r[1]; ++i)
          ++cellStart[static_cast<std::size_t>(j * kCells + i) + 1];
    }
    for (std::size_t k = 0; k < static_cast<std::size_t>(kCells * kCells); ++k)
      cellStart[k + 1] += cellStart[k];
    cellPieces.resize(static_cast<std::size_t>(cellStart.back()));
    std::vector<int> fill(cellStart.begin(), cellStart.end() - 1);
    for (std::size_t k = 0; k < pieces.size(); ++k) {
      int r[4];
      span(pieces[k], u0, v0, du, dv, mu, mv, kCells, r);
      for (int j = r[2]; j <= r[3]; ++j)
        for (int i = r[0]; i <= r[1]; ++i) {
          const std::size_t c = static_cast<std::size_t>(j * kCells + i);
          cellPieces[static_cast<std::size_t>(fill[c]++)] = static_cast<int>(k);
          state[c] = Boundary;
        }
    }
  }

  /// Sets state `v` on the Unknown cells 4-connected to cell (i, j) of an n × n array `st`
  /// through Unknown cells: a region free of pcurves lies on one side of the loops.
  static void flood(std::uint8_t* st, int n, int i, int j, std::uint8_t v,
                    std::vector<int>& stack) {
    if (st[j * n + i] != Unknown) return;
    st[j * n + i] = v;
    stack.assign(1, j * n + i);
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      const int ci = c % n, cj = c / n;
      const int nb[4][2] = {{ci - 1, cj}, {ci + 1, cj}, {ci, cj - 1}, {ci, cj + 1}};
      for (const auto& q : nb) {
        if (q[0] < 0 || q[0] >= n || q[1] < 0 || q[1] >= n) continue;
        std::uint8_t& t = st[q[1] * n + q[0]];
        if (t != Unknown) continue;
        t = v;
        stack.push_back(q[1] * n + q[0]);
      }
    }
  }
};

/// The states of one copy's cells, classified as queries reach them.
struct OccFaceSurface::TrimCells {
  using G = TrimGrid;
  explicit TrimCells(const TrimGrid& g) : state(g.state) {}
  std::vector<std::uint8_t> state;
  /// Sub-cell states of a Boundary cell (kSub² each, built on the cell's first query).
  std::vector<int> subOf = std::vector<int>(G::kCells * G::kCells, -1);
  std::vector<std::uint8_t> sub;
  std::vector<int> scratch;

  /// The sub-cell states of Boundary cell k (built on first use). Sub-cells along a side
  /// shared with a classified cell that no pcurve comes near take its state (and pass it on
  /// to the sub-cells connected to them).
  template <class Classify>
  std::uint8_t* subCells(const TrimGrid& g, int k, Classify classify) {
    constexpr int kCells = G::kCells, kSub = G::kSub;
    if (subOf[static_cast<std::size_t>(k)] < 0) {
      const int ci = k % kCells, cj = k / kCells;
      // Neighbour states first (classifying them may flood the top level).
      std::uint8_t nbState[4] = {G::Boundary, G::Boundary, G::Boundary, G::Boundary};
      const int nb[4][2] = {{ci - 1, cj}, {ci + 1, cj}, {ci, cj - 1}, {ci, cj + 1}};
      for (int s = 0; s < 4; ++s) {
        const int ni = nb[s][0], nj = nb[s][1];
        if (ni < 0 || ni >= kCells || nj < 0 || nj >= kCells) continue;
        std::uint8_t& t = state[static_cast<std::size_t>(nj * kCells + ni)];
        if (t == G::Unknown)
          G::flood(state.data(), kCells, ni, nj,
                   classify(g.u0 + (ni + 0.5) * g.du, g.v0 + (nj + 0.5) * g.dv) ? G::In : G::Out,
                   scratch);
        nbState[s] = t;
      }
      subOf[static_cast<std::size_t>(k)] = static_cast<int>(sub.size());
      sub.resize(sub.size() + kSub * kSub, G::Unknown);
      std::uint8_t* st = sub.data() + subOf[static_cast<std::size_t>(k)];
      {
        const double x0 = g.u0 + ci * g.du, y0 = g.v0 + cj * g.dv;
        const double mu = 0.25 * g.subDu() + g.tol, mv = 0.25 * g.subDv() + g.tol;
        for (int p = g.cellStart[static_cast<std::size_t>(k)];
             p < g.cellStart[static_cast<std::size_t>(k) + 1]; ++p) {
          const auto& pc =
              g.pieces[static_cast<std::size_t>(g.cellPieces[static_cast<std::size_t>(p)])];
          // The piece's chord in steps of at most one sub-cell, each marking its box.
          const double lx = (pc[2] - pc[0]) / g.subDu(), ly = (pc[3] - pc[1]) / g.subDv();
          const int steps = std::max(1, static_cast<int>(std::ceil(std::sqrt(lx * lx + ly * ly))));
          for (int k2 = 0; k2 < steps; ++k2) {
            const double a = static_cast<double>(k2) / steps,
                         b = static_cast<double>(k2 + 1) / steps;
            const std::array<double, 4> q = {
                pc[0] + a * (pc[2] - pc[0]), pc[1] + a * (pc[3] - pc[1]),
                pc[0] + b * (pc[2] - pc[0]), pc[1] + b * (pc[3] - pc[1])};
            // span() clamps to the cell: steps only near the cell must not mark its border.
            if (std::max(q[0], q[2]) + mu < x0 || std::min(q[0], q[2]) - mu > x0 + g.du ||
                std::max(q[1], q[3]) + mv < y0 || std::min(q[1], q[3]) - mv > y0 + g.dv)
              continue;
            int r[4];
            G::span(q, x0, y0, g.subDu(), g.subDv(), mu, mv, kSub, r);
            for (int j = r[2]; j <= r[3]; ++j)
              for (int i = r[0]; i <= r[1]; ++i) st[j * kSub + i] = G::Boundary;
          }
        }
        for (int s = 0; s < 4; ++s) {
          if (nbState[s] != G::In && nbState[s] != G::Out) continue;
          for (int m = 0; m < kSub; ++m) {
            const int i = s == 0 ? 0 : s == 1 ? kSub - 1 : m;
            const int j = s == 2 ? 0 : s == 3 ? kSub - 1 : m;
            G::flood(st, kSub, i, j, nbState[s], scratch);
          }
        }
      }
    }
    return sub.data() + subOf[static_cast<std::size_t>(k)];
  }

  /// Side of (u,v), in a Boundary sub-cell of Boundary cell k (sub-cell states `sc`), from
  /// the pieces of the cell: the parity of their crossings with the segment to the centre of
  /// the nearest sub-cell of the cell whose side is known (classified first when none is).
  /// The pieces follow the pcurves within 1/20 sub-cell and that centre is farther than that
  /// from them, so the parity is the pcurves' own as long as (u,v) is too: −1 when (u,v) is
  /// within that deviation plus the classifier's tolerance band of a piece.
  template <class Classify>
  int sideByCrossings(const TrimGrid& g, int k, std::uint8_t* sc, double u, double v,
                      Classify classify) {
    constexpr int kCells = G::kCells, kSub = G::kSub;
    const int ci = k % kCells, cj = k / kCells;
    const double su = g.subDu(), sv = g.subDv();
    const double x0 = g.u0 + ci * g.du, y0 = g.v0 + cj * g.dv;
    const double px = (u - x0) / su, py = (v - y0) / sv;  // in sub-cells
    int ref = -1;
    for (int pass = 0; pass < 2 && ref < 0; ++pass) {
      double best = std::numeric_limits<double>::infinity();
      for (int q = 0; q < kSub * kSub; ++q) {
        const std::uint8_t s = sc[q];
        if (s == G::Boundary || (pass == 0 && s == G::Unknown)) continue;
        const double dx = q % kSub + 0.5 - px, dy = q / kSub + 0.5 - py;
        if (dx * dx + dy * dy < best) {
          best = dx * dx + dy * dy;
          ref = q;
        }
      }
      if (pass == 0 || ref < 0) continue;
      const int ri = ref % kSub, rj = ref / kSub;  // an Unknown one: classify its region
      G::flood(sc, kSub, ri, rj,
               classify(x0 + (ri + 0.5) * su, y0 + (rj + 0.5) * sv) ? G::In : G::Out, scratch);
    }
    if (ref < 0) return -1;
    const double qx = ref % kSub + 0.5, qy = ref / kSub + 0.5;
    const double dx = qx - px, dy = qy - py, len2 = dx * dx + dy * dy;
    const double margin = 0.1 + g.tol / std::min(su, sv);
    int crossings = 0;
    for (int p = g.cellStart[static_cast<std::size_t>(k)];
         p < g.cellStart[static_cast<std::size_t>(k) + 1]; ++p) {
      const auto& pc =
          g.pieces[static_cast<std::size_t>(g.cellPieces[static_cast<std::size_t>(p)])];
      const double ax = (pc[0] - x0) / su, ay = (pc[1] - y0) / sv;
      const double bx = (pc[2] - x0) / su, by = (pc[3] - y0) / sv;
      if (segmentDistance2(ax, ay, bx, by, px, py) <= margin * margin) return -1;
      // Crossing of the segment (u,v) → centre, half-open at the piece's ends (a polyline
      // through the segment at a shared end counts once).
      const double sa = (ax - px) * dy - (ay - py) * dx;
      const double sb = (bx - px) * dy - (by - py) * dx;
      if ((sa > 0.0) == (sb > 0.0)) continue;
      const double s =
          ((ax - px) * dx + (ay - py) * dy + ((bx - ax) * dx + (by - ay) * dy) * (sa / (sa - sb))) /
          len2;
      if (s >= 0.0 && s <= 1.0) ++crossings;
    }
    const bool refIn = sc[ref] == G::In;
    return (crossings % 2 == 0) == refIn ? 1 : 0;
  }
};

/// The tolerance zones of a face's boundary: a ball of its tolerance around each vertex of
/// the face, and around each non-degenerated edge the points within its tolerance of its 3D
/// curve. An edge's curve is kept as a polyline through points of the curve (within `dev`
/// of it both ways), in chunks of kChunk segments with their boxes grown by tolerance + dev:
/// a point farther than that from the polyline is outside the zone, one nearer than
/// tolerance − dev inside; in between the curve itself decides.
struct OccFaceSurface::ToleranceZones {
  static constexpr std::size_t kChunk = 8;
  struct Edge {
    TopoDS_Edge edge;
    double tol = 0.0, dev = 0.0;  // tol: the tolerance zone's radius (0: the edge has none)
    /// A trimming curve off its 3D edge (isTrimGap): the points of the surface within
    /// `strip` of the 3D curve on its outer side (inward: per polyline point, the unit vector
    /// tangent to the surface, across the curve, into the face) are outside the face's 3D
    /// boundary; every move keeps out of them, the untangling's too. With no inward side
    /// found (inward empty), the whole band within `strip` is kept out of.
    bool trim = false;
    double strip = 0.0, edgeTol = 0.0;
    std::vector<Vec3> inward;
    Box3 box = kEmptyBox;
    std::vector<double> t;         // the polyline's points: curve parameters …
    std::vector<Vec3> x;           // … and positions, in the curve's order
    std::vector<Box3> chunkBoxes;  // segments [kChunk·c, kChunk·(c + 1)) of the polyline
  };
  std::vector<Edge> edges;
  std::vector<std::pair<Vec3, double>> vertices;  // point, tolerance
  bool empty() const { return edges.empty() && vertices.empty(); }
  bool hasTrim = false;  // some edge is a trim zone
};

/// Per copy: the edges' curve adaptors of the zones (OCC adaptors are not thread-safe).
struct OccFaceSurface::ZoneCurves {
  std::vector<std::unique_ptr<BRepAdaptor_Curve>> curves;
};

/// What the copies of one face share: its classifier, its grid's pcurve index and the
/// tolerance zones of its boundary, each built once, by the first query of any copy that
/// needs it (the CAD recovery's included).
struct OccFaceSurface::TrimShared {
  std::once_flag classifierOnce, gridOnce, zonesOnce;
  /// The shape's diagonal, the scale of isTrimGap (set by CadShape before any query; 0: the
  /// face's own box diagonal).
  double shapeDiagonal = 0.0;
  std::unique_ptr<BRepTopAdaptor_FClass2d> classifier;
  std::unique_ptr<TrimGrid> grid;  // null: not usable (a missing or pathological pcurve)
  std::unique_ptr<ToleranceZones> zones;
  /// Serializes the classifier's queries: BRepTopAdaptor_FClass2d::Perform is const but not
  /// thread-safe (its sequences of wires cache the last item they were asked for).
  std::mutex classifierMutex;
  /// Whether the grid was built (or found unusable); containsFast() queries before that.
  std::atomic<bool> gridTried{false};
  std::atomic<int> queries{0};
};

namespace {

/// containsFast() builds a face's grid (~0.1 ms) only after this many queries (each ~µs with
/// the classifier) unless prepare() built it: a face with a handful of nodes near it (as most
/// faces of a fine part's CAD recovery) never pays for one.
constexpr int kQueriesBeforeGrid = 48;

/// The grid of OccFaceSurface::contains: every pcurve of the face is cut into pieces at most
/// one cell (16 sub-cells) long whose chords pass within 1/20 sub-cell of the curve at a
/// quarter, half and three quarters of the piece, kept as their two half-chords through the
/// curve's midpoint (a straight pcurve: equal chords, at once). A piece marks every cell its
/// box comes near; in a cell, the steps of at most one sub-cell along its chords mark the
/// sub-cells their boxes come near. Null when a pcurve is missing or infinite.
std::unique_ptr<OccFaceSurface::TrimGrid> buildTrimGrid(const TopoDS_Face& face,
                                                        const ParamBounds& b, double tol) {
  using Grid = OccFaceSurface::TrimGrid;
  const double W = b.umax - b.umin, H = b.vmax - b.vmin;
  if (!(W > 0.0) || !(H > 0.0) || !std::isfinite(W) || !std::isfinite(H)) return nullptr;
  auto g = std::make_unique<Grid>();
  g->tol = tol;
  g->u0 = b.umin - tol;
  g->v0 = b.vmin - tol;
  g->du = (W + 2.0 * tol) / Grid::kCells;
  g->dv = (H + 2.0 * tol) / Grid::kCells;
  const double su = g->subDu(), sv = g->subDv();
  auto subCells2 = [&](const gp_Pnt2d& p, const gp_Pnt2d& q) {  // squared, in sub-cells
    const double x = (p.X() - q.X()) / su, y = (p.Y() - q.Y()) / sv;
    return x * x + y * y;
  };
  // Scratch reused from face to face (one build allocates its pieces once, at their size).
  thread_local std::vector<std::array<double, 4>> pieces;
  pieces.clear();
  // A piece p0 → p1 through pm, kept as its two half-chords; false past the size cap.
  auto addPiece = [&](const gp_Pnt2d& p0, const gp_Pnt2d& pm, const gp_Pnt2d& p1) {
    if (pieces.size() > 4000000) return false;
    pieces.push_back({p0.X(), p0.Y(), pm.X(), pm.Y()});
    pieces.push_back({pm.X(), pm.Y(), p1.X(), p1.Y()});
    return true;
  };
  for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
    const TopoDS_Edge& e = TopoDS::Edge(ex.Current());
    double f = 0.0, l = 0.0;
    const Handle(Geom2d_Curve) c = BRep_Tool::CurveOnSurface(e, face, f, l);
    if (c.IsNull() || !std::isfinite(f) || !std::isfinite(l)) return nullptr;
    if (Geom2dAdaptor_Curve(c, f, l).GetType() == GeomAbs_Line) {
      // A straight pcurve: equal chords at most one cell (16 sub-cells) long, exact.
      const gp_Pnt2d a = c->Value(f), z = c->Value(l);
      const double len = std::sqrt(subCells2(a, z));
      if (!std::isfinite(len)) return nullptr;
      const int n = std::max(1, static_cast<int>(std::ceil(len / 16.0)));
      auto at = [&](double s) {
        return gp_Pnt2d(a.X() + s * (z.X() - a.X()), a.Y() + s * (z.Y() - a.Y()));
      };
      for (int k = 0; k < n; ++k)
        if (!addPiece(at(static_cast<double>(k) / n), at((k + 0.5) / n),
                      at(static_cast<double>(k + 1) / n)))
          return nullptr;
      continue;
    }
    struct Piece {
      double t0, t1;
      gp_Pnt2d p0, p1;
      int depth;
    };
    thread_local std::vector<Piece> stack;
    stack.clear();
    constexpr int kStart = 8;
    gp_Pnt2d prev = c->Value(f);
    for (int k = 1; k <= kStart; ++k) {
      const double t = f + (l - f) * k / kStart;
      const gp_Pnt2d p = c->Value(t);
      stack.push_back({f + (l - f) * (k - 1) / kStart, t, prev, p, 0});
      prev = p;
    }
    while (!stack.empty()) {
      const Piece pc = stack.back();
      stack.pop_back();
      const double tm = 0.5 * (pc.t0 + pc.t1);
      const gp_Pnt2d pm = c->Value(tm);
      const gp_Pnt2d mid(0.5 * (pc.p0.X() + pc.p1.X()), 0.5 * (pc.p0.Y() + pc.p1.Y()));
      bool fine = subCells2(pc.p0, pc.p1) <= 256.0 && subCells2(pm, mid) <= 0.0025;
      if (fine) {
        // The curve at a quarter and three quarters against the half-chords (in sub-cells):
        // a piece whose midpoint sits on the chord may still bend away between.
        auto offChord = [&](const gp_Pnt2d& a, const gp_Pnt2d& b, const gp_Pnt2d& x) {
          return segmentDistance2(0.0, 0.0, (b.X() - a.X()) / su, (b.Y() - a.Y()) / sv,
                                  (x.X() - a.X()) / su, (x.Y() - a.Y()) / sv);
        };
        fine = offChord(pc.p0, pm, c->Value(0.5 * (pc.t0 + tm))) <= 0.0025 &&
               offChord(pm, pc.p1, c->Value(0.5 * (tm + pc.t1))) <= 0.0025;
      }
      if (!fine && pc.depth < 24) {
        stack.push_back({pc.t0, tm, pc.p0, pm, pc.depth + 1});
        stack.push_back({tm, pc.t1, pm, pc.p1, pc.depth + 1});
        continue;
      }
      if (!fine || !addPiece(pc.p0, pm, pc.p1)) return nullptr;  // a pathological pcurve
    }
  }
  g->pieces.assign(pieces.begin(), pieces.end());
  g->buildBuckets();
  return g;
}

}  // namespace

namespace {

/// Squared distance from p to the segment a–b.
double segmentDistance2(const Vec3& a, const Vec3& b, const Vec3& p) {
  const Vec3 e = b - a;
  const double l2 = e.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(e) / l2, 0.0, 1.0) : 0.0;
  return (a + t * e - p).squaredNorm();
}

/// The zones of `face` (see OccFaceSurface::ToleranceZones): of its edges and vertices more
/// than twice as tolerant as the face itself (the classifier's band, the face's tolerance,
/// keeps contains() off the others: on a part built by OCC, whose tolerances are all 1e-7,
/// there are none). An edge's polyline: its curve
/// cut in 8 pieces, halved until the curve at a quarter, half and three quarters of a piece
/// is within dev = max(tolerance / 10, 1e-4 × the diagonal of the edge's box) of its chord.
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

const OccFaceSurface::ToleranceZones& OccFaceSurface::zones() const {
  TrimShared& t = *trim_;
  std::call_once(t.zonesOnce,
                 [&]() { t.zones = buildToleranceZones(face_, t.shapeDiagonal, uvTol_); });
  return *t.zones;
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

const OccFaceSurface::TrimGrid* OccFaceSurface::trimGrid() const {
  TrimShared& t = *trim_;
  std::call_once(t.gridOnce, [&]() {
    try {
      t.grid = buildTrimGrid(face_, faceBounds_, uvTol_);
    } catch (const Standard_Failure&) {
      t.grid.reset();
    }
    t.gridTried.store(true, std::memory_order_release);
  });
  return t.grid.get();
}

void OccFaceSurface::prepare() const { trimGrid(); }

bool OccFaceSurface::containsWithinBand(double u, double v) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return false;
  const Vec2 w = wrap(Vec2(u, v));
  return classifyWithClassifier(w.x(), w.y(), true);
}

bool OccFaceSurface::classifyWithClassifier(double u, double v, bool band, bool strict) const {
  TrimShared& t = *trim_;
  std::call_once(t.classifierOnce, [&]() {
    t.classifier = std::make_unique<BRepTopAdaptor_FClass2d>(face_, uvTol_);
  });
  const Standard_Boolean recadre = uTurn_ == 0.0 && vTurn_ == 0.0 ? Standard_True : Standard_False;
  std::lock_guard<std::mutex> lock(t.classifierMutex);
  const TopAbs_State st = band ? t.classifier->TestOnRestriction(gp_Pnt2d(u, v), uvTol_, recadre)
                               : t.classifier->Perform(gp_Pnt2d(u, v), recadre);
  return st == TopAbs_IN || (st == TopAbs_ON && !strict);
}

bool OccFaceSurface::insideTrimmingLoops(double u, double v) const {
  if (!(u >= surfaceBounds_.umin && u <= surfaceBounds_.umax && v >= surfaceBounds_.vmin &&
        v <= surfaceBounds_.vmax))
    return false;  // NaN too
  const int known = containsFast(u, v);
  if (known >= 0) return known == 1;
  const Vec2 w = wrap(Vec2(u, v));
  return classifyWithClassifier(w.x(), w.y(), false, true);
}

bool OccFaceSurface::containsNearBoundary(double u, double v) const {
  return insideTrimmingLoops(u, v) && !inTrimStrip(u, v);
}

bool OccFaceSurface::inTrimStrip(double u, double v) const {
  return zones().hasTrim && inBoundaryTolerance(value(u, v), true);
}

bool OccFaceSurface::contains(double u, double v) const {
  // (every zone: the tolerance zones and the strips, φ(u,v) evaluated once)
  return insideTrimmingLoops(u, v) && (zones().empty() || !inBoundaryTolerance(value(u, v)));
}

int OccFaceSurface::containsFast(double u, double v) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return 0;
  // Quick rejection outside the face's parameter box, in a periodic direction modulo the
  // period; inside it, the point is taken to the box's window (where the pcurves, and so the
  // grid, lie).
  const double tol = uvTol_;
  auto outside = [tol](double x, double lo, double hi, bool periodic, double period, double* rep) {
    *rep = periodic ? wrapInto(x, lo - tol, period) : x;
    return *rep < lo - tol || *rep > hi + tol;
  };
  Vec2 w;
  if (outside(u, faceBounds_.umin, faceBounds_.umax, uPeriodic_, uPeriod_, &w.x())) return 0;
  if (outside(v, faceBounds_.vmin, faceBounds_.vmax, vPeriodic_, vPeriod_, &w.y())) return 0;
  TrimShared& t = *trim_;
  if (!t.gridTried.load(std::memory_order_acquire) &&
      t.queries.fetch_add(1, std::memory_order_relaxed) < kQueriesBeforeGrid)
    return -1;
  if (const TrimGrid* grid = trimGrid()) {
    const TrimGrid& g = *grid;
    if (!cells_) cells_ = std::make_unique<TrimCells>(g);
    TrimCells& c = *cells_;
    const double x = (w.x() - g.u0) / g.du, y = (w.y() - g.v0) / g.dv;
    if (x >= 0.0 && x < TrimGrid::kCells && y >= 0.0 && y < TrimGrid::kCells) {
      const int ci = static_cast<int>(x), cj = static_cast<int>(y);
      const int k = cj * TrimGrid::kCells + ci;
      auto classify = [this](double cu, double cv) {
        return classifyWithClassifier(cu, cv, false);
      };
      std::uint8_t st = c.state[static_cast<std::size_t>(k)];
      if (st == TrimGrid::Unknown) {
        // No pcurve comes near this cell (nor the cells connected to it through such cells):
        // all of them are where its centre is.
        TrimGrid::flood(c.state.data(), TrimGrid::kCells, ci, cj,
                        classify(g.u0 + (ci + 0.5) * g.du, g.v0 + (cj + 0.5) * g.dv)
                            ? TrimGrid::In
                            : TrimGrid::Out,
                        c.scratch);
        st = c.state[static_cast<std::size_t>(k)];
      } else if (st == TrimGrid::Boundary) {
        const int si = std::min(TrimGrid::kSub - 1, static_cast<int>((x - ci) * TrimGrid::kSub));
        const int sj = std::min(TrimGrid::kSub - 1, static_cast<int>((y - cj) * TrimGrid::kSub));
        std::uint8_t* sc = c.subCells(g, k, classify);
        if (sc[sj * TrimGrid::kSub + si] == TrimGrid::Unknown)
          TrimGrid::flood(sc, TrimGrid::kSub, si, sj,
                          classify(g.u0 + ci * g.du + (si + 0.5) * g.subDu(),
                                   g.v0 + cj * g.dv + (sj + 0.5) * g.subDv())
                              ? TrimGrid::In
                              : TrimGrid::Out,
                          c.scratch);
        st = sc[sj * TrimGrid::kSub + si];
        if (st == TrimGrid::Boundary) return c.sideByCrossings(g, k, sc, w.x(), w.y(), classify);
      }
      if (st != TrimGrid::Boundary) return st == TrimGrid::In ? 1 : 0;
    }
  }
  return -1;
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
