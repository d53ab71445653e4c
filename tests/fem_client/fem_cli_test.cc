// The fem_client binary as a child process: its help and usage errors,
// check, run on the embedded server with every output, the same run on two
// loopback rve_servers giving the same timeseries bit for bit, summarise
// writing the run's summary again, and cases it refuses (a run it cannot do,
// a bad file) failing with a clear message and no misleading outputs, and a
// second run into a directory in use refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "nlohmann/json.hpp"
#include "tests/support/process_util.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using testing_util::ReadFile;

// This process's scratch directory, created afresh on first use and removed
// at the end when every test passed.
const std::string& ScratchDir() {
  static const std::string* const dir = [] {
    const fs::path d = fs::path(testing::TempDir()) / absl::StrCat("fem_cli_test_", getpid());
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
[[maybe_unused]] testing::Environment* const kCleanup =
    testing::AddGlobalTestEnvironment(new ScratchCleanup);

std::string TempPath(const std::string& name) { return ScratchDir() + "/" + name; }

std::string Quote(const std::string& s) { return absl::StrCat("'", s, "'"); }

std::string Case(const std::string& name) {
  return absl::StrCat(RVEHUB_SOURCE_DIR "/cases/", name, ".json");
}

// The embedded server's workers and the template cache the fem tests share.
std::string CommonFlags() {
  return absl::StrCat(" --threads=2 --template-cache=",
                      Quote((fs::path(testing::TempDir()) / "fem_test_templates").string()));
}

struct Result {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

std::ostream& operator<<(std::ostream& os, const Result& r) {
  return os << "exit " << r.exit_code << "\n--- stdout:\n" << r.out << "--- stderr:\n" << r.err;
}

Result RunClient(const std::string& args) {
  static int count = 0;
  const std::string err_path = TempPath(absl::StrCat("stderr", ++count, ".txt"));
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat(Quote(FEM_CLIENT_PATH), " ", args, " 2>", Quote(err_path)));
  Result r{run.exit_code, std::move(run.out), ReadFile(err_path)};
  std::remove(err_path.c_str());
  return r;
}

// timeseries.csv as text without its wall_step_s column (wall-clock time,
// the one column that differs between runs of the same case).
std::string WithoutWallTime(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  for (absl::string_view line : absl::StrSplit(text, '\n', absl::SkipEmpty())) {
    rows.push_back(absl::StrSplit(line, ','));
  }
  if (rows.empty()) return "";
  std::size_t k = 0;
  while (k < rows[0].size() && rows[0][k] != "wall_step_s") ++k;
  EXPECT_LT(k, rows[0].size()) << "no wall_step_s column";
  std::string out;
  for (std::vector<std::string>& row : rows) {
    if (k < row.size()) row.erase(row.begin() + k);
    absl::StrAppend(&out, absl::StrJoin(row, ","), "\n");
  }
  return out;
}

Json ReadJson(const std::string& path) {
  return Json::parse(ReadFile(path), nullptr, /*allow_exceptions=*/false);
}

// summary.json without its wall time.
Json WithoutWall(Json summary) {
  summary.erase("wall_s");
  return summary;
}

TEST(FemCliTest, HelpDocumentsEveryCommandAndOption) {
  const Result r = RunClient("--help");
  ASSERT_EQ(r.exit_code, 0) << r;
  for (const char* word : {"run", "check", "summarise", "--out", "--servers", "--threads",
                           "--token-file", "--tls-ca", "--timeout", "--template-cache",
                           "--stop-after", "--quiet", "--set", "resume", "checkpoint.h5"}) {
    EXPECT_TRUE(absl::StrContains(r.out, word)) << word;
  }
}

TEST(FemCliTest, UsageErrorsExitTwoWithAMessage) {
  const std::string c = Quote(Case("fem-single-element-ci"));
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"", "no command"},
           {"frobnicate " + c, "unknown command 'frobnicate'"},
           {"run", "run needs a case file"},
           {"run " + c, "--out=DIR is required"},
           {"run " + c + " --out=x --threads=0", "--threads must be an integer in 1..1024"},
           {"run " + c + " --out=x --stop-after=0", "--stop-after must be a positive integer"},
           {"run " + c + " --out=x --servers=nohost", "--servers"},
           {"run " + c + " --out=x --bogus=1", "bogus"},
           {"resume", "resume needs a checkpoint"},
           {"resume x/checkpoint.h5 --set=mesh.elements=[2,2]",
            "--set /mesh/elements: a resume may change only the Newton settings"},
           {"check " + c + " --out=x", "check takes no options"},
           {"summarise " + c, "summarise needs --out=DIR"}}) {
    SCOPED_TRACE(args);
    const Result r = RunClient(args);
    EXPECT_EQ(r.exit_code, 2) << r;
    EXPECT_TRUE(absl::StrContains(r.err, message)) << r.err;
  }
  EXPECT_FALSE(fs::exists("x"));
}

// A checkpoint that is not there is refused before the output directory
// (by default the checkpoint's) is made.
TEST(FemCliTest, AMissingCheckpointMakesNoDirectory) {
  const Result r = RunClient("resume no_such_run/checkpoint.h5");
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "no_such_run/checkpoint.h5: no such checkpoint file")) << r;
  EXPECT_FALSE(fs::exists("no_such_run"));
}

// A file that is not a checkpoint, resumed into a new directory: refused,
// and the directory the lock made for it is gone again.
TEST(FemCliTest, AnUnreadableCheckpointLeavesNoNewDirectory) {
  const std::string bad = TempPath("not_a_checkpoint.h5");
  std::ofstream(bad) << "not HDF5";
  const std::string out = TempPath("resumed_from_nothing");
  const Result r = RunClient(absl::StrCat("resume ", Quote(bad), " --out=", Quote(out)));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "not_a_checkpoint.h5")) << r;
  EXPECT_FALSE(fs::exists(out));
}

TEST(FemCliTest, CheckPrintsTheCaseInCanonicalForm) {
  const Result r = RunClient(absl::StrCat("check ", Quote(Case("fem-biaxial-coarse-ci")),
                                          " --set=solver.tolerance=0.005"));
  ASSERT_EQ(r.exit_code, 0) << r;
  const Json j = Json::parse(r.out, nullptr, /*allow_exceptions=*/false);
  ASSERT_TRUE(j.is_object()) << r.out;
  EXPECT_EQ(j["name"], "fem-biaxial-coarse-ci");
  EXPECT_EQ(j["solver"]["tolerance"], 0.005);
  EXPECT_EQ(j["loading"]["steps"], 5);  // the canonical form's step count
  const Result bad = RunClient(
      absl::StrCat("check ", Quote(Case("fem-single-element-ci")), " --set=/mesh/elements=[0,1]"));
  EXPECT_EQ(bad.exit_code, 1) << bad;
  EXPECT_TRUE(absl::StrContains(bad.err, "/mesh/elements/0: must be an integer")) << bad.err;
}

// The run's outputs, then summarise writing summary.json again from the
// timeseries alone.
TEST(FemCliTest, RunWritesEveryOutputAndSummariseWritesTheSummaryAgain) {
  const std::string dir = TempPath("run");
  const Result r = RunClient(absl::StrCat("run ", Quote(Case("fem-single-element-ci")),
                                          " --out=", Quote(dir), CommonFlags()));
  ASSERT_EQ(r.exit_code, 0) << r;
  for (const char* line : {"load step 5/5", "summary: peak_stress_Pa",
                           "check: pass final_stress_Pa", "fem_client: finished at", "time split",
                           "DEM engine", "FEM (assembly, solves)", "DEM steps per increment"}) {
    EXPECT_TRUE(absl::StrContains(r.err, line)) << line;
  }
  for (const char* file : {"timeseries.csv", "iterations.csv", "summary.json", "plot.png",
                           "results.h5", "results.xdmf", "run.json"}) {
    EXPECT_TRUE(fs::exists(fs::path(dir) / file)) << file;
  }
  const Json run = ReadJson(dir + "/run.json");
  ASSERT_TRUE(run.is_object());
  EXPECT_EQ(run["program"], "fem_client");
  EXPECT_EQ(run["command"], "run");
  EXPECT_EQ(run["outcome"], "finished");
  EXPECT_EQ(run["final_step"], 5);
  EXPECT_EQ(run["case"]["name"], "fem-single-element-ci");
  EXPECT_FALSE(run["end"].is_null());
  const Json summary = ReadJson(dir + "/summary.json");
  ASSERT_TRUE(summary.is_object());
  EXPECT_GT(summary["peak_stress_Pa"].get<double>(), 2e5);
  EXPECT_EQ(summary["peak_strain"], 0.01);

  fs::remove(dir + "/summary.json");
  fs::remove(dir + "/plot.png");
  const Result again = RunClient(
      absl::StrCat("summarise ", Quote(Case("fem-single-element-ci")), " --out=", Quote(dir)));
  ASSERT_EQ(again.exit_code, 0) << again;
  EXPECT_TRUE(absl::StrContains(again.out, "summary: peak_stress_Pa")) << again.out;
  EXPECT_EQ(ReadJson(dir + "/summary.json"), summary);
  EXPECT_TRUE(fs::exists(dir + "/plot.png"));
  EXPECT_TRUE(absl::StrContains(again.out, "check: pass final_stress_Pa")) << again.out;

  // A check the run misses: its line says FAIL and the exit status is 3.
  const Result missed =
      RunClient(absl::StrCat("summarise ", Quote(Case("fem-single-element-ci")),
                             " --out=", Quote(dir), " --set=/checks/0/reference=300000"));
  EXPECT_EQ(missed.exit_code, 3) << missed;
  EXPECT_TRUE(absl::StrContains(missed.out, "check: FAIL final_stress_Pa")) << missed.out;
  EXPECT_TRUE(absl::StrContains(missed.err, "a check failed")) << missed.err;
}

// Two rve_server processes share the RVEs of the coarse biaxial specimen;
// the results are the embedded server's, bit for bit, and so are those of a
// run stopped on the embedded server and resumed on the two.
TEST(FemCliTest, RemoteServersGiveTheEmbeddedResult) {
  const std::string embedded = TempPath("embedded");
  const Result e = RunClient(absl::StrCat("run ", Quote(Case("fem-biaxial-coarse-ci")),
                                          " --out=", Quote(embedded), " --quiet", CommonFlags()));
  ASSERT_EQ(e.exit_code, 0) << e;
  // From here gRPC polls briefly, so that the child notices a closed channel quickly.
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);
  testing_util::ServerProcess a(RVE_SERVER_PATH, TempPath("server-a.log"));
  testing_util::ServerProcess b(RVE_SERVER_PATH, TempPath("server-b.log"));
  ASSERT_FALSE(a.address().empty()) << a.Log();
  ASSERT_FALSE(b.address().empty()) << b.Log();
  EXPECT_TRUE(absl::StartsWith(a.address(), "127.0.0.1:")) << a.address();
  const std::string remote = TempPath("remote");
  const Result r = RunClient(absl::StrCat("run ", Quote(Case("fem-biaxial-coarse-ci")),
                                          " --out=", Quote(remote), " --servers=", a.address(), ",",
                                          b.address(), " --quiet", CommonFlags()));
  ASSERT_EQ(r.exit_code, 0) << r << "\nserver logs:\n" << a.Log() << b.Log();
  EXPECT_TRUE(absl::StrContains(r.err, "creating 32 RVEs (one per Gauss point) on 2 server(s)"))
      << r.err;
  const std::string expected = WithoutWallTime(ReadFile(embedded + "/timeseries.csv"));
  ASSERT_FALSE(expected.empty());
  EXPECT_EQ(WithoutWallTime(ReadFile(remote + "/timeseries.csv")), expected);
  EXPECT_EQ(WithoutWall(ReadJson(remote + "/summary.json")),
            WithoutWall(ReadJson(embedded + "/summary.json")));
  // Stopped on the embedded server, resumed on the two: the same run.
  const std::string moved = TempPath("moved");
  const Result stopped =
      RunClient(absl::StrCat("run ", Quote(Case("fem-biaxial-coarse-ci")), " --out=", Quote(moved),
                             " --stop-after=2 --quiet", CommonFlags()));
  ASSERT_EQ(stopped.exit_code, 0) << stopped;
  EXPECT_TRUE(absl::StrContains(stopped.err, "continue with: fem_client resume")) << stopped.err;
  EXPECT_EQ(ReadJson(moved + "/run.json")["last_checkpoint"]["step"], 2);
  const Result resumed =
      RunClient(absl::StrCat("resume ", Quote(moved + "/checkpoint.h5"), " --servers=", a.address(),
                             ",", b.address(), " --quiet", CommonFlags()));
  ASSERT_EQ(resumed.exit_code, 0) << resumed;
  EXPECT_TRUE(absl::StrContains(resumed.err, "resumed ")) << resumed.err;
  EXPECT_EQ(WithoutWallTime(ReadFile(moved + "/timeseries.csv")), expected);
  const Json record = ReadJson(moved + "/run.json");
  ASSERT_TRUE(record.is_object());
  EXPECT_EQ(record["command"], "resume");
  EXPECT_EQ(record["outcome"], "finished");
  ASSERT_TRUE(record.contains("previous") && record["previous"][0].contains("last_checkpoint"))
      << record.dump(2);
  EXPECT_EQ(record["previous"][0]["last_checkpoint"]["step"], 2);
  EXPECT_EQ(a.Stop(), 0) << a.Log();
  EXPECT_EQ(b.Stop(), 0) << b.Log();
}

// A case that cannot run: a clear error, and no output directory, run
// record or results that would pass for a run.
TEST(FemCliTest, ARefusedCaseFailsClearlyAndWritesNothing) {
  const std::string dir = TempPath("refused");
  // A pin at the middle of a face with no node there (two along it): the
  // case is refused as it is read.
  const Result r =
      RunClient(absl::StrCat("run ", Quote(Case("fem-single-element-ci")),
                             " --set=/boundaries/0/pin=middle --out=", Quote(dir), CommonFlags()));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err,
                                "/boundaries/0/pin: the left face has 2 nodes, none at its "
                                "middle"))
      << r.err;
  EXPECT_FALSE(fs::exists(dir));
  // A case file that does not parse: named, nothing written.
  const std::string bad = TempPath("bad.json");
  std::ofstream(bad) << R"({"name": "bad", "mesh": {"size": [1, 1]}})";
  const Result b = RunClient(absl::StrCat("run ", Quote(bad), " --out=", Quote(dir)));
  EXPECT_EQ(b.exit_code, 1) << b;
  EXPECT_TRUE(absl::StrContains(b.err, bad)) << b.err;
  EXPECT_FALSE(fs::exists(dir));
  // summarise of a directory without a run: the missing timeseries named.
  const Result s = RunClient(
      absl::StrCat("summarise ", Quote(Case("fem-single-element-ci")), " --out=", Quote(dir)));
  EXPECT_EQ(s.exit_code, 1) << s;
  EXPECT_TRUE(absl::StrContains(s.err, "timeseries.csv")) << s.err;
}

// A load step larger than the RVEs take in one call (|V − I| ≤ 0.05): with
// no cut-backs allowed the run ends at its first step naming the bound, and
// its outputs say it failed (no summary; the timeseries ends before the
// step).
TEST(FemCliTest, ALoadStepTooLargeForTheServersEndsTheRunNamingTheBound) {
  const std::string dir = TempPath("too-large");
  const Result r = RunClient(
      absl::StrCat("run ", Quote(Case("fem-single-element-ci")),
                   " --set=/loading/end_axial_strain=0.1 --set=/loading/steps=2",
                   " '--set=/solver={\"max_cutbacks\": 0}'", " --out=", Quote(dir), CommonFlags()));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "load step 1 (a part of 1 of it, after 0 cut-backs)"))
      << r.err;
  EXPECT_TRUE(absl::StrContains(r.err, "exceeds the per-call limit 0.05")) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/summary.json"));
  const Json run = ReadJson(dir + "/run.json");
  ASSERT_TRUE(run.is_object()) << ReadFile(dir + "/run.json");
  EXPECT_EQ(run.value("outcome", ""), "failed") << run.dump();
  EXPECT_TRUE(absl::StrContains(run.value("error", ""), "per-call limit")) << run.dump();
  const std::vector<std::string> rows =
      absl::StrSplit(ReadFile(dir + "/timeseries.csv"), '\n', absl::SkipEmpty());
  ASSERT_EQ(rows.size(), 2u);  // the header and step 0
  EXPECT_TRUE(rows[1].starts_with("0,")) << rows[1];
}

// While one run writes into a directory, a second run into it is refused at
// its start, naming the first run's pid; once the first has ended (killed,
// even), a run there goes ahead.
TEST(FemCliTest, ADirectoryInUseByAnotherRunIsRefused) {
  const std::string dir = TempPath("in-use");
  const std::string cache = (fs::path(testing::TempDir()) / "fem_test_templates").string();
  // 5000 load steps: killed long before the end.
  testing_util::ChildProcess first(
      {FEM_CLIENT_PATH, "run", Case("fem-single-element-ci"), "--set=/loading/steps=5000",
       "--out=" + dir, "--threads=2", "--template-cache=" + cache},
      TempPath("in-use-first.txt"));
  const std::string holder = absl::StrCat(first.pid(), " ");
  for (int i = 0; i < 600 && !ReadFile(dir + "/.lock").starts_with(holder); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(ReadFile(dir + "/.lock").starts_with(holder))
      << ReadFile(TempPath("in-use-first.txt"));
  const Result second = RunClient(absl::StrCat("run ", Quote(Case("fem-single-element-ci")),
                                               " --out=", Quote(dir), CommonFlags()));
  EXPECT_EQ(second.exit_code, 1) << second;
  EXPECT_TRUE(absl::StrContains(
      second.err, absl::StrCat(dir, " is in use by another run (pid ", first.pid(), ")")))
      << second;
  EXPECT_FALSE(absl::StrContains(second.err, "HDF5")) << second;
  ASSERT_TRUE(first.Running()) << "the first run ended: " << ReadFile(TempPath("in-use-first.txt"));

  first.Kill();
  const Result after = RunClient(absl::StrCat("run ", Quote(Case("fem-single-element-ci")),
                                              " --out=", Quote(dir), CommonFlags()));
  EXPECT_EQ(after.exit_code, 0) << after;
}

}  // namespace
}  // namespace rvehub::fem
