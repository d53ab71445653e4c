// The Newton solver with a rigid platen under force control: G&Z §5.2's
// stress-controlled simple shear (bottom fixed, sides periodic, the top a
// rough platen whose height is held and whose horizontal force is
// prescribed) against the closed form and the strain-controlled run,
// reversal, cycles through cut-backs, quadratic convergence with the
// stiffening stand-in, and the set-ups Create refuses.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_format.h"
#include "fem_client/core/elastic_material.h"
#include "fem_client/core/static_solver.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::SpyMaterial;

constexpr double kE = 1e8, kNu = 0.3;          // Pa, [-]
constexpr double kLateral = 1e5;               // Pa
constexpr double kWidth = 2.0, kHeight = 1.0;  // m
constexpr double kTau = 3e4;                   // Pa: G&Z's |τ|

Mesh Specimen(ElementType type) {
  RectangleSpec spec;
  spec.width = kWidth;
  spec.height = kHeight;
  spec.nx = 4;
  spec.ny = 2;
  spec.type = type;
  return *StructuredRectangle(spec);
}

std::vector<Eigen::Matrix3d> Consolidated(const Mesh& mesh) {
  return std::vector<Eigen::Matrix3d>(CountGaussPoints(mesh),
                                      -kLateral * Eigen::Matrix3d::Identity());
}

// Bottom fixed; the sides periodic, or free under the lateral pressure.
Boundary Base(const Mesh& mesh, bool periodic) {
  Boundary b;
  AddFixed(mesh.node_sets.at("bottom"), b);
  if (periodic) {
    b.periodic =
        *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  } else {
    b.pressures = {{mesh.edge_sets.at("left"), kLateral}, {mesh.edge_sets.at("right"), kLateral}};
  }
  return b;
}

// The top's height held, sheared by a force (N/m per step) on the rigid
// platen.
Boundary ForceControlled(const Mesh& mesh, double force, bool periodic = true) {
  Boundary b = Base(mesh, periodic);
  AddRoller(mesh.node_sets.at("top"), 1, b);
  AddForcedPlaten(mesh.node_sets.at("top"), 0, force, b);
  return b;
}

// The top's height held, sheared by a displacement (m per step).
Boundary StrainControlled(const Mesh& mesh, double shift, bool periodic = true) {
  Boundary b = Base(mesh, periodic);
  AddPlaten(mesh.node_sets.at("top"), 0, shift, Platen::kRough, b);
  return b;
}

SolverOptions Tight() {
  SolverOptions options;
  options.displacement_tolerance = 1e-12;
  options.max_iterations = 30;
  return options;
}

// The linear stand-in's shear stress under ΔF = I + γ e_x ⊗ e_y from an
// isotropic stress: 2G (V − I)_xy = 2Gγ/√(4 + γ²) (V the left stretch), so
// the γ that carries τ; τ/G to O(γ²/8).
double ShearStrain(double tau) {
  const double g = ShearModulus(kE, kNu);
  return 2 * tau / std::sqrt(4 * g * g - tau * tau);
}

double LargestDifference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

std::string Errors(const SubStepReport& sub) {
  std::string out;
  for (const IterationReport& it : sub.iterations) {
    out += absl::StrFormat(" (%.2e, %.2e)", it.displacement_error, it.force_error);
  }
  return out;
}

// τ = 30 kPa on the platen (F = τW) shears the periodic specimen uniformly:
// every node at u = (γy, 0) with the stand-in's γ for τ, to 1e-9 of γH; γ
// is τ/G but for the O(γ²/8) of the finite rotation. The strain-controlled
// run that prescribes γH at the top lands on the same displacements and
// stresses, and its platen carries F, to 1e-9. Under force control the
// top is no support: its reaction vanishes, the body's resistance is F.
TEST(StaticSolverForceTest, AForceOnThePlatenShearsAsTheStrainControlledRunDoes) {
  const double force = kTau * kWidth, gamma = ShearStrain(kTau);
  const double shear = ShearModulus(kE, kNu);
  EXPECT_NEAR(gamma, kTau / shear, 0.2 * gamma * gamma * gamma);
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8}) {
    const Mesh mesh = Specimen(type);
    auto forced_material = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
    auto strained_material = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
    ASSERT_TRUE(forced_material.ok() && strained_material.ok());
    auto forced =
        StaticSolver::Create(mesh, ForceControlled(mesh, force), Tight(), forced_material->get());
    ASSERT_TRUE(forced.ok()) << forced.status();
    auto strained = StaticSolver::Create(mesh, StrainControlled(mesh, gamma * kHeight), Tight(),
                                         strained_material->get());
    ASSERT_TRUE(strained.ok()) << strained.status();
    const absl::StatusOr<StepReport> f = (*forced)->Step();
    ASSERT_TRUE(f.ok()) << f.status();
    const absl::StatusOr<StepReport> s = (*strained)->Step();
    ASSERT_TRUE(s.ok()) << s.status();
    std::printf("force control, %s: (E_d, E_f) per iteration:%s\n",
                std::string(ElementName(type)).c_str(), Errors(f->substeps[0]).c_str());

    const double scale = gamma * kHeight;
    Eigen::VectorXd uniform = Eigen::VectorXd::Zero(2 * mesh.nodes.size());
    for (std::size_t a = 0; a < mesh.nodes.size(); ++a) uniform[2 * a] = gamma * mesh.nodes[a].y();
    EXPECT_LT(LargestDifference((*forced)->displacement(), uniform), 1e-9 * scale);
    EXPECT_LT(LargestDifference((*forced)->displacement(), (*strained)->displacement()),
              1e-9 * scale);
    const std::span<const PointResponse> fr = (*forced)->responses(), sr = (*strained)->responses();
    for (std::size_t p = 0; p < fr.size(); ++p) {
      EXPECT_NEAR(fr[p].stress(0, 1), kTau, 1e-9 * kTau);
      EXPECT_LT((fr[p].stress - sr[p].stress).norm(), 1e-9 * kTau);
    }

    ASSERT_EQ(f->platens.size(), 1u);
    const PlatenState& platen = f->platens[0];
    EXPECT_EQ(platen.force, force);
    EXPECT_NEAR(platen.resistance, force, 1e-9 * force);
    EXPECT_NEAR(platen.displacement, scale, 1e-9 * scale);
    EXPECT_NEAR(f->forces.at("top").internal.x(), force, 1e-9 * force);
    EXPECT_NEAR(f->forces.at("top").reaction.x(), 0.0, 1e-9 * force);
    EXPECT_NEAR(s->forces.at("top").reaction.x(), force, 1e-9 * force);
    EXPECT_TRUE(s->platens.empty());
    ASSERT_EQ((*forced)->platens().size(), 1u);
    EXPECT_EQ((*forced)->platens()[0].displacement, platen.displacement);
  }
}

// Step(−1) takes the force back off: the load is exactly 0 again, the
// specimen returns to its start (to 1e-9 of γH) and the shear stress to 0.
// The normal stresses keep the stand-in's own second-order residue: the
// step back is ΔF⁻¹ = Rᵀ V⁻¹, so σ = σ₀ + C : Rᵀ(V + V⁻¹ − 2I)R with V + V⁻¹
// − 2I = (V − I)² V⁻¹ ≈ γ²/4 I in plane: σ_xx − σ₀ = σ_yy − σ₀ = (λ + G)γ²/2,
// σ_zz − σ₀ = λγ²/2 (to O(γ²) of themselves).
TEST(StaticSolverForceTest, ReversingTheForceReturnsTheSpecimen) {
  const Mesh mesh = Specimen(ElementType::kQ4);
  auto material = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(material.ok());
  auto solver =
      StaticSolver::Create(mesh, ForceControlled(mesh, kTau * kWidth), Tight(), material->get());
  ASSERT_TRUE(solver.ok()) << solver.status();
  ASSERT_TRUE((*solver)->Step(1.0).ok());
  const absl::StatusOr<StepReport> back = (*solver)->Step(-1.0);
  ASSERT_TRUE(back.ok()) << back.status();
  const double gamma = ShearStrain(kTau);
  const double off = (*solver)->displacement().cwiseAbs().maxCoeff();
  std::printf("reversed: largest displacement %.3e m (γH = %.3e m)\n", off, gamma * kHeight);
  EXPECT_EQ(back->platens[0].force, 0.0);
  EXPECT_LT(off, 1e-9 * gamma * kHeight);
  EXPECT_LT(std::abs(back->platens[0].displacement), 1e-9 * gamma * kHeight);
  EXPECT_NEAR(back->platens[0].resistance, 0.0, 1e-9 * kTau * kWidth);
  const double lambda = LameLambda(kE, kNu), shear = ShearModulus(kE, kNu);
  const Eigen::Vector3d residue =
      Eigen::Vector3d(lambda + shear, lambda + shear, lambda) * gamma * gamma / 2;
  for (const PointResponse& p : (*solver)->responses()) {
    EXPECT_NEAR(p.stress(0, 1), 0.0, 1e-9 * kTau);
    const Eigen::Vector3d normal = p.stress.diagonal() + Eigen::Vector3d::Constant(kLateral);
    EXPECT_LT((normal - residue).norm(), 1e-3 * residue.norm());
  }
}

// G&Z's cycles, τ: 0 → +τ → −τ → +τ → −τ → 0 (factors 1, −2, 2, −2, 1),
// against a material that refuses a step of ΔF_xy over 1e-3: the three
// steps of 2τ are cut back into halves. After every step the reported load
// is the sum of the increments applied so far (cut-back parts included,
// failed attempts not), the body's resistance equals it, and the platen's
// displacement is the closed form's γH for the current τ (to O(γ³)).
TEST(StaticSolverForceTest, TheReportedForceIsTheSumOfTheIncrementsThroughCutBacks) {
  const Mesh mesh = Specimen(ElementType::kQ4);
  auto inner = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(inner.ok());
  SpyMaterial spy(inner->get());
  spy.fail = [](std::span<const Eigen::Matrix3d> delta_f) -> absl::Status {
    for (const Eigen::Matrix3d& f : delta_f) {
      if (std::abs(f(0, 1)) > 1e-3) return absl::OutOfRangeError("too large a step");
    }
    return absl::OkStatus();
  };
  const double force = kTau * kWidth, gamma = ShearStrain(kTau);
  auto solver = StaticSolver::Create(mesh, ForceControlled(mesh, force), Tight(), &spy);
  ASSERT_TRUE(solver.ok()) << solver.status();
  double applied = 0.0;
  int cutbacks = 0;
  for (double factor : {1.0, -2.0, 2.0, -2.0, 1.0}) {
    const absl::StatusOr<StepReport> report = (*solver)->Step(factor);
    ASSERT_TRUE(report.ok()) << report.status();
    applied += factor * force;
    cutbacks += report->cutbacks;
    EXPECT_EQ(report->cutbacks, std::abs(factor) > 1 ? 1 : 0) << factor;
    ASSERT_EQ(report->platens.size(), 1u);
    const PlatenState& platen = report->platens[0];
    EXPECT_NEAR(platen.force, applied, 1e-12 * force) << factor;
    EXPECT_NEAR(platen.resistance, applied, 1e-9 * force) << factor;
    EXPECT_NEAR(platen.displacement, gamma * kHeight * applied / force,
                gamma * gamma * gamma * kHeight)
        << factor;
    EXPECT_EQ((*solver)->platens()[0].force, platen.force);
    for (const SubStepReport& sub : report->substeps) {
      for (const IterationReport& it : sub.iterations) EXPECT_TRUE(std::isfinite(it.force_error));
    }
  }
  EXPECT_EQ(cutbacks, 3);
  EXPECT_NEAR((*solver)->platens()[0].force, 0.0, 1e-12 * force);
}

// With the stiffening stand-in's exact tangent Newton still converges
// quadratically under force control (the load is dead: the tangent is the
// strain-controlled one), on the periodic specimen and on one with free
// sides under the lateral pressure (a non-uniform field), E_f normalised
// with the platen's load: once E_d < 0.1 each iteration's E_d and E_f are
// below twice the square of the one before (measured factors 0.01–1.5),
// until round-off (1e-13). The strain-controlled run that moves the top by
// the platen's displacement found lands on the same displacements and its
// platen pushes with the same force (its reaction: the pressures on the
// top corners included), to 1e-9.
TEST(StaticSolverForceTest, NewtonConvergesQuadraticallyUnderForceControl) {
  const StiffeningParameters stand_in{5e7, 3e7, 40.0};
  const double tau = 1.5e6;  // Pa: γ ≈ 5 %, well into the nonlinear range
  for (bool periodic : {true, false}) {
    const Mesh mesh = Specimen(ElementType::kQ4);
    auto forced_material = StiffeningElasticMaterial::Create(stand_in, Consolidated(mesh));
    auto strained_material = StiffeningElasticMaterial::Create(stand_in, Consolidated(mesh));
    ASSERT_TRUE(forced_material.ok() && strained_material.ok());
    SolverOptions options = Tight();
    options.displacement_tolerance = 1e-13;
    auto forced = StaticSolver::Create(mesh, ForceControlled(mesh, tau * kWidth, periodic), options,
                                       forced_material->get());
    ASSERT_TRUE(forced.ok()) << forced.status();
    const absl::StatusOr<StepReport> report = (*forced)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    ASSERT_EQ(report->cutbacks, 0);
    const std::vector<IterationReport>& it = report->substeps[0].iterations;
    std::printf("stiffening, %s sides, force control, (E_d, E_f) per iteration:%s\n",
                periodic ? "periodic" : "free", Errors(report->substeps[0]).c_str());
    int checked = 0;
    for (std::size_t j = 1; j < it.size(); ++j) {
      const IterationReport& before = it[j - 1];
      const IterationReport& now = it[j];
      if (before.displacement_error > 0.1) continue;
      if (now.displacement_error > 1e-13) {
        EXPECT_LT(now.displacement_error, 2 * before.displacement_error * before.displacement_error)
            << "iteration " << j + 1;
        ++checked;
      }
      if (now.force_error > 1e-13) {
        EXPECT_LT(now.force_error, 2 * before.force_error * before.force_error)
            << "iteration " << j + 1;
      }
    }
    EXPECT_GE(checked, periodic ? 1 : 2);
    EXPECT_LT(it.back().force_error, 1e-12);

    const PlatenState& platen = report->platens[0];
    EXPECT_GT(platen.displacement, 0.02 * kHeight);
    auto strained =
        StaticSolver::Create(mesh, StrainControlled(mesh, platen.displacement, periodic), options,
                             strained_material->get());
    ASSERT_TRUE(strained.ok()) << strained.status();
    const absl::StatusOr<StepReport> s = (*strained)->Step();
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_NEAR(s->forces.at("top").reaction.x(), tau * kWidth, 1e-9 * tau * kWidth);
    EXPECT_LT(LargestDifference((*forced)->displacement(), (*strained)->displacement()),
              1e-9 * platen.displacement);
  }
}

void ExpectError(const absl::Status& s, absl::StatusCode code, const std::string& says) {
  EXPECT_EQ(s.code(), code) << s;
  EXPECT_TRUE(absl::StrContains(s.message(), says)) << s << "\nshould say: " << says;
}

// A platen whose forced dof is also prescribed on one of its nodes, and a
// forced platen taken for a support.
TEST(StaticSolverForceTest, CreateRefusesConflictsAndMissingSupports) {
  const Mesh mesh = Specimen(ElementType::kQ4);
  auto material = LinearElasticMaterial::Create(kE, kNu, Consolidated(mesh));
  ASSERT_TRUE(material.ok());
  const auto create = [&](const Boundary& b) {
    return StaticSolver::Create(mesh, b, SolverOptions(), material->get()).status();
  };
  Boundary held = ForceControlled(mesh, kTau * kWidth);
  const int corner = mesh.node_sets.at("top").back();
  AddRoller(std::vector<int>{corner}, 0, held);
  ExpectError(create(held), absl::StatusCode::kInvalidArgument,
              absl::StrFormat("node %d dof x is both prescribed and in forced platen 0", corner));
  Boundary rollers;
  AddRoller(mesh.node_sets.at("bottom"), 1, rollers);
  AddRoller(mesh.node_sets.at("top"), 1, rollers);
  AddForcedPlaten(mesh.node_sets.at("top"), 0, kTau * kWidth, rollers);
  ExpectError(create(rollers), absl::StatusCode::kFailedPrecondition,
              "the mesh has no supports against rigid-body motion");
}

}  // namespace
}  // namespace rvehub::fem
