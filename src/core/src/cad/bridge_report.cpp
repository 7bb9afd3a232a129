// SurfMesh — the CAD bridge's report text: node class names, the summary and the note on the
// nodes of no element.
#include "recovery.h"

#include <algorithm>
#include <cstddef>
#include <sstream>
#include <string>
#include <utility>

namespace surfmesh {

const char* nodeClassName(NodeClass c) {
  switch (c) {
    case NodeClass::Vertex:
      return "vertex";
    case NodeClass::Edge:
      return "edge";
    case NodeClass::Face:
      return "face";
    case NodeClass::None:
      return "none";
  }
  return "?";
}

namespace cad_detail {

/// The start of the note on the nodes of no element, up to the entity the farthest lies on.
constexpr const char* kLooseNodesFormat =
    "{count} nodes belong to no element (e.g. nodes of edge or vertex elements); they are kept "
    "fixed and lie on the shape: {on_vertices} on CAD vertices, {on_edges} on CAD edges, "
    "{on_faces} on faces; farthest: node {node} ({distance} from ";

Diagnostic looseNodesNote(const BridgeReport& r) {
  std::size_t on[3] = {0, 0, 0}, worst = 0;
  for (std::size_t k = 0; k < r.looseNodes.size(); ++k) {
    const NodeClass c = r.looseClass[k];
    if (c == NodeClass::Vertex || c == NodeClass::Edge || c == NodeClass::Face)
      ++on[static_cast<int>(c)];
    if (r.looseDistance[k] > r.looseDistance[worst]) worst = k;
  }
  Diagnostic d;
  d.code = code::kUnusedNodes;
  d.count = static_cast<std::int64_t>(r.looseNodes.size());
  d.nodes.push_back(r.looseNodes[worst]);
  for (std::size_t k = 0; k < std::min<std::size_t>(r.looseNodes.size(), 5); ++k)
    d.nodes.push_back(r.looseNodes[k]);
  const char* entity = nameEntity(d, r.looseClass[worst], r.looseEntity[worst]);
  d.values = {{"on_vertices", static_cast<double>(on[0])},
              {"on_edges", static_cast<double>(on[1])},
              {"on_faces", static_cast<double>(on[2])},
              {"distance", r.looseDistance[worst]}};
  d.format = std::string(kLooseNodesFormat) + entity + "); e.g. nodes {nodes1}";
  return d;
}

}  // namespace cad_detail

void BridgeReport::warn(Diagnostic d) {
  warnings.push_back(d.render());
  diagnostics.push_back(std::move(d));
}

std::string BridgeReport::summary() const {
  std::ostringstream os;
  os << nodeClass.size() << " nodes: " << vertexNodes << " on vertices (" << poleNodes
     << " poles), " << edgeNodes << " on edges, " << faceNodes << " inside faces";
  if (unusedNodes) os << ", " << unusedNodes << " in no element";
  os << "; " << fixedNodes << " fixed, " << slidingNodes << " sliding\n";
  std::size_t elems = 0;
  for (int c : faceElements) elems += static_cast<std::size_t>(c);
  os << elems << " elements on " << facesUsed << " faces; max distance to the shape " << maxDistance
     << " (node " << worstNode << ", tolerance " << tolerance << ")\n";
  if (!flippedFaces.empty()) {
    os << flippedFaces.size() << " face(s) meshed with the opposite winding (flipped): ";
    for (std::size_t i = 0; i < flippedFaces.size(); ++i) os << (i ? ", " : "") << flippedFaces[i];
    os << "\n";
  }
  for (const auto& w : warnings) os << "warning: " << w << "\n";
  return os.str();
}

}  // namespace surfmesh
