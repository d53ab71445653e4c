// Plain values a client exchanges with RVE servers, whichever endpoint
// carries them (embedded registry or gRPC): increments, per-RVE outcomes and
// initial stresses. No gRPC and no server internals.
#ifndef RVEHUB_RVE_SERVER_CLIENT_TYPES_H_
#define RVEHUB_RVE_SERVER_CLIENT_TYPES_H_

#include <functional>

#include "absl/status/status.h"
#include "rve_server/service/rve_batch.h"
#include "store/record.h"

namespace rvehub::client {

// Increments, per-RVE outcomes and initial stresses are the registry's own
// (service/rve_batch.h): the embedded endpoint hands them on without a copy.
using ::rvehub::Increment;
using ::rvehub::InitialStress;
using ::rvehub::RveOutcome;

// Receives exported RVE states one at a time; an error stops the export.
using RecordSink = std::function<absl::Status(store::RveRecord&&)>;

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_TYPES_H_
