// SurfMesh — BRepMesh triangulation of a CadShape merged into one mesh (see occ_mesher.h).
#include "surfmesh/cad/occ_mesher.h"

#include <BRepBuilderAPI_Copy.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Poly_PolygonOnTriangulation.hxx>
#include <Poly_Triangulation.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>

#include <algorithm>
#include <array>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace surfmesh {

namespace {

struct UnionFind {
  std::vector<std::int32_t> parent;
  std::int32_t add() {
    parent.push_back(static_cast<std::int32_t>(parent.size()));
    return parent.back();
  }
  std::int32_t find(std::int32_t a) {
    while (parent[static_cast<std::size_t>(a)] != a) {
      parent[static_cast<std::size_t>(a)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
      a = parent[static_cast<std::size_t>(a)];
    }
    return a;
  }
  void unite(std::int32_t a, std::int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  }
};

int rank(NodeClass c) {
  switch (c) {
    case NodeClass::Vertex:
      return 3;
    case NodeClass::Edge:
      return 2;
    case NodeClass::Face:
      return 1;
    default:
      return 0;
  }
}

}  // namespace

OccMesh meshWithBRepMesh(const CadShape& shape, double linearDeflection, double angularDeflection,
                         bool relative) {
  if (!(linearDeflection > 0.0)) throw std::invalid_argument("meshWithBRepMesh: deflection <= 0");
  BRepBuilderAPI_Copy copier(shape.shape(), Standard_False, Standard_False);
  const TopoDS_Shape work = copier.Shape();
  BRepMesh_IncrementalMesh mesher(work, linearDeflection, relative, angularDeflection,
                                  Standard_True);
  TopTools_IndexedMapOfShape faces, edges, vertices;
  TopExp::MapShapes(work, TopAbs_FACE, faces);
  TopExp::MapShapes(work, TopAbs_EDGE, edges);
  TopExp::MapShapes(work, TopAbs_VERTEX, vertices);
  if (faces.Extent() != shape.faceCount() || edges.Extent() != shape.edgeCount())
    throw std::runtime_error("meshWithBRepMesh: the copy changed the topology");

  OccMesh out;
  UnionFind uf;
  std::vector<Vec3> pts;
  std::vector<NodeClass> cls;
  std::vector<std::int32_t> ent;
  std::vector<std::array<std::int32_t, 3>> tris;
  std::vector<std::int32_t> triFace;
  // First registration of each edge polygon: global ids and the first node's position.
  std::unordered_map<int, std::vector<std::int32_t>> edgeNodes;
  auto mark = [&](std::int32_t g, NodeClass c, int id) {
    const std::size_t i = static_cast<std::size_t>(g);
    if (rank(c) > rank(cls[i])) {
      cls[i] = c;
      ent[i] = id;
    }
  };

  for (int f = 1; f <= faces.Extent(); ++f) {
    const TopoDS_Face& face = TopoDS::Face(faces(f));
    TopLoc_Location loc;
    const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
    if (tri.IsNull()) {
      out.unmeshedFaces.push_back(f - 1);
      continue;
    }
    const gp_Trsf trsf = loc.Transformation();
    std::vector<std::int32_t> local(static_cast<std::size_t>(tri->NbNodes()) + 1);
    for (int i = 1; i <= tri->NbNodes(); ++i) {
      const gp_Pnt p = tri->Node(i).Transformed(trsf);
      local[static_cast<std::size_t>(i)] = uf.add();
      pts.emplace_back(p.X(), p.Y(), p.Z());
      cls.push_back(NodeClass::Face);
      ent.push_back(f - 1);
    }
    for (TopExp_Explorer ex(face, TopAbs_EDGE); ex.More(); ex.Next()) {
      const TopoDS_Edge& edge = TopoDS::Edge(ex.Current());
      const int e = edges.FindIndex(edge) - 1;
      const Handle(Poly_PolygonOnTriangulation) poly =
          BRep_Tool::PolygonOnTriangulation(edge, tri, loc);
      if (poly.IsNull() || e < 0) continue;
      const int n = poly->NbNodes();
      std::vector<std::int32_t> g(static_cast<std::size_t>(n));
      for (int k = 1; k <= n; ++k)
        g[static_cast<std::size_t>(k - 1)] = local[static_cast<std::size_t>(poly->Node(k))];
      const bool degenerated = BRep_Tool::Degenerated(edge);
      const bool seam = BRep_Tool::IsClosed(edge, face);
      TopoDS_Vertex v1, v2;
      TopExp::Vertices(TopoDS::Edge(edge.Oriented(TopAbs_FORWARD)), v1, v2);
      const int iv1 = vertices.FindIndex(v1) - 1, iv2 = vertices.FindIndex(v2) - 1;
      for (int k = 0; k < n; ++k) {
        const std::int32_t gk = g[static_cast<std::size_t>(k)];
        if (degenerated) {
          mark(gk, NodeClass::Vertex, iv1);
          uf.unite(gk, g[0]);
        } else if (k == 0 || k == n - 1) {
          const Vec3& p = pts[static_cast<std::size_t>(gk)];
          const gp_Pnt a = BRep_Tool::Pnt(v1), b = BRep_Tool::Pnt(v2);
          const double da = (p - Vec3(a.X(), a.Y(), a.Z())).norm();
          const double db = (p - Vec3(b.X(), b.Y(), b.Z())).norm();
          mark(gk, NodeClass::Vertex, da <= db ? iv1 : iv2);
        } else if (!seam) {
          mark(gk, NodeClass::Edge, e);
        }
      }
      auto it = edgeNodes.find(e);
      if (it == edgeNodes.end()) {
        edgeNodes.emplace(e, g);
      } else if (static_cast<int>(it->second.size()) == n) {
        // Same discretization seen from another face (or the other side of a seam): match
        // the direction by the first node's position.
        const auto& r = it->second;
        const Vec3& p0 = pts[static_cast<std::size_t>(g[0])];
        const bool same = (pts[static_cast<std::size_t>(r.front())] - p0).norm() <=
                          (pts[static_cast<std::size_t>(r.back())] - p0).norm();
        for (int k = 0; k < n; ++k)
          uf.unite(g[static_cast<std::size_t>(k)],
                   r[static_cast<std::size_t>(same ? k : n - 1 - k)]);
      }
    }
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int t = 1; t <= tri->NbTriangles(); ++t) {
      int a = 0, b = 0, c = 0;
      tri->Triangle(t).Get(a, b, c);
      if (reversed) std::swap(b, c);
      tris.push_back({local[static_cast<std::size_t>(a)], local[static_cast<std::size_t>(b)],
                      local[static_cast<std::size_t>(c)]});
      triFace.push_back(f - 1);
    }
  }

  // Compact the merged nodes.
  const std::size_t total = pts.size();
  std::vector<std::int32_t> newId(total, -1);
  for (std::size_t i = 0; i < total; ++i) {
    const std::int32_t r = uf.find(static_cast<std::int32_t>(i));
    if (newId[static_cast<std::size_t>(r)] < 0) {
      newId[static_cast<std::size_t>(r)] = static_cast<std::int32_t>(out.input.nodes.size());
      out.input.nodes.push_back(pts[static_cast<std::size_t>(r)]);
      out.nodeClass.push_back(NodeClass::Face);
      out.nodeEntity.push_back(-1);
    }
    newId[i] = newId[static_cast<std::size_t>(r)];
  }
  for (std::size_t i = 0; i < total; ++i) {
    const std::size_t j = static_cast<std::size_t>(newId[i]);
    if (out.nodeEntity[j] < 0 || rank(cls[i]) > rank(out.nodeClass[j])) {
      out.nodeClass[j] = cls[i];
      out.nodeEntity[j] = ent[i];
    }
  }
  for (std::size_t t = 0; t < tris.size(); ++t) {
    const std::int32_t a = newId[static_cast<std::size_t>(tris[t][0])];
    const std::int32_t b = newId[static_cast<std::size_t>(tris[t][1])];
    const std::int32_t c = newId[static_cast<std::size_t>(tris[t][2])];
    if (a == b || b == c || a == c) {
      ++out.droppedTriangles;
      continue;
    }
    out.input.conn.insert(out.input.conn.end(), {a, b, c});
    out.input.types.push_back(ElementType::Tri3);
    out.elemFace.push_back(triFace[t]);
  }
  out.droppedCoincident = dropCoincidentTriangles(out.input, &out.elemFace);
  return out;
}

std::size_t dropCoincidentTriangles(MeshInput& mesh, std::vector<std::int32_t>* elemFace) {
  const std::size_t E = mesh.types.size();
  for (std::size_t e = 0; e < E; ++e)
    if (mesh.types[e] != ElementType::Tri3)
      throw std::invalid_argument("dropCoincidentTriangles: element " + std::to_string(e) +
                                  " is not a tri3");
  if (mesh.conn.size() != 3 * E || (elemFace && elemFace->size() != E))
    throw std::invalid_argument("dropCoincidentTriangles: array sizes do not match");
  // Group the triangles by their sorted nodes; the winding is the parity of the sort.
  std::map<std::array<std::int32_t, 3>, std::vector<std::size_t>> groups;
  std::vector<int> winding(E);
  for (std::size_t e = 0; e < E; ++e) {
    std::array<std::int32_t, 3> k = {mesh.conn[3 * e], mesh.conn[3 * e + 1], mesh.conn[3 * e + 2]};
    const int inversions = (k[0] > k[1]) + (k[0] > k[2]) + (k[1] > k[2]);
    winding[e] = inversions % 2 == 0 ? 1 : -1;
    std::sort(k.begin(), k.end());
    groups[k].push_back(e);
  }
  std::vector<char> keep(E, 1);
  std::size_t removed = 0;
  for (const auto& g : groups) {
    const std::vector<std::size_t>& members = g.second;
    if (members.size() < 2) continue;
    int net = 0;
    for (std::size_t e : members) net += winding[e];
    bool kept = false;
    for (std::size_t e : members) {
      const bool stays = !kept && net != 0 && winding[e] == (net > 0 ? 1 : -1);
      kept = kept || stays;
      if (!stays) {
        keep[e] = 0;
        ++removed;
      }
    }
  }
  if (removed == 0) return 0;
  std::vector<std::int32_t> conn, faces;
  conn.reserve(3 * (E - removed));
  for (std::size_t e = 0; e < E; ++e) {
    if (!keep[e]) continue;
    conn.insert(conn.end(), mesh.conn.begin() + static_cast<std::ptrdiff_t>(3 * e),
                mesh.conn.begin() + static_cast<std::ptrdiff_t>(3 * e + 3));
    if (elemFace) faces.push_back((*elemFace)[e]);
  }
  mesh.conn = std::move(conn);
  mesh.types.assign(E - removed, ElementType::Tri3);
  mesh.offsets.clear();
  if (elemFace) *elemFace = std::move(faces);
  return removed;
}

}  // namespace surfmesh
