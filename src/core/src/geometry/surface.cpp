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

Vec3 Surface::normalAcrossPole(double u, double v) const {
  const SurfaceD1 d = d1(u, v);
  const Vec3 n = normalOf(d);
  if (n.squaredNorm() > 0.0 || !d.du.allFinite() || !d.dv.allFinite()) return n;
  // φ_v vanishing: the singular line is u = const and the meridian is v = const (and the
  // other way round). Steps across the line grow tenfold from 1e-9 of the bounds, towards
  // their middle: a degenerated edge bounds its face's domain, and beyond it lies the
  // surface's other nappe, whose normal is turned over. (Unbounded: towards increasing values.)
  const bool acrossU = d.dv.squaredNorm() <= d.du.squaredNorm();
  const ParamBounds b = bounds();
  const double lo = acrossU ? b.umin : b.vmin, hi = acrossU ? b.umax : b.vmax;
  const double x = acrossU ? u : v;
  const bool bounded = std::isfinite(hi - lo) && hi - lo < 1e299;
  const double range = bounded ? hi - lo : std::max(1.0, std::abs(x));
  const double dir = bounded ? (x <= 0.5 * (lo + hi) ? 1.0 : -1.0) : 1.0;
  for (double h = 1e-9 * range; h <= 0.25 * range; h *= 10.0) {
    const double y = x + dir * h;
    const Vec3 m = acrossU ? normal(y, v) : normal(u, y);
    if (m.squaredNorm() > 0.0) return m;
  }
  return Vec3::Zero();
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
