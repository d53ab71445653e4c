// The embedded endpoint over a given registry, for code that shares one
// registry between endpoints or with a server in the same process (tests,
// benchmarks). Clients that only want an in-process registry use
// MakeEmbeddedEndpoint(EmbeddedOptions) from endpoint.h.
#ifndef RVEHUB_RVE_SERVER_CLIENT_EMBEDDED_ENDPOINT_H_
#define RVEHUB_RVE_SERVER_CLIENT_EMBEDDED_ENDPOINT_H_

#include <memory>

#include "rve_server/client/endpoint.h"
#include "rve_server/service/registry.h"

namespace rvehub::client {

// Direct calls into `registry` (shared with whoever else uses it).
std::unique_ptr<RveEndpoint> MakeEmbeddedEndpoint(std::shared_ptr<service::Registry> registry);

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_EMBEDDED_ENDPOINT_H_
