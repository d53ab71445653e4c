// The Newton solver against closed forms and its convergence rates: a single
// Q4 element in drained biaxial compression, the patch test through the
// solver, quadratic convergence with the exact tangent, the three tangent
// operators, a rigid rotation and periodic simple shear.
#include "fem_client/core/static_solver.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "fem_client/core/elastic_material.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::DistortedSquare;
using testing::InPlane;
using testing::InteriorNodes;
using testing::Prestress;
using testing::Rectangle;
using testing::SpyMaterial;
using testing::Uniform;

constexpr double kE = 1e8, kNu = 0.3;  // Pa, [-]
constexpr double kLateral = 1e5;       // Pa

// G&Z §3.3's single element: rollers on the left (x) and the bottom (y), a
// smooth platen on top moving by `increment` (m) per step, the lateral
// pressure on the right; consolidated isotropically to that pressure.
Boundary Biaxial(const Mesh& mesh, double increment) {
  Boundary b;
  AddRoller(mesh.node_sets.at("left"), 0, b);
  AddRoller(mesh.node_sets.at("bottom"), 1, b);
  AddPlaten(mesh.node_sets.at("top"), 1, increment, Platen::kSmooth, b);
  b.pressures = {{mesh.edge_sets.at("right"), kLateral}};
  return b;
}

// The stand-in's biaxial response step by step: with ΔF = diag(1 + εx, 1 +
// εy) (V − I = diag(εx, εy) exactly), σ_xx stays −p when εx = −λ εy/(λ +
// 2G), and σ_yy grows by E εy/(1 − ν²); εy = increment/H on the current
// height.
struct BiaxialState {
  double width, height, sigma_yy;
};
BiaxialState BiaxialClosedForm(BiaxialState s, double increment) {
  const double lambda = LameLambda(kE, kNu), shear = ShearModulus(kE, kNu);
  const double ey = increment / s.height, ex = -lambda * ey / (lambda + 2 * shear);
  return {s.width * (1 + ex), s.height + increment,
          s.sigma_yy + lambda * (ex + ey) + 2 * shear * ey};
}

// A rough-platen compression: bottom fixed, top moved by `increment` (m)
// with its x held, the lateral pressure on both sides.
Boundary RoughCompression(const Mesh& mesh, double increment) {
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  AddPlaten(mesh.node_sets.at("top"), 1, increment, Platen::kRough, b);
  b.pressures = {{mesh.edge_sets.at("left"), kLateral}, {mesh.edge_sets.at("right"), kLateral}};
  return b;
}

// Iterations down to round-off, to watch the convergence rate.
SolverOptions TightOptions(TangentOperator op) {
  SolverOptions options;
  options.tangent = op;
  options.displacement_tolerance = 1e-13;
  options.max_iterations = 30;
  return options;
}

std::string Errors(const SubStepReport& sub) {
  std::string out;
  for (const IterationReport& it : sub.iterations) {
    out += absl::StrFormat(" (%.2e, %.2e)", it.displacement_error, it.force_error);
  }
  return out;
}

// The single element follows the closed form step by step, with each
// operator: widths, the axial stress at every Gauss point and the
// platen's reaction σ_yy·W, to 1e-10. The Newton correction of this
// problem is exact after one solve with C (the stand-in is linear in the
// stretch it sees), so every operator converges in 2 iterations (the
// second confirms, E_d ~ 1e-15 < 1e-8).
TEST(StaticSolverTest, SingleElementBiaxialMatchesTheClosedForm) {
  const double width = 1.0, height = 2.0, increment = -2e-3;
  const Mesh mesh = Rectangle(width, height, 1, 1, ElementType::kQ4);
  for (TangentOperator op : {TangentOperator::kContact, TangentOperator::kPerturbation,
                             TangentOperator::kInitialElastic}) {
    auto material = LinearElasticMaterial::Create(
        kE, kNu, Uniform(mesh, -kLateral * Eigen::Matrix3d::Identity()));
    ASSERT_TRUE(material.ok());
    SolverOptions options;
    options.tangent = op;
    options.displacement_tolerance = 1e-8;
    auto solver = StaticSolver::Create(mesh, Biaxial(mesh, increment), options, material->get());
    ASSERT_TRUE(solver.ok()) << solver.status();
    BiaxialState expected{width, height, -kLateral};
    std::string per_step;
    for (int step = 1; step <= 10; ++step) {
      const absl::StatusOr<StepReport> report = (*solver)->Step();
      ASSERT_TRUE(report.ok()) << report.status();
      expected = BiaxialClosedForm(expected, increment);
      EXPECT_EQ(report->cutbacks, 0);
      ASSERT_EQ(report->substeps.size(), 1u);
      EXPECT_EQ(report->substeps[0].iterations.size(), 2u) << Errors(report->substeps[0]);
      per_step += absl::StrCat(" ", report->substeps[0].iterations.size());
      const Mesh& now = (*solver)->mesh();
      EXPECT_NEAR(now.nodes[1].x(), expected.width, 1e-10 * width);
      EXPECT_NEAR(now.nodes[2].y(), expected.height, 1e-10 * height);
      for (const PointResponse& r : (*solver)->responses()) {
        EXPECT_NEAR(r.stress(0, 0), -kLateral, 1e-10 * kLateral);
        EXPECT_NEAR(r.stress(1, 1), expected.sigma_yy, 1e-10 * std::abs(expected.sigma_yy));
        EXPECT_NEAR(r.stress(0, 1), 0.0, 1e-10 * kLateral);
      }
      const SetForces& top = report->forces.at("top");
      EXPECT_NEAR(top.reaction.y(), expected.sigma_yy * expected.width,
                  1e-10 * std::abs(expected.sigma_yy));
      // The left rollers balance the pressure (the top-left corner's share
      // among them).
      EXPECT_NEAR(report->forces.at("left").reaction.x(), kLateral * expected.height,
                  1e-10 * kLateral);
      // The right side carries the pressure: σ_xx·H inward, no reaction.
      EXPECT_NEAR(report->forces.at("right").internal.x(), -kLateral * expected.height,
                  1e-10 * kLateral);
      EXPECT_NEAR(report->forces.at("right").reaction.norm(), 0.0, 1e-10 * kLateral);
    }
    std::printf("biaxial, linear stand-in, %s operator: iterations per step%s\n",
                std::string(OperatorName(op)).c_str(), per_step.c_str());
    EXPECT_LT(expected.sigma_yy, -1.9 * kLateral);  // it did load the element
  }
}

// The same element with the stiffening stand-in under each operator, to
// G&Z's tolerance: all three reach the same state (to the tolerance's
// order), contact and perturbation in as many iterations as Newton needs,
// the initial elastic operator in more as the material stiffens.
TEST(StaticSolverTest, TheThreeOperatorsOnTheBiaxialElement) {
  const Mesh mesh = Rectangle(1.0, 2.0, 1, 1, ElementType::kQ4);
  const TangentOperator operators[] = {TangentOperator::kContact, TangentOperator::kPerturbation,
                                       TangentOperator::kInitialElastic};
  std::vector<double> top;
  std::vector<int> iterations;
  for (TangentOperator op : operators) {
    auto inner = StiffeningElasticMaterial::Create(
        {5e7, 3e7, 40.0}, Uniform(mesh, -kLateral * Eigen::Matrix3d::Identity()));
    ASSERT_TRUE(inner.ok());
    SpyMaterial spy(inner->get());
    SolverOptions options;
    options.tangent = op;
    options.displacement_tolerance = 1e-6;
    auto solver = StaticSolver::Create(mesh, Biaxial(mesh, -4e-3), options, &spy);
    ASSERT_TRUE(solver.ok()) << solver.status();
    std::string per_step;
    int total = 0;
    for (int step = 1; step <= 5; ++step) {
      const absl::StatusOr<StepReport> report = (*solver)->Step();
      ASSERT_TRUE(report.ok()) << OperatorName(op) << ": " << report.status();
      const int n = static_cast<int>(report->substeps[0].iterations.size());
      per_step += absl::StrCat(" ", n);
      total += n;
      if (step == 5) top.push_back(report->forces.at("top").reaction.y());
    }
    iterations.push_back(total);
    std::printf(
        "biaxial, stiffening stand-in, %s operator: iterations per step%s; %d Trials (%d "
        "with a tangent)\n",
        std::string(OperatorName(op)).c_str(), per_step.c_str(), spy.trials, spy.tangent_trials);
    if (op == TangentOperator::kInitialElastic) {
      EXPECT_EQ(spy.tangent_trials, 1);
    }
    if (op == TangentOperator::kPerturbation) {
      EXPECT_EQ(spy.tangent_trials, 0);
    }
  }
  EXPECT_NEAR(top[1], top[0], 1e-5 * std::abs(top[0]));
  EXPECT_NEAR(top[2], top[0], 1e-5 * std::abs(top[0]));
  EXPECT_LE(iterations[0], 15);
  EXPECT_LE(iterations[1], iterations[0] + 5);
  EXPECT_GT(iterations[2], iterations[0]);
}

// The patch test through the solver: the boundary nodes of the distorted
// meshes follow a linear field, the interior ones are solved for. They land
// on the field, every Gauss point has the same stress and the interior
// residual vanishes, to 1e-10 (round-off of the solve).
TEST(StaticSolverTest, PatchTestThroughTheSolver) {
  Eigen::Matrix2d h;
  h << 2e-3, -1e-3, 4e-3, -3e-3;
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8, ElementType::kQ8R}) {
    const Mesh mesh = DistortedSquare(type);
    auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, Prestress()));
    ASSERT_TRUE(material.ok());
    const std::vector<int> interior = InteriorNodes(mesh);
    const Boundary b = testing::PatchBoundary(mesh, h);
    SolverOptions options;
    options.displacement_tolerance = 1e-12;
    auto solver = StaticSolver::Create(mesh, b, options, material->get());
    ASSERT_TRUE(solver.ok()) << solver.status();
    const absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    for (int a : interior) {
      EXPECT_LT(((*solver)->displacement().segment<2>(2 * a) - h * mesh.nodes[a]).norm(),
                1e-10 * h.norm())
          << ElementName(type) << " node " << a;
    }
    const std::span<const PointResponse> r = (*solver)->responses();
    for (const PointResponse& p : r) {
      EXPECT_LT((p.stress - r[0].stress).norm(), 1e-10 * r[0].stress.norm()) << ElementName(type);
    }
    EXPECT_GT((r[0].stress - Prestress()).norm(), 1e5);  // it is not just the prestress
    EXPECT_LT(report->substeps[0].iterations.back().force_error, 1e-10) << ElementName(type);
  }
}

// Newton with the stiffening stand-in's exact tangent (and the exact
// geometric terms) converges quadratically: a rough-platen compression of
// 2 % in one step barrels a 4 × 4 mesh, and once E_d < 0.1 each
// iteration's E_d and E_f are below the square of the one before (measured
// factors 0.15–0.45), until round-off (1e-13).
TEST(StaticSolverTest, NewtonConvergesQuadraticallyWithTheExactTangent) {
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8, ElementType::kQ8R}) {
    const Mesh mesh = Rectangle(1.0, 1.0, 4, 4, type);
    auto material = StiffeningElasticMaterial::Create(
        {5e7, 3e7, 40.0}, Uniform(mesh, -kLateral * Eigen::Matrix3d::Identity()));
    ASSERT_TRUE(material.ok());
    auto solver = StaticSolver::Create(mesh, RoughCompression(mesh, -0.02),
                                       TightOptions(TangentOperator::kContact), material->get());
    ASSERT_TRUE(solver.ok()) << solver.status();
    const absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    const std::vector<IterationReport>& it = report->substeps[0].iterations;
    std::printf("quadratic, %s, (E_d, E_f) per iteration:%s\n",
                std::string(ElementName(type)).c_str(), Errors(report->substeps[0]).c_str());
    ASSERT_GE(it.size(), 4u);
    int checked = 0;
    for (std::size_t j = 1; j < it.size(); ++j) {
      const IterationReport& before = it[j - 1];
      const IterationReport& now = it[j];
      if (before.displacement_error > 0.1 || now.displacement_error < 1e-13) continue;
      EXPECT_LT(now.displacement_error, before.displacement_error * before.displacement_error)
          << "iteration " << j + 1;
      EXPECT_LT(now.force_error, before.force_error * before.force_error) << "iteration " << j + 1;
      ++checked;
    }
    EXPECT_GE(checked, 2);
    EXPECT_LT(it.back().force_error, 1e-12);
  }
}

// kPerturbation's D^p differs from the exact tangent by O(ξ) (tangent
// operator test): here Newton still converges, linearly at a rate of order
// ξ·α (1e-3), to the same solution as with the exact tangent, to the
// tolerance; each iteration costs 5 Trials.
TEST(StaticSolverTest, ThePerturbationOperatorConvergesToTheSameSolution) {
  const Mesh mesh = Rectangle(1.0, 1.0, 4, 4, ElementType::kQ4);
  Eigen::VectorXd u[2];
  int k = 0;
  for (TangentOperator op : {TangentOperator::kContact, TangentOperator::kPerturbation}) {
    auto inner = StiffeningElasticMaterial::Create(
        {5e7, 3e7, 40.0}, Uniform(mesh, -kLateral * Eigen::Matrix3d::Identity()));
    ASSERT_TRUE(inner.ok());
    SpyMaterial spy(inner->get());
    auto solver = StaticSolver::Create(mesh, RoughCompression(mesh, -0.02), TightOptions(op), &spy);
    ASSERT_TRUE(solver.ok()) << solver.status();
    const absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    const std::vector<IterationReport>& it = report->substeps[0].iterations;
    std::printf("%s operator, (E_d, E_f) per iteration:%s\n", std::string(OperatorName(op)).c_str(),
                Errors(report->substeps[0]).c_str());
    if (op == TangentOperator::kPerturbation) {
      // 1 Trial at ΔF = I, then per iteration 4 perturbations and 1 Trial.
      EXPECT_EQ(spy.trials, 1 + 5 * static_cast<int>(it.size()));
      EXPECT_EQ(report->trials, spy.trials);
      for (std::size_t j = 3; j < it.size(); ++j) {
        EXPECT_LT(it[j].displacement_error, 1e-2 * it[j - 1].displacement_error) << j;
      }
    }
    u[k++] = (*solver)->displacement();
  }
  EXPECT_LT((u[1] - u[0]).norm(), 1e-10 * u[0].norm());
}

// Rigid rotation: a prestressed element with the pressures that hold its
// stress on its faces, turned by 30° (and moved) by prescribing every node,
// stays in equilibrium: the stand-in returns R σ Rᵀ, the follower pressures
// turn with the faces, and every node's reaction is zero to round-off
// (1e-9 of the nodal forces p·L/2), as is each face's.
TEST(StaticSolverTest, ARigidRotationKeepsEquilibriumWithTheRotatedStress) {
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8, ElementType::kQ8R}) {
    Mesh mesh = Rectangle(1.0, 1.0, 1, 1, type);
    for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
      mesh.node_sets[absl::StrCat("node ", a)] = {a};
    }
    Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
    sigma.diagonal() << -2e5, -1e5, -1.5e5;
    auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, sigma));
    ASSERT_TRUE(material.ok());
    const double theta = M_PI / 6;
    Eigen::Matrix2d r;
    r << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
    const Eigen::Vector2d centre(0.5, 0.5), shift(0.3, -0.1);
    Boundary b;
    for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
      const Eigen::Vector2d du =
          (r - Eigen::Matrix2d::Identity()) * (mesh.nodes[a] - centre) + shift;
      b.prescribed.push_back({a, 0, du.x()});
      b.prescribed.push_back({a, 1, du.y()});
    }
    b.pressures = {{mesh.edge_sets.at("left"), 2e5},
                   {mesh.edge_sets.at("right"), 2e5},
                   {mesh.edge_sets.at("bottom"), 1e5},
                   {mesh.edge_sets.at("top"), 1e5}};
    auto solver = StaticSolver::Create(mesh, b, SolverOptions(), material->get());
    ASSERT_TRUE(solver.ok()) << solver.status();
    const absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
    rotation.topLeftCorner<2, 2>() = r;
    for (const PointResponse& p : (*solver)->responses()) {
      EXPECT_LT((p.stress - rotation * sigma * rotation.transpose()).norm(), 1e-9 * sigma.norm());
    }
    double largest = 0.0;
    for (const auto& [name, forces] : report->forces) {
      largest = std::max(largest, forces.reaction.norm());
    }
    EXPECT_LT(largest, 1e-9 * 2e5) << ElementName(type);
    std::printf("rigid rotation, %s: largest nodal or face reaction %.2e N/m (of p·L/2 = 1e5)\n",
                std::string(ElementName(type)).c_str(), largest);
    // The element turned: its first node went where the rotation takes it.
    EXPECT_LT(((*solver)->mesh().nodes[0] - (centre + r * (Eigen::Vector2d(0, 0) - centre) + shift))
                  .norm(),
              1e-15);
  }
}

// Newton finds the rotation itself: only node 0 (pinned at its rotated
// place) and node 1's y are prescribed, 3 steps of 10°; the element ends
// rigidly turned by 30° with the rotated stress, to the tolerance.
TEST(StaticSolverTest, NewtonFindsARigidRotationFromMinimalSupports) {
  const Mesh mesh = Rectangle(1.0, 1.0, 1, 1, ElementType::kQ4);
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  sigma.diagonal() << -2e5, -1e5, -1.5e5;
  auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, sigma));
  ASSERT_TRUE(material.ok());
  Boundary b;
  b.pressures = {{mesh.edge_sets.at("left"), 2e5},
                 {mesh.edge_sets.at("right"), 2e5},
                 {mesh.edge_sets.at("bottom"), 1e5},
                 {mesh.edge_sets.at("top"), 1e5}};
  // Node 1 sits at (cos, sin) of the angle: its y moves by sin θ_k −
  // sin θ_{k−1}, step k's factor times the first step's sin 10°.
  const double step_angle = M_PI / 18;
  b.prescribed = {{0, 0, 0.0}, {0, 1, 0.0}, {1, 1, std::sin(step_angle)}};
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  auto solver = StaticSolver::Create(mesh, b, options, material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  for (int step = 1; step <= 3; ++step) {
    const double factor =
        (std::sin(step * step_angle) - std::sin((step - 1) * step_angle)) / std::sin(step_angle);
    const absl::StatusOr<StepReport> report = (*solver)->Step(factor);
    ASSERT_TRUE(report.ok()) << report.status();
    std::printf("minimal supports, step %d:%s\n", step, Errors(report->substeps[0]).c_str());
  }
  const double angle = 3 * step_angle;
  Eigen::Matrix2d r;
  r << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  for (int a = 0; a < 4; ++a) {
    EXPECT_LT(((*solver)->mesh().nodes[a] - r * mesh.nodes[a]).norm(), 1e-9) << a;
  }
}

// Simple shear with periodic sides: the bottom fixed, a rough top platen
// moving sideways, right-side nodes following their left partners. Every
// Gauss point gets the same ΔF = I + γ e_x ⊗ e_y, every node u_x = γ y,
// u_y = 0 (to 1e-9: the solve's round-off); with free sides instead the
// field is far from uniform.
TEST(StaticSolverTest, PeriodicSimpleShearIsUniform) {
  const double gamma = 1e-3;  // per step
  for (bool periodic : {true, false}) {
    const Mesh mesh = Rectangle(1.0, 1.0, 4, 4, ElementType::kQ8);
    auto inner = LinearElasticMaterial::Create(
        kE, kNu, Uniform(mesh, -kLateral * Eigen::Matrix3d::Identity()));
    ASSERT_TRUE(inner.ok());
    SpyMaterial spy(inner->get());
    Boundary b;
    AddFixed(mesh.node_sets.at("bottom"), b);
    AddPlaten(mesh.node_sets.at("top"), 0, gamma * 1.0, Platen::kRough, b);
    if (periodic) {
      b.periodic =
          *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
    } else {
      b.pressures = {{mesh.edge_sets.at("left"), kLateral}, {mesh.edge_sets.at("right"), kLateral}};
    }
    SolverOptions options;
    options.displacement_tolerance = 1e-10;
    auto solver = StaticSolver::Create(mesh, b, options, &spy);
    ASSERT_TRUE(solver.ok()) << solver.status();
    for (int step = 0; step < 3; ++step) ASSERT_TRUE((*solver)->Step().ok());
    double off = 0.0;  // the largest departure from u = (γ y, 0)
    for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
      const Eigen::Vector2d expected(3 * gamma * mesh.nodes[a].y(), 0.0);
      off = std::max(off, ((*solver)->displacement().segment<2>(2 * a) - expected).norm());
    }
    if (periodic) {
      EXPECT_LT(off, 1e-9 * 3 * gamma);
      for (const Eigen::Matrix3d& f : spy.last_commit) {
        EXPECT_LT((f - spy.last_commit[0]).norm(), 1e-9 * gamma);
      }
      // Shearing leaves every y as it was: each step's ΔF is I + γ e_x ⊗ e_y.
      EXPECT_NEAR(spy.last_commit[0](0, 1), gamma, 1e-9 * gamma);
      EXPECT_NEAR(spy.last_commit[0](1, 0), 0.0, 1e-9 * gamma);
    } else {
      EXPECT_GT(off, 1e-2 * 3 * gamma);
    }
  }
}

// A periodic offset stretches the body: right-side nodes at u_left + (δ,
// 0), the top free, the bottom on rollers (node 0 pinned). The stand-in
// then strains uniformly, ε_xx = δ/W with σ_yy = 0: ε_yy = −λ ε_xx/(λ +
// 2G), exactly for this ΔF (no rotation, V − I = ΔF − I), to round-off.
TEST(StaticSolverTest, APeriodicOffsetStretchesUniformly) {
  const double width = 2.0, delta = 4e-3;
  const Mesh mesh = Rectangle(width, 1.0, 3, 2, ElementType::kQ4);
  auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, Eigen::Matrix3d::Zero()));
  ASSERT_TRUE(material.ok());
  Boundary b;
  AddRoller(mesh.node_sets.at("bottom"), 1, b);
  AddRoller(std::vector<int>{0}, 0, b);
  b.periodic = *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  b.periodic_offset_increment = Eigen::Vector2d(delta, 0.0);
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  auto solver = StaticSolver::Create(mesh, b, options, material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  ASSERT_TRUE((*solver)->Step().ok());
  const double lambda = LameLambda(kE, kNu), shear = ShearModulus(kE, kNu);
  const double ex = delta / width, ey = -lambda * ex / (lambda + 2 * shear);
  for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
    const Eigen::Vector2d expected(ex * mesh.nodes[a].x(), ey * mesh.nodes[a].y());
    EXPECT_LT(((*solver)->displacement().segment<2>(2 * a) - expected).norm(), 1e-12) << a;
  }
  for (const PointResponse& r : (*solver)->responses()) {
    EXPECT_NEAR(r.stress(0, 0), (lambda + 2 * shear) * ex + lambda * ey, 1e-9 * kE * ex);
    EXPECT_NEAR(r.stress(1, 1), 0.0, 1e-9 * kE * ex);
  }
}

}  // namespace
}  // namespace rvehub::fem
