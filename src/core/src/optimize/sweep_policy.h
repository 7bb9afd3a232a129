// The two policies of a run's sweeps (optimizer internals): the δ of each sweep
// (OptimizeOptions::deltaPolicy, deltaEpsilon, deltaStallSweeps) and when a run stops
// untangling or has converged. Plain values, tested on their own (sweep_policy_test.cpp).
#pragma once

#include "surfmesh/optimize/optimizer.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace surfmesh {
namespace detail {

/// The regularization δ̂ of each sweep. "fixed": OptimizeOptions::delta while an element is
/// tangled. "auto": δ̂ = √(ε(ε − σ_min)) from the smallest scaled det S (≤ 0), with ε cycled
/// through ε, ε/3, ε/9 when untangling stalls (deltaStallSweeps sweeps without fewer tangled
/// elements than ever, or a sweep that moved no node). Zero once no element is tangled.
class DeltaPolicy {
 public:
  /// `tangled`: the tangled elements with a movable node at the start of the run.
  DeltaPolicy(const OptimizeOptions& opt, std::size_t tangled)
      : fixed_(opt.deltaPolicy == "fixed"),
        delta_(opt.delta),
        epsilon0_(opt.deltaEpsilon),
        epsilon_(opt.deltaEpsilon),
        stallSweeps_(std::max(1, opt.deltaStallSweeps)),
        bestTangled_(tangled) {}

  /// δ̂ for a mesh with `tangled` tangled elements with a movable node and `minSigma` the
  /// smallest scaled det S of the elements that set it (the held folds included).
  double delta(std::size_t tangled, double minSigma) const {
    if (tangled == 0) return 0.0;
    if (fixed_) return delta_;
    const double eps = epsilon_;
    // The held elements still set δ while other elements are tangled: their nodes' moves are
    // measured with the same regularization as if they could be repaired (as before they were
    // held), only they no longer keep the untangling going.
    const double sm = std::min(minSigma, 0.0);
    return std::sqrt(eps * (eps - sm));
  }

  /// After an untangling sweep of the automatic policy that left `tangled` elements and moved
  /// `moved` nodes: cycles ε on a stall. True at a fixed point: no node moved with any of the
  /// three ε (three sweeps in a row without a move).
  bool afterUntanglingSweep(std::size_t tangled, std::size_t moved) {
    if (tangled < bestTangled_) {
      bestTangled_ = tangled;
      stalled_ = 0;
    } else {
      ++stalled_;
    }
    zeroMoves_ = moved == 0 ? zeroMoves_ + 1 : 0;
    if (stalled_ >= stallSweeps_ || moved == 0) {
      level_ = (level_ + 1) % 3;
      static const double kFactors[3] = {1.0, 1.0 / 3.0, 1.0 / 9.0};
      epsilon_ = epsilon0_ * kFactors[level_];
      stalled_ = 0;
    }
    return zeroMoves_ >= 3;
  }

  bool automatic() const { return !fixed_; }
  /// Which of ε, ε/3, ε/9 is in use (0, 1, 2).
  int epsilonLevel() const { return level_; }
  double epsilon() const { return epsilon_; }
  /// The fewest tangled elements after an untangling sweep of the automatic policy so far
  /// (the start's count before the first; unchanged under the fixed policy).
  std::size_t bestTangled() const { return bestTangled_; }

 private:
  bool fixed_;
  double delta_, epsilon0_, epsilon_;
  int stallSweeps_;
  std::size_t bestTangled_;
  int stalled_ = 0, zeroMoves_ = 0, level_ = 0;
};

/// When a run stops untangling, and when its smoothing has converged.
class StopRule {
 public:
  /// `tangled`: the tangled elements with a movable node at the start of the run.
  StopRule(const OptimizeOptions& opt, std::size_t tangled)
      : giveUpSweeps_(std::max(1, opt.giveUpStallCycles) * std::max(1, opt.deltaStallSweeps)),
        relTol_(opt.relTol),
        moveTol_(opt.moveTol),
        fewestTangled_(tangled) {}

  /// After sweep `sweep` left `tangled` elements: whether the run gives up untangling them,
  /// after giveUpSweeps() sweeps without fewer tangled elements than ever before.
  bool givesUp(int sweep, std::size_t tangled) {
    if (tangled < fewestTangled_) {
      fewestTangled_ = tangled;
      lastProgress_ = sweep;
    }
    return tangled > 0 && sweep - lastProgress_ >= giveUpSweeps_;
  }

  /// Whether a smoothing sweep (δ = 0, no element tangled) has converged: f (the movable
  /// elements' Σ (η − 1)²/2) and the quality deficit (their Σ (1 − q)) fell by at most relTol
  /// of their start, or no node moved by more than moveTol of its local size (`maxMove`).
  bool smoothed(double fStart, double fEnd, double deficitStart, double deficitEnd,
                double maxMove) const {
    auto decreaseBelowTol = [&](double start, double end) {
      return !(start > 0.0) || (start - end) <= relTol_ * std::max(start, 1e-300);
    };
    const bool decreaseSmall =
        decreaseBelowTol(fStart, fEnd) && decreaseBelowTol(deficitStart, deficitEnd);
    return decreaseSmall || maxMove <= moveTol_;
  }

  /// Untangling gives up after this many sweeps without fewer tangled elements than ever
  /// before: giveUpStallCycles × deltaStallSweeps; by default two full cycles of ε, every
  /// escape tried with each ε twice. (Over the 198 runs of the perturbation grid on three
  /// parts, and the test suite, the longest wait for a new best before reaching 0 tangled was
  /// 17 sweeps.)
  int giveUpSweeps() const { return giveUpSweeps_; }

 private:
  int giveUpSweeps_;
  double relTol_, moveTol_;
  std::size_t fewestTangled_;
  int lastProgress_ = 0;
};

}  // namespace detail
}  // namespace surfmesh
