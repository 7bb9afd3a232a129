// SurfMesh — OpenCASCADE adapters: a B-rep face as a Surface, a B-rep edge as a Curve.
//
// OccFaceSurface wraps a BRepAdaptor_Surface on a TopoDS_Face (the face's location applied):
//   * value/d1/d2 are BRepAdaptor_Surface::D0/D1/D2 (the parameterization of the underlying
//     surface, NOT reversed for a Reversed face: the face orientation only sets normalSign());
//   * bounds() is BRepTools::UVBounds of the face, except in periodic directions where it is
//     one period [c − P/2, c + P/2) centred on the middle c of the face's own range (so a face
//     that covers a full period gets [umin, umin + P), and a partial face never straddles the
//     wrap point: a node slightly outside its face's range is not sent a period away);
//     A face whose own range exceeds one period (a helical thread flank wound on a cylinder)
//     is NOT reported periodic: its bounds are its own range, on which its (u,v) are unique;
//     uTurnPeriod()/vTurnPeriod() give the underlying period to find a point's (u,v) there;
//   * normalSign() = −1 when face.Orientation() == TopAbs_REVERSED;
//   * contains(u,v) classifies (u,v) against the face's trimming loops (holes, inner wires)
//     with BRepTopAdaptor_FClass2d, after wrapping periodic coordinates (see contains() for
//     what counts as outside: the classifier's ON band, and φ(u,v) within the tolerance of
//     an edge or vertex of the face);
//     A 48 × 48 grid over the face's (u,v) box, with 16 × 16 sub-cells in the cells a pcurve
//     comes near, answers at once in every (sub-)cell no pcurve comes near: such regions are
//     classified once (by the classifier at one centre, then flood-filled); only points in
//     the sub-cells a pcurve passes through go to the classifier. The optimizer asks
//     contains() at every line-search trial; it builds the grids of the faces with free nodes
//     ahead (prepare()), other callers get one on a face's 48th query (before, the classifier
//     answers: a face queried a few times never pays for a grid).
//
// Neither class is thread-safe (OCC adaptors and the lazily classified cells are not): use
// clone() to get an independent copy per thread. A face's classifier and the pcurve index of
// its grid are built once, on the first contains() of any copy, and shared by all copies
// (the classifier's queries, rare once the grid answers, are serialized by a mutex); each
// copy keeps its own cell states, starting from those of the surface it was cloned from.
#pragma once

#include "surfmesh/geometry/curve.h"
#include "surfmesh/geometry/surface.h"

#include <Adaptor3d_Surface.hxx>
#include <BRepAdaptor_Curve.hxx>
#include <BRepAdaptor_Surface.hxx>
#include <Geom2d_Curve.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace surfmesh {

/// OCC name of the geometric type of a face's surface: "Plane", "Cylinder", "Cone", "Sphere",
/// "Torus", "BezierSurface", "BSplineSurface", "SurfaceOfRevolution", "SurfaceOfExtrusion",
/// "OffsetSurface", "OtherSurface".
std::string occSurfaceTypeName(const TopoDS_Face& face);

/// Axis-aligned box: xmin, ymin, zmin, xmax, ymax, zmax.
using Box3 = std::array<double, 6>;

/// Boxes that enclose surface `s` over the (u,v) rectangle `b`, one per cell of a
/// cells × cells grid: each is the box of its cell's corners, edge midpoints and centre, grown
/// by the largest gap between one of those midpoints and the middle of its chord, plus `grow`.
/// That is about four times what a surface smooth at the scale of a cell can bulge out of
/// the nine points' box, so every point of the surface over `b` lies in one of the boxes and
/// min over the boxes of their distance to p is a lower bound on p's distance to that part of
/// the surface (and the boxes are close: a box holds surface points, so the bound is at most
/// one box diagonal below the distance). Empty when an evaluation is not finite.
std::vector<Box3> surfacePatchBoxes(const Adaptor3d_Surface& s, const ParamBounds& b, int cells,
                                    double grow);

/// Squared distance from p to box b (0 inside; +inf for an empty box).
double boxDistance2(const Box3& b, const Vec3& p);

/// Distance from p to box b (0 inside; +inf for an empty box).
double boxDistance(const Box3& b, const Vec3& p);

/// How far the trimming curve of `edge` on `face` lies off the edge's 3D curve: the largest
/// distance from the surface's image of the pcurve, at `samples` parameters (a + (b − a)(i +
/// ½)/samples; with `ends` also a and b), to the 3D curve (its ends and Extrema_ExtPC's
/// minima). 0 for a degenerated edge or when OCC has no pcurve.
double trimCurveGap(const TopoDS_Edge& edge, const TopoDS_Face& face, int samples,
                    bool ends = false);
/// The samples trimCurveGap takes where a gap is reported (CadMesh's trim_gaps).
constexpr int kTrimGapSamples = 7;
/// Whether a trimming curve `gap` off its edge makes the face's 2D and 3D boundaries
/// disagree: beyond twice the edge's tolerance and 1e-6 × the shape's diagonal.
bool isTrimGap(double gap, double edgeTolerance, double diag);

/// A TopoDS_Face as a Surface (see the file comment for the conventions).
class OccFaceSurface final : public Surface {
 public:
  /// @param[in] face    the face (its location and orientation are honoured)
  /// @param[in] faceId  id used in describe() (e.g. the CadShape face index; −1 if none)
  explicit OccFaceSurface(const TopoDS_Face& face, int faceId = -1);
  ~OccFaceSurface() override;

  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override { return bounds_; }
  bool isUPeriodic() const override { return uPeriodic_; }
  bool isVPeriodic() const override { return vPeriodic_; }
  double uPeriod() const override { return uPeriod_; }
  double vPeriod() const override { return vPeriod_; }
  int normalSign() const override { return normalSign_; }
  /// Strictly inside the face: within the parameter range of its underlying surface in the
  /// non-periodic directions (no tolerance: a B-spline beyond its knots is an extrapolation,
  /// off the face's geometry) and inside its trimming loops. A point OCC's classifier puts ON
  /// a loop (within uvTolerance() of it, on either side) counts as outside: a node moved
  /// only to (u,v) that contains() accepts stays on the face as FreeCAD measures it
  /// (Face.distToShape), not merely within the face's tolerance of it.
  /// So does a point whose φ(u,v) lies within the tolerance zone of one of the face's
  /// boundary entities (inBoundaryTolerance()): OCC counts it ON that edge or vertex, and a
  /// node there is read back as an edge (vertex) node by the CAD recovery's tolerance hints
  /// and by FreeCAD's getNodesByEdge — at up to the edge's tolerance from its 3D curve, which
  /// on imported parts (1e-3 and more) lies that far from the loop its pcurve draws.
  ///
  /// Where a trimming curve lies off its 3D edge (isTrimGap: an imported B-rep whose 2D and
  /// 3D boundaries disagree), φ(u,v) on the 3D curve's outer side, within 1.25 × the gap
  /// (plus the edge's tolerance) of it, counts as outside too (inTrimStrip), so that no move
  /// takes a node outside the face's 3D boundary while its 2D boundary says inside.
  bool contains(double u, double v) const override;
  /// contains() without the tolerance zones of tolerant edges and vertices (the trimming
  /// loops, the classifier's band and the strips of trimming curves off their 3D edges).
  bool containsNearBoundary(double u, double v) const override;
  /// Whether φ(u,v) lies in the strip along a trimming curve off its 3D edge (see contains()).
  bool inTrimStrip(double u, double v) const;
  /// Whether a trimming curve of the face lies off its 3D edge (isTrimGap).
  bool hasTrimGaps() const;
  /// The shape's diagonal, the scale of isTrimGap for this face and its copies (CadShape sets
  /// it before any query; unset, the face's own box diagonal is taken).
  void setShapeDiagonal(double diag);
  /// Whether point p is within the tolerance of a vertex of the face (BRep_Tool::Tolerance)
  /// or within the tolerance of a non-degenerated edge of the face from its 3D curve (the
  /// distance the CAD recovery's tolerance hints take: Extrema_ExtPC and the ends), for the
  /// vertices and edges more than twice as tolerant as the face (the classifier's band keeps
  /// contains() off the others), or within the strip of a trimming curve off its 3D edge
  /// (with `trimOnly`, only those). The zones are built on first use and shared by the copies.
  bool inBoundaryTolerance(const Vec3& p, bool trimOnly = false) const;
  /// The trimming-loop part of contains() where it needs no classifier query at (u,v)
  /// itself: 1 inside, 0 outside (outside the face's parameter box, in a periodic direction
  /// modulo the period; in a sub-cell no trimming loop passes through; or, in one that a loop
  /// passes through, by the parity of the grid's pcurve pieces crossed on the way to a
  /// sub-cell of known side); −1
  /// within 1/10 sub-cell plus the tolerance of a pcurve piece (or when the face has no grid),
  /// where only a classifier can tell. (Classifying a region of the grid for the first time
  /// asks the classifier at one point of it.)
  int containsFast(double u, double v) const;
  /// OCC's fast polygon test (BRepTopAdaptor_FClass2d::TestOnRestriction) with the shared
  /// classifier: a point within the polygon's deflection band of a loop counts as inside. For
  /// callers that measure distances (the CAD recovery), where exactness at the boundary is
  /// moot. May throw Standard_Failure.
  bool containsWithinBand(double u, double v) const;
  /// Builds the grid of the face's trimming loops (shared by the copies).
  void prepare() const override;
  std::unique_ptr<Surface> clone() const override;
  /// "OCC face 12 (BSplineSurface)".
  std::string describe() const override;

  /// BRepTools::UVBounds of the face (not widened to a period).
  const ParamBounds& faceUVBounds() const { return faceBounds_; }
  /// Tolerance in (u,v) used by contains() (resolution of the face's 3D tolerance).
  double uvTolerance() const { return uvTol_; }
  /// Period of the underlying surface in u (v) when the face spans more than one period
  /// (then isUPeriodic() is false and (u,v) must be taken in faceUVBounds()); else 0.
  double uTurnPeriod() const { return uTurn_; }
  double vTurnPeriod() const { return vTurn_; }
  const TopoDS_Face& face() const { return face_; }
  const BRepAdaptor_Surface& adaptor() const { return adaptor_; }
  int faceId() const { return faceId_; }

  /// Cells of the face's (u,v) box that no trimming loop crosses answer contains() at once
  /// (defined in occ_trim.h): the pcurve index (TrimGrid, shared by the copies of a
  /// face with its classifier in TrimShared) and the cell states classified so far
  /// (TrimCells, one per copy).
  struct TrimGrid;
  struct TrimCells;
  struct TrimShared;
  /// The tolerance zones of the face's edges and vertices (inBoundaryTolerance()), shared,
  /// and the curve adaptors this copy measures them with.
  struct ToleranceZones;
  struct ZoneCurves;

 private:
  TopoDS_Face face_;
  int faceId_;
  BRepAdaptor_Surface adaptor_;
  ParamBounds bounds_, faceBounds_;
  /// Parameter range of the underlying surface (Geom_Surface::Bounds), ±∞ in a periodic or
  /// unbounded direction.
  ParamBounds surfaceBounds_;
  bool uPeriodic_ = false, vPeriodic_ = false;
  double uPeriod_ = 0.0, vPeriod_ = 0.0;
  double uTurn_ = 0.0, vTurn_ = 0.0;
  int normalSign_ = 1;
  double uvTol_ = 1e-9;
  std::shared_ptr<TrimShared> trim_;                // classifier + grid, built when first needed
  mutable std::unique_ptr<TrimCells> cells_;        // this copy's cell states (with the grid)
  mutable std::unique_ptr<ZoneCurves> zoneCurves_;  // this copy's edge adaptors (zones)
  OccFaceSurface(const OccFaceSurface& other);      // clone(): shares trim_, copies cells_
  const TrimGrid* trimGrid() const;     // trim_'s grid, built on first use (thread-safe)
  const ToleranceZones& zones() const;  // trim_'s zones, built on first use (thread-safe)
  /// The face's OCC classifier (BRepTopAdaptor_FClass2d with uvTolerance(), built on first
  /// use, shared by the copies, its queries serialized) at a wrapped (u,v): Perform, or with
  /// `band` TestOnRestriction. IN counts as inside, and ON too unless `strict`.
  bool classifyWithClassifier(double u, double v, bool band, bool strict = false) const;
  /// The trimming loops' part of contains(): (u,v) in the underlying surface's range and
  /// strictly inside the loops (containsFast, else the classifier; ON counts as outside).
  bool insideTrimmingLoops(double u, double v) const;
};

/// One face adjacent to an edge, with the edge's pcurve(s) on it.
struct EdgeFaceUse {
  int faceId = -1;               ///< face id (CadShape numbering)
  TopoDS_Face face;              ///< the face
  Handle(Geom2d_Curve) pcurve;   ///< pcurve of the FORWARD edge on the face
  Handle(Geom2d_Curve) pcurve2;  ///< second pcurve of a seam edge (REVERSED use), else null
  double uPeriod = 0.0;          ///< period of the face in u (0 if not periodic)
  double vPeriod = 0.0;          ///< period of the face in v (0 if not periodic)
};

/// A TopoDS_Edge as a Curve: C(t) and its derivatives from BRepAdaptor_Curve (t ∈ the edge's
/// range [tmin, tmax], the parameter of its 3D curve), and (u,v) on each adjacent face from the
/// edge's pcurves (BRep_Tool::CurveOnSurface; the two pcurves of a seam edge).
///
/// isPeriodic() is true for a closed edge whose curve is periodic with period tmax − tmin
/// (a full circle): t may then be wrapped by the period. A degenerated edge (a pole, no 3D
/// curve) evaluates to its vertex with zero derivatives.
class OccEdgeCurve final : public Curve {
 public:
  OccEdgeCurve(const TopoDS_Edge& edge, int edgeId, std::vector<EdgeFaceUse> faces);

  Vec3 value(double t) const override;
  CurveD2 d2(double t) const override;
  double tmin() const override { return tmin_; }
  double tmax() const override { return tmax_; }
  bool isPeriodic() const override { return periodic_; }
  double period() const override { return period_; }

  int faceCount() const override { return static_cast<int>(faces_.size()); }
  int faceId(int k) const override { return faces_[static_cast<std::size_t>(k)].faceId; }
  /// (u,v) of C(t) on face `faceId` through the pcurve; for a seam edge the pcurve whose image
  /// is closest to `near`. The result is shifted by whole periods of the face to be as close
  /// as possible to `near`. Throws std::invalid_argument if the edge does not bound that face.
  Vec2 uvOnFace(int faceId, double t, const Vec2& near) const override;

  std::unique_ptr<Curve> clone() const override;
  /// "OCC edge 7 (Circle)".
  std::string describe() const override;

  const TopoDS_Edge& edge() const { return edge_; }
  int edgeId() const { return edgeId_; }
  bool isDegenerated() const { return degenerated_; }
  /// Whether this edge is a seam of face `faceId` (two pcurves on it).
  bool isSeamOf(int faceId) const;
  const std::vector<EdgeFaceUse>& faceUses() const { return faces_; }
  /// The adaptor (valid only when !isDegenerated()).
  const BRepAdaptor_Curve& adaptor() const { return adaptor_; }

 private:
  const EdgeFaceUse& use(int faceId) const;

  TopoDS_Edge edge_;
  int edgeId_;
  std::vector<EdgeFaceUse> faces_;
  BRepAdaptor_Curve adaptor_;
  bool degenerated_ = false;
  Vec3 degeneratePoint_ = Vec3::Zero();
  double tmin_ = 0.0, tmax_ = 0.0;
  bool periodic_ = false;
  double period_ = 0.0;
};

}  // namespace surfmesh
