// SurfMesh — the CAD recovery's projection tools (internal to the CAD sources): a box grid for
// point queries against many boxes (BoxGrid), the per-thread Projector (a point's distance to
// a face, an edge or the whole shape, the faces near it, where it lies on the shape), the pool
// of projectors and the parallel loop that runs them (see cad_bridge.h for the algorithm).
#pragma once

#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"

#include <BRepAdaptor_Curve.hxx>
#include <Bnd_Box.hxx>
#include <Extrema_GenLocateExtPS.hxx>
#include <GeomAdaptor_Surface.hxx>
#include <Geom_Surface.hxx>
#include <Precision.hxx>
#include <ShapeAnalysis_Surface.hxx>
#include <Standard_Failure.hxx>
#include <gp_Pnt.hxx>
#include <gp_Pnt2d.hxx>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace surfmesh::cad_detail {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
/// Twice the distance by which rounding a point to single precision may move it, relative to
/// its largest coordinate (√3 × 2^-24 ≈ 1.03e-7).
inline constexpr double kSinglePrecisionRounding = 2e-7;
inline const double kNaN = std::numeric_limits<double>::quiet_NaN();

using Box = Box3;

inline Box toBox(const Bnd_Box& b) {
  if (b.IsVoid()) return {kInf, kInf, kInf, -kInf, -kInf, -kInf};
  Box r;
  b.Get(r[0], r[1], r[2], r[3], r[4], r[5]);
  return r;
}

inline gp_Pnt toPnt(const Vec3& v) { return gp_Pnt(v.x(), v.y(), v.z()); }

/// The boxes that contain a point, through a uniform grid over their union (cells registered
/// with every box that overlaps them): for many point queries against hundreds of boxes.
class BoxGrid {
 public:
  explicit BoxGrid(std::vector<Box> boxes) : boxes_(std::move(boxes)) {
    Box all = {kInf, kInf, kInf, -kInf, -kInf, -kInf};
    std::size_t count = 0;
    for (const Box& b : boxes_) {
      if (b[0] > b[3]) continue;
      ++count;
      for (std::size_t i = 0; i < 3; ++i) {
        all[i] = std::min(all[i], b[i]);
        all[i + 3] = std::max(all[i + 3], b[i + 3]);
      }
    }
    if (count == 0) return;
    n_ = std::clamp(static_cast<int>(std::ceil(std::cbrt(static_cast<double>(count)))), 1, 32);
    for (std::size_t i = 0; i < 3; ++i) {
      lo_[i] = all[i];
      const double extent = all[i + 3] - all[i];
      scale_[i] = extent > 0.0 ? n_ / extent : 0.0;
    }
    const std::size_t cells = static_cast<std::size_t>(n_) * n_ * n_;
    std::vector<std::int32_t> counts(cells + 1, 0);
    auto visit = [&](const Box& b, auto&& f) {
      int c0[3], c1[3];
      for (std::size_t i = 0; i < 3; ++i) {
        c0[i] = cell(b[i], i);
        c1[i] = cell(b[i + 3], i);
      }
      for (int x = c0[0]; x <= c1[0]; ++x)
        for (int y = c0[1]; y <= c1[1]; ++y)
          for (int z = c0[2]; z <= c1[2]; ++z) f(static_cast<std::size_t>((x * n_ + y) * n_ + z));
    };
    for (const Box& b : boxes_)
      if (b[0] <= b[3]) visit(b, [&](std::size_t c) { ++counts[c + 1]; });
    for (std::size_t c = 0; c < cells; ++c) counts[c + 1] += counts[c];
    offset_ = counts;
    ids_.resize(static_cast<std::size_t>(offset_[cells]));
    for (std::size_t k = 0; k < boxes_.size(); ++k)
      if (boxes_[k][0] <= boxes_[k][3])
        visit(boxes_[k], [&](std::size_t c) {
          ids_[static_cast<std::size_t>(counts[c]++)] = static_cast<std::int32_t>(k);
        });
  }

  /// Calls f(id) for every box that contains p.
  template <class F>
  void forEach(const Vec3& p, F&& f) const {
    if (n_ == 0) return;
    std::size_t c = 0;
    for (std::size_t i = 0; i < 3; ++i) {
      const double x = (p[static_cast<int>(i)] - lo_[i]) * scale_[i];
      if (!(x >= 0.0) || x > n_) return;
      c = c * static_cast<std::size_t>(n_) + static_cast<std::size_t>(std::min(int(x), n_ - 1));
    }
    for (std::int32_t k = offset_[c]; k < offset_[c + 1]; ++k) {
      const std::int32_t id = ids_[static_cast<std::size_t>(k)];
      if (boxDistance(boxes_[static_cast<std::size_t>(id)], p) == 0.0) f(static_cast<int>(id));
    }
  }

 private:
  int cell(double x, std::size_t i) const {
    return std::clamp(static_cast<int>((x - lo_[i]) * scale_[i]), 0, n_ - 1);
  }
  std::vector<Box> boxes_;
  int n_ = 0;
  double lo_[3] = {0, 0, 0}, scale_[3] = {0, 0, 0};
  std::vector<std::int32_t> offset_, ids_;
};

/// Distance of a point to one face.
struct FaceHit {
  int face = -1;
  double dist = kInf;      ///< distance to the trimmed face
  Vec2 uv = Vec2::Zero();  ///< projection on the face's surface (wrapped)
  bool inside = false;     ///< the surface projection lies in the trimmed domain
  bool hasUV = false;      ///< uv holds a projection (false for hits made from hints)
};
/// Per-thread projection tools on a CadShape (OCC algorithms are not shared between threads).
class Projector {
 public:
  Projector(const CadShape& s, const std::vector<Box>& faceBoxes, const std::vector<Box>& edgeBoxes,
            const std::vector<double>& faceSlack)
      : s_(s),
        faceBoxes_(faceBoxes),
        edgeBoxes_(edgeBoxes),
        faceSlack_(faceSlack),

        tools_(static_cast<std::size_t>(s.faceCount())),
        curves_(static_cast<std::size_t>(s.edgeCount())),
        surfaceCopies_(static_cast<std::size_t>(s.faceCount())),
        curveCopies_(static_cast<std::size_t>(s.edgeCount())) {
    preci_ = std::max(Precision::Confusion(), 1e-9 * s.diagonal());
    for (double x : faceSlack) maxSlack_ = std::max(maxSlack_, x);
  }

  /// Per-face projection tools of this thread.
  struct FaceTools {
    Handle(Geom_Surface) g;
    std::unique_ptr<GeomAdaptor_Surface> ad;
    std::unique_ptr<Extrema_GenLocateExtPS> loc;  // null for analytic surfaces
    std::unique_ptr<ShapeAnalysis_Surface> sas;
    std::vector<Vec3> samples;
    std::vector<Vec2> sampleUV;
    std::vector<unsigned char> sampleDegenerate;
    std::vector<Box> cells;   // boxes enclosing the surface over the face's (u,v) range
    std::vector<Box> blocks;  // the boxes of kBlock × kBlock cells
    Vec2 last = Vec2::Zero();
    Vec2 rest = Vec2::Zero();  // where the evaluation caches are reset (see forgetStarts)
    bool hasLast = false;
    bool ready = false;
    bool used = false;
  };

  /// Forgets the last foot point of every face used since the last call (the start of the
  /// next local search there) and puts its evaluators back in one state, so that what a run of
  /// queries finds does not depend on the queries made before it. (A B-spline adaptor caches
  /// one span; a point on a knot is evaluated in the cached span if it bounds it, which moves
  /// the result in the last bits.)
  void forgetStarts() {
    for (int f : used_) {
      FaceTools& ft = tools_[static_cast<std::size_t>(f)];
      ft.hasLast = false;
      ft.used = false;
      rest(ft);
    }
    used_.clear();
  }

  static void rest(FaceTools& ft) {
    if (ft.ad) ft.ad->Value(ft.rest.x(), ft.rest.y());
    if (ft.sas && ft.loc) ft.sas->Adaptor3d()->Value(ft.rest.x(), ft.rest.y());
  }

  /// This thread's tools for face f, built on its first use (and f noted as used since the
  /// last forgetStarts()).
  FaceTools& tools(int f);

  /// A lower bound on the distance from p to face f, whose bounding box is `box` away: the
  /// nearest of its cell boxes (free-form faces), never less than `box`.
  double lowerBound(int f, const Vec3& p, double box);

  /// Distance from p to edge e and the curve parameter of the nearest point.
  double edgeDistance(int e, const Vec3& p, double* t);

  /// Projection of p on the surface of face f; fills hit.uv (wrapped), hit.inside and the
  /// distance to the untrimmed surface (returned).
  double surfaceProjection(int f, const Vec3& p, FaceHit* hit);

  /// Free-form surfaces: OCC's local extremum search (Extrema_GenLocateExtPS, the normal
  /// equations, then the distance criterion) started from the previous point on this face and
  /// from the nearest non-degenerate samples of a grid over the face, until a point within
  /// `enough` (the point is on the surface) is found; ShapeAnalysis_Surface::ValueOfUV (global)
  /// when every start fails.
  void localProjection(FaceTools& ft, const gp_Pnt& P, double slack, gp_Pnt2d* uv, double* gap);

  /// For a face spanning several periods: shifts uv by whole periods of the underlying
  /// surface to a copy inside the face, if any (else leaves it in the face's range).
  bool findTurn(const OccFaceSurface& surf, int f, Vec2* uv);

  /// This thread's copies of face f's surface and edge e's curve (OCC adaptors are not
  /// thread-safe), made on first use.
  const Surface& surfaceCopy(int f) {
    auto& c = surfaceCopies_[static_cast<std::size_t>(f)];
    if (!c) c = s_.surface(f).clone();
    return *c;
  }
  const Curve& curveCopy(int e) {
    auto& c = curveCopies_[static_cast<std::size_t>(e)];
    if (!c) c = s_.curve(e).clone();
    return *c;
  }

  /// Whether (u,v) is inside (or on) face f's trimming loops: this thread's copy of the face
  /// answers at once away from the loops (its grid and classifier are shared with the other
  /// copies, the optimizer's included); next to them OCC's polygon test with its deflection
  /// band decides (the caller measures distances: exactness at the boundary is moot).
  bool classify(int f, const Vec2& uv) {
    const auto& surf = static_cast<const OccFaceSurface&>(surfaceCopy(f));
    const int known = surf.containsFast(uv.x(), uv.y());
    if (known >= 0) return known == 1;
    try {
      return surf.containsWithinBand(uv.x(), uv.y());
    } catch (const Standard_Failure&) {
      return false;
    }
  }

  /// Distance from p to the trimmed face f. Refinement through the boundary edges is skipped
  /// when the distance is certainly above `bound` (then the returned distance is a lower
  /// bound, > bound).
  FaceHit faceDistance(int f, const Vec3& p, double bound);

  /// 2 × the tolerance of the boundary edge of face f nearest to p (at least `base`).
  double boundarySlack(int f, const Vec3& p, double base);

  /// FreeCAD's node-on-entity rule (FemMesh.getNodesByVertex/Edge) for one node: the nearest
  /// vertex within its tolerance (`vertexTol`), else the only edge closer than its tolerance
  /// (`edgeTol`); −1 when none (or several edges) qualify.
  void toleranceHint(const Vec3& p, const BoxGrid& vertexGrid, const std::vector<double>& vertexTol,
                     const BoxGrid& edgeGrid, const std::vector<double>& edgeTol, int* hv, int* he);

  /// Whether a vertex other than `except` is nearer to p than d.
  bool vertexNearerThan(const Vec3& p, double d, int except) const;

  /// Whether an edge other than `except` (degenerated edges left out) is nearer to p than d.
  bool edgeNearerThan(const Vec3& p, double d, int except);

  /// Exact distance from p to the whole shape (branch and bound over face boxes).
  double shapeDistance(const Vec3& p, int* nearestFace);

  /// Distance from p to the whole shape: its faces, and the edges and vertices that bound no
  /// face (free edges, lone vertices: a shell's or a wire's), with the nearest entity
  /// (`kind`: Face, Edge or Vertex, `id` its 0-based id).
  double wholeShapeDistance(const Vec3& p, NodeClass* kind, int* id);

  /// Distances of a result's node as FreeCAD's distToShape measures them (the report's
  /// max_distance_to_face / _shape): to face f with its boundary edges' 3D curves, and to the
  /// whole shape with every edge's 3D curve. An edge's 3D curve is the B-rep's reference for
  /// the edge and may lie as far as the edge's tolerance off the faces' surfaces (the
  /// bottle's edges: 0.016): a node sliding on it is on the face. The edges are measured only
  /// where the face or shape distance exceeds `onShape` (below it the answer is known to be
  /// on the shape). `toFace` is NaN when f < 0; when it is at most `onShape`, `toShape` is
  /// taken equal to it (an upper bound) without searching the whole shape.
  void resultDistances(int f, const Vec3& p, double onShape, double* toFace, double* toShape);

  /// Where p lies on the whole shape: the CAD vertex within its tolerance (at least `close`),
  /// else the CAD edge (face-bound or free) within its tolerance, else the nearest face or
  /// free edge or lone vertex (wholeShapeDistance). Returns the distance to that entity.
  double locate(const Vec3& p, double close, NodeClass* kind, int* id, double* t);

  /// Every face within tol of p. Faces are searched near p first (the radius the per-face
  /// slack needs once a face at distance ~0 is found), then out to tol if none is that close.
  /// With `keep` > 0, faces farther than the nearest one plus max(keep, their slack) may be
  /// left out (the caller drops them): near p, faces are then visited nearest lower bound
  /// first, and a face whose lower bound is beyond that is not projected on.
  void facesNear(const Vec3& p, double tol, std::vector<FaceHit>* out, double keep = 0.0);

 private:
  static constexpr int kCells = 16;  // sampling grid of a free-form face: kCells² cells
  static constexpr double kSampleTurn = 0.39269908169872414;  // π/8
  static constexpr std::size_t kMaxSamples = 4096;
  static constexpr int kBlock = 4;  // cells per block side in lowerBound's search

  const CadShape& s_;
  const std::vector<Box>& faceBoxes_;
  const std::vector<Box>& edgeBoxes_;
  const std::vector<double>& faceSlack_;
  std::vector<FaceTools> tools_;
  std::vector<unsigned char> seen_;
  std::vector<std::pair<double, int>> order_;
  std::vector<int> used_;
  double maxSlack_ = 0.0;
  std::vector<std::unique_ptr<BRepAdaptor_Curve>> curves_;
  std::vector<std::unique_ptr<Surface>> surfaceCopies_;
  std::vector<std::unique_ptr<Curve>> curveCopies_;
  double preci_ = 1e-7;
};

/// The CAD recovery's projectors, one per thread slot, kept from one parallel pass to the next
/// (each builds its OCC tools and classifiers once per face, on first use).
struct ProjectorPool {
  ProjectorPool(int threads, const CadShape& s, const std::vector<Box>& fb,
                const std::vector<Box>& eb, const std::vector<double>& slack)
      : s_(s), fb_(fb), eb_(eb), slack_(slack), slots_(static_cast<std::size_t>(threads)) {}
  Projector& slot(std::size_t k) {
    auto& p = slots_[k];
    if (!p) p = std::make_unique<Projector>(s_, fb_, eb_, slack_);
    return *p;
  }
  std::size_t size() const { return slots_.size(); }

 private:
  const CadShape& s_;
  const std::vector<Box>& fb_;
  const std::vector<Box>& eb_;
  const std::vector<double>& slack_;
  std::vector<std::unique_ptr<Projector>> slots_;
};

/// Runs body(i, projector) for i in [0, n) on up to pool.size() threads, each with its own
/// Projector. The indices go in fixed chunks, each started with no foot point from earlier
/// queries (Projector::forgetStarts): which thread takes a chunk changes nothing, so the
/// recovery gives the same (u,v) to the last bit from run to run and for any thread count.
template <class Body>
void parallelFor(std::size_t n, ProjectorPool& pool, Body body) {
  const std::size_t chunk = 256;
  std::atomic<std::size_t> next{0};
  std::exception_ptr error;
  std::mutex errorMutex;
  auto worker = [&](std::size_t k) {
    try {
      Projector& proj = pool.slot(k);
      for (;;) {
        const std::size_t begin = next.fetch_add(chunk);
        if (begin >= n) break;
        const std::size_t end = std::min(n, begin + chunk);
        proj.forgetStarts();
        for (std::size_t i = begin; i < end; ++i) body(i, proj);
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(errorMutex);
      if (!error) error = std::current_exception();
      next = n;
    }
  };
  const int threads = static_cast<int>(pool.size());
  const int t = std::max(1, std::min<int>(threads, static_cast<int>((n + chunk - 1) / chunk)));
  if (t == 1) {
    worker(0);
  } else {
    std::vector<std::thread> team;
    for (int k = 0; k < t; ++k) team.emplace_back(worker, static_cast<std::size_t>(k));
    for (auto& th : team) th.join();
  }
  if (error) std::rethrow_exception(error);
}

/// What a Projector works with: the boxes of the shape's faces and edges, and per face how much
/// farther than the nearest face a node may be and still lie on it (the sloppiest tolerance
/// among the face's edges and vertices, at least 1e-6·diag, at most `tol`).
void projectorGeometry(const CadShape& S, double tol, std::vector<Box>* faceBoxes,
                       std::vector<Box>* edgeBoxes, std::vector<double>* faceSlack);

}  // namespace surfmesh::cad_detail
