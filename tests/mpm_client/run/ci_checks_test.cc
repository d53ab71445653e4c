// The reduced cases that no other test runs to the end, each run here and
// its checks (the case file's "checks", cases/FORMAT.md) asserted on the
// summary.json it writes. The others are asserted where they are run:
// single-element-biaxial in simulation_test, footing-dense-ci in
// fault_test, collapse-saturated-ci in simulation_saturated_test. pipe-ci
// (about 4 minutes) is left to `mpm_client summarise` by hand.
#include <memory>
#include <string>

#include "tests/mpm_client/run/simulation_test_util.h"
#include "tests/support/case_checks.h"

namespace rvehub::mpm::sim_test {
namespace {

void RunAndCheck(const std::string& name) {
  const CaseSpec spec = LoadOrDie(name);
  const std::string out = FreshDir(name);
  std::unique_ptr<Simulation> sim = StartOrDie(spec, Options(out));
  ASSERT_NE(sim, nullptr);
  absl::StatusOr<SimulationSummary> sum = sim->StepToEnd();
  ASSERT_TRUE(sum.ok()) << sum.status();
  ASSERT_TRUE(sum->finished);
  testing_util::ExpectCaseChecksPass(spec.checks, out);
  fs::remove_all(out);
}

TEST(CiChecksTest, FootingMedium) { RunAndCheck("footing-medium-ci"); }
TEST(CiChecksTest, FootingSoft) { RunAndCheck("footing-soft-ci"); }
TEST(CiChecksTest, BiaxialSpecimen) { RunAndCheck("biaxial-specimen-ci"); }
TEST(CiChecksTest, ColumnCollapse) { RunAndCheck("column-collapse-ci"); }
TEST(CiChecksTest, CyclicShakingDense) { RunAndCheck("cyclic-shaking-dense-ci"); }

}  // namespace
}  // namespace rvehub::mpm::sim_test
