// A node update: one safeguarded Newton step in (u,v) or along a CAD edge on a node's submesh
// (newton_step.cpp), and the escapes from the sweep's local minima with tangled elements
// (escapes.cpp). Optimizer internals.
#pragma once

#include "sweep_state.h"

namespace surfmesh {
namespace detail {

/// A line search's trials and the escapes' moves on one node or patch, on the shared State and
/// one Worker's scratch.
class NodeUpdater {
 public:
  NodeUpdater(State& s, Worker& w) : s_(s), w_(w) {}

  /// One safeguarded Newton step (with line search) on node i; returns the 3D move.
  double update(std::size_t i) {
    if (s_.mesh.nodeKind[i] == NodeKind::Face) return updateFaceNode(i);
    if (s_.mesh.nodeKind[i] == NodeKind::Edge) return updateEdgeNode(i);
    return 0.0;
  }

  /// Escape from a local minimum of the node-by-node sweep: a tangled element can be stuck
  /// when no single node can untangle it (e.g. a fan of thin triangles between two boundary
  /// nodes whose inner nodes have swapped their order: every node's kernel is empty while the
  /// others stay). For each tangled element (in the element cache) with a movable Face node,
  /// the Face nodes of its face within 0, 1, 2, 3 rings of it are relocated together to the
  /// harmonic (uniform Tutte) embedding in (u,v) of that patch with the nodes around it held —
  /// a valid embedding whenever the patch's outline is convex in (u,v). When that does not
  /// help (a non-convex outline; or thin elements valid in (u,v) but standing across a curved
  /// surface — a stacked fan of a coarse mesh between two CAD-edge nodes over 70° of a torus
  /// fillet), the patch is untangled jointly by relaxPatch, from the harmonic layout and from
  /// its current positions (with `relax`: the sweeps have left the number of tangled elements
  /// unchanged a few times in a row — a short stall usually ends by itself; an element whose
  /// patches failed is relaxed again only after State::RelaxBackoff's wait, at `sweep` ≥ its
  /// next sweep or at another `epsilonLevel`: the joint untangling costs up to hundreds of
  /// node updates per node, and a tangle no motion repairs would pay it at every stalled
  /// sweep until the run gives up — 48 of them by default). The smallest
  /// patch that leaves fewer tangled elements among all elements of the moved nodes is kept —
  /// strict progress, so it cannot cycle. Runs on one thread between sweeps, only while
  /// tangled elements stall; returns the number of elements untangled. Before the patches,
  /// with `relax`, the element's own nodes try a joint search (widenElement), except for the
  /// elements `held` marks (held folds and the like: no motion of theirs makes them valid).
  std::size_t escapeTangledElements(const std::vector<unsigned char>& frozen, bool relax, int sweep,
                                    int epsilonLevel, const std::vector<unsigned char>& held);

  /// Work arrays of escapeTangledElements, reused across its elements.
  struct EscapeScratch {
    std::vector<std::size_t> patch, elems;
    std::vector<Vec2> iter;
    std::vector<std::int64_t> nbrOffset;
    std::vector<std::int32_t> nbrIndex;  // index in the patch, −1 for a held node
    std::vector<Vec2> nbrUV;             // held neighbours: their (u,v) next to the node's
  };

  /// Whether node j is a Face node of `face` (what the escapes of its elements move).
  bool movableOn(std::size_t j, int face) const {
    return s_.mesh.nodeKind[j] == NodeKind::Face && s_.mesh.nodeFace[j] == face;
  }

  /// Adds to `nodes` the Face nodes of `face` of the elements around them (one ring).
  void growRing(std::vector<std::size_t>& nodes, int face) const;

  /// x.iter: the harmonic (uniform Tutte) layout in (u,v) of the patch x.patch of Face nodes
  /// of `face`, the nodes around it held (Gauss–Seidel on the uniform Laplacian).
  void harmonicLayout(EscapeScratch& x, int face, const Surface& surf);

  /// A stuck tangled element as the element escapes see it (escapeTangledElements).
  struct StuckElement {
    std::size_t e;
    int face;
    const Surface* surf;  // the face's surface (this worker's copy)
    bool relaxHere;       // the joint untangling (relaxPatch) may run for it this time
    bool held;            // it folds where no node may move (widening cannot repair it)
    int sweep;
    bool relaxed = false;  // set when relaxPatch ran for it
  };

  /// An element escape: tries to untangle the elements around stuck element st (its Face
  /// nodes in x.patch), each behind its bit of OptimizeOptions::escapes, keeping a move only
  /// when fewer elements are tangled (keepIfFewer). Returns the elements untangled (0: the
  /// positions are as they were).
  using ElementEscape = std::size_t (NodeUpdater::*)(StuckElement& st, EscapeScratch& x);

  /// The joint compass search over st's nodes, then with one ring around them (widenElement),
  /// with its own backoff; not for held elements.
  std::size_t escapeByWidening(StuckElement& st, EscapeScratch& x);

  /// The patches around st (its Face nodes, then with 1, 2, 3 rings): the harmonic layout,
  /// then (st.relaxHere) the joint untangling by relaxPatch from it and from the current
  /// positions. The first patch that leaves fewer elements tangled is kept.
  std::size_t escapeByPatches(StuckElement& st, EscapeScratch& x);

  /// The last resort: each of st's Face nodes alone at the best point of a grid over its
  /// neighbours (sampleNeighbourhood); then, with st.relaxHere, a Face node where st is valid
  /// and the Face nodes around it untangled (relaxPatch).
  std::size_t escapeBySampling(StuckElement& st, EscapeScratch& x);

  /// The element escapes in the order escapeTangledElements tries them on a stuck element;
  /// the first that untangles something ends that element's turn.
  static constexpr ElementEscape kElementEscapes[] = {&NodeUpdater::escapeByWidening,
                                                      &NodeUpdater::escapeByPatches,
                                                      &NodeUpdater::escapeBySampling};

  /// Straightens tangled high-order triangles and quad8 in (u,v): a curved element whose
  /// corner triangle (quad8: each corner's triangle of its corner quadrilateral) is valid but
  /// whose edge or interior nodes fold it (a mesher's second-order nodes projected across a
  /// thin or strongly curved face) gets its movable edge and interior nodes — Face nodes of the
  /// element's face — at the parametric interpolation of its corners (straight sides in (u,v),
  /// as the paper's initial high-order meshes; a quad8's side node at its side's midpoint).
  /// Kept only when fewer elements around the moved nodes are tangled than before — strict
  /// progress, like every escape. Returns the number of elements untangled.
  /// With `cached`, only the elements the element cache holds tangled are looked at.
  std::size_t straightenHighOrder(const std::vector<unsigned char>& frozen, bool cached);

  /// Escape for one tangled element e whose movable nodes (`nodes`: its Face nodes on `face`)
  /// must move together: a second-order triangle with its base on a CAD edge and its apex and
  /// two side nodes inside a narrow face untangles only when the apex and both side nodes move
  /// at once, which neither the node-by-node steps nor the harmonic layout (a non-convex
  /// outline) nor the joint Newton steps on f̂ (whose δ-regularized merit may prefer a fold)
  /// find. A compass search in (u,v) over those nodes raises the smallest scaled det S over e
  /// and the valid elements around them (the validity the sweeps weigh, without the measure)
  /// until it is positive, from their positions and perturbations of them (a fixed sequence
  /// per element: the result does not depend on threads); kept only when fewer of the elements
  /// around the nodes stay tangled — strict progress, like every escape. Returns the number of
  /// elements untangled. escapeTangledElements tries e's own nodes, then those with the Face
  /// nodes of the elements around them (a neighbour in the way must give room).
  std::size_t widenElement(std::size_t e, const std::vector<std::size_t>& nodes, int face,
                           const Surface& surf);

  /// The harmonic layout of escapeTangledElements is of the corners (a node's neighbours are
  /// the corners of its elements). A side or interior node of a high-order triangle or a
  /// quad8 in `patch` (no element's corner) goes instead to its place on straight sides in
  /// (u,v) between its element's corners (straightPlace), as laid out in `uv` (the patch's
  /// corners) or where they are: the average of the corners of a side's two elements would
  /// bend that side towards one of them (a second-order element with a Face corner and two
  /// Face side nodes between two nodes on a CAD edge stayed folded after every harmonic
  /// layout).
  void straightSides(const std::vector<std::size_t>& patch, int face, const Surface& surf,
                     std::vector<Vec2>* uv) const;

  /// Patch untangling budget of one escape (per element and ring at most two attempts), and
  /// the largest patch it untangles (at most 60 sweeps over its nodes per attempt).
  static constexpr int kMaxRelaxPatches = 48;
  static constexpr std::size_t kMaxRelaxPatchNodes = 96;
  /// Starts of widenElement's search (its nodes' positions, then perturbations of them).
  static constexpr int kWidenStarts = 16;
  /// Most nodes widenElement moves (e's and one ring around them).
  static constexpr std::size_t kMaxWidenNodes = 24;

 private:
  int relaxTries_ = 0;

  State& s_;
  Worker& w_;

  /// The elements around `nodes`, sorted and without repeats.
  void elementsAround(const std::vector<std::size_t>& nodes,
                      std::vector<std::size_t>* elems) const {
    elems->clear();
    for (std::size_t j : nodes)
      for (std::int64_t p = s_.begin(j); p < s_.end(j); ++p)
        elems->push_back(static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]));
    std::sort(elems->begin(), elems->end());
    elems->erase(std::unique(elems->begin(), elems->end()), elems->end());
  }

  /// How many of `elems` are tangled at the current positions (δ = 0).
  std::size_t tangledAmong(const std::vector<std::size_t>& elems) const {
    std::size_t t = 0;
    for (std::size_t q : elems)
      if (s_.evalWhole(q, 0.0).tangled) ++t;
    return t;
  }

  void save(const std::vector<std::size_t>& nodes, std::vector<Vec2>* uv, std::vector<Vec3>* xyz,
            std::vector<Vec3>* normal) const {
    uv->clear();
    xyz->clear();
    normal->clear();
    for (std::size_t j : nodes) {
      uv->push_back(s_.uv[j]);
      xyz->push_back(s_.xyz[j]);
      normal->push_back(s_.nodeNormal[j]);
    }
  }

  /// The strict progress every escape keeps to, so that none can cycle: `move()` changes the
  /// positions of `nodes` (Face nodes) and returns how many of the elements it watches are
  /// tangled then. Its result is kept when that is fewer than `t0`; else `nodes` are put back
  /// where they were. Returns the elements untangled.
  template <class Move>
  std::size_t keepIfFewer(const std::vector<std::size_t>& nodes, std::size_t t0, Move move) {
    std::vector<Vec2> uv;
    std::vector<Vec3> xyz, normal;
    save(nodes, &uv, &xyz, &normal);
    const std::size_t t1 = move();
    if (t1 < t0) return t0 - t1;
    restore(nodes, uv, xyz, normal);
    return 0;
  }

  /// Puts Face nodes `nodes` of `face` at the (wrapped) parameters `uv`: position, parameters
  /// and reference normal. False (some already placed) when a parameter is outside the
  /// trimmed face or at a degenerate point.
  bool placeAll(const std::vector<std::size_t>& nodes, const std::vector<Vec2>& uv, int face,
                const Surface& surf);

  void restore(const std::vector<std::size_t>& patch, const std::vector<Vec2>& uvSave,
               const std::vector<Vec3>& xyzSave, const std::vector<Vec3>& nSave) {
    for (std::size_t q = 0; q < patch.size(); ++q) {
      s_.uv[patch[q]] = uvSave[q];
      s_.xyz[patch[q]] = xyzSave[q];
      s_.nodeNormal[patch[q]] = nSave[q];
      s_.d2Valid[patch[q]] = 0;
    }
  }

  /// Untangles a stuck patch of Face nodes (the rest of the mesh held) by Gauss–Seidel sweeps
  /// of the local Newton steps over its nodes, with a node's move allowed to tangle elements
  /// of its submesh as long as f̂ decreases — as the paper's untangling, which the sweep's
  /// safeguard (never more tangled elements around a node) forbids. Linear triangles use the
  /// σ of their projection on the reference normal meanwhile: continuous across a triangle
  /// standing on its edge across a curved surface (where ±‖c‖ jumps, so that the barrier is
  /// invisible to the Newton steps). δ̂ follows a continuation 4, 1, 1/4, 1/16 × the sweep's,
  /// 15 sweeps each. Leaves the patch at the stage with the fewest tangled elements among
  /// `countTangled`'s (by the sweep's rule) and returns that count (`t0`, positions left as
  /// they are, when no stage beats it).
  template <class Count>
  std::size_t relaxPatch(const std::vector<std::size_t>& patch, Count& countTangled,
                         std::size_t t0);

  /// Submesh of node i with the node at x. `nfree(j)` gives the node's corner normal in the
  /// j-th incident element, `old(j)` its normal there before the move (Edge nodes).
  /// With derivatives when g/H are non-null. A trial (`cur` non-null) stops as soon as it
  /// cannot be accepted against `cur`; its per-element values land in the worker's scratch.
  /// With a tangent basis `T` (and `HUV` non-null) the Hessian is accumulated projected on it,
  /// as (h00, h01, h11), instead of in H.
  template <class NFree, class NOld>
  LocalEval evalLocal(std::size_t i, const Vec3& x, NFree nfree, NOld old, bool wantQuality,
                      const LocalEval* cur, Vec3* g, Mat3* H, const Tangent* T = nullptr,
                      Vec3* HUV = nullptr) {
    LocalEval r;
    if (g) g->setZero();
    if (H) H->setZero();
    if (HUV) HUV->setZero();
    const std::int64_t b = s_.begin(i), en = s_.end(i);
    const bool needEta0 = wantQuality || (cur && s_.mode.trackCache);
    Vec3* base = w_.baseNormal.data();
    for (std::int64_t p = b; p < en; ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      const int local = s_.inc.local[static_cast<std::size_t>(p)];
      const std::size_t j = static_cast<std::size_t>(p - b);
      const bool corner = local < cornerCount(s_.mesh.elemType[e]);
      // The element's normal without the free node's corner: the same for every trial of
      // this update (the nodes of one color share no element), so trials reuse it.
      if (!cur)
        base[j] = corner ? s_.rawNormal(e, static_cast<std::int64_t>(i), Vec3::Zero(), old(j))
                         : s_.rawNormal(e, -1, Vec3::Zero(), Vec3::Zero());
      const Vec3 nref = s_.usableNormal(e, corner ? Vec3(base[j] + nfree(j)) : base[j]);
      // A linear triangle's corner normals (acrossArea): the free node's, then its next and
      // previous corners' (the same for every trial of this update).
      bool guarded = s_.guarded(e);
      const bool tri = s_.mesh.elemType[e] == ElementType::Tri3 && guarded;
      Vec3 corners[kHeldSlots];
      if (tri) {
        Vec3* other = w_.otherNormals.data() + 2 * j;
        if (!cur) {
          other[0] = s_.cornerNormal(e, local == 2 ? 0 : local + 1);
          other[1] = s_.cornerNormal(e, local == 0 ? 2 : local - 1);
        }
        corners[0] = nfree(j);
        corners[1] = other[0];
        corners[2] = other[1];
      } else if (guarded) {
        // A held high-order triangle's or quad8's corner normals in its corners' order, the
        // free node's (when a corner) at the trial. Not held in this update when it stands
        // across already (an escape's joint move may leave it so): its nodes stay free to move.
        const int nc = s_.heldNormalCount(e);
        Vec3* kept = w_.cornerNormals.data() + kHeldSlots * j;
        if (!cur)
          for (int k = 0; k < nc; ++k)
            kept[k] = s_.heldNormal(
                e, k, *w_.geo.surfaces[static_cast<std::size_t>(s_.mesh.elemFace[e])]);
        for (int k = 0; k < nc; ++k) corners[k] = k == local ? nfree(j) : kept[k];
        if (!cur)
          w_.holdHere[j] = !s_.turnedAgainstNow(
              e, corners, *w_.geo.surfaces[static_cast<std::size_t>(s_.mesh.elemFace[e])]);
        guarded = w_.holdHere[j] != 0;
      }
      // A high-order triangle's Jacobians without the free node's term: the same for every
      // trial of this update too.
      HighOrderJacobians* pre = nullptr;
      if (isHighOrderTriangle(s_.mesh.elemType[e])) {
        pre = &w_.highOrder[j];
        if (!cur) s_.highOrderRest(e, local, pre);
      }
      const double delta = s_.mode.deltaHat * s_.deltaScale[e];
      Vec3 ge;
      Mat3 He;
      Vec3 heUV = Vec3::Zero();
      const ElemOut ev = HUV ? s_.evalElementUV(e, local, x, nref, delta, needEta0, *T, &ge, &heUV,
                                                pre, guarded ? corners : nullptr)
                             : s_.evalElement(e, local, x, nref, delta, needEta0, g ? &ge : nullptr,
                                              H ? &He : nullptr, pre, guarded ? corners : nullptr);
      if (cur) {
        w_.eta0[j] = ev.eta0;
        w_.sig[j] = ev.minSigma;
      }
      if (ev.held) w_.heldAcross = true;
      if (ev.tangled) {
        ++r.tangled;
        if (cur && r.tangled > cur->tangled && !s_.mode.relaxTangled) return reject();
      }
      if (!std::isfinite(ev.eta)) {
        r.finite = false;
        r.f = kInf;
        if (cur) return reject();
        continue;
      }
      const double d = ev.eta - 1.0;
      r.f += d * d;
      r.maxEta = std::max(r.maxEta, ev.eta);
      if (cur && !(r.f < cur->f)) return reject();
      if (g) *g += 2.0 * d * ge;
      if (H) *H += 2.0 * (ge * ge.transpose() + d * He);
      if (HUV) {
        const Vec2 gu(T->du.dot(ge), T->dv.dot(ge));
        *HUV += 2.0 * (Vec3(gu.x() * gu.x(), gu.x() * gu.y(), gu.y() * gu.y()) + d * heUV);
      }
      if (wantQuality) {
        const double q = (ev.tangled || !std::isfinite(ev.eta0)) ? 0.0 : 1.0 / ev.eta0;
        if (q < r.minQuality) {
          r.minQuality = q;
          if (g) r.gradWorst = ge;
        }
        if (cur && q < qualityBar(*cur)) {
          LocalEval rq = reject();
          rq.byQuality = true;
          return rq;
        }
      }
    }
    return r;
  }

  static LocalEval reject() {
    LocalEval r;
    r.finite = false;
    r.f = kInf;
    return r;
  }

  /// Acceptance test of a complete trial against the current state.
  bool acceptable(const LocalEval& cur, const LocalEval& trial) const {
    if (!trial.finite) return false;
    if (trial.tangled > cur.tangled && !s_.mode.relaxTangled) return false;
    if (!(trial.f < cur.f)) return false;
    if (s_.opt.monotone && cur.tangled == 0 && trial.minQuality < qualityBar(cur)) return false;
    return true;
  }

  /// Monotone mode: the least minimum quality of a valid submesh a move may leave — its
  /// current minimum or, when lower, the sweep's quality floor (the mesh's minimum over the
  /// elements with a movable node): no element falls below the mesh's minimum.
  double qualityBar(const LocalEval& cur) const {
    return std::min(cur.minQuality, s_.mode.qualityFloor);
  }

  /// Keeps the element values of the trial just evaluated (and accepted) for commitElements.
  void keepTrial() {
    w_.eta0.swap(w_.keptEta0);
    w_.sig.swap(w_.keptSig);
  }

  /// Records the kept trial's element values (δ = 0 sweeps keep the cache current).
  void commitElements(std::size_t i) {
    if (!s_.mode.trackCache) return;
    const std::int64_t b = s_.begin(i), en = s_.end(i);
    for (std::int64_t p = b; p < en; ++p) {
      const std::size_t e = static_cast<std::size_t>(s_.inc.elem[static_cast<std::size_t>(p)]);
      s_.eta0[e] = w_.keptEta0[static_cast<std::size_t>(p - b)];
      s_.minSigma[e] = w_.keptSig[static_cast<std::size_t>(p - b)];
    }
  }

  /// Whether a smoothing sweep (δ = 0) may try ω × a step of 3D length len3 at a node of local
  /// size L (see OptimizeOptions::overRelaxation): it must stay within L.
  bool overRelaxes(double len3, double L) const {
    const double omega = s_.opt.overRelaxation;
    return omega > 1.0 && s_.mode.deltaHat == 0.0 && omega * len3 <= L;
  }

  /// The line search's step factor at trial ls: ω at ls = −1 (an over-relaxed first trial),
  /// then 1, ½, ¼, …
  double stepFactor(int ls) const { return ls < 0 ? s_.opt.overRelaxation : std::ldexp(1.0, -ls); }

  /// Whether step b goes on the way step a went: the angle between them, measured in the
  /// surface's metric G, is below 60° (a zero step goes no way).
  static bool sameWay(const Vec2& a, const Vec2& b, const Mat2& G) {
    const double aa = a.dot(G * a), bb = b.dot(G * b);
    return aa > 0.0 && bb > 0.0 && a.dot(G * b) > 0.5 * std::sqrt(aa * bb);
  }

  double updateFaceNode(std::size_t i);

  /// Where a Face node of `face` at uv0 (surface derivatives d, orientation `orient`) whose
  /// fold the Newton step cannot open goes (updateFaceNode): the candidate among the centre of
  /// its kernel in (u,v) (kernelCenter), the parametric centroid of its neighbours
  /// (neighbourCentroid) and the points halfway and a quarter of the way there that leaves the
  /// fewest elements of its submesh tangled (then the lowest f̂), when fewer than `threshold`.
  /// Fills *uv, *dn, *nn (its parameters, derivatives and normal); false when none does.
  bool foldTarget(std::size_t i, int face, const Surface& surf, const Vec2& uv0, const NodeD2& d,
                  double orient, int threshold, Vec2* uv, SurfaceD2* dn, Vec3* nn);
  double updateEdgeNode(std::size_t i);

  /// The corner normals of sliding node i in each incident element at curve parameter t, into
  /// the worker's scratch.
  void edgeTrialNormals(std::size_t i, const Curve& curve, double t);

  /// Moves sliding node i to C(t) (its corner normals swapped in its elements' fixedNormal);
  /// returns the 3D move.
  double commitEdgeMove(std::size_t i, const Curve& curve, double t, const Vec3& x0);

  /// The 1-D counterpart of a Face node's escape: a sliding node whose Newton step fails or
  /// creeps while an element of its submesh (on either face of its edge) stays tangled scans
  /// its admissible interval [a, b] (uniformly, and geometrically towards both ends, where a
  /// triangle next to a CAD vertex may only be valid very close to it) and takes the point
  /// with the fewest tangled elements of its submesh (then the lowest f̂) when that is below
  /// `threshold` — strict progress, so it cannot cycle.
  bool slideEscape(std::size_t i, const Curve& curve, double a, double b, int threshold,
                   double* tOut);

  /// Parametric centroid, on face `face` next to uv0, of the corners of Face node i's elements
  /// other than i (a Laplacian target, as Gmsh's Laplace2D).
  bool neighbourCentroid(std::size_t i, int face, const Surface& surf, const Vec2& uv0, Vec2* c);

  /// The point of Face node i's "kernel" in (u,v) farthest from its boundary: every corner
  /// triangle of node i's elements that contains i is positively wound in (u,v) (for the face's
  /// reference orientation `orient`) exactly when i lies on the inner side of the line through
  /// the triangle's other two corners. The Chebyshev centre of these half-planes, measured in
  /// the metric of the surface's first fundamental form at uv0 (so that a strongly anisotropic
  /// parameterization does not skew it), found by enumerating the triples of lines (a 2-D
  /// linear program with a handful of constraints). False when the kernel is empty.
  bool kernelCenter(std::size_t i, int face, const Surface& surf, const Vec2& uv0, const NodeD2& d,
                    double orient, Vec2* centre);

  /// Current (u,v) on face `face`, next to `near`, of node j at corner k of element e (on that
  /// face): Face nodes of the face at their current (u,v), sliding Edge nodes at their current
  /// curve point (through the edge's pcurve), other nodes at their corner (u,v).
  Vec2 cornerOnFace(std::size_t e, int k, int face, const Surface& surf, const Vec2& near) const {
    const std::size_t j = static_cast<std::size_t>(s_.mesh.elementNodes(e)[k]);
    const Vec2& corner = s_.mesh.cornerUV[static_cast<std::size_t>(s_.mesh.elemOffset[e] + k)];
    Vec2 uvj = corner;
    if (s_.mesh.nodeKind[j] == NodeKind::Face && s_.mesh.nodeFace[j] == face) {
      uvj = s_.uv[j];
    } else if (s_.mesh.nodeKind[j] == NodeKind::Edge) {
      const Curve& cj = *w_.geo.curves[static_cast<std::size_t>(s_.mesh.nodeEdge[j])];
      uvj = cj.uvOnFace(face, s_.t[j], corner);
    }
    return surf.unwrapNear(uvj, near);
  }

  /// Escape of last resort for a tangled element that the Newton steps, the kernel centre, the
  /// neighbours' centroid and the patch untanglings leave: Face node i (of `face`) tries the
  /// centres of a kSampleGrid² grid over the parametric box of its elements' other corners.
  /// Without `valid`: moves to the one leaving the fewest elements of its submesh tangled (then
  /// the lowest f̂), when that is fewer than at its position — strict progress, like every
  /// escape; returns the number of elements untangled. On a thin, strongly curved face a
  /// triangle can stand across the surface with its free node far along the face from the
  /// others (the bottle's thread): the valid positions, nearer to them, lie beyond a barrier of
  /// f̂ that no local step crosses, and off the kernel (the triangle is wound right in (u,v)).
  /// With `valid` (an element of i's): sets *target to the point where that element is valid
  /// and the fewest elements of the submesh are tangled (then the lowest f̂), without moving i;
  /// returns 1 when there is one.
  std::size_t sampleNeighbourhood(std::size_t i, int face, const Surface& surf,
                                  std::int64_t valid = -1, Vec2* target = nullptr);
};

}  // namespace detail
}  // namespace surfmesh
