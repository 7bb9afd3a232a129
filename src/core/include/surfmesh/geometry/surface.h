// SurfMesh — parameterized surfaces φ : U ⊂ R² → R³.
//
// A Surface gives the point φ(u,v), its first derivatives φ_u, φ_v and second derivatives
// φ_uu, φ_uv, φ_vv, the parameter bounds, the periods of periodic directions, and the outward
// normal convention: the outward normal is normalSign() · (φ_u × φ_v) / ‖φ_u × φ_v‖.
//
// Surfaces are NOT required to be thread-safe (OpenCASCADE adaptors are not): every thread
// works on its own copy obtained with clone().
#pragma once

#include <Eigen/Dense>

#include <memory>
#include <string>

namespace surfmesh {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;

/// Point and first derivatives of a surface at (u,v).
struct SurfaceD1 {
  Vec3 p;   ///< φ(u,v)
  Vec3 du;  ///< ∂φ/∂u
  Vec3 dv;  ///< ∂φ/∂v
};

/// Point, first and second derivatives of a surface at (u,v).
struct SurfaceD2 {
  Vec3 p;    ///< φ(u,v)
  Vec3 du;   ///< ∂φ/∂u
  Vec3 dv;   ///< ∂φ/∂v
  Vec3 duu;  ///< ∂²φ/∂u²
  Vec3 duv;  ///< ∂²φ/∂u∂v
  Vec3 dvv;  ///< ∂²φ/∂v²
};

/// Parameter rectangle [umin,umax] × [vmin,vmax]. Infinite bounds are allowed (plane).
struct ParamBounds {
  double umin = -1e300;
  double umax = 1e300;
  double vmin = -1e300;
  double vmax = 1e300;
};

/// Abstract parameterized surface.
class Surface {
 public:
  virtual ~Surface() = default;

  /// φ(u,v).
  virtual Vec3 value(double u, double v) const = 0;
  /// φ and its first derivatives.
  virtual SurfaceD1 d1(double u, double v) const = 0;
  /// φ and its first and second derivatives.
  virtual SurfaceD2 d2(double u, double v) const = 0;

  /// Parameter bounds (for a periodic direction, one period).
  virtual ParamBounds bounds() const = 0;
  virtual bool isUPeriodic() const { return false; }
  virtual bool isVPeriodic() const { return false; }
  /// Period in u (only meaningful when isUPeriodic()).
  virtual double uPeriod() const { return 0.0; }
  /// Period in v (only meaningful when isVPeriodic()).
  virtual double vPeriod() const { return 0.0; }

  /// +1 when the outward normal is φ_u × φ_v, −1 when it is −φ_u × φ_v (e.g. a Reversed
  /// B-rep face).
  virtual int normalSign() const { return 1; }

  /// Whether (u,v) lies in the surface's domain. The default checks the bounds of the
  /// non-periodic directions; trimmed faces override it to test their trimming loops.
  virtual bool contains(double u, double v) const;

  /// contains() without keeping points out of the tolerance zones of the boundary's edges and
  /// vertices (OccFaceSurface; the same as contains() elsewhere): for the moves that untangle
  /// a fold, which may need a node where OCC counts it on a tolerant edge.
  virtual bool containsNearBoundary(double u, double v) const { return contains(u, v); }

  /// Builds ahead what contains() would build on its first call (a trimmed face's lookup
  /// grid), so that callers can do it in parallel over surfaces. Safe to call concurrently
  /// with any use of other copies; the default does nothing.
  virtual void prepare() const {}

  /// An independent copy, safe to use from another thread.
  virtual std::unique_ptr<Surface> clone() const = 0;

  /// Short human-readable description ("torus R=10 r=4", "OCC face 12 (BSplineSurface)").
  virtual std::string describe() const = 0;

  // ---- helpers built on the virtual interface -------------------------------------------

  /// Unit outward normal at (u,v) (normalSign applied); zero vector at a pole, where
  /// ‖φ_u × φ_v‖ ≤ kPoleNormalTol · max(‖φ_u‖, ‖φ_v‖)².
  Vec3 normal(double u, double v) const;
  /// The same from the first derivatives `d` at (u,v): normal(u,v) == normalOf(d1(u,v)).
  Vec3 normalOf(const SurfaceD1& d) const;
  /// normal(u,v), or where it is zero next to a singular line (a pole's band), the normal a
  /// little across that line into the parameter bounds, on the same meridian: the limit a
  /// cone-like tip has along each meridian, and at a smooth pole the pole's own normal. Zero
  /// when no normal is found within a quarter of the bounds.
  Vec3 normalAcrossPole(double u, double v) const;

  /// Wraps the periodic coordinates of `uv` into [min, min + period).
  Vec2 wrap(const Vec2& uv) const;

  /// Shifts the periodic coordinates of `uv` by whole periods so that it is as close as
  /// possible to `ref` (unwrapping across the seam).
  Vec2 unwrapNear(const Vec2& uv, const Vec2& ref) const;

  /// Clamps the non-periodic coordinates of `uv` into the bounds.
  Vec2 clampToBounds(const Vec2& uv) const;
};

/// Relative threshold under which ‖φ_u × φ_v‖ is considered degenerate (a pole):
/// ‖φ_u × φ_v‖ ≤ kDegenerateTol · max(‖φ_u‖, ‖φ_v‖)² (or either derivative vanishes).
constexpr double kDegenerateTol = 1e-12;

/// Relative threshold under which the surface has no normal (Surface::normal is zero):
/// ‖φ_u × φ_v‖ ≤ kPoleNormalTol · max(‖φ_u‖, ‖φ_v‖)². Looser than kDegenerateTol: a CAD face's
/// collapsed row of control points meets in a point only to within the model's tolerance, and
/// its degenerated edge lies a little off the singular line (a vertex at v = 5e−10), where
/// φ_u × φ_v is small but not zero. There the normal depends on the meridian the (u,v) happens
/// to be on (at a cone-like tip, by up to 180°), so it is no normal of the element there. The
/// optimizer's own test of a pole (isDegenerate) keeps kDegenerateTol.
constexpr double kPoleNormalTol = 1e-6;

/// True where the parameterization is degenerate (φ_u × φ_v ≈ 0), given φ_u and φ_v. Inline
/// and in scalar arithmetic: the optimizer asks at every node update and trial, with
/// derivatives it has just computed.
inline bool isDegenerate(const Vec3& du, const Vec3& dv) {
  // Squared: ‖c‖² ≤ tol² · max(‖φ_u‖², ‖φ_v‖²)² (no square roots on the optimizer's path).
  const double a2 = (du.x() * du.x() + du.y() * du.y()) + du.z() * du.z();
  const double b2 = (dv.x() * dv.x() + dv.y() * dv.y()) + dv.z() * dv.z();
  if (!(a2 > 0.0) || !(b2 > 0.0)) return true;
  const double t = kDegenerateTol * (a2 < b2 ? b2 : a2);
  const double c0 = du.y() * dv.z() - du.z() * dv.y();
  const double c1 = du.z() * dv.x() - du.x() * dv.z();
  const double c2 = du.x() * dv.y() - du.y() * dv.x();
  return (c0 * c0 + c1 * c1) + c2 * c2 <= t * t;
}

/// The same for d's φ_u and φ_v.
inline bool isDegenerate(const SurfaceD1& d) { return isDegenerate(d.du, d.dv); }

/// x shifted by whole periods into [lo, lo + period) (x itself when period ≤ 0 or x is not
/// finite).
double wrapInto(double x, double lo, double period);

}  // namespace surfmesh
