// SurfMesh — Lagrange triangles on equispaced nodes (p = 1…5) and symmetric triangle
// quadrature, for the distortion of high-order triangles (paper §5, Definition 4).
//
// Reference triangle: ξ = (ξ, η) ∈ {ξ ≥ 0, η ≥ 0, ξ + η ≤ 1}, corners (0,0), (1,0), (0,1),
// barycentric coordinates λ0 = 1 − ξ − η, λ1 = ξ, λ2 = η.
//
// Node ordering is Gmsh's (checked against gmsh.model.mesh.getElementProperties for
// tri6/tri10/tri15/tri21 in the tests): the 3 corners, then the p − 1 nodes of each edge
// 0→1, 1→2, 2→0 in that direction, then the interior nodes, which are themselves a triangle of
// order p − 3 with the same ordering (recursively) on the sub-triangle whose corners are
// (1/p, 1/p), (1 − 2/p, 1/p), (1/p, 1 − 2/p).
//
// Shape functions (Silvester's formula): the node with barycentric multi-index (i, j, k),
// i + j + k = p, has N = R_i(λ0) R_j(λ1) R_k(λ2) with R_m(λ) = Π_{s=0}^{m−1} (pλ − s)/(s + 1).
#pragma once

#include <Eigen/Dense>

#include <vector>

namespace surfmesh {

/// A symmetric quadrature rule on the reference triangle; the weights sum to 1 (they are
/// normalized by the reference area ½), so Σ w_q f(ξ_q) is the MEAN of f over the triangle.
struct TriangleQuadrature {
  int degree = 0;                       ///< polynomials of total degree ≤ degree are exact
  std::vector<Eigen::Vector2d> points;  ///< (ξ, η) of each point
  std::vector<double> weights;          ///< positive, Σ = 1
};

/// Dunavant's symmetric rules (IJNME 21, 1985), all points inside, all weights positive:
/// degree 1 (1 point), 2 (3), 4 (6), 6 (12), 8 (16), 10 (25). The orbit coordinates are
/// Dunavant's, refined by Newton's method on the moment equations to full double precision.
/// Returns the cheapest rule of degree ≥ `degree`; throws std::invalid_argument above 10.
const TriangleQuadrature& triangleQuadrature(int degree);

/// Equispaced Lagrange triangle of order p ∈ [1, 5] in Gmsh node ordering.
class LagrangeTriangle {
 public:
  /// Throws std::invalid_argument unless 1 ≤ order ≤ 5.
  explicit LagrangeTriangle(int order);

  int order() const { return p_; }
  /// (p + 1)(p + 2)/2.
  int nodeCount() const { return static_cast<int>(nodes_.size()); }
  /// Reference coordinates of the nodes, Gmsh ordering.
  const std::vector<Eigen::Vector2d>& nodes() const { return nodes_; }
  /// Barycentric multi-index (i, j, k) of each node: λ = (i, j, k)/p at the node.
  const std::vector<Eigen::Vector3i>& multiIndices() const { return index_; }

  /// Shape function values at ξ.
  /// @param[in]  xi  reference point
  /// @param[out] N   nodeCount() values (Σ N = 1)
  void shape(const Eigen::Vector2d& xi, double* N) const;

  /// Reference gradients at ξ.
  /// @param[in]  xi    reference point
  /// @param[out] grad  nodeCount() gradients (∂N/∂ξ, ∂N/∂η) (Σ = 0)
  void gradients(const Eigen::Vector2d& xi, Eigen::Vector2d* grad) const;

 private:
  int p_;
  std::vector<Eigen::Vector2d> nodes_;
  std::vector<Eigen::Vector3i> index_;
};

/// The shared LagrangeTriangle of order p (1…5).
const LagrangeTriangle& lagrangeTriangle(int order);

/// Everything the distortion of a high-order triangle of order p needs, precomputed once:
/// the quadrature rule of degree 2p (see high-order measure in element_measure.h) and the
/// reference gradients of every shape function at its points and at the element's nodes.
struct HighOrderTriangleRule {
  int order = 0;
  int nodes = 0;  ///< shape functions per element
  const TriangleQuadrature* quadrature = nullptr;
  /// gradAtPoint[q * nodes + i] = ∇N_i(ξ_q).
  std::vector<Eigen::Vector2d> gradAtPoint;
  /// gradAtNode[k * nodes + i] = ∇N_i(ξ_k) at the element's own node k.
  std::vector<Eigen::Vector2d> gradAtNode;
};

/// The shared rule for triangles of order p (1…5).
const HighOrderTriangleRule& highOrderTriangleRule(int order);

}  // namespace surfmesh
