// SurfMesh bindings — CAD shapes (OpenCASCADE B-rep read from BREP text or a file).
#include "handle.h"
#include "surfmesh/cad/cad_shape.h"

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>

namespace surfmesh::bindings {

void bind_bridge(py::module_& m);

void bind_cad(py::module_& m) {
  py::class_<CadShape, std::shared_ptr<CadShape>>(
      m, "CadShape",
      "A B-rep shape with 0-based face/edge/vertex ids in TopExp::MapShapes order (face id i is "
      "FreeCAD's Shape.Faces[i]).")
      .def_static(
          "from_brep_string",
          [](const std::string& brep) {
            py::gil_scoped_release release;
            return CadShape::fromBrepString(brep);
          },
          py::arg("brep"), "From BREP text (Part.Shape.exportBrepToString())")
      .def_static(
          "from_file",
          [](const std::string& path) {
            py::gil_scoped_release release;
            return CadShape::fromFile(path);
          },
          py::arg("path"), "From a .brep/.brp/.step/.stp/.iges/.igs file")
      .def_property_readonly("face_count", &CadShape::faceCount)
      .def_property_readonly("edge_count", &CadShape::edgeCount)
      .def_property_readonly("vertex_count", &CadShape::vertexCount)
      .def_property_readonly("diagonal", &CadShape::diagonal, "Bounding box diagonal")
      .def("face_type", &CadShape::faceType, py::arg("face"))
      .def(
          "surface", [](const CadShape& s, int face) -> const Surface& { return s.surface(face); },
          py::arg("face"), py::return_value_policy::reference_internal,
          "The Surface of a face (valid while the CadShape lives)")
      .def("vertex_point", &CadShape::vertexPoint, py::arg("vertex"))
      .def("edge_faces", &CadShape::edgeFaces, py::arg("edge"))
      .def("face_edges", &CadShape::faceEdges, py::arg("face"))
      .def("is_seam", &CadShape::isSeam, py::arg("edge"), py::arg("face"))
      .def("is_degenerated_edge", &CadShape::isDegeneratedEdge, py::arg("edge"))
      .def("describe", &CadShape::describe)
      .def("__repr__", [](const CadShape& s) {
        return "<CadShape " + std::to_string(s.faceCount()) + " faces, " +
               std::to_string(s.edgeCount()) + " edges, " + std::to_string(s.vertexCount()) +
               " vertices>";
      });
  bind_bridge(m);
}

}  // namespace surfmesh::bindings
