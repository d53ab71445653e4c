// The explicit MPM solver core: shape functions, filling regions with points,
// conservation in free flight, the RVE's share of a dilating increment, the
// 1-D wave speed, tractions, errors and checkpoint round trips.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "mpm_client/core/elastic.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/shape.h"
#include "mpm_client/core/solver.h"
#include "mpm_client/core/solver_checkpoint.h"
#include "tests/mpm_client/core/solver_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm {
namespace {

using dem::testing_util::ExpectSameBits;
using Eigen::Matrix2d;
using Eigen::Matrix3d;
using Eigen::Vector2d;

// --- shape functions

GridSpec TestGrid() {
  GridSpec g;
  g.origin = Vector2d(0.3, -0.2);
  g.cell_size = 0.1;
  g.nx = 10;
  g.ny = 8;
  return g;
}

// The uniform GIMP weight in the closed form of Bardenhagen & Kober (2004),
// r = x_p − x_I, lp ≤ h/2.
double GimpClosedForm(double r, double h, double lp) {
  const double a = std::abs(r);
  if (a >= h + lp) return 0.0;
  if (a > h - lp) return (h + lp - a) * (h + lp - a) / (4.0 * h * lp);
  if (a > lp) return 1.0 - a / h;
  return 1.0 - (r * r + lp * lp) / (2.0 * h * lp);
}

TEST(ShapeTest, PartitionOfUnityAndConsistency) {
  const GridSpec grid = TestGrid();
  const double h = grid.cell_size;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> ux(grid.origin.x() + h,
                                            grid.origin.x() + (grid.nx - 1) * h);
  std::uniform_real_distribution<double> uy(grid.origin.y() + h,
                                            grid.origin.y() + (grid.ny - 1) * h);
  std::uniform_real_distribution<double> ul(0.05 * h, h);
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    for (int trial = 0; trial < 2000; ++trial) {
      const Vector2d x(ux(rng), uy(rng));
      const Vector2d lp(ul(rng), ul(rng));
      ShapeValues s;
      ASSERT_TRUE(EvaluateShape(grid, kind, x, lp, s));
      ASSERT_LE(s.count, kMaxShapeNodes);
      double sum = 0.0;
      Vector2d grad = Vector2d::Zero(), centroid = Vector2d::Zero();
      Matrix2d xg = Matrix2d::Zero();
      for (int k = 0; k < s.count; ++k) {
        EXPECT_GE(s.weight[k], -1e-15);
        sum += s.weight[k];
        grad += s.gradient[k];
        centroid += s.weight[k] * NodePosition(grid, s.node[k]);
        xg += NodePosition(grid, s.node[k]) * s.gradient[k].transpose();
      }
      EXPECT_NEAR(sum, 1.0, 1e-14);
      EXPECT_LT(grad.norm(), 1e-11);
      EXPECT_LT((xg - Matrix2d::Identity()).norm(), 1e-12) << xg;
      EXPECT_LT((centroid - x).norm(), 1e-14);  // interior: Σ S x_I = x
    }
  }
}

TEST(ShapeTest, GimpClippedAtTheGridBorderStillSumsToOne) {
  const GridSpec grid = TestGrid();
  const double h = grid.cell_size;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 0.6 * h);
  for (int trial = 0; trial < 500; ++trial) {
    // Near the lower-left and upper-right corners, domains sticking out.
    const Vector2d near_lo = grid.origin + Vector2d(u(rng), u(rng));
    const Vector2d near_hi =
        grid.origin + h * Vector2d(grid.nx, grid.ny) - Vector2d(u(rng), u(rng));
    for (const Vector2d& x : {near_lo, near_hi}) {
      ShapeValues s;
      ASSERT_TRUE(EvaluateShape(grid, ShapeKind::kGimp, x, Vector2d(0.5 * h, 0.5 * h), s));
      double sum = 0.0;
      Vector2d grad = Vector2d::Zero();
      Matrix2d xg = Matrix2d::Zero();
      for (int k = 0; k < s.count; ++k) {
        ASSERT_GE(s.node[k], 0);
        ASSERT_LT(s.node[k], NodeCount(grid));
        sum += s.weight[k];
        grad += s.gradient[k];
        xg += NodePosition(grid, s.node[k]) * s.gradient[k].transpose();
      }
      EXPECT_NEAR(sum, 1.0, 1e-14);
      EXPECT_LT(grad.norm(), 1e-11);
      EXPECT_LT((xg - Matrix2d::Identity()).norm(), 1e-12);
    }
  }
}

TEST(ShapeTest, GimpMatchesTheClosedFormAndLinearIsTheHat) {
  const GridSpec grid = TestGrid();
  const double h = grid.cell_size;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> ux(grid.origin.x() + h,
                                            grid.origin.x() + (grid.nx - 1) * h);
  std::uniform_real_distribution<double> uy(grid.origin.y() + h,
                                            grid.origin.y() + (grid.ny - 1) * h);
  std::uniform_real_distribution<double> ul(0.01 * h, 0.5 * h);
  for (int trial = 0; trial < 1000; ++trial) {
    const Vector2d x(ux(rng), uy(rng));
    const Vector2d lp(ul(rng), ul(rng));
    ShapeValues s, lin;
    ASSERT_TRUE(EvaluateShape(grid, ShapeKind::kGimp, x, lp, s));
    ASSERT_TRUE(EvaluateShape(grid, ShapeKind::kLinear, x, lp, lin));
    EXPECT_LE(s.count, 9);  // lp ≤ h/2: at most 3×3 nodes
    EXPECT_EQ(lin.count, 4);
    for (int k = 0; k < s.count; ++k) {
      const Vector2d r = x - NodePosition(grid, s.node[k]);
      const double expected = GimpClosedForm(r.x(), h, lp.x()) * GimpClosedForm(r.y(), h, lp.y());
      EXPECT_NEAR(s.weight[k], expected, 1e-13);
    }
    for (int k = 0; k < lin.count; ++k) {
      const Vector2d r = x - NodePosition(grid, lin.node[k]);
      EXPECT_NEAR(lin.weight[k], (1.0 - std::abs(r.x()) / h) * (1.0 - std::abs(r.y()) / h), 1e-14);
    }
  }
}

TEST(ShapeTest, GimpWeightsAndGradientsAreContinuousAcrossCellBoundaries) {
  const GridSpec grid = TestGrid();
  const double h = grid.cell_size;
  const double lp = 0.25 * h;
  const double y = grid.origin.y() + 3.37 * h;
  // Breakpoints along x: the grid line and x_I ± lp, x_I ± (h − lp).
  const double line = grid.origin.x() + 4.0 * h;
  for (double at : {line, line + lp, line - lp, line + h - lp, line - h + lp}) {
    const double eps = 1e-9 * h;
    ShapeValues left, right;
    ASSERT_TRUE(
        EvaluateShape(grid, ShapeKind::kGimp, Vector2d(at - eps, y), Vector2d(lp, lp), left));
    ASSERT_TRUE(
        EvaluateShape(grid, ShapeKind::kGimp, Vector2d(at + eps, y), Vector2d(lp, lp), right));
    std::map<int, std::pair<double, Vector2d>> l, r;
    for (int k = 0; k < left.count; ++k) l[left.node[k]] = {left.weight[k], left.gradient[k]};
    for (int k = 0; k < right.count; ++k) r[right.node[k]] = {right.weight[k], right.gradient[k]};
    for (int node = 0; node < NodeCount(grid); ++node) {
      const auto a = l.count(node) ? l[node] : std::make_pair(0.0, Vector2d(Vector2d::Zero()));
      const auto b = r.count(node) ? r[node] : std::make_pair(0.0, Vector2d(Vector2d::Zero()));
      EXPECT_NEAR(a.first, b.first, 1e-8) << "node " << node << " at x = " << at;
      EXPECT_LT((a.second - b.second).norm(), 1e-6) << "node " << node << " at x = " << at;
    }
  }
}

TEST(ShapeTest, OutsideTheGridIsRejected) {
  const GridSpec grid = TestGrid();
  ShapeValues s;
  EXPECT_FALSE(EvaluateShape(grid, ShapeKind::kLinear, Vector2d(0.29, 0.0), Vector2d::Zero(), s));
  EXPECT_FALSE(EvaluateShape(grid, ShapeKind::kGimp, Vector2d(0.5, 0.61), Vector2d(0.01, 0.01), s));
  EXPECT_FALSE(EvaluateShape(grid, ShapeKind::kGimp, Vector2d(NAN, 0.0), Vector2d(0.01, 0.01), s));
  // The closed rectangle counts as inside.
  EXPECT_TRUE(EvaluateShape(grid, ShapeKind::kLinear, Vector2d(1.3, 0.6), Vector2d::Zero(), s));
}

// --- filling and histories

TEST(FillRegionsTest, PointsMassesAndTractions) {
  CaseSpec spec = BlockCase(0.1, 10, 10, Vector2d(0.2, 0.0), Vector2d(0.6, 0.3), 2);
  spec.solver.thickness = 0.5;
  SurfaceTraction t = FaceLoad("top", 1, 1, Vector2d(0.0, -1e3));
  t.from = 0.3;
  t.to = 0.5;
  spec.tractions.push_back(t);
  absl::StatusOr<MaterialPoints> mp = FillRegions(spec);
  ASSERT_TRUE(mp.ok()) << mp.status();
  ASSERT_EQ(mp->size(), 4u * 3u * 4u);
  EXPECT_NEAR(TotalMass(*mp), 2000.0 * 0.4 * 0.3 * 0.5, 1e-9);
  EXPECT_DOUBLE_EQ(mp->position[0].x(), 0.225);
  EXPECT_DOUBLE_EQ(mp->half_size0[0].x(), 0.025);
  // Top layer (y = 0.275), x in [0.3, 0.5]: 0.325, 0.375, 0.425, 0.475.
  ASSERT_EQ(mp->loads.size(), 4u);
  for (const SurfaceLoad& load : mp->loads) {
    EXPECT_DOUBLE_EQ(mp->position[load.point].y(), 0.275);
    EXPECT_DOUBLE_EQ(load.length0, 0.05);
  }
  // Density 0 needs the callback; off-grid corners are rejected.
  spec.regions[0].density = 0.0;
  EXPECT_FALSE(FillRegions(spec).ok());
  absl::StatusOr<MaterialPoints> cb =
      FillRegions(spec, [](int) -> absl::StatusOr<double> { return 1500.0; });
  ASSERT_TRUE(cb.ok());
  EXPECT_NEAR(TotalMass(*cb), 1500.0 * 0.4 * 0.3 * 0.5, 1e-9);
  spec.regions[0].upper.x() = 0.63;
  EXPECT_EQ(FillRegions(spec, std::vector<double>{1500.0}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(VelocityHistoryTest, InterpolatesAndIntegrates) {
  const std::vector<VelocityPoint> h = {{1.0, Vector2d(0.0, -1.0)}, {3.0, Vector2d(2.0, -1.0)}};
  EXPECT_EQ(VelocityAt(h, 0.5), Vector2d(0.0, -1.0));
  EXPECT_EQ(VelocityAt(h, 2.0), Vector2d(1.0, -1.0));
  EXPECT_EQ(VelocityAt(h, 5.0), Vector2d(2.0, -1.0));
  // ∫0^4: x: 0 + (1/2)·2·2 + 2·1 = 4; y: −4.
  EXPECT_LT((DisplacementAt(h, 4.0) - Vector2d(4.0, -4.0)).norm(), 1e-14);
  EXPECT_LT((DisplacementAt(h, 2.0) - Vector2d(0.5, -2.0)).norm(), 1e-14);
  EXPECT_EQ(DisplacementAt({}, 3.0), Vector2d::Zero());
  // A velocity jump at t = 1 (two points at the same time).
  const std::vector<VelocityPoint> jump = {
      {0.0, Vector2d(0.0, 0.0)}, {1.0, Vector2d(2.0, 0.0)}, {1.0, Vector2d(0.0, 1.0)}};
  EXPECT_EQ(VelocityAt(jump, 1.5), Vector2d(0.0, 1.0));
  EXPECT_LT((DisplacementAt(jump, 1.5) - Vector2d(1.0, 0.5)).norm(), 1e-14);
  const std::vector<VelocityPoint> mid_jump = {{0.0, Vector2d(1.0, 0.0)},
                                               {1.0, Vector2d(1.0, 0.0)},
                                               {1.0, Vector2d(3.0, 0.0)},
                                               {2.0, Vector2d(3.0, 0.0)}};
  EXPECT_LT((DisplacementAt(mid_jump, 1.5) - Vector2d(2.5, 0.0)).norm(), 1e-14);
}

// --- free flight

TEST(FreeFlightTest, GravityMomentumGrowsAsMgt) {
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    CaseSpec spec = BlockCase(0.1, 20, 20, Vector2d(0.5, 0.5), Vector2d(1.5, 1.2), 2);
    spec.solver.shape = kind;
    spec.solver.gravity = Vector2d(0.0, -9.81);
    spec.solver.pic_fraction = 0.5;
    spec.solver.time_step = 1e-3;
    ZeroStressModel model;
    const Vector2d v0(0.3, 2.0);
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {v0});
    const double mass = TotalMass(solver->points());
    RunSteps(*solver, 200);
    EXPECT_EQ(TotalMass(solver->points()), mass);
    const Vector2d expected = mass * (v0 + solver->time() * spec.solver.gravity);
    EXPECT_LT((Momentum(solver->points()) - expected).norm(), 1e-12 * expected.norm());
  }
}

// --- the RVE's share of a dilating increment (rve.max_void_ratio)

TEST(RveIncrementTest, APackingAtTheCapShearsAndRotatesWithoutOpening) {
  Matrix2d df;
  df << 1.01, 0.02, -0.003, 1.004;  // dilating: det ≈ 1.014
  ASSERT_GT(df.determinant(), 1.0);
  PointResponse loose;  // stress-free
  loose.void_ratio = 0.5;
  const Matrix2d capped = RveIncrement(df, loose, 0.3);
  EXPECT_NEAR(capped.determinant(), 1.0, 1e-15);
  EXPECT_LT((capped * std::sqrt(df.determinant()) - df).norm(), 1e-15);  // same shape change
  // Below the cap, without a cap or when squeezed: the continuum's own.
  PointResponse dense = loose;
  dense.void_ratio = 0.29;
  EXPECT_EQ(RveIncrement(df, dense, 0.3), df);
  EXPECT_EQ(RveIncrement(df, loose, 0.0), df);
  const Matrix2d squeeze = df.inverse();
  EXPECT_EQ(RveIncrement(squeeze, loose, 0.3), squeeze);
  // A packing that still pushes, however little, opens and unloads.
  PointResponse pushing = loose;
  pushing.stress(0, 1) = -1e-9;
  EXPECT_EQ(RveIncrement(df, pushing, 0.3), df);
}

TEST(RveIncrementTest, AnExpandingBlockOpensItsPointsButNotTheirPackingsAboveTheCap) {
  for (double e : {0.2, 0.5}) {
    SCOPED_TRACE(e);
    CaseSpec spec = BlockCase(0.1, 20, 20, Vector2d(0.5, 0.5), Vector2d(1.5, 1.5), 2);
    spec.solver.pic_fraction = 0.0;
    spec.solver.time_step = 1e-3;
    spec.rve.max_void_ratio = 0.3;
    absl::StatusOr<MaterialPoints> points = FillRegions(spec);
    ASSERT_TRUE(points.ok()) << points.status();
    const Vector2d centre(1.0, 1.0);
    for (std::size_t p = 0; p < points->size(); ++p) {
      points->velocity[p] = 0.5 * (points->position[p] - centre);  // dilating at 1 /s
    }
    RecordingModel model(e);
    absl::StatusOr<std::unique_ptr<Solver>> solver =
        Solver::Create(spec, *std::move(points), &model);
    ASSERT_TRUE(solver.ok()) << solver.status();
    // The first step's points have no RVE result yet (e = 0): never capped.
    RunSteps(**solver, 1);
    double most = 0.0;
    for (const Matrix3d& d : model.last()) most = std::max(most, d.determinant());
    EXPECT_GT(most, 1.0 + 5e-4);
    std::vector<double> volume_before = (*solver)->points().volume;
    RunSteps(**solver, 1);
    const MaterialPoints& mp = (*solver)->points();
    int opened = 0;
    for (std::size_t p = 0; p < mp.size(); ++p) {
      const double det = model.last()[p].determinant();
      if (mp.volume[p] > volume_before[p] * (1.0 + 5e-4)) ++opened;
      if (e < 0.3) {  // the packing takes the point's own volume change
        EXPECT_NEAR(det, mp.volume[p] / volume_before[p], 1e-12) << "point " << p;
      } else {
        EXPECT_NEAR(det, 1.0, 1e-14) << "point " << p;
      }
    }
    // The continuum opens as before either way.
    EXPECT_GT(opened, static_cast<int>(mp.size()) / 2);
    // The cap reads the checkpointed result: a resumed solver sends its
    // packings the same increments.
    std::map<std::string, std::vector<double>> doubles;
    std::map<std::string, std::vector<std::int64_t>> ints;
    ExportSolverState(**solver, doubles, ints);
    RecordingModel resumed_model(e);
    absl::StatusOr<std::unique_ptr<Solver>> resumed =
        SolverFromState(spec, doubles, ints, &resumed_model);
    ASSERT_TRUE(resumed.ok()) << resumed.status();
    RunSteps(**solver, 1);
    RunSteps(**resumed, 1);
    EXPECT_EQ(model.last(), resumed_model.last());
  }
}

TEST(FreeFlightTest, RigidTranslationConservesMomentumAndEnergyExactly) {
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    CaseSpec spec = BlockCase(0.1, 20, 20, Vector2d(0.5, 0.5), Vector2d(1.5, 1.2), 3);
    spec.solver.shape = kind;
    spec.solver.pic_fraction = 0.0;
    spec.solver.time_step = 1e-3;
    ZeroStressModel model;
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(1.3, -0.7)});
    const Vector2d p0 = Momentum(solver->points());
    const double e0 = solver->KineticEnergy();
    RunSteps(*solver, 300);
    EXPECT_EQ(Momentum(solver->points()), p0);
    EXPECT_EQ(solver->KineticEnergy(), e0);
    // The block moved rigidly: 0.39 m to the right.
    EXPECT_NEAR(solver->points().position[0].x(), 0.5 + 0.1 / 6 + 1.3 * 0.3, 1e-12);
  }
}

// --- 1-D wave speed

// A bar along x between roller walls (ε_yy = 0: 1-D strain) moves at −v0
// into a smooth wall at x = 0; the stopping front runs at c = sqrt(M/ρ).
// Returns the front speed between x = 0.5 m and 1.5 m from the half-amplitude
// crossings of the points' velocity.
double MeasuredWaveSpeed(ShapeKind kind, double youngs, double nu, double rho) {
  const double h = 0.01, v0 = 0.1;
  CaseSpec spec = BlockCase(h, 220, 1, Vector2d(0.0, 0.0), Vector2d(2.0, h), 2, rho);
  spec.solver.shape = kind;
  spec.solver.pic_fraction = 0.0;
  const double c = std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.solver.time_step = 0.1 * h / c;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kSmooth), MakeWall(1, h, ContactKind::kSmooth),
                MakeWall(0, 0.0, ContactKind::kSmooth)};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(-v0, 0.0)});
  // Probes: the lower points of the columns at x = 0.5025 and 1.5025 m.
  const int probe[2] = {100, 300};
  EXPECT_NEAR(solver->points().position[probe[0]].x(), 0.5025, 1e-12);
  EXPECT_NEAR(solver->points().position[probe[1]].x(), 1.5025, 1e-12);
  double arrival[2] = {-1.0, -1.0};
  double prev[2] = {-v0, -v0};
  while (arrival[1] < 0.0 && solver->time() < 2.0 * 2.0 / c) {
    const double t0 = solver->time();
    const absl::Status s = solver->Step();
    EXPECT_TRUE(s.ok()) << s;
    if (!s.ok()) return 0.0;
    for (int k = 0; k < 2; ++k) {
      const double v = solver->points().velocity[probe[k]].x();
      if (arrival[k] < 0.0 && v > -0.5 * v0) {
        // Linear interpolation of the crossing within the step.
        arrival[k] = t0 + solver->dt() * (-0.5 * v0 - prev[k]) / (v - prev[k]);
      }
      prev[k] = v;
    }
  }
  EXPECT_GT(arrival[1], 0.0);
  return (solver->points().position[probe[1]].x() - solver->points().position[probe[0]].x()) /
         (arrival[1] - arrival[0]);
}

TEST(WaveSpeedTest, OneDimensionalPWaveSpeed) {
  const double youngs = 10e6, nu = 0.3, rho = 2000.0;
  const double c = std::sqrt(PWaveModulus(youngs, nu) / rho);
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    const double measured = MeasuredWaveSpeed(kind, youngs, nu, rho);
    const double error = measured / c - 1.0;
    std::printf("wave speed (%s): measured %.4f m/s, c = %.4f m/s, error %+.3f %%\n",
                kind == ShapeKind::kLinear ? "linear" : "GIMP", measured, c, 100.0 * error);
    EXPECT_LT(std::abs(error), 0.02);
  }
}

// --- tractions

TEST(TractionTest, ConfinedBlockTakesTheAppliedPressure) {
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    const double rho = 2000.0, youngs = 2e6, nu = 0.3, p = 1e3, h = 0.05;
    CaseSpec spec = BlockCase(h, 12, 10, Vector2d(0.0, 0.0), Vector2d(0.4, 0.4), 2, rho);
    spec.solver.shape = kind;
    spec.solver.pic_fraction = 1.0;
    spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
    spec.walls = {MakeWall(1, 0.0, ContactKind::kSmooth), MakeWall(0, 0.0, ContactKind::kSmooth)};
    SurfaceTraction t = FaceLoad("right", 0, 1, Vector2d(-p, 0.0));
    t.ramp_time = 0.02;
    spec.tractions = {t};
    LinearElasticModel model(youngs, nu);
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
    ASSERT_EQ(solver->points().loads.size(), 16u);
    RunSteps(*solver, 1500);
    double worst = 0.0;
    for (const Matrix3d& s : solver->points().stress) {
      worst = std::max(worst, std::abs(s(0, 0) / -p - 1.0));
    }
    std::printf("traction (%s): worst |sxx/(-p) - 1| = %.3g, left wall %.4g N (p·A = %.4g N)\n",
                kind == ShapeKind::kLinear ? "linear" : "GIMP", worst, solver->Reactions()[1].x(),
                -p * 0.4);
    EXPECT_LT(worst, 0.01);
    // The left wall takes the load: the soil pushes it towards −x.
    EXPECT_NEAR(solver->Reactions()[1].x(), -p * 0.4 * spec.solver.thickness, 0.01 * p * 0.4);
  }
}

TEST(TractionTest, LoadFactorFollowsTheHistoryOrTheRamp) {
  const std::vector<LoadFactorPoint> pulse = {{0.01, 0.0}, {0.02, 1.0}, {0.04, 0.0}};
  EXPECT_EQ(LoadFactorAt(pulse, 0.0, 0.0), 0.0);  // held before the first time
  EXPECT_DOUBLE_EQ(LoadFactorAt(pulse, 0.0, 0.015), 0.5);
  EXPECT_EQ(LoadFactorAt(pulse, 0.0, 0.02), 1.0);
  EXPECT_DOUBLE_EQ(LoadFactorAt(pulse, 0.0, 0.03), 0.5);
  EXPECT_EQ(LoadFactorAt(pulse, 0.0, 1.0), 0.0);           // held after the last
  EXPECT_DOUBLE_EQ(LoadFactorAt(pulse, 5.0, 0.015), 0.5);  // a history overrides the ramp
  EXPECT_EQ(LoadFactorAt({}, 0.02, 0.005), 0.25);
  EXPECT_EQ(LoadFactorAt({}, 0.02, 0.05), 1.0);
  EXPECT_EQ(LoadFactorAt({}, 0.0, 0.0), 1.0);
}

// A pulse on a free block (no walls, no gravity): MPM conserves momentum, so
// the block's momentum after the pulse is the load's impulse, t·L·thickness
// times the area under the factor (0.01 s for a triangle of 0.02 s; the steps
// land on the history's points). The load acts on the current surface length,
// which the elastic block (strain ~p/E = 5e-4) changes by ~1e-5: the bound.
TEST(TractionTest, PulseGivesAFreeBlockItsImpulse) {
  const double youngs = 2e6, nu = 0.3, rho = 2000.0, h = 0.05, p = 1e3;
  CaseSpec spec = BlockCase(h, 20, 20, Vector2d(0.3, 0.3), Vector2d(0.7, 0.6), 2, rho);
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.pic_fraction = 0.0;
  spec.solver.time_step = 1e-3;
  SurfaceTraction t = FaceLoad("impulse", 1, 1, Vector2d(0.0, -p));
  t.history = {{0.0, 0.0}, {0.01, 1.0}, {0.02, 0.0}};
  t.from = 0.4;
  t.to = 0.6;
  spec.tractions = {t};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  ASSERT_EQ(solver->points().loads.size(), 8u);  // 0.2 m of the face, 0.025 m apart
  RunSteps(*solver, 40);
  const Vector2d expected(0.0, -p * 0.2 * spec.solver.thickness * 0.01);
  const Vector2d momentum = Momentum(solver->points());
  std::printf("pulse impulse: momentum (%.6g, %.6g) N s, expected (0, %.6g)\n", momentum.x(),
              momentum.y(), expected.y());
  EXPECT_LT((momentum - expected).norm(), 1e-4 * expected.norm());
}

// A point stretched to 6 times its width (a shear band's point with 1 point
// per cell) has its surface 3 cells out, where no node has mass: its own
// nodes take the load, and the block gets the full impulse. (The step used
// to fail there.)
TEST(TractionTest, AStretchedPointsLoadGoesToItsOwnNodesWhereItsSurfaceHasNone) {
  const double h = 0.1, p = 1e3, dt = 1e-3;
  CaseSpec spec = BlockCase(h, 10, 10, Vector2d(0.4, 0.4), Vector2d(0.5, 0.5), 1);
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.pic_fraction = 0.0;
  spec.solver.time_step = dt;
  spec.tractions = {FaceLoad("push", 0, 1, Vector2d(-p, 0.0))};
  ZeroStressModel model;
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  ASSERT_EQ(solver->points().size(), 1u);
  ASSERT_EQ(solver->points().loads.size(), 1u);
  solver->mutable_points().F[0] = Eigen::Vector2d(6.0, 1.0).asDiagonal();
  ASSERT_TRUE(solver->Step().ok());
  // The face keeps its height h (the load's length follows F's y column).
  const Vector2d expected(-p * h * spec.solver.thickness * dt, 0.0);
  EXPECT_LT((Momentum(solver->points()) - expected).norm(), 1e-12 * expected.norm());
}

// --- errors

TEST(SolverErrorsTest, InvalidSpecsAndPointsLeavingTheGrid) {
  CaseSpec spec = BlockCase(0.1, 4, 4, Vector2d(0.1, 0.1), Vector2d(0.3, 0.3), 1);
  ZeroStressModel model;
  absl::StatusOr<MaterialPoints> mp = FillRegions(spec);
  ASSERT_TRUE(mp.ok());
  CaseSpec bad = spec;
  bad.walls = {MakeWall(0, 0.15, ContactKind::kSmooth)};
  EXPECT_EQ(Solver::Create(bad, *mp, &model).status().code(), absl::StatusCode::kInvalidArgument);
  bad = spec;
  bad.solver.pic_fraction = 1.5;
  EXPECT_EQ(Solver::Create(bad, *mp, &model).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(Solver::Create(spec, *mp, nullptr).ok());

  // No time step yet.
  std::unique_ptr<Solver> solver = *Solver::Create(spec, *mp, &model);
  EXPECT_EQ(solver->Step().code(), absl::StatusCode::kFailedPrecondition);
  // A point flying off the grid is named.
  solver->set_dt(0.01);
  solver->mutable_points().velocity[3] = Vector2d(0.0, 20.0);
  absl::Status s;
  for (int i = 0; i < 100 && s.ok(); ++i) s = solver->Step();
  EXPECT_EQ(s.code(), absl::StatusCode::kOutOfRange);
  EXPECT_NE(s.message().find("material point"), std::string::npos) << s;
}

// A model whose answer for one point is not finite is named before anything
// changes; a step that blows up (here a time step 1e200 s long: the free
// block's edge nodes reach an infinite velocity) stops with the point it
// left not finite, where before it returned OK, and under kDrop would have
// parked that point as off the grid without a word.
TEST(SolverErrorsTest, ANonFiniteAnswerOrStepIsAnErrorNamingThePoint) {
  const CaseSpec spec = BlockCase(0.1, 6, 6, Vector2d(0.2, 0.2), Vector2d(0.4, 0.4), 1);
  absl::StatusOr<MaterialPoints> mp = FillRegions(spec);
  ASSERT_TRUE(mp.ok());
  const std::size_t n = mp->size();
  std::vector<Matrix3d> stress(n, -1e5 * Matrix3d::Identity());
  stress[2](0, 1) = stress[2](1, 0) = std::numeric_limits<double>::quiet_NaN();
  FixedStressModel nan_model(stress);
  std::unique_ptr<Solver> solver = *Solver::Create(spec, *mp, &nan_model);
  solver->set_dt(1e-4);
  const absl::Status answer = solver->Step();
  EXPECT_EQ(answer.code(), absl::StatusCode::kInternal);
  EXPECT_NE(answer.message().find("material point 2 at (0.25, 0.35) m with a stress"),
            std::string::npos)
      << answer;
  EXPECT_EQ(solver->step(), 0);
  EXPECT_EQ(solver->points().stress, mp->stress);
  EXPECT_EQ(solver->points().F, mp->F);

  for (LostPointPolicy policy : {LostPointPolicy::kStop, LostPointPolicy::kDrop}) {
    CaseSpec unstable = spec;
    unstable.solver.lost_points = policy;
    FixedStressModel model(std::vector<Matrix3d>(n, -1e5 * Matrix3d::Identity()));
    solver = *Solver::Create(unstable, *mp, &model);
    solver->set_dt(1e200);
    const absl::Status s = solver->Step();
    EXPECT_EQ(s.code(), absl::StatusCode::kFailedPrecondition);
    EXPECT_NE(s.message().find("material point 0's position (-inf, -inf) m is not finite"),
              std::string::npos)
        << s;
    EXPECT_NE(s.message().find("became unstable"), std::string::npos) << s;
    EXPECT_EQ(solver->step(), 0);
    EXPECT_EQ(solver->time(), 0.0);
  }
}

// --- checkpoints

void ExpectBitIdentical(const Solver& a, const Solver& b) {
  std::map<std::string, std::vector<double>> da, db;
  std::map<std::string, std::vector<std::int64_t>> ia, ib;
  ExportSolverState(a, da, ia);
  ExportSolverState(b, db, ib);
  ASSERT_EQ(da.size(), db.size());
  for (const auto& [key, values] : da) {
    ExpectSameBits(values, db.at(key), key.c_str());
  }
  EXPECT_EQ(ia, ib);
}

TEST(CheckpointTest, ADroppedPointIsParkedOffTheGridAndResumesBitIdentically) {
  CaseSpec spec = BlockCase(0.1, 6, 6, Vector2d(0.1, 0.1), Vector2d(0.5, 0.5), 1);
  spec.solver.lost_points = LostPointPolicy::kDrop;
  ZeroStressModel model;
  absl::StatusOr<MaterialPoints> mp = FillRegions(spec);
  ASSERT_TRUE(mp.ok());
  std::unique_ptr<Solver> solver = *Solver::Create(spec, *mp, &model);
  solver->set_dt(0.01);
  solver->mutable_points().velocity[3] = Vector2d(0.0, 20.0);
  // Off the grid (y > 0.6 m) within a few steps, with the neighbours it
  // drags along through their shared nodes; the run goes on.
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(solver->Step().ok()) << i;
  const MaterialPoints& points = solver->points();
  const std::vector<std::uint8_t>& lost = solver->lost();
  ASSERT_EQ(lost.size(), points.size());
  const GridSpec& grid = spec.grid;
  int parked_count = 0;
  for (std::size_t p = 0; p < points.size(); ++p) {
    EXPECT_EQ(lost[p] == 1, !InsideGrid(grid, points.position[p])) << p;
    parked_count += lost[p];
  }
  EXPECT_EQ(lost[3], 1);
  EXPECT_LT(parked_count, static_cast<int>(points.size()) / 2);
  const Vector2d parked = points.position[3];
  EXPECT_GT(parked.y(), 0.6);
  // It stays where it left, with its mass, and out of the kinetic energy.
  double energy = 0.0;
  for (std::size_t p = 0; p < points.size(); ++p) {
    if (!lost[p]) energy += 0.5 * points.mass[p] * points.velocity[p].squaredNorm();
  }
  EXPECT_DOUBLE_EQ(solver->KineticEnergy(), energy);
  EXPECT_GT(points.velocity[3].norm(), 0.0);
  // A checkpoint holds no more than before: the parked point is off the
  // grid again after import, and both continue bit-identically.
  std::map<std::string, std::vector<double>> doubles;
  std::map<std::string, std::vector<std::int64_t>> ints;
  ExportSolverState(*solver, doubles, ints);
  std::unique_ptr<Solver> resumed = *Solver::Create(spec, *mp, &model);
  ASSERT_TRUE(ImportSolverState(*resumed, doubles, ints).ok());
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(solver->Step().ok());
    ASSERT_TRUE(resumed->Step().ok());
  }
  EXPECT_EQ(solver->points().position[3], parked);
  EXPECT_EQ(resumed->lost(), solver->lost());
  ExpectBitIdentical(*solver, *resumed);
}

TEST(CheckpointTest, ExportImportContinuesBitIdentically) {
  const double rho = 2000.0, g = 9.81, youngs = 2e6, nu = 0.3, h = 0.05;
  CaseSpec spec = BlockCase(h, 16, 12, Vector2d(0.2, 0.0), Vector2d(0.6, 0.4), 2, rho);
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.gravity = Vector2d(0.0, -g);
  spec.solver.pic_fraction = 0.1;
  spec.solver.wave_modulus = PWaveModulus(youngs, nu);
  spec.solver.cfl = 0.3;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kFrictional, 0.4),
                MakeWall(0, 0.2, ContactKind::kSmooth)};
  RigidBody pipe;
  pipe.name = "pipe";
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.center = Vector2d(0.45, 0.47);
  pipe.radius = 0.07;
  pipe.contact = ContactKind::kFrictional;
  pipe.friction = 0.3;
  pipe.velocity = {{0.0, Vector2d(0.0, 0.0)}, {0.01, Vector2d(0.02, -0.1)}};
  spec.bodies = {pipe};
  SurfaceTraction t = FaceLoad("surcharge", 1, 1, Vector2d(0.0, -2e3));
  t.ramp_time = 0.005;
  t.to = 0.35;
  SurfaceTraction pulse = t;  // a history travels with the checkpoint
  pulse.name = "pulse";
  pulse.ramp_time = 0.0;
  pulse.history = {{0.0, 0.0}, {0.003, 1.0}, {0.006, 0.0}};
  pulse.from = 0.4;
  pulse.to = 0.6;
  spec.tractions = {t, pulse};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> a = MakeSolver(spec, &model, {Vector2d(0.05, 0.0)});
  EXPECT_NEAR(a->dt(), 0.3 * h / std::sqrt(PWaveModulus(youngs, nu) / rho), 1e-18);
  RunSteps(*a, 10);
  std::map<std::string, std::vector<double>> doubles;
  std::map<std::string, std::vector<std::int64_t>> ints;
  ExportSolverState(*a, doubles, ints);
  LinearElasticModel model_b = model;  // the material's own state travels separately
  absl::StatusOr<std::unique_ptr<Solver>> b = SolverFromState(spec, doubles, ints, &model_b);
  ASSERT_TRUE(b.ok()) << b.status();
  ExpectBitIdentical(*a, **b);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(a->Step().ok());
    ASSERT_TRUE((*b)->Step().ok());
  }
  EXPECT_EQ(a->step(), 30);
  ExpectBitIdentical(*a, **b);
  EXPECT_EQ(a->Reactions(), (*b)->Reactions());

  // A state with a field missing or of the wrong length changes nothing.
  std::map<std::string, std::vector<double>> broken = doubles;
  broken.erase("velocity");
  EXPECT_EQ(ImportSolverState(**b, broken, ints).code(), absl::StatusCode::kInvalidArgument);
  broken = doubles;
  broken["stress"].pop_back();
  EXPECT_EQ(ImportSolverState(**b, broken, ints).code(), absl::StatusCode::kInvalidArgument);
  // A load naming a traction the case does not have.
  std::map<std::string, std::vector<std::int64_t>> bad_source = ints;
  bad_source["load_source"].back() = 2;
  const absl::Status named = ImportSolverState(**b, doubles, bad_source);
  EXPECT_EQ(named.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(named.message().find("names traction 2"), std::string::npos) << named;
  // Values that are not finite, or a time before the start.
  broken = doubles;
  broken["velocity"][3] = std::numeric_limits<double>::infinity();
  absl::Status refused = ImportSolverState(**b, broken, ints);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("material point 1: velocity ("), std::string::npos) << refused;
  EXPECT_NE(refused.message().find(", inf) m/s is not finite"), std::string::npos) << refused;
  broken = doubles;
  broken["response_stress"][9 * 4 + 8] = std::numeric_limits<double>::quiet_NaN();
  refused = ImportSolverState(**b, broken, ints);
  EXPECT_NE(refused.message().find("material point 4: RVE stress is not finite"), std::string::npos)
      << refused;
  broken = doubles;
  broken["time"][0] = -1.0;
  refused = ImportSolverState(**b, broken, ints);
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("state time -1 s"), std::string::npos) << refused;
  EXPECT_EQ((*b)->step(), 30);
  ExpectBitIdentical(*a, **b);

  // A history whose times do not increase is refused when the solver is made.
  CaseSpec unordered = spec;
  unordered.tractions[1].history[2].time = 0.003;
  LinearElasticModel model_c = model;
  absl::StatusOr<MaterialPoints> points = FillRegions(unordered);
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_EQ(Solver::Create(unordered, *points, &model_c).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace rvehub::mpm
