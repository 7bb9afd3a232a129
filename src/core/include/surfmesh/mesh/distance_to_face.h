// SurfMesh — how far an element's interior lies from the CAD surface it stands for.
#pragma once

#include "surfmesh/mesh/surface_mesh.h"

#include <vector>

namespace surfmesh {

/// Default number of steps per side of the reference element at which
/// elementDistanceToFace samples it: 45 points on a triangle, 81 on a quadrilateral.
constexpr int kDistanceDivisions = 8;

/// The parameters of the point of surface s nearest to x near (u,v): Newton on
/// ½|φ(u,v) − x|² from uv, Gauss–Newton steps where the Hessian is not positive definite, each
/// step halved until the distance does not grow (a local search, not a global one). Writes
/// that distance (NaN when φ is not finite at uv).
Vec2 nearestParameters(const Surface& s, const Vec3& x, Vec2 uv, double* distance);

/// Largest distance of every element's interior from the surface of its face.
///
/// The element is sampled at the points of a regular grid of `divisions` steps per side of
/// its reference element (barycentric (i, j)/n with i + j ≤ n on a triangle, (i, j)/n on the
/// unit square of a quadrilateral), mapped by its own shape functions (Lagrange of the
/// element's order, bilinear for quad4) from its nodes' positions `xyz`. Each sample x is
/// projected onto the surface of the element's face by a Newton iteration on ½|φ(u,v) − x|²
/// (Gauss–Newton steps where the Hessian is not positive definite, with a backtracking line
/// search), started from the element's corner (u,v) (`cornerUV`) interpolated the same way:
/// the nearest point of the surface near the element, not a global search. The result is
/// the largest |φ(u*,v*) − x| over the samples (0 for an element whose nodes and interior lie
/// on a plane it is meshed on; the chord's sagitta R(1 − cos(θ/2)) for a straight side
/// spanning an angle θ of a cylinder of radius R).
///
/// @param[in] mesh      a mesh whose elemFace, cornerUV and surfaces are filled (cad_mesh,
///                      makeSingleSurfaceMesh)
/// @param[in] divisions steps per side, ≥ 1 (std::invalid_argument otherwise)
/// @return one distance per element (NaN for an element with non-finite coordinates)
std::vector<double> elementDistanceToFace(const SurfaceMesh& mesh,
                                          int divisions = kDistanceDivisions);

}  // namespace surfmesh
