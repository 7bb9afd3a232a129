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
/// `divisions` steps per side of its reference element, where J(ξ) = ±|x_ξ × x_η| is the
/// Jacobian determinant of the map from the reference element (Lagrange shape functions of
/// the element's order, bilinear for quad4): the area the map gives a unit of reference area
/// (what a shell solver integrates with), negative where the element's tangent plane
/// x_ξ × x_η is wound against the CAD face's outward normal (faceOrientation applied), zero
/// where it stands perpendicular to it. The face's normal at a point is first taken as the
/// interpolation Σ N_i n_i of its normals n_i at the element's nodes (a node at a pole: the
/// direction of the others' sum), as the certificate's first test does; when that finds some
/// J ≤ 0, the face's own normal at the point that the element's (u,v) map reaches decides
/// instead (the interpolation where the face has no normal there). A mesh without faces
/// (elemFace, surfaces, cornerUV not filled) is measured along the corners' normal
/// (x1 − x0) × (x2 − x0), Verdict's centre normal for a quadrilateral.
///
/// 1 for a straight-sided triangle and a parallelogram wound along the face; −1 for a tangled
/// linear triangle; in (0, 1) for a valid curved element or a non-parallelogram quad (a
/// quad's value is its smallest over its largest corner area); ≤ 0 when J vanishes or changes
/// sign inside the element (a fold: the element is invalid for a solver). On a plane this is
/// Gmsh's minJ/maxJ (Johnen, Remacle, Geuzaine 2013); Gmsh measures J along the straight
/// corner triangle's normal everywhere, which differs where the face's normal turns within the
/// element. 0 for an element whose corners are collinear; NaN for a non-finite node.
///
/// @param[in] mesh      any SurfaceMesh (positions xyz, connectivity, and where filled the
///                      elements' faces and corner (u,v))
/// @param[in] divisions steps per side, ≥ 1 (std::invalid_argument otherwise)
std::vector<double> elementJacobianRatio(const SurfaceMesh& mesh,
                                         int divisions = kJacobianDivisions);

/// The same for element e alone (divisions ≥ 1 is not checked).
double jacobianRatioOf(const SurfaceMesh& mesh, std::size_t e, int divisions = kJacobianDivisions);

}  // namespace surfmesh
