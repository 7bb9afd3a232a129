// The optimizer's working state (node copies, element caches, the per-run holds and
// backoffs), a node update's submesh evaluation and a worker thread's scratch (optimizer
// internals).
#pragma once

#include "surfmesh/measures/certificate.h"
#include "surfmesh/measures/element_measure.h"
#include "surfmesh/optimize/optimizer.h"
#include "sweep_support.h"
#include "triangle_kernel.h"

#include <unordered_map>

namespace surfmesh {
namespace detail {

/// Cached surface derivatives at a node's accepted position (reused by its next Newton step).
struct NodeD2 {
  Vec3 du, dv, duu, duv, dvv;
};

/// faceCorners bit: the element is held from standing across its surface (a linear triangle:
/// acrossArea; a high-order one: see State's constructor).
constexpr unsigned kAcrossGuard = 0x80u;
/// Corner normals kept per element (cornerN): a quad's four.
constexpr int kCornerSlots = 4;
/// Normals kept per held element in a node update (Worker::cornerNormals): a high-order
/// triangle's at every node (certifyTriangleAgainstNodeNormals), a quad8's at its corners.
constexpr int kHeldSlots = kMaxElementNodes;
/// Curved elements held from standing across by their tangent planes at the corners (State's
/// constructor): high-order triangles and quad8.
inline bool heldCurved(ElementType t) { return isHighOrderTriangle(t) || t == ElementType::Quad8; }
/// What an evaluation means in the current sweep: the sweep sets it, an escape overrides it
/// for its own evaluations (ModeScope) until the scope ends.
struct EvalMode {
  double deltaHat = 0.0;  // dimensionless δ of the current sweep
  // Monotone mode, δ = 0 sweeps: the lowest quality of the valid elements with a movable node
  // at the start of the sweep. A move may lower its submesh's minimum quality down to this
  // floor, not below it, so that the mesh's minimum over those elements never decreases.
  // +∞ in untangling sweeps (no valid submesh's minimum may drop).
  double qualityFloor = kInf;
  bool trackCache = true;  // δ = 0 sweep: keep eta0/minSigma current at every accepted move
  // Patch untangling (escapeTangledElements → relaxPatch): a node's move may tangle more
  // elements of its submesh than it had (only f̂ must decrease), linear triangles use their
  // projected σ; the patch as a whole is kept only when it ends with fewer tangled elements.
  bool relaxTangled = false;
};

/// The optimizer's working state. Node positions and parameters are copies of the mesh's
/// (written back at the end, so that a cancelled run leaves the mesh untouched); element
/// corner (u,v) are not copied: they are refreshed from the final node parameters.
struct State {
  const SurfaceMesh& mesh;
  const PlanarMeasure& measure;
  const OptimizeOptions& opt;
  Incidence inc;
  bool allTri3 = true;
  std::size_t maxDegree = 0;
  // ---- nodes -----------------------------------------------------------------------------
  std::vector<Vec3> xyz;
  std::vector<Vec2> uv;
  std::vector<double> t;
  std::vector<Vec3> nodeNormal;         // reference normal of Face nodes at their (u,v)
  std::vector<NodeD2> d2;               // surface derivatives at a Face node's position
  std::vector<unsigned char> d2Valid;   // whether d2[i] is current
  std::vector<std::int32_t> lastVisit;  // clock of the node's last update
  std::vector<std::int32_t> movedAt;    // clock of its last significant move (0: never)
  /// Per node: its last accepted Newton step of a smoothing sweep, in (u,v) (Face nodes) or t
  /// (x; sliding nodes); zero after any other move. Over-relaxation follows it (see
  /// OptimizeOptions::overRelaxation).
  std::vector<Eigen::Vector2f> lastStep;
  // ---- elements --------------------------------------------------------------------------
  // Reference normal of element e: normalized (fixedNormal[e] + Σ nodeNormal over its Face
  // corners), fixedNormal holding the corner normals of its Fixed and Edge corners.
  std::vector<Vec3> fixedNormal;
  std::vector<std::uint8_t> faceCorners;  // bit k: corner k of element e is a Face node
  // The surface's normal at the corners of the linear triangles with a corner that is not a
  // Face node (acrossArea): cornerElems lists those triangles in increasing order, cornerN
  // holds 3 normals per entry, current for sliding nodes (commitEdgeMove); Face corners'
  // entries are unused (nodeNormal holds them). No per-element array: most elements have none.
  std::vector<std::int32_t> cornerElems;
  std::vector<Vec3> cornerN;
  std::vector<double> elemSize;  // √(mean squared corner edge length), frozen per sweep
  // Size² that scales δ for element e: the input's corner scales averaged over the elements
  // around its corners, frozen for the whole run. Frozen, because a δ that followed the
  // element's own size would let a tangled element shrink to a point at no cost; averaged,
  // because a tangled input element may itself be tiny.
  std::vector<double> deltaScale;
  std::vector<double> eta0;      // η with δ = 0 (+∞ tangled), kept current in δ = 0 sweeps
  std::vector<double> minSigma;  // scaled det S (≤ 0 tangled), idem
  // ---- sliding nodes ---------------------------------------------------------------------
  std::vector<std::int64_t> edgeSlot;  // N (or empty): first index in edgeNormal, −1
  std::vector<Vec3> edgeNormal;        // corner normal of an Edge node in each incident element
  // ---- sweep -----------------------------------------------------------------------------
  EvalMode mode;  // what an evaluation means now (set per sweep, overridden by escapes)
  // Backoff of the patch untangling per stuck element (escapeTangledElements): after n failed
  // attempts in a row, an element's patches are relaxed again only min(2^(n−1),
  // deltaStallSweeps) sweeps later, or as soon as ε has moved to another level. Only elements
  // that stay tangled have an entry.
  struct RelaxBackoff {
    int fails = 0;
    int nextSweep = 0;
    int epsilonLevel = 0;
    /// One more failure at `sweep`: the next try waits min(2^(fails−1), stallSweeps) sweeps.
    void failed(int sweep, int stallSweeps) {
      ++fails;
      const int wait = 1 << std::min(fails - 1, 20);
      nextSweep = sweep + std::min(wait, std::max(1, stallSweeps));
    }
  };
  std::unordered_map<std::size_t, RelaxBackoff> relaxBackoff;
  // The same backoff for the harmonic layout alone (the escapes of the first stalled sweeps,
  // before the joint untangling is allowed): it does not depend on δ, only on the positions,
  // so retrying it at every stalled sweep mostly repeats a failure (hundreds of stuck
  // elements made it cost more than the sweep on a second-order mesh).
  std::unordered_map<std::size_t, RelaxBackoff> harmonicBackoff;
  // The backoff of widenElement's joint search (see escapeTangledElements), without the cap
  // of deltaStallSweeps: a search that failed mostly fails again, and costs hundreds of
  // element evaluations per start.
  std::unordered_map<std::size_t, RelaxBackoff> widenBackoff;
  std::size_t patchUntanglings = 0;  // elements whose patches were relaxed (per escape)
  std::size_t straightened = 0;      // elements untangled by straightenHighOrder
  std::int32_t clock = 0;            // advanced once per color
  std::int32_t validFrom = 1;        // a node last visited before this clock is revisited

  State(const SurfaceMesh& m, const PlanarMeasure& pm, const OptimizeOptions& o,
        HoldAcross holdAcross);

  std::int64_t begin(std::size_t i) const { return inc.offset[i]; }
  std::int64_t end(std::size_t i) const { return inc.offset[i + 1]; }

  /// Reference normal (any length) of element e with the corner normal of free node i (in this
  /// element) replaced by `nfree` (i < 0: the current normals). `oldFree` is the corner normal i
  /// had in e when i is an Edge node (it is part of fixedNormal), zero otherwise.
  Vec3 elementNormal(std::size_t e, std::int64_t i, const Vec3& nfree, const Vec3& oldFree) const {
    return usableNormal(e, rawNormal(e, i, nfree, oldFree));
  }

  /// elementNormal without the fallback for a zero sum.
  Vec3 rawNormal(std::size_t e, std::int64_t i, const Vec3& nfree, const Vec3& oldFree) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    const unsigned mask = faceCorners[e];
    Vec3 n = fixedNormal[e];
    for (int k = 0; k < nc; ++k) {
      const std::int32_t j = nd[k];
      if (j == i) {
        n += nfree - oldFree;
      } else if ((mask >> k) & 1u) {
        n += nodeNormal[static_cast<std::size_t>(j)];
      }
    }
    return n;
  }

  /// Not normalized: the element measures only use its direction (the sign of c·n, and n/‖n‖
  /// for degenerate elements). Corner normals that cancel give no direction (zero, as in
  /// elementReferenceNormal); all corners at a pole: the normal at the centroid.
  Vec3 usableNormal(std::size_t e, const Vec3& n) const {
    const double n2 = n.squaredNorm();
    if (n2 == 0.0) return elementReferenceNormal(mesh, e);
    if (n2 < kNormalCancelTol * kNormalCancelTol) return Vec3::Zero();
    return n;
  }

  double cornerScale(std::size_t e) const {
    const int nc = cornerCount(mesh.elemType[e]);
    const std::int32_t* nd = mesh.elementNodes(e);
    double s = 0.0;
    for (int k = 0; k < nc; ++k) s += (xyz[nd[(k + 1) % nc]] - xyz[nd[k]]).squaredNorm();
    return s / nc;
  }

  /// Mean edge length of node i's submesh (from the frozen scales).
  double localSize(std::size_t i) const {
    double s = 0.0;
    const std::int64_t b = begin(i), en = end(i);
    for (std::int64_t p = b; p < en; ++p)
      s += elemSize[static_cast<std::size_t>(inc.elem[static_cast<std::size_t>(p)])];
    return en > b ? s / static_cast<double>(en - b) : 0.0;
  }

  /// Element e's node positions, its node `local` at x (local < 0: every node where it is).
  void positions(std::size_t e, int local, const Vec3& x, Vec3* xs) const {
    const std::int32_t* nd = mesh.elementNodes(e);
    const int cnt = mesh.elementSize(e);
    for (int k = 0; k < cnt; ++k) xs[k] = (k == local) ? x : xyz[static_cast<std::size_t>(nd[k])];
  }

  /// cornerSides of high-order triangle e with its node `local` at x (local < 0: at the
  /// current positions) and corner normals `corners` (its corners' order).
  CornerSides cornerSidesAt(std::size_t e, int local, const Vec3& x, const Vec3* corners) const {
    Vec3 xs[kMaxElementNodes];
    positions(e, local, x, xs);
    return cornerSides(mesh.elemType[e], xs, corners);
  }

  /// Normals a held element is judged by (heldNormal): every node's for a high-order
  /// triangle, the corners' for a quad8.
  int heldNormalCount(std::size_t e) const {
    return isHighOrderTriangle(mesh.elemType[e]) ? mesh.elementSize(e)
                                                 : cornerCount(mesh.elemType[e]);
  }

  /// The surface's unit normal at node k of element e (zero at a pole): cornerNormal for a
  /// corner; a high-order node's own for a Face node, else at its (u,v) in e on `surf`, the
  /// surface of e's face that the calling thread owns (an OCC surface's evaluation caches are
  /// not thread-safe: the mesh's own surfaces are the main thread's).
  Vec3 heldNormal(std::size_t e, int k, const Surface& surf) const {
    if (k < cornerCount(mesh.elemType[e])) return cornerNormal(e, k);
    const std::size_t j = static_cast<std::size_t>(mesh.elementNodes(e)[k]);
    if (mesh.nodeKind[j] == NodeKind::Face) return nodeNormal[j];
    return mesh.referenceNormal(mesh.elemFace[e], mesh.elementUV(e)[k], surf);
  }

  /// Whether element e, its node `local` at x (local < 0: at the current positions), with the
  /// normals `normals` (heldNormal's, in its nodes' order) has its tangent plane wound against
  /// the surface: a quad8 at a corner (cornerSides); a high-order triangle anywhere, as its
  /// Jacobian is not proven positive against the normals interpolated from its nodes
  /// (certifyTriangleAgainstNodeNormals; at the corners that is the corner test).
  bool turnedAgainst(std::size_t e, int local, const Vec3& x, const Vec3* normals) const {
    if (!isHighOrderTriangle(mesh.elemType[e])) return cornerSidesAt(e, local, x, normals).against;
    Vec3 xs[kMaxElementNodes];
    positions(e, local, x, xs);
    return !triangleJacobianPositiveAgainstNodeNormals(elementOrder(mesh.elemType[e]), xs, normals);
  }

  /// turnedAgainst at the current positions (the hold's decision, once per run and per node
  /// update), where for a high-order triangle the face's own normals on pieces of the element
  /// decide when the interpolation of `normals` cannot tell (curvedTriangleAlongFace, as the
  /// quality report): a valid element is held from becoming invalid by the report's test.
  /// `surf`: the calling thread's copy of the element's surface.
  bool turnedAgainstNow(std::size_t e, const Vec3* normals, const Surface& surf) const {
    if (!isHighOrderTriangle(mesh.elemType[e])) return turnedAgainst(e, -1, Vec3::Zero(), normals);
    Vec3 xs[kMaxElementNodes];
    positions(e, -1, Vec3::Zero(), xs);
    Vec2 uvNow[kMaxElementNodes];
    currentUV(e, surf, uvNow);
    return !curvedTriangleAlongFace(mesh, e, surf, xs, normals, uvNow);
  }

  /// The (u,v) of element e's nodes on its face at the current positions: a Face node of that
  /// face at its own (u,v) (unwrapped next to its corner entry), the others at their corner
  /// entries (nodes that do not move, or slide: those are not held).
  void currentUV(std::size_t e, const Surface& surf, Vec2* out) const {
    const std::int32_t* nd = mesh.elementNodes(e);
    const Vec2* c = mesh.elementUV(e);
    for (int k = 0; k < mesh.elementSize(e); ++k) {
      const std::size_t j = static_cast<std::size_t>(nd[k]);
      out[k] = mesh.nodeKind[j] == NodeKind::Face && mesh.nodeFace[j] == mesh.elemFace[e]
                   ? surf.unwrapNear(uv[j], c[k])
                   : c[k];
    }
  }

  /// The Jacobians of high-order triangle e at its nodes and quadrature points without the
  /// term of its node `local` (see HighOrderJacobians), at the current positions.
  void highOrderRest(std::size_t e, int local, HighOrderJacobians* out) const {
    Vec3 xs[kMaxElementNodes];
    positions(e, -1, Vec3::Zero(), xs);
    highOrderJacobians(mesh.elemType[e], xs, local, out);
  }

  /// The ideal element e's Jacobians are measured against (OptimizeOptions::highOrderTargets),
  /// null for the equilateral.
  const Mat2* targetOf(std::size_t e) const {
    if (opt.highOrderTargets.size() != mesh.elementCount() ||
        !isHighOrderTriangle(mesh.elemType[e]))
      return nullptr;
    const Mat2& W = opt.highOrderTargets[e];
    return W(0, 0) != 0.0 ? &W : nullptr;
  }

  /// Element e with node `local` at x (others at their positions) and reference normal n.
  /// `pre`: for a high-order triangle, highOrderRest(e, local) when the other nodes have not
  /// moved since (a line search), or null.
  /// `corners`: a linear triangle's unit corner normals in the order (local, its next corner,
  /// its previous corner), see acrossArea; a high-order triangle's or quad8's held from
  /// standing across (guarded) in its corners' order: the element counts as tangled (held) when its
  /// tangent plane at a corner is wound against the normal there. Null: no hold.
  ElemOut evalElement(std::size_t e, int local, const Vec3& x, const Vec3& n, double delta,
                      bool wantEta0, Vec3* grad, Mat3* hess,
                      const HighOrderJacobians* pre = nullptr,
                      const Vec3* corners = nullptr) const {
    const std::int32_t* nd = mesh.elementNodes(e);
    if (mesh.elemType[e] == ElementType::Tri3) {
      const int k1 = local == 2 ? 0 : local + 1, k2 = local == 0 ? 2 : local - 1;
      return triangleKernel(measure, x, xyz[static_cast<std::size_t>(nd[k1])],
                            xyz[static_cast<std::size_t>(nd[k2])], n, delta, wantEta0, grad, hess,
                            mode.relaxTangled, corners);
    }
    const Vec3 nu = n.normalized();
    double eta0 = kInf;  // η with δ = 0, from the same pass over the element
    ElementEval ev;
    const Mat2* target = targetOf(e);
    if (pre) {
      ev = highOrderTriangleDistortion(measure, *pre, x, nu, delta, grad, hess,
                                       wantEta0 ? &eta0 : nullptr, target);
      if (!ev.tangled) {  // valid at the samples: the certificate, as elementDistortion's
        Vec3 xs[kMaxElementNodes];
        positions(e, local, x, xs);
        markUncertifiedFold(mesh.elemType[e], xs, nu, delta, &ev, grad, hess,
                            wantEta0 ? &eta0 : nullptr, &measure, local, target);
      }
    } else {
      Vec3 xs[kMaxElementNodes];
      positions(e, local, x, xs);
      ev = elementDistortion(measure, mesh.elemType[e], xs, nu, delta, local, grad, hess,
                             wantEta0 ? &eta0 : nullptr, target);
    }
    ElemOut r;
    r.eta = ev.eta;
    r.minSigma = ev.minSigma;
    r.tangled = ev.tangled;
    if (wantEta0) r.eta0 = (ev.tangled || !std::isfinite(eta0)) ? kInf : eta0;
    if (corners && !ev.tangled && std::isfinite(ev.eta)) {
      if (turnedAgainst(e, local, x, corners)) {
        // Held from standing across: the move tangles it (a node update rejects it), while
        // its cached η and det S stay the paper's, as the quality report measures them. (Not
        // `held`: a run left with tangled elements does not start again without the hold for
        // it — the node updates only refuse moves, the whole-mesh values and the escapes do
        // not see it.)
        r.tangled = true;
        if (delta == 0.0) r.eta = kInf;
      }
    }
    return r;
  }

  /// evalElement with the Hessian projected on the tangent basis T (as (h00, h01, h11)).
  SURFMESH_HOT_INLINE ElemOut evalElementUV(std::size_t e, int local, const Vec3& x, const Vec3& n,
                                            double delta, bool wantEta0, const Tangent& T,
                                            Vec3* grad, Vec3* hessUV,
                                            const HighOrderJacobians* pre = nullptr,
                                            const Vec3* corners = nullptr) const {
    if (mesh.elemType[e] == ElementType::Tri3) {
      const std::int32_t* nd = mesh.elementNodes(e);
      const int k1 = local == 2 ? 0 : local + 1, k2 = local == 0 ? 2 : local - 1;
      return triangleKernelUV(measure, x, xyz[static_cast<std::size_t>(nd[k1])],
                              xyz[static_cast<std::size_t>(nd[k2])], n, delta, wantEta0, T, grad,
                              hessUV, mode.relaxTangled, corners);
    }
    Mat3 H;
    const ElemOut r = evalElement(e, local, x, n, delta, wantEta0, grad, &H, pre, corners);
    if (std::isfinite(r.eta)) {
      const Vec3 Hdu = H * T.du, Hdv = H * T.dv;
      *hessUV = Vec3(T.du.dot(Hdu), T.du.dot(Hdv), T.dv.dot(Hdv));
    }
    return r;
  }

  /// Whole-mesh element e at the current positions.
  ElemOut evalWhole(std::size_t e, double delta) const {
    const Vec3 n = elementNormal(e, -1, Vec3::Zero(), Vec3::Zero());
    const std::int32_t* nd = mesh.elementNodes(e);
    Vec3 corners[3];
    // (A high-order triangle is held by its node updates only: the whole-mesh values are the
    // paper's measure.)
    const bool tri = mesh.elemType[e] == ElementType::Tri3 && guarded(e);
    if (tri)
      for (int k = 0; k < 3; ++k) corners[k] = cornerNormal(e, k);
    return evalElement(e, 0, xyz[static_cast<std::size_t>(nd[0])], n, delta, true, nullptr, nullptr,
                       nullptr, tri ? corners : nullptr);
  }

  /// Whether element e is held from standing across its surface (acrossArea).
  bool guarded(std::size_t e) const { return (faceCorners[e] & kAcrossGuard) != 0; }

  /// The surface's unit normal at corner k of element e (zero at a pole): the node's own for a
  /// Face node, else the one kept in cornerN.
  const Vec3& cornerNormal(std::size_t e, int k) const {
    if ((faceCorners[e] >> k) & 1u)
      return nodeNormal[static_cast<std::size_t>(mesh.elementNodes(e)[k])];
    return cornerN[static_cast<std::size_t>(cornerSlot(e) + k)];
  }

  /// First index in cornerN of element e's corner normals (−1: e is not in cornerElems).
  std::int64_t cornerSlot(std::size_t e) const {
    const auto it =
        std::lower_bound(cornerElems.begin(), cornerElems.end(), static_cast<std::int32_t>(e));
    if (it == cornerElems.end() || *it != static_cast<std::int32_t>(e)) return -1;
    return kCornerSlots * static_cast<std::int64_t>(it - cornerElems.begin());
  }
};

/// Sets a State's evaluation mode for the life of the scope; the mode before comes back at its
/// end, also on an exception.
class ModeScope {
 public:
  ModeScope(State& s, const EvalMode& m) : s_(s), saved_(s.mode) { s.mode = m; }
  ~ModeScope() { s_.mode = saved_; }
  ModeScope(const ModeScope&) = delete;
  ModeScope& operator=(const ModeScope&) = delete;

 private:
  State& s_;
  EvalMode saved_;
};

/// Evaluation of a node's submesh at a candidate position.
struct LocalEval {
  double f = 0.0;           // Σ (η − 1)² with the sweep's δ
  int tangled = 0;          // elements with det S ≤ 0
  double minQuality = 1.0;  // min 1/η with δ = 0 (0 when tangled); when asked
  double maxEta = 1.0;      // largest η (sweep's δ) of the submesh
  bool finite = true;
  bool byQuality = false;         // a trial rejected (at least) for lowering minQuality
  Vec3 gradWorst = Vec3::Zero();  // ∂η/∂x of the element of minQuality (with g and quality)
};

/// Per-thread scratch (allocated once, sized by the largest node degree) and statistics,
/// padded to its own cache lines.
struct alignas(64) Worker {
  explicit Worker(const State& s) : geo(s.mesh) {
    eta0.resize(s.maxDegree);
    sig.resize(s.maxDegree);
    keptEta0.resize(s.maxDegree);
    keptSig.resize(s.maxDegree);
    normals.resize(s.maxDegree);
    baseNormal.resize(s.maxDegree);
    otherNormals.resize(2 * s.maxDegree);
    if (!s.allTri3) {
      cornerNormals.resize(kHeldSlots * s.maxDegree);
      holdHere.resize(s.maxDegree);
      highOrder.resize(s.maxDegree);
    }
  }
  ThreadGeometry geo;
  std::vector<double> eta0, sig;  // trial's per-element η(δ=0) and scaled det S
  // The same of the last accepted trial (swapped in by keepTrial: later trials of the same
  // update, rejected part way, overwrite eta0/sig).
  std::vector<double> keptEta0, keptSig;
  std::vector<Vec3> normals;     // trial's corner normals of a sliding node
  std::vector<Vec3> baseNormal;  // per incident element: its normal without the free corner
  // Per incident linear triangle: the corner normals of its two other corners (acrossArea).
  std::vector<Vec3> otherNormals;
  // Per incident held high-order triangle or quad8: its node normals (a quad8's corners only;
  // the free node's replaced at each trial), kHeldSlots each.
  std::vector<Vec3> cornerNormals;
  std::vector<unsigned char> holdHere;  // whether that triangle is held in this update
  // Per incident high-order triangle: its Jacobians without the free node's term.
  std::vector<HighOrderJacobians> highOrder;
  double maxRelMove = 0.0;
  std::size_t updated = 0, moved = 0;
  bool heldAcross = false;  // an evaluation of this worker held a triangle (acrossArea)
  char pad[64];
};
}  // namespace detail
}  // namespace surfmesh
