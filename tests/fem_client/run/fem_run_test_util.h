// What the fem_client run tests share: scratch directories, timeseries
// columns, curves read off a polyline, and a case run to its end.
#ifndef RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_
#define RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "client_run/timeseries.h"
#include "fem_client/case/case.h"
#include "fem_client/run/simulation.h"

namespace rvehub::fem::run_test {

using Columns = std::map<std::string, std::vector<double>>;

// `name` under this process's directory `test`_PID in the test temp
// directory: removed if it exists, its parent created.
inline std::string ScratchPath(const std::string& test, const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::path(testing::TempDir()) / absl::StrCat(test, "_", getpid()) / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d.parent_path());
  return d.string();
}

// A CSV's columns by name; empty (and the test failed) when it cannot be read.
inline Columns ReadColumns(const std::string& path) {
  absl::StatusOr<Columns> columns = client_run::ReadCsvColumns(path);
  EXPECT_TRUE(columns.ok()) << columns.status();
  return columns.ok() ? *columns : Columns{};
}

// y(x) on a polyline, linear between its points (x ascending).
inline double Interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  const auto it = std::upper_bound(xs.begin(), xs.end(), x);
  if (it == xs.begin()) return ys.front();
  if (it == xs.end()) return ys.back();
  const std::size_t i = it - xs.begin();
  return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
}

// The shipped case `name` (cases/NAME.json, with `overrides`) run to its end
// on an embedded server of two workers into `out`; its summary, or the
// test failed.
inline absl::StatusOr<FemRunSummary> RunShippedCase(const std::string& name, const std::string& out,
                                                    std::span<const CaseOverride> overrides = {}) {
  absl::StatusOr<FemCase> c =
      LoadFemCase(std::string(RVEHUB_SOURCE_DIR "/cases/") + name + ".json", overrides);
  if (!c.ok()) return c.status();
  FemSimulationOptions o;
  o.out_dir = out;
  o.threads = 2;
  o.template_cache_dir =
      (std::filesystem::path(testing::TempDir()) / "fem_test_templates").string();
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(*c, o);
  if (!sim.ok()) return sim.status();
  return (*sim)->StepToEnd();
}

}  // namespace rvehub::fem::run_test

#endif  // RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_
