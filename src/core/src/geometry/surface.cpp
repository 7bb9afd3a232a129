#include "surfmesh/geometry/surface.h"

#include <algorithm>
#include <cmath>

namespace surfmesh {

bool Surface::contains(double u, double v) const {
  const ParamBounds b = bounds();
  const double tu = 1e-9 * std::max(1.0, std::abs(b.umax - b.umin));
  const double tv = 1e-9 * std::max(1.0, std::abs(b.vmax - b.vmin));
  if (!isUPeriodic() && (u < b.umin - tu || u > b.umax + tu)) return false;
  if (!isVPeriodic() && (v < b.vmin - tv || v > b.vmax + tv)) return false;
  return std::isfinite(u) && std::isfinite(v);
}

Vec3 Surface::normal(double u, double v) const { return normalOf(d1(u, v)); }

Vec3 Surface::normalOf(const SurfaceD1& d) const {
  const Vec3 n = d.du.cross(d.dv);
  const double len = n.norm();
  if (!(len > kPoleNormalTol * std::max(d.du.squaredNorm(), d.dv.squaredNorm())))
    return Vec3::Zero();
  return (normalSign() * (n / len)).eval();
}

double wrapInto(double x, double lo, double period) {
  if (!(period > 0.0) || !std::isfinite(x)) return x;
  double k = std::floor((x - lo) / period);
  double y = x - k * period;
  if (y >= lo + period) y -= period;
  if (y < lo) y = lo;
  return y;
}

static double nearestShift(double x, double ref, double period) {
  if (!(period > 0.0) || !std::isfinite(x)) return x;
  return x - std::round((x - ref) / period) * period;
}

Vec2 Surface::wrap(const Vec2& uv) const {
  const ParamBounds b = bounds();
  Vec2 r = uv;
  if (isUPeriodic()) r.x() = wrapInto(r.x(), b.umin, uPeriod());
  if (isVPeriodic()) r.y() = wrapInto(r.y(), b.vmin, vPeriod());
  return r;
}

Vec2 Surface::unwrapNear(const Vec2& uv, const Vec2& ref) const {
  Vec2 r = uv;
  if (isUPeriodic()) r.x() = nearestShift(r.x(), ref.x(), uPeriod());
  if (isVPeriodic()) r.y() = nearestShift(r.y(), ref.y(), vPeriod());
  return r;
}

Vec2 Surface::clampToBounds(const Vec2& uv) const {
  const ParamBounds b = bounds();
  Vec2 r = uv;
  if (!isUPeriodic()) r.x() = std::min(std::max(r.x(), b.umin), b.umax);
  if (!isVPeriodic()) r.y() = std::min(std::max(r.y(), b.vmin), b.vmax);
  return r;
}

}  // namespace surfmesh
