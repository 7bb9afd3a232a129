#include "surfmesh/measures/element_measure.h"

#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/lagrange_triangle.h"

#include <cmath>
#include <limits>

namespace surfmesh {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

namespace {

/// What η and the validity share at a Jacobian J: K = J W⁻¹, F = ‖K‖², the normal c of the
/// plane of J and σ = γ‖c‖ det W⁻¹ oriented by n (σ = 0 for a degenerate or perpendicular
/// element).
struct JacobianPlane {
  Jacobian32 K;
  double F = 0.0, detWinv = 0.0;
  Vec3 c;
  double cn = 0.0;
  bool finite = false, regular = false;
  double gamma = -1.0, sigma = 0.0;

  // Scalar arithmetic, inlined: Eigen's products here store K's entries one by one and read
  // them back in pairs before the stores complete, which stalled every evaluation (the plane
  // is computed at every node and quadrature point of high-order elements).
  __attribute__((always_inline))
  JacobianPlane(const Jacobian32& J, const Mat2& Winv, const Vec3& n) {
    const double w00 = Winv(0, 0), w01 = Winv(0, 1), w10 = Winv(1, 0), w11 = Winv(1, 1);
    const double a0 = J(0, 0), a1 = J(1, 0), a2 = J(2, 0);  // J₁
    const double b0 = J(0, 1), b1 = J(1, 1), b2 = J(2, 1);  // J₂
    const double k00 = a0 * w00 + b0 * w10, k10 = a1 * w00 + b1 * w10, k20 = a2 * w00 + b2 * w10;
    const double k01 = a0 * w01 + b0 * w11, k11 = a1 * w01 + b1 * w11, k21 = a2 * w01 + b2 * w11;
    F = (k00 * k00 + k10 * k10 + k20 * k20) + (k01 * k01 + k11 * k11 + k21 * k21);
    detWinv = w00 * w11 - w01 * w10;
    const double c0 = a1 * b2 - a2 * b1, c1 = a2 * b0 - a0 * b2, c2 = a0 * b1 - a1 * b0;
    const double cc = c0 * c0 + c1 * c1 + c2 * c2;
    cn = std::sqrt(cc);
    K << k00, k01, k10, k11, k20, k21;
    c = Vec3(c0, c1, c2);
    finite = std::isfinite(F) && std::isfinite(cn) && F > 0.0;
    if (!finite) return;
    const double orient = c0 * n.x() + c1 * n.y() + c2 * n.z();
    regular = cn > 1e-14 * F && orientationDefined(orient, cc, n.squaredNorm());
    gamma = (regular && orient > 0.0) ? 1.0 : -1.0;
    sigma = regular ? gamma * cn * detWinv : 0.0;
  }
  /// r's minSigma (2σ/F, −1 for a non-finite or zero J) and tangled (σ ≤ 0).
  void validity(ElementEval* r) const {
    r->minSigma = finite ? 2.0 * sigma / F : -1.0;
    r->tangled = !finite || !(sigma > 0.0);
  }
};

}  // namespace

ElementEval jacobianValidity(const Jacobian32& J, const Mat2& Winv, const Vec3& n) {
  ElementEval r;
  JacobianPlane(J, Winv, n).validity(&r);
  return r;
}

ElementEval jacobianDistortion(const PlanarMeasure& m, const Jacobian32& J, const Mat2& Winv,
                               const Vec3& n, double delta, const Eigen::Vector2d* b, Vec3* grad,
                               Mat3* hess, double* eta0) {
  ElementEval r;
  if (eta0) *eta0 = kInf;
  const JacobianPlane pl(J, Winv, n);
  pl.validity(&r);
  if (!pl.finite) {
    r.eta = kInf;
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return r;
  }
  const Jacobian32& K = pl.K;
  const Vec3& c = pl.c;
  const double F = pl.F, detWinv = pl.detWinv, cn = pl.cn, gamma = pl.gamma, sigma = pl.sigma;
  const bool regular = pl.regular;
  if (delta == 0.0 && r.tangled) {
    r.eta = kInf;
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return r;
  }
  if (!(b && (grad || hess))) {  // the value alone: no partial derivatives
    r.eta = m.invariantValue(F, sigma, regularizedSigmaValue(sigma, delta));
    if (eta0 && !r.tangled) *eta0 = delta == 0.0 ? r.eta : m.invariantValue(F, sigma, sigma);
    return r;
  }
  const RegularizedSigma rs = regularizedSigma(sigma, delta);
  const InvariantDerivs d = m.invariants(F, sigma, rs);
  r.eta = d.h;
  if (eta0 && !r.tangled) *eta0 = delta == 0.0 ? d.h : m.invariantValue(F, sigma, sigma);
  {
    const Eigen::Vector2d beta = Winv.transpose() * (*b);
    const Vec3 gF = 2.0 * K * beta;
    // c is affine in x: dc = w × dx with w = b1 J₁ − b0 J₂ (J taken without the free node's
    // increment; the increment's own cross product vanishes).
    const Vec3 w = (*b)(1) * J.col(0) - (*b)(0) * J.col(1);
    Vec3 nu;  // unit normal of the element plane, oriented by n
    if (regular)
      nu = gamma * c / cn;
    else
      nu = n.normalized();
    const Vec3 mw = nu.cross(w);
    const Vec3 gs = detWinv * mw;
    if (grad) *grad = d.hF * gF + d.hs * gs;
    if (hess) {
      Mat3 H = d.hFF * gF * gF.transpose() + d.hFs * (gF * gs.transpose() + gs * gF.transpose()) +
               d.hss * gs * gs.transpose();
      H.diagonal().array() += d.hF * 2.0 * beta.squaredNorm();
      if (regular) H += (d.hs * detWinv * gamma / cn) * crossProjected(w, mw);
      *hess = H;
    }
  }
  return r;
}

ElementEval triangleDistortion(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1,
                               const Vec3& x2, const Vec3& n, double delta, const Mat2& Winv,
                               Vec3* grad, Mat3* hess, double* eta0) {
  Jacobian32 J;
  J.col(0) = x1 - x0;
  J.col(1) = x2 - x0;
  if (grad || hess) {
    const Eigen::Vector2d b(-1.0, -1.0);  // J = [x1, x2] − x0 (1, 1)
    return jacobianDistortion(m, J, Winv, n, delta, &b, grad, hess, eta0);
  }
  return jacobianDistortion(m, J, Winv, n, delta, nullptr, nullptr, nullptr, eta0);
}

ElementEval elementDistortion(const PlanarMeasure& m, ElementType type, const Vec3* x,
                              const Vec3& n, double delta, int freeLocal, Vec3* grad, Mat3* hess,
                              double* eta0, const Mat2* target) {
  switch (type) {
    case ElementType::Tri3: {
      if (freeLocal < 0 || (!grad && !hess))
        return triangleDistortion(m, x[0], x[1], x[2], n, delta, equilateralWinv(), nullptr,
                                  nullptr, eta0);
      // Cyclic relabeling keeps the orientation; the equilateral ideal makes η invariant.
      const int k = freeLocal;
      return triangleDistortion(m, x[k], x[(k + 1) % 3], x[(k + 2) % 3], n, delta,
                                equilateralWinv(), grad, hess, eta0);
    }
    case ElementType::Quad4:
      return quadDistortion(m, x, n, delta, freeLocal, grad, hess, eta0);
    case ElementType::Quad8:
      return quad8Distortion(m, x, n, delta, freeLocal, grad, hess, eta0);
    default:
      return highOrderTriangleDistortion(m, type, x, n, delta, freeLocal, grad, hess, eta0, target);
  }
}

ElementEval quadDistortion(const PlanarMeasure& m, const Vec3* x, const Vec3& n, double delta,
                           int freeLocal, Vec3* grad, Mat3* hess, double* eta0) {
  // Knupp: the corner k triangle (x_k, x_{k+1}, x_{k−1}) with the square corner as ideal.
  // η = (¼ Σ η_k²)^½ ; tangled when any corner is.
  const bool derivs = freeLocal >= 0 && (grad || hess);
  double sum = 0.0, sum0 = 0.0;  // Σ η_k² (with δ, and with δ = 0)
  ElementEval r;
  r.minSigma = kInf;
  Vec3 gsum = Vec3::Zero();
  Mat3 Hsum = Mat3::Zero();
  for (int k = 0; k < 4; ++k) {
    const int i0 = k, i1 = (k + 1) % 4, i2 = (k + 3) % 4;
    Jacobian32 J;
    J.col(0) = x[i1] - x[i0];
    J.col(1) = x[i2] - x[i0];
    ElementEval e;
    Vec3 g = Vec3::Zero();
    Mat3 H = Mat3::Zero();
    bool involved = false;
    double e0 = kInf;
    double* e0p = eta0 ? &e0 : nullptr;
    if (derivs) {
      Eigen::Vector2d b(0.0, 0.0);
      if (freeLocal == i0) b = Eigen::Vector2d(-1.0, -1.0);
      if (freeLocal == i1) b = Eigen::Vector2d(1.0, 0.0);
      if (freeLocal == i2) b = Eigen::Vector2d(0.0, 1.0);
      involved = freeLocal == i0 || freeLocal == i1 || freeLocal == i2;
      if (involved)
        e = jacobianDistortion(m, J, squareCornerWinv(), n, delta, &b, &g, &H, e0p);
      else
        e = jacobianDistortion(m, J, squareCornerWinv(), n, delta, nullptr, nullptr, nullptr, e0p);
    } else {
      e = jacobianDistortion(m, J, squareCornerWinv(), n, delta, nullptr, nullptr, nullptr, e0p);
    }
    sum0 += e0 * e0;
    r.minSigma = std::min(r.minSigma, e.minSigma);
    r.tangled = r.tangled || e.tangled;
    if (!std::isfinite(e.eta)) {
      r.eta = kInf;
      continue;
    }
    sum += e.eta * e.eta;
    if (involved) {
      gsum += 2.0 * e.eta * g;
      Hsum += 2.0 * (g * g.transpose() + e.eta * H);
    }
  }
  if (eta0) *eta0 = (r.tangled || !std::isfinite(sum0)) ? kInf : std::sqrt(0.25 * sum0);
  if (!std::isfinite(r.eta)) {
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return r;
  }
  const double Q = 0.25 * sum;  // η² of the quad
  r.eta = std::sqrt(Q);
  if (derivs) {
    // η = √Q, ∇η = ∇Q / (2η), ∇²η = ∇²Q/(2η) − ∇Q∇Qᵀ/(4η³), with ∇Q = ¼ Σ ∇η_k².
    const Vec3 gQ = 0.25 * gsum;
    const Mat3 HQ = 0.25 * Hsum;
    if (grad) *grad = gQ / (2.0 * r.eta);
    if (hess) *hess = HQ / (2.0 * r.eta) - gQ * gQ.transpose() / (4.0 * r.eta * r.eta * r.eta);
  }
  return r;
}

void chainToSurface(const SurfaceD2& d, const Vec3& g, const Mat3& H, Vec2* gu, Mat2* Hu) {
  Eigen::Matrix<double, 3, 2> Jp;
  Jp.col(0) = d.du;
  Jp.col(1) = d.dv;
  if (gu) *gu = Jp.transpose() * g;
  if (Hu) {
    Mat2 h = Jp.transpose() * H * Jp;
    h(0, 0) += g.dot(d.duu);
    h(0, 1) += g.dot(d.duv);
    h(1, 0) += g.dot(d.duv);
    h(1, 1) += g.dot(d.dvv);
    *Hu = h;
  }
}

void chainToCurve(const CurveD2& d, const Vec3& g, const Mat3& H, double* gt, double* Ht) {
  if (gt) *gt = d.dt.dot(g);
  if (Ht) *Ht = d.dt.dot(H * d.dt) + g.dot(d.dtt);
}

void elementShapeValues(ElementType t, double a, double b, double* N) {
  if (t == ElementType::Quad4) {
    N[0] = (1 - a) * (1 - b);
    N[1] = a * (1 - b);
    N[2] = a * b;
    N[3] = (1 - a) * b;
    return;
  }
  if (t == ElementType::Quad8) {
    quad8ShapeValues(a, b, N);
    return;
  }
  lagrangeTriangle(elementOrder(t)).shape(Eigen::Vector2d(a, b), N);
}

Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e) {
  return elementReferenceNormal(mesh, e, mesh.surfaces);
}

Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e,
                            const std::vector<const Surface*>& surfaces) {
  return elementReferenceNormal(mesh, e, surfaces, nullptr);
}

Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e,
                            const std::vector<const Surface*>& surfaces, Vec3* cornerNormals) {
  const int f = mesh.elemFace[e];
  const int nc = cornerCount(mesh.elemType[e]);
  const Vec2* uv = mesh.elementUV(e);
  const Surface& s = *surfaces[static_cast<std::size_t>(f)];
  const int o =
      mesh.faceOrientation.empty() ? 1 : mesh.faceOrientation[static_cast<std::size_t>(f)];
  // mesh.referenceNormal(f, c) on `surfaces`.
  auto referenceNormal = [&](const Vec2& c) { return Vec3((o * s.normal(c.x(), c.y())).eval()); };
  Vec3 n = Vec3::Zero();
  bool anyCorner = false;
  for (int k = 0; k < nc; ++k) {
    const Vec3 nk = referenceNormal(uv[k]);
    if (cornerNormals) cornerNormals[k] = nk;
    anyCorner = anyCorner || nk.squaredNorm() > 0.0;
    n += nk;
  }
  if (anyCorner && n.squaredNorm() < kNormalCancelTol * kNormalCancelTol) return Vec3::Zero();
  if (!anyCorner) {
    // Every corner without a normal (at a pole, or within its band: elements smaller than
    // kPoleNormalTol of the parameter range around a tip): the normal at the parametric
    // centroid, or across the singular line on the centroid's meridian. Gmsh's curvature-
    // sized meshes put elements of 5e-7 around B-spline cone tips (nist_pmi_2), which with no
    // normal at all were counted tangled however they were wound.
    Vec2 c = Vec2::Zero();
    for (int k = 0; k < nc; ++k) c += uv[k];
    n = mesh.referenceNormalAcrossPole(f, c / nc, s);
  }
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

void elementNodeNormals(const SurfaceMesh& mesh, std::size_t e,
                        const std::vector<const Surface*>& surfaces, Vec3* nodeNormals) {
  const int f = mesh.elemFace[e];
  const Vec2* uv = mesh.elementUV(e);
  const Surface& s = *surfaces[static_cast<std::size_t>(f)];
  const int o =
      mesh.faceOrientation.empty() ? 1 : mesh.faceOrientation[static_cast<std::size_t>(f)];
  bool any = false;
  for (int k = 0; k < mesh.elementSize(e); ++k) {
    nodeNormals[k] = Vec3((o * s.normal(uv[k].x(), uv[k].y())).eval());
    any = any || nodeNormals[k].squaredNorm() > 0.0;
  }
  if (any) return;
  // No node with a normal (the element inside a pole's band): every node takes the element's
  // reference normal, taken across the singular line (elementReferenceNormal).
  const Vec3 n = elementReferenceNormal(mesh, e, surfaces);
  for (int k = 0; k < mesh.elementSize(e); ++k) nodeNormals[k] = n;
}

bool curvedTriangleAlongFace(const SurfaceMesh& mesh, std::size_t e, const Surface& s,
                             const Vec3* x, const Vec3* nodeNormals, const Vec2* uv) {
  const int order = elementOrder(mesh.elemType[e]);
  const LagrangeTriangle& L = lagrangeTriangle(order);
  const int nn = L.nodeCount();
  const FaceNormalAt normalAt = [&](const Eigen::Vector2d& xi) {
    double N[kMaxElementNodes];
    L.shape(xi, N);
    Vec2 c = Vec2::Zero();
    for (int i = 0; i < nn; ++i) c += N[i] * uv[i];
    // Inside a pole's band: the normal on this point's meridian across the singular line.
    return mesh.referenceNormalAcrossPole(mesh.elemFace[e], c, s);
  };
  return triangleJacobianPositiveOnPieces(order, x, nodeNormals, normalAt);
}

CornerSides cornerSides(ElementType type, const Vec3* x, const Vec3* cornerNormals) {
  const int nc = cornerCount(type);
  CornerSides r;
  for (int k = 0; k < nc; ++k) {
    const Vec3& n = cornerNormals[k];
    if (!(n.squaredNorm() > 0.0)) continue;
    Vec3 c;
    if (type == ElementType::Tri3) {
      c = (x[1] - x[0]).cross(x[2] - x[0]);
    } else if (type == ElementType::Quad4) {
      c = (x[(k + 1) % 4] - x[k]).cross(x[(k + 3) % 4] - x[k]);
    } else if (type == ElementType::Quad8) {
      const Jacobian32 J = quad8JacobianAtNode(x, k);
      c = J.col(0).cross(J.col(1));
    } else {
      // A high-order triangle's tangent plane at a corner: its Jacobian there (the corners
      // alone, not every node and quadrature point as highOrderJacobians).
      const Jacobian32 J = highOrderJacobianAtNode(type, x, k);
      c = J.col(0).cross(J.col(1));
    }
    if (c.dot(n) > 0.0)
      r.along = true;
    else
      r.against = true;
  }
  return r;
}

bool standsEdgeOn(ElementType type, const Vec3* x, const Vec3* cornerNormals) {
  if (type != ElementType::Tri3) return false;
  const Vec3 c = (x[1] - x[0]).cross(x[2] - x[0]);
  const double cn = c.norm();
  if (!(cn > 0.0)) return false;
  bool any = false;
  for (int k = 0; k < 3; ++k) {
    const Vec3& n = cornerNormals[k];
    if (!(n.squaredNorm() > 0.0)) continue;
    any = true;
    if (!(kEdgeOnSlope * std::abs(c.dot(n)) < cn * n.norm())) return false;
  }
  return any;
}

bool standsAcross(ElementType type, const Vec3* x, const Vec3* cornerNormals) {
  const CornerSides s = cornerSides(type, x, cornerNormals);
  return s.along && s.against;
}

}  // namespace surfmesh
