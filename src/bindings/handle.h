// SurfMesh bindings — the Python-side owner of a SurfaceMesh and of the geometry it points to.
#pragma once

#include "surfmesh/mesh/surface_mesh.h"

#include <pybind11/pybind11.h>

#include <memory>
#include <string>

namespace surfmesh {
class CadMesh;
}

namespace surfmesh::bindings {

namespace py = pybind11;

/// A SurfaceMesh together with whatever keeps its surfaces and curves alive (an analytic
/// surface, or the CAD bridge's mesh and its CadShape). Exposed to Python as `SurfaceMesh`.
struct MeshHandle {
  std::shared_ptr<void> owner;  ///< keeps `mesh` and its geometry alive (the CadMesh for "cad")
  SurfaceMesh* mesh = nullptr;  ///< the mesh (owned through `owner`)
  py::dict report;              ///< how the mesh was built (bridge report), as a dict
  std::string source;           ///< "cad" or "surface"

  SurfaceMesh& get() const;
  /// The CadMesh that owns the mesh (source "cad"), else null.
  CadMesh* cadMesh() const {
    return source == "cad" && owner ? static_cast<CadMesh*>(owner.get()) : nullptr;
  }
};

using MeshClass = py::class_<MeshHandle, std::shared_ptr<MeshHandle>>;

void bind_geometry(py::module_& m);
void bind_measures(py::module_& m);
MeshClass bind_mesh(py::module_& m);
void bind_cad(py::module_& m);
void bind_optimize(MeshClass& cls);

}  // namespace surfmesh::bindings
