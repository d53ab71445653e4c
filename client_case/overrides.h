// Fields of a case set from outside its file (a client's --set=PATH=VALUE),
// so that a parameter sweep needs no copied case files: the same for every
// client's case format.
#ifndef RVEHUB_CLIENT_CASE_OVERRIDES_H_
#define RVEHUB_CLIENT_CASE_OVERRIDES_H_

#include <span>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "toolkit/json_pointer.h"

namespace rvehub::client_case {

// One field of a case set from outside the file.
struct CaseOverride {
  std::string pointer;  // JSON pointer of the field, e.g. "/rve/min_steps"
  std::string value;    // JSON text, e.g. "4", "[1, 2]", "\"gimp\""
};

// "PATH=VALUE": PATH a JSON pointer ("/rve/min_steps", "/regions/0/density")
// or the same with dots ("rve.min_steps", "regions.0.density"); VALUE JSON, or
// a string when it does not parse as JSON (--set name=sweep-3). InvalidArgument
// for a text without "=" or with an empty path.
absl::StatusOr<CaseOverride> ParseOverride(absl::string_view text);

// `overrides` applied in order to the parsed case `doc` before it is
// validated, so an override is checked exactly like the file. An override
// whose parent is not in the case (or not an object or array, or an array
// index past its end) is InvalidArgument "--set <pointer>: ...".
absl::Status ApplyOverrides(std::span<const CaseOverride> overrides, fields::Json& doc);

}  // namespace rvehub::client_case

#endif  // RVEHUB_CLIENT_CASE_OVERRIDES_H_
