// Finite-difference check of the restricted measure's derivatives in (u,v), shared by tests.
#pragma once

#include "surfmesh/geometry/surface.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/measure.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace surfmesh::testmesh {

// Restricted measure of a free node in (u,v): exact gradient and Hessian vs finite differences
// (rate 2), on a torus and on a polynomial patch.
inline void checkRestrictedDerivatives(const Surface& s, const Vec2 uv[3], double delta,
                                       double h0 = 2e-4) {
  for (const auto& name : measureNames()) {
    const PlanarMeasure& m = measureByName(name);
    const Vec3 x1 = s.value(uv[1].x(), uv[1].y()), x2 = s.value(uv[2].x(), uv[2].y());
    const Vec3 n = s.normal(uv[0].x(), uv[0].y());
    auto f = [&](const Vec2& p) {
      return triangleDistortion(m, s.value(p.x(), p.y()), x1, x2, n, delta, equilateralWinv()).eta;
    };
    auto grad = [&](const Vec2& p, Mat2* H) {
      const SurfaceD2 d = s.d2(p.x(), p.y());
      Vec3 g;
      Mat3 Hx;
      triangleDistortion(m, d.p, x1, x2, n, delta, equilateralWinv(), &g, &Hx);
      Vec2 gu;
      chainToSurface(d, g, Hx, &gu, H);
      return gu;
    };
    Mat2 H;
    const Vec2 g = grad(uv[0], &H);
    double err[2] = {0, 0}, herr[2] = {0, 0};
    for (int level = 0; level < 2; ++level) {
      const double h = h0 / (1 << level);
      for (int k = 0; k < 2; ++k) {
        Vec2 e = Vec2::Zero();
        e(k) = h;
        const double fd = (f(uv[0] + e) - f(uv[0] - e)) / (2 * h);
        err[level] = std::max(err[level], std::abs(fd - g(k)));
        const Vec2 gfd = (grad(uv[0] + e, nullptr) - grad(uv[0] - e, nullptr)) / (2 * h);
        for (int j = 0; j < 2; ++j) herr[level] = std::max(herr[level], std::abs(gfd(j) - H(k, j)));
      }
    }
    if (err[0] > 1e-9) {
      EXPECT_NEAR(err[0] / err[1], 4.0, 0.6) << name << " " << s.describe();
    }
    if (herr[0] > 1e-9) {
      EXPECT_NEAR(herr[0] / herr[1], 4.0, 0.6) << name << " " << s.describe();
    }
    EXPECT_LT(err[0], 1e-4 * (1 + g.norm())) << name << " " << s.describe();
    EXPECT_LT(herr[0], 1e-3 * (1 + H.norm())) << name << " " << s.describe();
  }
}

}  // namespace surfmesh::testmesh
