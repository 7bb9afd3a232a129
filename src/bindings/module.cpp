// SurfMesh bindings — the `SurfMesh._surfmesh` module: registers one binding file per topic.
#include "arrays.h"
#include "handle.h"

#include <Standard_Failure.hxx>
#include <Standard_Type.hxx>
#include <pybind11/pybind11.h>

#include <stdexcept>
#include <string>

namespace py = pybind11;

PYBIND11_MODULE(_surfmesh, m) {
  m.doc() =
      "SurfMesh core: quality measures, smoothing and untangling of surface meshes on CAD "
      "surfaces. Arrays: positions float64 (N, 3) row-major, integers int64.";
  // std::invalid_argument is translated to ValueError by pybind11 itself; keep that explicit.
  // An OpenCASCADE exception that escapes the core (it is not a std::exception, so pybind11
  // would say only "Caught an unknown exception!") names its type and message.
  // The core's refusal of its input (surfmesh::InputError) is an InputError, a ValueError
  // whose `diagnostic` attribute holds the structured diagnostic (code, ids: diagnosticDict).
  // (Kept for the module's life: never destroyed, as the exception type outlives the module.)
  static PyObject* inputError =
      (new py::exception<surfmesh::InputError>(m, "InputError", PyExc_ValueError))->ptr();
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const surfmesh::InputError& e) {
      py::object exc = py::handle(inputError)(e.what());
      exc.attr("diagnostic") = surfmesh::bindings::diagnosticDict(e.diagnostic());
      PyErr_SetObject(inputError, exc.ptr());
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const Standard_Failure& e) {
      const Handle(Standard_Type) type = e.DynamicType();
      const char* what = e.GetMessageString();
      std::string text = "OpenCASCADE raised ";
      text += type.IsNull() ? "Standard_Failure" : type->Name();
      if (what != nullptr && *what != '\0') text += std::string(": ") + what;
      PyErr_SetString(PyExc_RuntimeError, text.c_str());
    }
  });
  surfmesh::bindings::bind_geometry(m);
  surfmesh::bindings::bind_measures(m);
  auto meshClass = surfmesh::bindings::bind_mesh(m);
  surfmesh::bindings::bind_optimize(meshClass);
  surfmesh::bindings::bind_cad(m);
}
