// SurfMesh — the Jacobian ratio of curved (and straight) elements.
#include "surfmesh/mesh/jacobian_ratio.h"

#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/lagrange_triangle.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace surfmesh {

namespace {

/// Reference gradients (∂N/∂a, ∂N/∂b) of element type t at (a, b): Gmsh's reference triangle,
/// or the unit square of a bilinear quadrilateral.
void shapeGradients(ElementType t, double a, double b, Vec2* grad) {
  if (t == ElementType::Quad4) {
    grad[0] = Vec2(-(1 - b), -(1 - a));
    grad[1] = Vec2(1 - b, -a);
    grad[2] = Vec2(b, a);
    grad[3] = Vec2(-b, 1 - a);
    return;
  }
  if (t == ElementType::Quad8) {
    Eigen::Vector2d g[8];
    quad8ShapeGradients(a, b, g);
    for (int i = 0; i < 8; ++i) grad[i] = g[i];
    return;
  }
  lagrangeTriangle(elementOrder(t)).gradients(Vec2(a, b), grad);
}

/// The points where jacobianRatioOf samples det J on an element of type t (its nodes, then
/// a grid of `divisions` steps per side) with the shape functions' values and reference
/// gradients there: the same for every element of the type, so tabulated once.
struct SamplePoints {
  int k = 0;  // nodes per element
  std::vector<Vec2> points;
  std::vector<double> N;   // k per point
  std::vector<Vec2> grad;  // k per point
};

SamplePoints samplePoints(ElementType t, int divisions) {
  SamplePoints s;
  s.k = nodeCount(t);
  auto add = [&](const Vec2& p) { s.points.push_back(p); };
  if (isQuad(t)) {
    for (double a : {0.0, 1.0})
      for (double b : {0.0, 1.0}) add(Vec2(a, b));
    if (t == ElementType::Quad8)  // its side nodes
      for (const Vec2& p : {Vec2(0.5, 0.0), Vec2(1.0, 0.5), Vec2(0.5, 1.0), Vec2(0.0, 0.5)}) add(p);
  } else {
    for (const Vec2& p : lagrangeTriangle(elementOrder(t)).nodes()) add(p);
  }
  for (int i = 0; i <= divisions; ++i)
    for (int j = 0; j <= (isQuad(t) ? divisions : divisions - i); ++j)
      add(Vec2(double(i) / divisions, double(j) / divisions));
  s.N.resize(s.points.size() * static_cast<std::size_t>(s.k));
  s.grad.resize(s.N.size());
  for (std::size_t q = 0; q < s.points.size(); ++q) {
    const Vec2& p = s.points[q];
    elementShapeValues(t, p.x(), p.y(), &s.N[q * static_cast<std::size_t>(s.k)]);
    shapeGradients(t, p.x(), p.y(), &s.grad[q * static_cast<std::size_t>(s.k)]);
  }
  return s;
}

/// samplePoints of every element type at kJacobianDivisions, built on first use.
const SamplePoints& defaultSamplePoints(ElementType t) {
  static const std::vector<SamplePoints> table = [] {
    std::vector<SamplePoints> v;
    for (int c = 0; isElementTypeCode(c); ++c)
      v.push_back(samplePoints(static_cast<ElementType>(c), kJacobianDivisions));
    return v;
  }();
  return table[static_cast<std::size_t>(t)];
}

}  // namespace

double jacobianRatioOf(const SurfaceMesh& mesh, std::size_t e, int divisions) {
  Vec3 x[kMaxElementNodes];
  Vec3 nodeNormal[kMaxElementNodes];
  const ElementType t = mesh.elemType[e];
  const int k = mesh.elementSize(e);
  const std::int32_t* nodes = mesh.elementNodes(e);
  for (int a = 0; a < k; ++a) x[a] = mesh.xyz[static_cast<std::size_t>(nodes[a])];
  for (int a = 0; a < k; ++a)
    if (!x[a].allFinite()) return std::numeric_limits<double>::quiet_NaN();
  const bool quad = isQuad(t);
  const int f = e < mesh.elemFace.size() ? mesh.elemFace[e] : -1;
  const bool onFace = f >= 0 && static_cast<std::size_t>(f) < mesh.surfaces.size() &&
                      mesh.surfaces[static_cast<std::size_t>(f)] != nullptr &&
                      mesh.cornerUV.size() == mesh.elemNodes.size();
  const Vec2* uv = onFace ? mesh.elementUV(e) : nullptr;
  if (onFace) {
    // The face's normals at the nodes, a pole's replaced as the certificate does.
    Vec3 atNodes[kMaxElementNodes];
    elementNodeNormals(mesh, e, mesh.surfaces, atNodes);
    double sumNorm = 0.0;
    if (!fillPoleNormals(atNodes, k, nodeNormal, &sumNorm))
      return std::numeric_limits<double>::quiet_NaN();
  } else {
    // No face: the element's own corner normal (Gmsh's convention).
    const Vec3 n = quad ? Vec3((x[1] + x[2] - x[0] - x[3]).cross(x[2] + x[3] - x[0] - x[1]))
                        : Vec3((x[1] - x[0]).cross(x[2] - x[0]));
    const double len = n.norm();
    if (!(len > 0.0)) return 0.0;
    for (int a = 0; a < k; ++a) nodeNormal[a] = n / len;
  }
  SamplePoints own;  // (another number of divisions than the tabulated one)
  if (divisions != kJacobianDivisions) own = samplePoints(t, divisions);
  const SamplePoints& sp = divisions == kJacobianDivisions ? defaultSamplePoints(t) : own;
  // exact: the face's own normal at the point the element's (u,v) map reaches (the
  // interpolated node normals where the face has none there).
  auto ratio = [&](bool exact) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (std::size_t q = 0; q < sp.points.size(); ++q) {
      const double* N = &sp.N[q * static_cast<std::size_t>(k)];
      const Vec2* grad = &sp.grad[q * static_cast<std::size_t>(k)];
      Vec3 xa = Vec3::Zero(), xb = Vec3::Zero(), n = Vec3::Zero();
      Vec2 at = Vec2::Zero();
      for (int a = 0; a < k; ++a) {
        xa += grad[a].x() * x[a];
        xb += grad[a].y() * x[a];
        n += N[a] * nodeNormal[a];
        if (exact) at += N[a] * uv[a];
      }
      if (exact) {
        const Vec3 nf = mesh.referenceNormal(f, at);
        if (nf.squaredNorm() > 0.0) n = nf;
      }
      if (!(n.squaredNorm() > 0.0)) continue;  // no direction here (normals cancelling)
      const Vec3 c = xa.cross(xb);
      const double side = n.dot(c);
      const double J = side > 0.0 ? c.norm() : side < 0.0 ? -c.norm() : 0.0;
      lo = std::min(lo, J);
      hi = std::max(hi, std::abs(J));
    }
    return hi > 0.0 && lo < std::numeric_limits<double>::infinity() ? lo / hi : 0.0;
  };
  const double r = ratio(false);
  // Where the interpolated normals see J <= 0, the face's own normals decide (as the
  // certificate's pieces do): the normal may turn faster than the interpolation follows.
  return r <= 0.0 && onFace ? ratio(true) : r;
}

std::vector<double> elementJacobianRatio(const SurfaceMesh& mesh, int divisions) {
  if (divisions < 1)
    throw std::invalid_argument("divisions must be at least 1, got " + std::to_string(divisions));
  std::vector<double> out(mesh.elementCount(), 0.0);
  for (std::size_t e = 0; e < out.size(); ++e) out[e] = jacobianRatioOf(mesh, e, divisions);
  return out;
}

}  // namespace surfmesh
