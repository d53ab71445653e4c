// The solver's state for checkpoints (StaticSolver::State / Restore): a
// solver restored into a fresh one, with a copy of its material, steps on
// exactly as the original does, bit for bit, under pressures and a forced
// platen, with the stiffening stand-in's exact tangent and with the
// initial elastic operator; a state that does not fit is refused, naming
// the field, and changes nothing.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "fem_client/core/elastic_material.h"
#include "fem_client/core/static_solver.h"

namespace rvehub::fem {
namespace {

constexpr double kLateral = 1e5;  // Pa

Mesh Specimen(ElementType type = ElementType::kQ4) {
  RectangleSpec spec;
  spec.width = 2.0;
  spec.height = 1.0;
  spec.nx = 4;
  spec.ny = 2;
  spec.type = type;
  return *StructuredRectangle(spec);
}

// Bottom fixed, the sides under the lateral pressure, the top's height
// held and sheared by a force on its rigid platen (N/m per step).
Boundary Sheared(const Mesh& mesh) {
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  b.pressures = {{mesh.edge_sets.at("left"), kLateral}, {mesh.edge_sets.at("right"), kLateral}};
  AddRoller(mesh.node_sets.at("top"), 1, b);
  AddForcedPlaten(mesh.node_sets.at("top"), 0, 2e4, b);
  return b;
}

StiffeningParameters Stiffening() { return {1e8, 5e7, 40.0}; }

std::vector<Eigen::Matrix3d> Consolidated(const Mesh& mesh) {
  return std::vector<Eigen::Matrix3d>(CountGaussPoints(mesh),
                                      -kLateral * Eigen::Matrix3d::Identity());
}

bool SameBits(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

// Everything a step reports and leaves, compared bit for bit.
void ExpectSameStep(const StepReport& a, const StepReport& b, const StaticSolver& sa,
                    const StaticSolver& sb) {
  ASSERT_EQ(a.substeps.size(), b.substeps.size());
  for (std::size_t s = 0; s < a.substeps.size(); ++s) {
    ASSERT_EQ(a.substeps[s].iterations.size(), b.substeps[s].iterations.size());
    for (std::size_t j = 0; j < a.substeps[s].iterations.size(); ++j) {
      EXPECT_EQ(a.substeps[s].iterations[j].displacement_error,
                b.substeps[s].iterations[j].displacement_error);
      EXPECT_EQ(a.substeps[s].iterations[j].force_error, b.substeps[s].iterations[j].force_error);
    }
  }
  EXPECT_EQ(a.step, b.step);
  EXPECT_EQ(a.trials, b.trials);
  ASSERT_EQ(a.platens.size(), 1u);
  ASSERT_EQ(b.platens.size(), 1u);
  EXPECT_EQ(a.platens[0].force, b.platens[0].force);
  EXPECT_EQ(a.platens[0].resistance, b.platens[0].resistance);
  EXPECT_EQ(a.platens[0].displacement, b.platens[0].displacement);
  for (const auto& [name, f] : a.forces) {
    EXPECT_TRUE(SameBits(f.reaction, b.forces.at(name).reaction)) << name;
    EXPECT_TRUE(SameBits(f.internal, b.forces.at(name).internal)) << name;
  }
  EXPECT_TRUE(SameBits(sa.displacement(), sb.displacement()));
  ASSERT_EQ(sa.responses().size(), sb.responses().size());
  for (std::size_t p = 0; p < sa.responses().size(); ++p) {
    EXPECT_TRUE(SameBits(sa.responses()[p].stress, sb.responses()[p].stress)) << p;
  }
  for (std::size_t n = 0; n < sa.mesh().nodes.size(); ++n) {
    EXPECT_TRUE(SameBits(sa.mesh().nodes[n], sb.mesh().nodes[n])) << n;
  }
}

// Three steps on one solver; its state and a copy of its material into a
// fresh solver; then both go on for three more steps (one of them
// reversed) and agree bit for bit.
// With the previous increment as the predictor the state carries it too.
TEST(StaticSolverStateTest, ARestoredSolverStepsOnAsTheOriginal) {
  const std::pair<TangentOperator, Predictor> settings[] = {
      {TangentOperator::kPerturbation, Predictor::kZero},
      {TangentOperator::kInitialElastic, Predictor::kZero},
      {TangentOperator::kPerturbation, Predictor::kPrevious}};
  for (const auto& [op, predictor] : settings) {
    SCOPED_TRACE(std::string(OperatorName(op)) +
                 (predictor == Predictor::kPrevious ? ", previous" : ", zero"));
    const Mesh mesh = Specimen();
    SolverOptions options;
    options.tangent = op;
    options.predictor = predictor;
    options.max_iterations = 40;
    auto material = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
    ASSERT_TRUE(material.ok()) << material.status();
    auto original = StaticSolver::Create(mesh, Sheared(mesh), options, material->get());
    ASSERT_TRUE(original.ok()) << original.status();
    for (int s = 0; s < 3; ++s) ASSERT_TRUE((*original)->Step().ok());

    const SolverState state = (*original)->State();
    EXPECT_EQ(state.steps, 3);
    EXPECT_EQ(state.platen_force, std::vector<double>{6e4});
    EXPECT_GT(state.last_rate.size(), 0);
    StiffeningElasticMaterial copy = **material;
    auto restored = StaticSolver::Create(mesh, Sheared(mesh), options, &copy);
    ASSERT_TRUE(restored.ok()) << restored.status();
    ASSERT_TRUE((*restored)->Restore(state).ok());
    EXPECT_EQ((*restored)->steps(), 3);
    for (double factor : {1.0, -1.0, 1.0}) {
      const absl::StatusOr<StepReport> a = (*original)->Step(factor);
      const absl::StatusOr<StepReport> b = (*restored)->Step(factor);
      ASSERT_TRUE(a.ok()) << a.status();
      ASSERT_TRUE(b.ok()) << b.status();
      ExpectSameStep(*a, *b, **original, **restored);
    }
  }
}

// A state before the first step restores to a solver that starts afresh.
TEST(StaticSolverStateTest, AStateBeforeTheFirstStepStartsAfresh) {
  const Mesh mesh = Specimen();
  auto m1 = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
  auto m2 = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
  ASSERT_TRUE(m1.ok() && m2.ok());
  auto a = StaticSolver::Create(mesh, Sheared(mesh), SolverOptions{}, m1->get());
  auto b = StaticSolver::Create(mesh, Sheared(mesh), SolverOptions{}, m2->get());
  ASSERT_TRUE(a.ok() && b.ok());
  const SolverState fresh = (*a)->State();
  EXPECT_TRUE(fresh.responses.empty());
  ASSERT_TRUE((*b)->Restore(fresh).ok());
  const absl::StatusOr<StepReport> ra = (*a)->Step(), rb = (*b)->Step();
  ASSERT_TRUE(ra.ok() && rb.ok());
  ExpectSameStep(*ra, *rb, **a, **b);
}

// Each bad state: InvalidArgument naming the field; the solver keeps what
// it had (here: two steps done), and steps on from there.
TEST(StaticSolverStateTest, AStateThatDoesNotFitIsRefusedAndChangesNothing) {
  const Mesh mesh = Specimen();
  auto material = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
  ASSERT_TRUE(material.ok());
  auto solver = StaticSolver::Create(mesh, Sheared(mesh), SolverOptions{}, material->get());
  ASSERT_TRUE(solver.ok());
  ASSERT_TRUE((*solver)->Step().ok());
  ASSERT_TRUE((*solver)->Step().ok());
  const SolverState good = (*solver)->State();
  const double nan = std::nan("");
  struct Bad {
    const char* name;
    void (*spoil)(SolverState&, double);
    const char* message;
  };
  const Bad cases[] = {
      {"negative steps", [](SolverState& s, double) { s.steps = -1; }, "steps is negative"},
      {"a node missing", [](SolverState& s, double) { s.nodes.pop_back(); }, "nodes has 14 nodes"},
      {"a node not finite", [](SolverState& s, double x) { s.nodes[3].x() = x; }, "not finite"},
      {"displacement short", [](SolverState& s, double) { s.displacement.conservativeResize(3); },
       "displacement has 3 values, not 30"},
      {"displacement NaN", [](SolverState& s, double x) { s.displacement[5] = x; },
       "displacement has a value that is not finite"},
      {"responses missing after steps", [](SolverState& s, double) { s.responses.clear(); },
       "responses are missing after 2 steps"},
      {"a response short", [](SolverState& s, double) { s.responses.pop_back(); },
       "responses has 31 Gauss points, not 32"},
      {"a stress not finite", [](SolverState& s, double x) { s.responses[7].stress(1, 1) = x; },
       "not finite"},
      {"residual short", [](SolverState& s, double) { s.residual.conservativeResize(29); },
       "residual has 29 values"},
      {"f_int NaN", [](SolverState& s, double x) { s.f_int[0] = x; }, "f_int has a value"},
      {"platen force missing", [](SolverState& s, double) { s.platen_force.clear(); },
       "platen_force has 0 values, not 1"},
      {"initial tangents short",
       [](SolverState& s, double) { s.initial_tangents.assign(3, Tangent::Zero()); },
       "initial_tangents has 3 Gauss points, not 0 or 32"},
      {"last rate short", [](SolverState& s, double) { s.last_rate.conservativeResize(3); },
       "last_rate has 3 values"},
      {"last rate NaN", [](SolverState& s, double x) { s.last_rate[2] = x; },
       "last_rate has a value that is not finite"},
      {"an inverted element", [](SolverState& s, double) { std::swap(s.nodes[0], s.nodes[6]); },
       "nodes give a mesh the solver refuses"},
  };
  for (const Bad& bad : cases) {
    SCOPED_TRACE(bad.name);
    SolverState s = good;
    bad.spoil(s, nan);
    const absl::Status status = (*solver)->Restore(std::move(s));
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_TRUE(absl::StrContains(status.message(), bad.message)) << status;
    EXPECT_TRUE(absl::StartsWith(status.message(), "solver state: ")) << status;
    EXPECT_EQ((*solver)->steps(), 2);
    EXPECT_TRUE(SameBits((*solver)->displacement(), good.displacement));
  }
  // Still the solver it was: its next step is the one it would have taken.
  StiffeningElasticMaterial copy = **material;
  auto twin = StaticSolver::Create(mesh, Sheared(mesh), SolverOptions{}, &copy);
  ASSERT_TRUE(twin.ok());
  ASSERT_TRUE((*twin)->Restore(good).ok());
  const absl::StatusOr<StepReport> a = (*solver)->Step(), b = (*twin)->Step();
  ASSERT_TRUE(a.ok() && b.ok());
  ExpectSameStep(*a, *b, **solver, **twin);
}

}  // namespace
}  // namespace rvehub::fem

namespace rvehub::fem {
namespace {

// Starting each step from the last converged increment reaches the same
// solution (to the tolerance) in fewer iterations on a smooth path: the
// stiffening stand-in with the exact (perturbation) tangent, six steps.
TEST(StaticSolverPredictorTest, ThePreviousIncrementStartsNewtonCloser) {
  const Mesh mesh = Specimen();
  int iterations[2] = {0, 0};
  Eigen::VectorXd displacement[2];
  for (int k = 0; k < 2; ++k) {
    SolverOptions options;
    options.tangent = TangentOperator::kPerturbation;
    options.displacement_tolerance = 1e-8;
    options.predictor = k == 0 ? Predictor::kZero : Predictor::kPrevious;
    auto material = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
    ASSERT_TRUE(material.ok());
    auto solver = StaticSolver::Create(mesh, Sheared(mesh), options, material->get());
    ASSERT_TRUE(solver.ok());
    for (int s = 0; s < 6; ++s) {
      absl::StatusOr<StepReport> r = (*solver)->Step();
      ASSERT_TRUE(r.ok()) << r.status();
      for (const SubStepReport& sub : r->substeps) iterations[k] += sub.iterations.size();
    }
    displacement[k] = (*solver)->displacement();
  }
  // Measured: 24 iterations from zero, 19 from the previous increment.
  EXPECT_LT(iterations[1], iterations[0]);
  EXPECT_LT((displacement[1] - displacement[0]).norm(), 1e-7 * displacement[0].norm());
}

// With a second gradient the state carries its fields (Σ, λ, v) and the
// predictor's rate of its unknowns: a restored solver steps on bit for bit,
// its second gradient included; a state whose fields do not fit is refused.
TEST(StaticSolverStateTest, ASecondGradientTravelsWithTheState) {
  const Mesh mesh = Specimen(ElementType::kQ8R);
  SolverOptions options;
  options.tangent = TangentOperator::kPerturbation;
  options.predictor = Predictor::kPrevious;
  options.max_iterations = 40;
  options.second_gradient = 1e4;
  auto material = StiffeningElasticMaterial::Create(Stiffening(), Consolidated(mesh));
  ASSERT_TRUE(material.ok()) << material.status();
  auto original = StaticSolver::Create(mesh, Sheared(mesh), options, material->get());
  ASSERT_TRUE(original.ok()) << original.status();
  for (int s = 0; s < 3; ++s) ASSERT_TRUE((*original)->Step().ok());
  const SolverState state = (*original)->State();
  ASSERT_EQ(state.second_gradient.double_stress.size(), 32u);
  EXPECT_EQ(state.second_gradient.multiplier.size(), 32);
  EXPECT_EQ(state.second_gradient.micro.size(), 4 * 15);    // the 5 × 3 corner nodes
  EXPECT_GT(state.second_gradient.multiplier.norm(), 0.0);  // sheared, not uniform

  for (const char* field : {"multiplier", "micro", "double_stress"}) {
    SolverState bad = state;
    if (std::string(field) == "multiplier") bad.second_gradient.multiplier.conservativeResize(5);
    if (std::string(field) == "micro") bad.second_gradient.micro[3] = std::nan("");
    if (std::string(field) == "double_stress") bad.second_gradient.double_stress.pop_back();
    StiffeningElasticMaterial copy = **material;
    auto other = StaticSolver::Create(mesh, Sheared(mesh), options, &copy);
    ASSERT_TRUE(other.ok());
    const absl::Status status = (*other)->Restore(std::move(bad));
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_TRUE(absl::StrContains(status.message(), std::string("second_gradient.") + field))
        << status;
  }

  StiffeningElasticMaterial copy = **material;
  auto restored = StaticSolver::Create(mesh, Sheared(mesh), options, &copy);
  ASSERT_TRUE(restored.ok()) << restored.status();
  ASSERT_TRUE((*restored)->Restore(state).ok());
  for (double factor : {1.0, -1.0, 1.0}) {
    const absl::StatusOr<StepReport> a = (*original)->Step(factor);
    const absl::StatusOr<StepReport> b = (*restored)->Step(factor);
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    ExpectSameStep(*a, *b, **original, **restored);
  }
  const SecondGradientState sa = (*original)->State().second_gradient;
  const SecondGradientState sb = (*restored)->State().second_gradient;
  EXPECT_TRUE(SameBits(sa.multiplier, sb.multiplier));
  EXPECT_TRUE(SameBits(sa.micro, sb.micro));
  for (std::size_t p = 0; p < sa.double_stress.size(); ++p) {
    EXPECT_TRUE(SameBits(sa.double_stress[p], sb.double_stress[p])) << p;
  }

  // A solver without a second gradient refuses the fields.
  StiffeningElasticMaterial plain = **material;
  auto without =
      StaticSolver::Create(Specimen(ElementType::kQ8R), Sheared(mesh), SolverOptions{}, &plain);
  ASSERT_TRUE(without.ok());
  SolverState foreign = state;
  foreign.last_rate.resize(0);
  const absl::Status status = (*without)->Restore(std::move(foreign));
  EXPECT_TRUE(absl::StrContains(status.message(), "without a second gradient")) << status;
}

}  // namespace
}  // namespace rvehub::fem
