// SurfMesh — closed-form surfaces, used by tests, benchmarks and the demo.
//
// Each class documents its parameterization; all derivatives are exact.
#pragma once

#include "surfmesh/geometry/surface.h"

#include <array>

namespace surfmesh {

/// φ(u,v) = origin + u·e1 + v·e2 (e1, e2 need not be orthonormal). Unbounded unless
/// bounds are given.
class PlaneSurface final : public Surface {
 public:
  PlaneSurface(const Vec3& origin = Vec3::Zero(), const Vec3& e1 = Vec3::UnitX(),
               const Vec3& e2 = Vec3::UnitY(), ParamBounds b = {});
  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override { return b_; }
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  Vec3 o_, e1_, e2_;
  ParamBounds b_;
};

/// Cylinder of radius r around the z axis: φ(u,v) = (r cos u, r sin u, v),
/// u ∈ [0, 2π) periodic, v ∈ [vmin, vmax]. φ_u × φ_v points outwards.
class CylinderSurface final : public Surface {
 public:
  CylinderSurface(double r, double vmin, double vmax);
  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override;
  bool isUPeriodic() const override { return true; }
  double uPeriod() const override;
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  double r_, vmin_, vmax_;
};

/// Sphere of radius r: φ(u,v) = r (cos v cos u, cos v sin u, sin v), u ∈ [0, 2π) periodic
/// (longitude), v ∈ [−π/2, π/2] (latitude, poles at ±π/2, as OpenCASCADE's Geom_SphericalSurface).
/// φ_u × φ_v points outwards.
class SphereSurface final : public Surface {
 public:
  explicit SphereSurface(double r);
  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override;
  bool isUPeriodic() const override { return true; }
  double uPeriod() const override;
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  double r_;
};

/// Torus with major radius R and minor radius r around the z axis:
/// φ(u,v) = ((R + r cos v) cos u, (R + r cos v) sin u, r sin v), u, v ∈ [0, 2π) both periodic.
/// φ_u × φ_v points outwards.
class TorusSurface final : public Surface {
 public:
  TorusSurface(double R, double r);
  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override;
  bool isUPeriodic() const override { return true; }
  bool isVPeriodic() const override { return true; }
  double uPeriod() const override;
  double vPeriod() const override;
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  double R_, r_;
};

/// Biquadratic polynomial patch φ(u,v) = Σ_{i,j=0..2} c[i][j] u^i v^j on [0,1]² (a bilinear
/// patch when only c[0][0], c[1][0], c[0][1], c[1][1] are non-zero).
class PolynomialPatch final : public Surface {
 public:
  using Coeffs = std::array<std::array<Vec3, 3>, 3>;
  explicit PolynomialPatch(const Coeffs& c, ParamBounds b = {0.0, 1.0, 0.0, 1.0});
  /// The bilinear patch through the four corners φ(0,0)=p00, φ(1,0)=p10, φ(0,1)=p01, φ(1,1)=p11.
  static PolynomialPatch bilinear(const Vec3& p00, const Vec3& p10, const Vec3& p01,
                                  const Vec3& p11);
  Vec3 value(double u, double v) const override;
  SurfaceD1 d1(double u, double v) const override;
  SurfaceD2 d2(double u, double v) const override;
  ParamBounds bounds() const override { return b_; }
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  Coeffs c_;
  ParamBounds b_;
};

/// Wraps another surface and flips its outward normal convention (normalSign() = −inner's).
class ReversedSurface final : public Surface {
 public:
  explicit ReversedSurface(std::unique_ptr<Surface> inner);
  Vec3 value(double u, double v) const override { return s_->value(u, v); }
  SurfaceD1 d1(double u, double v) const override { return s_->d1(u, v); }
  SurfaceD2 d2(double u, double v) const override { return s_->d2(u, v); }
  ParamBounds bounds() const override { return s_->bounds(); }
  bool isUPeriodic() const override { return s_->isUPeriodic(); }
  bool isVPeriodic() const override { return s_->isVPeriodic(); }
  double uPeriod() const override { return s_->uPeriod(); }
  double vPeriod() const override { return s_->vPeriod(); }
  int normalSign() const override { return -s_->normalSign(); }
  bool contains(double u, double v) const override { return s_->contains(u, v); }
  bool containsNearBoundary(double u, double v) const override {
    return s_->containsNearBoundary(u, v);
  }
  std::unique_ptr<Surface> clone() const override;
  std::string describe() const override;

 private:
  std::unique_ptr<Surface> s_;
};

}  // namespace surfmesh
