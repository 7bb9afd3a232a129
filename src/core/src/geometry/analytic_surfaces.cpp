#include "surfmesh/geometry/analytic_surfaces.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

namespace {
constexpr double kTwoPi = 6.283185307179586476925286766559;
constexpr double kHalfPi = 1.5707963267948966192313216916398;
}  // namespace

// ---- Plane ----------------------------------------------------------------------------------

PlaneSurface::PlaneSurface(const Vec3& origin, const Vec3& e1, const Vec3& e2, ParamBounds b)
    : o_(origin), e1_(e1), e2_(e2), b_(b) {
  if (e1.cross(e2).norm() == 0.0) throw std::invalid_argument("PlaneSurface: parallel axes");
}
Vec3 PlaneSurface::value(double u, double v) const { return o_ + u * e1_ + v * e2_; }
SurfaceD1 PlaneSurface::d1(double u, double v) const { return {value(u, v), e1_, e2_}; }
SurfaceD2 PlaneSurface::d2(double u, double v) const {
  return {value(u, v), e1_, e2_, Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
}
std::unique_ptr<Surface> PlaneSurface::clone() const {
  return std::make_unique<PlaneSurface>(*this);
}
std::string PlaneSurface::describe() const { return "plane"; }

// ---- Cylinder -------------------------------------------------------------------------------

CylinderSurface::CylinderSurface(double r, double vmin, double vmax)
    : r_(r), vmin_(vmin), vmax_(vmax) {
  if (!(r > 0.0) || !(vmax > vmin))
    throw std::invalid_argument("CylinderSurface: bad radius/range");
}
Vec3 CylinderSurface::value(double u, double v) const {
  return {r_ * std::cos(u), r_ * std::sin(u), v};
}
SurfaceD1 CylinderSurface::d1(double u, double v) const {
  const double c = std::cos(u), s = std::sin(u);
  return {{r_ * c, r_ * s, v}, {-r_ * s, r_ * c, 0.0}, {0.0, 0.0, 1.0}};
}
SurfaceD2 CylinderSurface::d2(double u, double v) const {
  const double c = std::cos(u), s = std::sin(u);
  return {{r_ * c, r_ * s, v},     {-r_ * s, r_ * c, 0.0}, {0.0, 0.0, 1.0},
          {-r_ * c, -r_ * s, 0.0}, Vec3::Zero(),           Vec3::Zero()};
}
ParamBounds CylinderSurface::bounds() const { return {0.0, kTwoPi, vmin_, vmax_}; }
double CylinderSurface::uPeriod() const { return kTwoPi; }
std::unique_ptr<Surface> CylinderSurface::clone() const {
  return std::make_unique<CylinderSurface>(*this);
}
std::string CylinderSurface::describe() const {
  std::ostringstream s;
  s << "cylinder r=" << r_;
  return s.str();
}

// ---- Sphere ---------------------------------------------------------------------------------

SphereSurface::SphereSurface(double r) : r_(r) {
  if (!(r > 0.0)) throw std::invalid_argument("SphereSurface: bad radius");
}
Vec3 SphereSurface::value(double u, double v) const {
  const double cv = std::cos(v);
  return {r_ * cv * std::cos(u), r_ * cv * std::sin(u), r_ * std::sin(v)};
}
SurfaceD1 SphereSurface::d1(double u, double v) const {
  const double cu = std::cos(u), su = std::sin(u), cv = std::cos(v), sv = std::sin(v);
  return {{r_ * cv * cu, r_ * cv * su, r_ * sv},
          {-r_ * cv * su, r_ * cv * cu, 0.0},
          {-r_ * sv * cu, -r_ * sv * su, r_ * cv}};
}
SurfaceD2 SphereSurface::d2(double u, double v) const {
  const double cu = std::cos(u), su = std::sin(u), cv = std::cos(v), sv = std::sin(v);
  SurfaceD2 d;
  d.p = {r_ * cv * cu, r_ * cv * su, r_ * sv};
  d.du = {-r_ * cv * su, r_ * cv * cu, 0.0};
  d.dv = {-r_ * sv * cu, -r_ * sv * su, r_ * cv};
  d.duu = {-r_ * cv * cu, -r_ * cv * su, 0.0};
  d.duv = {r_ * sv * su, -r_ * sv * cu, 0.0};
  d.dvv = {-r_ * cv * cu, -r_ * cv * su, -r_ * sv};
  return d;
}
ParamBounds SphereSurface::bounds() const { return {0.0, kTwoPi, -kHalfPi, kHalfPi}; }
double SphereSurface::uPeriod() const { return kTwoPi; }
std::unique_ptr<Surface> SphereSurface::clone() const {
  return std::make_unique<SphereSurface>(*this);
}
std::string SphereSurface::describe() const {
  std::ostringstream s;
  s << "sphere r=" << r_;
  return s.str();
}

// ---- Torus ----------------------------------------------------------------------------------

TorusSurface::TorusSurface(double R, double r) : R_(R), r_(r) {
  if (!(r > 0.0) || !(R > r)) throw std::invalid_argument("TorusSurface: need R > r > 0");
}
Vec3 TorusSurface::value(double u, double v) const {
  const double w = R_ + r_ * std::cos(v);
  return {w * std::cos(u), w * std::sin(u), r_ * std::sin(v)};
}
SurfaceD1 TorusSurface::d1(double u, double v) const {
  const double cu = std::cos(u), su = std::sin(u), cv = std::cos(v), sv = std::sin(v);
  const double w = R_ + r_ * cv;
  return {
      {w * cu, w * su, r_ * sv}, {-w * su, w * cu, 0.0}, {-r_ * sv * cu, -r_ * sv * su, r_ * cv}};
}
SurfaceD2 TorusSurface::d2(double u, double v) const {
  const double cu = std::cos(u), su = std::sin(u), cv = std::cos(v), sv = std::sin(v);
  const double w = R_ + r_ * cv;
  SurfaceD2 d;
  d.p = {w * cu, w * su, r_ * sv};
  d.du = {-w * su, w * cu, 0.0};
  d.dv = {-r_ * sv * cu, -r_ * sv * su, r_ * cv};
  d.duu = {-w * cu, -w * su, 0.0};
  d.duv = {r_ * sv * su, -r_ * sv * cu, 0.0};
  d.dvv = {-r_ * cv * cu, -r_ * cv * su, -r_ * sv};
  return d;
}
ParamBounds TorusSurface::bounds() const { return {0.0, kTwoPi, 0.0, kTwoPi}; }
double TorusSurface::uPeriod() const { return kTwoPi; }
double TorusSurface::vPeriod() const { return kTwoPi; }
std::unique_ptr<Surface> TorusSurface::clone() const {
  return std::make_unique<TorusSurface>(*this);
}
std::string TorusSurface::describe() const {
  std::ostringstream s;
  s << "torus R=" << R_ << " r=" << r_;
  return s.str();
}

// ---- Polynomial patch -----------------------------------------------------------------------

PolynomialPatch::PolynomialPatch(const Coeffs& c, ParamBounds b) : c_(c), b_(b) {}

PolynomialPatch PolynomialPatch::bilinear(const Vec3& p00, const Vec3& p10, const Vec3& p01,
                                          const Vec3& p11) {
  Coeffs c;
  for (auto& row : c)
    for (auto& x : row) x = Vec3::Zero();
  c[0][0] = p00;
  c[1][0] = p10 - p00;
  c[0][1] = p01 - p00;
  c[1][1] = p11 - p10 - p01 + p00;
  return PolynomialPatch(c);
}

SurfaceD2 PolynomialPatch::d2(double u, double v) const {
  const double pu[3] = {1.0, u, u * u}, dpu[3] = {0.0, 1.0, 2.0 * u}, ddpu[3] = {0.0, 0.0, 2.0};
  const double pv[3] = {1.0, v, v * v}, dpv[3] = {0.0, 1.0, 2.0 * v}, ddpv[3] = {0.0, 0.0, 2.0};
  SurfaceD2 d{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const Vec3& c = c_[i][j];
      d.p += pu[i] * pv[j] * c;
      d.du += dpu[i] * pv[j] * c;
      d.dv += pu[i] * dpv[j] * c;
      d.duu += ddpu[i] * pv[j] * c;
      d.duv += dpu[i] * dpv[j] * c;
      d.dvv += pu[i] * ddpv[j] * c;
    }
  return d;
}
Vec3 PolynomialPatch::value(double u, double v) const { return d2(u, v).p; }
SurfaceD1 PolynomialPatch::d1(double u, double v) const {
  const SurfaceD2 d = d2(u, v);
  return {d.p, d.du, d.dv};
}
std::unique_ptr<Surface> PolynomialPatch::clone() const {
  return std::make_unique<PolynomialPatch>(*this);
}
std::string PolynomialPatch::describe() const { return "polynomial patch"; }

// ---- Reversed -------------------------------------------------------------------------------

ReversedSurface::ReversedSurface(std::unique_ptr<Surface> inner) : s_(std::move(inner)) {
  if (!s_) throw std::invalid_argument("ReversedSurface: null surface");
}
std::unique_ptr<Surface> ReversedSurface::clone() const {
  return std::make_unique<ReversedSurface>(s_->clone());
}
std::string ReversedSurface::describe() const { return "reversed " + s_->describe(); }

}  // namespace surfmesh
