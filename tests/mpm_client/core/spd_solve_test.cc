#include "mpm_client/core/spd_solve.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"

namespace rvehub::mpm {
namespace {

// The graph Laplacian of a chain of n nodes (unit conductances), plus `fixed`
// on the first node's diagonal: a drained (Dirichlet) end when fixed > 0,
// and a chain no boundary reaches, singular, when fixed = 0.
Eigen::SparseMatrix<double> Chain(int n, double fixed) {
  std::vector<Eigen::Triplet<double>> t = {{0, 0, fixed}};
  for (int i = 0; i + 1 < n; ++i) {
    t.insert(t.end(), {{i, i, 1.0}, {i + 1, i + 1, 1.0}, {i, i + 1, -1.0}, {i + 1, i, -1.0}});
  }
  Eigen::SparseMatrix<double> a(n, n);
  a.setFromTriplets(t.begin(), t.end());
  return a;
}

constexpr char kHint[] = "is every part connected to a drained boundary?";

TEST(SpdSolveTest, SolvesASystemToItsTolerance) {
  const Eigen::SparseMatrix<double> a = Chain(200, 1.0);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(200, -1.0, 2.0);
  int iterations = -1;
  const absl::StatusOr<Eigen::VectorXd> x = SolveSpd(a, b, "chain", kHint, &iterations);
  ASSERT_TRUE(x.ok()) << x.status();
  const Eigen::VectorXd exact = Eigen::MatrixXd(a).ldlt().solve(b);
  EXPECT_LT((*x - exact).norm(), 1e-9 * exact.norm());
  EXPECT_LT((a * *x - b).norm(), 1e-10 * b.norm());
  EXPECT_GT(iterations, 1);
}

// A value that is not finite, or so large that CG's squared norms overflow
// (which turns every iterate NaN), comes from a step that blew up: the
// message says so and leaves the hint out, which would mislead.
TEST(SpdSolveTest, AnUnstableInputIsNamedAndNotBlamedOnTheHint) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::SparseMatrix<double> bad_matrix = Chain(10, 1.0);
  bad_matrix.coeffRef(3, 3) = inf;
  Eigen::VectorXd nan_rhs = Eigen::VectorXd::Ones(10);
  nan_rhs[4] = nan;
  Eigen::SparseMatrix<double> huge_matrix = Chain(10, 1.0) * 1e200;
  const struct {
    const char* name;
    Eigen::SparseMatrix<double> a;
    Eigen::VectorXd b;
    const char* says;
  } kCases[] = {
      {"NaN in b", Chain(10, 1.0), nan_rhs,
       "x met a value that is not finite in its matrix or right-hand side"},
      {"inf in a", bad_matrix, Eigen::VectorXd::Ones(10),
       "x met a value that is not finite in its matrix or right-hand side"},
      {"b of 1e200", Chain(10, 1.0), Eigen::VectorXd::Constant(10, 1e200),
       "x met values too large to solve (its squared norms overflow)"},
      {"a of 1e200", huge_matrix, Eigen::VectorXd::Ones(10),
       "x met values too large to solve (its squared norms overflow)"},
  };
  for (const auto& c : kCases) {
    const absl::Status s = SolveSpd(c.a, c.b, "x", kHint).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kInternal) << c.name << ": " << s;
    EXPECT_TRUE(absl::StrContains(s.message(), c.says)) << c.name << ": " << s;
    EXPECT_TRUE(absl::StrContains(s.message(), "the solution became unstable"))
        << c.name << ": " << s;
    EXPECT_FALSE(absl::StrContains(s.message(), "drained")) << c.name << ": " << s;
  }
  // Just below the overflow it still solves: the bound is CG's, not ours.
  EXPECT_TRUE(SolveSpd(Chain(10, 1.0), Eigen::VectorXd::Constant(10, 1e150), "x").ok());
}

// A chain no boundary reaches, loaded unevenly, has no solution: CG's
// iterates turn NaN (a zero curvature), which from moderate input means a
// singular matrix, the hint's case; a non-symmetric matrix, on which CG
// wanders without converging, is reported with the hint too.
TEST(SpdSolveTest, ASingularOrNonSymmetricSystemGivesTheHint) {
  Eigen::VectorXd uneven = Eigen::VectorXd::Zero(10);
  uneven[0] = 1.0;
  const absl::Status singular = SolveSpd(Chain(10, 0.0), uneven, "x", kHint).status();
  EXPECT_EQ(singular.code(), absl::StatusCode::kInternal) << singular;
  EXPECT_EQ(singular.message(),
            "x broke down (its iterates are not finite: the matrix is singular or not positive "
            "definite): is every part connected to a drained boundary?");
  // Without a hint the sentence ends at the cause.
  EXPECT_TRUE(absl::EndsWith(SolveSpd(Chain(10, 0.0), uneven, "x").status().message(),
                             "not positive definite)"));
  // Loaded evenly (b orthogonal to the constant null vector) it is
  // consistent, and CG finds a solution.
  Eigen::VectorXd balanced = Eigen::VectorXd::Zero(10);
  balanced[0] = 1.0;
  balanced[9] = -1.0;
  const absl::StatusOr<Eigen::VectorXd> x = SolveSpd(Chain(10, 0.0), balanced, "x", kHint);
  ASSERT_TRUE(x.ok()) << x.status();
  EXPECT_LT((Chain(10, 0.0) * *x - balanced).norm(), 1e-10);

  // 5 × 5, unit diagonal, off-diagonal entries that make it non-symmetric.
  Eigen::MatrixXd d(5, 5);
  d << 1, 0.5, -0.8, 0.3, 0.9,  //
      -0.7, 1, 0.6, -0.9, 0.2,  //
      0.4, -0.3, 1, 0.8, -0.6,  //
      0.9, 0.7, -0.5, 1, 0.4,   //
      -0.2, 0.8, 0.9, -0.7, 1;
  const absl::Status wandering =
      SolveSpd(d.sparseView(), Eigen::VectorXd::Ones(5), "x", kHint).status();
  EXPECT_EQ(wandering.code(), absl::StatusCode::kInternal) << wandering;
  EXPECT_TRUE(absl::EndsWith(wandering.message(), std::string(": ") + kHint)) << wandering;
  EXPECT_FALSE(absl::StrContains(wandering.message(), "unstable")) << wandering;
}

}  // namespace
}  // namespace rvehub::mpm
