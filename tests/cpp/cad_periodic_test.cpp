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

#include <cmath>
#include <memory>
#include <string>
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
