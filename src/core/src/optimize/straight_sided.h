// Where a curved element's high-order nodes lie on straight sides between its corners.
#pragma once

#include "surfmesh/measures/lagrange_triangle.h"
#include "surfmesh/mesh/surface_mesh.h"

namespace surfmesh {

/// Where node `local` (not a corner) of a high-order triangle or quad8 lies on straight sides
/// between its corners' points c (cornerCount of them): the interpolation of its reference
/// position (a quad8's side node: its side's midpoint). P is Vec2 for corners' parameters
/// (straight sides in (u,v)) or Vec3 for their positions (the straight-sided element's node).
template <class P>
P straightPlace(ElementType type, int local, const P* c) {
  if (type == ElementType::Quad8) return P(0.5 * (c[local - 4] + c[(local - 3) % 4]));
  const Eigen::Vector2d xi =
      lagrangeTriangle(elementOrder(type)).nodes()[static_cast<std::size_t>(local)];
  return P((1.0 - xi.x() - xi.y()) * c[0] + xi.x() * c[1] + xi.y() * c[2]);
}

}  // namespace surfmesh
