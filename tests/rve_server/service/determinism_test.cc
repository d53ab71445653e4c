// Bit-exact determinism of the DEM engine: repeated runs, the thread count
// of the server's worker pool (each RVE on one thread, RVEs sharing no
// state: results are bit-identical whatever the thread count) and restart from a RveSnapshot
// (packing.h: "Restoring it gives a bit-identical continuation"). Doubles are compared bit for bit,
// never with tolerances.
#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
#include "gtest/gtest.h"
#include "rve_server/engine/rve.h"
#include "rve_server/service/registry.h"
#include "rve_server/service/worker_pool.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

using testing_util::CreateOrDie;
using testing_util::ExpectIdenticalPackings;
using testing_util::ExpectIdenticalStates;
using testing_util::Prepared;
using testing_util::SameBits;

// ΔF = [[1, 2e-4], [0, 1 − 1e-4]]: simple shear with axial compression.
Eigen::Matrix3d ShearIncrement(double scale = 1.0) {
  Eigen::Matrix3d df = Eigen::Matrix3d::Identity();
  df(0, 1) = 2e-4 * scale;
  df(1, 1) = 1.0 - 1e-4 * scale;
  return df;
}

// Runs `n` increments of ShearIncrement on `rve`, the last one asking for
// the tangent; returns the states.
std::vector<RveState> RunIncrements(Rve& rve, int n) {
  std::vector<RveState> out;
  for (int k = 0; k < n; ++k) {
    ApplyOptions options;
    options.want_tangent = k + 1 == n;
    absl::StatusOr<RveState> s = rve.Apply(ShearIncrement(), options);
    EXPECT_TRUE(s.ok()) << s.status();
    if (!s.ok()) break;
    out.push_back(*s);
  }
  return out;
}

TEST(DeterminismTest, SameStateAndIncrementsGiveIdenticalResults) {
  Rve a = CreateOrDie(Prepared("SET-dense"));
  Rve b = CreateOrDie(Prepared("SET-dense"));
  const std::vector<RveState> sa = RunIncrements(a, 20);
  const std::vector<RveState> sb = RunIncrements(b, 20);
  ASSERT_EQ(sa.size(), 20u);
  ASSERT_EQ(sb.size(), 20u);
  for (int k = 0; k < 20; ++k) {
    ExpectIdenticalStates(sa[k], sb[k], "increment " + std::to_string(k));
  }
  ExpectIdenticalPackings(a.ToSnapshot(), b.ToSnapshot(), "after 20 increments");
  // The run did something: the sheared state differs from the start, so the
  // comparison above is not between two untouched copies.
  EXPECT_GT(a.ToSnapshot().total_steps, 0);
  EXPECT_NE(sa.back().stress(0, 1), CreateOrDie(Prepared("SET-dense")).Observe().stress(0, 1));
  EXPECT_TRUE(sa.back().tangent.has_value());
}

// ApplyOptions::stress_only: the RVE evolves bit for bit as with full
// increments and reports the same stress, void ratio and permeability; the
// rest of its state is left at zero, and a later full observation (or a full
// increment after stress-only ones) gives what the full path gives. The
// increments turn the cell (ΔF with a spin), as an MPM point's do.
TEST(DeterminismTest, StressOnlyIncrementsEvolveAndMeasureAlike) {
  Rve full = CreateOrDie(Prepared("SET-dense"));
  Rve lean = full;
  ApplyOptions stress_only;
  stress_only.stress_only = true;
  for (int k = 0; k < 8; ++k) {
    Eigen::Matrix3d df = ShearIncrement();
    df(1, 0) = -1e-4;                   // a spin as well as a stretch
    const bool lean_call = k % 4 != 3;  // three stress-only increments, then a full one
    absl::StatusOr<RveState> a = full.Apply(df);
    absl::StatusOr<RveState> b = lean.Apply(df, lean_call ? stress_only : ApplyOptions{});
    ASSERT_TRUE(a.ok()) << a.status();
    ASSERT_TRUE(b.ok()) << b.status();
    const std::string where = "increment " + std::to_string(k);
    EXPECT_TRUE(SameBits(a->stress, b->stress)) << where;
    EXPECT_TRUE(SameBits(a->void_ratio, b->void_ratio)) << where;
    EXPECT_TRUE(SameBits(a->permeability, b->permeability)) << where;
    EXPECT_EQ(a->steps, b->steps) << where;
    if (lean_call) {
      EXPECT_EQ(b->num_contacts, 0) << where;
      EXPECT_FALSE(b->fabric_defined) << where;
      EXPECT_EQ(b->coordination, 0.0) << where;
      EXPECT_EQ(b->kinetic_energy, 0.0) << where;
      // Observed in full afterwards: what the full increment returned
      // (Observe counts no steps).
      RveState observed = lean.Observe();
      observed.steps = a->steps;
      ExpectIdenticalStates(*a, observed, where + ", observed in full");
    } else {
      ExpectIdenticalStates(*a, *b, where);
    }
    ExpectIdenticalPackings(full.ToSnapshot(), lean.ToSnapshot(), where);
  }
  EXPECT_GT(full.Observe().num_contacts, 0);
}

TEST(DeterminismTest, WorkerPoolApplyIsIndependentOfThreadCount) {
  constexpr int kRves = 8;
  constexpr int kRounds = 4;
  std::vector<Rve> one, two;
  for (int k = 0; k < kRves; ++k) {
    one.push_back(CreateOrDie(Prepared("SET-dense")));
    two.push_back(CreateOrDie(Prepared("SET-dense")));
  }
  std::vector<Rve*> ptr_one, ptr_two;
  for (int k = 0; k < kRves; ++k) {
    ptr_one.push_back(&one[k]);
    ptr_two.push_back(&two[k]);
  }
  // A different increment per RVE, so that the RVEs diverge and a mix-up
  // between them (or between their scratch data) would show.
  std::vector<Eigen::Matrix3d> df;
  for (int k = 0; k < kRves; ++k) df.push_back(ShearIncrement(1.0 + 0.5 * k));
  ApplyOptions options;
  options.want_tangent = true;
  // The server's worker pool, the one parallel mechanism in production.
  service::WorkerPool pool_one(1), pool_two(2);
  const auto apply = [&](service::WorkerPool& pool, std::vector<Rve*>& rves) {
    std::vector<absl::StatusOr<RveState>> out(rves.size(), absl::UnknownError("not run"));
    pool.ParallelFor(rves.size(), [&](std::size_t k) { out[k] = rves[k]->Apply(df[k], options); });
    return out;
  };
  for (int round = 0; round < kRounds; ++round) {
    const std::vector<absl::StatusOr<RveState>> r1 = apply(pool_one, ptr_one);
    const std::vector<absl::StatusOr<RveState>> r2 = apply(pool_two, ptr_two);
    for (int k = 0; k < kRves; ++k) {
      ASSERT_TRUE(r1[k].ok()) << r1[k].status();
      ASSERT_TRUE(r2[k].ok()) << r2[k].status();
      ExpectIdenticalStates(*r1[k], *r2[k],
                            "round " + std::to_string(round) + ", RVE " + std::to_string(k));
    }
  }
  for (int k = 0; k < kRves; ++k) {
    ExpectIdenticalPackings(one[k].ToSnapshot(), two[k].ToSnapshot(), "RVE " + std::to_string(k));
  }
  // The RVEs did follow their own increments (they differ from each other).
  EXPECT_FALSE(SameBits(one[0].Observe().stress, one[kRves - 1].Observe().stress));
  // A batch result equals the same RVE driven alone by Apply.
  Rve alone = CreateOrDie(Prepared("SET-dense"));
  absl::StatusOr<RveState> last;
  for (int round = 0; round < kRounds; ++round) last = alone.Apply(df[kRves - 1], options);
  ASSERT_TRUE(last.ok()) << last.status();
  ExpectIdenticalPackings(alone.ToSnapshot(), two[kRves - 1].ToSnapshot(), "batch vs alone");
}

// The registry's two ways of returning a batch — collected (Apply) or handed
// to the caller RVE by RVE on the workers (ApplyEach, as the embedded client
// uses it) — give the same bits on one worker and on two, every index once;
// a whole-call error hands out nothing.
TEST(DeterminismTest, RegistryApplyEachMatchesApplyOnAnyThreadCount) {
  constexpr int kRves = 12;
  std::vector<std::int64_t> ids;
  std::vector<service::Increment> batch;
  for (int k = 0; k < kRves; ++k) {
    ids.push_back(100 + 7 * k);
    batch.push_back({ids.back(), ShearIncrement(1.0 + 0.25 * k)});
  }
  auto make = [&](int threads) {
    service::RegistryOptions o;
    o.threads = threads;
    auto r = std::make_unique<service::Registry>(o);
    EXPECT_TRUE(r->PutTemplate({"dense", "", Prepared("SET-dense")}, false).ok());
    EXPECT_TRUE(r->Create("run", "dense", ids, {}, std::nullopt, false).ok());
    return r;
  };
  std::unique_ptr<service::Registry> collected = make(1), each_one = make(1), each_two = make(2);
  ApplyOptions options;
  options.want_tangent = true;
  for (std::int64_t step = 1; step <= 3; ++step) {
    absl::StatusOr<std::vector<service::RveOutcome>> a =
        collected->Apply("run", step, service::ApplyMode::kCommit, options, batch);
    ASSERT_TRUE(a.ok()) << a.status();
    for (service::Registry* r : {each_one.get(), each_two.get()}) {
      std::vector<service::RveOutcome> got(kRves);
      std::vector<int> calls(kRves, 0);
      absl::Mutex mu;
      ASSERT_TRUE(r->ApplyEach("run", step, service::ApplyMode::kCommit, options, batch, {},
                               [&](std::size_t k, service::RveOutcome&& o) {
                                 absl::MutexLock lock(&mu);
                                 ++calls[k];
                                 got[k] = std::move(o);
                               })
                      .ok());
      for (int k = 0; k < kRves; ++k) {
        const std::string where = "step " + std::to_string(step) + ", index " + std::to_string(k);
        ASSERT_EQ(calls[k], 1) << where;
        ASSERT_TRUE(got[k].status.ok()) << got[k].status;
        EXPECT_EQ(got[k].id, ids[k]) << where;
        EXPECT_EQ(got[k].step, step) << where;
        ExpectIdenticalStates((*a)[k].state, got[k].state, where);
      }
    }
  }
  // An unknown id: refused for the whole batch before any outcome.
  std::vector<service::Increment> bad = batch;
  bad.back().id = 99999;
  int handed = 0;
  const absl::Status refused =
      each_two->ApplyEach("run", 4, service::ApplyMode::kCommit, options, bad, {},
                          [&](std::size_t, service::RveOutcome&&) { ++handed; });
  EXPECT_EQ(refused.code(), absl::StatusCode::kNotFound) << refused;
  EXPECT_EQ(handed, 0);
}

TEST(DeterminismTest, RestartFromPackingContinuesBitIdentically) {
  Rve original = CreateOrDie(Prepared("SET-dense"));
  ASSERT_EQ(RunIncrements(original, 10).size(), 10u);
  const RveSnapshot saved = original.ToSnapshot();
  Rve restored = CreateOrDie(saved);
  // The restored RVE holds the same state before it moves on.
  ExpectIdenticalStates(original.Observe(true), restored.Observe(true), "at restart");
  ExpectIdenticalPackings(saved, restored.ToSnapshot(), "round trip");
  const std::vector<RveState> so = RunIncrements(original, 10);
  const std::vector<RveState> sr = RunIncrements(restored, 10);
  ASSERT_EQ(so.size(), 10u);
  ASSERT_EQ(sr.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    ExpectIdenticalStates(so[k], sr[k], "increment " + std::to_string(10 + k));
  }
  ExpectIdenticalPackings(original.ToSnapshot(), restored.ToSnapshot(), "after 20 increments");
  EXPECT_EQ(original.ToSnapshot().total_steps, restored.ToSnapshot().total_steps);
  EXPECT_GT(restored.ToSnapshot().total_steps, saved.total_steps);
}

// A restart mid-shear, while contacts slide at the Coulomb limit and the
// particles move (no relaxation before the save), continued by increments
// that relax: the contact history must carry over exactly.
TEST(DeterminismTest, RestartMidShearWithRelaxContinuesBitIdentically) {
  Rve original = CreateOrDie(Prepared("SET-dense"));
  ApplyOptions options;
  options.relax = true;
  options.relax_tolerance = 1e-3;
  Eigen::Matrix3d big = Eigen::Matrix3d::Identity();
  big(0, 1) = 0.01;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(original.Apply(big).ok());
  Rve restored = CreateOrDie(original.ToSnapshot());
  for (int k = 0; k < 5; ++k) {
    absl::StatusOr<RveState> so = original.Apply(ShearIncrement(10.0), options);
    absl::StatusOr<RveState> sr = restored.Apply(ShearIncrement(10.0), options);
    ASSERT_TRUE(so.ok()) << so.status();
    ASSERT_TRUE(sr.ok()) << sr.status();
    ExpectIdenticalStates(*so, *sr, "increment " + std::to_string(k));
  }
  ExpectIdenticalPackings(original.ToSnapshot(), restored.ToSnapshot(), "after mid-shear restart");
}

// A restart shortly before the periodic cell is reduced (MaybeFlip at
// a·b > 0.55 |a|², i.e. γ ≈ 0.55 for a square cell): the continuation
// crosses the change of lattice basis on both copies at the same step.
TEST(DeterminismTest, RestartBeforeCellFlipContinuesBitIdentically) {
  Rve original = CreateOrDie(Prepared("SET-dense"));
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 0.05;  // |V − I| ≈ 0.035 < Controls::max_stretch
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(original.Apply(shear).ok()) << "increment " << k;
  const auto skew = [](const Rve& rve) {  // a·b / |a|² of the cell
    return rve.cell().col(0).dot(rve.cell().col(1)) / rve.cell().col(0).squaredNorm();
  };
  ASSERT_GT(skew(original), 0.4);   // sheared ...
  ASSERT_LT(skew(original), 0.55);  // ... but not yet reduced
  Rve restored = CreateOrDie(original.ToSnapshot());
  for (int k = 0; k < 4; ++k) {
    absl::StatusOr<RveState> so = original.Apply(shear);
    absl::StatusOr<RveState> sr = restored.Apply(shear);
    ASSERT_TRUE(so.ok()) << so.status();
    ASSERT_TRUE(sr.ok()) << sr.status();
    ExpectIdenticalStates(*so, *sr, "increment " + std::to_string(10 + k));
  }
  // The basis changed: the cell is reduced again (|a·b| ≤ ½|a|²).
  std::printf("cell skew a·b/|a|² after the continuation: %.3f\n", skew(original));
  EXPECT_LT(std::abs(skew(original)), 0.5);
  ExpectIdenticalPackings(original.ToSnapshot(), restored.ToSnapshot(), "after the flip");
}

// Restart of the other contact histories: rolling moments (footing-dense,
// rolling resistance β = 1, η = 0.05, liang-zhao-mpm-dem Table 2) and contact
// bonds (SET-dense cemented with c = 1 MPa, guo-et-al-spfem-dem §2.4), saved
// mid-loading while bonds break under extension and shear.
TEST(DeterminismTest, RestartCarriesRollingMomentsAndBonds) {
  RveSnapshot cemented = Prepared("SET-dense");
  cemented.material.bond_cohesion = 1e6;  // Pa
  for (const auto& [name, start] :
       {std::pair<std::string, RveSnapshot>{"footing-dense", Prepared("footing-dense")},
        {"cemented SET-dense", cemented}}) {
    SCOPED_TRACE(name);
    Rve original = CreateOrDie(start);
    original.BondContacts();  // no-op without cohesion
    Eigen::Matrix3d df = Eigen::Matrix3d::Identity();
    df(0, 1) = 5e-3;
    df(1, 1) = 1.0 + 2e-3;  // extension: some bonds break
    for (int k = 0; k < 5; ++k) ASSERT_TRUE(original.Apply(df).ok()) << "increment " << k;
    const RveSnapshot saved = original.ToSnapshot();
    int moments = 0, bonds = 0;
    for (const ContactHistory& c : saved.contacts) {
      moments += c.rolling_moment != 0.0;
      bonds += c.bond_strength > 0.0;
    }
    std::printf("%s: %zu contact histories, %d rolling moments, %d bonds at the restart\n",
                name.c_str(), saved.contacts.size(), moments, bonds);
    // The histories under test are there (the check is not vacuous).
    EXPECT_EQ(moments > 0, start.material.rolling_beta > 0);
    EXPECT_EQ(bonds > 0, start.material.bond_cohesion > 0);
    Rve restored = CreateOrDie(saved);
    for (int k = 0; k < 10; ++k) {
      absl::StatusOr<RveState> so = original.Apply(ShearIncrement(10.0));
      absl::StatusOr<RveState> sr = restored.Apply(ShearIncrement(10.0));
      ASSERT_TRUE(so.ok()) << so.status();
      ASSERT_TRUE(sr.ok()) << sr.status();
      ExpectIdenticalStates(*so, *sr, "increment " + std::to_string(5 + k));
    }
    ExpectIdenticalPackings(original.ToSnapshot(), restored.ToSnapshot(), "after the restart");
  }
}

}  // namespace
}  // namespace rvehub::dem
