#include "mpm_client/output.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "rve_server/common/plot.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

absl::Status IoError(absl::string_view what, const std::string& path) {
  return absl::UnavailableError(absl::StrCat(what, " ", path, ": ", std::strerror(errno)));
}

std::string Header(const std::vector<std::string>& columns) {
  return absl::StrCat(absl::StrJoin(columns, ","), "\n");
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

absl::StatusOr<std::unique_ptr<TimeseriesWriter>> TimeseriesWriter::Resume(
    const std::string& path, const std::vector<std::string>& columns, std::int64_t step) {
  std::ifstream in(path);
  if (!in) return IoError("cannot read", path);
  std::string line;
  const std::string header = Header(columns);
  if (!std::getline(in, line) || line + "\n" != header) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " does not have the columns of this case; cannot resume into it"));
  }
  std::string kept = header;
  while (std::getline(in, line)) {
    std::vector<absl::string_view> cells = absl::StrSplit(line, ',');
    double row_step = 0;
    if (cells.size() < 2 || !absl::SimpleAtod(cells[1], &row_step)) break;
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
  if (!std::getline(in, line)) return absl::DataLossError(absl::StrCat(path, " is empty"));
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
      columns[names[i]].push_back(v);
    }
  }
  return columns;
}

absl::Status WriteCasePlot(const CaseSpec& spec, const std::string& csv_path,
                           const std::string& png_path) {
  const OutputSpec& out = spec.output;
  if (out.plot == "none") return absl::OkStatus();
  ASSIGN_OR_RETURN(auto cols, ReadCsvColumns(csv_path));
  auto column = [&](const std::string& name) -> absl::StatusOr<std::vector<double>> {
    auto it = cols.find(name);
    if (it == cols.end()) {
      return absl::InvalidArgumentError(absl::StrCat(csv_path, " has no column ", name));
    }
    return it->second;
  };
  auto scaled = [](std::vector<double> v, double f) {
    for (double& x : v) x *= f;
    return v;
  };
  std::vector<plot::Panel> panels;
  if (out.plot == "stress-strain") {
    absl::StatusOr<std::vector<double>> eyy = column("mean_eyy");
    absl::StatusOr<std::vector<double>> exx = column("mean_exx");
    absl::StatusOr<std::vector<double>> syy = column("mean_syy");
    absl::StatusOr<std::vector<double>> sxx = column("mean_sxx");
    for (const auto* c : {&eyy, &exx, &syy, &sxx}) {
      if (!c->ok()) return c->status();
    }
    std::vector<double> ev(eyy->size());
    for (std::size_t i = 0; i < ev.size(); ++i) ev[i] = 100.0 * ((*eyy)[i] + (*exx)[i]);
    const std::vector<double> axial = scaled(*eyy, 100.0);
    panels.push_back({"Stress-strain (mean of all points)",
                      "axial strain eyy (%)",
                      "stress (kPa, compression +)",
                      {{"syy", axial, scaled(*syy, 1e-3)}, {"sxx", axial, scaled(*sxx, 1e-3)}}});
    panels.push_back({"Volumetric strain",
                      "axial strain eyy (%)",
                      "ev = exx + eyy (%, compression +)",
                      {{"ev", axial, ev}}});
  } else if (out.plot == "load-settlement") {
    absl::StatusOr<std::vector<double>> fy = column(out.plot_body + "_fy");
    absl::StatusOr<std::vector<double>> dy = column(out.plot_body + "_dy");
    if (!fy.ok()) return fy.status();
    if (!dy.ok()) return dy.status();
    const double area = out.plot_width * spec.solver.thickness;  // m²
    std::vector<double> q = scaled(*fy, 1e-3 / area);
    panels.push_back({absl::StrCat("Load-settlement of ", out.plot_body),
                      "settlement (m)",
                      "q = fy / (B t) (kPa)",
                      {{out.plot_body, scaled(*dy, -1.0), q}}});
  } else {
    return absl::InvalidArgumentError(absl::StrCat("unknown plot kind '", out.plot, "'"));
  }
  return plot::WritePng(png_path, panels);
}

}  // namespace rvehub::mpm
