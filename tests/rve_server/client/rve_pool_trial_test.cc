// TRIAL through the endpoints and the pool, as an implicit client's Newton
// iterations use it: a TRIAL changes no RVE (its record is the same bit for
// bit), the COMMIT of the converged ΔF returns the TRIAL's states and those
// of a twin run that never tried, remote servers agree with the embedded
// registry, a TRIAL at a step the RVEs are not ready for is refused per point,
// and a TRIAL whose reply is lost is sent again.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/client/rve_pool.h"
#include "rve_server/embedded/endpoint.h"
#include "tests/rve_server/client/rve_pool_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::client::pool_test {
namespace {

std::vector<RveRecord> ExportOrDie(RvePool& pool) {
  absl::StatusOr<std::vector<RveRecord>> r = pool.ExportAll();
  EXPECT_TRUE(r.ok()) << r.status();
  return r.ok() ? *std::move(r) : std::vector<RveRecord>{};
}

std::vector<dem::RveState> GetOrDie(RvePool& pool) {
  absl::StatusOr<std::vector<dem::RveState>> s = pool.Get(/*want_tangent=*/true);
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *std::move(s) : std::vector<dem::RveState>{};
}

std::vector<dem::RveState> TrialOrDie(RvePool& pool, std::int64_t step,
                                      const std::vector<Eigen::Matrix3d>& delta_f,
                                      bool want_tangent) {
  absl::StatusOr<std::vector<dem::RveState>> s = pool.Trial(step, delta_f, want_tangent);
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *std::move(s) : std::vector<dem::RveState>{};
}

std::vector<dem::RveState> CommitOrDie(RvePool& pool, std::int64_t step,
                                       const std::vector<Eigen::Matrix3d>& delta_f,
                                       bool want_tangent) {
  absl::StatusOr<std::vector<dem::RveState>> s = pool.Apply(step, delta_f, want_tangent);
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *std::move(s) : std::vector<dem::RveState>{};
}

// A Newton iterate short of the converged ΔF: more axial compression.
std::vector<Eigen::Matrix3d> Iterate(std::int64_t step) {
  std::vector<Eigen::Matrix3d> f = DeltaFs(step);
  for (Eigen::Matrix3d& m : f) m(1, 1) -= 5e-5;
  return f;
}

// The pool's RVEs after step 1 are left bit for bit as they were by TRIALs
// of step 2 through the pool and through each endpoint directly; the
// TRIALs computed something (a new stress, a tangent when asked) and are
// counted apart from the COMMITs.
void ExpectTrialsChangeNothing(RvePool& pool, const std::string& where) {
  SCOPED_TRACE(where);
  Start(pool);
  ApplyOrDie(pool, 1);
  const std::vector<RveRecord> before = ExportOrDie(pool);
  const std::vector<dem::RveState> committed = GetOrDie(pool);
  ASSERT_EQ(before.size(), static_cast<std::size_t>(kPoints));
  const std::int64_t evaluations = pool.evaluations();
  const std::int64_t applied = pool.apply_stats().increments;
  const double work = pool.point_work()[0];

  const std::vector<dem::RveState> tried = TrialOrDie(pool, 2, DeltaFs(2), true);
  ASSERT_EQ(tried.size(), static_cast<std::size_t>(kPoints));
  for (int p = 0; p < kPoints; ++p) {
    EXPECT_TRUE(tried[p].tangent.has_value()) << "point " << p;
    EXPECT_FALSE(SameBits(tried[p].stress, committed[p].stress)) << "point " << p;
    // Compressed further than step 1 left it (tension +).
    EXPECT_LT(tried[p].stress(1, 1), committed[p].stress(1, 1)) << "point " << p;
  }
  const std::vector<dem::RveState> again = TrialOrDie(pool, 2, Iterate(2), false);
  ASSERT_EQ(again.size(), static_cast<std::size_t>(kPoints));
  EXPECT_FALSE(again[0].tangent.has_value());

  // Each endpoint directly: the outcome keeps the committed step.
  for (int k = 0; k < pool.num_endpoints(); ++k) {
    std::vector<Increment> increments;
    for (std::int64_t p : pool.points_of(k)) increments.push_back({p, DeltaF(p, 2)});
    ASSERT_FALSE(increments.empty());
    absl::StatusOr<std::vector<RveOutcome>> o =
        pool.endpoint(k).Apply(kRun, 2, ApplyMode::kTrial, increments, {}, absl::Seconds(60));
    ASSERT_TRUE(o.ok()) << o.status();
    ASSERT_EQ(o->size(), increments.size());
    for (std::size_t i = 0; i < o->size(); ++i) {
      EXPECT_TRUE((*o)[i].status.ok()) << (*o)[i].status;
      EXPECT_EQ((*o)[i].id, increments[i].id);
      EXPECT_EQ((*o)[i].step, 1);
      // The pool's TRIAL of the same ΔF, less the tangent.
      const dem::RveState& via_pool = tried[increments[i].id];
      EXPECT_TRUE(SameBits((*o)[i].state.stress, via_pool.stress));
      EXPECT_TRUE(SameBits((*o)[i].state.void_ratio, via_pool.void_ratio));
      EXPECT_FALSE((*o)[i].state.tangent.has_value());
    }
  }

  ExpectSameRecords(before, ExportOrDie(pool));
  for (const RveRecord& r : before) EXPECT_EQ(r.step, 1);
  ExpectSameStates(committed, GetOrDie(pool), "Get after the trials");
  EXPECT_EQ(pool.evaluations(), evaluations);
  EXPECT_EQ(pool.apply_stats().increments, applied);
  EXPECT_EQ(pool.trial_stats().increments, 2 * kPoints);
  EXPECT_GT(pool.trial_stats().dem_steps, 0);
  // The servers' work counts for balancing, whatever the mode.
  EXPECT_GT(pool.point_work()[0], work);
}

TEST(RvePoolTrialTest, TrialLeavesEveryRveUnchangedEmbedded) {
  RvePool pool(EmbeddedEndpoints(2), kRun);
  ExpectTrialsChangeNothing(pool, "embedded");
}

TEST(RvePoolTrialTest, TrialLeavesEveryRveUnchangedRemote) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RvePool pool(RemoteEndpoints(servers), kRun);
  ExpectTrialsChangeNothing(pool, "remote");
}

// Newton on every point: a TRIAL of an iterate, a TRIAL of the converged
// ΔF, its COMMIT. The COMMIT returns the second TRIAL's states, and the run
// goes on as a twin that committed the same ΔF without trying.
void ExpectCommitAfterTrialsMatches(RvePool& tried, RvePool& twin, bool want_tangent,
                                    const std::string& where) {
  SCOPED_TRACE(where);
  Start(tried);
  Start(twin);
  ExpectSameStates(ApplyOrDie(tried, 1), ApplyOrDie(twin, 1), "step 1");
  const std::vector<dem::RveState> iterate = TrialOrDie(tried, 2, Iterate(2), want_tangent);
  const std::vector<dem::RveState> trial = TrialOrDie(tried, 2, DeltaFs(2), want_tangent);
  const std::vector<dem::RveState> commit = CommitOrDie(tried, 2, DeltaFs(2), want_tangent);
  const std::vector<dem::RveState> direct = CommitOrDie(twin, 2, DeltaFs(2), want_tangent);
  ASSERT_EQ(trial.size(), static_cast<std::size_t>(kPoints));
  ASSERT_EQ(iterate.size(), static_cast<std::size_t>(kPoints));
  EXPECT_FALSE(SameBits(iterate[0].stress, trial[0].stress));  // another ΔF, another state
  ExpectSameStates(trial, commit, "TRIAL vs COMMIT");
  ExpectSameStates(commit, direct, "COMMIT after TRIALs vs the twin's");
  for (int p = 0; p < kPoints; ++p) {
    EXPECT_EQ(commit[p].tangent.has_value(), want_tangent) << "point " << p;
    EXPECT_TRUE(commit[p].fabric_defined) << "point " << p;
    EXPECT_GT(commit[p].void_ratio, 0.0) << "point " << p;
  }
  EXPECT_EQ(tried.evaluations(), twin.evaluations());
  EXPECT_EQ(tried.trial_stats().increments, 2 * kPoints);
  EXPECT_EQ(twin.trial_stats().increments, 0);
  const std::vector<RveRecord> a = ExportOrDie(tried);
  ExpectSameRecords(a, ExportOrDie(twin));
  EXPECT_EQ(a[0].step, 2);
  ExpectSameStates(ApplyOrDie(tried, 3), ApplyOrDie(twin, 3), "step 3");
}

TEST(RvePoolTrialTest, CommitAfterTrialsMatchesTheTrialAndATwinEmbedded) {
  for (bool want_tangent : {false, true}) {
    RvePool tried(EmbeddedEndpoints(2), kRun);
    RvePool twin(EmbeddedEndpoints(2), kRun);
    ExpectCommitAfterTrialsMatches(tried, twin, want_tangent,
                                   absl::StrCat("embedded, want_tangent ", want_tangent));
  }
}

TEST(RvePoolTrialTest, CommitAfterTrialsMatchesTheTrialAndATwinRemote) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  // Two runs on the same servers.
  RvePool tried(RemoteEndpoints(servers), "tried-run");
  RvePool twin(RemoteEndpoints(servers), "twin-run");
  ExpectCommitAfterTrialsMatches(tried, twin, /*want_tangent=*/true, "remote");
}

TEST(RvePoolTrialTest, TrialOverTwoRemoteServersEqualsTheEmbeddedPool) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RvePool embedded(EmbeddedEndpoints(1), kRun);
  RvePool remote(RemoteEndpoints(servers), kRun);
  Start(embedded);
  Start(remote);
  EXPECT_EQ(remote.assignment(), (std::vector<int>{0, 1, 0, 1, 0, 1}));
  for (std::int64_t step = 1; step <= 2; ++step) {
    for (bool want_tangent : {true, false}) {
      const std::string where = absl::StrCat("step ", step, ", want_tangent ", want_tangent);
      const std::vector<dem::RveState> a = TrialOrDie(embedded, step, Iterate(step), want_tangent);
      const std::vector<dem::RveState> b = TrialOrDie(remote, step, Iterate(step), want_tangent);
      ASSERT_EQ(a.size(), static_cast<std::size_t>(kPoints)) << where;
      ExpectSameStates(a, b, where);
      EXPECT_EQ(b[5].tangent.has_value(), want_tangent) << where;
    }
    ExpectSameStates(ApplyOrDie(embedded, step), ApplyOrDie(remote, step),
                     absl::StrCat("COMMIT of step ", step));
  }
  EXPECT_GT(remote.last_apply_seconds()[1], 0.0);
  EXPECT_EQ(remote.trial_stats().increments, 4 * kPoints);
  ExpectSameRecords(ExportOrDie(embedded), ExportOrDie(remote));
}

// The registry takes a TRIAL of step S only from RVEs at step S − 1: the
// step just committed (which a COMMIT would answer from memory) and one
// ahead are refused per point; step 0 fails the whole call. Nothing moves.
void ExpectWrongStepsRefused(RvePool& pool, const std::string& label) {
  SCOPED_TRACE(label);
  Start(pool);
  ApplyOrDie(pool, 1);
  const std::vector<RveRecord> before = ExportOrDie(pool);
  ASSERT_EQ(pool.points_of(0).front(), 0);

  absl::StatusOr<std::vector<dem::RveState>> s = pool.Trial(1, DeltaFs(1), false);
  EXPECT_TRUE(absl::IsFailedPrecondition(s.status())) << s.status();
  ExpectContains(s.status().message(), "trial of step 1: " + label + ": material point 0");
  ExpectContains(s.status().message(), "is at step 1; step 1 needs it at step 0");
  // The same ΔF as a COMMIT is a retry, answered from memory.
  EXPECT_TRUE(pool.Apply(1, DeltaFs(1)).ok());

  s = pool.Trial(3, DeltaFs(3), true);
  EXPECT_TRUE(absl::IsFailedPrecondition(s.status())) << s.status();
  ExpectContains(s.status().message(), "trial of step 3: " + label + ": material point 0");
  ExpectContains(s.status().message(), "is at step 1; step 3 needs it at step 2");

  s = pool.Trial(0, DeltaFs(0), false);
  EXPECT_TRUE(absl::IsInvalidArgument(s.status())) << s.status();
  ExpectContains(s.status().message(), "step 0 must be >= 1");

  EXPECT_TRUE(pool.TakeFailed().empty());  // refusals, not losses
  EXPECT_EQ(pool.trial_stats().increments, 0);
  ExpectSameRecords(before, ExportOrDie(pool));
  for (const RveRecord& r : ExportOrDie(pool)) EXPECT_EQ(r.step, 1);
  // The right step still goes.
  EXPECT_EQ(TrialOrDie(pool, 2, DeltaFs(2), false).size(), static_cast<std::size_t>(kPoints));
}

TEST(RvePoolTrialTest, TrialAtAWrongStepIsRefusedPerPointAndChangesNothing) {
  {
    RvePool pool(EmbeddedEndpoints(2), kRun);
    ExpectWrongStepsRefused(pool, "embedded RVE registry");
  }
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RvePool remote(RemoteEndpoints(servers), kRun);
  ExpectWrongStepsRefused(remote, absl::StrCat("RVE server ", servers.address(0)));
}

TEST(RvePoolTrialTest, ATrialWhoseReplyIsLostIsSentAgain) {
  RvePool plain(EmbeddedEndpoints(1), kRun);
  std::vector<std::unique_ptr<RveEndpoint>> e;
  auto faulty = std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()),
                                                 FaultyEndpoint::Fault::kLoseFirstReply);
  FaultyEndpoint* lossy = faulty.get();
  e.push_back(std::move(faulty));
  RvePool retried(std::move(e), kRun, QuickRetries());
  Start(plain);
  Start(retried);
  ExpectSameStates(TrialOrDie(plain, 1, DeltaFs(1), true), TrialOrDie(retried, 1, DeltaFs(1), true),
                   "trial after a lost reply");
  EXPECT_EQ(lossy->apply_calls(), 2);
  EXPECT_EQ(retried.trial_stats().increments, kPoints);  // the lost reply counts nothing
  const std::vector<RveRecord> records = ExportOrDie(retried);
  ExpectSameRecords(ExportOrDie(plain), records);
  for (const RveRecord& r : records) EXPECT_EQ(r.step, 0);  // neither attempt committed
  ExpectSameStates(ApplyOrDie(plain, 1), ApplyOrDie(retried, 1), "step 1");

  // A server that stays away is given up on, and reported.
  std::vector<std::unique_ptr<RveEndpoint>> d;
  auto down = std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()),
                                               FaultyEndpoint::Fault::kAlwaysUnavailable);
  FaultyEndpoint* dead = down.get();
  d.push_back(std::move(down));
  RvePool pool(std::move(d), kRun, QuickRetries());
  Start(pool);
  absl::StatusOr<std::vector<dem::RveState>> s = pool.Trial(1, DeltaFs(1), false);
  EXPECT_TRUE(absl::IsUnavailable(s.status())) << s.status();
  ExpectContains(s.status().message(), "trial of step 1: faulty endpoint");
  ExpectContains(s.status().message(), "gave up after 4 attempts");
  EXPECT_EQ(dead->apply_calls(), 4);
  EXPECT_EQ(pool.TakeFailed(), std::vector<int>{0});
}

}  // namespace
}  // namespace rvehub::client::pool_test
