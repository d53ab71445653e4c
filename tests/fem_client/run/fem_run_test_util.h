// What the fem_client run tests share: scratch directories and timeseries
// columns.
#ifndef RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_
#define RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "client_run/timeseries.h"

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

}  // namespace rvehub::fem::run_test

#endif  // RVEHUB_TESTS_FEM_CLIENT_RUN_FEM_RUN_TEST_UTIL_H_
