// Running the mpm_client binary as a child process for its tests: a scratch
// directory, a small single-element case, its reference run, and readers for
// its CSV and XDMF outputs.
//
// The small case is cases/single-element-biaxial.json with a fixed 2 ms time
// step and 35 steps (0.07 s); prepared templates are shared by every test
// process through one cache directory.
#ifndef RVEHUB_TESTS_MPM_CLIENT_MPM_CLI_TEST_UTIL_H_
#define RVEHUB_TESTS_MPM_CLIENT_MPM_CLI_TEST_UTIL_H_

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "tests/support/process_util.h"

namespace rvehub::mpm::cli_test {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using testing_util::ReadFile;

inline constexpr char kHeader[] =
    "time,step,left_fx,left_fy,bottom_fx,bottom_fy,platen_fx,platen_fy,platen_dx,platen_dy,"
    "mean_sxx,mean_syy,mean_sxy,mean_exx,mean_eyy,mean_exy,mean_p,mean_q,mean_void_ratio,"
    "kinetic_energy,potential_energy,front_x,top_y,wall_per_step_s";

// This process's scratch directory, created afresh on first use and removed
// at the end when every test passed.
inline const std::string& ScratchDir() {
  static const std::string* const dir = [] {
    const fs::path d = fs::path(testing::TempDir()) / absl::StrCat("mpm_cli_test_", getpid());
    fs::remove_all(d);
    fs::create_directories(d);
    return new std::string(d.string());
  }();
  return *dir;
}

class ScratchCleanup : public testing::Environment {
 public:
  void TearDown() override {
    if (testing::UnitTest::GetInstance()->Passed()) fs::remove_all(ScratchDir());
  }
};
[[maybe_unused]] inline testing::Environment* const kCleanup =
    testing::AddGlobalTestEnvironment(new ScratchCleanup);

inline std::string TempPath(const std::string& name) { return ScratchDir() + "/" + name; }

// Prepared templates, shared by all test processes (written atomically).
inline std::string TemplateCache() {
  return (fs::path(testing::TempDir()) / "mpm_cli_test_templates").string();
}

inline std::string Quote(const std::string& s) { return absl::StrCat("'", s, "'"); }

struct Result {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

// Runs mpm_client with `args` (shell-quoted where needed).
inline Result RunClient(const std::string& args) {
  static int count = 0;
  const std::string err_path = TempPath(absl::StrCat("stderr", ++count, ".txt"));
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat(Quote(MPM_CLIENT_PATH), " ", args, " 2>", Quote(err_path)));
  Result r{run.exit_code, std::move(run.out), ReadFile(err_path)};
  std::remove(err_path.c_str());
  return r;
}

inline std::ostream& operator<<(std::ostream& os, const Result& r) {
  return os << "exit " << r.exit_code << "\n--- stdout:\n" << r.out << "--- stderr:\n" << r.err;
}

// The embedded server's workers and the shared template cache.
inline std::string CommonFlags() {
  return absl::StrCat(" --threads=2 --template-cache=", Quote(TemplateCache()));
}

// The small case: rows every 5 steps, frames every 10, no checkpoints.
inline Json SmallCase() {
  Json c = Json::parse(ReadFile(RVEHUB_SOURCE_DIR "/cases/single-element-biaxial.json"));
  c["solver"]["time_step"] = 0.002;
  c["solver"]["end_time"] = 0.07;  // 35 steps
  c["output"] = {{"frame_every", 10},
                 {"timeseries_every", 5},
                 {"checkpoint_every", 0},
                 {"progress_every", 10},
                 {"plot", "stress-strain"}};
  // The shipped checks are for the full 15 %, not these 35 steps.
  c.erase("checks");
  return c;
}

inline std::string WriteCase(const std::string& name, const Json& c) {
  const std::string path = TempPath(name + ".json");
  std::ofstream(path) << c.dump(2);
  return path;
}

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;

  int Column(const std::string& name) const {
    for (std::size_t k = 0; k < header.size(); ++k) {
      if (header[k] == name) return static_cast<int>(k);
    }
    ADD_FAILURE() << "no column " << name << " in " << absl::StrJoin(header, ",");
    return 0;
  }
  // The column as numbers.
  std::vector<double> Values(const std::string& name) const {
    const int k = Column(name);
    std::vector<double> v;
    for (const std::vector<std::string>& row : rows) {
      double x = NAN;
      EXPECT_TRUE(k < static_cast<int>(row.size()) && absl::SimpleAtod(row[k], &x))
          << name << " of row " << v.size();
      v.push_back(x);
    }
    return v;
  }
};

inline Csv ParseCsv(const std::string& text) {
  Csv csv;
  const std::vector<std::string> lines = absl::StrSplit(text, '\n', absl::SkipEmpty());
  for (std::size_t k = 0; k < lines.size(); ++k) {
    std::vector<std::string> cells = absl::StrSplit(lines[k], ',');
    if (k == 0) {
      csv.header = std::move(cells);
    } else {
      EXPECT_EQ(cells.size(), csv.header.size()) << "line " << k + 1 << ": " << lines[k];
      csv.rows.push_back(std::move(cells));
    }
  }
  return csv;
}

// timeseries.csv as text without its wall_per_step_s column (wall-clock
// time, the one column that differs between runs of the same case).
inline std::string WithoutWallTime(const std::string& text) {
  Csv csv = ParseCsv(text);
  if (csv.header.empty()) return "";
  const int k = csv.Column("wall_per_step_s");
  csv.header.erase(csv.header.begin() + k);
  std::string out = absl::StrCat(absl::StrJoin(csv.header, ","), "\n");
  for (std::vector<std::string>& row : csv.rows) {
    if (k < static_cast<int>(row.size())) row.erase(row.begin() + k);
    absl::StrAppend(&out, absl::StrJoin(row, ","), "\n");
  }
  return out;
}

// The "step_N" grids of results.xdmf, in file order, with their times.
inline std::vector<std::pair<std::string, std::string>> XdmfFrames(const std::string& xdmf) {
  std::vector<std::pair<std::string, std::string>> frames;
  const std::string grid = "<Grid Name=\"step_", time = "<Time Value=\"";
  for (std::size_t at = xdmf.find(grid); at != std::string::npos; at = xdmf.find(grid, at + 1)) {
    const std::size_t name = at + grid.size();
    const std::size_t t = xdmf.find(time, name);
    if (t == std::string::npos) {
      ADD_FAILURE() << "no time after grid at " << at;
      break;
    }
    const std::size_t value = t + time.size();
    frames.emplace_back(xdmf.substr(name, xdmf.find('"', name) - name),
                        xdmf.substr(value, xdmf.find('"', value) - value));
  }
  return frames;
}

// The small case run once per process, uninterrupted, on the embedded server.
struct RunOutput {
  std::string dir;
  Result result;
};
inline const RunOutput& ReferenceRun() {
  static const RunOutput* const run = [] {
    auto* r = new RunOutput;
    r->dir = TempPath("reference");
    r->result = RunClient(absl::StrCat("run ", Quote(WriteCase("reference", SmallCase())),
                                       " --out=", Quote(r->dir), CommonFlags()));
    return r;
  }();
  return *run;
}
}  // namespace rvehub::mpm::cli_test

#endif  // RVEHUB_TESTS_MPM_CLIENT_MPM_CLI_TEST_UTIL_H_
