// The escapes of the sweep from local minima with tangled elements: the harmonic patch layout,
// the joint untangling of a patch, the joint search of one element's nodes, the straightening
// of curved elements and the sampling of a node's neighbourhood. Each keeps its move only when
// fewer elements around the moved nodes are tangled (strict progress).
#include "node_updater.h"
#include "straight_sided.h"

namespace surfmesh {
namespace detail {

std::size_t NodeUpdater::escapeTangledElements(const std::vector<unsigned char>& frozen, bool relax,
                                               int sweep, int epsilonLevel,
                                               const std::vector<unsigned char>& held) {
  std::size_t gained = 0;
  EscapeScratch x;
  for (std::size_t e = 0; e < s_.mesh.elementCount(); ++e) {
    if (frozen[e] || s_.minSigma[e] > 0.0) continue;
    const int face = s_.mesh.elemFace[e];
    const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
    std::vector<std::size_t>& patch = x.patch;
    patch.clear();
    const std::int32_t* nd = s_.mesh.elementNodes(e);
    for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (movableOn(j, face) && std::find(patch.begin(), patch.end(), j) == patch.end())
        patch.push_back(j);
    }
    if (patch.empty()) continue;
    auto backoff = s_.relaxBackoff.find(e);
    const bool relaxHere = relax && (backoff == s_.relaxBackoff.end() ||
                                     backoff->second.epsilonLevel != epsilonLevel ||
                                     sweep >= backoff->second.nextSweep);
    auto hBackoff = s_.harmonicBackoff.find(e);
    if (!relaxHere && hBackoff != s_.harmonicBackoff.end() && sweep < hBackoff->second.nextSweep)
      continue;
    StuckElement stuck{e, face, &surf, relaxHere, held[e] != 0, sweep};
    std::size_t g = 0;
    for (ElementEscape escape : kElementEscapes)
      if ((g = (this->*escape)(stuck, x)) > 0) break;
    const bool relaxed = stuck.relaxed;
    gained += g;
    const bool kept = g > 0;
    if (kept && backoff != s_.relaxBackoff.end()) s_.relaxBackoff.erase(backoff);
    if (kept && hBackoff != s_.harmonicBackoff.end()) s_.harmonicBackoff.erase(hBackoff);
    if (!kept && !relaxed) s_.harmonicBackoff[e].failed(sweep, s_.opt.deltaStallSweeps);
    if (relaxed) ++s_.patchUntanglings;
    if (!kept && relaxed) {
      State::RelaxBackoff& b = s_.relaxBackoff[e];
      b.failed(sweep, s_.opt.deltaStallSweeps);
      b.epsilonLevel = epsilonLevel;
    }
  }
  return gained;
}

void NodeUpdater::growRing(std::vector<std::size_t>& nodes, int face) const {
  const std::size_t n0 = nodes.size();
  for (std::size_t q = 0; q < n0; ++q)
    for (std::int64_t p = s_.begin(nodes[q]); p < s_.end(nodes[q]); ++p) {
      const std::size_t f = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* fn = s_.mesh.elementNodes(f);
      for (int k = 0; k < s_.mesh.elementSize(f); ++k) {
        const std::size_t j = static_cast<std::size_t>(fn[k]);
        if (movableOn(j, face) && std::find(nodes.begin(), nodes.end(), j) == nodes.end())
          nodes.push_back(j);
      }
    }
}

void NodeUpdater::harmonicLayout(EscapeScratch& x, int face, const Surface& surf) {
  const std::vector<std::size_t>& patch = x.patch;
  // Neighbour lists of the patch nodes (corners of their elements).
  x.nbrOffset.assign(1, 0);
  x.nbrIndex.clear();
  x.nbrUV.clear();
  for (std::size_t j : patch) {
    for (std::int64_t p = s_.begin(j); p < s_.end(j); ++p) {
      const std::size_t f = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const std::int32_t* fn = s_.mesh.elementNodes(f);
      for (int k = 0; k < cornerCount(s_.mesh.elemType[f]); ++k) {
        const std::size_t o = static_cast<std::size_t>(fn[k]);
        if (o == j) continue;
        const auto it = std::find(patch.begin(), patch.end(), o);
        x.nbrIndex.push_back(it == patch.end() ? -1
                                               : static_cast<std::int32_t>(it - patch.begin()));
        x.nbrUV.push_back(cornerOnFace(f, k, face, surf, s_.uv[j]));
      }
    }
    x.nbrOffset.push_back(static_cast<std::int64_t>(x.nbrIndex.size()));
  }
  // Gauss–Seidel on the uniform Laplacian of the patch (its outline held).
  std::vector<Vec2>& iter = x.iter;
  iter.clear();
  for (std::size_t j : patch) iter.push_back(s_.uv[j]);
  for (int sweep = 0; sweep < 200; ++sweep) {
    double change = 0.0;
    for (std::size_t q = 0; q < patch.size(); ++q) {
      Vec2 c = Vec2::Zero();
      const std::int64_t b0 = x.nbrOffset[q], b1 = x.nbrOffset[q + 1];
      for (std::int64_t r = b0; r < b1; ++r) {
        const std::int32_t o = x.nbrIndex[static_cast<std::size_t>(r)];
        c += o < 0 ? x.nbrUV[static_cast<std::size_t>(r)]
                   : surf.unwrapNear(iter[static_cast<std::size_t>(o)], iter[q]);
      }
      if (b1 > b0) {
        c /= static_cast<double>(b1 - b0);
        change = std::max(change, (c - iter[q]).lpNorm<Eigen::Infinity>());
        iter[q] = c;
      }
    }
    if (change == 0.0) break;
  }
}

std::size_t NodeUpdater::escapeByWidening(StuckElement& st, EscapeScratch& x) {
  const std::size_t e = st.e;
  auto wBackoff = s_.widenBackoff.find(e);
  if (!(s_.opt.escapes & kEscapeWiden) || !st.relaxHere ||
      st.held ||  // (a held element cannot become valid)
      (wBackoff != s_.widenBackoff.end() && st.sweep < wBackoff->second.nextSweep))
    return 0;
  // e's own nodes, then with the Face nodes of the elements around them
  std::size_t g = widenElement(e, x.patch, st.face, *st.surf);
  if (g == 0) {
    std::vector<std::size_t> wider = x.patch;
    growRing(wider, st.face);
    if (wider.size() > x.patch.size() && wider.size() <= kMaxWidenNodes)
      g = widenElement(e, wider, st.face, *st.surf);
  }
  if (g > 0) {
    if (wBackoff != s_.widenBackoff.end()) s_.widenBackoff.erase(wBackoff);
  } else {
    s_.widenBackoff[e].failed(st.sweep, 1 << 20);  // retried after 1, 2, 4, 8… sweeps
  }
  return g;
}

std::size_t NodeUpdater::escapeByPatches(StuckElement& st, EscapeScratch& x) {
  const int face = st.face;
  const Surface& surf = *st.surf;
  const bool relaxHere = st.relaxHere;
  bool* relaxed = &st.relaxed;
  std::vector<std::size_t>& patch = x.patch;
  for (int ring = 0; ring <= 3; ++ring) {
    if (ring > 0) {  // grow by one ring of Face nodes of this face
      const std::size_t n0 = patch.size();
      growRing(patch, face);
      if (patch.size() == n0 || patch.size() > 256) break;
    }
    elementsAround(patch, &x.elems);
    auto countTangled = [&]() { return tangledAmong(x.elems); };
    const std::size_t t0 = countTangled();
    if (t0 == 0) continue;  // nothing to gain here (the cache is from the last sweep)
    const bool layout = (s_.opt.escapes & kEscapeHarmonic) != 0;
    if (layout) {
      harmonicLayout(x, face, surf);
      straightSides(patch, face, surf, &x.iter);
    }
    bool placed = false;
    std::size_t g = keepIfFewer(patch, t0, [&] {
      placed = layout && placeAll(patch, x.iter, face, surf);
      return placed ? countTangled() : t0;
    });
    if (g > 0) return g;
    // The harmonic layout did not help (a non-convex outline in (u,v), or elements valid
    // in (u,v) but not on the surface): untangle the patch by local Newton steps on f̂
    // that may pass through tangled states, from the harmonic layout when it was placeable
    // (placed again: the same positions) and from the input positions.
    if (!relaxHere || patch.size() > kMaxRelaxPatchNodes || !(s_.opt.escapes & kEscapeRelaxPatch))
      continue;
    for (const bool fromLayout : {true, false}) {
      if ((fromLayout && !placed) || relaxTries_ >= kMaxRelaxPatches) continue;
      ++relaxTries_;
      *relaxed = true;
      g = keepIfFewer(patch, t0, [&] {
        if (fromLayout) placeAll(patch, x.iter, face, surf);
        return relaxPatch(patch, countTangled, t0);
      });
      if (g > 0) return g;
    }
  }
  return 0;
}

std::size_t NodeUpdater::escapeBySampling(StuckElement& st, EscapeScratch& x) {
  const std::size_t e = st.e;
  const int face = st.face;
  const Surface& surf = *st.surf;
  const bool relaxHere = st.relaxHere;
  bool* relaxed = &st.relaxed;
  if (!(s_.opt.escapes & kEscapeSample)) return 0;
  const std::int32_t* nd = s_.mesh.elementNodes(e);
  // Each Face node of the element alone, at the best point of a grid over its neighbours.
  for (int k = 0; k < s_.mesh.elementSize(e); ++k) {
    const std::size_t j = static_cast<std::size_t>(nd[k]);
    if (!movableOn(j, face)) continue;
    const std::size_t g = sampleNeighbourhood(j, face, surf);
    if (g > 0) return g;
  }
  // Then, with the joint untangling allowed: a Face node of the element where the element
  // is valid, the other Face nodes of its elements untangled around it (relaxPatch), kept
  // when fewer elements around them all are tangled.
  std::vector<std::size_t>& patch = x.patch;
  const bool relaxAllowed = relaxHere && (s_.opt.escapes & kEscapeRelaxPatch);
  for (int k = 0; k < s_.mesh.elementSize(e) && relaxAllowed; ++k) {
    const std::size_t j = static_cast<std::size_t>(nd[k]);
    Vec2 target;
    if (!movableOn(j, face) || relaxTries_ >= kMaxRelaxPatches ||
        !sampleNeighbourhood(j, face, surf, static_cast<std::int64_t>(e), &target))
      continue;
    patch.assign(1, j);
    growRing(patch, face);
    if (patch.size() == 1 || patch.size() - 1 > kMaxRelaxPatchNodes) continue;
    std::rotate(patch.begin(), patch.begin() + 1, patch.end());  // j last
    elementsAround(patch, &x.elems);
    auto countTangled = [&]() { return tangledAmong(x.elems); };
    const std::size_t t0 = countTangled();
    const std::vector<std::size_t> around(patch.begin(), patch.end() - 1);  // j at the target
    ++relaxTries_;
    *relaxed = true;
    const std::size_t g = keepIfFewer(patch, t0, [&] {
      return placeAll({j}, {target}, face, surf) ? relaxPatch(around, countTangled, t0) : t0;
    });
    if (g > 0) return g;
  }
  return 0;
}

std::size_t NodeUpdater::straightenHighOrder(const std::vector<unsigned char>& frozen,
                                             bool cached) {
  std::size_t gained = 0;
  std::vector<std::size_t> moved, elems;
  std::vector<Vec2> target;
  for (std::size_t e = 0; e < s_.mesh.elementCount(); ++e) {
    const ElementType type = s_.mesh.elemType[e];
    if (frozen[e] || !heldCurved(type)) continue;
    if ((cached && s_.minSigma[e] > 0.0) || !s_.evalWhole(e, 0.0).tangled) continue;
    const int face = s_.mesh.elemFace[e];
    const Surface& surf = *w_.geo.surfaces[static_cast<std::size_t>(face)];
    const std::int32_t* nd = s_.mesh.elementNodes(e);
    const int nc = cornerCount(type);
    const Vec3 n = s_.elementNormal(e, -1, Vec3::Zero(), Vec3::Zero());
    // The corners first: a triangle's one corner triangle, each corner's of a quad.
    const int cornerTriangles = nc == 3 ? 1 : nc;
    bool cornersTangled = false;
    for (int k = 0; k < cornerTriangles && !cornersTangled; ++k) {
      const Vec3& xk = s_.xyz[static_cast<std::size_t>(nd[k])];
      Jacobian32 J;
      J.col(0) = s_.xyz[static_cast<std::size_t>(nd[(k + 1) % nc])] - xk;
      J.col(1) = s_.xyz[static_cast<std::size_t>(nd[(k + nc - 1) % nc])] - xk;
      cornersTangled = jacobianValidity(J, equilateralWinv(), n).tangled;
    }
    if (cornersTangled) continue;
    Vec2 c[4];
    c[0] = cornerOnFace(e, 0, face, surf,
                        s_.mesh.cornerUV[static_cast<std::size_t>(s_.mesh.elemOffset[e])]);
    for (int k = 1; k < nc; ++k) c[k] = cornerOnFace(e, k, face, surf, c[0]);
    moved.clear();
    target.clear();
    bool ok = true;
    for (int k = nc; k < s_.mesh.elementSize(e) && ok; ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      if (s_.mesh.nodeKind[j] != NodeKind::Face || s_.mesh.nodeFace[j] != face) continue;
      const Vec2 t = surf.wrap(straightPlace(type, k, c));
      ok = t.allFinite() && surf.containsNearBoundary(t.x(), t.y());
      moved.push_back(j);
      target.push_back(t);
    }
    if (!ok || moved.empty()) continue;
    elementsAround(moved, &elems);
    const std::size_t t0 = tangledAmong(elems);
    gained += keepIfFewer(
        moved, t0, [&] { return placeAll(moved, target, face, surf) ? tangledAmong(elems) : t0; });
  }
  s_.straightened += gained;
  return gained;
}

std::size_t NodeUpdater::widenElement(std::size_t e, const std::vector<std::size_t>& nodes,
                                      int face, const Surface& surf) {
  std::vector<std::size_t> elems, watch;
  elementsAround(nodes, &elems);
  const std::size_t t0 = tangledAmong(elems);
  if (t0 == 0) return 0;
  watch.push_back(e);  // e and the valid elements around it: none may fold
  for (std::size_t q : elems)
    if (q != e && !s_.evalWhole(q, 0.0).tangled) watch.push_back(q);
  // Their smallest det S, kept per element: a trial move of one node evaluates only the
  // watched elements of that node (aff).
  std::vector<double> sig(watch.size());
  std::vector<std::vector<std::size_t>> aff(nodes.size());
  for (std::size_t q = 0; q < nodes.size(); ++q)
    for (std::int64_t p = s_.begin(nodes[q]); p < s_.end(nodes[q]); ++p) {
      const auto f = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const auto it = std::find(watch.begin(), watch.end(), f);
      if (it != watch.end()) aff[q].push_back(static_cast<std::size_t>(it - watch.begin()));
    }
  auto minSig = [&]() {
    double o = kInf;
    for (double v : sig) o = std::min(o, v);
    return o;
  };
  auto objective = [&]() {
    for (std::size_t w = 0; w < watch.size(); ++w) sig[w] = s_.evalWhole(watch[w], 0.0).minSigma;
    return minSig();
  };
  std::vector<double> sigSave;
  // Initial step: half the extent in (u,v) of e's corners.
  const Vec2 c0 = cornerOnFace(e, 0, face, surf, s_.mesh.elementUV(e)[0]);
  Vec2 lo = c0, hi = c0;
  for (int k = 1; k < cornerCount(s_.mesh.elemType[e]); ++k) {
    const Vec2 ck = cornerOnFace(e, k, face, surf, c0);
    lo = lo.cwiseMin(ck);
    hi = hi.cwiseMax(ck);
  }
  Vec2 h0 = 0.5 * (hi - lo);
  if (!(h0.maxCoeff() > 0.0) || !h0.allFinite()) return 0;
  h0 = h0.cwiseMax(Vec2::Constant(1e-3 * h0.maxCoeff()));
  std::vector<Vec2> uvSave, best, one(1);
  std::vector<Vec3> xyzSave, nSave;
  std::vector<std::size_t> single(1);
  save(nodes, &uvSave, &xyzSave, &nSave);
  const double o0 = objective();
  double bestO = o0;
  auto placeOne = [&](std::size_t j, const Vec2& uv) {
    single[0] = j;
    one[0] = uv;
    return placeAll(single, one, face, surf);
  };
  static const Vec2 kDirs[8] = {{1, 0}, {-1, 0},  {0, 1},  {0, -1},
                                {1, 1}, {-1, -1}, {1, -1}, {-1, 1}};
  std::uint64_t seed = 0x9e3779b97f4a7c15ull * (e + 1);
  auto unit = [&]() {  // in [−1, 1), a fixed sequence per element
    seed ^= seed << 13;
    seed ^= seed >> 7;
    seed ^= seed << 17;
    return static_cast<double>(seed >> 11) * (2.0 / 9007199254740992.0) - 1.0;
  };
  for (int start = 0; start < kWidenStarts && !(bestO > 0.0); ++start) {
    if (start > 0) {
      restore(nodes, uvSave, xyzSave, nSave);
      const double r = start % 2 ? 0.5 : 1.5;
      for (std::size_t q = 0; q < nodes.size(); ++q)
        placeOne(nodes[q], uvSave[q] + r * Vec2(unit() * h0.x(), unit() * h0.y()));
    }
    double o = objective();
    Vec2 h = h0;
    // Until e and its neighbours are valid (the sweeps then smooth them), or the step is
    // 1e-4 of the first.
    for (int it = 0; it < 60 && !(o > 0.0) && h.x() > 1e-4 * h0.x(); ++it) {
      bool moved = false;
      for (std::size_t q = 0; q < nodes.size(); ++q)
        for (const Vec2& d : kDirs) {
          const std::size_t j = nodes[q];
          const Vec2 old = s_.uv[j];
          if (!placeOne(j, old + Vec2(d.x() * h.x(), d.y() * h.y()))) continue;
          sigSave.clear();
          for (std::size_t w : aff[q]) {
            sigSave.push_back(sig[w]);
            sig[w] = s_.evalWhole(watch[w], 0.0).minSigma;
          }
          const double o1 = minSig();
          if (o1 > o) {
            o = o1;
            moved = true;
          } else {
            placeOne(j, old);
            for (std::size_t k = 0; k < aff[q].size(); ++k) sig[aff[q][k]] = sigSave[k];
          }
        }
      if (!moved) h *= 0.5;
    }
    if (o > bestO) {
      bestO = o;
      best.clear();
      for (std::size_t j : nodes) best.push_back(s_.uv[j]);
    }
  }
  restore(nodes, uvSave, xyzSave, nSave);
  if (best.empty()) return 0;
  return keepIfFewer(nodes, t0,
                     [&] { return placeAll(nodes, best, face, surf) ? tangledAmong(elems) : t0; });
}

void NodeUpdater::straightSides(const std::vector<std::size_t>& patch, int face,
                                const Surface& surf, std::vector<Vec2>* uv) const {
  for (std::size_t q = 0; q < patch.size(); ++q) {
    const std::size_t j = patch[q];
    if (s_.begin(j) == s_.end(j)) continue;
    const std::size_t p0 = static_cast<std::size_t>(s_.begin(j));
    const std::size_t f = static_cast<std::size_t>(s_.inc.elem[p0]);
    const int local = s_.inc.local[p0];
    const ElementType type = s_.mesh.elemType[f];
    const int nc = cornerCount(type);
    if (!heldCurved(type) || local < nc) continue;
    const Vec2 ref = (*uv)[q];
    Vec2 c[4];
    for (int k = 0; k < nc; ++k) {
      const std::size_t o = static_cast<std::size_t>(s_.mesh.elementNodes(f)[k]);
      const auto it = std::find(patch.begin(), patch.end(), o);
      c[k] = it == patch.end()
                 ? cornerOnFace(f, k, face, surf, ref)
                 : surf.unwrapNear((*uv)[static_cast<std::size_t>(it - patch.begin())], ref);
    }
    (*uv)[q] = straightPlace(type, local, c);
  }
}

bool NodeUpdater::placeAll(const std::vector<std::size_t>& nodes, const std::vector<Vec2>& uv,
                           int face, const Surface& surf) {
  const double orient = static_cast<double>(
      s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
  for (std::size_t q = 0; q < nodes.size(); ++q) {
    const Vec2 w = surf.wrap(uv[q]);
    if (!w.allFinite() || !surf.containsNearBoundary(w.x(), w.y())) return false;
    const SurfaceD1 d = surf.d1(w.x(), w.y());
    if (isDegenerate(d)) return false;
    const std::size_t j = nodes[q];
    s_.uv[j] = w;
    s_.xyz[j] = d.p;
    const Vec3 c = d.du.cross(d.dv);
    s_.nodeNormal[j] = (orient / c.norm()) * c;
    s_.d2Valid[j] = 0;
  }
  return true;
}

template <class Count>
std::size_t NodeUpdater::relaxPatch(const std::vector<std::size_t>& patch, Count& countTangled,
                                    std::size_t t0) {
  const double deltaHat = s_.mode.deltaHat;
  EvalMode relax = s_.mode;
  relax.trackCache = false;
  relax.relaxTangled = true;
  const ModeScope scope(s_, relax);
  std::size_t best = t0;
  std::vector<Vec2> uvBest;
  std::vector<Vec3> xyzBest, nBest;
  const double dMin = std::max(deltaHat, 1e-4);
  for (double dh = 4.0 * dMin; dh >= dMin / 20.0; dh *= 0.25) {  // 4, 1, 1/4, 1/16 × δ̂
    s_.mode.deltaHat = dh;
    for (int sweep = 0; sweep < 15; ++sweep) {
      double mv = 0.0;
      for (std::size_t j : patch) mv += update(j);
      if (mv == 0.0) break;
    }
    s_.mode.relaxTangled = false;  // count with the sweep's rule
    const std::size_t t = countTangled();
    s_.mode.relaxTangled = true;
    if (t < best) {
      best = t;
      uvBest.clear();
      xyzBest.clear();
      nBest.clear();
      for (std::size_t j : patch) {
        uvBest.push_back(s_.uv[j]);
        xyzBest.push_back(s_.xyz[j]);
        nBest.push_back(s_.nodeNormal[j]);
      }
      if (t == 0) break;
    }
  }
  if (best < t0) restore(patch, uvBest, xyzBest, nBest);
  return best;
}

std::size_t NodeUpdater::sampleNeighbourhood(std::size_t i, int face, const Surface& surf,
                                             std::int64_t valid, Vec2* target) {
  static constexpr int kSampleGrid = 16;
  const Vec2 uv0 = s_.uv[i];
  Vec2 lo = uv0, hi = uv0;
  int validAt = -1;  // valid's index in i's incidence
  for (std::int64_t p = s_.begin(i); p < s_.end(i); ++p) {
    const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
    const int nc = cornerCount(s_.mesh.elemType[e]);
    if (s_.inc.local[static_cast<std::size_t>(p)] >= nc) return 0;  // a high-order side node
    if (static_cast<std::int64_t>(e) == valid) validAt = static_cast<int>(p - s_.begin(i));
    for (int k = 0; k < nc; ++k) {
      if (static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]) == i) continue;
      const Vec2 c = cornerOnFace(e, k, face, surf, uv0);
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
  }
  if (!lo.allFinite() || !hi.allFinite() || (valid >= 0 && validAt < 0)) return 0;
  const double orient = static_cast<double>(
      s_.mesh.faceOrientation[static_cast<std::size_t>(face)] * surf.normalSign());
  auto zero = [](std::size_t) { return Vec3::Zero().eval(); };
  const Vec3 n0 = s_.nodeNormal[i];
  const LocalEval cur = evalLocal(
      i, s_.xyz[i], [&](std::size_t) { return n0; }, zero, false, nullptr, nullptr, nullptr);
  // Evaluated as a trial (against a bound no trial reaches), evalLocal keeps each element's
  // η at δ = 0 and det S in the worker's scratch.
  LocalEval any;
  any.f = kInf;
  any.tangled = std::numeric_limits<int>::max();
  EvalMode tracking = s_.mode;
  tracking.trackCache = true;
  const ModeScope scope(s_, tracking);  // to the end: what follows the grid evaluates nothing
  int bestTangled = valid >= 0 ? std::numeric_limits<int>::max() : cur.tangled;
  double bestF = kInf;
  Vec2 bestUV = uv0;
  for (int a = 0; a < kSampleGrid; ++a)
    for (int b = 0; b < kSampleGrid; ++b) {
      const Vec2 r((a + 0.5) / kSampleGrid, (b + 0.5) / kSampleGrid);
      const Vec2 uvT = surf.wrap(lo + (hi - lo).cwiseProduct(r));
      if (!uvT.allFinite() || !surf.containsNearBoundary(uvT.x(), uvT.y())) continue;
      const SurfaceD1 dT = surf.d1(uvT.x(), uvT.y());
      if (isDegenerate(dT)) continue;
      const Vec3 cr = dT.du.cross(dT.dv);
      const Vec3 nT = (orient / cr.norm()) * cr;
      const LocalEval tr = valid >= 0 ? evalLocal(
                                            i, dT.p, [&](std::size_t) { return nT; }, zero, false,
                                            &any, nullptr, nullptr)
                                      : evalLocal(
                                            i, dT.p, [&](std::size_t) { return nT; }, zero, false,
                                            nullptr, nullptr, nullptr);
      if (!tr.finite) continue;
      const std::size_t v = static_cast<std::size_t>(std::max(validAt, 0));
      if (valid >= 0 ? (w_.sig[v] <= 0.0 || !std::isfinite(w_.eta0[v])) : tr.tangled >= cur.tangled)
        continue;  // `valid` still tangled, or no progress
      if (tr.tangled < bestTangled || (tr.tangled == bestTangled && tr.f < bestF)) {
        bestTangled = tr.tangled;
        bestF = tr.f;
        bestUV = uvT;
      }
    }
  if (valid >= 0) {
    if (bestTangled == std::numeric_limits<int>::max()) return 0;
    *target = bestUV;
    return 1;
  }
  if (bestTangled >= cur.tangled || !placeAll({i}, {bestUV}, face, surf)) return 0;
  return static_cast<std::size_t>(cur.tangled - bestTangled);
}

}  // namespace detail
}  // namespace surfmesh
