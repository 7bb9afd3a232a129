// SurfMesh — simultaneous smoothing and untangling in parametric coordinates (paper §4).
//
// Minimizes f = ½ Σ_e (η_e − 1)² over the (u,v) of the Face nodes (and the t of the Edge
// nodes) by a nonlinear Gauss–Seidel sweep: each movable node takes a safeguarded Newton step
// on its local merit function f̂ (eq. 18–19) with a backtracking line search, and its new
// position is φ(u,v) (or C(t)) — the nodes never leave the CAD geometry.
//
// Untangling: while the mesh has tangled elements, η is evaluated with σ replaced by
// σ*(σ; δ). δ is chosen every sweep from the smallest scaled det S over the mesh, σ_min
// (Escobar et al. 2003):  δ = √(ε(ε − σ_min)) when σ_min < ε, else 0, with ε = deltaEpsilon.
// Scaled means divided by a local size² of the node's submesh, so the policy does not depend
// on units. Once no element is tangled, δ = 0: the barrier measure keeps the mesh valid.
//
// Nodes are swept color by color (no two nodes of one color share an element), which makes
// the result independent of the number of threads: a persistent team of `threads` workers
// (one clone of every surface/curve each) takes the nodes of a color in chunks, with a
// barrier between colors. While tangled elements remain every node is updated each sweep;
// afterwards only the active ones (see moveTol). A node whose Newton step fails in a badly
// shaped submesh (an element with η > 4) also tries short steps along ±φ_u, ±φ_v and the
// diagonals. A sweep also stops early (StopReason::Converged) when no node moved and the next
// sweep would repeat it (a fixed point, even with tangled elements left).
//
// Escapes from local minima while elements stay tangled (each accepted only when it leaves
// fewer tangled elements among those it changes — strict progress, so nothing cycles): a
// tangled high-order triangle with a valid corner triangle gets straight sides in (u,v)
// (before the first sweep and between stalled sweeps, see straightenedElements); a Face
// node whose Newton step fails or only creeps tries the centre of its kernel in (u,v) and the
// centroid of its neighbours; a sliding node scans its interval on the edge; between sweeps
// without progress, the Face nodes of a stuck element and of up to three rings around it are
// moved together to the harmonic embedding of that patch (of its corners; a high-order
// element's side nodes on straight sides in (u,v) between them), and after three such sweeps in
// a row the element's own Face nodes (then with those of the elements around them) first move
// together by a compass search in (u,v) that raises the smallest det S over it and the valid
// elements around them until it is positive (a second-order triangle with its base on a CAD
// edge and its apex and two side nodes in a narrow face opens only so), then the patch is also
// untangled jointly (Newton steps on its nodes alone that may tangle more elements while the
// objective drops, δ stepped down from 4× to 1/16 of the sweep's, projected areas in place of
// signed ones so that thin elements standing across a curved surface can turn over; an element that
// stays stuck is untangled jointly again only after a backoff of 1, 2, 4, then deltaStallSweeps
// sweeps, or when ε changes level, and its harmonic layout alone is retried after the same backoff
// — see OptimizeResult::patchUntanglings); last, a Face node of a stuck element tries the points of
// a grid over the (u,v) box of its neighbours, alone, then (with the joint untangling) at the
// point where the element is valid with the other Face nodes of its elements untangled
// jointly around it. Tangled elements without a movable node cannot change:
// they do not keep δ > 0 and are reported (OptimizeResult::warnings). The same holds for an
// element that folds where only nodes that may not move act (a tangled corner triangle of a
// quadrilateral on three such nodes, or on three nodes of one CAD edge — sliding along it or
// at its vertices: the corner stays a triangle of the edge's curve; a high-order triangle tangled
// at a node or quadrature point where the shape functions of its movable nodes have no gradient,
// e.g. at a CAD vertex between two element edges on fixed CAD edges; when no corner may move, the
// element's normal cannot change, and such a fold counts whatever the surface's normals at its
// corners say): it is held from the start (while other elements are tangled it still sets δ and
// takes part in the escapes, so the run is the same until no other element is tangled; then it
// smooths with δ = 0). Neither do, after giveUpStallCycles × deltaStallSweeps sweeps (6 × 8 by
// default) without fewer tangled elements than ever before (each level of ε tried twice), the
// elements still tangled: their nodes are held from then on, the rest of the mesh is smoothed
// with δ = 0, and they are reported in tangledMovable.
//
// Triangles standing across the surface (standsAcross): a linear triangle is measured in its
// own plane, oriented by the sum of its corner normals, so one whose plane cuts through a thin
// tube can be valid and well shaped. Every linear triangle that neither stands across its
// surface nor leans more than about 84° from it at a corner at the start of the run (or is
// tangled and wound against every corner, with a Face corner) and has no sliding node is held
// from becoming so: its σ follows the surface's normal at its corners there and is ≤ 0 —
// tangled for the run — when it is wound against one (see acrossArea in triangle_kernel.h). The
// quality report keeps the paper's σ. Where the held run leaves tangled elements a node may
// move, and the hold acted (OptimizeResult::heldAcross), a second run without it follows from
// its result: untangling comes first.
//
// Guarantees: the number of tangled elements of a node's submesh never increases (so the
// mesh's never does); in monotone mode the minimum quality of a valid mesh never decreases
// (see OptimizeOptions::monotone); Face nodes stay exactly at φ(u,v) inside the surface's
// domain (contains()), Edge nodes exactly at C(t) between their edge neighbours.
#pragma once

#include "surfmesh/mesh/quality.h"
#include "surfmesh/mesh/surface_mesh.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace surfmesh {

/// The escapes of the sweeps from states the node-by-node Newton steps cannot leave with
/// elements tangled, one bit each of OptimizeOptions::escapes. Every escape keeps a move only
/// when fewer elements around it are tangled (strict progress).
enum Escape : unsigned {
  /// Curved elements' movable high-order nodes at their straight-sided places in (u,v).
  kEscapeStraighten = 1u << 0,
  /// A joint compass search over a stuck element's nodes (and one ring around them).
  kEscapeWiden = 1u << 1,
  /// The harmonic layout in (u,v) of a patch of 0–3 rings around a stuck element.
  kEscapeHarmonic = 1u << 2,
  /// The joint untangling of such a patch by Newton steps that may pass through folds.
  kEscapeRelaxPatch = 1u << 3,
  /// A stuck element's node at the best point of a grid over its neighbours.
  kEscapeSample = 1u << 4,
  /// A Face node's kernel centre or its neighbours' centroid when its Newton step stalls.
  kEscapeFoldTarget = 1u << 5,
  /// A Face node's fallback steps along ±φ_u, ±φ_v and the diagonals in a poor submesh.
  kEscapeCompass = 1u << 6,
  /// A sliding node's scan of its interval on its CAD edge when its Newton step stalls.
  kEscapeSlide = 1u << 7,
  kAllEscapes = (1u << 8) - 1,
};

/// The escapes' names, in the order of their bits (kEscapeNames[k] is bit 1 << k).
inline constexpr const char* kEscapeNames[] = {"straighten", "widen",       "harmonic", "relax",
                                               "sample",     "fold-target", "compass",  "slide"};

struct OptimizeOptions {
  /// Distortion measure (a name of measureNames()).
  std::string measure = "shape";
  /// Maximum number of sweeps over the movable nodes.
  int maxSweeps = 100;
  /// Once the mesh is untangled (δ = 0), stop when the relative decrease over a sweep,
  /// (start − end) / start, is at most relTol both for f and for the quality deficit Σ (1 − q)
  /// (each over the elements with a movable node: a poor element between fixed nodes would
  /// dwarf the decrease), OR when no node moved by more than moveTol × its local size (mean
  /// edge length of its submesh) in the sweep. The deficit keeps the run going while a few
  /// very poor elements that no move improves (η ~ 100 beside close CAD-edge nodes) make
  /// most of f and the rest of the mesh still gains quality. With the
  /// defaults the quality statistics change by less than about 1e-3 after the stop
  /// (Gauss–Seidel converges linearly: chasing the last digits costs hundreds of sweeps).
  double relTol = 1e-3;
  /// See relTol. Also the activity threshold: a node is updated again only when it or a node
  /// of its submesh moved by more than moveTol × local size since its last update (nodes
  /// whose neighbourhood did not change are skipped: their update would fail again).
  double moveTol = 1e-3;
  /// Newton iterations per node and sweep (the paper uses 1).
  int innerIterations = 1;
  /// Over-relaxation ω of the smoothing sweeps (δ = 0): a node whose Newton step goes on the
  /// way its previous one went (less than 60° apart in the surface's metric; along its edge for
  /// a sliding node) first tries ω × that step (when that is no longer than its local size),
  /// and the step and its halvings only when that trial is not accepted (it must lower f, like
  /// every trial). Gauss–Seidel removes a smooth, mesh-wide deviation from the optimum by a
  /// fraction per sweep only, its nodes creeping the same way sweep after sweep; ω > 1 carries
  /// it further each sweep (as successive over-relaxation does for linear systems). A node
  /// whose steps turn back and forth (a local deviation, which Gauss–Seidel removes quickly)
  /// takes plain steps. 1: off. Untangling sweeps (δ > 0) take plain steps.
  double overRelaxation = 1.9;
  /// Maximum halvings of the line search. It stops earlier once the step's 3D length falls
  /// below 0.1 × moveTol × the node's local size (a shorter step would not count as a move),
  /// and in monotone mode, when the submesh's minimum quality is the least a move may leave
  /// (see monotone), once a trial lowered it while the worst element's η grows along the step
  /// (every shorter step lowers it too, to first order).
  int maxLineSearch = 30;
  /// δ policy: "auto" (Escobar, from σ_min each sweep) or "fixed" (use `delta` while tangled).
  std::string deltaPolicy = "auto";
  /// ε of the automatic δ policy (dimensionless, relative to the local size²). When the number
  /// of tangled elements has not decreased for `deltaStallSweeps` sweeps (or no node moved),
  /// ε cycles through ε, ε/3, ε/9: a smaller δ keeps more of the barrier (it freed a perturbed
  /// crank arm where ε = 1e-2 left one element tangled), a larger one untangles heavily folded
  /// meshes (the order-2 revolution surface with half its elements tangled).
  double deltaEpsilon = 1e-2;
  /// Sweeps without fewer tangled elements before the automatic policy changes ε.
  int deltaStallSweeps = 8;
  /// Sweeps without fewer tangled elements than ever before after which a run gives up
  /// untangling (the elements still tangled are held, see above), in units of
  /// deltaStallSweeps: 6, two full cycles of ε with every escape tried twice at each level.
  /// The "reference" mode's repair runs use 3 (one cycle): they start from corners the
  /// linear run already untangled with the full patience, and what they leave tangled is
  /// mostly what no motion of the free nodes around it repairs. Not offered by the bindings.
  int giveUpStallCycles = 6;
  /// δ of the fixed policy (dimensionless).
  double delta = 1e-2;
  /// Reject the moves that would lower the mesh's minimum quality. While the mesh is being
  /// untangled (δ > 0), a move may not lower the minimum quality of its node's submesh when
  /// that submesh is valid. Once it is untangled, a move may lower its submesh's minimum down
  /// to, not below, the minimum quality of the mesh's elements with a movable node at the
  /// start of the sweep: the minimum over those elements never decreases from sweep to sweep,
  /// while nodes next to an element better than the worst stay free to trade some of its
  /// quality for a lower f (holding every submesh's minimum blocked about half of the node
  /// updates and left the mean quality lower on most CAD parts).
  bool monotone = true;
  /// Worker threads for the sweeps; 0 = all hardware threads.
  int threads = 0;
  /// How curved elements (tri6 … tri21, quad8) are optimized:
  ///  * "reference": against their straight-sided counterpart on the surface (same corners,
  ///    high-order nodes where interpolating the face puts them), the measure a FEM solver's
  ///    checks follow. The corners are optimized as the linear mesh they span with the paper's
  ///    linear measure, each high-order node inside its face then goes to its straight-sided
  ///    place, and only the elements that leaves invalid (and high-order nodes sliding along
  ///    CAD edges) are optimized further with the Definition-4 measure. On a plane a
  ///    straight-sided element stays affine. Never worse: the moves of a result that would
  ///    make an element valid in the input invalid, lower the minimum quality where no element
  ///    is tangled, or on a valid input lower the minimum corner quality or Jacobian ratio are
  ///    cut back (a shorter move for every node, or for the elements at fault) until none
  ///    does; when that leaves the input unchanged, more elements invalid than it or an
  ///    element tangled again, the "integral" result instead. Where elements stay invalid,
  ///    the "integral" mode again on them and three rings around them from the input's
  ///    positions there, taken when it leaves fewer, with the straight-sided result kept away
  ///    from the elements that one left invalid. Last, with the corners, the nodes on CAD
  ///    edges and those of invalid elements held, the high-order nodes inside the faces are
  ///    optimized against each element's straight-sided triangle (highOrderTargets), face by
  ///    face kept where that raises the face's mean Jacobian ratio and keeps every element
  ///    valid and the minimum ratio and quality (reference_mode.cpp).
  ///  * "integral": every node by the paper's Definition-4 integral measure (the paper's
  ///    Table 4); it may curve the sides of a straight-sided element to improve the measure.
  /// Linear meshes are the same in both modes.
  std::string highOrder = "reference";
  /// Whether the run may change the mesh's connectivity:
  ///  * "none": node motion only;
  ///  * "flip": the smoothing run is followed by passes of edge flips (edge_flips.h), each
  ///    followed by a run over the nodes within two rings of the rewired elements, until a
  ///    pass flips nothing (at most kMaxFlipRounds passes). A flip swaps the diagonal of two
  ///    triangles (tri3, or tri6 whose shared side node may move) of one face inside it, when
  ///    that raises the pair's smaller quality without lowering its smallest scaled Jacobian
  ///    or Jacobian ratio, or makes an invalid pair valid. Node ids and count, element ids and
  ///    faces are kept; only the two elements' node lists change (OptimizeResult::
  ///    rewiredElements). Quadrilaterals and triangles of order 3 and more are not flipped.
  std::string topology = "none";
  /// The escapes the sweeps may take (Escape bits, all by default). For ablation studies
  /// (bench_cad's BENCH_WITHOUT): not offered by the bindings.
  unsigned escapes = kAllEscapes;
  /// Empty, or one entry per node: nonzero for the nodes the run must leave where they are
  /// (held like CAD vertices; e.g. the nodes of the elements outside a region to optimize).
  std::vector<unsigned char> fixedNodes;
  /// Empty, or one entry per element: W⁻¹ of the ideal a high-order triangle's Jacobians are
  /// measured against (straightSidedTarget), instead of the equilateral triangle's; a zero
  /// entry (and every other element type) keeps the equilateral. The "reference" mode sets it
  /// for its repair stage; not offered by the bindings.
  std::vector<Mat2> highOrderTargets;
};

enum class StopReason { Converged, MaxSweeps, Cancelled, NothingToDo };
const char* stopReasonName(StopReason r);

/// Reported after every sweep (and the escapes that follow it), of the mesh as the sweep leaves
/// it, counted as the quality report counts (a triangle only the across hold counts as tangled
/// in the run is valid here); return false from the callback to cancel the run. A run whose
/// last check put nodes back (OptimizeResult::restoredNodes) reports once more, with the same
/// sweep number, of the mesh it returns.
struct OptimizeProgress {
  int sweep = 0;
  int maxSweeps = 0;
  double objective = 0.0;  ///< f = ½ Σ (η − 1)² with the δ of the sweep
  std::size_t tangled = 0;
  double minQuality = 0.0;
  double delta = 0.0;
  /// Which run of several this sweep belongs to (0 for a single run): the "reference" mode
  /// for curved elements runs the corners' linear mesh, then the repair, then possibly the
  /// "integral" mode around the elements the repair left invalid (or on the whole input when
  /// the repair made it worse), then the straightening, each counting tangled elements of its
  /// own mesh; a stage with no node to move reports nothing; sweep numbers go on across them.
  int stage = 0;
};
using ProgressCallback = std::function<bool(const OptimizeProgress&)>;

struct OptimizeResult {
  QualityStats before;
  QualityStats after;
  int sweeps = 0;
  double seconds = 0.0;
  StopReason reason = StopReason::Converged;
  double initialObjective = 0.0;
  double finalObjective = 0.0;
  std::size_t movedNodes = 0;  ///< nodes whose position changed
  int threadsUsed = 1;
  /// Escapes by patch untangling tried (each: one tangled element the node-by-node sweeps no
  /// longer untangle, its Face nodes within up to 3 rings relaxed jointly, up to 8 short runs
  /// over at most 96 nodes), summed over the run. An element that stays stuck is retried
  /// after 1, 2, 4, then every deltaStallSweeps sweeps, and when ε changes level: a few
  /// escapes per ε level, not one per stalled sweep.
  std::size_t patchUntanglings = 0;
  /// Tangled high-order triangles untangled by straightening: an element whose corner
  /// triangle is valid gets its movable edge and interior nodes at the parametric
  /// interpolation of its corners (straight sides in (u,v)), kept when fewer elements around
  /// them are tangled. Tried before the first sweep and between stalled sweeps.
  std::size_t straightenedElements = 0;
  /// Whether the run held a linear triangle from standing across its surface: a node move
  /// was weighed with the triangle leaning more than about 84° from the surface's normal at
  /// a corner (see the optimizer's acrossArea). Where the held run leaves tangled elements a
  /// node may move, a second run without the hold follows.
  bool heldAcross = false;
  /// Elements tangled after the run that fold where no node that may move acts (none of
  /// their nodes may move, or see the held folds above): no node motion can repair them.
  std::vector<std::int32_t> tangledUnmovable;
  /// Elements tangled after the run with at least one movable node.
  std::vector<std::int32_t> tangledMovable;
  /// Edge flips made (topology "flip"), and the elements whose node lists they changed
  /// (sorted; ids and faces kept).
  std::size_t flips = 0;
  std::vector<std::int32_t> rewiredElements;
  /// Topology "flip": elements left whose corners all lie on one CAD edge (its nodes and end
  /// vertices): a needle along the edge that neither flips nor moves can open; inserting or
  /// removing nodes would (needleElements in edge_flips.h).
  std::vector<std::int32_t> needles;
  /// Nodes put back where they were in the input because the run left invalid an element
  /// that was valid there (and so on, ring by ring: keep_valid.cpp). 0 on most runs: the
  /// sweeps and escapes keep valid elements valid; this makes it a guarantee.
  std::size_t restoredNodes = 0;
  /// One line per non-empty list above (count and element ids).
  std::vector<std::string> warnings;
};

/// Optimizes `mesh` in place (xyz, uv, nodeT, cornerUV of movable nodes).
///
/// With sliding (NodeKind::Edge) nodes the run has two phases of up to maxSweeps sweeps each:
/// first the Edge nodes are held (the result of a fixed boundary), then they slide from there.
/// The second phase never increases the number of tangled elements and, in monotone mode,
/// never lowers the minimum quality of a valid mesh: sliding never ends with more tangled
/// elements or a lower minimum quality than the fixed boundary. `sweeps` counts both phases,
/// progress reports sweeps out of 2 × maxSweeps.
///
/// With a measure other than "shape", a run that leaves tangled elements some node may move is
/// followed by one that untangles the input with the shape measure (whose barrier opens folds
/// the Oddy measure's can hold, e.g. a sliver at a fillet) and one with the measure from there;
/// that result is kept when it leaves fewer tangled elements (`sweeps` counts all three).
///
/// On cancellation
/// (callback returned false) or on an exception the mesh is left exactly as it was.
/// Throws std::invalid_argument for an invalid mesh or options.
///
/// `before`, when given, is the quality of the mesh as it is, with options.measure, that the
/// caller already measured (measureQuality(mesh, measure).stats): it becomes result.before
/// instead of being measured again.
OptimizeResult optimizeMesh(SurfaceMesh& mesh, const OptimizeOptions& options = {},
                            const ProgressCallback& progress = {},
                            const QualityStats* before = nullptr);

/// Greedy coloring of the movable nodes such that no two nodes of one color share an element.
/// Returns colors[c] = list of node ids.
std::vector<std::vector<std::int32_t>> colorMovableNodes(const SurfaceMesh& mesh);

}  // namespace surfmesh
