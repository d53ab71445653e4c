// The Gauss points' material backed by RVEs: the contact tangent as a
// minor-symmetric strain tangent, a COMMIT equal bit for bit to the last
// TRIAL of the same ΔF (embedded and over loopback servers), and G&Z §3.3's
// single element driven by Newton iterations of TRIALs on four RVEs.
#include "fem_client/run/rve_material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "fem_client/core/boundary.h"
#include "fem_client/core/mesh.h"
#include "fem_client/core/static_solver.h"
#include "tests/rve_server/client/rve_pool_test_util.h"

namespace rvehub::fem {
namespace {

using client::RvePool;
namespace pool_test = client::pool_test;

TEST(SymmetricTangentTest, HasBothMinorSymmetriesAndKeepsASymmetricTangent) {
  Eigen::Matrix<double, 9, 9> d = Eigen::Matrix<double, 9, 9>::Zero();
  d.topLeftCorner<5, 5>().setRandom();
  const Tangent s = SymmetricTangent(d);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) {
          EXPECT_EQ(s(3 * i + j, 3 * k + l), s(3 * j + i, 3 * k + l));
          EXPECT_EQ(s(3 * i + j, 3 * k + l), s(3 * i + j, 3 * l + k));
        }
  // σ_01 from ε_01 alone: the mean of the four entries.
  EXPECT_DOUBLE_EQ(s(1, 1), 0.25 * (d(1, 1) + d(3, 1) + d(1, 3) + d(3, 3)));
  EXPECT_DOUBLE_EQ(s(0, 4), 0.5 * (d(0, 4) + d(0, 4)));
  EXPECT_EQ(SymmetricTangent(s), s);
}

// Four RVEs of SET-dense (400 discs) at their template state on `endpoints`.
std::unique_ptr<RvePool> FourRves(std::vector<std::unique_ptr<client::RveEndpoint>> endpoints,
                                  const std::string& run) {
  auto pool = std::make_unique<RvePool>(std::move(endpoints), run);
  EXPECT_TRUE(pool->UploadTemplates(pool_test::Templates()).ok());
  const std::vector<std::string> names(4, "set-dense");
  absl::StatusOr<std::vector<dem::RveState>> created = pool->Create(names);
  EXPECT_TRUE(created.ok()) << created.status();
  return pool;
}

Eigen::Matrix3d Compression(double strain) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
  f(1, 1) = 1.0 - strain;
  return f;
}

// Newton's iterates, then the converged ΔF: the COMMIT's states equal the
// last TRIAL's field by field, bit for bit, and the committed step moves on.
void ExpectCommitEqualsLastTrial(RvePool& pool) {
  RveMaterial material(&pool, 0);
  for (double strain : {2e-4, 1.2e-4, 1e-4}) {
    const std::vector<Eigen::Matrix3d> df(4, Compression(strain));
    ASSERT_TRUE(material.Trial(df, /*want_tangent=*/true).ok());
  }
  const std::vector<dem::RveState> trial = material.last_trial();
  ASSERT_TRUE(material.Commit(std::vector<Eigen::Matrix3d>(4, Compression(1e-4))).ok());
  EXPECT_EQ(material.committed_step(), 1);
  ASSERT_EQ(material.committed().size(), 4u);
  for (int k = 0; k < 4; ++k) {
    SCOPED_TRACE(k);
    dem::RveState committed = material.committed()[k];
    committed.tangent = trial[k].tangent;  // the COMMIT did not ask for it
    pool_test::ExpectIdenticalStates(committed, trial[k], "committed against trial");
  }
}

TEST(RveMaterialTest, CommitEqualsTheLastTrialEmbedded) {
  std::unique_ptr<RvePool> pool = FourRves(pool_test::EmbeddedEndpoints(1), "fem-embedded");
  ExpectCommitEqualsLastTrial(*pool);
}

TEST(RveMaterialTest, CommitEqualsTheLastTrialOnTwoLoopbackServers) {
  pool_test::Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  std::unique_ptr<RvePool> pool = FourRves(pool_test::RemoteEndpoints(servers), "fem-remote");
  ExpectCommitEqualsLastTrial(*pool);
}

// G&Z §3.3 on four identical RVEs: one Q4 element 1 m × 1 m, rollers left
// and bottom, a smooth platen on top pressed 0.1 % per step, the lateral
// pressure the packings start at (their mean stress). Three steps converge
// to E_d < 0.01 with the contact tangent within G&Z's few iterations at
// small strain (Fig. 7: 2–4), the element stays nearly uniform (four equal
// RVEs; their ΔF differ in the last bits from one Gauss point to the next,
// which the packings' contact networks amplify: σ_yy within 0.5 %, measured
// 0.1 %), and the platen's reaction per width is the RVEs' mean σ_yy.
TEST(RveMaterialTest, SingleElementConvergesOnFourRves) {
  std::unique_ptr<RvePool> pool = FourRves(pool_test::EmbeddedEndpoints(1), "fem-element");
  absl::StatusOr<std::vector<dem::RveState>> start = pool->Get(false);
  ASSERT_TRUE(start.ok());
  const double lateral = -(*start)[0].stress(0, 0);  // Pa, compression
  ASSERT_GT(lateral, 1e4);
  RectangleSpec spec;
  spec.width = spec.height = 1.0;
  spec.nx = spec.ny = 1;
  spec.type = ElementType::kQ4;
  absl::StatusOr<Mesh> mesh = StructuredRectangle(spec);
  ASSERT_TRUE(mesh.ok());
  Boundary b;
  AddRoller(mesh->node_sets.at("left"), 0, b);
  AddRoller(mesh->node_sets.at("bottom"), 1, b);
  AddPlaten(mesh->node_sets.at("top"), 1, -1e-3, Platen::kSmooth, b);
  b.pressures = {{mesh->edge_sets.at("right"), lateral}};
  RveMaterial material(pool.get(), 0);
  absl::StatusOr<std::unique_ptr<StaticSolver>> solver =
      StaticSolver::Create(*mesh, b, SolverOptions(), &material);
  ASSERT_TRUE(solver.ok()) << solver.status();
  for (int step = 1; step <= 3; ++step) {
    absl::StatusOr<StepReport> report = (*solver)->Step();
    ASSERT_TRUE(report.ok()) << report.status();
    ASSERT_EQ(report->cutbacks, 0);
    const std::vector<IterationReport>& it = report->substeps.back().iterations;
    EXPECT_LE(it.size(), 6u);
    EXPECT_LT(it.back().displacement_error, 0.01);
    std::printf("step %d: %zu iterations, E_d %.2e, E_f %.2e\n", step, it.size(),
                it.back().displacement_error, it.back().force_error);
    const std::vector<dem::RveState>& rves = material.committed();
    double mean_syy = 0.0;
    for (const dem::RveState& r : rves) mean_syy += r.stress(1, 1) / 4;
    for (const dem::RveState& r : rves) {
      EXPECT_NEAR(r.stress(1, 1), mean_syy, 5e-3 * std::abs(mean_syy));
    }
    const double width = (*solver)->mesh().nodes[1].x() - (*solver)->mesh().nodes[0].x();
    // The residual left at E_d < 0.01 (E_f ~ 2e-4 of the forces) bounds the
    // difference.
    EXPECT_NEAR(report->forces.at("top").reaction.y(), mean_syy * width, 1e-2 * std::abs(mean_syy));
  }
  EXPECT_EQ(material.committed_step(), 3);
  EXPECT_LT(material.committed()[0].stress(1, 1), -1.2 * lateral);  // loaded axially
}

}  // namespace
}  // namespace rvehub::fem
