#include "arrays.h"

#include <pybind11/stl.h>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace surfmesh::bindings {

namespace {
std::string shapeString(const py::array& a) {
  std::ostringstream s;
  s << "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) s << (k ? ", " : "") << a.shape(k);
  if (a.ndim() == 1) s << ",";
  s << ")";
  return s.str();
}
}  // namespace

void checkShape2D(const ArrayD& a, py::ssize_t cols, const char* what, py::ssize_t rows) {
  if (a.ndim() != 2 || a.shape(1) != cols || (rows >= 0 && a.shape(0) != rows)) {
    std::ostringstream s;
    s << what << " must have shape (" << (rows >= 0 ? std::to_string(rows) : std::string("N"))
      << ", " << cols << "), got " << shapeString(a);
    throw std::invalid_argument(s.str());
  }
}

void checkShape1D(const ArrayI& a, const char* what, py::ssize_t n) {
  if (a.ndim() != 1 || (n >= 0 && a.shape(0) != n)) {
    std::ostringstream s;
    s << what << " must be 1-D" << (n >= 0 ? " with " + std::to_string(n) + " entries" : "")
      << ", got shape " << shapeString(a);
    throw std::invalid_argument(s.str());
  }
}

std::vector<unsigned char> toMask(const py::object& o, py::ssize_t n, const char* what) {
  if (o.is_none()) return {};
  const auto mask = py::cast<py::array_t<bool, py::array::c_style | py::array::forcecast>>(o);
  if (mask.ndim() != 1 || mask.shape(0) != n)
    throw std::invalid_argument(std::string(what) + " must be a bool array of shape (" +
                                std::to_string(n) + ",)");
  return std::vector<unsigned char>(mask.data(), mask.data() + n);
}

void checkFinite(const ArrayD& a, const char* what) {
  const double* p = a.data();
  const py::ssize_t n = a.size();
  const py::ssize_t cols = a.ndim() == 2 ? a.shape(1) : 1;
  for (py::ssize_t i = 0; i < n; ++i) {
    if (!std::isfinite(p[i])) {
      // (the rows of the arrays checked here are nodes: positions, (u,v))
      std::ostringstream s;
      s << p[i];
      Diagnostic d;
      d.code = code::kNonFiniteNode;
      d.count = 1;
      d.nodes = {static_cast<std::int64_t>(i / cols)};
      d.format =
          std::string(what) + " contains a non-finite value (" + s.str() + ") in node {node}";
      throw InputError(std::move(d));
    }
  }
}

void checkRange(const ArrayI& a, std::int64_t lo, std::int64_t hi, const char* what) {
  const std::int64_t* p = a.data();
  const py::ssize_t n = a.size();
  for (py::ssize_t i = 0; i < n; ++i) {
    if (p[i] < lo || p[i] >= hi) {
      std::ostringstream s;
      s << what << "[" << i << "] = " << p[i] << " is out of range [" << lo << ", " << hi << ")";
      throw std::invalid_argument(s.str());
    }
  }
}

std::vector<Vec3> toVec3(const ArrayD& a) {
  std::vector<Vec3> out(static_cast<std::size_t>(a.shape(0)));
  const double* p = a.data();
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
  return out;
}

std::vector<Vec2> toVec2(const ArrayD& a) {
  std::vector<Vec2> out(static_cast<std::size_t>(a.shape(0)));
  const double* p = a.data();
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec2(p[2 * i], p[2 * i + 1]);
  return out;
}

std::vector<std::int32_t> toInt32(const ArrayI& a) {
  std::vector<std::int32_t> out(static_cast<std::size_t>(a.size()));
  const std::int64_t* p = a.data();
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<std::int32_t>(p[i]);
  return out;
}

py::array_t<double> fromVec3(const std::vector<Vec3>& v) {
  py::array_t<double> out({static_cast<py::ssize_t>(v.size()), py::ssize_t(3)});
  double* p = out.mutable_data();
  for (std::size_t i = 0; i < v.size(); ++i) {
    p[3 * i] = v[i].x();
    p[3 * i + 1] = v[i].y();
    p[3 * i + 2] = v[i].z();
  }
  return out;
}

py::array_t<double> fromDoubles(const std::vector<double>& v) {
  py::array_t<double> out(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

py::dict diagnosticDict(const Diagnostic& d) {
  py::dict values;
  for (const auto& [name, v] : d.values) values[py::str(name)] = v;
  py::dict out;
  out["code"] = d.code;
  out["text"] = d.render();
  out["format"] = d.format;
  out["count"] = d.count;
  out["nodes"] = py::cast(d.nodes);
  out["elements"] = py::cast(d.elements);
  out["faces"] = py::cast(d.faces);
  out["edges"] = py::cast(d.edges);
  out["vertices"] = py::cast(d.vertices);
  out["values"] = values;
  return out;
}

}  // namespace surfmesh::bindings
