// A case's validation checks (client_case/spec/check_spec.h) evaluated
// against a run's summary: pass or fail, with the numbers that decided it,
// and the line mpm_client prints for each.
#ifndef RVEHUB_CLIENT_RUN_CHECKS_H_
#define RVEHUB_CLIENT_RUN_CHECKS_H_

#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "client_case/spec/check_spec.h"
#include "client_run/summary.h"

namespace rvehub::client_run {

struct CheckResult {
  client_case::CheckSpec check;
  // The quantity (and a reference_quantity) are in the summary; else the
  // check fails and `missing` names the key.
  bool found = false;
  std::string missing;
  double value = 0.0;      // ours, the quantity's units
  double reference = 0.0;  // the check's number, or its reference_quantity's value
  double allowed = 0.0;    // the largest |value − reference| that passes, same units
  bool pass = false;
};

// Each check against `summary`, in order. A check passes when both its keys
// are present, the value is finite and |value − reference| ≤ allowed (for a
// bound, value − reference ≤ allowed (upper) or reference − value ≤
// allowed (lower)).
std::vector<CheckResult> EvaluateChecks(std::span<const client_case::CheckSpec> checks,
                                        const Summary& summary);
bool AllPass(std::span<const CheckResult> results);

// "pass N_q = 14.94 (reference 14.4 ± 10 % = 1.44; liang-zhao-mpm-dem §3.3
// Fig. 12)", "pass kinetic_energy_peak_J = 913 (reference at most 1088 + 0
// = 0; ...)", or "FAIL N_q: not in summary.json (...)".
std::string FormatCheck(const CheckResult& r);

// summarise's exit status when the outputs were written but a check failed
// (mpm_client and fem_client alike): apart from a failure (1) and a usage
// error (2), so that a test or CI job can tell a result that misses its
// reference from a run that broke.
inline constexpr int kCheckFailedExitCode = 3;

// "summary: KEY = VALUE" per summary entry, then "check: ..." (FormatCheck)
// per check: what `summarise` prints and a finished run logs. `all_pass`
// (when given): every check passes, or there are none.
std::vector<std::string> SummaryAndCheckLines(const Summary& summary,
                                              std::span<const client_case::CheckSpec> checks,
                                              bool* all_pass = nullptr);

// SummaryAndCheckLines on stdout; true when every check passes (or there
// are none).
bool PrintSummaryAndChecks(const Summary& summary, std::span<const client_case::CheckSpec> checks);

// summary.json as WriteSummary writes it: the numbers (the "case" entry and
// anything that is not a number left out), in the file's order.
// NotFound when the file cannot be read, InvalidArgument when it is not a
// JSON object.
absl::StatusOr<Summary> ReadSummary(const std::string& path);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_CHECKS_H_
