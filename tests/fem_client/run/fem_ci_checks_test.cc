// The reduced fem cases run to their end on an embedded server and their
// checks (the case file's "checks", cases/FORMAT.md) asserted on the
// summary.json each writes: the element and the biaxial specimens at 1 %
// against the DEM element test on the same RVE. The second-gradient case's
// are asserted in fem_second_gradient_test, which runs it anyway.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "fem_client/case/case.h"
#include "fem_client/run/simulation.h"
#include "tests/fem_client/run/fem_run_test_util.h"
#include "tests/support/case_checks.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;

void RunAndCheck(const std::string& name) {
  absl::StatusOr<FemCase> c = LoadFemCase(RVEHUB_SOURCE_DIR "/cases/" + name + ".json", {});
  ASSERT_TRUE(c.ok()) << c.status();
  FemSimulationOptions o;
  o.out_dir = run_test::ScratchPath("fem_ci_checks_test", name);
  o.threads = 2;
  o.template_cache_dir = (fs::path(testing::TempDir()) / "fem_test_templates").string();
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(*c, o);
  ASSERT_TRUE(sim.ok()) << sim.status();
  absl::StatusOr<FemRunSummary> summary = (*sim)->StepToEnd();
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_TRUE(summary->finished);
  testing_util::ExpectCaseChecksPass(c->checks, o.out_dir);
  fs::remove_all(o.out_dir);
}

TEST(FemCiChecksTest, SingleElement) { RunAndCheck("fem-single-element-ci"); }
TEST(FemCiChecksTest, BiaxialCoarse) { RunAndCheck("fem-biaxial-coarse-ci"); }
TEST(FemCiChecksTest, BiaxialCoarseQ8) { RunAndCheck("fem-biaxial-coarse-q8-ci"); }

}  // namespace
}  // namespace rvehub::fem
