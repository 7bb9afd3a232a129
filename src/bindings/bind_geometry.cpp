// SurfMesh bindings — parameterized surfaces (the analytic ones are used by tests and the demo).
#include "handle.h"
#include "surfmesh/geometry/analytic_surfaces.h"

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>

namespace surfmesh::bindings {

namespace {
py::dict boundsDict(const ParamBounds& b) {
  py::dict d;
  d["umin"] = b.umin;
  d["umax"] = b.umax;
  d["vmin"] = b.vmin;
  d["vmax"] = b.vmax;
  return d;
}
}  // namespace

void bind_geometry(py::module_& m) {
  py::class_<Surface>(m, "Surface",
                      "A parameterized surface φ(u,v) (abstract). Outward normal = "
                      "normal_sign · φu × φv / |φu × φv|.")
      .def(
          "value", [](const Surface& s, double u, double v) { return Vec3(s.value(u, v)); },
          py::arg("u"), py::arg("v"), "φ(u,v) as a 3-vector")
      .def(
          "d1",
          [](const Surface& s, double u, double v) {
            const SurfaceD1 d = s.d1(u, v);
            return py::make_tuple(Vec3(d.p), Vec3(d.du), Vec3(d.dv));
          },
          py::arg("u"), py::arg("v"), "(φ, φu, φv)")
      .def(
          "normal", [](const Surface& s, double u, double v) { return Vec3(s.normal(u, v)); },
          py::arg("u"), py::arg("v"), "unit outward normal (zero at a pole)")
      .def(
          "contains", [](const Surface& s, double u, double v) { return s.contains(u, v); },
          py::arg("u"), py::arg("v"))
      .def_property_readonly("bounds", [](const Surface& s) { return boundsDict(s.bounds()); })
      .def_property_readonly("u_periodic", &Surface::isUPeriodic)
      .def_property_readonly("v_periodic", &Surface::isVPeriodic)
      .def_property_readonly("u_period", &Surface::uPeriod)
      .def_property_readonly("v_period", &Surface::vPeriod)
      .def_property_readonly("normal_sign", &Surface::normalSign)
      .def("describe", &Surface::describe)
      .def("__repr__", [](const Surface& s) { return "<Surface " + s.describe() + ">"; });

  py::class_<PlaneSurface, Surface>(m, "PlaneSurface")
      .def(py::init([](const Vec3& o, const Vec3& e1, const Vec3& e2) {
             return PlaneSurface(o, e1, e2);
           }),
           py::arg("origin") = Vec3(0, 0, 0), py::arg("e1") = Vec3(1, 0, 0),
           py::arg("e2") = Vec3(0, 1, 0), "φ(u,v) = origin + u·e1 + v·e2 (unbounded)");
  py::class_<CylinderSurface, Surface>(m, "CylinderSurface")
      .def(py::init<double, double, double>(), py::arg("r"), py::arg("vmin"), py::arg("vmax"),
           "φ(u,v) = (r cos u, r sin u, v)");
  py::class_<SphereSurface, Surface>(m, "SphereSurface")
      .def(py::init<double>(), py::arg("r"),
           "φ(u,v) = r (cos v cos u, cos v sin u, sin v), v the latitude");
  py::class_<TorusSurface, Surface>(m, "TorusSurface")
      .def(py::init([](double R, double r) {
             if (!(R > 0.0) || !(r > 0.0) || !std::isfinite(R) || !std::isfinite(r))
               throw std::invalid_argument("torus radii must be positive and finite");
             return TorusSurface(R, r);
           }),
           py::arg("R"), py::arg("r"),
           "φ(u,v) = ((R + r cos v) cos u, (R + r cos v) sin u, r sin v); the parameterization "
           "of OpenCASCADE's (and FreeCAD's Part) torus");
}

}  // namespace surfmesh::bindings
