// A case's checks against a summary (client_run/checks.h): the band of a
// relative and an absolute tolerance, a one-sided bound, a reference read
// from the summary, what fails (a missing or non-finite figure) and the
// printed line.
#include "client_run/checks.h"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "gtest/gtest.h"

namespace rvehub::client_run {
namespace {

using client_case::CheckSpec;

CheckSpec Relative(const std::string& quantity, double reference, double tolerance) {
  CheckSpec c;
  c.quantity = quantity;
  c.reference = reference;
  c.relative = true;
  c.tolerance = tolerance;
  c.source = "paper §1 Fig. 2";
  return c;
}

CheckSpec Absolute(const std::string& quantity, double reference, double tolerance) {
  CheckSpec c = Relative(quantity, reference, tolerance);
  c.relative = false;
  return c;
}

const Summary kSummary = {{"N_q", 15.0}, {"N_q_reduced", 8.0}, {"front_at_rest", 1.0}};

TEST(ChecksTest, ARelativeToleranceIsAShareOfTheReference) {
  // 15 against 14.4: 4.2 % off.
  std::vector<CheckResult> r = EvaluateChecks(
      std::vector{Relative("N_q", 14.4, 0.05), Relative("N_q", 14.4, 0.04)}, kSummary);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_TRUE(r[0].found);
  EXPECT_EQ(r[0].value, 15.0);
  EXPECT_EQ(r[0].reference, 14.4);
  EXPECT_DOUBLE_EQ(r[0].allowed, 0.72);
  EXPECT_TRUE(r[0].pass);
  EXPECT_FALSE(r[1].pass);
  EXPECT_FALSE(AllPass(r));
  EXPECT_TRUE(AllPass(std::span(r).first(1)));
}

TEST(ChecksTest, AnAbsoluteToleranceIsInTheQuantitysUnits) {
  std::vector<CheckResult> r = EvaluateChecks(
      std::vector{Absolute("N_q", 14.0, 1.0), Absolute("N_q", 14.0, 0.99),
                  Absolute("front_at_rest", 1.0, 0.0), Absolute("front_at_rest", 0.0, 0.0)},
      kSummary);
  EXPECT_TRUE(r[0].pass);
  EXPECT_FALSE(r[1].pass);
  EXPECT_TRUE(r[2].pass);  // a flag matched exactly
  EXPECT_FALSE(r[3].pass);
}

// A paper's "smaller than the dry column's": only one side is guarded.
TEST(ChecksTest, ABoundGuardsOneSideOnly) {
  CheckSpec at_most = Absolute("N_q", 16.0, 0.0), at_least = Relative("N_q", 16.0, 0.05);
  at_most.bound = CheckSpec::Bound::kUpper;
  at_least.bound = CheckSpec::Bound::kLower;
  std::vector<CheckResult> r = EvaluateChecks(std::vector{at_most, at_least}, kSummary);
  EXPECT_TRUE(r[0].pass);   // 15 ≤ 16, however far below
  EXPECT_FALSE(r[1].pass);  // 15 < 16 − 0.8
  EXPECT_EQ(FormatCheck(r[0]), "pass N_q = 15 (reference at most 16 + 0 = 0; paper §1 Fig. 2)");
  EXPECT_EQ(FormatCheck(r[1]),
            "FAIL N_q = 15 (reference at least 16 − 5 % = 0.8; paper §1 Fig. 2)");
  at_most.reference = 14.0;
  at_least.reference = 10.0;
  r = EvaluateChecks(std::vector{at_most, at_least}, kSummary);
  EXPECT_FALSE(r[0].pass);
  EXPECT_TRUE(r[1].pass);  // 15 ≥ 10, however far above
  at_least.reference_quantity = "N_q_reduced";
  EXPECT_EQ(FormatCheck(EvaluateChecks(std::vector{at_least}, kSummary)[0]),
            "pass N_q = 15 (reference at least N_q_reduced = 8 − 5 % = 0.4; paper §1 Fig. 2)");
  const Summary nan = {{"N_q", std::numeric_limits<double>::quiet_NaN()}};
  EXPECT_FALSE(EvaluateChecks(std::vector{at_most}, nan)[0].pass);
}

TEST(ChecksTest, AReferenceQuantityIsReadFromTheSummary) {
  CheckSpec c = Relative("N_q", 0.0, 1.0);
  c.reference_quantity = "N_q_reduced";
  std::vector<CheckResult> r = EvaluateChecks(std::vector{c}, kSummary);
  EXPECT_EQ(r[0].reference, 8.0);
  EXPECT_DOUBLE_EQ(r[0].allowed, 8.0);
  EXPECT_TRUE(r[0].pass);  // 15 within 8 ± 8
  c.tolerance = 0.8;
  EXPECT_FALSE(EvaluateChecks(std::vector{c}, kSummary)[0].pass);
  EXPECT_EQ(FormatCheck(EvaluateChecks(std::vector{c}, kSummary)[0]),
            "FAIL N_q = 15 (reference N_q_reduced = 8 ± 80 % = 6.4; paper §1 Fig. 2)");
}

TEST(ChecksTest, AMissingOrNonFiniteFigureFails) {
  CheckSpec by_key = Relative("N_q", 0.0, 0.1);
  by_key.reference_quantity = "N_q_prandtl";
  const Summary nan = {{"N_q", std::numeric_limits<double>::quiet_NaN()}};
  std::vector<CheckResult> r =
      EvaluateChecks(std::vector{Relative("runout_normalised", 1.8, 0.1), by_key}, kSummary);
  EXPECT_FALSE(r[0].found);
  EXPECT_EQ(r[0].missing, "runout_normalised");
  EXPECT_FALSE(r[0].pass);
  EXPECT_EQ(r[1].missing, "N_q_prandtl");
  EXPECT_FALSE(r[1].pass);
  EXPECT_EQ(FormatCheck(r[0]),
            "FAIL runout_normalised: runout_normalised is not in summary.json (reference 1.8 ± "
            "10 %; paper §1 Fig. 2)");
  EXPECT_FALSE(EvaluateChecks(std::vector{Absolute("N_q", 0.0, 1e12)}, nan)[0].pass);
}

TEST(ChecksTest, APassingLineNamesOursTheReferenceTheToleranceAndTheSource) {
  EXPECT_EQ(FormatCheck(EvaluateChecks(std::vector{Relative("N_q", 14.4, 0.1)}, kSummary)[0]),
            "pass N_q = 15 (reference 14.4 ± 10 % = 1.44; paper §1 Fig. 2)");
  EXPECT_EQ(FormatCheck(EvaluateChecks(std::vector{Absolute("N_q", 14.4, 1)}, kSummary)[0]),
            "pass N_q = 15 (reference 14.4 ± 1 = 1; paper §1 Fig. 2)");
}

TEST(ChecksTest, TheLinesAreTheSummaryThenTheChecksWithTheirVerdict) {
  bool all_pass = false;
  EXPECT_EQ(SummaryAndCheckLines(kSummary, std::vector{Relative("N_q", 14.4, 0.1)}, &all_pass),
            (std::vector<std::string>{
                "summary: N_q = 15", "summary: N_q_reduced = 8", "summary: front_at_rest = 1",
                "check: pass N_q = 15 (reference 14.4 ± 10 % = 1.44; paper §1 Fig. 2)"}));
  EXPECT_TRUE(all_pass);
  SummaryAndCheckLines(kSummary, std::vector{Absolute("N_q", 14.4, 0.1)}, &all_pass);
  EXPECT_FALSE(all_pass);
  SummaryAndCheckLines(kSummary, {}, &all_pass);
  EXPECT_TRUE(all_pass);  // no checks
}

TEST(ChecksTest, ReadSummaryKeepsTheNumbersInTheFilesOrder) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("rvehub_checks_test_" + std::to_string(getpid()) + ".json");
  ASSERT_TRUE(WriteSummary(path.string(), "x", {{"b", 2.0}, {"a", 1.5}}).ok());
  absl::StatusOr<Summary> s = ReadSummary(path.string());
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(*s, (Summary{{"b", 2.0}, {"a", 1.5}}));  // "case" left out
  std::ofstream(path) << "[1, 2]";
  EXPECT_EQ(ReadSummary(path.string()).status().code(), absl::StatusCode::kInvalidArgument);
  std::filesystem::remove(path);
  EXPECT_EQ(ReadSummary(path.string()).status().code(), absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace rvehub::client_run
