// SurfMesh bindings — SurfaceMesh handles: building one on an analytic surface, reading node
// data back, and measuring quality.
#include "arrays.h"
#include "handle.h"
#include "surfmesh/cad/cad_bridge.h"
#include "surfmesh/geometry/analytic_surfaces.h"
#include "surfmesh/measures/measure.h"
#include "surfmesh/mesh/distance_to_face.h"
#include "surfmesh/mesh/jacobian_ratio.h"
#include "surfmesh/mesh/quality.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <sstream>
#include <stdexcept>

namespace surfmesh::bindings {

SurfaceMesh& MeshHandle::get() const {
  if (mesh == nullptr) throw std::invalid_argument("empty SurfaceMesh handle");
  return *mesh;
}

namespace {

struct SurfaceOwner {
  std::unique_ptr<Surface> surface;
  SurfaceMesh mesh;
};

py::dict statsDict(const QualityStats& s) {
  py::dict d;
  d["min"] = s.min;
  d["max"] = s.max;
  d["mean"] = s.mean;
  d["std"] = s.stddev;
  d["tangled"] = s.tangled;
  d["elements"] = s.elements;
  d["across"] = s.across;
  return d;
}

template <class T>
py::array_t<T> toArray(const std::vector<T>& v) {
  py::array_t<T> out(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

}  // namespace

py::dict qualityDict(const MeshQuality& q) {
  py::dict d;
  d["quality"] = fromDoubles(q.quality);
  d["distortion"] = fromDoubles(q.distortion);
  py::array_t<bool> tangled(static_cast<py::ssize_t>(q.tangled.size()));
  bool* p = tangled.mutable_data();
  for (std::size_t i = 0; i < q.tangled.size(); ++i) p[i] = q.tangled[i] != 0;
  d["tangled"] = tangled;
  d["min_sigma"] = fromDoubles(q.minSigma);
  py::array_t<bool> across(static_cast<py::ssize_t>(q.across.size()));
  for (std::size_t i = 0; i < q.across.size(); ++i) across.mutable_data()[i] = q.across[i] != 0;
  d["across"] = across;
  d["stats"] = statsDict(q.stats);
  return d;
}

py::dict statsToDict(const QualityStats& s) { return statsDict(s); }

MeshClass bind_mesh(py::module_& m) {
  MeshClass cls(m, "SurfaceMesh",
                "A surface mesh whose nodes lie on CAD faces or on an analytic surface. Built by "
                "cad_mesh() or single_surface_mesh().");
  cls.def_property_readonly("node_count", [](const MeshHandle& h) { return h.get().nodeCount(); })
      .def_property_readonly("element_count",
                             [](const MeshHandle& h) { return h.get().elementCount(); })
      .def_readonly("report", &MeshHandle::report, "How the mesh was built (dict)")
      .def_readonly("source", &MeshHandle::source)
      .def(
          "positions", [](const MeshHandle& h) { return fromVec3(h.get().xyz); },
          "Node positions, float64 (N, 3) (a copy)")
      .def(
          "uv",
          [](const MeshHandle& h) {
            const auto& uv = h.get().uv;
            py::array_t<double> out({static_cast<py::ssize_t>(uv.size()), py::ssize_t(2)});
            double* p = out.mutable_data();
            for (std::size_t i = 0; i < uv.size(); ++i) {
              p[2 * i] = uv[i].x();
              p[2 * i + 1] = uv[i].y();
            }
            return out;
          },
          "Node (u,v) on node_faces() (meaningless where node_faces() is −1), (N, 2)")
      .def(
          "node_faces", [](const MeshHandle& h) { return toArray(h.get().nodeFace); },
          "Per node: the face id the node moves on, −1 when on a CAD edge or vertex")
      .def(
          "node_edges",
          [](const MeshHandle& h) {
            const auto& me = h.get();
            if (me.nodeEdge.empty()) return toArray(std::vector<std::int32_t>(me.nodeCount(), -1));
            return toArray(me.nodeEdge);
          },
          "Per node: the edge id the node lies on, −1 otherwise")
      .def(
          "node_kinds",
          [](const MeshHandle& h) {
            const auto& k = h.get().nodeKind;
            py::array_t<std::int8_t> out(static_cast<py::ssize_t>(k.size()));
            for (std::size_t i = 0; i < k.size(); ++i)
              out.mutable_data()[i] = static_cast<std::int8_t>(k[i]);
            return out;
          },
          "Per node: 0 fixed, 1 moves on its face, 2 slides along its edge")
      .def(
          "element_faces", [](const MeshHandle& h) { return toArray(h.get().elemFace); },
          "Per element: the face id it lies on")
      .def(
          "element_nodes",
          [](const MeshHandle& h, const std::vector<std::int32_t>& elements) {
            const SurfaceMesh& m = h.get();
            py::list out;
            for (std::int32_t e : elements) {
              if (e < 0 || static_cast<std::size_t>(e) >= m.elementCount())
                throw std::invalid_argument("element " + std::to_string(e) + " out of range (" +
                                            std::to_string(m.elementCount()) + " elements)");
              const std::int32_t* nd = m.elementNodes(static_cast<std::size_t>(e));
              out.append(
                  std::vector<std::int32_t>(nd, nd + m.elementSize(static_cast<std::size_t>(e))));
            }
            return out;
          },
          py::arg("elements"),
          "The node ids (0-based, the handle's) of each element of `elements`, in Gmsh order: "
          "after edge flips (optimize's rewired_elements), their new node lists")
      .def(
          "release_node_search",
          [](MeshHandle& h) {
            if (CadMesh* cm = h.cadMesh()) cm->releaseNodeSearch();
          },
          "Frees the per-node face search kept by cad_mesh(keep_node_search=True)")
      .def(
          "distances_to_shape",
          [](const MeshHandle& h, const ArrayD& points, const ArrayI& faces) {
            const CadMesh* cm = h.cadMesh();
            if (!cm)
              throw std::invalid_argument("distances_to_shape: the mesh was not made by cad_mesh");
            checkShape2D(points, 3, "points");
            checkShape1D(faces, "faces", points.shape(0));
            checkRange(faces, -1, cm->shape().faceCount(), "faces");
            const std::vector<Vec3> p = toVec3(points);
            const std::vector<std::int32_t> f = toInt32(faces);
            std::vector<double> toFace, toShape;
            {
              py::gil_scoped_release release;
              cm->distancesToShape(p, f, &toFace, &toShape);
            }
            return py::make_tuple(fromDoubles(toFace), fromDoubles(toShape));
          },
          py::arg("points"), py::arg("faces"),
          "(to_face, to_shape): per point (float64 (K, 3)), its distance to the trimmed face "
          "faces[k] (int64 (K,), shape face ids; -1: nan) with its boundary edges' 3D curves, "
          "and to the whole shape (faces, edges, lone vertices), as FreeCAD's distToShape "
          "measures them")
      .def_property_readonly(
          "keeps_node_search",
          [](const MeshHandle& h) {
            const CadMesh* cm = h.cadMesh();
            return cm && cm->keepsNodeSearch();
          },
          "Whether the per-node face search is kept (cad_mesh(keep_node_search=True))")
      .def(
          "validate", [](const MeshHandle& h) { h.get().validate(); },
          "Checks sizes, ranges and finiteness (ValueError naming the first problem)")
      .def(
          "measure",
          [](const MeshHandle& h, const std::string& name) {
            const PlanarMeasure& pm = measureByName(name);  // ValueError for unknown names
            const SurfaceMesh& me = h.get();
            MeshQuality q;
            {
              py::gil_scoped_release release;
              q = measureQuality(me, pm);
            }
            return qualityDict(q);
          },
          py::arg("measure") = "shape",
          "Per-element quality: dict with quality (1/η, 0 tangled), distortion (η), tangled "
          "(bool), min_sigma, across (bool: standing across the surface — wound along its "
          "normal at some corners and against it at others) and stats (min, max, mean, std, "
          "tangled, elements, across)")
      .def(
          "distance_to_face",
          [](const MeshHandle& h, int divisions) {
            const SurfaceMesh& me = h.get();
            std::vector<double> d;
            {
              py::gil_scoped_release release;
              d = elementDistanceToFace(me, divisions);
            }
            return fromDoubles(d);
          },
          py::arg("divisions") = kDistanceDivisions,
          "Per element: the largest distance of its interior from its face's surface, sampled "
          "on a grid of `divisions` steps per side of the reference element (float64 (E,))")
      .def(
          "jacobian_ratio",
          [](const MeshHandle& h, int divisions) {
            const SurfaceMesh& me = h.get();
            std::vector<double> r;
            {
              py::gil_scoped_release release;
              r = elementJacobianRatio(me, divisions);
            }
            return fromDoubles(r);
          },
          py::arg("divisions") = kJacobianDivisions,
          "Per element: min J / max |J| of the map from its reference element, at its nodes and "
          "on a grid of `divisions` steps per side, J = +-|x_xi x x_eta| signed by the face's "
          "normal (1 straight, <= 0 folded or wound against the face; float64 (E,))");

  m.def(
      "single_surface_mesh",
      [](const Surface& surface, const ArrayD& uv, const std::string& type, const ArrayI& conn,
         const ArrayI& fixed) {
        const ElementType t = elementTypeFromName(type);
        const py::ssize_t k = nodeCount(t);
        checkShape2D(uv, 2, "uv");
        checkFinite(uv, "uv");
        const py::ssize_t n = uv.shape(0);
        if (n == 0) throw std::invalid_argument("uv is empty: the mesh has no nodes");
        if (conn.ndim() != 2 || conn.shape(1) != k) {
          std::ostringstream s;
          s << "conn must have shape (E, " << k << ") for " << type << " elements";
          throw std::invalid_argument(s.str());
        }
        if (conn.shape(0) == 0) throw std::invalid_argument("conn is empty: no elements");
        checkRange(conn, 0, n, "conn");
        checkShape1D(fixed, "fixed");
        checkRange(fixed, 0, n, "fixed");
        auto owner = std::make_shared<SurfaceOwner>();
        owner->surface = surface.clone();
        owner->mesh =
            makeSingleSurfaceMesh(*owner->surface, toVec2(uv), t, toInt32(conn), toInt32(fixed));
        owner->mesh.validate();
        auto h = std::make_shared<MeshHandle>();
        h->mesh = &owner->mesh;
        h->owner = owner;
        h->source = "surface";
        h->report["surface"] = owner->surface->describe();
        return h;
      },
      py::arg("surface"), py::arg("uv"), py::arg("type"), py::arg("conn"),
      py::arg("fixed") = ArrayI(0),
      "Mesh on one analytic surface: nodes at φ(uv) (uv: float64 (N, 2)), elements `type` "
      "with conn int64 (E, k), nodes listed in `fixed` never move.");
  return cls;
}

}  // namespace surfmesh::bindings
