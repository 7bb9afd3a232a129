// SurfMesh bindings — the numpy interchange types, fixed once, and their validators.
//
//   positions     float64, (N, 3), C order (row-major)       → RowsD3
//   (u,v)         float64, (N, 2), C order                    → RowsD2
//   integers      int64, 1-D (types, offsets, connectivity, hints)
//
// Arrays are accepted through pybind11's `array_t<T, c_style | forcecast>`, so a float32 or
// int32 array is converted once; anything that cannot be converted raises TypeError. Every
// validator runs with the GIL held, before C++ code sees the data, and throws
// std::invalid_argument (→ ValueError) naming the offending index.
#pragma once

#include "surfmesh/diagnostic.h"
#include "surfmesh/geometry/surface.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <string>
#include <vector>

namespace surfmesh::bindings {

namespace py = pybind11;

using ArrayD = py::array_t<double, py::array::c_style | py::array::forcecast>;
using ArrayI = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

/// Checks that `a` is (rows × cols) (rows = −1: any). `what` names the argument.
void checkShape2D(const ArrayD& a, py::ssize_t cols, const char* what, py::ssize_t rows = -1);
/// Checks that `a` is 1-D with `n` entries (n = −1: any).
void checkShape1D(const ArrayI& a, const char* what, py::ssize_t n = -1);
/// Checks that every entry of `a` is finite; reports the first offending row.
void checkFinite(const ArrayD& a, const char* what);
/// Checks lo ≤ a[i] < hi for every entry (ids / indices); reports the first offending entry.
void checkRange(const ArrayI& a, std::int64_t lo, std::int64_t hi, const char* what);

/// None → empty; else a 1-D bool array (anything numpy converts) of `n` entries → 0/1 per
/// entry. `what` names the argument.
std::vector<unsigned char> toMask(const py::object& o, py::ssize_t n, const char* what);

/// (N, 3) positions → std::vector<Vec3>, (N, 2) → std::vector<Vec2> (after checkShape2D).
std::vector<Vec3> toVec3(const ArrayD& a);
std::vector<Vec2> toVec2(const ArrayD& a);
/// 1-D int64 → std::vector<std::int32_t> (values already range-checked to fit).
std::vector<std::int32_t> toInt32(const ArrayI& a);

/// New (N, 3) float64 array from positions.
py::array_t<double> fromVec3(const std::vector<Vec3>& v);
/// New 1-D arrays from vectors.
py::array_t<double> fromDoubles(const std::vector<double>& v);

/// A diagnostic as Python sees it: {"code", "text" (rendered with the core's indices),
/// "format", "count", "nodes", "elements", "faces", "edges", "vertices" (lists of int),
/// "values" (dict of name: float)}.
py::dict diagnosticDict(const Diagnostic& d);

}  // namespace surfmesh::bindings
