// Run ids and template names: the one rule for them, checked by servers on
// every call and by clients before the work that would end in an upload.
#ifndef RVEHUB_RVE_SERVER_COMMON_NAMES_H_
#define RVEHUB_RVE_SERVER_COMMON_NAMES_H_

#include <cstddef>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace rvehub {

inline constexpr std::size_t kMaxNameLength = 128;

// [A-Za-z0-9._-], 1 to kMaxNameLength characters; else InvalidArgument
// naming `what` ("run_id", "--name", ...) and quoting the name as QuotedName.
absl::Status ValidateName(absl::string_view what, absl::string_view name);

// `name` for an error message: in quotes, C-escaped, at most 64 bytes shown
// then its length (a 10 KB id must not come back whole).
std::string QuotedName(absl::string_view name);

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_NAMES_H_
