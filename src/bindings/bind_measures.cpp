// SurfMesh bindings — the registry of planar distortion measures.
#include "handle.h"
#include "surfmesh/measures/measure.h"

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace surfmesh::bindings {

void bind_measures(py::module_& m) {
  m.def("measure_names", &measureNames, "Names of the distortion measures, e.g. ['shape', 'oddy']");
  m.def(
      "measure_description",
      [](const std::string& name) { return measureByName(name).description(); }, py::arg("name"),
      "Formula and reference of a measure (ValueError for an unknown name)");
  m.def(
      "planar_distortion",
      [](const std::string& name, const Mat2& S, double delta) {
        if (!(delta >= 0.0)) throw std::invalid_argument("delta must be >= 0");
        return measureByName(name).value(S, delta);
      },
      py::arg("name"), py::arg("S"), py::arg("delta") = 0.0,
      "η(S) of a 2×2 Jacobian S (inf when det S ≤ 0 and delta = 0)");
  m.def(
      "element_types",
      []() {
        py::dict d;
        for (ElementType t :
             {ElementType::Tri3, ElementType::Quad4, ElementType::Tri6, ElementType::Tri10,
              ElementType::Tri15, ElementType::Tri21, ElementType::Quad8})
          d[elementTypeName(t)] = static_cast<int>(t);
        return d;
      },
      "Element type names → the integer codes used in the `types` arrays");
}

}  // namespace surfmesh::bindings
