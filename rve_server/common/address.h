// HOST:PORT addresses of RVE servers, as rve_server --listen and mpm_client
// --servers take them. gRPC reads a port past 65535 modulo 65536 (given
// 127.0.0.1:70000 it listened on, or dialled, port 4464) and takes an empty
// one for a default: an address is checked here before gRPC sees it.
#ifndef RVEHUB_RVE_SERVER_COMMON_ADDRESS_H_
#define RVEHUB_RVE_SERVER_COMMON_ADDRESS_H_

#include "absl/status/status.h"
#include "absl/strings/string_view.h"

namespace rvehub {

enum class PortZero {
  kAllowed,  // listening: port 0 picks a free one
  kRefused,  // dialling: there is no port 0 to reach
};

// OK for HOST:PORT with a non-empty HOST (a name, an IPv4 address or an IPv6
// one in brackets) and PORT a decimal number in 1..65535 (0 too where
// allowed), and for a target with one of gRPC's schemes (unix:, unix-abstract:,
// vsock:, ipv4:, ipv6:, dns:), which gRPC reads itself. Else InvalidArgument
// naming `what` ("--listen", "--servers") and quoting the address.
absl::Status ValidateAddress(absl::string_view what, absl::string_view address, PortZero zero);

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_ADDRESS_H_
