// SurfMesh — structured diagnostics (see surfmesh/diagnostic.h).
#include "surfmesh/diagnostic.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace surfmesh {

namespace {

/// The list `name` of `d` (singular or plural spelling), as text ids, or false when `name`
/// names no list.
bool idList(const Diagnostic& d, const std::string& name, std::vector<std::string>* out) {
  out->clear();
  auto ints = [&](const auto& v) {
    for (const auto x : v) out->push_back(std::to_string(x));
    return true;
  };
  auto shapeIds = [&](const std::vector<int>& v, const char* prefix) {
    for (const int x : v) out->push_back(prefix + std::to_string(x + 1));
    return true;
  };
  if (name == "node") return ints(d.nodes);
  if (name == "element") return ints(d.elements);
  if (name == "face") return shapeIds(d.faces, "Face");
  if (name == "edge") return shapeIds(d.edges, "Edge");
  if (name == "vertex") return shapeIds(d.vertices, "Vertex");
  return false;
}

/// The text of one placeholder's `key` (what is between the braces), or false.
bool fill(const Diagnostic& d, const std::string& key, std::string* out) {
  if (key == "count") {
    *out = std::to_string(d.count);
    return true;
  }
  for (const auto& [name, v] : d.values)
    if (name == key) {
      *out = diagnosticNumber(v);
      return true;
    }
  // kind, plural?, index: "node", "nodes", "node2", "nodes1", "vertex", "vertices1"
  std::size_t digits = key.size();
  while (digits > 0 && key[digits - 1] >= '0' && key[digits - 1] <= '9') --digits;
  std::string kind = key.substr(0, digits);
  const std::size_t k = digits < key.size() ? std::strtoul(key.c_str() + digits, nullptr, 10) : 0;
  bool plural = false;
  if (kind == "vertices") {
    kind = "vertex";
    plural = true;
  } else if (kind.size() > 1 && kind.back() == 's') {
    kind.pop_back();
    plural = true;
  }
  std::vector<std::string> ids;
  if (!idList(d, kind, &ids) || k >= ids.size()) return false;
  if (!plural) {
    *out = ids[k];
    return true;
  }
  out->clear();
  for (std::size_t i = k; i < ids.size(); ++i) *out += (i > k ? " " : "") + ids[i];
  return true;
}

}  // namespace

std::string diagnosticNumber(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15)
    return std::to_string(static_cast<long long>(v));
  std::ostringstream os;
  os << v;
  return os.str();
}

std::string Diagnostic::render() const {
  std::string out;
  out.reserve(format.size() + 32);
  for (std::size_t i = 0; i < format.size();) {
    const std::size_t close = format[i] == '{' ? format.find('}', i) : std::string::npos;
    std::string text;
    if (close != std::string::npos && fill(*this, format.substr(i + 1, close - i - 1), &text)) {
      out += text;
      i = close + 1;
    } else {
      out += format[i++];
    }
  }
  return out;
}

InputError::InputError(Diagnostic d)
    : std::invalid_argument(d.render()), diagnostic_(std::move(d)) {}

}  // namespace surfmesh
