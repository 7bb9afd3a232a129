// SurfMesh bindings — the CAD bridge: cad_mesh(shape, arrays, hints, tolerance, boundary).
#include "arrays.h"
#include "handle.h"
#include "surfmesh/cad/cad_bridge.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace surfmesh::bindings {

namespace {

constexpr std::int64_t kTypeCount = 7;  // ElementType Tri3 … Tri21, Quad8

template <class T>
py::array_t<T> toArray(const std::vector<T>& v) {
  py::array_t<T> out(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

std::vector<std::int32_t> hintVector(const py::object& o, py::ssize_t n, std::int64_t count,
                                     const char* what) {
  if (o.is_none()) return {};
  ArrayI a = py::cast<ArrayI>(o);
  checkShape1D(a, what, n);
  checkRange(a, -1, count, what);
  return toInt32(a);
}

py::dict reportDict(const BridgeReport& r) {
  py::dict d;
  py::array_t<std::uint8_t> cls(static_cast<py::ssize_t>(r.nodeClass.size()));
  for (std::size_t i = 0; i < r.nodeClass.size(); ++i)
    cls.mutable_data()[i] = static_cast<std::uint8_t>(r.nodeClass[i]);
  d["node_class"] = cls;
  d["node_class_names"] =
      py::make_tuple(nodeClassName(NodeClass::Vertex), nodeClassName(NodeClass::Edge),
                     nodeClassName(NodeClass::Face), nodeClassName(NodeClass::None));
  d["node_entity"] = toArray(r.nodeEntity);
  d["node_param"] = toArray(r.nodeParam);
  d["node_distance"] = toArray(r.nodeDistance);
  std::vector<bool> flipped(r.faceFlipped.begin(), r.faceFlipped.end());
  d["face_flipped"] = flipped;
  d["flipped_faces"] = r.flippedFaces;
  d["face_elements"] = r.faceElements;
  d["miswound_elements"] = toArray(r.miswoundElements);
  d["placed_nodes"] = toArray(r.placedNodes);
  d["loose_nodes"] = toArray(r.looseNodes);
  py::array_t<std::uint8_t> looseClass(static_cast<py::ssize_t>(r.looseClass.size()));
  for (std::size_t i = 0; i < r.looseClass.size(); ++i)
    looseClass.mutable_data()[i] = static_cast<std::uint8_t>(r.looseClass[i]);
  d["loose_class"] = looseClass;
  d["loose_entity"] = toArray(r.looseEntity);
  d["loose_distance"] = toArray(r.looseDistance);
  py::list gaps;
  for (const auto& g : r.trimGaps)
    gaps.append(py::dict(py::arg("face") = g.face, py::arg("edge") = g.edge, py::arg("gap") = g.gap,
                         py::arg("tolerance") = g.tolerance));
  d["trim_gaps"] = gaps;
  d["tolerance"] = r.tolerance;
  d["max_distance"] = r.maxDistance;
  d["worst_node"] = r.worstNode;
  d["vertex_nodes"] = r.vertexNodes;
  d["edge_nodes"] = r.edgeNodes;
  d["face_nodes"] = r.faceNodes;
  d["unused_nodes"] = r.unusedNodes;
  d["pole_nodes"] = r.poleNodes;
  d["fixed_nodes"] = r.fixedNodes;
  d["sliding_nodes"] = r.slidingNodes;
  d["faces_used"] = r.facesUsed;
  d["hints_rejected"] = r.hintsRejected;
  d["hints_taken"] = r.hintsTaken;
  d["warnings"] = r.warnings;
  py::list diagnostics;
  for (const Diagnostic& x : r.diagnostics) diagnostics.append(diagnosticDict(x));
  d["diagnostics"] = diagnostics;
  d["seconds"] = r.seconds;
  d["summary"] = r.summary();
  return d;
}

}  // namespace

void bind_bridge(py::module_& m) {
  m.def(
      "diagnostic_codes",
      [] {
        py::list out;
        for (const DiagnosticCode& c : kDiagnosticCodes)
          out.append(py::dict(py::arg("code") = c.code, py::arg("refusal") = c.refusal,
                              py::arg("meaning") = c.meaning));
        return out;
      },
      "Every code of the core's diagnostics: [{code, refusal (an InputError, else a warning of "
      "the bridge report's 'diagnostics'), meaning}].");
  m.def(
      "cad_mesh",
      [](std::shared_ptr<CadShape> shape, const ArrayD& nodes, const ArrayI& types,
         const ArrayI& offsets, const ArrayI& conn, const py::object& hint_face,
         const py::object& hint_edge, const py::object& hint_vertex, double tolerance,
         const std::string& boundary, int threads, bool tolerance_hints, bool keep_node_search,
         const py::object& same_nodes_as, const py::object& left_out_nodes) {
        if (!shape) throw std::invalid_argument("shape is None");
        const CadMesh* previous =
            same_nodes_as.is_none() ? nullptr : same_nodes_as.cast<const MeshHandle&>().cadMesh();
        // ---- validate everything before the core sees it (GIL held) ----
        checkShape2D(nodes, 3, "nodes");
        const py::ssize_t n = nodes.shape(0);
        if (n == 0) throw std::invalid_argument("the mesh is empty (no nodes)");
        checkFinite(nodes, "nodes");
        checkShape1D(types, "types");
        const py::ssize_t e = types.shape(0);
        if (e == 0) throw std::invalid_argument("the mesh has no elements");
        checkRange(types, 0, kTypeCount, "types");
        checkShape1D(offsets, "offsets", e + 1);
        checkShape1D(conn, "conn");
        const std::int64_t* off = offsets.data();
        const std::int64_t* ty = types.data();
        if (off[0] != 0) throw std::invalid_argument("offsets[0] must be 0");
        for (py::ssize_t k = 0; k < e; ++k) {
          const std::int64_t size = off[k + 1] - off[k];
          const int expected = nodeCount(static_cast<ElementType>(ty[k]));
          if (size != expected) {
            std::ostringstream s;
            s << "element " << k << " (" << elementTypeName(static_cast<ElementType>(ty[k]))
              << ") has " << size << " nodes in offsets, expected " << expected;
            throw std::invalid_argument(s.str());
          }
        }
        if (off[e] != conn.shape(0)) {
          std::ostringstream s;
          s << "offsets[-1] = " << off[e] << " but conn has " << conn.shape(0) << " entries";
          throw std::invalid_argument(s.str());
        }
        checkRange(conn, 0, n, "conn");
        if (!std::isfinite(tolerance) || tolerance < 0.0)
          throw std::invalid_argument("tolerance must be >= 0 (0: automatic), got " +
                                      std::to_string(tolerance));
        if (boundary != "fixed" && boundary != "slide")
          throw std::invalid_argument("boundary must be 'fixed' or 'slide', got '" + boundary +
                                      "'");
        if (threads < 0) throw std::invalid_argument("threads must be >= 0");
        MeshInput in;
        in.nodes = toVec3(nodes);
        in.types.resize(static_cast<std::size_t>(e));
        for (py::ssize_t k = 0; k < e; ++k)
          in.types[static_cast<std::size_t>(k)] = static_cast<ElementType>(ty[k]);
        in.offsets.assign(off, off + e + 1);
        in.conn = toInt32(conn);
        in.hintFace = hintVector(hint_face, n, shape->faceCount(), "hint_face");
        in.hintEdge = hintVector(hint_edge, n, shape->edgeCount(), "hint_edge");
        in.hintVertex = hintVector(hint_vertex, n, shape->vertexCount(), "hint_vertex");
        in.leftOutNeighbour = toMask(left_out_nodes, n, "left_out_nodes");
        BridgeOptions opt;
        opt.tolerance = tolerance;
        opt.boundary = boundary;
        opt.threads = threads;
        opt.toleranceHints = tolerance_hints;
        opt.keepNodeSearch = keep_node_search;
        std::shared_ptr<CadMesh> cm;
        {
          py::gil_scoped_release release;
          cm = std::make_shared<CadMesh>(shape, in, opt, previous);
        }
        auto h = std::make_shared<MeshHandle>();
        h->mesh = &cm->mesh();
        h->owner = cm;
        h->source = "cad";
        h->report = reportDict(cm->report());
        return h;
      },
      py::arg("shape"), py::arg("nodes"), py::arg("types"), py::arg("offsets"), py::arg("conn"),
      py::arg("hint_face") = py::none(), py::arg("hint_edge") = py::none(),
      py::arg("hint_vertex") = py::none(), py::arg("tolerance") = 0.0,
      py::arg("boundary") = "fixed", py::arg("threads") = 0, py::arg("tolerance_hints") = false,
      py::arg("keep_node_search") = false, py::arg("same_nodes_as") = py::none(),
      py::arg("left_out_nodes") = py::none(),
      "Recovers a mesh on a CadShape. nodes float64 (N, 3); types int64 (E,) codes of "
      "element_types(); offsets int64 (E+1,); conn int64 0-based (Gmsh node order); optional "
      "hint_face/edge/vertex int64 (N,) 0-based ids or −1; tolerance 0 = 1e-3·diagonal; "
      "boundary 'fixed' or 'slide'; tolerance_hints: nodes without a hint are hinted to the "
      "vertex or the single edge whose own tolerance they are within (FreeCAD's "
      "FemMesh.getNodesByVertex/Edge rule); keep_node_search: the result keeps its per-node "
      "face search (~100 bytes per node) so that same_nodes_as=<that result> can skip it when "
      "recovering the same nodes with other elements (the same answer, faster); left_out_nodes "
      "bool (N,): nodes of elements left out of conn, which lie on the mesh's boundary only "
      "through the hole those leave (on a CAD edge only within twice its tolerance, else they "
      "move in their face). Returns a "
      "SurfaceMesh whose .report says how every node was classified.");
}

}  // namespace surfmesh::bindings
