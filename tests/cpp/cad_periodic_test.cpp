// SurfMesh — periodic faces whatever their parameter range: a torus with v in [-π, π] or
// [π, 3π], seams of spheres, cylinders and cones moved to -π or π. The shape's boxes must hold
// the surface (OCC's own bounding of some of these is flat), and the CAD bridge must put every
// node of a BRepMesh triangulation on its face.
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/cad/occ_mesher.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/quality.h"

#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRepPrimAPI_MakeTorus.hxx>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <GeomLProp_SLProps.hxx>
#include <Geom_ConicalSurface.hxx>
#include <Geom_CylindricalSurface.hxx>
#include <Geom_SphericalSurface.hxx>
#include <Geom_ToroidalSurface.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <gp_Ax2.hxx>
#include <gp_Ax3.hxx>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace surfmesh;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct PeriodicCase {
  std::string name;
  TopoDS_Face face;
  Handle(Geom_Surface) surface;  // with the face's location
  double u0, u1, v0, v1;         // the face's (u,v) box
};

PeriodicCase madeFace(const std::string& name, const Handle(Geom_Surface) & s, double u0, double u1,
                      double v0, double v1) {
  BRepBuilderAPI_MakeFace mk(s, u0, u1, v0, v1, 1e-7);
  EXPECT_TRUE(mk.IsDone()) << name;
  return {name, mk.Face(), s, u0, u1, v0, v1};
}

/// The first face of a primitive, as FreeCAD's Part.makeTorus / makeSphere build them.
PeriodicCase primitiveFace(const std::string& name, const TopoDS_Shape& shape) {
  TopExp_Explorer ex(shape, TopAbs_FACE);
  const TopoDS_Face face = TopoDS::Face(ex.Current());
  PeriodicCase c{name, face, BRep_Tool::Surface(face), 0, 0, 0, 0};
  BRepTools::UVBounds(face, c.u0, c.u1, c.v0, c.v1);
  return c;
}

std::vector<PeriodicCase> cases() {
  const gp_Ax3 ax;  // origin, z axis
  Handle(Geom_Surface) torus = new Geom_ToroidalSurface(ax, 10.0, 4.0);
  Handle(Geom_Surface) sphere = new Geom_SphericalSurface(ax, 5.0);
  Handle(Geom_Surface) cylinder = new Geom_CylindricalSurface(ax, 3.0);
  Handle(Geom_Surface) cone = new Geom_ConicalSurface(ax, 0.3, 2.0);
  const gp_Ax2 ax2;
  return {
      madeFace("torus_v_0_2pi", torus, 0.0, 2 * kPi, 0.0, 2 * kPi),
      madeFace("torus_v_mpi_pi", torus, 0.0, 2 * kPi, -kPi, kPi),
      madeFace("torus_v_pi_3pi", torus, 0.0, 2 * kPi, kPi, 3 * kPi),
      madeFace("torus_u_mpi_pi_v_mhalfpi", torus, -kPi, kPi, -0.5 * kPi, 1.5 * kPi),
      madeFace("sphere_u_mpi_pi", sphere, -kPi, kPi, -0.5 * kPi, 0.5 * kPi),
      madeFace("cylinder_u_mpi_pi", cylinder, -kPi, kPi, 0.0, 10.0),
      madeFace("cone_u_pi_3pi", cone, kPi, 3 * kPi, 0.0, 6.0),
      // Part.makeTorus(10, 4, p, d, -180, 180) and (-90, 270): OCC's own bounding of these
      // faces is flat (OCCT 7.6)
      primitiveFace("makeTorus_mpi_pi", BRepPrimAPI_MakeTorus(ax2, 10.0, 4.0, -kPi, kPi).Shape()),
      primitiveFace("makeTorus_mhalfpi_3halfpi",
                    BRepPrimAPI_MakeTorus(ax2, 10.0, 4.0, -0.5 * kPi, 1.5 * kPi).Shape()),
      primitiveFace("makeSphere", BRepPrimAPI_MakeSphere(ax2, 5.0).Shape()),
      primitiveFace("makeCylinder", BRepPrimAPI_MakeCylinder(ax2, 3.0, 10.0).Shape()),
  };
}

std::shared_ptr<CadShape> makeShape(const PeriodicCase& c) {
  return std::make_shared<CadShape>(c.face);
}

}  // namespace

TEST(CadPeriodic, FaceAndShapeBoxesHoldTheWholeSurface) {
  for (const PeriodicCase& c : cases()) {
    auto shape = makeShape(c);
    const Bnd_Box& fb = shape->faceBox(0);
    const Bnd_Box& sb = shape->boundingBox();
    double xmin = 1e300, xmax = -1e300, zmin = 1e300, zmax = -1e300;
    const int n = 48;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) {
        const gp_Pnt p =
            c.surface->Value(c.u0 + (c.u1 - c.u0) * i / n, c.v0 + (c.v1 - c.v0) * j / n);
        EXPECT_FALSE(fb.IsOut(p)) << c.name << " face box misses (" << p.X() << ", " << p.Y()
                                  << ", " << p.Z() << ")";
        EXPECT_FALSE(sb.IsOut(p)) << c.name;
        xmin = std::min(xmin, p.X()), xmax = std::max(xmax, p.X());
        zmin = std::min(zmin, p.Z()), zmax = std::max(zmax, p.Z());
      }
    // The diagonal (the scale of every tolerance) is the surface's, not a sliver's.
    EXPECT_GE(shape->diagonal(), std::hypot(xmax - xmin, zmax - zmin)) << c.name;
  }
}

TEST(CadPeriodic, BridgePutsEveryNodeOfATriangulationOnItsFace) {
  std::size_t onFace = 0;  // BRepMesh puts none inside the cylinder: count over all cases
  for (const PeriodicCase& c : cases()) {
    auto shape = makeShape(c);
    OccMesh om = meshWithBRepMesh(*shape, 0.002 * shape->diagonal(), 0.3);
    ASSERT_GT(om.input.nodes.size(), 50u) << c.name;
    // A face made from a closed surface over a shifted range can have two vertices at the
    // seams' crossing: their nodes are one point of the surface, merged here.
    for (std::int32_t& n : om.input.conn)
      for (std::int32_t k = 0; k < n; ++k)
        if ((om.input.nodes[static_cast<std::size_t>(k)].array() ==
             om.input.nodes[static_cast<std::size_t>(n)].array())
                .all()) {
          n = k;
          break;
        }
    std::unique_ptr<CadMesh> cm;
    try {
      cm = std::make_unique<CadMesh>(shape, om.input);
    } catch (const std::exception& e) {
      ADD_FAILURE() << c.name << ": " << e.what();
      continue;
    }
    EXPECT_LE(cm->report().maxDistance, 1e-9 * shape->diagonal()) << c.name;
    // Every node's (u,v) maps back onto the node, inside the face's range modulo its periods.
    const SurfaceMesh& m = cm->mesh();
    for (std::size_t k = 0; k < m.nodeCount(); ++k) {
      if (m.nodeFace[k] < 0) continue;
      ++onFace;
      const Vec3 x =
          m.surfaces[static_cast<std::size_t>(m.nodeFace[k])]->value(m.uv[k].x(), m.uv[k].y());
      EXPECT_LE((x - om.input.nodes[k]).norm(), 1e-9 * shape->diagonal())
          << c.name << " node " << k;
    }
    EXPECT_EQ(measureQuality(m, measureByName("shape")).stats.tangled, 0u) << c.name;
  }
  EXPECT_GT(onFace, 1000u);
}

namespace {

/// OCC's own outward normal of `face` at the foot of p on its surface (GeomLProp's limit
/// normal where a derivative vanishes), independent of SurfMesh's recovery.
Vec3 occNormalAt(const TopoDS_Face& face, const Vec3& p) {
  const Handle(Geom_Surface) s = BRep_Tool::Surface(face);
  GeomAPI_ProjectPointOnSurf proj(gp_Pnt(p.x(), p.y(), p.z()), s);
  EXPECT_GT(proj.NbPoints(), 0);
  double u = 0.0, v = 0.0;
  proj.LowerDistanceParameters(u, v);
  GeomLProp_SLProps props(s, u, v, 1, 1e-9);
  EXPECT_TRUE(props.IsNormalDefined());
  const gp_Dir n = props.Normal();
  const double o = face.Orientation() == TopAbs_REVERSED ? -1.0 : 1.0;
  return o * Vec3(n.X(), n.Y(), n.Z());
}

}  // namespace

TEST(CadPeriodic, ConeApexOffTheSingularityLeavesValidElementsValid) {
  // A cone whose apex (surface parameter v = 0) is not where its face's degenerated edge lies:
  // Gmsh's crank shaft has one at v = −6.2e−11, where φ_u is not zero and φ_u × φ_v points
  // the other way (the other nappe). Every element at the apex took that normal at its
  // apex corner and was reported standing across, though valid (3 of the crank shaft's, at
  // orders 1 to 3). Here: BRepMesh's valid triangulation, and the same with side nodes on the
  // surface (tria6), judged by OCC's normals away from the apex; the report must agree: 0.
  const gp_Ax3 ax;
  Handle(Geom_Surface) cone = new Geom_ConicalSurface(ax, 0.4, 0.0);  // apex at v = 0
  for (double v0 : {0.0, -6e-11, -1e-9, 2e-9}) {
    const PeriodicCase c = madeFace("cone_apex", cone, 0.0, 2 * kPi, v0, 6.0);
    auto shape = makeShape(c);
    OccMesh om = meshWithBRepMesh(*shape, 0.01 * shape->diagonal(), 0.3);
    ASSERT_GT(om.input.types.size(), 50u);
    // tria6: each side's node at the surface's point nearest the side's midpoint.
    MeshInput quad = om.input;
    quad.conn.clear();
    std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> sideNode;
    for (std::size_t e = 0; e < om.input.types.size(); ++e) {
      const std::int32_t* t = om.input.conn.data() + 3 * e;
      std::int32_t mid[3];
      for (int k = 0; k < 3; ++k) {
        const std::int32_t a = t[k], b = t[(k + 1) % 3];
        auto key = std::minmax(a, b);
        auto it = sideNode.find(key);
        if (it == sideNode.end()) {
          const Vec3 m = 0.5 * (om.input.nodes[static_cast<std::size_t>(a)] +
                                om.input.nodes[static_cast<std::size_t>(b)]);
          GeomAPI_ProjectPointOnSurf proj(gp_Pnt(m.x(), m.y(), m.z()), cone);
          const gp_Pnt f = proj.NearestPoint();
          quad.nodes.push_back(Vec3(f.X(), f.Y(), f.Z()));
          it = sideNode.emplace(key, static_cast<std::int32_t>(quad.nodes.size() - 1)).first;
        }
        mid[k] = it->second;
      }
      quad.types[e] = ElementType::Tri6;
      quad.conn.insert(quad.conn.end(), {t[0], t[1], t[2], mid[0], mid[1], mid[2]});
    }
    for (const MeshInput* in : {&om.input, &quad}) {
      const bool curved = in == &quad;
      std::ostringstream what;
      what << (curved ? "tria6" : "tri3") << ", degenerated edge at v = " << v0;
      // The independent judge: x_ξ × x_η against OCC's normal, at interior points only (the
      // apex has no normal of its own).
      std::size_t judgedInvalid = 0;
      const int n = 6;
      for (std::size_t e = 0; e < in->types.size(); ++e) {
        const std::int32_t* t = in->conn.data() + (curved ? 6 : 3) * e;
        auto X = [&](int k) { return in->nodes[static_cast<std::size_t>(t[k])]; };
        bool bad = false;
        for (int i = 1; i < n && !bad; ++i)
          for (int j = 1; i + j < n && !bad; ++j) {
            const double xi = double(i) / n, eta = double(j) / n, l = 1.0 - xi - eta;
            Vec3 a = X(1) - X(0), b = X(2) - X(0), x = l * X(0) + xi * X(1) + eta * X(2);
            if (curved) {  // P2 shape functions, Gmsh's node order
              a = (4 * xi - 1) * X(1) - (4 * l - 1) * X(0) + 4 * (l - xi) * X(3) + 4 * eta * X(4) -
                  4 * eta * X(5);
              b = (4 * eta - 1) * X(2) - (4 * l - 1) * X(0) - 4 * xi * X(3) + 4 * xi * X(4) +
                  4 * (l - eta) * X(5);
              x = l * (2 * l - 1) * X(0) + xi * (2 * xi - 1) * X(1) + eta * (2 * eta - 1) * X(2) +
                  4 * l * xi * X(3) + 4 * xi * eta * X(4) + 4 * eta * l * X(5);
            }
            bad = a.cross(b).dot(occNormalAt(c.face, x)) <= 0.0;
          }
        judgedInvalid += bad;
      }
      EXPECT_EQ(judgedInvalid, 0u) << what.str() << ": the test's mesh is not valid";
      CadMesh cm(shape, *in);
      const MeshQuality q = measureQuality(cm.mesh(), measureByName("shape"));
      EXPECT_EQ(q.stats.tangled, 0u) << what.str();
      EXPECT_EQ(q.stats.across, judgedInvalid) << what.str();
    }
  }
}

namespace {

/// A cone's apex at v = 0, a node on the axis 5e-6 beyond it (its nearest point on the face:
/// the apex), a ring of 8 nodes 2e-5 down the cone and the face's circle at v = 6; the first
/// `leftOut` of the fan triangles at the node are left out (the node borders their hole).
/// The node must be the apex's pole, held where it is, and the elements measure valid.
void expectApexNodeIsThePole(int leftOut) {
  const gp_Ax3 ax;
  Handle(Geom_Surface) cone = new Geom_ConicalSurface(ax, 0.4, 0.0);  // apex at v = 0
  const PeriodicCase c = madeFace("cone_apex_node", cone, 0.0, 2 * kPi, 0.0, 6.0);
  auto shape = makeShape(c);
  MeshInput in;
  auto at = [&](double u, double v) {
    const gp_Pnt p = cone->Value(u, v);
    return Vec3(p.X(), p.Y(), p.Z());
  };
  const Vec3 apex = at(0.0, 0.0);
  const Vec3 axis = (at(0.0, 1.0) + at(kPi, 1.0)) / 2.0 - apex;
  in.nodes.push_back(apex - 5e-6 * axis.normalized());  // beyond the apex, on the axis
  constexpr int k = 8;
  for (int i = 0; i < k; ++i) in.nodes.push_back(at(2 * kPi * i / k, 2e-5));
  for (int i = 0; i < k; ++i) in.nodes.push_back(at(2 * kPi * i / k, 6.0));
  for (int i = 0; i < k; ++i) {
    const std::int32_t a = 1 + i, a1 = 1 + (i + 1) % k, b = 1 + k + i, b1 = 1 + k + (i + 1) % k;
    if (i >= leftOut) in.conn.insert(in.conn.end(), {0, a, a1});
    in.conn.insert(in.conn.end(), {a, b, b1, a, b1, a1});
    for (int t = i >= leftOut ? 0 : 1; t < 3; ++t) in.types.push_back(ElementType::Tri3);
  }
  if (leftOut > 0) {
    in.leftOutNeighbour.assign(in.nodes.size(), 0);
    for (int i = 0; i <= leftOut; ++i) in.leftOutNeighbour[static_cast<std::size_t>(i)] = 1;
  }
  std::unique_ptr<CadMesh> cm;
  ASSERT_NO_THROW(cm = std::make_unique<CadMesh>(shape, in));
  EXPECT_EQ(cm->report().nodeClass[0], NodeClass::Vertex);
  EXPECT_EQ(cm->report().poleNodes, 1u);
  EXPECT_EQ(cm->mesh().nodeKind[0], NodeKind::Fixed);
  const MeshQuality q = measureQuality(cm->mesh(), measureByName("shape"));
  EXPECT_EQ(q.stats.tangled + q.stats.across, 0u);
}

}  // namespace

TEST(CadPeriodic, FaceNodeProjectedOntoTheApexIsThePole) {
  // Gmsh's curvature-sized MeshAdapt mesh of nist_pmi_2 at diagonal / 17 has a node 4.9e-6
  // from a B-spline face's apex, among elements whose sides there are shorter than 5e-5: too
  // far from the apex's vertex to be taken for it (a tenth of its shortest side), and its
  // nearest point on the face is the apex itself, where every point of the singular line lies.
  // As a face node, its (u,v) was one point of that line and its elements' corners another
  // (a pole's free coordinate follows the element's other corners): the recovery refused the
  // mesh ("the corner (u,v) of node … does not match the node's (u,v)"). Here: a cone's apex
  // at v = 0, a node on the axis 5e-6 beyond it (its nearest point on the face: the apex), a
  // ring of 8 nodes 2e-5 down the cone and the face's circle at v = 6.
  expectApexNodeIsThePole(0);
}

TEST(CadPeriodic, ElementsInsideAPolesBandTakeTheNormalAcrossIt) {
  // Gmsh's curvature-sized MeshAdapt mesh of nist_pmi_2 puts elements of 5e-7 around the tips
  // of B-spline cones, closer to the singular line than kPoleNormalTol of the parameter range:
  // no corner, nor the centroid, has a normal there (Surface::normal is zero), and such an
  // element was counted tangled however it was wound (136 of that mesh's elements, every one
  // along FreeCAD's normalAt). Here: a cone's apex node, two rings of 8 nodes 1e-7 and 2e-7
  // down the cone (every corner of the elements between them in the band), the face's circle
  // at v = 6. Wound along the face, none is tangled; one element between the rings wound
  // against it is, and it alone. The same as straight-sided tri6, whose certificate had no node
  // normal there either (Gmsh's order-2 mesh of that part: 398 valid elements reported
  // standing across).
  const gp_Ax3 ax;
  Handle(Geom_Surface) cone = new Geom_ConicalSurface(ax, 0.4, 0.0);  // apex at v = 0
  const PeriodicCase c = madeFace("cone_pole_band", cone, 0.0, 2 * kPi, 0.0, 6.0);
  auto shape = makeShape(c);
  auto at = [&](double u, double v) {
    const gp_Pnt p = cone->Value(u, v);
    return Vec3(p.X(), p.Y(), p.Z());
  };
  constexpr int k = 8;
  auto build = [&](bool flipOne, bool curved) {
    MeshInput in;
    in.nodes.push_back(at(0.0, 0.0));
    for (double v : {1e-7, 2e-7, 6.0})
      for (int i = 0; i < k; ++i) in.nodes.push_back(at(2 * kPi * (i + 0.5 * (v > 1.5e-7)) / k, v));
    // tri6: straight sides, their nodes at the sides' midpoints (off the cone by less than
    // 1e-15 in the band).
    std::map<std::pair<std::int32_t, std::int32_t>, std::int32_t> sides;
    auto mid = [&](std::int32_t a, std::int32_t b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = sides.find(key);
      if (it != sides.end()) return it->second;
      in.nodes.push_back(
          0.5 * (in.nodes[static_cast<std::size_t>(a)] + in.nodes[static_cast<std::size_t>(b)]));
      return sides[key] = static_cast<std::int32_t>(in.nodes.size() - 1);
    };
    std::vector<std::array<std::int32_t, 3>> tris;
    auto tri = [&](std::int32_t a, std::int32_t b, std::int32_t d) { tris.push_back({a, b, d}); };
    for (int i = 0; i < k; ++i) tri(0, 1 + i, 1 + (i + 1) % k);
    for (int ring = 0; ring < 2; ++ring) {
      const std::int32_t a0 = 1 + ring * k, b0 = 1 + (ring + 1) * k;
      for (int i = 0; i < k; ++i) {
        const std::int32_t a = a0 + i, a1 = a0 + (i + 1) % k, b = b0 + i, b1 = b0 + (i + 1) % k;
        tri(a, b, a1);
        if (ring == 0 && i == 0 && flipOne) {
          tri(a1, b1, b);  // wound against the face
        } else {
          tri(a1, b, b1);
        }
      }
    }
    for (const auto& t : tris) {
      in.conn.insert(in.conn.end(), t.begin(), t.end());
      if (curved) {
        const std::int32_t m0 = mid(t[0], t[1]), m1 = mid(t[1], t[2]), m2 = mid(t[2], t[0]);
        in.conn.insert(in.conn.end(), {m0, m1, m2});
      }
      in.types.push_back(curved ? ElementType::Tri6 : ElementType::Tri3);
    }
    return in;
  };
  for (int run = 0; run < 4; ++run) {
    const bool flipOne = run % 2 == 1, curved = run >= 2;
    SCOPED_TRACE(curved ? "tri6" : "tri3");
    std::unique_ptr<CadMesh> cm;
    ASSERT_NO_THROW(cm = std::make_unique<CadMesh>(shape, build(flipOne, curved)));
    const SurfaceMesh& m = cm->mesh();
    // The rings' nodes are face nodes inside the band: none of them has a normal.
    for (std::size_t n = 1; n <= 2 * k; ++n) {
      ASSERT_EQ(m.nodeKind[n], NodeKind::Face) << n;
      EXPECT_EQ(m.referenceNormal(m.nodeFace[n], m.uv[n]).squaredNorm(), 0.0) << n;
    }
    const MeshQuality q = measureQuality(m, measureByName("shape"));
    EXPECT_EQ(q.stats.tangled + q.stats.across, flipOne ? 1u : 0u) << "flipOne " << flipOne;
    if (flipOne) EXPECT_TRUE(q.tangled[k + 1]);  // the second element of the first strip
  }
}

TEST(CadPeriodic, NodeBesideALeftOutElementProjectedOntoTheApexIsThePole) {
  // The same rule as FaceNodeProjectedOntoTheApexIsThePole for a node on the border of a hole
  // the elements left out leave (such a node moves in its face): Gmsh's order-2 Delaunay mesh
  // of OCC's propeller at diagonal / 8 with curvature sizes has them at the hub's tip, and the
  // recovery refused it ("the corner (u,v) of node … does not match the node's (u,v)"). Here
  // the case of FaceNodeProjectedOntoTheApexIsThePole with three of its eight fan triangles
  // left out.
  expectApexNodeIsThePole(3);
}
