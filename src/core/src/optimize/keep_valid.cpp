// Never worse, element by element (see keep_valid.h).
//
// The sweeps keep every valid submesh valid at each node move, and the escapes keep a move
// only when it leaves fewer tangled elements around it: a joint move may still trade one valid
// element for two tangled ones, and the curved elements' certificate (exact, on the whole
// element) sees folds the optimizer's quadrature points do not. This is the last word: the
// nodes of an element the run made invalid go back where they were, ring by ring until none is.
#include "keep_valid.h"

namespace surfmesh::detail {

void PutBack::undo(SurfaceMesh& mesh) const {
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    mesh.xyz[nodes[k]] = xyz[k];
    mesh.uv[nodes[k]] = uv[k];
    if (!mesh.nodeT.empty()) mesh.nodeT[nodes[k]] = nodeT[k];
  }
  for (const auto& [slot, value] : corners) mesh.cornerUV[slot] = value;
}

std::size_t keepValidElements(SurfaceMesh& mesh, const InputPositions& input,
                              const std::vector<unsigned char>& grade0,
                              const PlanarMeasure& measure, MeshQuality* q, PutBack* undo) {
  const std::size_t N = mesh.nodeCount(), E = mesh.elementCount();
  std::vector<unsigned char> back;  // put back already (allocated on the first)
  std::size_t restored = 0;
  for (;;) {
    // The nodes of the elements worse now than in the input, not yet put back.
    std::vector<std::size_t> now;
    for (std::size_t e = 0; e < E; ++e) {
      if (q->grade(e) <= grade0[e]) continue;
      if (back.empty()) back.assign(N, 0);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const std::size_t i = static_cast<std::size_t>(nd[k]);
        if (!back[i]) {
          back[i] = 2;  // this round
          now.push_back(i);
        }
      }
    }
    // None left (or, were an element at its input's positions still invalid, nothing more
    // to put back).
    if (now.empty()) return restored;
    for (const std::size_t i : now) {
      if (undo) {
        undo->nodes.push_back(i);
        undo->xyz.push_back(mesh.xyz[i]);
        undo->uv.push_back(mesh.uv[i]);
        if (!mesh.nodeT.empty()) undo->nodeT.push_back(mesh.nodeT[i]);
      }
      if (mesh.xyz[i] != input.xyz[i]) ++restored;
      mesh.xyz[i] = input.xyz[i];
      mesh.uv[i] = input.uv[i];
      if (!mesh.nodeT.empty()) mesh.nodeT[i] = input.nodeT[i];
    }
    // The corner (u,v) of the nodes put back, in every element (as the input had them).
    for (std::size_t e = 0; e < E; ++e) {
      const std::size_t off = static_cast<std::size_t>(mesh.elemOffset[e]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const std::size_t c = off + static_cast<std::size_t>(k);
        if (back[static_cast<std::size_t>(nd[k])] == 2 && mesh.cornerUV[c] != input.cornerUV[c]) {
          if (undo) undo->corners.emplace_back(c, mesh.cornerUV[c]);
          mesh.cornerUV[c] = input.cornerUV[c];
        }
      }
    }
    for (const std::size_t i : now) back[i] = 1;
    *q = measureQuality(mesh, measure);
  }
}

}  // namespace surfmesh::detail
