// SurfMesh bindings — the `SurfMesh._surfmesh` module: registers one binding file per topic.
#include "handle.h"

#include <pybind11/pybind11.h>

#include <stdexcept>

namespace py = pybind11;

PYBIND11_MODULE(_surfmesh, m) {
  m.doc() =
      "SurfMesh core: quality measures, smoothing and untangling of surface meshes on CAD "
      "surfaces. Arrays: positions float64 (N, 3) row-major, integers int64.";
  // std::invalid_argument is translated to ValueError by pybind11 itself; keep that explicit.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  surfmesh::bindings::bind_geometry(m);
  surfmesh::bindings::bind_measures(m);
  auto meshClass = surfmesh::bindings::bind_mesh(m);
  surfmesh::bindings::bind_optimize(meshClass);
  surfmesh::bindings::bind_cad(m);
}
