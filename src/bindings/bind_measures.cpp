// SurfMesh bindings — the registry of planar distortion measures, and the certificate of a
// curved triangle's Jacobian sign (certificate.h) with the sampled check it is compared to.
#include "arrays.h"
#include "handle.h"
#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/measures/measure.h"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace surfmesh::bindings {

namespace {

/// The nodes of E elements of `type`: (E·k, 3) or (E, k, 3) float64 → E·k positions.
std::vector<Vec3> elementNodes(const ArrayD& nodes, ElementType type, py::ssize_t E) {
  const py::ssize_t k = nodeCount(type);
  const bool flat = nodes.ndim() == 2 && nodes.shape(0) == E * k && nodes.shape(1) == 3;
  const bool stacked =
      nodes.ndim() == 3 && nodes.shape(0) == E && nodes.shape(1) == k && nodes.shape(2) == 3;
  if (!flat && !stacked) {
    std::ostringstream s;
    s << "nodes must have shape (" << E << ", " << k << ", 3) or (" << E * k << ", 3) for " << E
      << " " << elementTypeName(type) << " elements";
    throw std::invalid_argument(s.str());
  }
  std::vector<Vec3> x(static_cast<std::size_t>(E * k));
  const double* p = nodes.data();
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
  return x;
}

/// (E, 3) normals → E vectors.
std::vector<Vec3> elementNormals(const ArrayD& normals) {
  checkShape2D(normals, 3, "normals");
  return toVec3(normals);
}

py::dict certificateDict(const JacobianCertificate& c) {
  py::dict d;
  d["verdict"] = jacobianSignName(c.sign);
  d["point"] = py::make_tuple(c.point.x(), c.point.y());
  d["value"] = c.value;
  d["min_coefficient"] = c.minCoefficient;
  d["min_sampled"] = c.minSampled;
  d["ratio"] = c.ratio;
  d["lower_bound"] = c.lowerBound;
  d["tolerance"] = c.tolerance;
  d["depth"] = c.depth;
  d["pieces"] = c.pieces;
  return d;
}

}  // namespace

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
  m.def(
      "certify_element",
      [](const std::string& type, const ArrayD& nodes, const ArrayD& normal) {
        const ElementType t = elementTypeFromName(type);
        if (isQuad(t))
          throw std::invalid_argument("certify_element: " + type + " is not a triangle");
        if (normal.ndim() != 1 || normal.shape(0) != 3)
          throw std::invalid_argument("normal must have shape (3,)");
        const std::vector<Vec3> x = elementNodes(nodes, t, 1);
        const Vec3 n(normal.data()[0], normal.data()[1], normal.data()[2]);
        return certificateDict(certifyElementJacobian(t, x.data(), n));
      },
      py::arg("type"), py::arg("nodes"), py::arg("normal"),
      "Proves the sign of det J = (x_xi x x_eta).n over the whole reference triangle of one "
      "Lagrange triangle (type 'tri3', 'tri6', 'tri10', 'tri15' or 'tri21'; nodes float64 (k, 3) "
      "in Gmsh order; normal the element's reference normal, the sum of its corner normals) by "
      "Bernstein coefficients and subdivision. Dict: verdict ('positive' proven > 0 everywhere, "
      "'non_positive' det J <= tolerance at `point`, 'undecided' not proven: invalid), point "
      "(xi, eta), value (det J there), min_coefficient, min_sampled, ratio (their quotient), "
      "lower_bound (proven, when positive), tolerance, depth, pieces");
  m.def(
      "certify_elements",
      [](const std::string& type, const ArrayD& nodes, const ArrayD& normals) {
        const ElementType t = elementTypeFromName(type);
        if (isQuad(t))
          throw std::invalid_argument("certify_elements: " + type + " is not a triangle");
        const std::vector<Vec3> n = elementNormals(normals);
        const py::ssize_t E = static_cast<py::ssize_t>(n.size());
        const std::vector<Vec3> x = elementNodes(nodes, t, E);
        const std::size_t k = static_cast<std::size_t>(nodeCount(t));
        py::array_t<std::int8_t> verdict(E);
        py::array_t<double> point({E, static_cast<py::ssize_t>(2)});
        py::array_t<double> value(E), minCoefficient(E), minSampled(E);
        py::array_t<std::int32_t> pieces(E);
        {
          std::int8_t* v = verdict.mutable_data();
          double *pt = point.mutable_data(), *val = value.mutable_data();
          double *mc = minCoefficient.mutable_data(), *ms = minSampled.mutable_data();
          std::int32_t* pc = pieces.mutable_data();
          py::gil_scoped_release release;
          for (std::size_t e = 0; e < n.size(); ++e) {
            const JacobianCertificate c = certifyElementJacobian(t, x.data() + e * k, n[e]);
            v[e] = static_cast<std::int8_t>(c.sign);
            pt[2 * e] = c.point.x();
            pt[2 * e + 1] = c.point.y();
            val[e] = c.value;
            mc[e] = c.minCoefficient;
            ms[e] = c.minSampled;
            pc[e] = c.pieces;
          }
        }
        py::dict d;
        d["verdict"] = verdict;
        d["point"] = point;
        d["value"] = value;
        d["min_coefficient"] = minCoefficient;
        d["min_sampled"] = minSampled;
        d["pieces"] = pieces;
        return d;
      },
      py::arg("type"), py::arg("nodes"), py::arg("normals"),
      "certify_element for E triangles of one type: nodes float64 (E, k, 3) or (E*k, 3), normals "
      "(E, 3). Dict of arrays: verdict int8 (1 positive, 0 non-positive, -1 undecided), point "
      "(E, 2), value, min_coefficient, min_sampled, pieces");
  m.def(
      "elements_tangled",
      [](const std::string& type, const ArrayD& nodes, const ArrayD& normals,
         const std::string& measure, bool samplesOnly) {
        const ElementType t = elementTypeFromName(type);
        const PlanarMeasure& pm = measureByName(measure);
        const std::vector<Vec3> n = elementNormals(normals);
        const py::ssize_t E = static_cast<py::ssize_t>(n.size());
        const std::vector<Vec3> x = elementNodes(nodes, t, E);
        const std::size_t k = static_cast<std::size_t>(nodeCount(t));
        py::array_t<bool> tangled(E);
        bool* out = tangled.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t e = 0; e < n.size(); ++e) {
            const Vec3* xe = x.data() + e * k;
            ElementEval ev;
            if (samplesOnly && isHighOrderTriangle(t)) {
              // The samples alone: the evaluation from precomputed Jacobians, which leaves the
              // certificate to its caller.
              HighOrderJacobians pre;
              highOrderJacobians(t, xe, -1, &pre);
              ev = highOrderTriangleDistortion(pm, pre, Vec3::Zero(), n[e], 0.0, nullptr, nullptr,
                                               nullptr);
            } else {
              ev = elementDistortion(pm, t, xe, n[e], 0.0);
            }
            out[e] = ev.tangled || !std::isfinite(ev.eta) || !(ev.eta > 0.0);
          }
        }
        return tangled;
      },
      py::arg("type"), py::arg("nodes"), py::arg("normals"), py::arg("measure") = "shape",
      py::arg("samples_only") = false,
      "The validity check of the quality report (SurfaceMesh.measure's `tangled`) for E elements "
      "of one type given by their nodes (as certify_elements) and reference normals (E, 3): "
      "det S <= 0 at a node or quadrature point or det J not proven positive by the certificate "
      "(high-order triangles), at a node or Gauss point or not proven (quad8). With "
      "samples_only, a high-order triangle's nodes and quadrature points alone (the check before "
      "the certificate). bool (E,)");
}

}  // namespace surfmesh::bindings
