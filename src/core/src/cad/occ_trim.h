// SurfMesh — the trimming machinery of OccFaceSurface (internal to the CAD sources): the grid
// that answers contains() without the classifier (TrimGrid, TrimCells), the tolerance zones of
// a face's boundary (ToleranceZones, ZoneCurves) and what the copies of a face share
// (TrimShared), with the small box and point helpers the adapters' sources share.
#pragma once

#include "surfmesh/cad/occ_surface.h"

#include <BRepTopAdaptor_FClass2d.hxx>
#include <gp_Pnt.hxx>
#include <gp_Vec.hxx>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

namespace surfmesh {

namespace occ_detail {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// A box that contains nothing (grown by include()).
inline constexpr Box3 kEmptyBox = {kInf, kInf, kInf, -kInf, -kInf, -kInf};

/// Grows b to take in the ball of radius r around p.
inline void include(Box3& b, const Vec3& p, double r = 0.0) {
  for (std::size_t k = 0; k < 3; ++k) {
    b[k] = std::min(b[k], p[static_cast<int>(k)] - r);
    b[k + 3] = std::max(b[k + 3], p[static_cast<int>(k)] + r);
  }
}

/// Grows b to take in box c.
inline void include(Box3& b, const Box3& c) {
  for (std::size_t k = 0; k < 3; ++k) {
    b[k] = std::min(b[k], c[k]);
    b[k + 3] = std::max(b[k + 3], c[k + 3]);
  }
}

inline Vec3 toVec(const gp_Pnt& p) { return Vec3(p.X(), p.Y(), p.Z()); }
inline Vec3 toVec(const gp_Vec& v) { return Vec3(v.X(), v.Y(), v.Z()); }

/// Squared distance from point (px, py) to the segment (ax, ay)–(bx, by).
inline double segmentDistance2(double ax, double ay, double bx, double by, double px, double py) {
  const double ex = bx - ax, ey = by - ay, l2 = ex * ex + ey * ey;
  const double t = l2 > 0.0 ? std::clamp(((px - ax) * ex + (py - ay) * ey) / l2, 0.0, 1.0) : 0.0;
  const double dx = ax + t * ex - px, dy = ay + t * ey - py;
  return dx * dx + dy * dy;
}

/// Squared distance from p to the segment a–b.
inline double segmentDistance2(const Vec3& a, const Vec3& b, const Vec3& p) {
  const Vec3 e = b - a;
  const double l2 = e.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(e) / l2, 0.0, 1.0) : 0.0;
  return (a + t * e - p).squaredNorm();
}

/// The zones of `face` (see OccFaceSurface::ToleranceZones): of its edges and vertices more
/// than twice as tolerant as the face itself (the classifier's band, the face's tolerance,
/// keeps contains() off the others: on a part built by OCC, whose tolerances are all 1e-7,
/// there are none). An edge's polyline: its curve cut in 8 pieces, halved until the curve at a
/// quarter, half and three quarters of a piece is within dev = max(tolerance / 10, 1e-4 × the
/// diagonal of the edge's box) of its chord. `diag`: the scale of isTrimGap (≤ 0: the face's
/// own box diagonal); `uvTol`: the face's classifier tolerance. Defined in occ_zones.cpp.
std::unique_ptr<OccFaceSurface::ToleranceZones> buildToleranceZones(const TopoDS_Face& face,
                                                                    double diag, double uvTol);

}  // namespace occ_detail

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
      if (occ_detail::segmentDistance2(ax, ay, bx, by, px, py) <= margin * margin) return -1;
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
    Box3 box = occ_detail::kEmptyBox;
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

}  // namespace surfmesh
