// SurfMesh — OpenCASCADE adapters (OccFaceSurface, OccEdgeCurve) and CadShape on real parts.
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/cad/occ_surface.h"

#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepClass3d_SolidClassifier.hxx>
#include <BRepClass_FaceClassifier.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRepTopAdaptor_FClass2d.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <Geom2d_Curve.hxx>
#include <GeomAPI_ProjectPointOnCurve.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <GeomAdaptor_Surface.hxx>
#include <Geom_Curve.hxx>
#include <Geom_Surface.hxx>
#include <Poly_Triangulation.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Wire.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Vec2d.hxx>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

using namespace surfmesh;

namespace {

std::shared_ptr<CadShape> load(const std::string& name) {
  return CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/" + name);
}

/// The (n + 1)² points of a regular lattice over a face's (u,v) box.
std::vector<Vec2> uvLattice(const ParamBounds& b, int n) {
  std::vector<Vec2> out;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      out.emplace_back(b.umin + (b.umax - b.umin) * i / n, b.vmin + (b.vmax - b.vmin) * j / n);
  return out;
}

/// OCC's own answer for (u,v) of face s: Perform of an independent classifier, IN or ON.
bool insideByOcc(BRepTopAdaptor_FClass2d& ref, const OccFaceSurface& s, const Vec2& p) {
  const Vec2 w = s.wrap(p);
  const TopAbs_State st = ref.Perform(gp_Pnt2d(w.x(), w.y()), Standard_True);
  return st == TopAbs_IN || st == TopAbs_ON;
}

/// contains()'s reference for (u,v) of face s: an independent classifier's Perform says IN
/// (ON, within the face's (u,v) tolerance of a loop on either side, counts as outside), and
/// (u,v) lies in the range of the face's underlying surface (Geom_Surface::Bounds) in the
/// directions that are not periodic.
bool strictlyInsideByOcc(BRepTopAdaptor_FClass2d& ref, const OccFaceSurface& s, const Vec2& p,
                         bool recadre = true) {
  const Vec2 w = s.wrap(p);
  const Handle(Geom_Surface) g = BRep_Tool::Surface(s.face());
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  g->Bounds(u0, u1, v0, v1);
  if (!s.isUPeriodic() && s.uTurnPeriod() == 0.0 && !g->IsUPeriodic() && (w.x() < u0 || w.x() > u1))
    return false;
  if (!s.isVPeriodic() && s.vTurnPeriod() == 0.0 && !g->IsVPeriodic() && (w.y() < v0 || w.y() > v1))
    return false;
  return ref.Perform(gp_Pnt2d(w.x(), w.y()), recadre ? Standard_True : Standard_False) == TopAbs_IN;
}

/// contains()'s full reference: strictlyInsideByOcc, and φ(u,v) outside the tolerance zones
/// of the face's edges and vertices (inBoundaryTolerance(), checked on its own by
/// ContainsExcludesTheToleranceZonesOfTheFacesEdgesAndVertices).
bool containedByOcc(BRepTopAdaptor_FClass2d& ref, const OccFaceSurface& s, const Vec2& p,
                    bool recadre = true) {
  return strictlyInsideByOcc(ref, s, p, recadre) && !s.inBoundaryTolerance(s.value(p.x(), p.y()));
}

/// Interior (u,v) points of a face: the nodes of its BRepMesh triangulation that are not on
/// an edge polygon.
std::vector<Vec2> interiorUV(const TopoDS_Face& face, double deflection) {
  BRepMesh_IncrementalMesh(face, deflection, Standard_False, 0.5);
  TopLoc_Location loc;
  const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
  std::vector<Vec2> out;
  if (tri.IsNull() || !tri->HasUVNodes()) return out;
  std::vector<unsigned char> onEdge(static_cast<std::size_t>(tri->NbNodes()) + 1, 0);
  for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
    const auto poly = BRep_Tool::PolygonOnTriangulation(TopoDS::Edge(ex.Current()), tri, loc);
    if (poly.IsNull()) continue;
    for (int k = 1; k <= poly->NbNodes(); ++k) onEdge[static_cast<std::size_t>(poly->Node(k))] = 1;
  }
  for (int i = 1; i <= tri->NbNodes(); ++i)
    if (!onEdge[static_cast<std::size_t>(i)])
      out.emplace_back(tri->UVNode(i).X(), tri->UVNode(i).Y());
  return out;
}

/// (u,v) centroids of a face's BRepMesh triangles (inside the face).
std::vector<Vec2> triangleCentroidsUV(const TopoDS_Face& face, double deflection) {
  BRepMesh_IncrementalMesh(face, deflection, Standard_False, 0.5);
  TopLoc_Location loc;
  const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
  std::vector<Vec2> out;
  if (tri.IsNull() || !tri->HasUVNodes()) return out;
  for (int t = 1; t <= tri->NbTriangles(); ++t) {
    int a = 0, b = 0, c = 0;
    tri->Triangle(t).Get(a, b, c);
    const gp_XY m = (tri->UVNode(a).XY() + tri->UVNode(b).XY() + tri->UVNode(c).XY()) / 3.0;
    out.emplace_back(m.X(), m.Y());
  }
  return out;
}

TEST(OccFaceSurface, DerivativesMatchFiniteDifferencesOnBSplineFaces) {
  auto shape = load("occt_propeller.brep");
  int tested = 0;
  for (int f = 0; f < shape->faceCount() && tested < 4; ++f) {
    if (shape->faceType(f) != "BSplineSurface") continue;
    ++tested;
    const OccFaceSurface& s = shape->surface(f);
    const ParamBounds b = s.faceUVBounds();
    for (double a : {0.3, 0.5, 0.7}) {
      const double u = b.umin + a * (b.umax - b.umin), v = b.vmin + (1 - a) * (b.vmax - b.vmin);
      const SurfaceD2 d = s.d2(u, v);
      EXPECT_LE((d.p - s.value(u, v)).norm(), 1e-12 * (1 + d.p.norm()));
      const SurfaceD1 d1 = s.d1(u, v);
      EXPECT_LE((d1.du - d.du).norm(), 1e-12 * (1 + d.du.norm()));
      // Central differences, error O(h²): compare at two steps and check the rate.
      auto err = [&](double hu, double hv) {
        const SurfaceD2 pu = s.d2(u + hu, v), mu = s.d2(u - hu, v);
        const SurfaceD2 pv = s.d2(u, v + hv), mv = s.d2(u, v - hv);
        std::array<double, 5> e = {
            ((pu.p - mu.p) / (2 * hu) - d.du).norm() / (1 + d.du.norm()),
            ((pv.p - mv.p) / (2 * hv) - d.dv).norm() / (1 + d.dv.norm()),
            ((pu.du - mu.du) / (2 * hu) - d.duu).norm() / (1 + d.duu.norm()),
            ((pv.dv - mv.dv) / (2 * hv) - d.dvv).norm() / (1 + d.dvv.norm()),
            ((pv.du - mv.du) / (2 * hv) - d.duv).norm() / (1 + d.duv.norm())};
        return e;
      };
      const double hu = 1e-3 * (b.umax - b.umin), hv = 1e-3 * (b.vmax - b.vmin);
      const auto e1 = err(hu, hv), e2 = err(hu / 2, hv / 2);
      for (std::size_t k = 0; k < 5; ++k) {
        EXPECT_LT(e1[k], 1e-3) << "face " << f << " derivative " << k;
        if (e1[k] > 1e-9) {
          EXPECT_GT(e1[k] / std::max(e2[k], 1e-300), 3.0) << "face " << f;
        }
      }
    }
  }
  EXPECT_EQ(tested, 4);
}

// The recovery skips the projection on a face when these boxes put it too far away, so they
// must never cut through the surface: every point of the surface over the face's (u,v) box
// lies in a box (distance 0), and off the surface the bound is at most the distance that
// OCC's projection (GeomAPI_ProjectPointOnSurf over the same range) or the offset along the
// normal gives, and at least that minus one box diagonal.
TEST(OccFaceSurface, PatchBoxesBoundTheDistanceToTheSurfaceFromBelow) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int faces = 0;
  std::size_t offPoints = 0, positive = 0;
  for (const char* part : {"occt_propeller.brep", "occt_crankarm.brep", "occt_bottle.brep",
                           "occt_housing_bottom.brep", "nist_pmi_1.step", "nist_pmi_2.step"}) {
    auto shape = load(part);
    int tested = 0;
    for (int f = 0; f < shape->faceCount() && tested < 12; ++f) {
      const std::string type = shape->faceType(f);
      if (type == "Plane" || type == "Cylinder" || type == "Cone" || type == "Sphere" ||
          type == "Torus")
        continue;
      ++tested;
      const ParamBounds b = shape->surface(f).faceUVBounds();
      const Handle(Geom_Surface) g = BRep_Tool::Surface(shape->face(f));
      const GeomAdaptor_Surface ad(g);
      const std::vector<Box3> boxes = surfacePatchBoxes(ad, b, 16, 0.0);
      ASSERT_EQ(boxes.size(), 256u) << part << " face " << f;
      auto lower = [&](const Vec3& p) {
        double d = std::numeric_limits<double>::infinity();
        for (const Box3& x : boxes) d = std::min(d, boxDistance(x, p));
        return d;
      };
      double maxDiag = 0.0;
      Box3 all = boxes[0];
      for (const Box3& x : boxes) {
        maxDiag = std::max(maxDiag, Vec3(x[3] - x[0], x[4] - x[1], x[5] - x[2]).norm());
        for (std::size_t k = 0; k < 3; ++k) {
          all[k] = std::min(all[k], x[k]);
          all[k + 3] = std::max(all[k + 3], x[k + 3]);
        }
      }
      const double size = Vec3(all[3] - all[0], all[4] - all[1], all[5] - all[2]).norm();
      // On the surface, off the sampling lattice.
      int outside = 0;
      for (int i = 0; i < 41; ++i)
        for (int j = 0; j < 41; ++j) {
          const double u = b.umin + (b.umax - b.umin) * (i + 0.37) / 41.0;
          const double v = b.vmin + (b.vmax - b.vmin) * (j + 0.71) / 41.0;
          const gp_Pnt q = ad.Value(u, v);
          if (lower(Vec3(q.X(), q.Y(), q.Z())) > 0.0) ++outside;
        }
      EXPECT_EQ(outside, 0) << part << " face " << f << " (" << type << ")";
      // Off the surface.
      for (int k = 0; k < 40; ++k) {
        const double u = b.umin + (b.umax - b.umin) * unit(rng);
        const double v = b.vmin + (b.vmax - b.vmin) * unit(rng);
        gp_Pnt q;
        gp_Vec du, dv;
        ad.D1(u, v, q, du, dv);
        const gp_Vec n = du.Crossed(dv);
        if (n.Magnitude() < 1e-12 * du.Magnitude() * dv.Magnitude() || n.Magnitude() == 0.0)
          continue;
        const double t = (unit(rng) - 0.5) * 0.6 * size;
        const gp_Pnt P = q.Translated(n.Normalized() * t);
        double ref = std::abs(t);
        GeomAPI_ProjectPointOnSurf proj(P, g, b.umin, b.umax, b.vmin, b.vmax);
        if (proj.NbPoints() > 0) ref = std::min(ref, proj.LowerDistance());
        const double lb = lower(Vec3(P.X(), P.Y(), P.Z()));
        ++offPoints;
        if (lb > 0.0) ++positive;
        EXPECT_LE(lb, ref + 1e-12 * size) << part << " face " << f << " t " << t;
        EXPECT_GE(lb, ref - maxDiag - 1e-12 * size) << part << " face " << f << " t " << t;
      }
    }
    EXPECT_GT(tested, 0) << part;
    faces += tested;
  }
  EXPECT_GE(faces, 30);
  // Not a vacuous bound: most points a fair way off their face are put some way off it.
  EXPECT_GT(positive, offPoints / 2);
}

TEST(OccFaceSurface, NormalSignPointsOutOfTheSolid) {
  auto shape = load("occt_screw.step");
  const double diag = shape->diagonal();
  int reversed = 0, forward = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const OccFaceSurface& s = shape->surface(f);
    const bool rev = shape->face(f).Orientation() == TopAbs_REVERSED;
    EXPECT_EQ(s.normalSign(), rev ? -1 : 1);
    (rev ? reversed : forward)++;
    const std::vector<Vec2> uv = triangleCentroidsUV(shape->face(f), 1e-3 * diag);
    ASSERT_FALSE(uv.empty());
    const Vec2 q = uv[uv.size() / 2];
    const Vec3 p = s.value(q.x(), q.y()), n = s.normal(q.x(), q.y());
    const double eps = 1e-4 * diag;
    auto state = [&](const Vec3& x) {
      BRepClass3d_SolidClassifier c(shape->shape(), gp_Pnt(x.x(), x.y(), x.z()), 1e-9);
      return c.State();
    };
    EXPECT_EQ(state(p + eps * n), TopAbs_OUT) << "face " << f;
    EXPECT_EQ(state(p - eps * n), TopAbs_IN) << "face " << f;
  }
  EXPECT_GT(reversed, 0);
  EXPECT_GT(forward, 0);
}

TEST(OccFaceSurface, ContainsIsFalseInAHoleAndTrueInside) {
  auto shape = load("occt_housing_bottom.brep");
  int holes = 0;
  for (int f = 0; f < shape->faceCount() && holes < 5; ++f) {
    const TopoDS_Face& face = shape->face(f);
    const TopoDS_Wire outer = BRepTools::OuterWire(face);
    TopTools_IndexedMapOfShape wires;
    TopExp::MapShapes(face, TopAbs_WIRE, wires);
    if (wires.Extent() < 2) continue;
    const OccFaceSurface& s = shape->surface(f);
    if (s.isUPeriodic() || s.isVPeriodic()) continue;
    for (int w = 1; w <= wires.Extent(); ++w) {
      const TopoDS_Wire& wire = TopoDS::Wire(wires(w));
      if (wire.IsSame(outer)) continue;
      // The centre of an inner loop's (u,v) points: inside the hole for a convex hole.
      Vec2 c = Vec2::Zero();
      int k = 0;
      for (BRepTools_WireExplorer ex(wire, face); ex.More(); ex.Next()) {
        double a = 0, b = 0;
        const auto pc = BRep_Tool::CurveOnSurface(ex.Current(), face, a, b);
        for (int i = 0; i < 8; ++i) {
          const gp_Pnt2d q = pc->Value(a + (b - a) * i / 8.0);
          c += Vec2(q.X(), q.Y());
          ++k;
        }
      }
      c /= k;
      BRepClass_FaceClassifier ref(face, gp_Pnt2d(c.x(), c.y()), 1e-9);
      if (ref.State() != TopAbs_OUT) continue;  // not a convex hole
      EXPECT_FALSE(s.contains(c.x(), c.y())) << "face " << f << " hole centre " << c.transpose();
      ++holes;
    }
    for (const Vec2& q : interiorUV(face, 1e-3 * shape->diagonal()))
      EXPECT_TRUE(s.contains(q.x(), q.y())) << "face " << f << " at " << q.transpose();
  }
  EXPECT_GE(holes, 3);
}

// contains() answers from a grid of cells that no pcurve comes near; it must give the same
// answer as OCC's classifier asked directly, everywhere: on a lattice over each face's (u,v)
// box and at points scattered around its pcurves (just inside and just outside the loops).
TEST(OccFaceSurface, ContainsAgreesWithTheOccClassifierEverywhere) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (const char* part : {"occt_housing_bottom.brep", "occt_crankarm.brep", "nist_pmi_1.step"}) {
    auto shape = load(part);
    std::size_t checked = 0, inside = 0, mismatches = 0;
    for (int f = 0; f < shape->faceCount(); ++f) {
      const TopoDS_Face& face = shape->face(f);
      const OccFaceSurface s(face, f);  // a fresh copy: its grid is built here
      const bool recadre = s.uTurnPeriod() == 0.0 && s.vTurnPeriod() == 0.0;
      BRepTopAdaptor_FClass2d ref(face, s.uvTolerance());
      const ParamBounds b = s.faceUVBounds();
      const double W = b.umax - b.umin, H = b.vmax - b.vmin;
      std::vector<Vec2> pts;
      const int n = 23;  // not a divisor of the grid's 48 cells
      for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j)
          pts.emplace_back(b.umin - 0.01 * W + 1.02 * W * i / n,
                           b.vmin - 0.01 * H + 1.02 * H * j / n);
      for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
        double a = 0, c = 0;
        const auto pc = BRep_Tool::CurveOnSurface(TopoDS::Edge(ex.Current()), face, a, c);
        if (pc.IsNull()) continue;
        for (int k = 0; k < 16; ++k) {
          const gp_Pnt2d q = pc->Value(a + (c - a) * U(rng));
          // 0.3 … 3 cells of the 48-cell grid, or of its 16 × 16 sub-cells, away in a random
          // direction
          const double cell = k % 2 == 0 ? 1.0 / 48.0 : 1.0 / (48.0 * 16.0);
          const double r = (0.3 + 2.7 * U(rng)) * cell, t = 6.283185307179586 * U(rng);
          pts.emplace_back(q.X() + r * W * std::cos(t), q.Y() + r * H * std::sin(t));
        }
      }
      for (const Vec2& p : pts) {
        const Vec2 w = s.wrap(p);
        if (!s.isUPeriodic() &&
            (w.x() < b.umin - s.uvTolerance() || w.x() > b.umax + s.uvTolerance()))
          continue;  // outside the face's box: contains() answers without the classifier
        if (!s.isVPeriodic() &&
            (w.y() < b.vmin - s.uvTolerance() || w.y() > b.vmax + s.uvTolerance()))
          continue;
        const bool expected = containedByOcc(ref, s, p, recadre);
        const bool got = s.contains(p.x(), p.y());
        ++checked;
        inside += expected ? 1 : 0;
        if (got != expected) {
          ++mismatches;
          ADD_FAILURE() << part << " face " << f << " at " << p.transpose() << ": contains " << got
                        << ", classifier " << expected;
        }
      }
    }
    std::cout << part << ": " << checked << " points, " << inside << " inside, " << mismatches
              << " mismatches\n";
    EXPECT_GT(inside, checked / 5);
    EXPECT_LT(inside, checked);
  }
}

// The copies of a face share its classifier and grid: a copy made before the face's first
// query and the face itself both agree with a classifier built on its own, through the first
// queries (the classifier's) and past the one that builds the grid.
TEST(OccFaceSurface, TheCopiesShareTheClassifierAndTheGrid) {
  auto shape = load("occt_housing_bottom.brep");
  std::size_t checked = 0, faces = 0;
  for (int f = 0; f < shape->faceCount() && faces < 6; ++f) {
    const TopoDS_Face& face = shape->face(f);
    const OccFaceSurface s(face, f);
    if (s.uTurnPeriod() != 0.0 || s.vTurnPeriod() != 0.0) continue;
    ++faces;
    const std::unique_ptr<Surface> copy = s.clone();
    BRepTopAdaptor_FClass2d ref(face, s.uvTolerance());
    for (const Vec2& p : uvLattice(s.faceUVBounds(), 29)) {
      const bool expected = containedByOcc(ref, s, p);
      EXPECT_EQ(copy->contains(p.x(), p.y()), expected) << "face " << f << " at " << p.transpose();
      EXPECT_EQ(s.contains(p.x(), p.y()), expected) << "face " << f << " at " << p.transpose();
      ++checked;
    }
  }
  EXPECT_EQ(faces, 6u);
  EXPECT_GT(checked, 0u);
}

// containsFast() answers only what it knows without asking the classifier at the point (before
// a face's grid exists: nothing), and then agrees with OCC's classifier; containsWithinBand()
// is OCC's polygon test with its band. Checked on a lattice over every face of the housing.
TEST(OccFaceSurface, FastAndBandTestsAgreeWithTheClassifier) {
  auto shape = load("occt_housing_bottom.brep");
  std::size_t answered = 0, asked = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const OccFaceSurface s(shape->face(f), f);
    if (s.uTurnPeriod() != 0.0 || s.vTurnPeriod() != 0.0) continue;
    const ParamBounds b = s.faceUVBounds();
    EXPECT_EQ(s.containsFast(0.5 * (b.umin + b.umax), 0.5 * (b.vmin + b.vmax)), -1)
        << "face " << f << ": no grid before its first queries";
    s.prepare();
    BRepTopAdaptor_FClass2d ref(s.face(), s.uvTolerance());
    for (const Vec2& p : uvLattice(b, 23)) {
      const int fast = s.containsFast(p.x(), p.y());
      ++asked;
      if (fast >= 0) {
        ++answered;
        EXPECT_EQ(fast == 1, insideByOcc(ref, s, p)) << "face " << f << " at " << p.transpose();
      }
      const Vec2 w = s.wrap(p);
      const TopAbs_State band =
          ref.TestOnRestriction(gp_Pnt2d(w.x(), w.y()), s.uvTolerance(), Standard_True);
      EXPECT_EQ(s.containsWithinBand(p.x(), p.y()), band == TopAbs_IN || band == TopAbs_ON)
          << "face " << f << " at " << p.transpose();
    }
  }
  // Most lattice points lie away from the loops: the grids answer them.
  EXPECT_GT(answered, asked / 2);
}

// Next to the trimming loops (points off every boundary pcurve by 0.02 to 0.6 of a grid
// sub-cell, 1/768 of the face's parameter box, on both sides), containsFast() answers most
// points from the pieces of the grid cell (no classifier at the point) and agrees with OCC's
// classifier on every one it answers.
TEST(OccFaceSurface, FastTestNextToTheLoopsAgreesWithTheClassifier) {
  std::size_t answered = 0, asked = 0;
  for (const char* part : {"occt_housing_bottom.brep", "occt_propeller.brep", "occt_bottle.brep"}) {
    auto shape = load(part);
    for (int f = 0; f < shape->faceCount(); ++f) {
      const OccFaceSurface s(shape->face(f), f);
      if (s.uTurnPeriod() != 0.0 || s.vTurnPeriod() != 0.0) continue;
      s.prepare();
      const ParamBounds b = s.faceUVBounds();
      const double su = (b.umax - b.umin) / 768.0, sv = (b.vmax - b.vmin) / 768.0;
      BRepTopAdaptor_FClass2d ref(s.face(), s.uvTolerance());
      for (TopExp_Explorer ex(s.face(), TopAbs_EDGE); ex.More(); ex.Next()) {
        double t0 = 0.0, t1 = 0.0;
        const Handle(Geom2d_Curve) c =
            BRep_Tool::CurveOnSurface(TopoDS::Edge(ex.Current()), s.face(), t0, t1);
        if (c.IsNull()) continue;
        for (int k = 1; k < 12; ++k) {
          gp_Pnt2d q;
          gp_Vec2d d;
          c->D1(t0 + (t1 - t0) * k / 12.0, q, d);
          // the normal to the pcurve, measured in sub-cells
          Vec2 n(-d.Y() / sv, d.X() / su);
          if (!(n.norm() > 0.0)) continue;
          n /= n.norm();
          for (double off : {-0.6, -0.3, -0.1, -0.02, 0.02, 0.1, 0.3, 0.6}) {
            const Vec2 p(q.X() + off * n.x() * su, q.Y() + off * n.y() * sv);
            const int fast = s.containsFast(p.x(), p.y());
            ++asked;
            if (fast < 0) continue;
            ++answered;
            EXPECT_EQ(fast == 1, insideByOcc(ref, s, p))
                << part << " face " << f << " at " << p.transpose() << " (" << off << ")";
          }
        }
      }
    }
  }
  std::cout << answered << " of " << asked << " points next to the loops answered\n";
  EXPECT_GT(answered, asked / 2);
}

// In a periodic direction a face may cover part of the period (a torus's fillet): points
// outside its parameter box modulo the period are outside at once, those inside it are
// answered by its grid, whichever period they are given in. Checked against OCC's classifier on
// a lattice over two periods around every periodic face of three parts.
TEST(OccFaceSurface, FastTestOverTwoPeriodsAgreesWithTheClassifier) {
  std::size_t answered = 0, asked = 0, faces = 0;
  for (const char* part : {"occt_housing_bottom.brep", "occt_propeller.brep", "occt_screw.step"}) {
    auto shape = load(part);
    for (int f = 0; f < shape->faceCount(); ++f) {
      const OccFaceSurface s(shape->face(f), f);
      if (s.uTurnPeriod() != 0.0 || s.vTurnPeriod() != 0.0) continue;
      if (!s.isUPeriodic() && !s.isVPeriodic()) continue;
      ++faces;
      s.prepare();
      ParamBounds b = s.faceUVBounds();
      if (s.isUPeriodic()) {
        b.umin -= 0.5 * s.uPeriod();
        b.umax = b.umin + 2.0 * s.uPeriod();
      }
      if (s.isVPeriodic()) {
        b.vmin -= 0.5 * s.vPeriod();
        b.vmax = b.vmin + 2.0 * s.vPeriod();
      }
      BRepTopAdaptor_FClass2d ref(s.face(), s.uvTolerance());
      for (const Vec2& p : uvLattice(b, 31)) {
        const int fast = s.containsFast(p.x(), p.y());
        ++asked;
        if (fast < 0) continue;
        ++answered;
        EXPECT_EQ(fast == 1, insideByOcc(ref, s, p))
            << part << " face " << f << " at " << p.transpose();
      }
    }
  }
  std::cout << faces << " periodic faces: " << answered << " of " << asked << " answered\n";
  EXPECT_GT(faces, 10u);
  EXPECT_GT(answered, 9 * asked / 10);
}

// prepare() builds ahead, once for all copies, what contains() builds on first use: two
// threads preparing their own copies of every face at once (as the optimizer does over the
// faces), then contains() of a third copy agrees with OCC's classifier on a lattice.
TEST(OccFaceSurface, PreparedCopiesOnTwoThreadsAgreeWithTheClassifier) {
  auto shape = load("occt_housing_bottom.brep");
  std::vector<std::unique_ptr<OccFaceSurface>> faces;
  for (int f = 0; f < shape->faceCount(); ++f) {
    auto s = std::make_unique<OccFaceSurface>(shape->face(f), f);
    if (s->uTurnPeriod() == 0.0 && s->vTurnPeriod() == 0.0) faces.push_back(std::move(s));
  }
  ASSERT_GT(faces.size(), 10u);
  std::vector<std::unique_ptr<Surface>> copiesA, copiesB;
  for (const auto& s : faces) {
    copiesA.push_back(s->clone());
    copiesB.push_back(s->clone());
  }
  std::thread other([&] {
    for (const auto& c : copiesB) c->prepare();
  });
  for (const auto& c : copiesA) c->prepare();
  other.join();
  std::size_t checked = 0;
  for (const auto& s : faces) {
    const std::unique_ptr<Surface> third = s->clone();
    BRepTopAdaptor_FClass2d ref(s->face(), s->uvTolerance());
    for (const Vec2& p : uvLattice(s->faceUVBounds(), 17)) {
      EXPECT_EQ(third->contains(p.x(), p.y()), containedByOcc(ref, *s, p))
          << "face " << s->faceId() << " at " << p.transpose();
      ++checked;
    }
  }
  EXPECT_EQ(checked, faces.size() * 18u * 18u);
}

// The copies of a face share its classifier and grid; two threads asking contains() of their
// own copies at once, next to the trimming loops (where the classifier is asked), get the
// answers of OCC's classifier. Faces with several wires (holes) matter most: OCC's classifier
// walks its wires through sequences that cache the last item asked for (not thread-safe).
TEST(OccFaceSurface, CopiesOnTwoThreadsAgreeWithTheClassifierNextToHoles) {
  auto shape = load("occt_housing_bottom.brep");
  std::size_t faces = 0, checked = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const TopoDS_Face& face = shape->face(f);
    int wires = 0;
    for (TopExp_Explorer ex(face, TopAbs_WIRE); ex.More(); ex.Next()) ++wires;
    if (wires < 2) continue;
    ++faces;
    const OccFaceSurface original(face, f);
    const bool recadre = original.uTurnPeriod() == 0.0 && original.vTurnPeriod() == 0.0;
    const ParamBounds b = original.faceUVBounds();
    const double W = b.umax - b.umin, H = b.vmax - b.vmin;
    // Points within a sub-cell of the pcurves.
    std::mt19937 rng(static_cast<unsigned>(f) + 1);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<Vec2> pts;
    for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
      double a = 0, c = 0;
      const auto pc = BRep_Tool::CurveOnSurface(TopoDS::Edge(ex.Current()), face, a, c);
      if (pc.IsNull()) continue;
      for (int k = 0; k < 250; ++k) {
        const gp_Pnt2d q = pc->Value(a + (c - a) * U(rng));
        const double r = U(rng) / (48.0 * 16.0), t = 6.283185307179586 * U(rng);
        pts.emplace_back(q.X() + r * W * std::cos(t), q.Y() + r * H * std::sin(t));
      }
    }
    BRepTopAdaptor_FClass2d ref(face, original.uvTolerance());
    std::vector<char> expected(pts.size());
    for (std::size_t k = 0; k < pts.size(); ++k) {
      const Vec2 w = original.wrap(pts[k]);
      const bool inBox = (original.isUPeriodic() || (w.x() >= b.umin - original.uvTolerance() &&
                                                     w.x() <= b.umax + original.uvTolerance())) &&
                         (original.isVPeriodic() || (w.y() >= b.vmin - original.uvTolerance() &&
                                                     w.y() <= b.vmax + original.uvTolerance()));
      expected[k] = inBox && containedByOcc(ref, original, pts[k], recadre);
    }
    std::vector<char> got[2];
    std::vector<std::unique_ptr<Surface>> copies;
    for (int t = 0; t < 2; ++t) copies.push_back(original.clone());
    std::vector<std::thread> threads;
    for (int t = 0; t < 2; ++t)
      threads.emplace_back([&, t]() {
        got[t].resize(pts.size());
        for (int rep = 0; rep < 3; ++rep)
          for (std::size_t k = 0; k < pts.size(); ++k) {
            const std::size_t q = t == 0 ? k : pts.size() - 1 - k;
            got[t][q] = copies[static_cast<std::size_t>(t)]->contains(pts[q].x(), pts[q].y());
          }
      });
    for (auto& th : threads) th.join();
    for (int t = 0; t < 2; ++t)
      for (std::size_t k = 0; k < pts.size(); ++k)
        if (got[t][k] != expected[k])
          ADD_FAILURE() << "face " << f << " thread " << t << " at " << pts[k].transpose()
                        << ": contains " << int(got[t][k]) << ", classifier " << int(expected[k]);
    checked += pts.size();
  }
  std::cout << faces << " faces with holes, " << checked << " points\n";
  EXPECT_GE(faces, 3u);
}

// contains() is strict where OCC's tolerances would let a node off the face: a point within
// the classifier's tolerance band of a trimming loop (OCC says ON) is outside, and so is a
// point beyond the range of a B-spline face's surface (OCC's classifier, whose loop may run
// along that border, says ON or IN; the surface there is an extrapolation). Points of both
// kinds next to every pcurve of the crank arm, whose B-spline faces span their surfaces.
TEST(OccFaceSurface, ContainsExcludesTheToleranceBandAndTheSurfacesOutside) {
  auto shape = load("occt_crankarm.brep");
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::size_t onBand = 0, beyondRange = 0, inner = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const TopoDS_Face& face = shape->face(f);
    const OccFaceSurface& s = shape->surface(f);
    BRepTopAdaptor_FClass2d ref(face, s.uvTolerance());
    const Handle(Geom_Surface) g = BRep_Tool::Surface(face);
    double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
    g->Bounds(u0, u1, v0, v1);
    const double tol = s.uvTolerance();
    for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
      double a = 0, c = 0;
      const auto pc = BRep_Tool::CurveOnSurface(TopoDS::Edge(ex.Current()), face, a, c);
      if (pc.IsNull()) continue;
      for (int k = 0; k < 8; ++k) {
        gp_Pnt2d q;
        gp_Vec2d d;
        pc->D1(a + (c - a) * (0.05 + 0.9 * U(rng)), q, d);
        if (d.Magnitude() == 0.0) continue;
        const gp_Vec2d nrm(-d.Y() / d.Magnitude(), d.X() / d.Magnitude());
        for (const double side : {-1.0, 1.0}) {
          // Half the band away from the loop: ON for OCC, outside for contains().
          const Vec2 p(q.X() + side * 0.5 * tol * nrm.X(), q.Y() + side * 0.5 * tol * nrm.Y());
          if (ref.Perform(gp_Pnt2d(p.x(), p.y()), Standard_True) == TopAbs_ON) {
            EXPECT_FALSE(s.contains(p.x(), p.y())) << "face " << f << " ON at " << p.transpose();
            ++onBand;
          }
          // Beyond the surface's range in u or v, where OCC's classifier still lets it in.
          for (const Vec2 r : {Vec2(u0 - 0.5 * tol, q.Y()), Vec2(u1 + 0.5 * tol, q.Y()),
                               Vec2(q.X(), v0 - 0.5 * tol), Vec2(q.X(), v1 + 0.5 * tol)}) {
            if (s.isUPeriodic() || s.isVPeriodic() || g->IsUPeriodic() || g->IsVPeriodic()) break;
            if (std::abs(r.x() - q.X()) > tol && std::abs(r.y() - q.Y()) > tol) continue;
            const TopAbs_State st = ref.Perform(gp_Pnt2d(r.x(), r.y()), Standard_True);
            if (st != TopAbs_IN && st != TopAbs_ON) continue;
            EXPECT_FALSE(s.contains(r.x(), r.y()))
                << "face " << f << " beyond at " << r.transpose();
            ++beyondRange;
          }
          // Three bands inside the loop: IN for OCC and for contains().
          const Vec2 in(q.X() + side * 3.0 * tol * nrm.X(), q.Y() + side * 3.0 * tol * nrm.Y());
          if (in.x() >= u0 && in.x() <= u1 && in.y() >= v0 && in.y() <= v1 &&
              ref.Perform(gp_Pnt2d(in.x(), in.y()), Standard_True) == TopAbs_IN &&
              !s.inBoundaryTolerance(s.value(in.x(), in.y()))) {
            EXPECT_TRUE(s.contains(in.x(), in.y())) << "face " << f << " IN at " << in.transpose();
            ++inner;
          }
        }
      }
    }
  }
  std::cout << onBand << " points ON a loop, " << beyondRange << " beyond a surface's range, "
            << inner << " just inside\n";
  EXPECT_GT(onBand, 100u);
  EXPECT_GT(beyondRange, 20u);
  EXPECT_GT(inner, 100u);
}

// An edge's tolerance is a zone around its 3D curve where OCC counts a point ON the edge, and
// where the CAD recovery's tolerance hints (FreeCAD's getNodesByEdge rule) put a node on the
// edge; the same for a vertex. On imported parts it reaches 1e-3 and more (and the 3D curve
// lies that far from the loop its pcurve draws), far wider than the face's own tolerance that
// sets the classifier's band. contains() must reject the face's points in those zones: a node
// pushed there against the loop is read back as an edge node, measured to the edge's 3D
// curve. A box with one edge (and its two vertices) at tolerance 0.05: points of each face
// along that edge are outside at 0.025 from it and inside at 0.1; along the box's other edges
// (tolerance 1e-7) they are inside at 0.025.
TEST(OccFaceSurface, ContainsExcludesTheToleranceZonesOfTheFacesEdgesAndVertices) {
  const TopoDS_Shape box = BRepPrimAPI_MakeBox(10.0, 10.0, 10.0).Shape();
  TopTools_IndexedMapOfShape edges;
  TopExp::MapShapes(box, TopAbs_EDGE, edges);
  const TopoDS_Edge wide = TopoDS::Edge(edges(1));
  const double tol = 0.05;
  BRep_Builder builder;
  builder.UpdateEdge(wide, tol);
  for (TopExp_Explorer ex(wide, TopAbs_VERTEX); ex.More(); ex.Next())
    builder.UpdateVertex(TopoDS::Vertex(ex.Current()), tol);
  const CadShape shape(box);
  std::size_t zone = 0, free = 0, corners = 0;
  for (int f = 0; f < shape.faceCount(); ++f) {
    const TopoDS_Face& face = shape.face(f);
    const OccFaceSurface& s = shape.surface(f);
    BRepTopAdaptor_FClass2d ref(face, s.uvTolerance());
    for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
      const TopoDS_Edge& e = TopoDS::Edge(ex.Current());
      const bool isWide = e.IsSame(wide);
      double a = 0, c = 0;
      const auto pc = BRep_Tool::CurveOnSurface(e, face, a, c);
      ASSERT_FALSE(pc.IsNull());
      for (const double t : {0.3, 0.5, 0.7}) {
        gp_Pnt2d q;
        gp_Vec2d d;
        pc->D1(a + (c - a) * t, q, d);
        // The plane's (u,v) are lengths: the inward normal of the loop, at unit speed.
        gp_Vec2d nrm(-d.Y(), d.X());
        nrm.Normalize();
        const gp_Pnt2d probe(q.X() + 2.0 * tol * nrm.X(), q.Y() + 2.0 * tol * nrm.Y());
        if (ref.Perform(probe) != TopAbs_IN) nrm.Reverse();
        auto at = [&](double dist) { return Vec2(q.X() + dist * nrm.X(), q.Y() + dist * nrm.Y()); };
        ASSERT_EQ(ref.Perform(gp_Pnt2d(at(0.5 * tol).x(), at(0.5 * tol).y())), TopAbs_IN);
        const Vec2 near = at(0.5 * tol), far = at(2.0 * tol);
        EXPECT_TRUE(s.contains(far.x(), far.y())) << "face " << f << " at " << far.transpose();
        if (isWide) {
          EXPECT_FALSE(s.contains(near.x(), near.y()))
              << "face " << f << " at " << near.transpose() << ", 0.025 from the wide edge";
          EXPECT_TRUE(s.inBoundaryTolerance(s.value(near.x(), near.y())));
          ++zone;
        } else {
          EXPECT_TRUE(s.contains(near.x(), near.y()))
              << "face " << f << " at " << near.transpose() << ", 0.025 from a tight edge";
          ++free;
        }
      }
      // Next to the wide edge's vertices, off the wide edge itself: in the vertex's ball.
      if (isWide) continue;
      for (TopExp_Explorer vx(e, TopAbs_VERTEX); vx.More(); vx.Next()) {
        const TopoDS_Vertex& v = TopoDS::Vertex(vx.Current());
        if (BRep_Tool::Tolerance(v) < tol) continue;
        const gp_Pnt2d q = BRep_Tool::Parameters(v, face);
        const Vec2 c2(0.5 * (s.faceUVBounds().umin + s.faceUVBounds().umax),
                      0.5 * (s.faceUVBounds().vmin + s.faceUVBounds().vmax));
        const Vec2 in = Vec2(q.X(), q.Y()) + 0.6 * tol * (c2 - Vec2(q.X(), q.Y())).normalized();
        EXPECT_FALSE(s.contains(in.x(), in.y())) << "face " << f << " at " << in.transpose();
        ++corners;
      }
    }
  }
  EXPECT_EQ(zone, 2u * 3u);  // the wide edge bounds two faces
  EXPECT_EQ(free, (4u * 6u - 2u) * 3u);
  EXPECT_GT(corners, 0u);
}

TEST(OccFaceSurface, PeriodicFacesWrapAroundTheirOwnRange) {
  auto shape = load("occt_crankarm.brep");
  int periodic = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const OccFaceSurface& s = shape->surface(f);
    if (!s.isUPeriodic()) continue;
    ++periodic;
    const ParamBounds b = s.bounds(), fb = s.faceUVBounds();
    EXPECT_NEAR(b.umax - b.umin, s.uPeriod(), 1e-12);
    EXPECT_LE(b.umin, fb.umin + 1e-9);
    EXPECT_GE(b.umax, fb.umax - 1e-9);
    for (const Vec2& q : interiorUV(shape->face(f), 1e-3 * shape->diagonal())) {
      EXPECT_TRUE(s.contains(q.x() + s.uPeriod(), q.y()));
      EXPECT_LE((s.value(q.x() + s.uPeriod(), q.y()) - s.value(q.x(), q.y())).norm(),
                1e-9 * shape->diagonal());
    }
  }
  EXPECT_GT(periodic, 0);
}

TEST(OccEdgeCurve, DerivativesAndPcurvesAgreeWithTheEdge) {
  auto shape = load("occt_bottle.brep");
  const double diag = shape->diagonal();
  int seams = 0;
  for (int e = 0; e < shape->edgeCount(); ++e) {
    const OccEdgeCurve& c = shape->curve(e);
    if (c.isDegenerated()) continue;
    const double t0 = c.tmin(), t1 = c.tmax(), h = 1e-4 * (t1 - t0);
    const double tol = BRep_Tool::Tolerance(shape->edge(e));
    for (double a : {0.25, 0.5, 0.75}) {
      const double t = t0 + a * (t1 - t0);
      const CurveD2 d = c.d2(t);
      const Vec3 fd1 = (c.value(t + h) - c.value(t - h)) / (2 * h);
      const Vec3 fd2 = (c.d2(t + h).dt - c.d2(t - h).dt) / (2 * h);
      EXPECT_LE((fd1 - d.dt).norm(), 1e-5 * (1 + d.dt.norm())) << "edge " << e;
      if (c.adaptor().Continuity() >= GeomAbs_C2) {  // C'' jumps at the knots of C1 splines
        EXPECT_LE((fd2 - d.dtt).norm(), 1e-4 * (1 + d.dtt.norm())) << "edge " << e;
      }
      for (int k = 0; k < c.faceCount(); ++k) {
        const int f = c.faceId(k);
        const OccFaceSurface& s = shape->surface(f);
        const Vec2 uv = c.uvOnFace(f, t, Vec2(s.bounds().umin, s.bounds().vmin));
        EXPECT_LE((s.value(uv.x(), uv.y()) - d.p).norm(), 2 * tol + 1e-7 * diag)
            << "edge " << e << " face " << f;
        if (c.isSeamOf(f)) {
          // The two pcurves of a seam: `near` picks the closer one, a period apart.
          const Vec2 a1 = c.uvOnFace(f, t, Vec2(s.bounds().umin, uv.y()));
          const Vec2 a2 = c.uvOnFace(f, t, Vec2(s.bounds().umax, uv.y()));
          if (s.isUPeriodic()) {
            EXPECT_NEAR(std::abs(a2.x() - a1.x()), s.uPeriod(), 1e-9);
          }
          ++seams;
        }
      }
    }
  }
  EXPECT_GT(seams, 0);
  EXPECT_THROW(shape->curve(0).uvOnFace(-5, 0.0, Vec2::Zero()), std::invalid_argument);
}

TEST(OccEdgeCurve, ClosedCircularEdgesArePeriodic) {
  auto shape = load("occt_crankarm.brep");
  int closed = 0;
  for (int e = 0; e < shape->edgeCount(); ++e) {
    const OccEdgeCurve& c = shape->curve(e);
    if (!c.isPeriodic()) continue;
    ++closed;
    EXPECT_NEAR(c.tmax() - c.tmin(), c.period(), 1e-9);
    EXPECT_LE((c.value(c.tmin()) - c.value(c.tmax())).norm(), 1e-7 * shape->diagonal());
    EXPECT_EQ(shape->edgeVertices(e).size(), 1u);
  }
  EXPECT_GT(closed, 0);
}

TEST(CadShape, IdsFollowTopExpMapShapesAndAdjacencyIsConsistent) {
  auto shape = load("occt_propeller.brep");
  EXPECT_EQ(shape->faceCount(), 76);
  EXPECT_EQ(shape->edgeCount(), 170);
  EXPECT_NEAR(shape->diagonal(), 1359, 30);
  TopTools_IndexedMapOfShape faces;
  TopExp::MapShapes(shape->shape(), TopAbs_FACE, faces);
  for (int f = 0; f < shape->faceCount(); ++f) {
    EXPECT_TRUE(shape->face(f).IsSame(faces(f + 1)));
    EXPECT_EQ(shape->faceId(faces(f + 1)), f);
    for (int e : shape->faceEdges(f)) {
      const auto& ef = shape->edgeFaces(e);
      EXPECT_TRUE(std::binary_search(ef.begin(), ef.end(), f));
    }
  }
  EXPECT_THROW(shape->face(76), std::out_of_range);
  EXPECT_NE(shape->describe().find("BSplineSurface"), std::string::npos);
}

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(CadShape, ReadErrorsSayWhatAndWhere) {
  const std::string dir = SURFMESH_TEST_DATA_DIR;
  EXPECT_NE(errorOf([&] { CadShape::fromFile(dir + "/missing.step"); }).find("missing.step"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { CadShape::fromFile(dir + "/README.md"); }).find("unknown extension"),
            std::string::npos);
  EXPECT_NE(errorOf([] { CadShape::fromBrepString(""); }).find("empty"), std::string::npos);
  EXPECT_NE(errorOf([] { CadShape::fromBrepString("not a brep"); }).find("BREP"),
            std::string::npos);
  std::ostringstream vertexOnly;
  BRepTools::Write(BRepBuilderAPI_MakeVertex(gp_Pnt(1, 2, 3)).Vertex(), vertexOnly);
  EXPECT_NE(errorOf([&] { CadShape::fromBrepString(vertexOnly.str()); }).find("no faces"),
            std::string::npos);
  // A BREP string round trip gives the same shape.
  auto screw = load("occt_screw.step");
  std::ostringstream brep;
  BRepTools::Write(screw->shape(), brep);
  auto again = CadShape::fromBrepString(brep.str());
  EXPECT_EQ(again->faceCount(), screw->faceCount());
  EXPECT_NEAR(again->diagonal(), screw->diagonal(), 1e-9 * screw->diagonal());
}

}  // namespace

// A trimming curve off its 3D edge (nist_pmi_2, a STEP file of another CAD system: gaps up to
// 0.016 at edges of tolerance 1e-7): between the curve's image and the 3D edge lies a strip
// that the 2D boundary counts in and the 3D boundary out. contains() and containsNearBoundary()
// (every move of the optimizer, the untangling's too) refuse the points of that strip. The
// side of the 3D edge is judged here on its own: the nearest point Q of the 3D curve, the
// curve's tangent there taken to (u,v), and on which side of it an independent classifier puts
// points 20 gaps away. Points of the face far from such edges keep their answer.
TEST(OccFaceSurface, ContainsRefusesTheStripBetweenATrimmingCurveAndItsThreeDEdge) {
  auto shape = load("nist_pmi_2.step");
  const double diag = shape->diagonal();
  std::size_t pairs = 0, strip = 0, refused = 0, farChecked = 0, farKept = 0, nearIn = 0,
              nearKept = 0;
  for (int f = 0; f < shape->faceCount(); ++f) {
    const TopoDS_Face& face = shape->face(f);
    const OccFaceSurface& s = shape->surface(f);
    std::vector<std::pair<TopoDS_Edge, double>> gaps;
    for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
      const TopoDS_Edge& e = TopoDS::Edge(ex.Current());
      if (BRep_Tool::Degenerated(e) || BRep_Tool::IsClosed(e, face)) continue;
      const double gap = trimCurveGap(e, face, kTrimGapSamples);
      if (isTrimGap(gap, BRep_Tool::Tolerance(e), diag)) gaps.emplace_back(e, gap);
    }
    EXPECT_EQ(s.hasTrimGaps(), !gaps.empty()) << "face " << f;
    if (gaps.empty()) continue;
    const Handle(Geom_Surface) gs = BRep_Tool::Surface(face);
    BRepTopAdaptor_FClass2d ref(face, s.uvTolerance());
    for (const auto& [e, gap] : gaps) {
      ++pairs;
      double a = 0.0, b = 0.0, c0 = 0.0, c1 = 0.0;
      const Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(e, face, a, b);
      const Handle(Geom_Curve) c3 = BRep_Tool::Curve(e, c0, c1);
      ASSERT_FALSE(pc.IsNull() || c3.IsNull());
      for (int i = 0; i < 101; ++i) {
        const gp_Pnt2d uvX = pc->Value(a + (b - a) * (i + 0.5) / 101);
        const gp_Pnt X = gs->Value(uvX.X(), uvX.Y());
        GeomAPI_ProjectPointOnCurve onCurve(X, c3, c0, c1);
        if (onCurve.NbPoints() == 0) continue;
        const gp_Pnt Q = onCurve.NearestPoint();
        const double tq = onCurve.LowerDistanceParameter();
        // the strip's middle there, on the surface
        GeomAPI_ProjectPointOnSurf toM(gp_Pnt((X.XYZ() + Q.XYZ()) / 2.0), gs);
        GeomAPI_ProjectPointOnSurf toQ(Q, gs);
        if (toM.NbPoints() == 0 || toQ.NbPoints() == 0) continue;
        double um = 0, vm = 0, uq = 0, vq = 0;
        toM.LowerDistanceParameters(um, vm);
        toQ.LowerDistanceParameters(uq, vq);
        const gp_Pnt M = gs->Value(um, vm);
        // which side of the 3D edge is inside, by the classifier 20 gaps away from Q
        gp_Pnt p0;
        gp_Vec du, dv, T;
        gs->D1(uq, vq, p0, du, dv);
        c3->D1(tq, p0, T);
        const double E = du.Dot(du), F = du.Dot(dv), G = dv.Dot(dv);
        const double det = E * G - F * F;
        if (!(det > 0.0)) continue;
        const double tu = (G * T.Dot(du) - F * T.Dot(dv)) / det;
        const double tv = (E * T.Dot(dv) - F * T.Dot(du)) / det;
        gp_Vec2d n(-tv, tu);  // across the curve in (u,v)
        const double len3 = (du * n.X() + dv * n.Y()).Magnitude();
        if (!(len3 > 0.0)) continue;
        n /= len3;  // a unit length on the surface
        const double reach = 20.0 * gap;
        const bool plusIn =
            ref.Perform(gp_Pnt2d(uq + reach * n.X(), vq + reach * n.Y())) == TopAbs_IN;
        const bool minusIn =
            ref.Perform(gp_Pnt2d(uq - reach * n.X(), vq - reach * n.Y())) == TopAbs_IN;
        if (plusIn == minusIn) continue;  // near a corner: no side to tell
        const double side = (um - uq) * n.X() + (vm - vq) * n.Y();
        const bool outside3D =
            (plusIn ? side < 0.0 : side > 0.0) && M.Distance(Q) > 2.0 * BRep_Tool::Tolerance(e);
        const bool inside2D = ref.Perform(gp_Pnt2d(um, vm)) == TopAbs_IN;
        // The point as far from the 3D edge on its inner side, inside both boundaries: kept
        // (the strip is on the outer side only; the nodes may come as near the 3D edge as the
        // 2D boundary lets them).
        const double inner = std::max(M.Distance(Q), 1e-4 * gap);
        const double ui = uq + (plusIn ? 1.0 : -1.0) * inner * n.X();
        const double vi = vq + (plusIn ? 1.0 : -1.0) * inner * n.Y();
        if (ref.Perform(gp_Pnt2d(ui, vi)) == TopAbs_IN) {
          ++nearIn;
          const bool kept = !s.inTrimStrip(ui, vi);
          EXPECT_TRUE(kept) << "face " << f << " inner point at " << ui << ", " << vi;
          nearKept += kept ? 1 : 0;
        }
        if (!(outside3D && inside2D)) continue;
        ++strip;
        const bool near = s.containsNearBoundary(um, vm), in = s.contains(um, vm);
        EXPECT_TRUE(s.inTrimStrip(um, vm)) << "face " << f << " at " << um << ", " << vm;
        EXPECT_FALSE(near) << "face " << f << " at " << um << ", " << vm;
        EXPECT_FALSE(in) << "face " << f << " at " << um << ", " << vm;
        refused += !near && !in ? 1 : 0;
      }
    }
    // Interior points of the face's own triangulation far from its trimming curves' edges:
    // the same answer as the classifier's (they are inside).
    for (const Vec2& uv : interiorUV(face, 5e-5 * diag)) {
      const gp_Pnt P = gs->Value(uv.x(), uv.y());
      bool far = true;
      for (const auto& [e, gap] : gaps) {
        double c0 = 0.0, c1 = 0.0;
        GeomAPI_ProjectPointOnCurve pr(P, BRep_Tool::Curve(e, c0, c1), c0, c1);
        if (pr.NbPoints() > 0 && pr.LowerDistance() < 20.0 * gap) far = false;
      }
      if (!far || !strictlyInsideByOcc(ref, s, uv)) continue;
      ++farChecked;
      farKept += s.containsNearBoundary(uv.x(), uv.y()) && !s.inTrimStrip(uv.x(), uv.y());
    }
  }
  std::cout << "nist_pmi_2: " << pairs << " trimming curves off their edges; " << strip
            << " points of their strips inside the 2D boundary and outside the 3D one, " << refused
            << " refused; " << nearKept << " of " << nearIn
            << " points as near on the inner side kept; " << farKept << " of " << farChecked
            << " interior points far from them kept\n";
  EXPECT_GE(pairs, 14u);
  EXPECT_GT(strip, 50u);  // the check is not vacuous
  EXPECT_EQ(refused, strip);
  EXPECT_GT(nearIn, 100u);
  EXPECT_EQ(nearKept, nearIn);
  EXPECT_GT(farChecked, 100u);
  EXPECT_EQ(farKept, farChecked);
  // The OCC parts have no such curves: their faces behave as before (no strip to test).
  for (const char* part : {"occt_propeller.brep", "occt_screw.step", "occt_bottle.brep"}) {
    auto occ = load(part);
    for (int f = 0; f < occ->faceCount(); ++f)
      EXPECT_FALSE(occ->surface(f).hasTrimGaps()) << part << " face " << f;
  }
}
