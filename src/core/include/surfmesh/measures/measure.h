// SurfMesh — planar distortion measures as pluggable units (after MFEM TMOP and Verdict).
//
// A measure is a function η(S) of the 2×2 Jacobian S = Dφ of the affine map from the ideal
// element to the physical element (Knupp, "Algebraic mesh quality metrics", SIAM J. Numer. Anal.
// 2001). η ≥ 1, η = 1 on the ideal element, η = ∞ when the element is degenerate or tangled
// (σ = det S ≤ 0). The quality is q = 1/η ∈ [0, 1].
//
// Untangling (Escobar et al., CMAME 2003): evaluated with δ > 0, σ is replaced by
//     σ*(σ; δ) = (σ + √(σ² + 4δ²)) / 2 > 0,
// which makes η finite and smooth for every S, so that a tangled element can be optimized.
// With δ = 0 the measure is the original barrier: +∞ for σ ≤ 0.
//
// Every measure implemented here is rotation invariant and written in terms of the two
// invariants F = ‖S‖²_F and σ = det S; its class supplies h(F, σ*) and the partial derivatives,
// and the base class turns them into the gradient and the Hessian with respect to S.
#pragma once

#include <Eigen/Dense>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace surfmesh {

using Mat2 = Eigen::Matrix2d;
/// Hessian with respect to S, indexed by the row-major flattening (S00, S01, S10, S11).
using Mat4 = Eigen::Matrix4d;

/// Value and derivatives of h(F, σ) with respect to F = ‖S‖² and σ = det S (σ already carries
/// the regularization: partials are with respect to the raw σ).
struct InvariantDerivs {
  double h = 0.0;
  double hF = 0.0, hs = 0.0;
  double hFF = 0.0, hFs = 0.0, hss = 0.0;
};

/// σ*(σ; δ) = (σ + √(σ² + 4δ²))/2 and its first two derivatives in σ. For δ = 0: σ*, 1, 0.
struct RegularizedSigma {
  double value, d1, d2;
};
inline RegularizedSigma regularizedSigma(double sigma, double delta) {
  if (delta == 0.0) return {sigma, 1.0, 0.0};
  const double r = std::sqrt(sigma * sigma + 4.0 * delta * delta);
  // (σ + r)/2 written without cancellation for σ < 0.
  const double s = sigma >= 0.0 ? 0.5 * (sigma + r) : 2.0 * delta * delta / (r - sigma);
  return {s, s / r, 2.0 * delta * delta / (r * r * r)};
}
/// σ*(σ; δ) alone.
inline double regularizedSigmaValue(double sigma, double delta) {
  if (delta == 0.0) return sigma;
  const double r = std::sqrt(sigma * sigma + 4.0 * delta * delta);
  return sigma >= 0.0 ? 0.5 * (sigma + r) : 2.0 * delta * delta / (r - sigma);
}

class PlanarMeasure {
 public:
  virtual ~PlanarMeasure() = default;
  /// Registry name ("shape", "oddy").
  virtual std::string name() const = 0;
  /// Formula and reference, for documentation and the GUI.
  virtual std::string description() const = 0;
  /// Whether evaluate() can fill a Hessian (a measure without one is used by gradient steps).
  virtual bool hasHessian() const { return true; }
  /// Whether η(λS) = η(S) for λ > 0 (with δ = 0).
  virtual bool scaleInvariant() const { return true; }

  /// η(S) (with σ → σ* when δ > 0). Returns +∞ when δ = 0 and σ ≤ 0. Never throws, never NaN
  /// for finite S.
  double value(const Mat2& S, double delta) const;

  /// η(S), and when non-null ∂η/∂S (2×2) and ∂²η/∂S² (4×4, row-major flattening).
  /// For δ = 0 and σ ≤ 0 returns +∞ and leaves grad/hess untouched.
  double evaluate(const Mat2& S, double delta, Mat2* grad, Mat4* hess) const;

  /// h and its partials at F = ‖S‖², σ = det S (raw), with s = σ*(σ; δ) > 0 given with its
  /// derivatives. Elements on surfaces are evaluated through this (the measures are rotation
  /// invariant, so η depends on the element's plane only through F and σ).
  virtual InvariantDerivs invariants(double F, double sigma, const RegularizedSigma& s) const = 0;
  /// h alone (s = σ* > 0): what line-search trials need.
  virtual double invariantValue(double F, double sigma, double s) const {
    return invariants(F, sigma, {s, 1.0, 0.0}).h;
  }
};

/// Shape distortion (Knupp 2001; paper eq. 20): η = ‖S‖² / (2σ), σ → σ* for untangling.
/// Equals the inverse of Verdict's tri_shape on triangles (4√3·A / Σ l²) and of the mean
/// ratio; η = 1 exactly on similarity transforms of the ideal element.
class ShapeMeasure final : public PlanarMeasure {
 public:
  std::string name() const override { return "shape"; }
  std::string description() const override;

  InvariantDerivs invariants(double F, double sigma, const RegularizedSigma& s) const override;
  double invariantValue(double F, double sigma, double s) const override;
};

/// Oddy distortion (Oddy et al. 1988; Knupp 2001; paper eq. 22):
///     η = (3/2) σ⁻² (‖SᵀS‖² − ⅓‖S‖⁴),
/// which for 2×2 matrices (‖SᵀS‖² = ‖S‖⁴ − 2σ²) is η = (‖S‖⁴ − 3σ²)/σ². σ → σ* in the
/// denominator for untangling. η = 1 on similarity transforms of the ideal element.
class OddyMeasure final : public PlanarMeasure {
 public:
  std::string name() const override { return "oddy"; }
  std::string description() const override;

  InvariantDerivs invariants(double F, double sigma, const RegularizedSigma& s) const override;
  double invariantValue(double F, double sigma, double s) const override;
};

/// A measure with the size of the ideal element added: η' = η · (σ* + 1/σ*)/2, 1 exactly when
/// S is a rotation (the element is the ideal one, moved). For an ideal of the element's own
/// size (a high-order triangle against its straight-sided triangle, straightSidedTarget), so
/// that a curved element's det J stays near its straight-sided one's: the Jacobian ratio a FEM
/// check reads. Not registered (its ideal must have the element's size).
class SizedMeasure final : public PlanarMeasure {
 public:
  explicit SizedMeasure(const PlanarMeasure& base) : base_(base) {}
  std::string name() const override { return base_.name() + "+size"; }
  std::string description() const override;
  bool hasHessian() const override { return base_.hasHessian(); }
  bool scaleInvariant() const override { return false; }
  InvariantDerivs invariants(double F, double sigma, const RegularizedSigma& s) const override;
  double invariantValue(double F, double sigma, double s) const override;

 private:
  const PlanarMeasure& base_;
};

/// Names of every registered measure, in registration order.
std::vector<std::string> measureNames();
/// The measure registered under `name`; throws std::invalid_argument listing the known names.
const PlanarMeasure& measureByName(const std::string& name);

/// Inverse of the ideal-element matrix W for an equilateral triangle: the ideal triangle is
/// (0,0), (1,0), (1/2, √3/2), W = [[1, 1/2], [0, √3/2]], and S = A W⁻¹ with A = [y1−y0, y2−y0].
const Mat2& equilateralWinv();
/// W⁻¹ = I for the right-angled corner of the ideal square (quadrilaterals).
const Mat2& squareCornerWinv();

}  // namespace surfmesh
