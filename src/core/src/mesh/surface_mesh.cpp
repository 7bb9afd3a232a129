#include "surfmesh/mesh/surface_mesh.h"

#include "surfmesh/diagnostic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace surfmesh {

bool isElementTypeCode(int code) { return code >= 0 && code <= 6; }

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
    case ElementType::Quad8:
      return 8;
  }
  throw std::invalid_argument("unsupported element type code " +
                              std::to_string(static_cast<int>(t)) +
                              " (supported: tri3, quad4, tri6, tri10, tri15, tri21, quad8)");
}

int elementOrder(ElementType t) {
  switch (t) {
    case ElementType::Tri3:
    case ElementType::Quad4:
      return 1;
    case ElementType::Tri6:
    case ElementType::Quad8:
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
    case ElementType::Quad8:
      return "quad8";
  }
  return "?";
}

ElementType elementTypeFromName(const std::string& name) {
  for (ElementType t :
       {ElementType::Tri3, ElementType::Quad4, ElementType::Tri6, ElementType::Tri10,
        ElementType::Tri15, ElementType::Tri21, ElementType::Quad8})
    if (name == elementTypeName(t)) return t;
  throw std::invalid_argument("unknown element type '" + name +
                              "' (known: tri3, quad4, tri6, tri10, tri15, tri21, quad8)");
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
  return referenceNormal(f, uvp, *surfaces[static_cast<std::size_t>(f)]);
}

Vec3 SurfaceMesh::referenceNormal(int f, const Vec2& uvp, const Surface& s) const {
  const int o = faceOrientation.empty() ? 1 : faceOrientation[static_cast<std::size_t>(f)];
  return (o * s.normal(uvp.x(), uvp.y())).eval();
}

Vec3 SurfaceMesh::referenceNormalAcrossPole(int f, const Vec2& uvp, const Surface& s) const {
  const int o = faceOrientation.empty() ? 1 : faceOrientation[static_cast<std::size_t>(f)];
  return (o * s.normalAcrossPole(uvp.x(), uvp.y())).eval();
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

namespace {

[[noreturn]] void fail(const std::string& m) { throw std::invalid_argument(m); }
[[noreturn]] void fail(Diagnostic d) { throw InputError(std::move(d)); }

std::string vecText(const Vec3& p) {
  std::ostringstream s;
  s.precision(17);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

/// Two nodes used by elements at exactly the same position.
void checkDuplicateNodes(const SurfaceMesh& m) {
  // The nodes the elements use, ascending.
  std::vector<std::int32_t> used(m.elemNodes.begin(), m.elemNodes.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  // Sorted by position, then index (a total order: any sort gives the same sequence); the
  // positions are copied next to the indices so that the sort reads contiguous memory.
  struct Key {
    double x, y, z;
    std::int32_t i;
  };
  {
    std::vector<Key> keys(used.size());
    for (std::size_t k = 0; k < used.size(); ++k) {
      const Vec3& p = m.xyz[static_cast<std::size_t>(used[k])];
      keys[k] = {p.x(), p.y(), p.z(), used[k]};
    }
    std::sort(keys.begin(), keys.end(), [](const Key& p, const Key& q) {
      if (p.x != q.x) return p.x < q.x;
      if (p.y != q.y) return p.y < q.y;
      if (p.z != q.z) return p.z < q.z;
      return p.i < q.i;
    });
    for (std::size_t k = 0; k < used.size(); ++k) used[k] = keys[k].i;
  }  // (freed here: GCC 14 misreads a move-assignment of an empty vector as a bad delete)
  std::size_t count = 0;
  std::int32_t a0 = -1, b0 = -1;
  for (std::size_t k = 1; k < used.size(); ++k)
    if (m.xyz[static_cast<std::size_t>(used[k])] == m.xyz[static_cast<std::size_t>(used[k - 1])]) {
      if (count++ == 0) {
        a0 = used[k - 1];
        b0 = used[k];
      }
    }
  if (count) {
    Diagnostic d;
    d.code = code::kDuplicateNodes;
    d.count = static_cast<std::int64_t>(count);
    d.nodes = {a0, b0};
    d.format = "mesh has {count} duplicate node" + std::string(count > 1 ? "s" : "") +
               " (used by elements at the position of another node), e.g. nodes {node} and "
               "{node1} at " +
               vecText(m.xyz[static_cast<std::size_t>(a0)]) +
               ": the mesh is not conforming there; merge coincident nodes first";
    fail(std::move(d));
  }
}

/// Elements with the same corner nodes.
void checkDuplicateElements(const SurfaceMesh& m) {
  const std::size_t E = m.elementCount();
  // Duplicate elements.
  // Sorted corners (−1 padded) and the element, in lexicographic order: counted into buckets
  // by their first two entries (−1 and the smallest corner for triangles, which come first; the
  // smallest corner for quads), each bucket then sorted on its own.
  const std::size_t N = m.nodeCount();
  std::vector<std::array<std::int32_t, 5>> unsorted(E);
  std::vector<std::size_t> start(2 * N + 1, 0);
  auto bucket = [N](const std::array<std::int32_t, 5>& k) {
    return k[0] < 0 ? static_cast<std::size_t>(k[1]) : N + static_cast<std::size_t>(k[0]);
  };
  for (std::size_t e = 0; e < E; ++e) {
    const int nc = cornerCount(m.elemType[e]);
    std::array<std::int32_t, 5> k = {-1, -1, -1, -1, static_cast<std::int32_t>(e)};
    std::copy(m.elementNodes(e), m.elementNodes(e) + nc, k.begin());
    std::sort(k.begin(), k.begin() + 4);
    unsorted[e] = k;
    ++start[bucket(k) + 1];
  }
  for (std::size_t i = 0; i + 1 < start.size(); ++i) start[i + 1] += start[i];
  std::vector<std::array<std::int32_t, 5>> keys(E);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (const auto& k : unsorted) keys[fill[bucket(k)]++] = k;
  }
  unsorted = std::vector<std::array<std::int32_t, 5>>();
  for (std::size_t b = 0; b + 1 < start.size(); ++b)
    if (start[b + 1] - start[b] > 1)
      std::sort(keys.begin() + static_cast<std::ptrdiff_t>(start[b]),
                keys.begin() + static_cast<std::ptrdiff_t>(start[b + 1]));
  std::size_t dup = 0;
  std::int32_t e0 = -1, e1 = -1;
  for (std::size_t k = 1; k < E; ++k)
    if (std::equal(keys[k].begin(), keys[k].begin() + 4, keys[k - 1].begin()) && dup++ == 0) {
      e0 = keys[k - 1][4];
      e1 = keys[k][4];
    }
  if (dup) {
    Diagnostic d;
    d.code = code::kDuplicateElements;
    d.count = static_cast<std::int64_t>(dup);
    d.elements = {e0, e1};
    d.format = "mesh has {count} duplicate element" + std::string(dup > 1 ? "s" : "") +
               " (same corner nodes as another element), e.g. elements {element} and {element1}";
    fail(std::move(d));
  }
}

/// Elements with the same corner nodes; mesh edges shared by more than two elements of one
/// face.
void checkTopology(const SurfaceMesh& m) {
  const std::size_t E = m.elementCount();
  checkDuplicateElements(m);
  // Edges per face.
  struct EdgeUse {
    std::int32_t a, b, face, elem;
    bool operator<(const EdgeUse& o) const {
      return std::tie(a, b, face, elem) < std::tie(o.a, o.b, o.face, o.elem);
    }
  };
  // Sorted by (a, b, face, elem): counted into buckets by a (node ids are < N), each bucket
  // (the few edges at one node) then sorted on its own.
  const std::size_t N = m.nodeCount();
  std::vector<std::size_t> start(N + 1, 0);
  std::size_t corners = 0;
  for (std::size_t e = 0; e < E; ++e) {
    const int nc = cornerCount(m.elemType[e]);
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < nc; ++k)
      ++start[static_cast<std::size_t>(std::min(nd[k], nd[(k + 1) % nc])) + 1];
    corners += static_cast<std::size_t>(nc);
  }
  for (std::size_t i = 0; i < N; ++i) start[i + 1] += start[i];
  std::vector<EdgeUse> uses(corners);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t e = 0; e < E; ++e) {
      const int nc = cornerCount(m.elemType[e]);
      const std::int32_t* nd = m.elementNodes(e);
      for (int k = 0; k < nc; ++k) {
        const std::int32_t a = nd[k], b = nd[(k + 1) % nc];
        uses[fill[static_cast<std::size_t>(std::min(a, b))]++] = {
            std::min(a, b), std::max(a, b), m.elemFace[e], static_cast<std::int32_t>(e)};
      }
    }
  }
  for (std::size_t i = 0; i < N; ++i)
    if (start[i + 1] - start[i] > 1)
      std::sort(uses.begin() + static_cast<std::ptrdiff_t>(start[i]),
                uses.begin() + static_cast<std::ptrdiff_t>(start[i + 1]));
  std::size_t bad = 0, firstBegin = 0, firstEnd = 0;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].a == uses[i].a && uses[j].b == uses[i].b &&
           uses[j].face == uses[i].face)
      ++j;
    if (j - i > 2 && bad++ == 0) {
      firstBegin = i;
      firstEnd = j;
    }
    i = j;
  }
  if (bad) {
    const EdgeUse& u = uses[firstBegin];
    Diagnostic d;
    d.code = code::kNonManifold;
    d.count = static_cast<std::int64_t>(bad);
    d.nodes = {u.a, u.b};
    d.faces = {u.face};
    d.format = "mesh is non-manifold: {count} edge" + std::string(bad > 1 ? "s are" : " is") +
               " shared by more than two elements of one face, e.g. the edge between nodes "
               "{node} and {node1} is shared by " +
               std::to_string(firstEnd - firstBegin) + " elements (elements ";
    for (std::size_t k = firstBegin; k < firstEnd; ++k) {
      d.format +=
          (k > firstBegin ? ", {element" : "{element") + std::to_string(d.elements.size()) + "}";
      d.elements.push_back(uses[k].elem);
    }
    d.format += ") on {face}";
    fail(std::move(d));
  }
}

}  // namespace

void SurfaceMesh::validate() const {
  const std::size_t N = xyz.size();
  if (N == 0) fail("mesh has no nodes");
  if (elemType.empty()) fail("mesh has no elements");
  if (uv.size() != N || nodeFace.size() != N || nodeKind.size() != N)
    fail("node arrays have inconsistent sizes: " + std::to_string(N) + " positions, " +
         std::to_string(uv.size()) + " (u,v), " + std::to_string(nodeFace.size()) +
         " node faces, " + std::to_string(nodeKind.size()) + " node kinds");
  if (!nodeEdge.empty() && nodeEdge.size() != N) fail("nodeEdge has the wrong size");
  if (!nodeT.empty() && nodeT.size() != N) fail("nodeT has the wrong size");
  if (faceOrientation.size() != surfaces.size()) fail("faceOrientation has the wrong size");
  for (std::size_t f = 0; f < faceOrientation.size(); ++f)
    if (faceOrientation[f] != 1 && faceOrientation[f] != -1)
      fail("faceOrientation[" + std::to_string(f) + "] must be +1 or -1, got " +
           std::to_string(faceOrientation[f]));
  const std::size_t E = elemType.size();
  if (elemOffset.size() != E + 1 || elemFace.size() != E || cornerUV.size() != elemNodes.size())
    fail("element arrays have inconsistent sizes: " + std::to_string(E) + " types, " +
         std::to_string(elemOffset.size()) + " offsets (expected " + std::to_string(E + 1) + "), " +
         std::to_string(elemFace.size()) + " element faces, " + std::to_string(elemNodes.size()) +
         " element nodes, " + std::to_string(cornerUV.size()) + " corner (u,v)");
  if (elemOffset[0] != 0) fail("elemOffset[0] must be 0, got " + std::to_string(elemOffset[0]));
  for (std::size_t e = 0; e < E; ++e)
    if (elemOffset[e + 1] < elemOffset[e])
      fail("element offsets decrease at element " + std::to_string(e));
  if (static_cast<std::size_t>(elemOffset.back()) != elemNodes.size())
    fail("element offsets end at " + std::to_string(elemOffset.back()) + ", but there are " +
         std::to_string(elemNodes.size()) + " element nodes");
  for (std::size_t i = 0; i < N; ++i) {
    if (!xyz[i].allFinite())
      fail("node " + std::to_string(i) +
           " has a non-finite coordinate (NaN or inf): " + vecText(xyz[i]));
    const NodeKind k = nodeKind[i];
    if (k == NodeKind::Face) {
      const int f = nodeFace[i];
      if (f < 0 || static_cast<std::size_t>(f) >= surfaces.size() || !surfaces[f])
        fail("face node " + std::to_string(i) + " has no valid face (face id " + std::to_string(f) +
             ")");
      if (!uv[i].allFinite()) fail("face node " + std::to_string(i) + " has non-finite (u,v)");
    } else if (k == NodeKind::Edge) {
      if (nodeEdge.empty() || nodeT.empty()) fail("edge nodes need nodeEdge and nodeT");
      const int c = nodeEdge[i];
      if (c < 0 || static_cast<std::size_t>(c) >= curves.size() || !curves[c])
        fail("edge node " + std::to_string(i) + " has no valid edge (edge id " + std::to_string(c) +
             ")");
      if (!std::isfinite(nodeT[i]))
        fail("edge node " + std::to_string(i) + " has a non-finite curve parameter");
    } else if (k != NodeKind::Fixed) {
      fail("node " + std::to_string(i) + " has an unknown kind " +
           std::to_string(static_cast<int>(k)));
    }
  }
  int order = 0;
  std::size_t orderElem = 0;
  for (std::size_t e = 0; e < E; ++e) {
    const int code = static_cast<int>(elemType[e]);
    if (!isElementTypeCode(code))
      fail("element " + std::to_string(e) + " has an unsupported element type (code " +
           std::to_string(code) + "; supported: tri3, quad4, tri6, tri10, tri15, tri21, quad8)");
    const int n = elementSize(e);
    if (n != surfmesh::nodeCount(elemType[e]))
      fail("element " + std::to_string(e) + " has " + std::to_string(n) + " nodes, expected " +
           std::to_string(surfmesh::nodeCount(elemType[e])) + " for " +
           elementTypeName(elemType[e]));
    const int p = elementOrder(elemType[e]);
    if (e == 0) {
      order = p;
    } else if (p != order) {
      Diagnostic d;
      d.code = code::kMixedOrders;
      d.count = 2;
      d.elements = {static_cast<std::int64_t>(orderElem), static_cast<std::int64_t>(e)};
      d.format = "mesh mixes element orders: element {element} is " +
                 std::string(elementTypeName(elemType[orderElem])) + " (order " +
                 std::to_string(order) + "), element {element1} is " +
                 elementTypeName(elemType[e]) + " (order " + std::to_string(p) +
                 "); use elements of one order";
      fail(std::move(d));
    }
    const int f = elemFace[e];
    if (f < 0 || static_cast<std::size_t>(f) >= surfaces.size() || !surfaces[f])
      fail("element " + std::to_string(e) + " has no valid face (face id " + std::to_string(f) +
           ")");
    const std::int32_t* nd = elementNodes(e);
    for (int k = 0; k < n; ++k) {
      if (nd[k] < 0 || static_cast<std::size_t>(nd[k]) >= N)
        fail("element " + std::to_string(e) + " references node " + std::to_string(nd[k]) +
             " out of range [0, " + std::to_string(N) + ")");
      for (int j = 0; j < k; ++j)
        if (nd[j] == nd[k])
          fail("element " + std::to_string(e) + " repeats node " + std::to_string(nd[k]) +
               " (local positions " + std::to_string(j) + " and " + std::to_string(k) + ")");
      const Vec2& c = elementUV(e)[k];
      if (!c.allFinite()) fail("element " + std::to_string(e) + " has a non-finite corner (u,v)");
      // A face node's corner (u,v) on its own face is its (u,v), up to whole periods.
      const std::size_t n = static_cast<std::size_t>(nd[k]);
      if (nodeKind[n] == NodeKind::Face && nodeFace[n] == f) {
        const Vec2 d = surfaces[static_cast<std::size_t>(f)]->unwrapNear(uv[n], c) - c;
        if (!(d.cwiseAbs().maxCoeff() <= 1e-9 * (1.0 + c.cwiseAbs().maxCoeff())))
          fail("element " + std::to_string(e) + ": the corner (u,v) of node " + std::to_string(n) +
               " does not match the node's (u,v) on face " + std::to_string(f));
      }
    }
  }
  checkDuplicateNodes(*this);
  checkTopology(*this);
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
