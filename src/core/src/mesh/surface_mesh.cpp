#include "surfmesh/mesh/surface_mesh.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace surfmesh {

int nodeCount(ElementType t) {
  switch (t) {
    case ElementType::Tri3:
      return 3;
    case ElementType::Quad4:
      return 4;
    case ElementType::Tri6:
      return 6;
    case ElementType::Tri10:
      return 10;
    case ElementType::Tri15:
      return 15;
    case ElementType::Tri21:
      return 21;
  }
  return 0;
}

int elementOrder(ElementType t) {
  switch (t) {
    case ElementType::Tri3:
    case ElementType::Quad4:
      return 1;
    case ElementType::Tri6:
      return 2;
    case ElementType::Tri10:
      return 3;
    case ElementType::Tri15:
      return 4;
    case ElementType::Tri21:
      return 5;
  }
  return 0;
}

int cornerCount(ElementType t) { return t == ElementType::Quad4 ? 4 : 3; }

const char* elementTypeName(ElementType t) {
  switch (t) {
    case ElementType::Tri3:
      return "tri3";
    case ElementType::Quad4:
      return "quad4";
    case ElementType::Tri6:
      return "tri6";
    case ElementType::Tri10:
      return "tri10";
    case ElementType::Tri15:
      return "tri15";
    case ElementType::Tri21:
      return "tri21";
  }
  return "?";
}

ElementType elementTypeFromName(const std::string& name) {
  for (ElementType t : {ElementType::Tri3, ElementType::Quad4, ElementType::Tri6,
                        ElementType::Tri10, ElementType::Tri15, ElementType::Tri21})
    if (name == elementTypeName(t)) return t;
  throw std::invalid_argument("unknown element type '" + name +
                              "' (known: tri3, quad4, tri6, tri10, tri15, tri21)");
}

ElementType triangleOfOrder(int p) {
  switch (p) {
    case 1:
      return ElementType::Tri3;
    case 2:
      return ElementType::Tri6;
    case 3:
      return ElementType::Tri10;
    case 4:
      return ElementType::Tri15;
    case 5:
      return ElementType::Tri21;
    default:
      break;
  }
  throw std::invalid_argument("triangle order must be 1..5, got " + std::to_string(p));
}

Vec3 SurfaceMesh::referenceNormal(int f, const Vec2& uvp) const {
  const Surface& s = *surfaces[static_cast<std::size_t>(f)];
  const int o = faceOrientation.empty() ? 1 : faceOrientation[static_cast<std::size_t>(f)];
  return (o * s.normal(uvp.x(), uvp.y())).eval();
}

void SurfaceMesh::addElement(ElementType t, const std::int32_t* nodes, int face, const Vec2* uvs) {
  const int n = surfmesh::nodeCount(t);
  if (elemOffset.empty()) elemOffset.push_back(0);
  elemType.push_back(t);
  elemFace.push_back(face);
  const Surface* s = (face >= 0 && static_cast<std::size_t>(face) < surfaces.size())
                         ? surfaces[static_cast<std::size_t>(face)]
                         : nullptr;
  Vec2 ref = Vec2::Zero();
  for (int k = 0; k < n; ++k) {
    elemNodes.push_back(nodes[k]);
    Vec2 p = uvs ? uvs[k] : uv[static_cast<std::size_t>(nodes[k])];
    if (s) p = (k == 0) ? p : s->unwrapNear(p, ref);
    if (k == 0) ref = p;
    cornerUV.push_back(p);
  }
  elemOffset.push_back(static_cast<std::int64_t>(elemNodes.size()));
}

void SurfaceMesh::validate() const {
  const std::size_t N = xyz.size();
  auto fail = [](const std::string& m) { throw std::invalid_argument(m); };
  if (N == 0) fail("mesh has no nodes");
  if (elemType.empty()) fail("mesh has no elements");
  if (uv.size() != N || nodeFace.size() != N || nodeKind.size() != N)
    fail("node arrays have inconsistent sizes");
  if (!nodeEdge.empty() && nodeEdge.size() != N) fail("nodeEdge has the wrong size");
  if (!nodeT.empty() && nodeT.size() != N) fail("nodeT has the wrong size");
  if (faceOrientation.size() != surfaces.size()) fail("faceOrientation has the wrong size");
  const std::size_t E = elemType.size();
  if (elemOffset.size() != E + 1 || elemFace.size() != E ||
      static_cast<std::size_t>(elemOffset.back()) != elemNodes.size() ||
      cornerUV.size() != elemNodes.size())
    fail("element arrays have inconsistent sizes");
  for (std::size_t i = 0; i < N; ++i) {
    if (!xyz[i].allFinite()) {
      std::ostringstream s;
      s << "node " << i << " has a non-finite coordinate";
      fail(s.str());
    }
    const NodeKind k = nodeKind[i];
    if (k == NodeKind::Face) {
      const int f = nodeFace[i];
      if (f < 0 || static_cast<std::size_t>(f) >= surfaces.size() || !surfaces[f])
        fail("face node " + std::to_string(i) + " has no valid face");
      if (!uv[i].allFinite()) fail("face node " + std::to_string(i) + " has non-finite (u,v)");
    }
    if (k == NodeKind::Edge) {
      if (nodeEdge.empty() || nodeT.empty()) fail("edge nodes need nodeEdge and nodeT");
      const int c = nodeEdge[i];
      if (c < 0 || static_cast<std::size_t>(c) >= curves.size() || !curves[c])
        fail("edge node " + std::to_string(i) + " has no valid edge");
    }
  }
  for (std::size_t e = 0; e < E; ++e) {
    const int n = elementSize(e);
    if (n != surfmesh::nodeCount(elemType[e]))
      fail("element " + std::to_string(e) + " has " + std::to_string(n) + " nodes, expected " +
           std::to_string(surfmesh::nodeCount(elemType[e])) + " for " +
           elementTypeName(elemType[e]));
    const int f = elemFace[e];
    if (f < 0 || static_cast<std::size_t>(f) >= surfaces.size() || !surfaces[f])
      fail("element " + std::to_string(e) + " has no valid face");
    const std::int32_t* nd = elementNodes(e);
    for (int k = 0; k < n; ++k) {
      if (nd[k] < 0 || static_cast<std::size_t>(nd[k]) >= N)
        fail("element " + std::to_string(e) + " references node " + std::to_string(nd[k]) +
             " out of range [0, " + std::to_string(N) + ")");
      for (int j = 0; j < k; ++j)
        if (nd[j] == nd[k])
          fail("element " + std::to_string(e) + " repeats node " + std::to_string(nd[k]));
      if (!elementUV(e)[k].allFinite())
        fail("element " + std::to_string(e) + " has a non-finite corner (u,v)");
    }
  }
}

SurfaceMesh makeSingleSurfaceMesh(const Surface& surface, const std::vector<Vec2>& uvs,
                                  ElementType type, const std::vector<std::int32_t>& conn,
                                  const std::vector<std::int32_t>& fixedNodes) {
  SurfaceMesh m;
  m.surfaces = {&surface};
  m.faceOrientation = {1};
  const std::size_t N = uvs.size();
  m.xyz.resize(N);
  m.uv.resize(N);
  m.nodeFace.assign(N, 0);
  m.nodeKind.assign(N, NodeKind::Face);
  for (std::size_t i = 0; i < N; ++i) {
    m.uv[i] = surface.wrap(uvs[i]);
    m.xyz[i] = surface.value(m.uv[i].x(), m.uv[i].y());
  }
  for (std::int32_t i : fixedNodes) {
    if (i < 0 || static_cast<std::size_t>(i) >= N)
      throw std::invalid_argument("fixed node " + std::to_string(i) + " out of range");
    m.nodeKind[static_cast<std::size_t>(i)] = NodeKind::Fixed;
  }
  const int k = nodeCount(type);
  if (conn.size() % static_cast<std::size_t>(k) != 0)
    throw std::invalid_argument("connectivity length is not a multiple of the element size");
  for (std::size_t e = 0; e < conn.size() / k; ++e) {
    for (int j = 0; j < k; ++j) {
      const std::int32_t id = conn[e * k + j];
      if (id < 0 || static_cast<std::size_t>(id) >= N)
        throw std::invalid_argument("element " + std::to_string(e) + " references node " +
                                    std::to_string(id) + " out of range");
    }
    m.addElement(type, conn.data() + e * k, 0);
  }
  return m;
}

void syncFaceNodes(SurfaceMesh& mesh) {
  for (std::size_t i = 0; i < mesh.nodeCount(); ++i)
    if (mesh.nodeKind[i] == NodeKind::Face) {
      const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.nodeFace[i])];
      mesh.uv[i] = s.wrap(mesh.uv[i]);
      mesh.xyz[i] = s.value(mesh.uv[i].x(), mesh.uv[i].y());
    }
  for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
    const std::int32_t* nd = mesh.elementNodes(e);
    Vec2* cuv = mesh.cornerUV.data() + mesh.elemOffset[e];
    const Surface& s = *mesh.surfaces[static_cast<std::size_t>(mesh.elemFace[e])];
    const int n = mesh.elementSize(e);
    for (int k = 0; k < n; ++k) {
      const std::size_t i = static_cast<std::size_t>(nd[k]);
      if (mesh.nodeKind[i] == NodeKind::Face && mesh.nodeFace[i] == mesh.elemFace[e])
        cuv[k] = s.unwrapNear(mesh.uv[i], cuv[k]);
    }
  }
}

}  // namespace surfmesh
