#include "rve_server/common/names.h"

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"

namespace rvehub {

std::string QuotedName(absl::string_view name) {
  constexpr std::size_t kShown = 64;
  std::string s = absl::StrCat("\"", absl::CHexEscape(name.substr(0, kShown)), "\"");
  if (name.size() > kShown) absl::StrAppend(&s, "... (", name.size(), " bytes)");
  return s;
}

absl::Status ValidateName(absl::string_view what, absl::string_view name) {
  if (name.empty() || name.size() > kMaxNameLength) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, " must have 1 to ", kMaxNameLength, " characters, got ", name.size()));
  }
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) {
      return absl::InvalidArgumentError(absl::StrCat(
          what, " ", QuotedName(name), " may contain only letters, digits, '.', '_' and '-'"));
    }
  }
  return absl::OkStatus();
}

}  // namespace rvehub
