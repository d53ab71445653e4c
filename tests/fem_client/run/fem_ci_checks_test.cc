// The reduced fem cases run to their end on an embedded server and their
// checks (the case file's "checks", cases/FORMAT.md) asserted on the
// summary.json each writes: the element and the biaxial specimens at 1 %
// against the DEM element test on the same RVE. The second-gradient case's
// are asserted in fem_second_gradient_test, which runs it anyway.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "fem_client/case/case.h"
#include "tests/fem_client/run/fem_run_test_util.h"
#include "tests/support/case_checks.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;

void RunAndCheck(const std::string& name) {
  const std::string out = run_test::ScratchPath("fem_ci_checks_test", name);
  absl::StatusOr<FemRunSummary> summary = run_test::RunShippedCase(name, out);
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_TRUE(summary->finished);
  absl::StatusOr<FemCase> c = LoadFemCase(RVEHUB_SOURCE_DIR "/cases/" + name + ".json", {});
  ASSERT_TRUE(c.ok()) << c.status();
  testing_util::ExpectCaseChecksPass(c->checks, out);
  fs::remove_all(out);
}

TEST(FemCiChecksTest, SingleElement) { RunAndCheck("fem-single-element-ci"); }
TEST(FemCiChecksTest, BiaxialCoarse) { RunAndCheck("fem-biaxial-coarse-ci"); }
TEST(FemCiChecksTest, BiaxialCoarseQ8) { RunAndCheck("fem-biaxial-coarse-q8-ci"); }

}  // namespace
}  // namespace rvehub::fem
