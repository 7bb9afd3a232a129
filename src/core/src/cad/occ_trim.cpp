// SurfMesh — OccFaceSurface::contains(): the trimming loops through the grid of the face's
// pcurves (TrimGrid, TrimCells) and OCC's classifier, then the tolerance zones (see
// occ_surface.h).
#include "occ_trim.h"

#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Tool.hxx>
#include <Geom2dAdaptor_Curve.hxx>
#include <Geom2d_Curve.hxx>
#include <Standard_Failure.hxx>
#include <TopAbs_State.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <gp_Pnt2d.hxx>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace surfmesh {

using occ_detail::buildToleranceZones;
using occ_detail::segmentDistance2;

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

const OccFaceSurface::ToleranceZones& OccFaceSurface::zones() const {
  TrimShared& t = *trim_;
  std::call_once(t.zonesOnce,
                 [&]() { t.zones = buildToleranceZones(face_, t.shapeDiagonal, uvTol_); });
  return *t.zones;
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
}  // namespace surfmesh
