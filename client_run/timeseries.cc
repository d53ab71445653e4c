#include "client_run/timeseries.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <istream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::client_run {
namespace {

absl::Status IoError(absl::string_view what, const std::string& path) {
  return absl::UnavailableError(absl::StrCat(what, " ", path, ": ", std::strerror(errno)));
}

std::string Header(const std::vector<std::string>& columns) {
  return absl::StrCat(absl::StrJoin(columns, ","), "\n");
}

// Reads the first line of `in` (the file at `path`): FailedPrecondition unless
// it is the header of `columns`.
absl::Status ReadHeader(std::istream& in, const std::string& path,
                        const std::vector<std::string>& columns) {
  std::string line;
  if (!std::getline(in, line) || line + "\n" != Header(columns)) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " does not have the columns of this case; cannot resume into it"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::unique_ptr<TimeseriesWriter>> TimeseriesWriter::Create(
    const std::string& path, const std::vector<std::string>& columns) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return IoError("cannot create", path);
  const std::string header = Header(columns);
  if (std::fputs(header.c_str(), f) < 0 || std::fflush(f) != 0) {
    std::fclose(f);
    return IoError("cannot write", path);
  }
  return std::unique_ptr<TimeseriesWriter>(new TimeseriesWriter(f, path, columns.size()));
}

absl::Status TimeseriesWriter::CheckColumns(const std::string& path,
                                            const std::vector<std::string>& columns) {
  std::ifstream in(path);
  if (!in) return IoError("cannot read", path);
  return ReadHeader(in, path, columns);
}

absl::StatusOr<std::unique_ptr<TimeseriesWriter>> TimeseriesWriter::Resume(
    const std::string& path, const std::vector<std::string>& columns, std::int64_t step) {
  const std::size_t step_column =
      std::find(columns.begin(), columns.end(), "step") - columns.begin();
  if (step_column == columns.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": a timeseries to resume needs a step column"));
  }
  std::ifstream in(path);
  if (!in) return IoError("cannot read", path);
  RETURN_IF_ERROR(ReadHeader(in, path, columns));
  std::string kept = Header(columns), line;
  while (std::getline(in, line)) {
    std::vector<absl::string_view> cells = absl::StrSplit(line, ',');
    double row_step = 0;
    if (cells.size() <= step_column || !absl::SimpleAtod(cells[step_column], &row_step)) break;
    if (row_step > static_cast<double>(step)) break;
    absl::StrAppend(&kept, line, "\n");
  }
  in.close();
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return IoError("cannot rewrite", path);
  if (std::fputs(kept.c_str(), f) < 0 || std::fflush(f) != 0) {
    std::fclose(f);
    return IoError("cannot write", path);
  }
  return std::unique_ptr<TimeseriesWriter>(new TimeseriesWriter(f, path, columns.size()));
}

TimeseriesWriter::~TimeseriesWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

absl::Status TimeseriesWriter::Append(std::span<const double> values) {
  if (values.size() != columns_) {
    return absl::InternalError(
        absl::StrCat("timeseries row has ", values.size(), " values for ", columns_, " columns"));
  }
  std::string row;
  for (std::size_t i = 0; i < values.size(); ++i) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.17g", values[i]);
    absl::StrAppend(&row, i == 0 ? "" : ",", buf);
  }
  row += "\n";
  if (std::fputs(row.c_str(), file_) < 0 || std::fflush(file_) != 0) {
    return IoError("cannot write", path_);
  }
  return absl::OkStatus();
}

absl::StatusOr<std::map<std::string, std::vector<double>>> ReadCsvColumns(const std::string& path) {
  std::ifstream in(path);
  if (!in) return IoError("cannot read", path);
  std::string line;
  // bad(): a read failed (a directory opens, then reads EISDIR), as opposed
  // to the file's end.
  if (!std::getline(in, line)) {
    if (in.bad()) return IoError("cannot read", path);
    return absl::DataLossError(absl::StrCat(path, " is empty"));
  }
  std::vector<std::string> names = absl::StrSplit(line, ',');
  std::map<std::string, std::vector<double>> columns;
  for (const std::string& n : names) columns[n];
  int row = 1;
  while (std::getline(in, line)) {
    ++row;
    std::vector<absl::string_view> cells = absl::StrSplit(line, ',');
    if (cells.size() != names.size()) {
      return absl::DataLossError(absl::StrCat(path, " row ", row, " has ", cells.size(),
                                              " values for ", names.size(), " columns"));
    }
    for (std::size_t i = 0; i < cells.size(); ++i) {
      double v = 0;
      if (!absl::SimpleAtod(cells[i], &v)) {
        return absl::DataLossError(
            absl::StrCat(path, " row ", row, " column ", names[i], ": not a number"));
      }
      // SimpleAtod reads "nan", which no run writes; taken in, it would flip
      // the summary's comparisons quietly.
      if (std::isnan(v)) {
        return absl::DataLossError(
            absl::StrCat(path, " row ", row, " column ", names[i], ": NaN, which no run writes"));
      }
      columns[names[i]].push_back(v);
    }
  }
  if (in.bad()) return IoError("cannot read", path);  // not the end: a read that failed
  return columns;
}

}  // namespace rvehub::client_run
