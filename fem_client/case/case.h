// fem_client's case files: a FemCase (fem_case.h) as JSON
// (cases/FEM_FORMAT.md), parsed and validated, and written back canonically.
#ifndef RVEHUB_FEM_CLIENT_CASE_CASE_H_
#define RVEHUB_FEM_CLIENT_CASE_CASE_H_

#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "client_case/overrides.h"
#include "fem_client/case/fem_case.h"

namespace rvehub::fem {

// --set=PATH=VALUE, as mpm_client's (client_case/overrides.h).
using client_case::CaseOverride;
using client_case::ParseOverride;

// Parses and validates a case (JSON text) with `overrides` applied in order
// to the parsed JSON first, so an override is checked exactly like the
// file. `base_dir` resolves relative template files and the reference
// curve; the case holds them absolute. Errors are InvalidArgument "<JSON
// pointer of the bad field>: <what is wrong>", e.g. "/mesh/elements/0: must
// be an integer in 1..200, got 0", or for a JSON syntax error "line L,
// column C: <parser message>"; an override whose parent is not in the case
// is "--set <pointer>: ...". Unknown and duplicate keys are errors, and so
// are keys that do not apply (a "pressure" on a roller).
absl::StatusOr<FemCase> ParseFemCase(absl::string_view json_text, const std::string& base_dir,
                                     std::span<const CaseOverride> overrides = {});

// Reads and parses the case file at `path` (NotFound naming the path when it
// cannot be read); base_dir is the file's directory and the case name
// defaults to the file's stem. Parse errors are prefixed with "<path>: ".
absl::StatusOr<FemCase> LoadFemCase(const std::string& path,
                                    std::span<const CaseOverride> overrides = {});

// Canonical JSON of a case (every key that applies, defaults filled in, in
// the format's order), for checkpoints and `fem_client check`.
// ParseFemCase(ToJson(c)) gives back c for any case ParseFemCase produced.
std::string ToJson(const FemCase& c);

// What a case's RVEs hold in memory, roughly (client_case::kRveBytesPerDisc
// per disc, a template file's RVEs counted at 400 discs); ParseFemCase
// refuses a case above kMaxFemCaseBytes.
double EstimateRveBytes(const FemCase& c);
inline constexpr double kMaxFemCaseBytes = 32.0 * (1 << 30);  // 32 GiB

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CASE_CASE_H_
