#include "client_run/endpoints.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/embedded/endpoint.h"

namespace rvehub::client_run {

std::string MakeRunId(const std::string& case_name) {
  std::string name;
  for (char c : case_name) {
    name +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_') ? c : '_';
  }
  if (name.size() > 64) name.resize(64);
  return absl::StrCat(name.empty() ? "run" : name, "-",
                      absl::FormatTime("%Y%m%dT%H%M%S", absl::Now(), absl::UTCTimeZone()), "-",
                      getpid());
}

absl::StatusOr<std::vector<std::unique_ptr<client::RveEndpoint>>> MakeEndpoints(
    const std::vector<std::string>& servers, int threads, const client::ClientOptions& client) {
  std::vector<std::unique_ptr<client::RveEndpoint>> endpoints;
  if (servers.empty()) {
    embedded::EmbeddedOptions embedded;
    embedded.threads =
        threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    endpoints.push_back(embedded::MakeEndpoint(embedded));
  } else {
    for (const std::string& address : servers) {
      ASSIGN_OR_RETURN(std::unique_ptr<client::RveEndpoint> e,
                       client::RemoteServer::Connect(address, client));
      endpoints.push_back(std::move(e));
    }
  }
  return endpoints;
}

}  // namespace rvehub::client_run
