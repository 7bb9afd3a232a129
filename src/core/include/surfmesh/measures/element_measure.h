// SurfMesh — distortion of elements whose nodes lie on a surface (paper section 3).
//
// A linear triangle t_Σ = (x0, x1, x2) is mapped to its own plane by T (eq. 6–7):
//     e1 = x2 − x1, e2 = x0 − x1, ẽ1 = e1/‖e1‖, ẽ2,0 = (e2 − (e2·ẽ1)ẽ1)/‖…‖, ẽ2 = γ ẽ2,0,
//     γ = sign((ẽ1 × ẽ2,0) · n),   T(x) = [ẽ1 ẽ2]ᵀ (x − x1),
// so that y1 = (0,0), y2 = (‖e1‖, 0), y0 = (e2·ẽ1, γ‖e2 − (e2·ẽ1)ẽ1‖). The planar measure is
// then applied to (y0, y1, y2): S = [y1 − y0, y2 − y0] W⁻¹. A triangle whose orientation
// disagrees with the reference normal n has σ < 0: it is tangled.
//
// The reference normal n of an element is the normalized sum of the reference (outward) normals
// of its face at its corners, skipping corners where the parameterization is degenerate
// (poles). Elements store these corner normals so that the same n is used by the quality report
// and by the optimizer. Where that n is ill-defined (corner normals that cancel) or the element
// stands across it (its plane contains n), the element is tangled: see kNormalCancelTol and
// orientationDefined().
//
// The restricted measure (paper Remark 1, eq. 12–13) is the distortion as a function of one
// free node; its gradient and Hessian with respect to that node's position are exact, and
// chain rules carry them to the node's (u,v) on its surface or to its t on a curve.
#pragma once

#include "surfmesh/geometry/curve.h"
#include "surfmesh/geometry/surface.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/surface_mesh.h"

namespace surfmesh {

/// An element's orientation against its reference normal n is decided only when it is clear:
/// the element plane's normal c must not be perpendicular to n within kPerpendicularTol
/// (|c·n| > kPerpendicularTol ‖c‖ ‖n‖); otherwise the element counts as degenerate (σ = 0,
/// tangled). Without this margin the verdict on an element standing across its surface would
/// hang on rounding, and the optimizer (which updates corner normals as nodes move) and the
/// quality report could disagree on it — then a "valid" element could be flattened in
/// monotone mode. `cDotN` = c·n, `cNorm2` = ‖c‖², `nNorm2` = ‖n‖².
constexpr double kPerpendicularTol = 1e-9;
inline bool orientationDefined(double cDotN, double cNorm2, double nNorm2) {
  return cDotN * cDotN > (kPerpendicularTol * kPerpendicularTol) * cNorm2 * nNorm2;
}

/// The corner normals of an element (unit vectors, zero at poles) cancel when their sum is
/// shorter than this: the element spans opposite sides of its surface and has no reference
/// normal (zero, so it counts as tangled).
constexpr double kNormalCancelTol = 1e-6;

/// Result of one element evaluation.
struct ElementEval {
  double eta = 1.0;       ///< distortion (δ-regularized when δ > 0); +∞ when tangled and δ = 0
  double minSigma = 0.0;  ///< smallest det S over the element's sub-triangles / quadrature points,
                          ///< scaled to be dimensionless (det S / (element size)²)
  bool tangled = false;   ///< minSigma ≤ 0 (tangled or degenerate)
};

/// 3×2 Jacobian of an element's map from reference coordinates to R³ (columns: ∂x/∂ξ, ∂x/∂η).
using Jacobian32 = Eigen::Matrix<double, 3, 2>;

/// [w]×ᵀ (I − ν νᵀ) [w]× = ‖w‖² I − w wᵀ − (ν × w)(ν × w)ᵀ, from w and mw = ν × w: the
/// curvature of an element plane's ‖J₁ × J₂‖ as one node moves (w the opposite side's
/// direction as it enters J₁ × J₂, ν the plane's unit normal), without the two 3 × 3 products.
inline Mat3 crossProjected(const Vec3& w, const Vec3& mw) {
  Mat3 Q = -w * w.transpose() - mw * mw.transpose();
  Q.diagonal().array() += w.squaredNorm();
  return Q;
}

/// The distortion at one Jacobian J of a (possibly curved) element: S = T J W⁻¹ where T maps
/// the plane spanned by J to R² oriented by n, so η = h(F, σ) with F = ‖J W⁻¹‖²,
/// σ = γ‖J₁ × J₂‖ det W⁻¹, γ = sign((J₁ × J₂)·n).
/// When `b` is non-null, J depends on one free node x through J = J⁰ + x bᵀ (b = the node's
/// reference-gradient of its shape function, 2-vector) and grad/hess receive ∂η/∂x and
/// ∂²η/∂x² (exact; the Hessian term ∝ 1/‖J₁ × J₂‖ is dropped for degenerate J, where the
/// in-surface direction n is used for the orientation instead).
/// `minSigma` of the result is the signed shape quality 2σ/F ∈ [−1, 1] (≤ 0: tangled).
/// `eta0`, when non-null, receives η with δ = 0 at the same J (+∞ when tangled): what an
/// untangling sweep also needs, without a second evaluation.
ElementEval jacobianDistortion(const PlanarMeasure& m, const Jacobian32& J, const Mat2& Winv,
                               const Vec3& n, double delta, const Eigen::Vector2d* b, Vec3* grad,
                               Mat3* hess, double* eta0 = nullptr);

/// The validity part of jacobianDistortion alone (no measure evaluated): `minSigma` and
/// `tangled` as there, `eta` left at 1.
ElementEval jacobianValidity(const Jacobian32& J, const Mat2& Winv, const Vec3& n);

/// Distortion of the linear triangle (x0, x1, x2) with reference normal n (any length > 0),
/// ideal element given by Winv. When grad/hess are non-null, also the gradient (3) and Hessian
/// (3×3) with respect to x0 (the free node). A degenerate triangle (zero area or zero edge) is
/// tangled; with δ > 0 it still gets a finite value and derivatives.
ElementEval triangleDistortion(const PlanarMeasure& m, const Vec3& x0, const Vec3& x1,
                               const Vec3& x2, const Vec3& n, double delta, const Mat2& Winv,
                               Vec3* grad = nullptr, Mat3* hess = nullptr, double* eta0 = nullptr);

/// Distortion of any supported element. `x` holds the element's node positions (Gmsh order),
/// `n` its reference normal (see elementReferenceNormal()). When `freeLocal`
/// is ≥ 0 and grad/hess are non-null, fills the derivatives with respect to x[freeLocal].
///   Tri3       — triangleDistortion with the equilateral ideal;
///   Quad4      — the four corner triangles with the square corner as ideal (Knupp):
///                η = (¼ Σ_k η_k²)^½, tangled when any corner is;
///   Tri6…Tri21 — paper Definition 4: η̂ = (∫ η² / |t|)^½ by quadrature over the element,
///                tangled when det S ≤ 0 at any quadrature point;
///   Quad8      — the same over the unit square with the square as ideal (quad8Distortion).
/// `eta0`, when non-null, receives the element's η with δ = 0 (+∞ when tangled), from the same
/// Jacobians as η (one pass instead of two).
/// `target`: a high-order triangle's ideal, as highOrderTriangleDistortion's (ignored for the
/// other types).
ElementEval elementDistortion(const PlanarMeasure& m, ElementType type, const Vec3* x,
                              const Vec3& n, double delta, int freeLocal = -1, Vec3* grad = nullptr,
                              Mat3* hess = nullptr, double* eta0 = nullptr,
                              const Mat2* target = nullptr);

/// Quad4 implementation of elementDistortion (see above).
ElementEval quadDistortion(const PlanarMeasure& m, const Vec3* x, const Vec3& n, double delta,
                           int freeLocal, Vec3* grad, Mat3* hess, double* eta0 = nullptr);
/// Quad8 (serendipity quadrilateral) implementation of elementDistortion: the pointwise
/// distortion of S = T J(ξ) W⁻¹ on the unit square (W = I, the square), η̂ = (Σ_q w_q η_q²)^½
/// over the 3 × 3 Gauss points; tangled when det S ≤ 0 at a Gauss point or at any of its 8
/// nodes, or when the determinant is not proven positive on the whole square (Bernstein
/// coefficients of (J₁ × J₂)·n, refined by subdivision). A parallelogram with its side nodes at the
/// midpoints has the quality of the quad4 on its corners (element_quad8.cpp).
ElementEval quad8Distortion(const PlanarMeasure& m, const Vec3* x, const Vec3& n, double delta,
                            int freeLocal, Vec3* grad, Mat3* hess, double* eta0 = nullptr);
/// The Jacobian of the quad8 with nodes x (Gmsh order) from the unit square at its node k.
Jacobian32 quad8JacobianAtNode(const Vec3* x, int k);
/// The gradients (∂/∂s, ∂/∂t) of the 8 quad8 shape functions at (s, t) ∈ [0, 1]² (grad[8]).
void quad8ShapeGradients(double s, double t, Eigen::Vector2d* grad);
/// The values of the 8 quad8 shape functions at (s, t) ∈ [0, 1]² (N[8]).
void quad8ShapeValues(double s, double t, double* N);
/// The shape functions' values N[nodeCount(t)] of element type t at the reference point
/// (a, b): a triangle's (ξ, η) in Gmsh's reference triangle (Lagrange of its order), a
/// quadrilateral's (s, t) ∈ [0, 1]² (bilinear for quad4, serendipity for quad8).
void elementShapeValues(ElementType t, double a, double b, double* N);
/// High-order triangle implementation of elementDistortion (see above).
/// `target` as in the overload from precomputed Jacobians below.
ElementEval highOrderTriangleDistortion(const PlanarMeasure& m, ElementType type, const Vec3* x,
                                        const Vec3& n, double delta, int freeLocal, Vec3* grad,
                                        Mat3* hess, double* eta0 = nullptr,
                                        const Mat2* target = nullptr);

/// Most quadrature points of a high-order triangle's rule (Dunavant's degree 10, order 5).
constexpr int kMaxQuadraturePoints = 25;

/// A high-order triangle's Jacobians J(ξ) = Σ_i x_i ∇N_i(ξ)ᵀ at its nodes and at its quadrature
/// points, with the term of one free node left out (all terms when freeLocal < 0). A line search
/// that moves that node alone then evaluates the element in O(points) instead of
/// O(points × nodes): J = J_rest + x ∇N_free(ξ)ᵀ.
struct HighOrderJacobians {
  ElementType type = ElementType::Tri6;
  int freeLocal = -1;
  Jacobian32 atNode[kMaxElementNodes];
  Jacobian32 atPoint[kMaxQuadraturePoints];
};

/// Fills `out` for the high-order triangle with nodes x (Gmsh order) and free node
/// `freeLocal` (< 0: none). Throws std::invalid_argument for a quadrilateral.
void highOrderJacobians(ElementType type, const Vec3* x, int freeLocal, HighOrderJacobians* out);

/// The Jacobian J(ξ_k) = Σ_i x_i ∇N_i(ξ_k)ᵀ of the high-order triangle with nodes x (Gmsh order)
/// at its own node k alone. Throws std::invalid_argument for a quadrilateral.
Jacobian32 highOrderJacobianAtNode(ElementType type, const Vec3* x, int k);

/// highOrderTriangleDistortion with the free node (pre.freeLocal) at xFree and the other nodes
/// as in `pre`; derivatives with respect to the free node (none when pre.freeLocal < 0).
/// `target`: W⁻¹ of the element's ideal (its Jacobians measured as S = T J W⁻¹, by the
/// measure with the size term, SizedMeasure), the equilateral triangle's (by `m` alone) when
/// null; straightSidedTarget gives the reference mode's.
ElementEval highOrderTriangleDistortion(const PlanarMeasure& m, const HighOrderJacobians& pre,
                                        const Vec3& xFree, const Vec3& n, double delta, Vec3* grad,
                                        Mat3* hess, double* eta0 = nullptr,
                                        const Mat2* target = nullptr);

/// W⁻¹ of the straight-sided triangle on corners (x0, x1, x2) (the reference triangle's
/// corners (0,0), (1,0), (0,1) in that order): W is the triangle in its own plane, W = [a b]
/// in an orthonormal basis of the plane with a = x1 − x0 along its first axis and b = x2 − x0
/// on the side of positive det W. Measured against it, a high-order triangle with those
/// corners and its other nodes where the affine map puts them has η = 1 at every point (the
/// shape and Oddy measures are invariant under scaling and rotation), so curving is what the
/// surface asks for. With a target the measure also weighs the size (SizedMeasure), so that
/// det J stays near the straight-sided triangle's. False (and `Winv` untouched) when that
/// triangle is degenerate or wound against n (any length).
bool straightSidedTarget(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& n, Mat2* Winv);

/// Carries a gradient g (3) and Hessian H (3×3) in x to the surface parameters (u,v) through
/// x = φ(u,v): g_u = Jᵀ g, H_u = Jᵀ H J + Σ_m g_m ∇²φ_m, with J = [φ_u φ_v].
void chainToSurface(const SurfaceD2& d, const Vec3& g, const Mat3& H, Vec2* gu, Mat2* Hu);

/// Same through x = C(t): g_t = C'·g, H_t = C'ᵀ H C' + g·C''.
void chainToCurve(const CurveD2& d, const Vec3& g, const Mat3& H, double* gt, double* Ht);

/// Reference normal of element e of `mesh`: normalized sum over its corners of
/// mesh.referenceNormal(face, cornerUV), skipping degenerate corners; the normal at the
/// parametric centroid if every corner is degenerate. Zero when the corner normals cancel
/// (their sum shorter than kNormalCancelTol) or the centroid is degenerate too.
Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e);
/// The same with the surfaces taken from `surfaces` (face id → surface) instead of
/// mesh.surfaces: per-thread clones (surfaces are not thread-safe).
Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e,
                            const std::vector<const Surface*>& surfaces);
/// The same, also writing the corner normals it sums (mesh.referenceNormal at each corner's
/// (u,v), zero at poles) to cornerNormals[0 … cornerCount − 1].
Vec3 elementReferenceNormal(const SurfaceMesh& mesh, std::size_t e,
                            const std::vector<const Surface*>& surfaces, Vec3* cornerNormals);

/// Whether high-order triangle e of `mesh`, with nodes x, has its Jacobian positive against its
/// face's normals over the whole element (certificate.h, triangleJacobianPositiveOnPieces):
/// nodeNormals are the face's normals at its nodes (elementNodeNormals'), and inside, the
/// face's normal is mesh.referenceNormal at the element's map in (u,v) from uv[0 … k − 1], its
/// nodes' (u,v) on its face (unwrapped alike). `s` is the calling thread's copy of the face's
/// surface.
bool curvedTriangleAlongFace(const SurfaceMesh& mesh, std::size_t e, const Surface& s,
                             const Vec3* x, const Vec3* nodeNormals, const Vec2* uv);

/// The face's unit normals (mesh.referenceNormal, zero at a pole) at every node of element e,
/// at the node's (u,v) in e, written to nodeNormals[0 … elementSize − 1]; surfaces as above.
void elementNodeNormals(const SurfaceMesh& mesh, std::size_t e,
                        const std::vector<const Surface*>& surfaces, Vec3* nodeNormals);

/// Whether an element with nodes x (Gmsh order) stands across its surface: its own plane — a
/// linear triangle's plane, a quad4's corner triangle, a high-order triangle's or a quad8's
/// tangent plane at a corner node — is wound along the surface's normal cornerNormals[k] at some of
/// its corners k and against it (c·n_k ≤ 0) at others (zero normals, at poles, are skipped). E.g. a
/// triangle spanning more than half the way round a thin tube, whose plane cuts through the
/// part: a mesh coarse against the surface's curvature, or folded across it. The measure
/// orients an element by the sum of its corner normals and takes a linear one in its own plane
/// (the paper's definition), so it calls such an element valid when the sum says so, and may
/// find it well shaped. Gmsh's own meshes of CAD parts have some (at small fillets and holes).
bool standsAcross(ElementType type, const Vec3* x, const Vec3* cornerNormals);

/// Which ways the element's plane (as in standsAcross) is wound against the surface's normal
/// at its corners: along it (c·n_k > 0) at some corner, against it (c·n_k ≤ 0) at some corner.
/// Neither when every corner normal is zero. standsAcross is along && against.
struct CornerSides {
  bool along = false;
  bool against = false;
};
CornerSides cornerSides(ElementType type, const Vec3* x, const Vec3* cornerNormals);

/// A linear triangle whose plane stands edge-on to its surface: at every corner with a normal
/// (one at least), its plane leans more than acos(1/kEdgeOnSlope) ≈ 84° from the surface's
/// normal (|c·n_k| < ‖c‖ / kEdgeOnSlope, c = (x1 − x0) × (x2 − x0)). Its winding against the
/// surface is then a matter of rounding (standsAcross cannot tell) and the face it lies on is
/// doubtful: a triangle on a cylinder whose corners slid along the circle it ends on can lie
/// flat in the end cap's plane. The report does not count it; a run may not make a triangle
/// so (MeshQuality::grade, keepValidElements). False for other element types. The optimizer's
/// hold against leaning across (acrossArea, kAcrossSlope) takes the same angle.
constexpr double kEdgeOnSlope = 10.0;
bool standsEdgeOn(ElementType type, const Vec3* x, const Vec3* cornerNormals);

}  // namespace surfmesh
