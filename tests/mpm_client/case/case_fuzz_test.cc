// Hostile case files (mpm_client/case.h): the shipped cases mutated at
// random, seeded, are read or refused by pointer, never crash, and the
// accepted reduced cases run or stop with an error.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "mpm_client/case/case.h"
#include "mpm_client/core/elastic.h"
#include "mpm_client/core/solver.h"
#include "tests/mpm_client/case/case_test_util.h"
#include "tests/support/env_util.h"

namespace rvehub::mpm::case_test {
namespace {

// Every JSON pointer in `j` (containers and leaves; "" is the root).
void CollectPointers(const Json& j, const Json::json_pointer& at,
                     std::vector<Json::json_pointer>* out) {
  out->push_back(at);
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) CollectPointers(it.value(), at / it.key(), out);
  } else if (j.is_array()) {
    for (std::size_t k = 0; k < j.size(); ++k) CollectPointers(j[k], at / k, out);
  }
}

// The shipped MPM case files in `dir` whose names end with `suffix`, by name
// (fem-*.json are fem_client's).
std::vector<std::pair<std::string, Json>> ShippedCases(const fs::path& dir,
                                                       const std::string& suffix) {
  std::vector<std::pair<std::string, Json>> cases;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (!entry.path().filename().string().ends_with(suffix)) continue;
    if (entry.path().filename().string().starts_with("fem-")) continue;
    std::ifstream in(entry.path());
    cases.emplace_back(entry.path().filename().string(), Json::parse(in));
  }
  std::sort(cases.begin(), cases.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return cases;
}

// One to three random edits of a case (CaseFuzz): delete a field or element,
// add an unknown key, scale a number, or put an absurd value anywhere.
// Returns what was done, for the failure message.
std::string MutateCase(Json& doc, std::mt19937_64& rng) {
  static const std::vector<Json> absurd = {0,
                                           -1,
                                           1,
                                           2147483648.0,
                                           -2147483649.0,
                                           9.3e18,
                                           -9.3e18,
                                           1e308,
                                           -1e308,
                                           1e-308,
                                           -0.0,
                                           std::numeric_limits<std::int64_t>::max(),
                                           std::numeric_limits<std::int64_t>::min(),
                                           "",
                                           "x",
                                           "NaN",
                                           "inf",
                                           true,
                                           nullptr,
                                           Json::array(),
                                           Json::object(),
                                           Json::array({1e308, -1e308}),
                                           Json::array({0, 0, 0}),
                                           Json::array({"a", "b"})};
  auto pick = [&rng](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  const int edits = 1 + static_cast<int>(pick(3));
  std::string what;
  for (int e = 0; e < edits; ++e) {
    std::vector<Json::json_pointer> pointers;
    CollectPointers(doc, Json::json_pointer(), &pointers);
    const Json::json_pointer ptr = pointers[pick(pointers.size())];
    const std::string at = ptr.to_string();
    const int kind = static_cast<int>(pick(8));
    if (kind == 0 && !at.empty()) {  // delete the field or element
      Json& parent = doc[ptr.parent_pointer()];
      if (parent.is_object()) parent.erase(ptr.back());
      if (parent.is_array()) parent.erase(static_cast<std::size_t>(std::stoul(ptr.back())));
      absl::StrAppend(&what, " delete ", at, ";");
    } else if (kind == 1 && doc[ptr].is_object()) {  // an unknown key
      doc[ptr]["unknown_key"] = 1;
      absl::StrAppend(&what, " unknown key in ", at, ";");
    } else if (kind == 2 && doc[ptr].is_number()) {  // a nearby or scaled number
      const double x = doc[ptr].get<double>();
      const double factors[] = {-1.0, 0.5, 2.0, 1e3, 1e-3, 1.0000001};
      doc[ptr] = x * factors[pick(6)];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    } else if (!at.empty()) {
      doc[ptr] = absurd[pick(absurd.size())];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    }
  }
  return what;
}

// Hostile case files: the shipped cases with one to three fields replaced by
// absurd values (huge, tiny, negative, beyond int64, wrong types, empty
// containers), deleted, or joined by an unknown key. ParseCase must either
// accept the result, whose ToJson then parses back to the same spec, or refuse
// it with InvalidArgument naming a JSON pointer ("/..."), never crash; an
// accepted case's regions are then filled with material points, or refused.
// Seeded and sized from the environment like fuzz_test:
//   RVEHUB_CASE_FUZZ_ITERATIONS=100000 RVEHUB_CASE_FUZZ_SEED=7 build/tests/case_fuzz_test
TEST(CaseFuzz, MutatedShippedCasesAreAcceptedOrRefusedByPointer) {
  const std::int64_t iterations = testing_env::EnvInt("RVEHUB_CASE_FUZZ_ITERATIONS", 3000);
  const std::uint64_t seed =
      static_cast<std::uint64_t>(testing_env::EnvInt("RVEHUB_CASE_FUZZ_SEED", 1));
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  const std::vector<std::pair<std::string, Json>> cases = ShippedCases(dir, ".json");
  ASSERT_FALSE(cases.empty());
  std::mt19937_64 rng(seed);
  auto pick = [&rng](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  std::int64_t accepted = 0, filled = 0;
  for (std::int64_t it = 0; it < iterations; ++it) {
    const auto& [name, base] = cases[pick(cases.size())];
    Json doc = base;
    const std::string what = MutateCase(doc, rng);
    SCOPED_TRACE(absl::StrCat("iteration ", it, ", ", name, ":", what));
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), dir.string());
    if (!spec.ok()) {
      ASSERT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument) << spec.status();
      ASSERT_TRUE(MessageStartsWith(spec.status(), "/")) << spec.status();
      continue;
    }
    ++accepted;
    absl::StatusOr<CaseSpec> again = ParseCase(ToJson(*spec), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ASSERT_EQ(ToJson(*again), ToJson(*spec));
    // The accepted case's material points, as a run places them (no RVEs): filled or
    // refused, never a crash. Cases past a million points are left out for memory.
    if (EstimateSize(*spec).points <= 1000000) {
      const absl::StatusOr<MaterialPoints> points =
          FillRegions(*spec, std::vector<double>(spec->regions.size(), 2000.0));
      if (points.ok()) {
        ++filled;
      } else {
        ASSERT_EQ(points.status().code(), absl::StatusCode::kInvalidArgument) << points.status();
      }
    }
  }
  std::printf("case fuzz: %lld mutated cases, %lld accepted, %lld filled with points, seed %llu\n",
              static_cast<long long>(iterations), static_cast<long long>(accepted),
              static_cast<long long>(filled), static_cast<unsigned long long>(seed));
  // Mutations of unused or equivalent fields are accepted; most are refused.
  EXPECT_GT(accepted, 0);
  EXPECT_LT(accepted, iterations);
}

// The run stage of CaseFuzz: mutated reduced cases (cases/*-ci.json) that
// are read and hold at most 5000 points run up to 20 steps with a linear
// elastic stand-in for their RVEs (E = 20 MPa, ν = 0.3, the time step from its
// P-wave modulus at the case's CFL; saturated points' n0 0.2 where the case
// leaves it to the RVEs). Each step ends OK or with an error, never a crash
// (deploy/sanitize.sh runs it under ASan and UBSan); after an OK step every
// point's position and stress are finite. deploy/fuzz_runs.py does the same
// with RVEs, out of CI. Seeded like CaseFuzz:
//   RVEHUB_RUN_FUZZ_ITERATIONS=20000 RVEHUB_RUN_FUZZ_SEED=7 build/tests/case_fuzz_test
TEST(CaseFuzz, AcceptedMutatedCasesRunOrStopWithAnError) {
  const std::int64_t iterations = testing_env::EnvInt("RVEHUB_RUN_FUZZ_ITERATIONS", 3000);
  const std::uint64_t seed =
      static_cast<std::uint64_t>(testing_env::EnvInt("RVEHUB_RUN_FUZZ_SEED", 1));
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  const std::vector<std::pair<std::string, Json>> cases = ShippedCases(dir, "-ci.json");
  ASSERT_FALSE(cases.empty());
  constexpr double kYoungs = 20e6, kPoisson = 0.3;  // Pa, [-]
  std::mt19937_64 rng(seed);
  std::int64_t run = 0, stopped = 0, steps = 0;
  for (std::int64_t it = 0; it < iterations; ++it) {
    const auto& [name, base] = cases[rng() % cases.size()];
    Json doc = base;
    const std::string what = MutateCase(doc, rng);
    SCOPED_TRACE(absl::StrCat("iteration ", it, ", ", name, ":", what));
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), dir.string());
    if (!spec.ok() || EstimateSize(*spec).points > 5000) continue;
    spec->solver.wave_modulus = PWaveModulus(kYoungs, kPoisson);
    absl::StatusOr<MaterialPoints> points =
        FillRegions(*spec, std::vector<double>(spec->regions.size(), 2000.0));
    if (!points.ok()) continue;
    for (double& n0 : points->porosity0) {
      if (!(n0 > 0.0 && n0 < 1.0)) n0 = 0.2;
    }
    const std::size_t n = points->size();
    LinearElasticModel model(kYoungs, kPoisson);
    model.SetStress(std::vector<Eigen::Matrix3d>(n, Eigen::Matrix3d::Zero()));
    absl::StatusOr<std::unique_ptr<Solver>> solver =
        Solver::Create(*spec, *std::move(points), &model);
    if (!solver.ok() || !((*solver)->dt() > 0.0)) continue;
    ++run;
    for (int k = 0; k < 20 && (*solver)->time() < spec->solver.end_time; ++k) {
      if (!(*solver)->Step().ok()) {
        ++stopped;
        break;
      }
      ++steps;
      const MaterialPoints& mp = (*solver)->points();
      for (std::size_t p = 0; p < mp.size(); ++p) {
        ASSERT_TRUE(mp.position[p].allFinite() && mp.stress[p].allFinite())
            << "point " << p << " after step " << (*solver)->step();
      }
    }
  }
  std::printf(
      "run fuzz: %lld mutated cases, %lld run, %lld stopped with an error, %lld steps, "
      "seed %llu\n",
      static_cast<long long>(iterations), static_cast<long long>(run),
      static_cast<long long>(stopped), static_cast<long long>(steps),
      static_cast<unsigned long long>(seed));
  EXPECT_GT(run, 0);
}

}  // namespace
}  // namespace rvehub::mpm::case_test
