// The solver's schemes and its checkpoint arrays: Solver::Create picks the
// explicit or the two-phase scheme from the case, and a state exported by
// mpm_client/solver_checkpoint.h carries either scheme on bit-identically.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "mpm_client/core/elastic.h"
#include "mpm_client/core/explicit_solver.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/solver.h"
#include "mpm_client/core/solver_checkpoint.h"
#include "mpm_client/core/two_phase_solver.h"
#include "tests/mpm_client/core/solver_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm {
namespace {

using dem::testing_util::ExpectSameBits;
using Eigen::Vector2d;

using Doubles = std::map<std::string, std::vector<double>>;
using Ints = std::map<std::string, std::vector<std::int64_t>>;

constexpr double kYoungs = 10e6, kPoisson = 0.3;  // Pa, [-]

// A 0.4 m × 0.4 m block on 0.1 m cells, 2 × 2 points each, on a rough base
// between smooth walls, under gravity and a surcharge on its top; with
// `saturated`, its pores full of water drained at the top.
CaseSpec Block(bool saturated) {
  CaseSpec spec;
  spec.grid.cell_size = 0.1;
  spec.grid.nx = 4;
  spec.grid.ny = 6;
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.gravity = Vector2d(0.0, -9.81);
  spec.solver.pic_fraction = 0.1;
  spec.solver.time_step = 1e-4;
  MaterialRegion soil;
  soil.name = "soil";
  soil.lower = Vector2d(0.0, 0.0);
  soil.upper = Vector2d(0.4, 0.4);
  soil.points_per_cell_side = 2;
  soil.density = 1800.0;
  spec.regions = {soil};
  spec.walls = BoxWalls(0.4);
  SurfaceTraction load;
  load.name = "surcharge";
  load.region = "soil";
  load.normal_axis = 1;
  load.traction = Vector2d(0.0, -5e3);
  load.ramp_time = 1e-3;
  spec.tractions = {load};
  if (saturated) {
    spec.phases.saturated = true;
    spec.phases.fluid_density = 1000.0;
    spec.phases.permeability = 1e-4;
    spec.phases.porosity = 0.4;
    DrainedBoundary top;
    top.name = "top";
    top.axis = 1;
    top.position = 0.4;
    spec.phases.drained = {top};
  }
  return spec;
}

template <typename Map>
std::set<std::string> Keys(const Map& map) {
  std::set<std::string> keys;
  for (const auto& [key, values] : map) keys.insert(key);
  return keys;
}

TEST(SolverSchemeTest, TheCaseChoosesTheScheme) {
  LinearElasticModel model(kYoungs, kPoisson);
  std::unique_ptr<Solver> dry = MakeSolver(Block(false), &model);
  std::unique_ptr<Solver> saturated = MakeSolver(Block(true), &model);
  ASSERT_NE(dry, nullptr);
  ASSERT_NE(saturated, nullptr);
  EXPECT_NE(dynamic_cast<ExplicitSolver*>(dry.get()), nullptr);
  EXPECT_EQ(dynamic_cast<TwoPhaseSolver*>(dry.get()), nullptr);
  EXPECT_NE(dynamic_cast<TwoPhaseSolver*>(saturated.get()), nullptr);
  EXPECT_EQ(dynamic_cast<ExplicitSolver*>(saturated.get()), nullptr);
  // The water counts in the two-phase scheme's mass only.
  EXPECT_GT(saturated->MixtureMass(), dry->MixtureMass());
  // Each scheme checks its own part of the case.
  CaseSpec nonlocal = Block(true);
  nonlocal.solver.nonlocal_radius = 0.1;
  EXPECT_EQ(Solver::ForCase(nonlocal, &model).status().code(), absl::StatusCode::kInvalidArgument);
  nonlocal.phases.saturated = false;
  absl::StatusOr<std::unique_ptr<Solver>> dry_nonlocal = Solver::ForCase(nonlocal, &model);
  ASSERT_TRUE(dry_nonlocal.ok()) << dry_nonlocal.status();
  EXPECT_NE(dynamic_cast<ExplicitSolver*>(dry_nonlocal->get()), nullptr);
}

TEST(SolverCheckpointTest, EitherSchemeContinuesBitIdenticallyWithTheSameKeys) {
  const std::set<std::string> dry_keys = {"coordination",
                                          "deformation_gradient",
                                          "dt",
                                          "fabric_anisotropy",
                                          "half_size0",
                                          "load_length0",
                                          "load_ramp_time",
                                          "load_traction",
                                          "mass",
                                          "mean_rotation",
                                          "permeability",
                                          "position",
                                          "reactions",
                                          "response_stress",
                                          "stress",
                                          "time",
                                          "velocity",
                                          "void_ratio",
                                          "volume",
                                          "volume0"};
  std::set<std::string> saturated_keys = dry_keys;
  saturated_keys.insert({"fluid_velocity", "node_pressure", "pore_pressure", "porosity0",
                         "position0", "vertical_stress0"});
  const std::set<std::string> int_keys = {"load_normal_axis", "load_normal_sign", "load_point",
                                          "load_source",      "region",           "step"};
  for (bool saturated : {false, true}) {
    SCOPED_TRACE(saturated ? "two-phase" : "explicit");
    const CaseSpec spec = Block(saturated);
    LinearElasticModel model(kYoungs, kPoisson);
    std::unique_ptr<Solver> a = MakeSolver(spec, &model);
    ASSERT_NE(a, nullptr);
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(a->Step().ok()) << i;
    Doubles doubles;
    Ints ints;
    ExportSolverState(*a, doubles, ints);
    EXPECT_EQ(Keys(doubles), saturated ? saturated_keys : dry_keys);
    EXPECT_EQ(Keys(ints), int_keys);
    LinearElasticModel model_b = model;  // the material's own state travels separately
    absl::StatusOr<std::unique_ptr<Solver>> b = SolverFromState(spec, doubles, ints, &model_b);
    ASSERT_TRUE(b.ok()) << b.status();
    EXPECT_EQ(dynamic_cast<TwoPhaseSolver*>(b->get()) != nullptr, saturated);
    for (int i = 0; i < 10; ++i) {
      ASSERT_TRUE(a->Step().ok()) << i;
      ASSERT_TRUE((*b)->Step().ok()) << i;
    }
    Doubles da, db;
    Ints ia, ib;
    ExportSolverState(*a, da, ia);
    ExportSolverState(**b, db, ib);
    ASSERT_EQ(Keys(da), Keys(db));
    for (const auto& [key, values] : da) ExpectSameBits(values, db.at(key), key.c_str());
    EXPECT_EQ(ia, ib);
    EXPECT_EQ((*b)->step(), 20);
  }
}

TEST(SolverCheckpointTest, TheTwoPhaseSchemeRefusesADryStateAndKeepsItsOwn) {
  LinearElasticModel model(kYoungs, kPoisson);
  std::unique_ptr<Solver> dry = MakeSolver(Block(false), &model);
  std::unique_ptr<Solver> saturated = MakeSolver(Block(true), &model);
  ASSERT_NE(dry, nullptr);
  ASSERT_NE(saturated, nullptr);
  ASSERT_TRUE(saturated->Step().ok());
  Doubles dry_doubles, before, after;
  Ints dry_ints, before_ints, after_ints;
  ExportSolverState(*dry, dry_doubles, dry_ints);
  ExportSolverState(*saturated, before, before_ints);
  EXPECT_EQ(ImportSolverState(*saturated, dry_doubles, dry_ints).code(),
            absl::StatusCode::kInvalidArgument);
  ExportSolverState(*saturated, after, after_ints);
  for (const auto& [key, values] : before) ExpectSameBits(values, after.at(key), key.c_str());
  EXPECT_EQ(before_ints, after_ints);
}

}  // namespace
}  // namespace rvehub::mpm
