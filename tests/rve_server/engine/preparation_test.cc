// Isotropic preparation of RVE packings (rve_server/engine/prepare.h) against
// the targets of shared/reference/README.md: e0 and p0 of the parameter sets,
// coordination ≈ 4.3 and a nearly isotropic fabric for 400 discs at 100 kPa
// (guo-zhao-2014 §3.2), k = c·e³/(1+e) calibrated to k0 at e0 (two-phase
// paper eq. 28), and a preparation that is a fixed function of the seed.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

using testing_util::ExpectIdenticalPackings;
using testing_util::SameBits;

struct Prepared {
  RveSnapshot packing;
  PreparationReport report;
};

ParameterSet SetWithSeed(const std::string& name, std::uint64_t seed) {
  absl::StatusOr<ParameterSet> set = FindParameterSet(name);
  EXPECT_TRUE(set.ok()) << set.status();
  ParameterSet out = *set;
  out.preparation.seed = seed;
  return out;
}

Prepared PrepareNow(const std::string& name, std::uint64_t seed) {
  Prepared out;
  absl::StatusOr<RveSnapshot> packing = PreparePacking(SetWithSeed(name, seed), {}, &out.report);
  EXPECT_TRUE(packing.ok()) << name << " seed " << seed << ": " << packing.status();
  if (packing.ok()) out.packing = *std::move(packing);
  return out;
}

// Preparing 400 discs takes 1–2 s: each (set, seed) is prepared once per
// process and shared by the tests below.
const Prepared& Cached(const std::string& name, std::uint64_t seed) {
  static auto* cache = new std::map<std::pair<std::string, std::uint64_t>, Prepared>();
  auto key = std::pair(name, seed);
  auto it = cache->find(key);
  if (it == cache->end()) it = cache->emplace(key, PrepareNow(name, seed)).first;
  return it->second;
}

RveState ObserveOf(const RveSnapshot& packing) {
  absl::StatusOr<Rve> rve = Rve::Create(packing);
  EXPECT_TRUE(rve.ok()) << rve.status();
  return rve.ok() ? rve->Observe() : RveState{};
}

double Pressure(const RveState& s) { return -0.5 * s.stress.trace(); }  // Pa, compression +

// SET-dense (liang-zhao-mpm-dem Table 1): e0 = 0.177 at p0 = 100 kPa.
TEST(PreparationTest, SetDenseMeetsPublishedTargets) {
  const Prepared& prep = Cached("SET-dense", 1);
  const RveState s = ObserveOf(prep.packing);
  std::printf("SET-dense seed 1: e0 = %.5f, p0 = %.1f Pa, Z = %.3f, Fa = %.4f, unbalanced %.2e\n",
              s.void_ratio, Pressure(s), s.coordination, s.fabric_anisotropy,
              s.unbalanced_force_ratio);
  // The compaction friction is steered over a few trials only, and e(μ) is
  // noisy for 400 discs: 0.01 on e0 (≈ 6 %) is what the steering can promise.
  EXPECT_NEAR(s.void_ratio, 0.177, 0.01);
  // Preparation stops once p is within 1 % of p0 (prepare.h).
  EXPECT_NEAR(Pressure(s), 100e3, 0.01 * 100e3);
  // guo-zhao-2014 §3.2: Z ≈ 4.3 for 400 discs at 100 kPa; ±0.5 allows for the
  // dense-versus-loose spread between packings.
  EXPECT_GT(s.coordination, 3.8);
  EXPECT_LT(s.coordination, 4.8);
  // "Fabric nearly isotropic" (guo-zhao-2014 §3.2): Fa well below the values
  // of ~0.3–0.5 reached in shear.
  EXPECT_TRUE(s.fabric_defined);
  EXPECT_LT(s.fabric_anisotropy, 0.1);
  // The final stabilisation runs to an unbalanced-force ratio < 1e-4 (prepare.h).
  EXPECT_LT(s.unbalanced_force_ratio, 1e-4);
  // The deviator is also held within 1 % of p0 (prepare.cc).
  EXPECT_LT(0.5 * std::abs(s.stress(0, 0) - s.stress(1, 1)), 0.01 * 100e3);
}

// ENGINE BUG (disabled until fixed in prepare.cc): prepare.h promises that
// preparation repeats "while relaxing moved p or the deviator out of 1 % of
// p", but ConsolidateIsotropic measures the deviator as ½|σxx − σyy| only
// and leaves the shear component uncontrolled (xy is held at zero strain
// rate), so the prepared packing keeps the shear stress it happened to lock
// in: q = sqrt(¼(σxx − σyy)² + σxy²) (shared/reference: q = sqrt(½ s:s)) is
// 3.1 % of p for SET-dense seed 1 (σxy = 3.1 kPa), 6.1 % for consolidation
// seed 1 and up to 7 % for cyclic-loose seed 2.
TEST(PreparationTest, PreparedStressIsIsotropicIncludingShear) {
  for (const char* name : {"SET-dense", "consolidation"}) {
    SCOPED_TRACE(name);
    const RveState s = ObserveOf(Cached(name, 1).packing);
    const double half_diff = 0.5 * (s.stress(0, 0) - s.stress(1, 1));
    const double q = std::hypot(half_diff, s.stress(0, 1));
    std::printf("%s: p = %.1f Pa, ½(σxx − σyy) = %.1f Pa, σxy = %.1f Pa, q/p = %.4f\n", name,
                Pressure(s), half_diff, s.stress(0, 1), q / Pressure(s));
    // The 1 % of p that preparation promises for the deviator (prepare.h).
    EXPECT_LT(q, 0.01 * Pressure(s));
  }
}

TEST(PreparationTest, PermeabilityAtE0IsInitialPermeability) {
  const Prepared& prep = Cached("SET-dense", 1);
  const RveState s = ObserveOf(prep.packing);
  EXPECT_EQ(prep.packing.initial_void_ratio, s.void_ratio);
  // k = c·e³/(1+e) with c = k0 (1+e0)/e0³: equal to k0 = 1e-3 m/s up to a few
  // rounding errors (1e-12 relative).
  EXPECT_NEAR(s.permeability, 1e-3, 1e-12 * 1e-3);
  // And it follows the Kozeny–Carman-like law away from e0.
  const double c = prep.packing.permeability_coefficient;
  const double e0 = s.void_ratio;
  EXPECT_NEAR(c, 1e-3 * (1 + e0) / (e0 * e0 * e0), 1e-12 * c);
}

TEST(PreparationTest, SameSeedGivesBitIdenticalPacking) {
  const Prepared& first = Cached("SET-dense", 1);
  const Prepared second = PrepareNow("SET-dense", 1);
  ExpectIdenticalPackings(first.packing, second.packing);
  EXPECT_EQ(first.report.trials, second.report.trials);
  EXPECT_EQ(first.report.steps, second.report.steps);
  EXPECT_TRUE(SameBits(first.report.compaction_friction, second.report.compaction_friction));
  EXPECT_TRUE(SameBits(first.report.pressure, second.report.pressure));
}

TEST(PreparationTest, DifferentSeedGivesDifferentPackingNearTheSameE0) {
  const Prepared& one = Cached("SET-dense", 1);
  const Prepared& two = Cached("SET-dense", 2);
  ASSERT_EQ(one.packing.radius.size(), two.packing.radius.size());
  EXPECT_NE(one.packing.radius, two.packing.radius);
  EXPECT_NE(one.packing.sx, two.packing.sx);
  const RveState s = ObserveOf(two.packing);
  std::printf("SET-dense seed 2: e0 = %.5f, p0 = %.1f Pa, Z = %.3f\n", s.void_ratio, Pressure(s),
              s.coordination);
  // Same steering tolerance as for seed 1.
  EXPECT_NEAR(s.void_ratio, 0.177, 0.01);
  EXPECT_NEAR(Pressure(s), 100e3, 0.01 * 100e3);
}

// consolidation (liang-zhao-wu-soga Table 1): porosity n = 0.161, i.e.
// e0 = 0.161/0.839 = 0.1919, at 100 kPa.
TEST(PreparationTest, ConsolidationSetReachesItsPorosity) {
  const Prepared& prep = Cached("consolidation", 1);
  const RveState s = ObserveOf(prep.packing);
  std::printf("consolidation seed 1: e0 = %.5f (target %.5f), n = %.4f, p0 = %.1f Pa\n",
              s.void_ratio, 0.161 / 0.839, s.porosity, Pressure(s));
  // Same steering tolerance as SET-dense.
  EXPECT_NEAR(s.void_ratio, 0.161 / 0.839, 0.01);
  EXPECT_NEAR(Pressure(s), 100e3, 0.01 * 100e3);
  EXPECT_LT(s.unbalanced_force_ratio, 1e-4);
}

// PrepareTemplate's void ratio: the set's material packed to another e0
// (saturated-medium, 0.23, packed to 0.25 at 20 kPa, the looser state of the
// saturated-loose collapse), within the steering's tolerance; outside (0, 1)
// it is refused before any work.
TEST(PreparationTest, TemplatePackedToAnotherVoidRatio) {
  PreparationReport report;
  absl::StatusOr<RveSnapshot> loose =
      PrepareTemplate("saturated-medium", 1, {.pressure = 20e3, .void_ratio = 0.25}, &report);
  ASSERT_TRUE(loose.ok()) << loose.status();
  const RveState s = ObserveOf(*loose);
  std::printf("saturated-medium packed to e0 = 0.25 at 20 kPa: e0 = %.4f, Z = %.2f\n", s.void_ratio,
              s.coordination);
  EXPECT_NEAR(s.void_ratio, 0.25, 0.003);
  EXPECT_NEAR(Pressure(s), 20e3, 0.01 * 20e3);
  EXPECT_EQ(loose->initial_void_ratio, s.void_ratio);
  for (double e : {-0.1, 1.0, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_EQ(
        PrepareTemplate("saturated-medium", 1, {.pressure = 20e3, .void_ratio = e}).status().code(),
        absl::StatusCode::kInvalidArgument)
        << e;
  }
}

// A target the preparation cannot pack to is refused, naming the bound it
// met, instead of giving (and naming for the target) another packing: below
// the frictionless compaction's e, or above the one at the material's
// friction. 100 discs keep it short.
TEST(PreparationTest, TemplateVoidRatioOutOfReachIsRefusedNamingTheBound) {
  for (const auto& [e, bound] :
       std::vector<std::pair<double, std::string>>{{0.05, "the densest"}, {0.9, "the loosest"}}) {
    const absl::Status s =
        PrepareTemplate("SET-dense", 1, {.void_ratio = e, .num_particles = 100}).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
    EXPECT_TRUE(absl::StrContains(
        s.message(), absl::StrCat("target void ratio ", e, " is out of reach: ", bound,
                                  " SET-dense packs at 100000 Pa (seed 1, 100 discs), compacted ")))
        << s;
  }
}

// PrepareTemplate's particle count: a larger or smaller sample of the same
// material (100 discs keep the test short), at the set's pressure within the
// preparation's 1 %; a count outside [2, kMaxParticles] is refused before any
// work.
TEST(PreparationTest, TemplateWithAnotherParticleCount) {
  PreparationReport report;
  absl::StatusOr<RveSnapshot> small =
      PrepareTemplate("SET-dense", 1, {.num_particles = 100}, &report);
  ASSERT_TRUE(small.ok()) << small.status();
  EXPECT_EQ(small->radius.size(), 100u);
  EXPECT_NEAR(Pressure(ObserveOf(*small)), 100e3, 0.01 * 100e3);
  for (int n : {-5, 1, static_cast<int>(kMaxParticles) + 1}) {
    EXPECT_EQ(PrepareTemplate("SET-dense", 1, {.num_particles = n}).status().code(),
              absl::StatusCode::kInvalidArgument)
        << n;
  }
}

// The default name of a prepared packing says what was asked for, in a
// template name's alphabet ([A-Za-z0-9._-]) at any pressure.
TEST(PreparationTest, TemplateNameCarriesWhatWasAskedForInTheNameAlphabet) {
  EXPECT_EQ(TemplateName("SET-dense", 1, {}), "SET-dense-seed1");
  EXPECT_EQ(
      TemplateName("SET-dense", 2, {.pressure = 20e3, .void_ratio = 0.25, .num_particles = 100}),
      "SET-dense-seed2-p20000Pa-e0.25-100discs");
  EXPECT_EQ(TemplateName("SET-dense", 1, {.pressure = 2e6, .void_ratio = 1e-5}),
            "SET-dense-seed1-p2e06Pa-e1e-05");
  EXPECT_EQ(TemplateName("footing-dense", 3, {.rolling_eta = 0.02}), "footing-dense-seed3-eta0.02");
  EXPECT_EQ(TemplateName("footing-dense", 3, {.rolling_eta = 0.0}), "footing-dense-seed3-eta0");
}

// PrepareTemplate's rolling-resistance η: another material from a set with
// rolling resistance. The packing carries the new η (and the set's β), and
// is another packing than the set's (the compaction sees the moments). An η
// outside [0, kMaxRollingEta], or any η for a set without rolling resistance
// (β = 0, where it would change nothing), is refused before any work.
TEST(PreparationTest, TemplateWithAnotherRollingResistance) {
  PreparationReport report;
  const TemplateVariant small{.num_particles = 100};
  TemplateVariant weaker = small;
  weaker.rolling_eta = 0.02;
  absl::StatusOr<RveSnapshot> set_eta = PrepareTemplate("footing-dense", 1, small);
  absl::StatusOr<RveSnapshot> eta = PrepareTemplate("footing-dense", 1, weaker, &report);
  ASSERT_TRUE(set_eta.ok()) << set_eta.status();
  ASSERT_TRUE(eta.ok()) << eta.status();
  EXPECT_EQ(set_eta->material.rolling_eta, 0.05);
  EXPECT_EQ(eta->material.rolling_eta, 0.02);
  EXPECT_EQ(eta->material.rolling_beta, set_eta->material.rolling_beta);
  EXPECT_EQ(eta->material.friction, set_eta->material.friction);
  EXPECT_NE(eta->sx, set_eta->sx);
  EXPECT_NEAR(Pressure(ObserveOf(*eta)), 100e3, 0.01 * 100e3);
  EXPECT_EQ(report.void_ratio, ObserveOf(*eta).void_ratio);

  for (double bad : {-0.01, kMaxRollingEta * 1.01, std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::quiet_NaN()}) {
    TemplateVariant v = small;
    v.rolling_eta = bad;
    const absl::Status s = PrepareTemplate("footing-dense", 1, v).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_TRUE(absl::StrContains(s.message(), "rolling-resistance η")) << s;
  }
  TemplateVariant no_rolling = small;
  no_rolling.rolling_eta = 0.02;
  const absl::Status s = PrepareTemplate("SET-dense", 1, no_rolling).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(absl::StrContains(s.message(), "SET-dense, which has no rolling resistance")) << s;
}

// A stress the servo cannot reach is a clear refusal, not a deadline a
// client would take for a hung server, and it says why: the tolerance, and
// what the packing holds. 40 loose discs compacted straight to 100 Pa end
// near it (measured: σxx 88, σyy 86, σxy 3.7 Pa on 77 contacts); at 1 Pa
// they unjam into a gas (no contact). About 1 s each.
TEST(PreparationTest, AConsolidationThatCannotConvergeIsAFailedPrecondition) {
  const struct {
    double pressure;
    const char* target;
    const char* tolerance;
    const char* held;
  } kCases[] = {
      {100, "consolidation to σxx = 100 Pa, σyy = 100 Pa did not converge",
       "must come within 1 Pa (1 %)", "the packing holds σxx = "},
      {1, "consolidation to σxx = 1 Pa, σyy = 1 Pa did not converge",
       "must come within 0.01 Pa (1 %)", "the packing lost every contact"},
  };
  for (const auto& c : kCases) {
    const absl::StatusOr<RveSnapshot> packing =
        PrepareTemplate("SET-dense", 1, {.pressure = c.pressure, .num_particles = 40});
    ASSERT_FALSE(packing.ok()) << c.pressure;
    const absl::Status& s = packing.status();
    EXPECT_EQ(s.code(), absl::StatusCode::kFailedPrecondition) << s;
    for (const char* part : {c.target, c.tolerance, c.held, "below about 1 kPa"}) {
      EXPECT_TRUE(absl::StrContains(s.message(), part)) << part << "\n" << s;
    }
  }
}

// A stress the soft contacts cannot carry as a packing is refused, not
// prepared: at 10 MPa SET-dense's discs overlap past its voids (e < 0; the
// permeability coefficient, computed from e, was the first thing to fail).
// 100 discs at 100 kPa, then 10 MPa on that packing as the registry
// consolidates a point to its stress. Measured: e −0.22 at 10 MPa.
TEST(PreparationTest, AStressThatSqueezesThePackingPastEZeroIsRefused) {
  const absl::StatusOr<RveSnapshot> packing =
      PrepareTemplate("SET-dense", 1, {.num_particles = 100});
  ASSERT_TRUE(packing.ok()) << packing.status();
  absl::StatusOr<Rve> rve = Rve::Create(*packing);
  ASSERT_TRUE(rve.ok()) << rve.status();
  const absl::StatusOr<RveState> s = ConsolidateIsotropic(*rve, 10e6);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << s.status();
  EXPECT_TRUE(absl::StrContains(s.status().message(),
                                "consolidation to σxx = 1e+07 Pa, σyy = 1e+07 Pa squeezes the "
                                "discs into each other past any packing (e = -"))
      << s.status();
  const absl::Status prepared =
      PrepareTemplate("SET-dense", 1, {.pressure = 10e6, .num_particles = 100}).status();
  EXPECT_EQ(prepared.code(), absl::StatusCode::kInvalidArgument) << prepared;
  EXPECT_TRUE(absl::StrContains(prepared.message(), "past any packing")) << prepared;
}

// PrepareTemplate's pressure: the set's e0 sought at that pressure. A
// template compacted at 100 kPa and unloaded to 20 kPa swells instead
// (saturated-medium seed 1: e 0.2329 → 0.2432, coordination 3.22 → 2.66),
// which is why a case states where its e0 holds. Tolerances: p within the
// preparation's 1 %, e0 within the steering's 0.01 (as SET-dense).
TEST(PreparationTest, TemplateCompactedAtAGivenPressureKeepsItsVoidRatioThere) {
  PreparationReport report;
  absl::StatusOr<RveSnapshot> low =
      PrepareTemplate("saturated-medium", 1, {.pressure = 20e3}, &report);
  ASSERT_TRUE(low.ok()) << low.status();
  const RveState s = ObserveOf(*low);
  std::printf("saturated-medium at 20 kPa: e0 = %.4f, p = %.0f Pa, Z = %.2f\n", s.void_ratio,
              Pressure(s), s.coordination);
  EXPECT_NEAR(Pressure(s), 20e3, 0.01 * 20e3);
  EXPECT_NEAR(s.void_ratio, 0.23, 0.01);
  EXPECT_EQ(report.void_ratio, s.void_ratio);

  absl::StatusOr<RveSnapshot> high = PrepareTemplate("saturated-medium", 1);
  ASSERT_TRUE(high.ok()) << high.status();
  absl::StatusOr<Rve> unloaded = Rve::Create(*high);
  ASSERT_TRUE(unloaded.ok()) << unloaded.status();
  absl::StatusOr<RveState> at_20 = ConsolidateIsotropic(*unloaded, 20e3);
  ASSERT_TRUE(at_20.ok()) << at_20.status();
  std::printf("saturated-medium at 100 kPa unloaded to 20 kPa: e = %.4f, Z = %.2f\n",
              at_20->void_ratio, at_20->coordination);
  EXPECT_GT(at_20->void_ratio, s.void_ratio + 0.005);

  EXPECT_EQ(PrepareTemplate("saturated-medium", 1, {.pressure = -5.0}).status().code(),
            absl::StatusCode::kInvalidArgument);

  // Unloaded to 2 kPa (a collapse column's top), with the servo stopped once
  // the stress has stayed close for kSettleSteps, as the registry creates
  // material points: balanced and at the stress in 8800 steps (measured),
  // where the servo alone ran to its 600 000-step cap.
  absl::StatusOr<Rve> top = Rve::Create(*low);
  ASSERT_TRUE(top.ok()) << top.status();
  std::int64_t steps = 0;
  absl::StatusOr<RveState> at_2 = ConsolidateIsotropic(*top, 2e3, 1e-4, &steps, {}, kSettleSteps);
  ASSERT_TRUE(at_2.ok()) << at_2.status();
  std::printf("unloaded to 2 kPa in %lld steps: e = %.4f\n", static_cast<long long>(steps),
              at_2->void_ratio);
  EXPECT_NEAR(Pressure(*at_2), 2e3, 0.01 * 2e3);
  EXPECT_LT(at_2->unbalanced_force_ratio, 1e-4);
  EXPECT_LT(steps, 50000);
}

TEST(PreparationTest, ReportAgreesWithPacking) {
  for (const char* name : {"SET-dense", "consolidation"}) {
    SCOPED_TRACE(name);
    const Prepared& prep = Cached(name, 1);
    const RveState s = ObserveOf(prep.packing);
    // The void ratio is a function of the cell and radii only: exact.
    EXPECT_EQ(prep.report.void_ratio, s.void_ratio);
    EXPECT_EQ(prep.report.void_ratio, prep.packing.initial_void_ratio);
    // Observe is pure and sums the same contacts in the same (i, j) order as
    // the final state of the preparation; allow a few rounding errors only.
    EXPECT_NEAR(prep.report.pressure, Pressure(s), 1e-9 * 100e3);
    EXPECT_NEAR(prep.report.coordination, s.coordination, 1e-12);
    EXPECT_GE(prep.report.trials, 1);
    EXPECT_GT(prep.report.steps, 0);
    // The prepared state starts the step and rotation counters afresh.
    EXPECT_EQ(prep.packing.total_steps, 0);
    for (double th : prep.packing.theta) ASSERT_EQ(th, 0.0);
    // The compaction friction lies between frictionless and the material's.
    const ParameterSet set = SetWithSeed(name, 1);
    EXPECT_GE(prep.report.compaction_friction, 0.0);
    EXPECT_LE(prep.report.compaction_friction, set.material.friction);
    // The packing carries the material friction, not the compaction one.
    EXPECT_EQ(prep.packing.material.friction, set.material.friction);
    EXPECT_EQ(static_cast<int>(prep.packing.radius.size()), set.preparation.num_particles);
  }
}

}  // namespace
}  // namespace rvehub::dem
