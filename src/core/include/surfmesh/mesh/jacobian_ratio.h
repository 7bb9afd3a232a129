// SurfMesh — the Jacobian ratio of curved (and straight) elements: how much the map from the
// reference element stretches over the element.
#pragma once

#include "surfmesh/mesh/surface_mesh.h"

#include <vector>

namespace surfmesh {

/// Steps per side of the reference element at which elementJacobianRatio samples det J,
/// besides the element's own nodes.
constexpr int kJacobianDivisions = 8;

/// Per element: min J / max |J| over the element's nodes and the points of a regular grid of
/// `divisions` steps per side of its reference element, where J(ξ) = n · (x_ξ × x_η) is the
/// Jacobian determinant of the map from the reference element (Lagrange shape functions of
/// the element's order, bilinear for quad4) measured along the element's corner normal n:
/// (x1 − x0) × (x2 − x0) for a triangle, Verdict's centre normal (x1 + x2 − x0 − x3) ×
/// (x2 + x3 − x0 − x1) for a quadrilateral (unit length).
///
/// 1 for a straight-sided triangle and a parallelogram; in (0, 1) for a valid curved element
/// or a non-parallelogram quad (a quad's value is its smallest over its largest corner area);
/// ≤ 0 when J vanishes or changes sign inside the element (a fold: the element is invalid
/// for a solver) — the convention of Gmsh's minJ/maxJ (Johnen, Remacle, Geuzaine 2013).
/// 0 for an element whose corners are collinear (no normal).
///
/// @param[in] mesh      any SurfaceMesh (positions xyz and element connectivity are used)
/// @param[in] divisions steps per side, ≥ 1 (std::invalid_argument otherwise)
std::vector<double> elementJacobianRatio(const SurfaceMesh& mesh,
                                         int divisions = kJacobianDivisions);

/// The same for element e alone (divisions ≥ 1 is not checked).
double jacobianRatioOf(const SurfaceMesh& mesh, std::size_t e, int divisions = kJacobianDivisions);

}  // namespace surfmesh
