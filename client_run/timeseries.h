// A run's timeseries.csv (any continuum client's): one row per recorded
// step, one column per quantity, each row flushed; and its columns read back
// by name (summaries, plots, tests).
#ifndef RVEHUB_CLIENT_RUN_TIMESERIES_H_
#define RVEHUB_CLIENT_RUN_TIMESERIES_H_

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::client_run {

// Appends rows to a CSV file with a header line of column names, one of
// them "step" for Resume. Every row is flushed, so the file is complete up
// to the last step written even if the run is killed.
class TimeseriesWriter {
 public:
  // Creates (truncates) `path` and writes the header.
  static absl::StatusOr<std::unique_ptr<TimeseriesWriter>> Create(
      const std::string& path, const std::vector<std::string>& columns);
  // Keeps the rows of an existing file up to and including `step` (a resumed
  // run writes the later ones again; the rows' step is the column "step");
  // the header must equal `columns` (CheckColumns).
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

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_TIMESERIES_H_
