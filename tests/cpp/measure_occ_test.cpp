// The surface extension on real CAD geometry: restricted-measure derivatives on OpenCASCADE
// B-spline faces of a third-party part (tests/data/occt_propeller.brep).
#include "fd_check.h"
#include "surfmesh/cad/cad_shape.h"
#include "surfmesh/cad/occ_surface.h"

#include <BRepAdaptor_Surface.hxx>
#include <gtest/gtest.h>

using namespace surfmesh;

TEST(SurfaceMeasureOcc, RestrictedDerivativesOnBSplineFacesMatchFiniteDifferences) {
  const auto shape =
      CadShape::fromFile(std::string(SURFMESH_TEST_DATA_DIR) + "/occt_propeller.brep");
  int checked = 0;
  for (int f = 0; f < shape->faceCount() && checked < 6; ++f) {
    if (BRepAdaptor_Surface(shape->face(f)).GetType() != GeomAbs_BSplineSurface) continue;
    const OccFaceSurface& s = shape->surface(f);
    const ParamBounds b = s.bounds();
    const double du = b.umax - b.umin, dv = b.vmax - b.vmin;
    // A small counter-clockwise triangle (in the face's outward orientation) near the middle.
    const Vec2 c(b.umin + 0.45 * du, b.vmin + 0.55 * dv);
    Vec2 uv[3] = {c, c + Vec2(0.03 * du, 0.005 * dv), c + Vec2(0.01 * du, 0.03 * dv)};
    if (s.normalSign() < 0) std::swap(uv[1], uv[2]);
    const SurfaceD1 d = s.d1(c.x(), c.y());
    if (isDegenerate(d)) continue;
    const double h = 1e-3 * 0.03 * std::min(du, dv);  // FD step: small against the triangle
    testmesh::checkRestrictedDerivatives(s, uv, 0.0, h);
    // And a tangled configuration with the regularized measure (δ as the automatic policy
    // chooses it for σ_min ≈ −1: about 0.1 of the element's size²).
    std::swap(uv[1], uv[2]);
    const double size2 =
        (s.value(uv[1].x(), uv[1].y()) - s.value(uv[0].x(), uv[0].y())).squaredNorm();
    testmesh::checkRestrictedDerivatives(s, uv, 0.1 * size2, h);
    ++checked;
  }
  EXPECT_GE(checked, 3);
}
