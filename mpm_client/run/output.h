// Plain-text outputs of a simulation: timeseries.csv (one row per recorded
// step, one column per quantity) and the standard PNG plot drawn from it.
#ifndef RVEHUB_MPM_CLIENT_RUN_OUTPUT_H_
#define RVEHUB_MPM_CLIENT_RUN_OUTPUT_H_

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "client_run/timeseries.h"
#include "mpm_client/core/model.h"
#include "mpm_client/run/summary.h"

namespace rvehub::mpm {

// timeseries.csv (time and step its first two columns), shared with the
// other clients.
using client_run::ReadCsvColumns;
using client_run::TimeseriesWriter;

// What a finished run (or `mpm_client summarise`) writes from
// DIR/timeseries.csv, read once: DIR/summary.json with the case's headline
// figures (mpm_client/run/summary.h; not written when its kind has none) and
// DIR/plot.png, the case's standard plot (OutputSpec::plot; none for
// "none"): "stress-strain": the nominal platen curve (with a body) and the
// points' mean σyy, σxx and εv against εyy; "load-settlement": a footing's
// q/q_s with Prandtl's N_q and the ultimate load, a pipe's forces against
// its displacements, else q = fy/(plot_width·t) against settlement;
// "collapse": front and kinetic energy against time. Returns the figures.
absl::StatusOr<Summary> WriteRunOutputs(const CaseSpec& spec, const std::string& dir);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_RUN_OUTPUT_H_
