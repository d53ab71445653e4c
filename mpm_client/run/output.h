// Plain-text outputs of a simulation: timeseries.csv (one row per recorded
// step, one column per quantity) and the standard PNG plot drawn from it.
#ifndef RVEHUB_MPM_CLIENT_RUN_OUTPUT_H_
#define RVEHUB_MPM_CLIENT_RUN_OUTPUT_H_

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/core/model.h"
#include "mpm_client/run/summary.h"

namespace rvehub::mpm {

// Appends rows to a CSV file whose first two columns are time and step.
// Every row is flushed, so the file is complete up to the last step written
// even if the run is killed.
class TimeseriesWriter {
 public:
  // Creates (truncates) `path` and writes the header.
  static absl::StatusOr<std::unique_ptr<TimeseriesWriter>> Create(
      const std::string& path, const std::vector<std::string>& columns);
  // Keeps the rows of an existing file up to and including `step` (a resumed
  // run writes the later ones again); the header must equal `columns`
  // (CheckColumns).
  static absl::StatusOr<std::unique_ptr<TimeseriesWriter>> Resume(
      const std::string& path, const std::vector<std::string>& columns, std::int64_t step);
  // Whether `path` can be resumed into, reading only: FailedPrecondition when
  // its header is not `columns` (a run written by a binary with other
  // columns), an I/O error when it cannot be read. A resume checks it before
  // it touches any of the run's files.
  static absl::Status CheckColumns(const std::string& path,
                                   const std::vector<std::string>& columns);
  ~TimeseriesWriter();

  // One value per column (17 significant digits: doubles round-trip).
  absl::Status Append(std::span<const double> values);

 private:
  TimeseriesWriter(std::FILE* f, std::string path, std::size_t columns)
      : file_(f), path_(std::move(path)), columns_(columns) {}
  std::FILE* file_;
  std::string path_;
  std::size_t columns_;
};

// The columns of a CSV file written by TimeseriesWriter, by header name.
// DataLossError for a ragged row, a cell that is not a number, or NaN;
// ±inf are read (a front of no material is −inf).
absl::StatusOr<std::map<std::string, std::vector<double>>> ReadCsvColumns(const std::string& path);

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
