// SurfMesh — how far an element's interior lies from the CAD surface it stands for.
#include "surfmesh/mesh/distance_to_face.h"

#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace surfmesh {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Vec2 nearestParameters(const Surface& s, const Vec3& x, Vec2 uv, double* distance) {
  SurfaceD2 d = s.d2(uv.x(), uv.y());
  double best = (d.p - x).norm();
  if (!std::isfinite(best)) {
    *distance = kNaN;
    return uv;
  }
  for (int it = 0; it < 50 && best > 0.0; ++it) {
    const Vec3 r = d.p - x;
    const Vec2 g(d.du.dot(r), d.dv.dot(r));
    const double e = d.du.dot(d.du), f = d.du.dot(d.dv), gg = d.dv.dot(d.dv);
    double h00 = e + d.duu.dot(r), h01 = f + d.duv.dot(r), h11 = gg + d.dvv.dot(r);
    if (!(h00 > 0.0 && h00 * h11 - h01 * h01 > 0.0)) {  // not convex here: Gauss–Newton
      h00 = e;
      h01 = f;
      h11 = gg;
    }
    const double tiny = 1e-14 * (e + gg) + std::numeric_limits<double>::min();
    double det = h00 * h11 - h01 * h01;
    if (!(det > tiny * tiny)) {  // singular (a pole): regularize
      h00 += tiny;
      h11 += tiny;
      det = h00 * h11 - h01 * h01;
      if (!(det > 0.0)) break;
    }
    Vec2 step(-(h11 * g.x() - h01 * g.y()) / det, -(h00 * g.y() - h01 * g.x()) / det);
    double change = -1.0;  // how far φ moved in the accepted step; −1: no step accepted
    for (int half = 0; half < 40; ++half, step *= 0.5) {
      const Vec2 next = uv + step;
      const SurfaceD2 dn = s.d2(next.x(), next.y());
      const double dist = (dn.p - x).norm();
      if (std::isfinite(dist) && dist <= best) {
        change = (dn.p - d.p).norm();
        uv = next;
        d = dn;
        best = dist;
        break;
      }
    }
    if (change <= 1e-15 * (x.norm() + best)) break;  // no step, or converged
  }
  *distance = best;
  return uv;
}

namespace {

/// Distance from x to the surface near (u,v) (nearestParameters).
double projectDistance(const Surface& s, const Vec3& x, const Vec2& uv) {
  double dist = kNaN;
  nearestParameters(s, x, uv, &dist);
  return dist;
}

}  // namespace

std::vector<double> elementDistanceToFace(const SurfaceMesh& mesh, int divisions) {
  if (divisions < 1)
    throw std::invalid_argument("divisions must be at least 1, got " + std::to_string(divisions));
  const std::size_t E = mesh.elementCount();
  std::vector<double> out(E, 0.0);
  double N[kMaxElementNodes];
  const double n = divisions;
  for (std::size_t e = 0; e < E; ++e) {
    const ElementType t = mesh.elemType[e];
    const int k = mesh.elementSize(e);
    const std::int32_t* nodes = mesh.elementNodes(e);
    const Vec2* uvs = mesh.elementUV(e);
    const Surface& s = *mesh.surfaces.at(static_cast<std::size_t>(mesh.elemFace[e]));
    const bool quad = isQuad(t);
    double worst = 0.0;
    for (int i = 0; i <= divisions && !std::isnan(worst); ++i) {
      for (int j = 0; j <= (quad ? divisions : divisions - i); ++j) {
        elementShapeValues(t, i / n, j / n, N);
        Vec3 x = Vec3::Zero();
        Vec2 uv = Vec2::Zero();
        for (int a = 0; a < k; ++a) {
          x += N[a] * mesh.xyz[static_cast<std::size_t>(nodes[a])];
          uv += N[a] * uvs[a];
        }
        const double dist = projectDistance(s, x, uv);
        if (std::isnan(dist)) {
          worst = kNaN;
          break;
        }
        worst = std::max(worst, dist);
      }
    }
    out[e] = worst;
  }
  return out;
}

}  // namespace surfmesh
