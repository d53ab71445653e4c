// ValidateAddress: rve_server --listen and mpm_client --servers.
#include "rve_server/common/address.h"

#include <gtest/gtest.h>

#include <string>

namespace rvehub {
namespace {

TEST(AddressTest, HostPortWithAPortInRange) {
  for (const char* ok : {"127.0.0.1:50051", "localhost:1", "[::1]:65535", "node-7.cluster:8080",
                         "unix:/run/rvehub.sock", "dns:///rve.example:50051", "ipv4:127.0.0.1:9"}) {
    EXPECT_TRUE(ValidateAddress("--servers", ok, PortZero::kRefused).ok()) << ok;
  }
  EXPECT_TRUE(ValidateAddress("--listen", "127.0.0.1:0", PortZero::kAllowed).ok());
}

TEST(AddressTest, AnythingElseIsRefusedNamingIt) {
  // gRPC itself reads 70000 as 4464, -1 as 65535, and an empty port as its
  // default.
  for (const char* bad : {"127.0.0.1:70000", "127.0.0.1:65536", "127.0.0.1:-1", "127.0.0.1:",
                          "127.0.0.1", ":50051", "", ":", "127.0.0.1:0x10", "127.0.0.1: 5",
                          "127.0.0.1:000050051", "::1:50051", "127.0.0.1:0:0", "127.0.0.1:0"}) {
    const absl::Status s = ValidateAddress("--servers", bad, PortZero::kRefused);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_EQ(s.message(),
              std::string("--servers: \"") + bad + "\" is not HOST:PORT with a port in 1..65535")
        << bad;
  }
  EXPECT_EQ(ValidateAddress("--listen", "127.0.0.1:99999", PortZero::kAllowed).message(),
            "--listen: \"127.0.0.1:99999\" is not HOST:PORT with a port in 0..65535");
  const std::string long_address = std::string(5000, 'x') + ":1:2";
  const absl::Status long_one = ValidateAddress("--servers", long_address, PortZero::kRefused);
  EXPECT_LT(long_one.message().size(), 200u) << "the address is shown cut short";
}

}  // namespace
}  // namespace rvehub
