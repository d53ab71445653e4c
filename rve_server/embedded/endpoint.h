// The RVE service inside a client's own process: an RveEndpoint over a
// registry of this process (direct calls, no gRPC, no marshalling), which a
// client holds beside remote servers (rve_server/client/remote_server.h) and
// drives the same way, with the same results bit for bit.
#ifndef RVEHUB_RVE_SERVER_EMBEDDED_ENDPOINT_H_
#define RVEHUB_RVE_SERVER_EMBEDDED_ENDPOINT_H_

#include <memory>

#include "rve_server/client/endpoint.h"
#include "rve_server/service/registry.h"

namespace rvehub::embedded {

// A registry of the endpoint's own, with `threads` workers.
struct EmbeddedOptions {
  int threads = 1;
};
std::unique_ptr<client::RveEndpoint> MakeEndpoint(const EmbeddedOptions& options);

// Direct calls into `registry`, shared with whoever else uses it (tests and
// benchmarks that also serve it over gRPC, or hand it to several endpoints).
std::unique_ptr<client::RveEndpoint> MakeEndpoint(std::shared_ptr<service::Registry> registry);

}  // namespace rvehub::embedded

#endif  // RVEHUB_RVE_SERVER_EMBEDDED_ENDPOINT_H_
