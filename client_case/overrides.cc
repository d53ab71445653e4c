#include "client_case/overrides.h"

#include <utility>

#include "rve_server/common/status_macros.h"
#include "toolkit/json_document.h"

namespace rvehub::client_case {

absl::StatusOr<CaseOverride> ParseOverride(absl::string_view text) {
  ASSIGN_OR_RETURN(fields::Override o,
                   fields::ParseOverride(text, "--set=/rve/min_steps=4 or --set=rve.min_steps=4"));
  return CaseOverride{std::move(o.pointer), std::move(o.value)};
}

absl::Status ApplyOverrides(std::span<const CaseOverride> overrides, fields::Json& doc) {
  for (const CaseOverride& o : overrides) {
    RETURN_IF_ERROR(fields::ApplyOverride(o.pointer, o.value, doc));
  }
  return absl::OkStatus();
}

}  // namespace rvehub::client_case
