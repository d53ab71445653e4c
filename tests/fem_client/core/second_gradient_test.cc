// The local second gradient (second_gradient.h): Desrues eq. 44's modulus,
// the stiffness as the exact derivative of the terms, and through the
// solver a homogeneous patch that leaves it idle (λ = 0, Σ = 0, v = ∇u), a
// non-uniform field it stiffens, Newton's quadratic convergence with it,
// and the refusals.
#include "fem_client/core/second_gradient.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

#include "absl/strings/match.h"
#include "fem_client/core/elastic_material.h"
#include "fem_client/core/static_solver.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::DistortedSquare;
using testing::InteriorNodes;
using testing::Prestress;
using testing::Rectangle;
using testing::Uniform;

constexpr double kE = 1e8, kNu = 0.3;  // Pa, [-]

// Eq. 44 as printed: symmetric, and positive semi-definite (a double
// stress never gives energy back).
TEST(SecondGradientTest, TheModulusIsEquationFortyFour) {
  const double d = 7.0;
  const SecondGradientModulus m = IsotropicSecondGradientModulus(d);
  EXPECT_EQ(m(0, 0), d);
  EXPECT_EQ(m(0, 5), d / 2);
  EXPECT_EQ(m(1, 4), -d / 2);
  EXPECT_EQ(m(3, 5), -d / 2);
  EXPECT_EQ(m(7, 7), d);
  EXPECT_EQ(m(4, 5), 0.0);
  EXPECT_TRUE(m.isApprox(m.transpose(), 0.0));
  const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m).eigenvalues();
  EXPECT_GT(eig.minCoeff(), -1e-12 * d) << eig.transpose();
  EXPECT_GT(eig.maxCoeff(), d);
}

// The terms are linear in the increments: Terms(du, ds) − Terms(0, 0) =
// K·(du, ds) to round-off, on a distorted mesh from a committed state with
// λ and Σ.
TEST(SecondGradientTest, TheStiffnessIsTheExactDerivative) {
  const Mesh mesh = DistortedSquare(ElementType::kQ8R);
  auto sg = SecondGradient::Create(mesh, 3.0);
  ASSERT_TRUE(sg.ok()) << sg.status();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  SecondGradientState committed = sg->Initial();
  for (DoubleStress& s : committed.double_stress)
    s = DoubleStress::NullaryExpr([&] { return u(rng); });
  for (Eigen::Index k = 0; k < committed.multiplier.size(); ++k)
    committed.multiplier[k] = 1e3 * u(rng);
  const int dofs = 2 * static_cast<int>(mesh.nodes.size());
  Eigen::VectorXd du(dofs), ds(sg->unknowns());
  for (Eigen::Index k = 0; k < du.size(); ++k) du[k] = 1e-3 * u(rng);
  for (Eigen::Index k = 0; k < ds.size(); ++k)
    ds[k] = (k < 4 * sg->corner_nodes() ? 1e-3 : 50.0) * u(rng);
  const Eigen::VectorXd zero_u = Eigen::VectorXd::Zero(dofs),
                        zero_s = Eigen::VectorXd::Zero(ds.size());
  const SecondGradient::Terms t0 = sg->Evaluate(mesh, mesh.nodes, committed, zero_u, zero_s);
  const SecondGradient::Terms t1 = sg->Evaluate(mesh, mesh.nodes, committed, du, ds);
  Eigen::VectorXd x(dofs + ds.size());
  x << du, ds;
  const Eigen::VectorXd k_x = sg->Stiffness(mesh, mesh.nodes) * x;
  const Eigen::VectorXd internal = t1.internal - t0.internal;
  const Eigen::VectorXd residual = t1.residual - t0.residual;
  EXPECT_GT(internal.norm(), 0.0);
  EXPECT_LT((internal - k_x.head(dofs)).norm(), 1e-12 * internal.norm());
  EXPECT_LT((residual - k_x.tail(ds.size())).norm(), 1e-12 * residual.norm());
}

// Solver options for the tests: tight, the second gradient's D (N).
SolverOptions Tight(double d) {
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  options.max_iterations = 30;
  options.second_gradient = d;
  return options;
}

// The patch test with a second gradient: every boundary node moved by a
// uniform gradient H, the interior free. The second gradient sees no
// gradient of strain, so the interior follows H x as without it, λ and Σ
// stay zero (to round-off against the stresses) and v = H at every corner.
TEST(SecondGradientTest, AHomogeneousDeformationLeavesItIdle) {
  Eigen::Matrix2d h;
  h << 2e-3, -1e-3, 4e-3, -3e-3;
  const Mesh mesh = DistortedSquare(ElementType::kQ8R);
  auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, Prestress()));
  ASSERT_TRUE(material.ok());
  const std::vector<int> interior = InteriorNodes(mesh);
  const Boundary b = testing::PatchBoundary(mesh, h);
  auto solver = StaticSolver::Create(mesh, b, Tight(1e4), material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ASSERT_TRUE(report.ok()) << report.status();
  for (int a : interior) {
    EXPECT_LT(((*solver)->displacement().segment<2>(2 * a) - h * mesh.nodes[a]).norm(),
              1e-10 * h.norm())
        << "node " << a;
  }
  const SolverState state = (*solver)->State();
  const SecondGradientState& sg = state.second_gradient;
  ASSERT_EQ(sg.double_stress.size(), static_cast<std::size_t>(CountGaussPoints(mesh)));
  EXPECT_LT(sg.multiplier.cwiseAbs().maxCoeff(), 1e-8 * Prestress().norm());
  for (const DoubleStress& s : sg.double_stress) EXPECT_LT(s.norm(), 1e-10);
  ASSERT_EQ(sg.micro.size(), 4 * 9);  // the 3 × 3 corner nodes
  for (int c = 0; c < 9; ++c) {
    const Eigen::Vector4d v = sg.micro.segment<4>(4 * c);
    EXPECT_LT((v - Eigen::Vector4d(h(0, 0), h(0, 1), h(1, 0), h(1, 1))).norm(), 1e-10 * h.norm())
        << "corner " << c;
  }
}

// A rough-platen compression of a free-sided square (bottom fixed, top
// pushed down with its x held) barrels: a non-uniform strain. With a
// linear material and a small step, the platen's force is twice the
// stored energy over the travel (Clapeyron), and the second gradient
// adds positive energy at the same travel: the force grows with D. With
// D = 0 on Q8R the force is the plain first-gradient one.
TEST(SecondGradientTest, ItStiffensANonUniformField) {
  const Mesh mesh = Rectangle(1.0, 1.0, 4, 4, ElementType::kQ8R);
  std::vector<double> force;
  for (double d : {0.0, 1e4, 1e5, 1e6}) {
    auto material = LinearElasticMaterial::Create(kE, kNu, Uniform(mesh, Eigen::Matrix3d::Zero()));
    ASSERT_TRUE(material.ok());
    Boundary b;
    AddFixed(mesh.node_sets.at("bottom"), b);
    AddPlaten(mesh.node_sets.at("top"), 1, -1e-6, Platen::kRough, b);
    // A linear problem: one solve is exact, the second confirms to round-off.
    SolverOptions options = Tight(d);
    options.displacement_tolerance = 1e-8;
    auto solver = StaticSolver::Create(mesh, b, options, material->get());
    ASSERT_TRUE(solver.ok()) << solver.status();
    const absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << "D = " << d << ": " << report.status();
    force.push_back(-report->forces.at("top").reaction.y());
  }
  std::printf("platen force (N/m) at D = 0, 1e4, 1e5, 1e6 N: %.6g %.6g %.6g %.6g\n", force[0],
              force[1], force[2], force[3]);
  EXPECT_GT(force[0], 0.0);
  for (std::size_t k = 1; k < force.size(); ++k) EXPECT_GT(force[k], force[k - 1] * (1 + 1e-6));
  // A D of 1e6 N over 0.25 m elements is about E·h²/6: the same order
  // as the first gradient's stiffness, not a small correction.
  EXPECT_GT(force[3], 1.01 * force[0]);
}

// The second gradient is linear: Newton with the stiffening stand-in's
// exact tangent stays quadratic (each E_d below the square of the one
// before once below 0.1), as without it.
TEST(SecondGradientTest, NewtonStaysQuadratic) {
  const Mesh mesh = Rectangle(1.0, 1.0, 4, 4, ElementType::kQ8R);
  auto material = StiffeningElasticMaterial::Create(
      {5e7, 3e7, 40.0}, Uniform(mesh, -1e5 * Eigen::Matrix3d::Identity()));
  ASSERT_TRUE(material.ok());
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  AddPlaten(mesh.node_sets.at("top"), 1, -0.02, Platen::kRough, b);
  b.pressures = {{mesh.edge_sets.at("left"), 1e5}, {mesh.edge_sets.at("right"), 1e5}};
  SolverOptions options = Tight(1e5);
  options.displacement_tolerance = 1e-13;
  auto solver = StaticSolver::Create(mesh, b, options, material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  const absl::StatusOr<StepReport> report = (*solver)->Step();
  ASSERT_TRUE(report.ok()) << report.status();
  const std::vector<IterationReport>& it = report->substeps[0].iterations;
  int checked = 0;
  for (std::size_t j = 1; j < it.size(); ++j) {
    const double before = it[j - 1].displacement_error, now = it[j].displacement_error;
    std::printf("iteration %zu: E_d %.2e\n", j + 1, now);
    if (before > 0.1 || now < 1e-13) continue;
    EXPECT_LT(now, before * before) << "iteration " << j + 1;
    ++checked;
  }
  EXPECT_GE(checked, 2);
}

TEST(SecondGradientTest, RefusesElementsOtherThanQ8RAndABadModulus) {
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8}) {
    const Mesh mesh = Rectangle(1.0, 1.0, 1, 1, type);
    const absl::StatusOr<SecondGradient> sg = SecondGradient::Create(mesh, 1.0);
    ASSERT_FALSE(sg.ok());
    EXPECT_EQ(sg.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(absl::StrContains(sg.status().message(), "needs Q8R elements")) << sg.status();
    EXPECT_TRUE(absl::StrContains(sg.status().message(), ElementName(type))) << sg.status();
  }
  const Mesh mesh = Rectangle(1.0, 1.0, 1, 1, ElementType::kQ8R);
  for (double d : {-1.0, 0.0, std::numeric_limits<double>::infinity()}) {
    const absl::StatusOr<SecondGradient> sg = SecondGradient::Create(mesh, d);
    ASSERT_FALSE(sg.ok()) << d;
    EXPECT_TRUE(absl::StrContains(sg.status().message(), "positive and finite")) << sg.status();
  }
  // Through the solver: a Q4 mesh with a second gradient, a negative D.
  auto material = LinearElasticMaterial::Create(
      kE, kNu, Uniform(Rectangle(1.0, 1.0, 1, 1, ElementType::kQ4), Eigen::Matrix3d::Zero()));
  ASSERT_TRUE(material.ok());
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  auto solver = StaticSolver::Create(Rectangle(1.0, 1.0, 1, 1, ElementType::kQ4), b, Tight(1.0),
                                     material->get());
  ASSERT_FALSE(solver.ok());
  EXPECT_TRUE(absl::StrContains(solver.status().message(), "needs Q8R elements"));
  solver = StaticSolver::Create(Rectangle(1.0, 1.0, 1, 1, ElementType::kQ8R), b, Tight(-1.0),
                                material->get());
  ASSERT_FALSE(solver.ok());
  EXPECT_TRUE(absl::StrContains(solver.status().message(), "second-gradient modulus"));
}

}  // namespace
}  // namespace rvehub::fem
