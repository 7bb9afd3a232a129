// SurfMesh — the CAD recovery's winding analysis (see winding.h).
#include "winding.h"

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace surfmesh::cad_detail {

std::vector<EdgePair> manifoldEdgePairs(const MeshInput& input,
                                        const std::vector<std::int64_t>& offsets) {
  struct Side {
    std::uint64_t key;  // the edge's two nodes, smaller first
    std::int32_t elem;
    std::int32_t dir;  // +1 when the element runs from the smaller node to the larger one
  };
  std::vector<Side> sides;
  sides.reserve(input.conn.size());
  for (std::size_t e = 0; e < input.types.size(); ++e) {
    const int nc = cornerCount(input.types[e]);
    const std::int32_t* nd = input.conn.data() + offsets[e];
    for (int k = 0; k < nc; ++k) {
      const std::uint32_t a = static_cast<std::uint32_t>(nd[k]);
      const std::uint32_t b = static_cast<std::uint32_t>(nd[(k + 1) % nc]);
      if (a == b) continue;
      const std::uint64_t key = a < b ? (std::uint64_t(a) << 32 | b) : (std::uint64_t(b) << 32 | a);
      sides.push_back({key, static_cast<std::int32_t>(e), a < b ? 1 : -1});
    }
  }
  std::sort(sides.begin(), sides.end(), [](const Side& p, const Side& q) { return p.key < q.key; });
  std::vector<EdgePair> out;
  for (std::size_t i = 0; i < sides.size();) {
    std::size_t j = i + 1;
    while (j < sides.size() && sides[j].key == sides[i].key) ++j;
    if (j - i == 2 && sides[i].elem != sides[i + 1].elem)
      out.push_back({sides[i].elem, sides[i + 1].elem, sides[i].dir != sides[i + 1].dir});
    i = j;
  }
  return out;
}

std::vector<int> faceWindingSigns(const std::vector<EdgePair>& edges,
                                  const std::vector<std::int32_t>& elemFace, int NF,
                                  const std::vector<std::int64_t>& agree,
                                  const std::vector<std::int64_t>& disagree) {
  const std::size_t F = static_cast<std::size_t>(NF);
  // Relations between face pairs (f < g): + (same winding) / − votes over the manifold mesh
  // edges between them.
  struct Pair {
    std::int32_t f, g;
    std::int32_t vote;
  };
  std::vector<Pair> pairs;
  for (const EdgePair& p : edges) {
    const std::int32_t f = elemFace[static_cast<std::size_t>(p.e0)];
    const std::int32_t g = elemFace[static_cast<std::size_t>(p.e1)];
    if (f != g) pairs.push_back({std::min(f, g), std::max(f, g), p.alike ? 1 : -1});
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const Pair& p, const Pair& q) { return p.f != q.f ? p.f < q.f : p.g < q.g; });
  // Adjacency with one relation per face pair (ties: no relation).
  std::vector<std::vector<std::pair<std::int32_t, int>>> adj(F);
  for (std::size_t i = 0; i < pairs.size();) {
    std::size_t j = i;
    int sum = 0;
    while (j < pairs.size() && pairs[j].f == pairs[i].f && pairs[j].g == pairs[i].g)
      sum += pairs[j++].vote;
    if (sum != 0) {
      const int r = sum > 0 ? 1 : -1;
      adj[static_cast<std::size_t>(pairs[i].f)].push_back({pairs[i].g, r});
      adj[static_cast<std::size_t>(pairs[i].g)].push_back({pairs[i].f, r});
    }
    i = j;
  }
  pairs = std::vector<Pair>();
  // Connected parts: relative signs by a breadth-first walk, checked on every relation.
  std::vector<int> rel(F, 0), out(F, 1);
  std::vector<std::int32_t> part, queue;
  for (std::size_t root = 0; root < F; ++root) {
    if (rel[root] != 0) continue;
    part.clear();
    queue.assign(1, static_cast<std::int32_t>(root));
    rel[root] = 1;
    bool consistent = true;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::size_t f = static_cast<std::size_t>(queue[q]);
      part.push_back(static_cast<std::int32_t>(f));
      for (const auto& [g, r] : adj[f]) {
        const std::size_t gi = static_cast<std::size_t>(g);
        if (rel[gi] == 0) {
          rel[gi] = rel[f] * r;
          queue.push_back(g);
        } else if (rel[gi] != rel[f] * r) {
          consistent = false;
        }
      }
    }
    std::int64_t total = 0;
    for (std::int32_t f : part) {
      const std::size_t fi = static_cast<std::size_t>(f);
      total += rel[fi] * (agree[fi] - disagree[fi]);
    }
    const int sign = total < 0 ? -1 : 1;
    // Per-face votes, as without relations, when the relations contradict each other or a
    // face's own elements clearly say otherwise (more than 3 to 1, by at least 3: faces of an
    // open model whose normals are not oriented alike, joined without a cycle that would
    // show it).
    bool perFace = !consistent;
    for (std::int32_t f : part) {
      const std::size_t fi = static_cast<std::size_t>(f);
      const int o = sign * rel[fi];
      const std::int64_t with = o > 0 ? agree[fi] : disagree[fi];
      const std::int64_t against = o > 0 ? disagree[fi] : agree[fi];
      if (against >= 3 && against > 3 * with) perFace = true;
    }
    for (std::int32_t f : part) {
      const std::size_t fi = static_cast<std::size_t>(f);
      out[fi] = perFace ? (disagree[fi] > agree[fi] ? -1 : 1) : sign * rel[fi];
    }
  }
  return out;
}

namespace {

/// Links between elements across manifold edges, CSR by element: adj[deg[e] … deg[e+1]) holds
/// (the other element, +1 when the two are wound alike, −1 otherwise), for the edge pairs
/// where keep(pair) holds.
struct WindingLinks {
  std::vector<std::int64_t> deg;
  std::vector<std::pair<std::int32_t, std::int8_t>> adj;
};

template <class Keep>
WindingLinks windingLinks(const std::vector<EdgePair>& edges, std::size_t E, Keep keep) {
  WindingLinks l;
  l.deg.assign(E + 1, 0);
  for (const EdgePair& p : edges)
    if (keep(p)) {
      ++l.deg[static_cast<std::size_t>(p.e0) + 1];
      ++l.deg[static_cast<std::size_t>(p.e1) + 1];
    }
  for (std::size_t e = 0; e < E; ++e) l.deg[e + 1] += l.deg[e];
  l.adj.resize(static_cast<std::size_t>(l.deg[E]));
  std::vector<std::int64_t> fill(l.deg.begin(), l.deg.end() - 1);
  for (const EdgePair& p : edges) {
    if (!keep(p)) continue;
    const std::int8_t r = p.alike ? 1 : -1;
    l.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(p.e0)]++)] = {p.e1, r};
    l.adj[static_cast<std::size_t>(fill[static_cast<std::size_t>(p.e1)]++)] = {p.e0, r};
  }
  return l;
}

}  // namespace

std::vector<std::int32_t> miswoundElements(const std::vector<EdgePair>& edges,
                                           const std::vector<std::int32_t>& elemFace) {
  const std::size_t E = elemFace.size();
  // Links between two elements of one face across a manifold edge: r = +1 same winding (the
  // edge run in opposite directions), −1 opposite windings. CSR by element.
  const WindingLinks links = windingLinks(edges, E, [&](const EdgePair& p) {
    return elemFace[static_cast<std::size_t>(p.e0)] == elemFace[static_cast<std::size_t>(p.e1)];
  });
  const std::vector<std::int64_t>& deg = links.deg;
  const auto& adj = links.adj;
  std::vector<std::int8_t> cls(E, 0);
  std::vector<std::int32_t> part, out;
  for (std::size_t root = 0; root < E; ++root) {
    if (cls[root] != 0 || deg[root + 1] == deg[root]) continue;
    part.assign(1, static_cast<std::int32_t>(root));
    cls[root] = 1;
    bool consistent = true;
    std::size_t plus = 0;
    for (std::size_t q = 0; q < part.size(); ++q) {
      const std::size_t e = static_cast<std::size_t>(part[q]);
      plus += cls[e] > 0;
      for (std::int64_t k = deg[e]; k < deg[e + 1]; ++k) {
        const auto& [f, r] = adj[static_cast<std::size_t>(k)];
        const std::size_t fi = static_cast<std::size_t>(f);
        const std::int8_t want = static_cast<std::int8_t>(cls[e] * r);
        if (cls[fi] == 0) {
          cls[fi] = want;
          part.push_back(f);
        } else if (cls[fi] != want) {
          consistent = false;  // not orientable (a Möbius-like patch): no winding is "less"
        }
      }
    }
    const std::size_t minus = part.size() - plus;
    if (!consistent || plus == minus) continue;
    const std::int8_t fewer = plus < minus ? 1 : -1;
    for (std::int32_t e : part)
      if (cls[static_cast<std::size_t>(e)] == fewer) out.push_back(e);
  }
  std::sort(out.begin(), out.end());
  return out;
}

void settleDoubtfulFaces(const std::vector<EdgePair>& edges,
                         const std::vector<std::vector<int>>& candidates,
                         std::vector<std::int32_t>& elemFace) {
  const std::size_t E = elemFace.size();
  std::vector<std::int32_t> work;
  for (std::size_t e = 0; e < E; ++e)
    if (candidates[e].size() > 1) work.push_back(static_cast<std::int32_t>(e));
  if (work.empty()) return;
  // Links of each element across manifold edges (CSR): the other element, +1 wound alike.
  const WindingLinks links = windingLinks(edges, E, [](const EdgePair&) { return true; });
  const std::vector<std::int64_t>& deg = links.deg;
  const auto& adj = links.adj;
  std::vector<unsigned char> queued(E, 0);
  for (std::int32_t e : work) queued[static_cast<std::size_t>(e)] = 1;
  std::vector<int> good, bad;
  for (std::size_t q = 0; q < work.size(); ++q) {
    const std::size_t e = static_cast<std::size_t>(work[q]);
    queued[e] = 0;
    const std::vector<int>& cand = candidates[e];
    good.assign(cand.size(), 0);
    bad.assign(cand.size(), 0);
    for (std::int64_t k = deg[e]; k < deg[e + 1]; ++k) {
      const auto& [o, r] = adj[static_cast<std::size_t>(k)];
      const auto it =
          std::lower_bound(cand.begin(), cand.end(), elemFace[static_cast<std::size_t>(o)]);
      if (it == cand.end() || *it != elemFace[static_cast<std::size_t>(o)]) continue;
      ++(r > 0 ? good : bad)[static_cast<std::size_t>(it - cand.begin())];
    }
    const std::size_t cur = static_cast<std::size_t>(
        std::lower_bound(cand.begin(), cand.end(), elemFace[e]) - cand.begin());
    if (cur >= cand.size() || cand[cur] != elemFace[e] || bad[cur] == 0) continue;
    std::size_t best = cur;
    int bestScore = good[cur] - bad[cur];
    for (std::size_t i = 0; i < cand.size(); ++i)
      if (good[i] > 0 && good[i] - bad[i] > bestScore) {
        best = i;
        bestScore = good[i] - bad[i];
      }
    if (best == cur) continue;
    elemFace[e] = cand[best];
    // Doubtful neighbours may settle now.
    for (std::int64_t k = deg[e]; k < deg[e + 1]; ++k) {
      const std::size_t o = static_cast<std::size_t>(adj[static_cast<std::size_t>(k)].first);
      if (candidates[o].size() > 1 && !queued[o]) {
        queued[o] = 1;
        work.push_back(static_cast<std::int32_t>(o));
      }
    }
  }
}

}  // namespace surfmesh::cad_detail
