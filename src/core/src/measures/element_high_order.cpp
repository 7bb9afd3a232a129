#include "surfmesh/measures/element_measure.h"

#include <stdexcept>

namespace surfmesh {

ElementEval highOrderTriangleDistortion(const PlanarMeasure&, ElementType type, const Vec3*,
                                        const Vec3&, double, int, Vec3*, Mat3*) {
  throw std::invalid_argument(std::string("element type ") + elementTypeName(type) +
                              " is not supported by this build");
}

}  // namespace surfmesh
