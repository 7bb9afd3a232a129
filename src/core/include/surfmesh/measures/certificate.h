// SurfMesh — a proof of the sign of a curved triangle's Jacobian.
//
// The map a FEM solver uses for a Lagrange triangle of order p with 3D nodes x_i (Gmsh order,
// lagrange_triangle.h) is x(ξ) = Σ_i x_i N_i(ξ) on the reference triangle ξ = (ξ, η) ∈
// {ξ ≥ 0, η ≥ 0, ξ + η ≤ 1}. The element is valid when
//     D(ξ) = det J(ξ) = (x_ξ × x_η) · n > 0   on the WHOLE reference triangle,
// n being the element's fixed reference normal. D is a polynomial of total degree 2(p − 1)
// (x_ξ and x_η have degree p − 1), so it has exact coefficients in the triangular Bernstein
// basis B_{ijk} = d!/(i! j! k!) λ0^i λ1^j λ2^k of degree d = 2(p − 1). Bernstein polynomials
// are ≥ 0 and sum to 1, so min D ≥ min coefficient, and the coefficients at the three corners
// are D's values there; subdividing the triangle (de Casteljau) gives each piece its own
// coefficients, which converge to D's values (Johnen, Remacle, Geuzaine, "Geometrical validity
// of curvilinear finite elements", JCP 233, 2013; Gmsh's Numeric/bezierBasis, JacobianBasis).
//
// The certificate (certificate.cpp): D's Bernstein coefficients computed exactly from the
// element's Bézier control points (products of Bernstein polynomials, no sampling); then the
// triangle is bisected at the midpoint of a piece's longest edge (one de Casteljau pyramid
// gives both halves), depth first, the half with the smaller coefficient first:
//   - a piece whose coefficients are all > τ is proven valid;
//   - a point with D ≤ τ (a piece's corner, or the domain point of a piece's smallest
//     coefficient, each re-evaluated from the nodes) proves the element invalid;
//   - pieces still undecided after 2 kCertificateMaxDepth bisections (kCertificateMaxDepth
//     splits in four), or beyond kCertificateMaxPieces pieces, leave the verdict Undecided,
//     which callers must treat as invalid.
// τ = kPerpendicularTol ‖n‖ max_α ‖a_α‖ max_β ‖b_β‖, a_α and b_β the Bézier coefficients of
// x_ξ and x_η, which bound ‖x_ξ‖ and ‖x_η‖ on the whole triangle: the same relative margin as
// orientationDefined() (|c·n| > 1e-9 ‖c‖ ‖n‖ with ‖c‖ ≤ ‖x_ξ‖ ‖x_η‖), so a determinant that is
// zero within rounding (a side node exactly at the quarter point) counts as a fold, not as
// valid, and the verdict does not hang on the last bits.
//
// The reference normal n and poles / degenerate parametrizations. The certificate needs only
// the nodes' 3D positions and the direction n; it never evaluates the surface, so a node at a
// pole or on a degenerate edge of the parametrization is an ordinary point. n is the element's
// reference normal as the distortion measures use it (elementReferenceNormal in
// element_measure.h): the normalized sum of the face's outward normals at the element's
// corners, where a corner at a pole (degenerate parametrization, no normal) contributes none
// (zero), and the normal at the parametric centroid is used when every corner is degenerate.
// When the corner normals cancel (their sum shorter than kNormalCancelTol) that n is zero: then
// D ≡ 0 and the certificate returns NonPositive (value 0 at the centroid) — the element is
// invalid, as it is tangled for the measures. A non-finite node or normal gives Undecided.
//
// Against the surface. The reference normal is one direction for the whole element; where the
// face's normal turns within it (a blade, a fillet), D > 0 against the reference normal does not
// keep the element's tangent plane from turning across the surface's inside the element (it is
// then wound against the surface there: "standing across" at an interior point, where the
// corner test of standsAcross cannot see it). certifyTriangleAgainstNodeNormals proves instead
//     D_h(ξ) = (x_ξ × x_η) · n_h(ξ) > 0,  n_h(ξ) = Σ_i N_i(ξ) n_i,
// n_i the face's unit normal at node i's (u,v): the isoparametric interpolation of the CAD
// normals at the nodes (a shell element's director field). D_h is a polynomial of degree
// 3p − 2, certified by the same Bernstein expansion and subdivision. At the corners D_h is the
// corner test of standsAcross; n_h differs from the face's normal at the point by the
// interpolation error of degree p + 1 in the element's size. A node at a pole (where the face
// has no normal: zero) takes the direction of the sum of the other nodes' normals; zero normals
// everywhere make D_h ≡ 0, NonPositive. (Where the face's normal turns by a large angle within
// one element, n_h is a coarse picture of it: such an element is far too coarse for its face.)
//
// Order 1 (Tri3): D is the constant ((x1 − x0) × (x2 − x0)) · n, the plain orientation test.
// Quadrilaterals: quad4's D = (x_s × x_t)·n is affine in (s, t) (x_s × x_t has no st term),
// so its four corners decide it, which the corner triangles of quadDistortion already check;
// quad8's D is proven by its own tensor-product Bernstein certificate inside quad8Distortion
// (element_quad8.cpp). elementCertifiedValid() dispatches to those verdicts for quads rather
// than duplicating them; certifyElementJacobian() is for triangles only.
#pragma once

#include "surfmesh/measures/element_measure.h"

#include <Eigen/Dense>

#include <functional>
#include <limits>

namespace surfmesh {

/// Subdivision levels of the certificate (each as deep as a split in 4: two bisections), as
/// quad8's proof.
constexpr int kCertificateMaxDepth = 8;
/// Most pieces examined before giving up (Undecided): bounds the work on a determinant that
/// touches zero along a curve (a nearly degenerate element) to a few milliseconds.
constexpr int kCertificateMaxPieces = 8192;

/// The certificate's verdict on D = det J = (x_ξ × x_η)·n over the reference triangle.
enum class JacobianSign : int {
  Positive = 1,     ///< proven: D > τ everywhere (every coefficient of every piece > τ)
  NonPositive = 0,  ///< proven: D(point) ≤ τ at the returned point (evaluated from the nodes)
  Undecided = -1,   ///< neither within the depth / piece limits: treat as invalid
};

/// Name of a verdict: "positive", "non_positive", "undecided".
const char* jacobianSignName(JacobianSign s);

/// The certificate of one element, with diagnostics.
struct JacobianCertificate {
  JacobianSign sign = JacobianSign::Undecided;
  /// NonPositive: the reference point (ξ, η) where D ≤ τ was found; NaN otherwise.
  Eigen::Vector2d point = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  /// NonPositive: D at `point`, evaluated directly from the nodes; NaN otherwise.
  double value = std::numeric_limits<double>::quiet_NaN();
  /// Smallest Bernstein coefficient of D on the whole triangle (before any subdivision).
  double minCoefficient = std::numeric_limits<double>::quiet_NaN();
  /// Smallest D over the equispaced points of order d (a diagnostic: the verdict does not use
  /// them).
  double minSampled = std::numeric_limits<double>::quiet_NaN();
  /// minCoefficient / minSampled: 1 when the first expansion is already sharp, larger (or
  /// negative) when subdivision was needed (Johnen et al.'s measure of the bound's quality).
  double ratio = std::numeric_limits<double>::quiet_NaN();
  /// Positive: a proven lower bound of D (the smallest coefficient over the final pieces).
  double lowerBound = std::numeric_limits<double>::quiet_NaN();
  /// τ, the margin below which D counts as zero (see the file comment).
  double tolerance = 0.0;
  /// Deepest subdivision level reached, in splits in four (two bisections; a single bisection
  /// counts as 1); 0: the first expansion decided.
  int depth = 0;
  int pieces = 0;  ///< pieces whose coefficients were examined
};

/// D(ξ) = (x_ξ × x_η)·n at one reference point for the Lagrange triangle of order p (1…5) with
/// nodes x (Gmsh order).
double triangleJacobianDeterminant(int order, const Vec3* x, const Vec3& n,
                                   const Eigen::Vector2d& xi);

/// Certifies the sign of D over the whole reference triangle for the Lagrange triangle of
/// order p ∈ [1, 5] with nodes x (Gmsh order) against the direction n (see the file comment).
/// Throws std::invalid_argument for another order.
JacobianCertificate certifyTriangleJacobian(int order, const Vec3* x, const Vec3& n,
                                            int maxDepth = kCertificateMaxDepth);

/// D_h(ξ) = (x_ξ × x_η)·Σ_i N_i(ξ) n_i at one reference point (see the file comment).
double triangleJacobianAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals,
                                          const Eigen::Vector2d& xi);

/// Certifies the sign of D_h over the whole reference triangle for the Lagrange triangle of
/// order p ∈ [1, 5] with nodes x and the face's unit normals at its nodes (Gmsh order; zero at
/// a pole). τ = kPerpendicularTol max_α ‖a_α‖ max_β ‖b_β‖ max_δ ‖N_δ‖ (the Bézier coefficients
/// of x_ξ, x_η and n_h). Throws
/// std::invalid_argument for another order.
JacobianCertificate certifyTriangleAgainstNodeNormals(int order, const Vec3* x,
                                                      const Vec3* nodeNormals,
                                                      int maxDepth = kCertificateMaxDepth);

/// D's smallest Bernstein coefficient on the whole reference triangle (no subdivision),
/// computed exactly from the element's Bézier control points P_α (|α| = p): with λ = (1 − ξ − η, ξ,
/// η), x_ξ = Σ_{|α|=p−1} p (P_{α+e1} − P_{α+e0}) B_α and x_η = Σ p (P_{α+e2} − P_{α+e0}) B_α, and a
/// product of Bernstein polynomials is one,
///     Σ f_α B_α^m · Σ g_β B_β^n = Σ_γ (Σ_{α+β=γ} C(m,α) C(n,β) / C(m+n,γ) f_α g_β) B_γ^{m+n}
/// (C the multinomial coefficients): the certificate's first expansion, minCoefficient and τ.
/// minCoefficient > tolerance is the certificate's proof at depth 0. NaN when something is
/// not finite.
struct CoefficientBound {
  double minCoefficient = std::numeric_limits<double>::quiet_NaN();
  double tolerance = std::numeric_limits<double>::quiet_NaN();  ///< τ
};
CoefficientBound bezierCoefficientBound(int order, const Vec3* x, const Vec3& n);
/// The same for D_h against the nodes' normals (zero at a pole, as the certificate takes them).
CoefficientBound bezierCoefficientBoundAgainstNodeNormals(int order, const Vec3* x,
                                                          const Vec3* nodeNormals);

/// Whether certifyTriangleJacobian(order, x, n).sign is Positive (within its margin τ), for
/// callers that need the verdict alone (the same search, without the sampled diagnostics).
bool triangleJacobianPositive(int order, const Vec3* x, const Vec3& n);

/// The same for certifyTriangleAgainstNodeNormals.
bool triangleJacobianPositiveAgainstNodeNormals(int order, const Vec3* x, const Vec3* nodeNormals);

/// The node normals the certificate against them takes (out[0 … nn − 1]): a node at a pole
/// (zero normal) takes the direction of the others' sum. *sumNorm: the length of that sum;
/// false when a normal is not finite.
bool fillPoleNormals(const Vec3* in, int nn, Vec3* out, double* sumNorm);

/// Split depth of triangleJacobianPositiveOnPieces: at most 4^3 = 64 pieces.
constexpr int kFaceNormalPieceDepth = 3;

/// The face's unit normal (zero at a pole) at the point of the surface that an element's map
/// in (u,v) reaches at reference point ξ.
using FaceNormalAt = std::function<Vec3(const Eigen::Vector2d&)>;

/// Whether D against the face's own normals is positive on the whole triangle, where the
/// interpolation of its node normals (certifyTriangleAgainstNodeNormals) cannot tell: the face's
/// normal turns too fast within the element for one interpolation (a blade's tip, a B-spline
/// patch's nearly collapsed corner). The element is split in four at its reference midpoints,
/// recursively to `depth`; each piece is a Lagrange triangle of the same order (the element's
/// map restricted to it: exact), with the face's normals at its own nodes (`normalAt`), and
/// must be proven positive by the certificate against node normals. The interpolation error
/// falls as h^(p+1) with the piece's size h. True at once when the whole element is proven
/// positive against `nodeNormals`; false as soon as the search finds a point where D against
/// the face's own normal is not positive, or a piece at `depth` is not proven positive.
bool triangleJacobianPositiveOnPieces(int order, const Vec3* x, const Vec3* nodeNormals,
                                      const FaceNormalAt& normalAt,
                                      int depth = kFaceNormalPieceDepth);

/// certifyTriangleJacobian for a triangle type (Tri3, Tri6, Tri10, Tri15, Tri21). Throws
/// std::invalid_argument for a quadrilateral (see elementCertifiedValid).
JacobianCertificate certifyElementJacobian(ElementType type, const Vec3* x, const Vec3& n);

/// The certificate as the measures apply it to a high-order triangle (types Tri6 … Tri21) that
/// the sampled check (its nodes and quadrature points) found untangled, with nodes x and the
/// unit reference normal n of the evaluation: when D is not proven positive everywhere the
/// element is marked tangled as a fold the samples see is — r->tangled, r->minSigma ≤ 0, η = ∞
/// and the derivatives zero when δ = 0, *eta0 (η at δ = 0, when asked) = ∞. With δ > 0 and a
/// measure m, the fold is made visible to the untangling: the pointwise distortion at the
/// certificate's point ξ* (where D ≤ τ) joins the element's mean with the weight of one node,
///     η̂² ← η̂² + η*²/n_nodes,
/// and the gradient and Hessian with respect to node `freeLocal` (when asked; both need the
/// gradient) follow — so that Newton steps open a fold lying between the quadrature points.
/// Returns whether it marked the element. Nothing is done for another type or an element
/// already tangled. `target`: the ideal the fold's point is measured against, as
/// highOrderTriangleDistortion's (equilateral when null).
bool markUncertifiedFold(ElementType type, const Vec3* x, const Vec3& n, double delta,
                         ElementEval* r, Vec3* grad, Mat3* hess, double* eta0,
                         const PlanarMeasure* m = nullptr, int freeLocal = -1,
                         const Mat2* target = nullptr);

/// Whether the element's D is proven positive everywhere: triangles by the certificate
/// (Positive; NonPositive and Undecided are invalid), quad4 by its corner triangles (D affine in
/// (s, t)), quad8 by its own Bernstein certificate (quad8Distortion's tangled flag, which also
/// covers its nodes and Gauss points).
bool elementCertifiedValid(ElementType type, const Vec3* x, const Vec3& n);

}  // namespace surfmesh
