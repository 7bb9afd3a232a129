// Finite-difference check of elementDistortion's derivatives with respect to one node's (u,v)
// on a surface, for any element type (shared by the quad and high-order tests).
#pragma once

#include "surfmesh/geometry/surface.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/measure.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace surfmesh::testmesh {

/// Errors of the central differences at h and h/2 (gradient and Hessian, max norm).
struct FdErrors {
  double grad[2] = {0, 0};
  double hess[2] = {0, 0};
  double gradNorm = 0, hessNorm = 0;
};

/// Element of type `type` whose nodes are φ(uv[i]); node `k` is free and moves in (u,v);
/// the reference normal n is held fixed. Compares the exact gradient/Hessian in (u,v)
/// (elementDistortion + chainToSurface) with central differences, and expects the error to
/// fall at rate 2 when h is halved.
inline FdErrors checkElementDerivatives(const PlanarMeasure& m, const Surface& s, ElementType type,
                                        const std::vector<Vec2>& uv, int k, const Vec3& n,
                                        double delta, double h0, const std::string& what) {
  std::vector<Vec3> x(uv.size());
  for (std::size_t i = 0; i < uv.size(); ++i) x[i] = s.value(uv[i].x(), uv[i].y());
  auto f = [&](const Vec2& p) {
    std::vector<Vec3> y = x;
    y[static_cast<std::size_t>(k)] = s.value(p.x(), p.y());
    return elementDistortion(m, type, y.data(), n, delta).eta;
  };
  auto grad = [&](const Vec2& p, Mat2* H) {
    const SurfaceD2 d = s.d2(p.x(), p.y());
    std::vector<Vec3> y = x;
    y[static_cast<std::size_t>(k)] = d.p;
    Vec3 g;
    Mat3 Hx;
    elementDistortion(m, type, y.data(), n, delta, k, &g, &Hx);
    Vec2 gu;
    chainToSurface(d, g, Hx, &gu, H);
    return gu;
  };
  const Vec2 p0 = uv[static_cast<std::size_t>(k)];
  Mat2 H;
  const Vec2 g = grad(p0, &H);
  FdErrors r;
  r.gradNorm = g.norm();
  r.hessNorm = H.norm();
  for (int level = 0; level < 2; ++level) {
    const double h = h0 / (1 << level);
    for (int c = 0; c < 2; ++c) {
      Vec2 e = Vec2::Zero();
      e(c) = h;
      const double fd = (f(p0 + e) - f(p0 - e)) / (2 * h);
      r.grad[level] = std::max(r.grad[level], std::abs(fd - g(c)));
      const Vec2 gfd = (grad(p0 + e, nullptr) - grad(p0 - e, nullptr)) / (2 * h);
      for (int j = 0; j < 2; ++j)
        r.hess[level] = std::max(r.hess[level], std::abs(gfd(j) - H(c, j)));
    }
  }
  EXPECT_TRUE(g.allFinite() && H.allFinite()) << what;
  // Below ~1e-7 relative the differences are dominated by rounding: no rate to see there.
  const double gs = 1e-7 * (1 + r.gradNorm), hs = 1e-7 * (1 + r.hessNorm);
  if (r.grad[0] > gs) {
    EXPECT_NEAR(r.grad[0] / r.grad[1], 4.0, 0.6) << "gradient " << what;
  }
  if (r.hess[0] > hs) {
    EXPECT_NEAR(r.hess[0] / r.hess[1], 4.0, 0.6) << "Hessian " << what;
  }
  EXPECT_LT(r.grad[0], 1e-3 * (1 + r.gradNorm)) << what;
  EXPECT_LT(r.hess[0], 1e-2 * (1 + r.hessNorm)) << what;
  return r;
}

}  // namespace surfmesh::testmesh
