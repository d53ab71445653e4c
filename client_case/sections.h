// The case-file sections that mean the same for every continuum client
// (mpm_client, fem_client): "templates" (the RVE packings), "rve" (the
// controls set on every RVE), each read from and written back to JSON by one
// field table (toolkit/field_table.h), and "checks" (the validation checks
// against summary.json). Errors are InvalidArgument
// "<JSON pointer>: <what is wrong>", as every field-table reader's.
#ifndef RVEHUB_CLIENT_CASE_SECTIONS_H_
#define RVEHUB_CLIENT_CASE_SECTIONS_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "client_case/spec/check_spec.h"
#include "client_case/spec/rve_spec.h"
#include "toolkit/json_pointer.h"

namespace rvehub::client_case {

// One element of "templates" at pointer `ptr`: exactly one of "parameter_set"
// (a known set, with seed, pressure, void_ratio, particles, rolling_eta) or
// "file" (relative to `base_dir`, the case file's directory; held absolute
// and normalised, so a spec written to a checkpoint does not depend on the
// working directory).
absl::Status ParseTemplate(const fields::Json& j, const std::string& ptr,
                           const std::string& base_dir, TemplateSpec* t);
// Its canonical JSON: every key that applies (no "seed" for a file).
fields::OrderedJson WriteTemplate(const TemplateSpec& t);

// The discs of one of the template's RVEs, for a case's memory estimate:
// the parameter set's (or "particles") when prepared, 400 for a file (not
// read here).
int EstimatedDiscs(const TemplateSpec& t);
// An RVE's memory per disc (bench/README.md: 55.5 KB per 400-disc RVE).
inline constexpr double kRveBytesPerDisc = 140.0;

// The keys of "rve" a client takes. All of them by default (mpm_client's
// explicit step); a quasi-static client has no step duration to cap an
// increment at (real_time) and no point volume apart from its RVE's
// (max_void_ratio), so for it they are unknown keys.
struct RveKeys {
  bool real_time = true;
  bool max_void_ratio = true;
};

// The "rve" object at `ptr`, its keys limited to `keys`.
absl::Status ParseRve(const fields::Json& j, const std::string& ptr, const RveKeys& keys,
                      RveSpec* rve);
// Its canonical JSON: every key of `keys` (real_time and
// full_state_every_step only when true).
fields::OrderedJson WriteRve(const RveSpec& rve, const RveKeys& keys);

// The "checks" array at `ptr` (cases/FORMAT.md): each element an object of
// "quantity" (a summary.json key), "reference" (a number, or another
// summary.json key), exactly one of "relative_tolerance" (in (0, 10]) or
// "absolute_tolerance" (>= 0), an optional "bound" ("upper" or "lower": the
// reference bounds one side only) and a non-empty "source"; unknown keys
// refused. `checks` is left untouched on an error.
absl::Status ParseChecks(const fields::Json& j, const std::string& ptr,
                         std::vector<CheckSpec>* checks);
// Its canonical JSON, the keys in that order.
fields::OrderedJson WriteChecks(const std::vector<CheckSpec>& checks);

}  // namespace rvehub::client_case

#endif  // RVEHUB_CLIENT_CASE_SECTIONS_H_
