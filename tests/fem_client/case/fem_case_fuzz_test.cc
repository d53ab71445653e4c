// Hostile fem case files (fem_client/case/case.h): the shipped fem cases
// and the tests' full and shear cases, mutated at random (seeded), are read
// or refused by pointer, never crash, and what is read round-trips.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "fem_client/case/case.h"
#include "gtest/gtest.h"
#include "tests/fem_client/case/fem_case_test_util.h"
#include "tests/support/env_util.h"

namespace rvehub::fem::case_test {
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

// One to three random edits: delete a field or element, add an unknown key,
// scale a number, or put an absurd value anywhere. Returns what was done.
std::string Mutate(Json& doc, std::mt19937_64& rng) {
  static const std::vector<Json> absurd = {0,
                                           -1,
                                           1,
                                           3,
                                           2147483648.0,
                                           9.3e18,
                                           -9.3e18,
                                           1e308,
                                           1e-308,
                                           -0.0,
                                           std::numeric_limits<std::int64_t>::max(),
                                           std::numeric_limits<std::int64_t>::min(),
                                           "",
                                           "x",
                                           "left",
                                           "periodic",
                                           "shear",
                                           "q8",
                                           true,
                                           nullptr,
                                           Json::array(),
                                           Json::object(),
                                           Json::array({0, 0}),
                                           Json::array({1e308, -1e308}),
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
    if (kind == 0 && !at.empty()) {
      Json& parent = doc[ptr.parent_pointer()];
      if (parent.is_object()) parent.erase(ptr.back());
      if (parent.is_array()) parent.erase(static_cast<std::size_t>(std::stoul(ptr.back())));
      absl::StrAppend(&what, " delete ", at, ";");
    } else if (kind == 1 && doc[ptr].is_object()) {
      doc[ptr]["unknown_key"] = 1;
      absl::StrAppend(&what, " unknown key in ", at, ";");
    } else if (kind == 2 && doc[ptr].is_number()) {
      const double factors[] = {-1.0, 0.5, 2.0, 1e3, 1e-3, 1.0000001};
      doc[ptr] = doc[ptr].get<double>() * factors[pick(6)];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    } else if (!at.empty()) {
      doc[ptr] = absurd[pick(absurd.size())];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    }
  }
  return what;
}

// ParseFemCase must accept a mutated case, whose ToJson then parses back to
// the same canonical form, or refuse it with InvalidArgument naming a JSON
// pointer ("/..."). Seeded and sized from the environment:
//   RVEHUB_FEM_CASE_FUZZ_ITERATIONS=100000 RVEHUB_FEM_CASE_FUZZ_SEED=7
//   build/tests/fem_case_fuzz_test
TEST(FemCaseFuzz, MutatedCasesAreAcceptedOrRefusedByPointer) {
  const std::int64_t iterations = testing_env::EnvInt("RVEHUB_FEM_CASE_FUZZ_ITERATIONS", 3000);
  const std::uint64_t seed =
      static_cast<std::uint64_t>(testing_env::EnvInt("RVEHUB_FEM_CASE_FUZZ_SEED", 1));
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  std::vector<std::pair<std::string, Json>> cases;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with("fem-") || entry.path().extension() != ".json") continue;
    std::ifstream in(entry.path());
    cases.emplace_back(name, Json::parse(in));
  }
  std::sort(cases.begin(), cases.end());
  ASSERT_FALSE(cases.empty());
  // The tests' cases hold what the shipped ones lack (q8 with a rough platen,
  // k0, the perturbation tangent, a stress-controlled cycle on a small mesh);
  // the full case's files are not in cases/, so its file template is dropped.
  Json full = Json::parse(kFullCase);
  full["templates"].erase(1);
  full["output"].erase("reference_curve");
  cases.emplace_back("full", full);
  cases.emplace_back("shear", Json::parse(kShearCase));

  std::mt19937_64 rng(seed);
  std::int64_t accepted = 0;
  for (std::int64_t it = 0; it < iterations; ++it) {
    const auto& [name, base] = cases[rng() % cases.size()];
    Json doc = base;
    const std::string what = Mutate(doc, rng);
    SCOPED_TRACE(absl::StrCat("iteration ", it, ", ", name, ":", what));
    absl::StatusOr<FemCase> c = ParseFemCase(doc.dump(), dir.string());
    if (!c.ok()) {
      ASSERT_EQ(c.status().code(), absl::StatusCode::kInvalidArgument) << c.status();
      ASSERT_TRUE(MessageStartsWith(c.status(), "/")) << c.status();
      continue;
    }
    ++accepted;
    absl::StatusOr<FemCase> again = ParseFemCase(ToJson(*c), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ASSERT_EQ(ToJson(*again), ToJson(*c));
  }
  std::printf("fem case fuzz: %lld mutated cases, %lld accepted, seed %llu\n",
              static_cast<long long>(iterations), static_cast<long long>(accepted),
              static_cast<unsigned long long>(seed));
  EXPECT_GT(accepted, 0);
  EXPECT_LT(accepted, iterations);
}

}  // namespace
}  // namespace rvehub::fem::case_test
