#include "sweep_support.h"

namespace surfmesh {
namespace detail {

Incidence buildIncidence(const SurfaceMesh& m) {
  Incidence inc;
  const std::size_t N = m.nodeCount();
  inc.offset.assign(N + 1, 0);
  for (std::int32_t n : m.elemNodes) ++inc.offset[static_cast<std::size_t>(n) + 1];
  for (std::size_t i = 0; i < N; ++i) inc.offset[i + 1] += inc.offset[i];
  inc.elem.resize(m.elemNodes.size());
  inc.local.resize(m.elemNodes.size());
  std::vector<std::int64_t> fill(inc.offset.begin(), inc.offset.end() - 1);
  for (std::size_t e = 0; e < m.elementCount(); ++e) {
    const std::int32_t* nd = m.elementNodes(e);
    for (int k = 0; k < m.elementSize(e); ++k) {
      const std::int64_t p = fill[static_cast<std::size_t>(nd[k])]++;
      inc.elem[static_cast<std::size_t>(p)] = static_cast<std::int32_t>(e);
      inc.local[static_cast<std::size_t>(p)] = static_cast<std::int8_t>(k);
    }
  }
  return inc;
}

std::vector<std::vector<std::int32_t>> colorNodes(const SurfaceMesh& mesh, const Incidence& inc) {
  const std::size_t N = mesh.nodeCount();
  std::vector<int> color(N, -1);
  std::vector<std::vector<std::int32_t>> colors;
  std::vector<std::int64_t> mark;  // mark[c] == i when color c is used by a neighbour of i
  for (std::size_t i = 0; i < N; ++i) {
    if (!isMovable(mesh.nodeKind[i])) continue;
    const auto ii = static_cast<std::int64_t>(i);
    for (std::int64_t p = inc.offset[i]; p < inc.offset[i + 1]; ++p) {
      const std::size_t e = static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* nd = mesh.elementNodes(e);
      for (int k = 0; k < mesh.elementSize(e); ++k) {
        const int c = color[static_cast<std::size_t>(nd[k])];
        if (c >= 0) mark[static_cast<std::size_t>(c)] = ii;
      }
    }
    std::size_t c = 0;
    while (c < mark.size() && mark[c] == ii) ++c;
    if (c == mark.size()) {
      mark.push_back(-1);
      colors.emplace_back();
    }
    color[i] = static_cast<int>(c);
    colors[c].push_back(static_cast<std::int32_t>(i));
  }
  return colors;
}
std::vector<unsigned char> widenByRings(const SurfaceMesh& mesh, std::vector<unsigned char> region,
                                        int rings) {
  if (rings <= 0) return region;
  std::vector<std::vector<std::int32_t>> nodeElems(mesh.nodeCount());
  for (std::size_t e = 0; e < mesh.elementCount(); ++e)
    for (int k = 0; k < mesh.elementSize(e); ++k)
      nodeElems[static_cast<std::size_t>(mesh.elementNodes(e)[k])].push_back(
          static_cast<std::int32_t>(e));
  for (int r = 0; r < rings; ++r) {
    std::vector<unsigned char> next = region;
    for (std::size_t e = 0; e < mesh.elementCount(); ++e) {
      if (!region[e]) continue;
      for (int k = 0; k < mesh.elementSize(e); ++k)
        for (std::int32_t g : nodeElems[static_cast<std::size_t>(mesh.elementNodes(e)[k])])
          next[static_cast<std::size_t>(g)] = 1;
    }
    region.swap(next);
  }
  return region;
}

}  // namespace detail
}  // namespace surfmesh
