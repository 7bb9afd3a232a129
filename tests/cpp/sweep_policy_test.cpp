// The δ policy and the stop rule of a run's sweeps, on their own (src/core/src/optimize/
// sweep_policy.h): values computed by hand from OptimizeOptions' documentation.
#include "../../src/core/src/optimize/sweep_policy.h"

#include <gtest/gtest.h>

#include <cmath>

using surfmesh::OptimizeOptions;
using surfmesh::detail::DeltaPolicy;
using surfmesh::detail::StopRule;

TEST(DeltaPolicy, ZeroWithoutTangledElements) {
  OptimizeOptions opt;
  EXPECT_EQ(DeltaPolicy(opt, 0).delta(0, -3.0), 0.0);
  opt.deltaPolicy = "fixed";
  EXPECT_EQ(DeltaPolicy(opt, 0).delta(0, -3.0), 0.0);
}

TEST(DeltaPolicy, FixedIsTheOptionWhileTangled) {
  OptimizeOptions opt;
  opt.deltaPolicy = "fixed";
  opt.delta = 0.25;
  DeltaPolicy p(opt, 5);
  EXPECT_FALSE(p.automatic());
  EXPECT_EQ(p.delta(5, -2.0), 0.25);
  EXPECT_EQ(p.delta(1, 0.5), 0.25);
}

TEST(DeltaPolicy, AutoIsTheRegularizationOfTheSmallestDetS) {
  OptimizeOptions opt;
  opt.deltaPolicy = "auto";
  opt.deltaEpsilon = 0.01;
  DeltaPolicy p(opt, 3);
  EXPECT_TRUE(p.automatic());
  // δ̂ = √(ε(ε − σ_min)); a positive σ_min counts as 0 (δ̂ = ε).
  EXPECT_DOUBLE_EQ(p.delta(3, -0.5), std::sqrt(0.01 * 0.51));
  EXPECT_DOUBLE_EQ(p.delta(3, 0.2), 0.01);
}

TEST(DeltaPolicy, EpsilonCyclesAfterStalledSweeps) {
  OptimizeOptions opt;
  opt.deltaEpsilon = 0.09;
  opt.deltaStallSweeps = 2;
  DeltaPolicy p(opt, 10);
  EXPECT_EQ(p.epsilonLevel(), 0);
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));  // a new best: no stall
  EXPECT_EQ(p.bestTangled(), 8u);
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));  // stall 1
  EXPECT_EQ(p.epsilonLevel(), 0);
  EXPECT_FALSE(p.afterUntanglingSweep(9, 100));  // stall 2: ε/3
  EXPECT_EQ(p.epsilonLevel(), 1);
  EXPECT_DOUBLE_EQ(p.epsilon(), 0.03);
  EXPECT_DOUBLE_EQ(p.delta(8, 0.0), 0.03);
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));  // ε/9
  EXPECT_EQ(p.epsilonLevel(), 2);
  EXPECT_DOUBLE_EQ(p.epsilon(), 0.01);
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));
  EXPECT_FALSE(p.afterUntanglingSweep(8, 100));  // back to ε
  EXPECT_EQ(p.epsilonLevel(), 0);
  EXPECT_DOUBLE_EQ(p.epsilon(), 0.09);
}

TEST(DeltaPolicy, ThreeSweepsWithoutAMoveAreAFixedPoint) {
  OptimizeOptions opt;
  opt.deltaStallSweeps = 100;
  DeltaPolicy p(opt, 4);
  EXPECT_FALSE(p.afterUntanglingSweep(4, 0));  // every sweep without a move changes ε
  EXPECT_EQ(p.epsilonLevel(), 1);
  EXPECT_FALSE(p.afterUntanglingSweep(4, 0));
  EXPECT_EQ(p.epsilonLevel(), 2);
  EXPECT_FALSE(p.afterUntanglingSweep(4, 3));  // a move resets the count
  EXPECT_FALSE(p.afterUntanglingSweep(4, 0));
  EXPECT_FALSE(p.afterUntanglingSweep(4, 0));
  EXPECT_TRUE(p.afterUntanglingSweep(4, 0));
}

TEST(StopRule, GivesUpAfterItsStallCyclesWithoutANewFewest) {
  // 6 stall periods by default (two cycles of ε), 3 in the "reference" mode's repair runs
  for (int cycles : {6, 3}) {
    OptimizeOptions opt;
    opt.deltaStallSweeps = 2;
    if (cycles != 6) opt.giveUpStallCycles = cycles;
    StopRule stop(opt, 7);
    const int n = 2 * cycles;
    EXPECT_EQ(stop.giveUpSweeps(), n);
    EXPECT_FALSE(stop.givesUp(1, 5));  // new fewest at sweep 1
    for (int sweep = 2; sweep <= n; ++sweep) EXPECT_FALSE(stop.givesUp(sweep, 6)) << sweep;
    EXPECT_TRUE(stop.givesUp(n + 1, 5));   // n sweeps since the last new fewest
    EXPECT_FALSE(stop.givesUp(n + 2, 4));  // a new fewest
    EXPECT_FALSE(stop.givesUp(30, 0));     // nothing tangled: nothing to give up
  }
  OptimizeOptions opt;
  opt.deltaStallSweeps = 2;
  opt.giveUpStallCycles = 0;
  EXPECT_EQ(StopRule(opt, 7).giveUpSweeps(), 2);  // (at least one stall period)
}

TEST(StopRule, SmoothingConvergesOnSmallDecreaseOrSmallMoves) {
  OptimizeOptions opt;
  opt.relTol = 1e-3;
  opt.moveTol = 1e-4;
  const StopRule stop(opt, 0);
  // Both f and the deficit fell by at most relTol of their start.
  EXPECT_TRUE(stop.smoothed(10.0, 9.995, 2.0, 1.999, 1.0));
  // f fell by more: not converged, unless no node moved by more than moveTol.
  EXPECT_FALSE(stop.smoothed(10.0, 9.0, 2.0, 1.999, 1.0));
  EXPECT_TRUE(stop.smoothed(10.0, 9.0, 2.0, 1.999, 1e-4));
  // The deficit fell by more.
  EXPECT_FALSE(stop.smoothed(10.0, 9.995, 2.0, 1.9, 1.0));
  // A zero start counts as no decrease to wait for.
  EXPECT_TRUE(stop.smoothed(0.0, 0.0, 0.0, 0.0, 1.0));
}
