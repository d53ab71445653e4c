#include "rve_server/common/address.h"

#include <algorithm>
#include <cstdint>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "rve_server/common/names.h"

namespace rvehub {

absl::Status ValidateAddress(absl::string_view what, absl::string_view address, PortZero zero) {
  for (absl::string_view scheme : {"unix:", "unix-abstract:", "vsock:", "ipv4:", "ipv6:", "dns:"}) {
    if (absl::StartsWith(address, scheme)) return absl::OkStatus();
  }
  const std::uint32_t lowest = zero == PortZero::kAllowed ? 0 : 1;
  const auto invalid = [&] {
    return absl::InvalidArgumentError(absl::StrCat(
        what, ": ", QuotedName(address), " is not HOST:PORT with a port in ", lowest, "..65535"));
  };
  const std::size_t colon = address.rfind(':');
  if (colon == absl::string_view::npos || colon == 0) return invalid();
  const absl::string_view host = address.substr(0, colon), port = address.substr(colon + 1);
  // An IPv6 host is bracketed; any other colon in the host is a mistake.
  const bool bracketed = absl::StartsWith(host, "[") && absl::EndsWith(host, "]");
  if (!bracketed && absl::StrContains(host, ':')) return invalid();
  std::uint32_t number = 0;
  if (port.empty() || port.size() > 5 ||
      !std::all_of(port.begin(), port.end(), [](char c) { return absl::ascii_isdigit(c); }) ||
      !absl::SimpleAtoi(port, &number) || number < lowest || number > 65535) {
    return invalid();
  }
  return absl::OkStatus();
}

}  // namespace rvehub
