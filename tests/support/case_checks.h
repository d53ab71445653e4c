// The shipped case's validation checks (cases/FORMAT.md, "checks") asserted
// on a finished run's summary.json: what the reduced cases' tests add after
// the runs they make anyway.
#ifndef RVEHUB_TESTS_SUPPORT_CASE_CHECKS_H_
#define RVEHUB_TESTS_SUPPORT_CASE_CHECKS_H_

#include <gtest/gtest.h>

#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "client_case/spec/check_spec.h"
#include "client_run/checks.h"

namespace rvehub::testing_util {

// Every check passes on `dir`/summary.json; the case has at least one.
inline void ExpectCaseChecksPass(std::span<const client_case::CheckSpec> checks,
                                 const std::string& dir) {
  EXPECT_FALSE(checks.empty()) << "the case has no checks";
  const absl::StatusOr<client_run::Summary> summary =
      client_run::ReadSummary(dir + "/summary.json");
  ASSERT_TRUE(summary.ok()) << summary.status();
  for (const client_run::CheckResult& r : client_run::EvaluateChecks(checks, *summary)) {
    std::printf("check: %s\n", client_run::FormatCheck(r).c_str());
    EXPECT_TRUE(r.pass) << client_run::FormatCheck(r);
  }
}

}  // namespace rvehub::testing_util

#endif  // RVEHUB_TESTS_SUPPORT_CASE_CHECKS_H_
