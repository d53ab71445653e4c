// A continuum client's RVE endpoints and run id: one embedded server in the
// client's process (no network), or remote rve_servers over gRPC.
#ifndef RVEHUB_CLIENT_RUN_ENDPOINTS_H_
#define RVEHUB_CLIENT_RUN_ENDPOINTS_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/endpoint.h"

namespace rvehub::client_run {

// A run id unique among the runs a shared server hosts: case name, time and
// process id. It names the RVEs on the servers only; results never depend on it.
std::string MakeRunId(const std::string& case_name);

// `servers` (HOST:PORT each) connected with `client` (token, TLS); without
// any, one embedded server with `threads` workers (0: all cores).
absl::StatusOr<std::vector<std::unique_ptr<client::RveEndpoint>>> MakeEndpoints(
    const std::vector<std::string>& servers, int threads, const client::ClientOptions& client);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_ENDPOINTS_H_
