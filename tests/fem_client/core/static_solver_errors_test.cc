// The solver's failures: cut-backs after a Trial's failure, the errors that
// end a run (naming the step, the iteration and the worst point), and the
// set-ups it refuses.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "fem_client/core/elastic_material.h"
#include "fem_client/core/static_solver.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::SpyMaterial;

constexpr double kE = 1e8, kNu = 0.3, kLateral = 1e5;

Mesh Rectangle(double width, double height, int nx, int ny) {
  RectangleSpec spec;
  spec.width = width;
  spec.height = height;
  spec.nx = nx;
  spec.ny = ny;
  return *StructuredRectangle(spec);
}

std::vector<Eigen::Matrix3d> Consolidated(const Mesh& mesh) {
  return std::vector<Eigen::Matrix3d>(CountGaussPoints(mesh),
                                      -kLateral * Eigen::Matrix3d::Identity());
}

Boundary Biaxial(const Mesh& mesh, double increment) {
  Boundary b;
  AddRoller(mesh.node_sets.at("left"), 0, b);
  AddRoller(mesh.node_sets.at("bottom"), 1, b);
  AddPlaten(mesh.node_sets.at("top"), 1, increment, Platen::kSmooth, b);
  b.pressures = {{mesh.edge_sets.at("right"), kLateral}};
  return b;
}

// Like an RVE asked for too large an increment: any ΔF farther than
// `limit` from I fails, naming the first such point.
absl::Status RefuseLargeIncrements(std::span<const Eigen::Matrix3d> delta_f, double limit) {
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    if ((delta_f[p] - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > limit) {
      return PointFailure(absl::OutOfRangeError("the packing cannot follow so large a step"),
                          static_cast<int>(p));
    }
  }
  return absl::OkStatus();
}

void ExpectError(const absl::Status& s, absl::StatusCode code, const std::string& says) {
  EXPECT_EQ(s.code(), code) << s;
  EXPECT_TRUE(absl::StrContains(s.message(), says)) << s << "\nshould say: " << says;
}

// A step of 1 % axial strain against a material that takes at most 0.3 %:
// the full and the half step fail, the quarter steps pass; the result is
// that of four quarter steps.
TEST(StaticSolverErrorsTest, ATrialFailureCutsTheStepBackThenItSucceeds) {
  const Mesh mesh = Rectangle(1.0, 2.0, 1, 1);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  spy.fail = [](std::span<const Eigen::Matrix3d> f) { return RefuseLargeIncrements(f, 3e-3); };
  SolverOptions options;
  options.displacement_tolerance = 1e-10;
  auto solver = StaticSolver::Create(mesh, Biaxial(mesh, -0.02), options, &spy);
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->cutbacks, 2);
  ASSERT_EQ(report->substeps.size(), 4u);
  for (const SubStepReport& sub : report->substeps) EXPECT_EQ(sub.fraction, 0.25);
  EXPECT_EQ(spy.commits, 4);

  auto plain = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(plain.ok());
  auto reference = StaticSolver::Create(mesh, Biaxial(mesh, -0.02), options, plain->get());
  ASSERT_TRUE(reference.ok());
  for (int k = 0; k < 4; ++k) ASSERT_TRUE((*reference)->Step(0.25).ok());
  EXPECT_LT(((*solver)->displacement() - (*reference)->displacement()).norm(),
            1e-12 * (*reference)->displacement().norm());
}

// With one cut-back allowed the run stops, keeping the Trial's code and
// its failed point, naming the step, the iteration and the Gauss point;
// the solver keeps its committed state and goes on with a smaller step.
// A lost server fails the same way at any step size: no cut-back, one
// Trial, the server's code and message kept.
TEST(StaticSolverErrorsTest, ALostServerEndsTheStepWithoutCutBacks) {
  const Mesh mesh = Rectangle(1.0, 2.0, 1, 1);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  int calls = 0;
  spy.fail = [&calls](std::span<const Eigen::Matrix3d>) {
    return ++calls == 1 ? absl::OkStatus()  // the initial stresses
                        : absl::UnavailableError("RVE server 127.0.0.1:1: connection refused");
  };
  auto solver = StaticSolver::Create(mesh, Biaxial(mesh, -0.002), SolverOptions(), &spy);
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ExpectError(report.status(), absl::StatusCode::kUnavailable, "after 0 cut-backs");
  ExpectError(report.status(), absl::StatusCode::kUnavailable, "connection refused");
  EXPECT_EQ(calls, 2);
}

TEST(StaticSolverErrorsTest, TooManyCutBacksEndTheStepNamingTheFailingPoint) {
  const Mesh mesh = Rectangle(1.0, 2.0, 1, 1);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  spy.fail = [](std::span<const Eigen::Matrix3d> f) { return RefuseLargeIncrements(f, 3e-3); };
  SolverOptions options;
  options.max_cutbacks = 1;
  auto solver = StaticSolver::Create(mesh, Biaxial(mesh, -0.02), options, &spy);
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ExpectError(report.status(), absl::StatusCode::kOutOfRange,
              "load step 1 (a part of 0.5 of it, after 1 cut-backs), iteration 1: the material "
              "failed at Gauss point 0 (element 0, point 0 at (");
  EXPECT_TRUE(absl::StrContains(report.status().message(), "cannot follow so large a step"));
  EXPECT_EQ(FailedPoint(report.status()), 0);
  EXPECT_EQ(spy.commits, 0);
  EXPECT_EQ((*solver)->displacement().norm(), 0.0);
  EXPECT_EQ((*solver)->steps(), 0);
  ASSERT_TRUE((*solver)->Step(0.25).ok());
  EXPECT_EQ((*solver)->steps(), 1);
}

// Newton given too few iterations: Aborted, naming the step, the last
// iteration with its errors and the node with the largest residual.
TEST(StaticSolverErrorsTest, NoConvergenceNamesTheLargestResidual) {
  const Mesh mesh = Rectangle(1.0, 1.0, 2, 2);
  auto material = StiffeningElasticMaterial::Create({5e7, 3e7, 40.0}, Consolidated(mesh));
  ASSERT_TRUE(material.ok());
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  AddPlaten(mesh.node_sets.at("top"), 1, -0.02, Platen::kRough, b);
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  options.max_iterations = 2;
  options.max_cutbacks = 2;
  auto solver = StaticSolver::Create(mesh, b, options, material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::Status s = (*solver)->Step().status();
  ExpectError(s, absl::StatusCode::kAborted,
              "load step 1 (a part of 0.25 of it, after 2 cut-backs), iteration 2: Newton did not "
              "converge (E_d = ");
  EXPECT_TRUE(absl::StrContains(s.message(), "the largest residual")) << s;
  EXPECT_TRUE(absl::StrContains(s.message(), "N/m, is at node ")) << s;
}

// With accept_unconverged the same two iterations are committed as they
// stand, without cut-backs, and the sub-step says so: the state is the one
// a solver reaches that converges at its second iteration, bit for bit.
TEST(StaticSolverErrorsTest, AnAcceptedUnconvergedStepCommitsItsLastIterate) {
  const Mesh mesh = Rectangle(1.0, 1.0, 2, 2);
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  AddPlaten(mesh.node_sets.at("top"), 1, -0.02, Platen::kRough, b);
  auto stiffening = [&] {
    return *StiffeningElasticMaterial::Create({5e7, 3e7, 40.0}, Consolidated(mesh));
  };
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  options.max_iterations = 2;
  options.max_cutbacks = 2;
  options.accept_unconverged = true;
  auto material = stiffening();
  auto solver = StaticSolver::Create(mesh, b, options, material.get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->cutbacks, 0);
  ASSERT_EQ(report->substeps.size(), 1u);
  EXPECT_FALSE(report->substeps[0].converged);
  ASSERT_EQ(report->substeps[0].iterations.size(), 2u);
  EXPECT_GT(report->substeps[0].iterations[1].displacement_error, 1e-12);
  EXPECT_EQ((*solver)->steps(), 1);

  // E_d < 1 holds at the second iteration (the first's is 1).
  options.displacement_tolerance = 1.0;
  options.accept_unconverged = false;
  auto loose_material = stiffening();
  auto loose = StaticSolver::Create(mesh, b, options, loose_material.get());
  ASSERT_TRUE(loose.ok()) << loose.status();
  const absl::StatusOr<StepReport> converged = (*loose)->Step();
  ASSERT_TRUE(converged.ok()) << converged.status();
  ASSERT_EQ(converged->substeps.size(), 1u);
  EXPECT_TRUE(converged->substeps[0].converged);
  EXPECT_EQ(converged->substeps[0].iterations.size(), 2u);
  const Eigen::VectorXd d = (*solver)->displacement(), e = (*loose)->displacement();
  ASSERT_EQ(d.size(), e.size());
  EXPECT_EQ(std::memcmp(d.data(), e.data(), sizeof(double) * d.size()), 0);
}

// kContact needs the material's tangent: without one the run stops at once
// (no cut-back cures it).
TEST(StaticSolverErrorsTest, TheContactOperatorNeedsATangent) {
  const Mesh mesh = Rectangle(1.0, 1.0, 1, 1);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  spy.drop_tangents = true;
  auto solver = StaticSolver::Create(mesh, Biaxial(mesh, -1e-3), SolverOptions(), &spy);
  ASSERT_TRUE(solver.ok());
  ExpectError((*solver)->Step().status(), absl::StatusCode::kFailedPrecondition,
              "after 0 cut-backs), iteration 1: the material gave no finite tangent at Gauss "
              "point 0 (element 0, point 0");
  EXPECT_EQ(spy.trials, 1);  // the Trial at ΔF = I only
}

TEST(StaticSolverErrorsTest, AnInvertedOrDegenerateElementIsRefusedAtCreate) {
  Mesh inverted = Rectangle(1.0, 1.0, 2, 1);
  std::swap(inverted.elements[1].nodes[1], inverted.elements[1].nodes[3]);
  auto material = LinearElasticMaterial::Create(kE, kNu, Consolidated(inverted));
  ASSERT_TRUE(material.ok());
  const Boundary b = Biaxial(inverted, -1e-3);
  ExpectError(StaticSolver::Create(inverted, b, SolverOptions(), material->get()).status(),
              absl::StatusCode::kInvalidArgument, "element 1 (Q4) is inverted at Gauss point 0");
  Mesh degenerate = Rectangle(1.0, 1.0, 2, 1);
  for (int id : degenerate.elements[0].nodes) degenerate.nodes[id].y() = 0.0;  // a flat element
  ExpectError(StaticSolver::Create(degenerate, b, SolverOptions(), material->get()).status(),
              absl::StatusCode::kInvalidArgument, "element 0 (Q4) is degenerate at Gauss point 0");
}

TEST(StaticSolverErrorsTest, AMeshWithoutSupportsIsRefusedBeforeAnySolve) {
  const Mesh mesh = Rectangle(1.0, 1.0, 2, 2);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  Boundary b;
  b.pressures = {{mesh.edge_sets.at("top"), kLateral}, {mesh.edge_sets.at("bottom"), kLateral}};
  ExpectError(StaticSolver::Create(mesh, b, SolverOptions(), &spy).status(),
              absl::StatusCode::kFailedPrecondition,
              "the mesh has no supports against rigid-body motion");
  EXPECT_EQ(spy.trials, 0);
}

TEST(StaticSolverErrorsTest, BadOptionsAndNoMaterialAreRefused) {
  const Mesh mesh = Rectangle(1.0, 1.0, 1, 1);
  auto material = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(material.ok());
  const Boundary b = Biaxial(mesh, -1e-3);
  for (auto change : std::vector<void (*)(SolverOptions&)>{
           [](SolverOptions& o) { o.displacement_tolerance = 0.0; },
           [](SolverOptions& o) { o.force_tolerance = -1.0; },
           [](SolverOptions& o) { o.max_iterations = 0; },
           [](SolverOptions& o) { o.max_cutbacks = 31; },
           [](SolverOptions& o) { o.perturbation = 0.0; }}) {
    SolverOptions options;
    change(options);
    EXPECT_EQ(StaticSolver::Create(mesh, b, options, material->get()).status().code(),
              absl::StatusCode::kInvalidArgument);
  }
  EXPECT_EQ(StaticSolver::Create(mesh, b, SolverOptions(), nullptr).status().code(),
            absl::StatusCode::kInvalidArgument);
  auto solver = StaticSolver::Create(mesh, b, SolverOptions(), material->get());
  ASSERT_TRUE(solver.ok());
  EXPECT_EQ((*solver)->Step(std::nan("")).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace rvehub::fem
