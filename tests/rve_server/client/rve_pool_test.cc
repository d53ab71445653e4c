// The RVE pool over embedded and remote endpoints: bit-identical results
// whatever the endpoints, cost balancing, retries of lost replies, errors
// naming the endpoint and point, and export/import onto another set of
// endpoints.
#include "rve_server/client/rve_pool.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/embedded/endpoint.h"
#include "rve_server/service/log.h"
#include "rve_server/service/server.h"
#include "tests/rve_server/client/rve_pool_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::client::pool_test {
namespace {

TEST(RvePoolTest, EmbeddedAndRemotePoolsAgreeBitForBit) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RvePool embedded(EmbeddedEndpoints(1), kRun);
  RvePool remote(RemoteEndpoints(servers), kRun);
  EXPECT_EQ(remote.endpoint(1).name(), servers.address(1));
  EXPECT_EQ(embedded.endpoint(0).name(), "embedded");
  Start(embedded);
  Start(remote);
  // Equal costs alternate: points 0, 2, 4 on the first server, 1, 3, 5 on
  // the second (each with both templates).
  EXPECT_EQ(remote.assignment(), (std::vector<int>{0, 1, 0, 1, 0, 1}));

  for (std::int64_t step = 1; step <= 5; ++step) {
    if (step == 5) {  // tangents cross the wire too
      dem::ApplyOptions o;
      o.want_tangent = true;
      embedded.set_apply_options(o);
      remote.set_apply_options(o);
    }
    const std::vector<dem::RveState> a = ApplyOrDie(embedded, step);
    const std::vector<dem::RveState> b = ApplyOrDie(remote, step);
    ASSERT_EQ(a.size(), static_cast<std::size_t>(kPoints));
    ExpectSameStates(a, b, absl::StrCat("step ", step));
    // Compressed: more compressive σyy (tension +) than the 100 kPa start.
    EXPECT_LT(a[1].stress(1, 1), -100e3);
    if (step == 5) {
      EXPECT_TRUE(b[2].tangent.has_value());
    }
  }
  EXPECT_EQ(embedded.evaluations(), 5 * kPoints);
  EXPECT_EQ(remote.evaluations(), 5 * kPoints);
  ASSERT_EQ(remote.last_apply_seconds().size(), 2u);
  EXPECT_GT(remote.last_apply_seconds()[1], 0.0);
  EXPECT_GE(remote.total_apply_seconds(), remote.last_apply_seconds()[1]);

  absl::StatusOr<std::vector<dem::RveState>> ga = embedded.Get(/*want_tangent=*/true);
  absl::StatusOr<std::vector<dem::RveState>> gb = remote.Get(/*want_tangent=*/true);
  ASSERT_TRUE(ga.ok()) << ga.status();
  ASSERT_TRUE(gb.ok()) << gb.status();
  ExpectSameStates(*ga, *gb, "Get");

  absl::StatusOr<std::vector<RveRecord>> ea = embedded.ExportAll();
  absl::StatusOr<std::vector<RveRecord>> eb = remote.ExportAll();
  ASSERT_TRUE(ea.ok()) << ea.status();
  ASSERT_TRUE(eb.ok()) << eb.status();
  ExpectSameRecords(*ea, *eb);
  EXPECT_EQ((*eb)[3].step, 5);

  ASSERT_TRUE(remote.DropAll().ok());
  absl::StatusOr<std::vector<dem::RveState>> gone = remote.Get(false);
  EXPECT_TRUE(absl::IsNotFound(gone.status())) << gone.status();
  EXPECT_TRUE(remote.DropAll().ok());  // nothing left to drop is fine
}

TEST(RvePoolTest, GeostaticStartsInSmallMessagesAgreeBitForBit) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RemoteOptions small;
  small.max_batch = 2;  // 3 points per server: two messages per call
  RvePool embedded(EmbeddedEndpoints(1), kRun);
  RvePool remote(RemoteEndpoints(servers, small), kRun);
  // One initial stress per point: isotropic or K0 with depth.
  std::vector<InitialStress> initial(kPoints);
  for (int p = 0; p < kPoints; ++p) {
    if (p % 2 == 0) {
      initial[p].kind = InitialStress::Kind::kIsotropic;
      initial[p].pressure = 100e3 * (1 + 0.02 * p);
    } else {
      initial[p].kind = InitialStress::Kind::kK0;
      initial[p].vertical_compression = 100e3 * (1 + 0.02 * p);
      initial[p].k0 = 0.9;
    }
  }
  std::vector<TemplateRecord> templates = Templates();
  const std::vector<std::string> names = TemplatePerPoint();
  for (RvePool* pool : {&embedded, &remote}) ASSERT_TRUE(pool->UploadTemplates(templates).ok());
  absl::StatusOr<std::vector<dem::RveState>> a = embedded.Create(names, initial);
  absl::StatusOr<std::vector<dem::RveState>> b = remote.Create(names, initial);
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(b.ok()) << b.status();
  ExpectSameStates(*a, *b, "created");
  EXPECT_NEAR((*a)[4].MeanPressure(), 108e3, 108e3 * 0.05);
  ExpectSameStates(ApplyOrDie(embedded, 1), ApplyOrDie(remote, 1), "step 1");
  absl::StatusOr<std::vector<dem::RveState>> ga = embedded.Get(false);
  absl::StatusOr<std::vector<dem::RveState>> gb = remote.Get(false);
  ASSERT_TRUE(ga.ok() && gb.ok());
  ExpectSameStates(*ga, *gb, "Get");
}

TEST(RvePoolTest, AssignmentIsGreedyLongestProcessingTime) {
  RvePool two(EmbeddedEndpoints(2), kRun);
  const std::vector<double> cost = {5, 4, 3, 3, 3};
  two.Assign(cost);
  // 5 → 0; 4 → 1; 3 (point 2) → 1 (load 4 < 5); 3 (point 3) → 0 (5 < 7);
  // 3 (point 4) → 1 (7 < 8). Loads 8 and 10.
  EXPECT_EQ(two.assignment(), (std::vector<int>{0, 1, 1, 0, 1}));
  EXPECT_EQ(std::vector<std::int64_t>(two.points_of(1).begin(), two.points_of(1).end()),
            (std::vector<std::int64_t>{1, 2, 4}));

  // Ties by point index, then by endpoint index.
  RvePool three(EmbeddedEndpoints(3), kRun);
  three.Assign(std::vector<double>{1, 2, 2, 1, 1, 0.5});
  // Order: 1, 2 (cost 2), 0, 3, 4 (cost 1), 5 → endpoints 0, 1, 2, 2, 0, 1.
  EXPECT_EQ(three.assignment(), (std::vector<int>{2, 0, 1, 2, 0, 1}));

  EXPECT_TRUE(absl::IsInvalidArgument(two.SetAssignment({0, 2})));
  EXPECT_EQ(two.assignment(), (std::vector<int>{0, 1, 1, 0, 1}));  // unchanged
  // Costs that are not finite and >= 0 count as 0: point 2 → 0, then points
  // 0 and 1 both to endpoint 1 (its load stays 0).
  two.Assign(std::vector<double>{-1, NAN, 2});
  EXPECT_EQ(two.assignment(), (std::vector<int>{1, 1, 0}));
  ASSERT_TRUE(two.SetAssignment({1, 1, 0}).ok());
  EXPECT_EQ(two.num_points(), 3);
}

TEST(RvePoolTest, RetriesALostReplyButNotABadRequest) {
  RvePool plain(EmbeddedEndpoints(1), kRun);
  std::vector<std::unique_ptr<RveEndpoint>> faulty_endpoints;
  auto faulty = std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()),
                                                 FaultyEndpoint::Fault::kLoseFirstReply);
  FaultyEndpoint* lossy = faulty.get();
  faulty_endpoints.push_back(std::move(faulty));
  RvePool retried(std::move(faulty_endpoints), kRun, QuickRetries());
  Start(plain);
  Start(retried);
  for (std::int64_t step = 1; step <= 2; ++step)
    ExpectSameStates(ApplyOrDie(plain, step), ApplyOrDie(retried, step), "after a lost reply");
  EXPECT_EQ(lossy->apply_calls(), 3);  // step 1 twice, step 2 once
  EXPECT_EQ(retried.evaluations(), 2 * kPoints);

  // A refused request is final; a server that stays away is given up on.
  for (auto [fault, code, calls] :
       {std::tuple{FaultyEndpoint::Fault::kRefuse, absl::StatusCode::kInvalidArgument, 1},
        std::tuple{FaultyEndpoint::Fault::kAlwaysUnavailable, absl::StatusCode::kUnavailable, 4}}) {
    std::vector<std::unique_ptr<RveEndpoint>> e;
    auto f = std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()), fault);
    FaultyEndpoint* raw = f.get();
    e.push_back(std::move(f));
    RvePool pool(std::move(e), kRun, QuickRetries());
    Start(pool);
    absl::StatusOr<std::vector<dem::RveState>> s = pool.Apply(1, DeltaFs(1));
    EXPECT_EQ(s.status().code(), code) << s.status();
    ExpectContains(s.status().message(), "faulty endpoint");
    EXPECT_EQ(raw->apply_calls(), calls);
  }
}

// What a client needs to survive a lost server: the endpoint that gave up
// is reported (a refusal is not a loss), gets no points once marked lost,
// and the RVEs restored from an earlier export onto the others continue
// bit-identically.
TEST(RvePoolTest, AnEndpointThatGaveUpIsReportedAndTheRunRestoredOnTheOthers) {
  RvePool reference(EmbeddedEndpoints(1), kRun);
  Start(reference);
  std::vector<std::unique_ptr<RveEndpoint>> e = EmbeddedEndpoints(1);
  auto faulty = std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()),
                                                 FaultyEndpoint::Fault::kAlwaysUnavailable);
  FaultyEndpoint* dead = faulty.get();
  e.push_back(std::move(faulty));
  e.push_back(embedded::MakeEndpoint(NewRegistry()));
  PoolOptions o = QuickRetries();
  o.max_attempts = 2;
  RvePool pool(std::move(e), kRun, o);
  Start(pool);
  ASSERT_EQ(pool.points_of(1).size(), 2u);
  absl::StatusOr<std::vector<RveRecord>> at0 = pool.ExportAll();
  ASSERT_TRUE(at0.ok()) << at0.status();
  EXPECT_TRUE(pool.TakeFailed().empty());

  absl::StatusOr<std::vector<dem::RveState>> failed = pool.Apply(1, DeltaFs(1));
  EXPECT_TRUE(absl::IsUnavailable(failed.status())) << failed.status();
  EXPECT_EQ(pool.TakeFailed(), std::vector<int>{1});
  EXPECT_TRUE(pool.TakeFailed().empty());  // taken
  EXPECT_EQ(dead->apply_calls(), 2);

  pool.MarkLost(1);
  EXPECT_EQ(pool.num_alive(), 2);
  EXPECT_TRUE(absl::IsInvalidArgument(pool.SetAssignment({0, 1, 2, 0, 1, 2})));
  pool.Assign(std::vector<double>(kPoints, 1.0));
  EXPECT_TRUE(pool.points_of(1).empty());
  EXPECT_EQ(pool.points_of(0).size() + pool.points_of(2).size(), static_cast<std::size_t>(kPoints));
  // Endpoints 0 and 2 hold RVEs at step 0 or 1: all go back to step 0.
  ASSERT_TRUE(pool.Restore(*at0).ok());
  for (std::int64_t step = 1; step <= 3; ++step) {
    ExpectSameStates(ApplyOrDie(reference, step), ApplyOrDie(pool, step),
                     absl::StrCat("restored, step ", step));
  }
  EXPECT_EQ(dead->apply_calls(), 2);  // never asked again
  EXPECT_TRUE(pool.TakeFailed().empty());

  // A refusal is final but no loss.
  std::vector<std::unique_ptr<RveEndpoint>> r;
  r.push_back(std::make_unique<FaultyEndpoint>(embedded::MakeEndpoint(NewRegistry()),
                                               FaultyEndpoint::Fault::kRefuse));
  RvePool refusing(std::move(r), kRun, QuickRetries());
  Start(refusing);
  EXPECT_TRUE(absl::IsInvalidArgument(refusing.Apply(1, DeltaFs(1)).status()));
  EXPECT_TRUE(refusing.TakeFailed().empty());
}

TEST(RvePoolTest, MigrationMovesRvesBetweenEndpointsBitIdentically) {
  RvePool reference(EmbeddedEndpoints(1), kRun);
  RvePool pool(EmbeddedEndpoints(3), kRun);
  Start(reference);
  Start(pool);
  ExpectSameStates(ApplyOrDie(reference, 1), ApplyOrDie(pool, 1), "step 1");
  absl::StatusOr<std::vector<RveRecord>> records = pool.ExportAll();
  ASSERT_TRUE(records.ok()) << records.status();
  const std::vector<int> before = pool.assignment();

  // Records that do not match the points are refused, nothing moved.
  std::vector<RveRecord> shuffled = *records;
  std::swap(shuffled[0], shuffled[1]);
  EXPECT_TRUE(absl::IsInvalidArgument(pool.Migrate({2, 2, 2, 2, 2, 2}, shuffled)));
  EXPECT_EQ(pool.assignment(), before);

  const std::vector<int> plan = {2, 2, 2, 0, 0, 1};
  ASSERT_TRUE(pool.Migrate(plan, *records).ok());
  EXPECT_EQ(pool.assignment(), plan);
  // Moved RVEs left their old endpoints: point 0 was on endpoint 0.
  ASSERT_EQ(before[0], 0);
  const std::int64_t moved = 0;
  absl::StatusOr<std::vector<RveOutcome>> gone =
      pool.endpoint(0).Get(kRun, std::span<const std::int64_t>(&moved, 1), false);
  ASSERT_TRUE(gone.ok()) << gone.status();
  EXPECT_TRUE(absl::IsNotFound((*gone)[0].status)) << (*gone)[0].status;
  for (std::int64_t step = 2; step <= 3; ++step) {
    ExpectSameStates(ApplyOrDie(reference, step), ApplyOrDie(pool, step),
                     absl::StrCat("migrated, step ", step));
  }
}

TEST(RvePoolTest, UnreachableServerIsUnavailableNamingTheAddress) {
  const std::string address = absl::StrCat("127.0.0.1:", ClosedPort());
  RemoteOptions remote;
  remote.connect_timeout = absl::Seconds(2);
  absl::StatusOr<std::unique_ptr<RveEndpoint>> e = RemoteServer::Connect(address, {}, remote);
  ASSERT_FALSE(e.ok());
  EXPECT_TRUE(absl::IsUnavailable(e.status())) << e.status();
  ExpectContains(e.status().message(), absl::StrCat("RVE server ", address, " is unreachable"));
}

TEST(RvePoolTest, ErrorsNameTheEndpointAndThePoint) {
  Servers servers(2);
  ASSERT_EQ(servers.size(), 2);
  RvePool remote(RemoteEndpoints(servers), kRun);
  Start(remote);
  // Point 3 (on the second server) stretched beyond the controls' 0.05: the
  // engine refuses that RVE alone.
  std::vector<Eigen::Matrix3d> f = DeltaFs(1);
  f[3](0, 0) = 1.1;
  absl::StatusOr<std::vector<dem::RveState>> s = remote.Apply(1, f);
  EXPECT_TRUE(absl::IsInvalidArgument(s.status())) << s.status();
  const std::string message(s.status().message());
  ExpectContains(message, absl::StrCat("RVE server ", servers.address(1)));
  ExpectContains(message, "material point 3");
  ExpectContains(message, "step 1");

  // det ΔF ≤ 0 for point 2 (first server): the whole call is refused.
  f = DeltaFs(1);
  f[2](1, 1) = -1;
  s = remote.Apply(1, f);
  EXPECT_TRUE(absl::IsInvalidArgument(s.status())) << s.status();
  ExpectContains(s.status().message(),
                 (absl::StrCat("RVE server ", servers.address(0), ": material point 2")));

  // Too few ΔF, and a pool with no points.
  EXPECT_TRUE(absl::IsInvalidArgument(
      remote.Apply(2, std::vector<Eigen::Matrix3d>(2, Eigen::Matrix3d::Identity())).status()));
  RvePool empty(EmbeddedEndpoints(1), kRun);
  EXPECT_TRUE(absl::IsFailedPrecondition(empty.Apply(1, {}).status()));
}

TEST(RvePoolTest, ExportImportOntoOtherEndpointsContinuesBitIdentically) {
  Servers servers(1);
  ASSERT_EQ(servers.size(), 1);
  RvePool original(EmbeddedEndpoints(2), kRun);
  Start(original);
  for (std::int64_t step = 1; step <= 3; ++step) ApplyOrDie(original, step);
  absl::StatusOr<std::vector<RveRecord>> saved = original.ExportAll();
  ASSERT_TRUE(saved.ok()) << saved.status();
  ASSERT_EQ(saved->size(), static_cast<std::size_t>(kPoints));

  // Three endpoints, one remote, uneven costs, another run id.
  std::vector<std::unique_ptr<RveEndpoint>> endpoints = EmbeddedEndpoints(2);
  endpoints.push_back(Remote(servers.address(0)));
  RvePool resumed(std::move(endpoints), "resumed-run");
  resumed.Assign(std::vector<double>{1, 2, 3, 4, 5, 6});
  ASSERT_TRUE(resumed.ImportAll(*saved).ok());
  for (std::int64_t step = 4; step <= 5; ++step) {
    ExpectSameStates(ApplyOrDie(original, step), ApplyOrDie(resumed, step),
                     absl::StrCat("step ", step, " after import"));
  }
  absl::StatusOr<std::vector<RveRecord>> a = original.ExportAll();
  absl::StatusOr<std::vector<RveRecord>> b = resumed.ExportAll();
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(b.ok()) << b.status();
  ExpectSameRecords(*a, *b);
  EXPECT_EQ((*b)[0].run_id, "resumed-run");

  // Importing the same points again: they exist.
  EXPECT_TRUE(absl::IsAlreadyExists(resumed.ImportAll(*saved)));
}

TEST(RvePoolTest, ApplyStatsCountIncrementsAndDemSteps) {
  // Bins of DEM steps per increment: ≤ 1, 2, 3–4, 5–8, …, then above 2048.
  EXPECT_EQ(ApplyStats::Bin(0), 0);
  EXPECT_EQ(ApplyStats::Bin(1), 0);
  EXPECT_EQ(ApplyStats::Bin(2), 1);
  EXPECT_EQ(ApplyStats::Bin(3), 2);
  EXPECT_EQ(ApplyStats::Bin(4), 2);
  EXPECT_EQ(ApplyStats::Bin(5), 3);
  EXPECT_EQ(ApplyStats::Bin(2048), ApplyStats::kBins - 2);
  EXPECT_EQ(ApplyStats::Bin(2049), ApplyStats::kBins - 1);
  EXPECT_EQ(ApplyStats::BinUpper(ApplyStats::kBins - 1), -1);

  RvePool pool(EmbeddedEndpoints(1), kRun);
  Start(pool);
  std::int64_t steps = 0;
  for (std::int64_t step = 1; step <= 3; ++step) {
    for (const dem::RveState& s : ApplyOrDie(pool, step)) steps += s.steps;
  }
  const ApplyStats& st = pool.apply_stats();
  EXPECT_EQ(st.increments, 3 * kPoints);
  EXPECT_EQ(st.dem_steps, steps);
  EXPECT_GE(st.dem_steps, 3 * (4 * 10 + 2 * 12));  // min_steps of the two templates
  std::int64_t binned = 0;
  for (std::int64_t h : st.histogram) binned += h;
  EXPECT_EQ(binned, st.increments);
  // min_steps 10 and 12 both fall in the 9–16 bin (the criterion asks for
  // fewer steps for these ΔF).
  EXPECT_EQ(st.histogram[ApplyStats::Bin(12)], 3 * kPoints);
  EXPECT_GT(st.engine_seconds, 0.0);
  EXPECT_EQ(pool.total_workers(), 1);
}

// Controls given for one template reach its RVEs only, and replace the
// template's own as a whole (the other template keeps min_steps 12).
TEST(RvePoolTest, ControlsPerTemplate) {
  RvePool pool(EmbeddedEndpoints(1), kRun);
  const std::vector<TemplateRecord> templates = Templates();
  ASSERT_TRUE(pool.UploadTemplates(templates).ok());
  dem::Controls quick = templates[0].packing.controls;
  quick.min_steps = 1;
  ASSERT_TRUE(pool.Create(TemplatePerPoint(), {}, {{"set-dense", quick}}).ok());
  // A strain of 1e-8: the quasi-static criterion asks for one DEM step.
  Eigen::Matrix3d tiny = Eigen::Matrix3d::Identity();
  tiny(1, 1) = 1 - 1e-8;
  absl::StatusOr<std::vector<dem::RveState>> s =
      pool.Apply(1, std::vector<Eigen::Matrix3d>(kPoints, tiny));
  ASSERT_TRUE(s.ok()) << s.status();
  for (int p = 0; p < kPoints; ++p) {
    EXPECT_EQ((*s)[p].steps, p % 3 == 0 ? 12 : 1) << "point " << p;
  }
  // The options go with every Apply: a duration of 2 DEM steps caps a
  // strain that the criterion would spread over many (min_steps holds).
  Eigen::Matrix3d big = Eigen::Matrix3d::Identity();
  big(1, 1) = 1 - 1e-2;
  dem::ApplyOptions capped;
  capped.duration = 1.5 * (*s)[1].time_step;  // s, the RVEs' Δt
  pool.set_apply_options(capped);
  s = pool.Apply(2, std::vector<Eigen::Matrix3d>(kPoints, big));
  ASSERT_TRUE(s.ok()) << s.status();
  for (int p = 0; p < kPoints; ++p) {
    EXPECT_EQ((*s)[p].steps, p % 3 == 0 ? 12 : 2) << "point " << p;
  }
}

// Points with the same initial stress share one consolidation: their RVEs
// are identical, and equal to one consolidated on its own.
TEST(RvePoolTest, PointsWithTheSameInitialStressGetIdenticalRves) {
  const std::vector<TemplateRecord> templates = Templates();
  std::vector<InitialStress> initial(kPoints);
  for (int p = 0; p < kPoints; ++p) {
    initial[p].kind = InitialStress::Kind::kIsotropic;
    initial[p].pressure = p % 2 == 0 ? 60e3 : 80e3;
  }
  RvePool pool(EmbeddedEndpoints(1), kRun);
  ASSERT_TRUE(pool.UploadTemplates(templates).ok());
  const std::vector<std::string> one_template(kPoints, "set-dense");
  ASSERT_TRUE(pool.Create(one_template, initial).ok());
  absl::StatusOr<std::vector<RveRecord>> all = pool.ExportAll();
  ASSERT_TRUE(all.ok()) << all.status();

  const std::vector<InitialStress> just_one = {initial[1]};
  RvePool single(EmbeddedEndpoints(1), kRun);
  ASSERT_TRUE(single.UploadTemplates(templates).ok());
  single.Assign(std::vector<double>{1.0});
  const std::vector<std::string> name = {"set-dense"};
  ASSERT_TRUE(single.Create(name, just_one).ok());
  absl::StatusOr<std::vector<RveRecord>> own = single.ExportAll();
  ASSERT_TRUE(own.ok()) << own.status();

  auto same = [](const RveRecord& a, const RveRecord& b) {
    return a.packing.sx == b.packing.sx && a.packing.sy == b.packing.sy &&
           a.packing.cell == b.packing.cell;
  };
  for (int p = 2; p < kPoints; ++p) {
    EXPECT_TRUE(same((*all)[p], (*all)[p % 2])) << "point " << p;
  }
  EXPECT_FALSE(same((*all)[0], (*all)[1]));
  EXPECT_TRUE(same((*all)[1], (*own)[0]));
}

}  // namespace
}  // namespace rvehub::client::pool_test
