// Where a continuum client's wall time went, as its run ends: the DEM
// engine, the service, transport and idle workers, the client's own solver
// and its outputs; then the DEM steps per increment, mean and histogram.
#ifndef RVEHUB_CLIENT_RUN_TIME_SPLIT_H_
#define RVEHUB_CLIENT_RUN_TIME_SPLIT_H_

#include <string>

#include "absl/strings/string_view.h"
#include "rve_server/client/rve_pool.h"

namespace rvehub::client_run {

struct TimeSplit {
  double wall_s = 0.0;    // s, the stepping loop
  double rve_s = 0.0;     // s, of wall_s inside RVE calls
  double output_s = 0.0;  // s, of wall_s writing outputs and checkpoints
  // The increments of those calls: DEM steps and the engine's time summed
  // over the workers (rve_workers of them).
  client::ApplyStats rve_stats;
  int rve_workers = 1;
};

// Two lines for people. `solver` names the rest of the wall time (mpm_client:
// "grid", the MPM step itself).
std::string FormatTimeSplit(const TimeSplit& split, absl::string_view solver);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_TIME_SPLIT_H_
