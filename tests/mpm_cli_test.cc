// The mpm_client binary (mpm_client/mpm_client_main.cc), run as a child
// process: usage and exit codes, `check` and its JSON-pointer messages, one
// short run of a small single-element case and its outputs, a run stopped
// and resumed from its checkpoint, and runs on real rve_server processes,
// whose timeseries equal the embedded server's.
//
// The small case is cases/single-element-biaxial.json with a fixed 2 ms time
// step and 35 steps (0.07 s); prepared templates are shared by every test
// process through one cache directory.
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
#include "tests/process_util.h"

namespace rvehub::mpm {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using testing_util::ReadFile;

constexpr char kHeader[] =
    "time,step,left_fx,left_fy,bottom_fx,bottom_fy,platen_fx,platen_fy,platen_dx,platen_dy,"
    "mean_sxx,mean_syy,mean_sxy,mean_exx,mean_eyy,mean_exy,mean_p,mean_q,mean_void_ratio,"
    "kinetic_energy,potential_energy,front_x,top_y,wall_per_step_s";

// This process's scratch directory, created afresh on first use and removed
// at the end when every test passed.
const std::string& ScratchDir() {
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
[[maybe_unused]] testing::Environment* const kCleanup =
    testing::AddGlobalTestEnvironment(new ScratchCleanup);

std::string TempPath(const std::string& name) { return ScratchDir() + "/" + name; }

// Prepared templates, shared by all test processes (written atomically).
std::string TemplateCache() {
  return (fs::path(testing::TempDir()) / "mpm_cli_test_templates").string();
}

std::string Quote(const std::string& s) { return absl::StrCat("'", s, "'"); }

struct Result {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

// Runs mpm_client with `args` (shell-quoted where needed).
Result RunClient(const std::string& args) {
  static int count = 0;
  const std::string err_path = TempPath(absl::StrCat("stderr", ++count, ".txt"));
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat(Quote(MPM_CLIENT_PATH), " ", args, " 2>", Quote(err_path)));
  Result r{run.exit_code, std::move(run.out), ReadFile(err_path)};
  std::remove(err_path.c_str());
  return r;
}

std::ostream& operator<<(std::ostream& os, const Result& r) {
  return os << "exit " << r.exit_code << "\n--- stdout:\n" << r.out << "--- stderr:\n" << r.err;
}

// The embedded server's workers and the shared template cache.
std::string CommonFlags() {
  return absl::StrCat(" --threads=2 --template-cache=", Quote(TemplateCache()));
}

// The small case: rows every 5 steps, frames every 10, no checkpoints.
Json SmallCase() {
  Json c = Json::parse(ReadFile(RVEHUB_SOURCE_DIR "/cases/single-element-biaxial.json"));
  c["solver"]["time_step"] = 0.002;
  c["solver"]["end_time"] = 0.07;  // 35 steps
  c["output"] = {{"frame_every", 10},
                 {"timeseries_every", 5},
                 {"checkpoint_every", 0},
                 {"progress_every", 10},
                 {"plot", "stress-strain"}};
  return c;
}

std::string WriteCase(const std::string& name, const Json& c) {
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

Csv ParseCsv(const std::string& text) {
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
std::string WithoutWallTime(const std::string& text) {
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
std::vector<std::pair<std::string, std::string>> XdmfFrames(const std::string& xdmf) {
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
const RunOutput& ReferenceRun() {
  static const RunOutput* const run = [] {
    auto* r = new RunOutput;
    r->dir = TempPath("reference");
    r->result = RunClient(absl::StrCat("run ", Quote(WriteCase("reference", SmallCase())),
                                       " --out=", Quote(r->dir), CommonFlags()));
    return r;
  }();
  return *run;
}

// ---------------------------------------------------------------------------
// Usage.

TEST(MpmCliTest, HelpDocumentsEveryCommandAndOption) {
  const Result r = RunClient("--help");
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(r.err, "");
  for (const char* text : {"mpm_client run CASE.json --out=DIR",
                           "mpm_client resume CHECKPOINT.h5",
                           "mpm_client check CASE.json",
                           "mpm_client summarise CASE.json",
                           "--out=DIR",
                           "--servers=H:P,...",
                           "--threads=N",
                           "--token-file=FILE",
                           "--tls-ca=FILE",
                           "--timeout=SECONDS",
                           "--template-cache=DIR",
                           "--stop-after=N",
                           "--quiet",
                           "--set=PATH=VALUE",
                           "results.h5",
                           "results.xdmf",
                           "timeseries.csv",
                           "plot.png",
                           "run.json",
                           "checkpoint.h5",
                           "Exit status"}) {
    EXPECT_TRUE(absl::StrContains(r.out, text)) << "no " << text << " in\n" << r.out;
  }
  EXPECT_EQ(RunClient("-h").out, r.out);
  // --help wins over anything else on the line.
  const Result also = RunClient("run nothing.json --bogus=1 --help");
  EXPECT_EQ(also.exit_code, 0) << also;
  EXPECT_EQ(also.out, r.out);
}

TEST(MpmCliTest, UsageErrorsExitTwoWithAMessage) {
  const std::string case_path = Quote(WriteCase("usage", SmallCase()));
  const std::string out_dir = TempPath("usage_out");
  const std::string out = absl::StrCat(" --out=", Quote(out_dir));
  struct Case {
    std::string args, message;
  };
  for (const Case& c : std::vector<Case>{
           {"", "no command (see --help)"},
           {"frobnicate", "unknown command 'frobnicate'"},
           {"run", "run needs a case file"},
           {"resume", "resume needs a checkpoint"},
           {"check", "check needs a case file"},
           {absl::StrCat("run ", case_path), "--out=DIR is required"},
           {absl::StrCat("run ", case_path, " --quiet"), "--out=DIR is required"},
           {absl::StrCat("run ", case_path, out, " --bogus=1"), "unknown option --bogus"},
           {absl::StrCat("run ", case_path, " --out"), "--out needs a value (--out=...)"},
           {absl::StrCat("run ", case_path, " --out="), "--out=DIR needs a directory"},
           {absl::StrCat("run ", case_path, " extra", out), "unexpected argument 'extra'"},
           {absl::StrCat("run ", case_path, out, " --threads=0"), "--threads must be"},
           {absl::StrCat("run ", case_path, out, " --threads=two"), "--threads must be"},
           {absl::StrCat("run ", case_path, out, " --timeout=-1"), "--timeout must be"},
           {absl::StrCat("run ", case_path, out, " --stop-after=0"), "--stop-after must be"},
           {absl::StrCat("run ", case_path, out, " --servers=,"), "--servers lists no server"},
           // gRPC dialled port 70000 − 65536 = 4464.
           {absl::StrCat("run ", case_path, out, " --servers=127.0.0.1:70000"),
            "--servers: \"127.0.0.1:70000\" is not HOST:PORT with a port in 1..65535"},
           {absl::StrCat("run ", case_path, out, " --servers=127.0.0.1:1,127.0.0.1:"),
            "--servers: \"127.0.0.1:\" is not HOST:PORT"},
           {absl::StrCat("run ", case_path, out, " --quiet=no"), "--quiet takes no value"},
           {absl::StrCat("resume x.h5 --stop-after=-3"), "--stop-after must be"},
           {absl::StrCat("check ", case_path, out), "check takes no options (got --out)"},
           {absl::StrCat("run ", case_path, out, " --set=rve.min_steps"), "--set needs PATH=VALUE"},
           {absl::StrCat("run ", case_path, out, " --set"), "--set needs a value"},
           {"resume x.h5 --set=/rve/min_steps=4", "resume takes no --set"},
           {absl::StrCat("run ", case_path, out, " --end-time=2"), "--end-time is for resume"},
           {"resume x.h5 --end-time=0", "--end-time must be a time in (0, 1e6] s"},
           {"resume x.h5 --end-time=soon", "--end-time must be a time"},
           {absl::StrCat("run ", case_path, out, " --cfl=0.25"), "--cfl is for resume"},
           {"resume x.h5 --cfl=0", "--cfl must be a number in (0, 1]"},
           {"resume x.h5 --cfl=1.5", "--cfl must be a number in (0, 1]"},
           {absl::StrCat("run ", case_path, out, " --f-bar=nodal"), "--f-bar is for resume"},
           {"resume x.h5 --f-bar=cell", "--f-bar must be one of none, nodal, got \"cell\""},
           {absl::StrCat("run ", case_path, out, " --nonlocal-radius=0.2"),
            "--nonlocal-radius is for resume"},
           {"resume x.h5 --nonlocal-radius=-1", "--nonlocal-radius must be a length in [0, 1e3] m"},
           {"resume x.h5 --nonlocal-radius=wide",
            "--nonlocal-radius must be a length in [0, 1e3] m"},
           {absl::StrCat("run ", case_path, out, " --nonlocal-fraction=0.5"),
            "--nonlocal-fraction is for resume"},
           {"resume x.h5 --nonlocal-fraction=0", "--nonlocal-fraction must be a number in (0, 1]"},
       }) {
    const Result r = RunClient(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << ": " << r;
    // One line naming the problem.
    EXPECT_TRUE(r.err.starts_with(absl::StrCat("mpm_client: ", c.message))) << c.args << ": " << r;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << c.args << ": " << r;
    EXPECT_EQ(r.out, "") << c.args;
  }
  EXPECT_FALSE(fs::exists(out_dir)) << "no output on a usage error";
}

// ---------------------------------------------------------------------------
// check.

TEST(MpmCliTest, CheckPrintsTheCaseInCanonicalForm) {
  const Result r = RunClient(absl::StrCat("check ", Quote(WriteCase("check", SmallCase()))));
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(r.err, "");
  const Json c = Json::parse(r.out, nullptr, /*allow_exceptions=*/false);
  ASSERT_FALSE(c.is_discarded()) << r.out;
  EXPECT_EQ(c["name"], "single-element-biaxial");
  EXPECT_EQ(c["solver"]["time_step"], 0.002);
  EXPECT_EQ(c["solver"]["end_time"], 0.07);
  EXPECT_EQ(c["solver"]["shape"], "gimp");
  EXPECT_EQ(c["walls"][0]["kind"], "smooth");  // "roller" in canonical form
  EXPECT_EQ(c["tractions"][0]["traction"], Json::array({-100e3, 0.0}));  // tension +
  EXPECT_EQ(c["rve"]["max_inertial_number"], 0.0);                       // defaults filled in
  // The canonical form is a valid case file itself and prints the same.
  const std::string again = TempPath("check_again.json");
  std::ofstream(again) << r.out;
  EXPECT_EQ(RunClient(absl::StrCat("check ", Quote(again))).out, r.out);
}

TEST(MpmCliTest, CheckNamesTheBadValueByItsJsonPointer) {
  struct Case {
    std::string name;
    std::function<void(Json&)> edit;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {"pic_fraction", [](Json& j) { j["solver"]["pic_fraction"] = 2; },
            "/solver/pic_fraction: must be in [0, 1], got 2"},
           {"typo", [](Json& j) { j["solver"]["pic_fracton"] = 0.1; },
            "/solver/pic_fracton: unknown key (did you mean \"pic_fraction\"?"},
           {"points", [](Json& j) { j["regions"][0]["points_per_cell_side"] = 0; },
            "/regions/0/points_per_cell_side: must be an integer in 1..8, got 0"},
           {"wall_kind", [](Json& j) { j["walls"][1]["kind"] = "sticky"; },
            "/walls/1/kind: unknown wall kind \"sticky\""},
           {"end_time", [](Json& j) { j["solver"].erase("end_time"); },
            "/solver/end_time: required key is missing"},
       }) {
    Json j = SmallCase();
    c.edit(j);
    const std::string path = WriteCase(absl::StrCat("bad_", c.name), j);
    const Result r = RunClient(absl::StrCat("check ", Quote(path)));
    EXPECT_EQ(r.exit_code, 1) << c.name << ": " << r;
    EXPECT_TRUE(r.err.starts_with(absl::StrCat("mpm_client: ", path, ": ", c.message)))
        << c.name << ": " << r.err;
    EXPECT_EQ(r.out, "") << c.name;
    // run validates the same way, before any work.
    const std::string out_dir = TempPath(absl::StrCat("bad_", c.name, "_out"));
    const Result run =
        RunClient(absl::StrCat("run ", Quote(path), " --out=", Quote(out_dir), CommonFlags()));
    EXPECT_EQ(run.exit_code, 1) << c.name << ": " << run;
    EXPECT_EQ(run.err, r.err) << c.name;
    EXPECT_FALSE(fs::exists(out_dir)) << c.name;
  }

  const std::string syntax = TempPath("syntax.json");
  std::ofstream(syntax) << "{\"grid\": tru";
  const Result bad_json = RunClient(absl::StrCat("check ", Quote(syntax)));
  EXPECT_EQ(bad_json.exit_code, 1) << bad_json;
  EXPECT_TRUE(absl::StrContains(bad_json.err, absl::StrCat(syntax, ": line 1, column ")))
      << bad_json.err;

  const std::string missing = TempPath("no_such_case.json");
  const Result not_found = RunClient(absl::StrCat("check ", Quote(missing)));
  EXPECT_EQ(not_found.exit_code, 1) << not_found;
  EXPECT_TRUE(absl::StrContains(not_found.err, absl::StrCat("'", missing, "'"))) << not_found.err;
  EXPECT_TRUE(absl::StrContains(not_found.err, "No such file")) << not_found.err;

  const Result directory = RunClient(absl::StrCat("check ", Quote(ScratchDir())));
  EXPECT_EQ(directory.exit_code, 1) << directory;
  EXPECT_TRUE(absl::StrContains(directory.err, "is a directory")) << directory.err;
}

// ---------------------------------------------------------------------------
// run and resume, embedded server.

TEST(MpmCliTest, RunWritesEveryOutput) {
  const RunOutput& run = ReferenceRun();
  const Result& r = run.result;
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(r.out, "");
  EXPECT_TRUE(absl::StrContains(r.err, "creating 4 RVEs on 1 server(s)")) << r.err;
  EXPECT_TRUE(absl::StrContains(r.err, "\nstep 10/35  t = 0.02 s")) << r.err;  // progress
  EXPECT_TRUE(absl::StrContains(r.err, "\nmpm_client: finished at step 35, t = 0.07 s; 35 steps"))
      << r.err;
  EXPECT_TRUE(r.err.ends_with(absl::StrCat("\nmpm_client: outputs in ", run.dir, "\n"))) << r.err;
  // Templates went to --template-cache, not DIR/templates.
  EXPECT_TRUE(fs::exists(fs::path(TemplateCache()) / "SET-dense-seed1.h5"));
  EXPECT_FALSE(fs::exists(run.dir + "/templates"));
  EXPECT_FALSE(fs::exists(run.dir + "/checkpoint.h5")) << "checkpoints are off";

  // timeseries.csv: a row every 5 steps and at the end, every value finite.
  const Csv csv = ParseCsv(ReadFile(run.dir + "/timeseries.csv"));
  EXPECT_EQ(absl::StrJoin(csv.header, ","), kHeader);
  const std::vector<double> steps = csv.Values("step");
  EXPECT_EQ(steps, (std::vector<double>{0, 5, 10, 15, 20, 25, 30, 35}));
  for (const std::vector<std::string>& row : csv.rows) {
    for (const std::string& cell : row) {
      double v = NAN;
      EXPECT_TRUE(absl::SimpleAtod(cell, &v) && std::isfinite(v)) << cell;
    }
  }
  ASSERT_EQ(csv.rows.size(), 8u);
  // Compression +: the platen moved down, the soil pushes it up, and the
  // mean vertical stress and strain grew from the 100 kPa start.
  EXPECT_LT(csv.Values("platen_dy").back(), 0);
  EXPECT_GT(csv.Values("platen_fy").back(), 0);
  EXPECT_GT(csv.Values("mean_eyy").back(), 0);
  EXPECT_NEAR(csv.Values("mean_p").front(), 100e3, 5e3);
  EXPECT_GT(csv.Values("mean_syy").back(), csv.Values("mean_syy").front());
  EXPECT_GT(csv.Values("kinetic_energy").back(), 0);

  // results.h5 (HDF5) and results.xdmf: frames every 10 steps and at the
  // end, at the timeseries' times (the same doubles).
  const std::string h5 = ReadFile(run.dir + "/results.h5");
  EXPECT_TRUE(h5.starts_with("\x89HDF\r\n\x1a\n")) << "not HDF5";
  const std::string xdmf = ReadFile(run.dir + "/results.xdmf");
  EXPECT_TRUE(absl::StrContains(xdmf, "<Xdmf")) << xdmf;
  EXPECT_TRUE(absl::StrContains(xdmf, "results.h5:/frames/35/stress")) << xdmf;
  const std::vector<std::pair<std::string, std::string>> frames = XdmfFrames(xdmf);
  std::vector<std::string> frame_steps;
  const std::vector<double> times = csv.Values("time");
  for (const auto& [step, time] : frames) {
    frame_steps.push_back(step);
    const int row = std::stoi(step) / 5;
    ASSERT_LT(row, static_cast<int>(times.size()));
    double t = NAN;
    EXPECT_TRUE(absl::SimpleAtod(time, &t)) << time;
    EXPECT_EQ(t, times[row]) << "frame " << step;
  }
  EXPECT_EQ(frame_steps, (std::vector<std::string>{"0", "10", "20", "30", "35"}));

  const std::string png = ReadFile(run.dir + "/plot.png");
  EXPECT_TRUE(png.starts_with("\x89PNG\r\n\x1a\n")) << "not a PNG";
  EXPECT_GT(png.size(), 1000u);
}

// summary.json: written by the run (the nominal biaxial peak), and again,
// the same bytes, by `summarise` from the run's timeseries, which also prints
// the figures; summarise needs --out and takes no run options.
TEST(MpmCliTest, SummariseRewritesTheRunsSummary) {
  const RunOutput& run = ReferenceRun();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const std::string written = ReadFile(run.dir + "/summary.json");
  EXPECT_TRUE(absl::StrContains(written, "\"peak_stress_Pa\"")) << written;
  EXPECT_TRUE(absl::StrContains(run.result.err, "summary: peak_stress_Pa = ")) << run.result.err;
  const std::string case_path = WriteCase("reference", SmallCase());
  fs::remove(run.dir + "/summary.json");
  const Result r =
      RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(run.dir)));
  EXPECT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(absl::StrContains(r.out, "summary: final_strain = ")) << r.out;
  EXPECT_EQ(ReadFile(run.dir + "/summary.json"), written);

  // A damaged timeseries (a NaN pasted into its last row) is refused with
  // its row and column, and no summary is written from it.
  const std::string damaged = TempPath("damaged-timeseries");
  fs::create_directories(damaged);
  std::string csv = ReadFile(run.dir + "/timeseries.csv");
  ASSERT_TRUE(csv.ends_with("\n"));
  const std::size_t last_row = csv.rfind('\n', csv.size() - 2) + 1;
  csv.replace(last_row, csv.find(',', last_row) - last_row, "nan");  // its time
  std::ofstream(damaged + "/timeseries.csv") << csv;
  const Result bad =
      RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(damaged)));
  EXPECT_EQ(bad.exit_code, 1) << bad;
  EXPECT_TRUE(absl::StrContains(bad.err, " column time: NaN, which no run writes")) << bad;
  EXPECT_FALSE(fs::exists(damaged + "/summary.json"));

  EXPECT_EQ(RunClient(absl::StrCat("summarise ", Quote(case_path))).exit_code, 2);
  EXPECT_EQ(RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(run.dir),
                                   " --threads=2"))
                .exit_code,
            2);
}

// Stopped after 20 steps (its checkpoint there), then resumed into the same
// directory: the timeseries equals the uninterrupted run's, and results.xdmf
// holds every frame once.
TEST(MpmCliTest, StopAndResumeMatchesTheUninterruptedRun) {
  const RunOutput& reference = ReferenceRun();
  ASSERT_EQ(reference.result.exit_code, 0) << reference.result;
  Json c = SmallCase();
  c["output"]["checkpoint_every"] = 20;
  const std::string dir = TempPath("resume");
  const Result stopped =
      RunClient(absl::StrCat("run ", Quote(WriteCase("resume", c)), " --out=", Quote(dir),
                             " --stop-after=20 --quiet", CommonFlags()));
  ASSERT_EQ(stopped.exit_code, 0) << stopped;
  EXPECT_TRUE(absl::StrContains(stopped.err, "mpm_client: stopped at step 20, t = 0.04 s"))
      << stopped.err;
  EXPECT_FALSE(absl::StrContains(stopped.err, "\nstep ")) << "--quiet: " << stopped.err;
  EXPECT_TRUE(fs::exists(dir + "/checkpoint.h5"));
  EXPECT_FALSE(fs::exists(dir + "/plot.png")) << "no plot before the end";
  EXPECT_EQ(ParseCsv(ReadFile(dir + "/timeseries.csv")).Values("step").back(), 20);

  // Without --out, into the checkpoint's directory.
  const Result resumed =
      RunClient(absl::StrCat("resume ", Quote(dir + "/checkpoint.h5"), " --quiet --threads=2"));
  ASSERT_EQ(resumed.exit_code, 0) << resumed;
  EXPECT_TRUE(absl::StrContains(resumed.err, "resumed ")) << resumed.err;
  EXPECT_TRUE(absl::StrContains(resumed.err, " at step 20")) << resumed.err;
  EXPECT_TRUE(
      absl::StrContains(resumed.err, "mpm_client: finished at step 35, t = 0.07 s; 15 steps"))
      << resumed.err;
  EXPECT_TRUE(resumed.err.ends_with(absl::StrCat("\nmpm_client: outputs in ", dir, "\n")))
      << resumed.err;

  const std::string expected = WithoutWallTime(ReadFile(reference.dir + "/timeseries.csv"));
  ASSERT_FALSE(expected.empty());
  EXPECT_EQ(WithoutWallTime(ReadFile(dir + "/timeseries.csv")), expected);
  std::vector<std::string> frame_steps;
  for (const auto& [step, time] : XdmfFrames(ReadFile(dir + "/results.xdmf"))) {
    frame_steps.push_back(step);
  }
  EXPECT_EQ(frame_steps, (std::vector<std::string>{"0", "10", "20", "30", "35"}));
  EXPECT_TRUE(ReadFile(dir + "/plot.png").starts_with("\x89PNG"));

  const Result not_a_checkpoint =
      RunClient(absl::StrCat("resume ", Quote(dir + "/results.h5"), " --quiet"));
  EXPECT_EQ(not_a_checkpoint.exit_code, 1) << not_a_checkpoint;
  const Result missing = RunClient(absl::StrCat("resume ", Quote(TempPath("none.h5"))));
  EXPECT_EQ(missing.exit_code, 1) << missing;
  EXPECT_TRUE(absl::StrContains(missing.err, TempPath("none.h5"))) << missing.err;
}

// --set overrides case fields before validation: check prints the result,
// and a bad value gets the file's message for its JSON pointer.
TEST(MpmCliTest, SetOverridesCaseFieldsValidatedLikeTheFile) {
  const std::string path = Quote(WriteCase("set", SmallCase()));
  const Result r =
      RunClient(absl::StrCat("check ", path,
                             " --set=/solver/end_time=0.05 --set=solver.shape=linear"
                             " --set=name=sweep-1 --set=regions.0.points_per_cell_side=1"
                             " --set=/solver/gravity=[0,-9.81]"));
  ASSERT_EQ(r.exit_code, 0) << r;
  const Json c = Json::parse(r.out, nullptr, /*allow_exceptions=*/false);
  ASSERT_FALSE(c.is_discarded()) << r.out;
  EXPECT_EQ(c["solver"]["end_time"], 0.05);
  EXPECT_EQ(c["solver"]["shape"], "linear");
  EXPECT_EQ(c["name"], "sweep-1");  // a bare word is a string
  EXPECT_EQ(c["regions"][0]["points_per_cell_side"], 1);
  EXPECT_EQ(c["solver"]["gravity"], Json::array({0.0, -9.81}));
  // Later overrides win.
  const Result twice =
      RunClient(absl::StrCat("check ", path, " --set=rve.min_steps=3 --set=/rve/min_steps=5"));
  ASSERT_EQ(twice.exit_code, 0) << twice;
  EXPECT_EQ(Json::parse(twice.out)["rve"]["min_steps"], 5);

  struct Case {
    std::string set, message;
  };
  for (const Case& bad : std::vector<Case>{
           {"/solver/pic_fraction=2", "/solver/pic_fraction: must be in [0, 1], got 2"},
           {"solver.pic_fracton=0.1", "/solver/pic_fracton: unknown key"},
           {"/solver/shape=\"cubic\"", "/solver/shape: unknown shape function \"cubic\""},
           {"/nope/x=1", "--set /nope/x: /nope is not in the case"},
           {"/walls/99/kind=fixed", "--set /walls/99/kind: /walls/99 is not in the case"},
           {"/walls/99={}", "--set /walls/99: /walls has 2 elements"},
           {"/name/x=1", "--set /name/x: /name is not an object or array"},
           {"/bad~pointer=1", "--set /bad~pointer: not a JSON pointer"},
           {"bad~key=1", "/bad~0key: unknown key"},  // dotted: escaped as a key
       }) {
    const Result rejected = RunClient(absl::StrCat("check ", path, " '--set=", bad.set, "'"));
    EXPECT_EQ(rejected.exit_code, 1) << bad.set << ": " << rejected;
    EXPECT_TRUE(absl::StrContains(rejected.err, absl::StrCat(": ", bad.message)))
        << bad.set << ": " << rejected.err;
    EXPECT_EQ(rejected.out, "");
  }
}

// --stop-after always leaves a checkpoint where it stops, even when the
// case writes none, and says where; resuming it finishes the run with the
// uninterrupted run's timeseries. run.json records each invocation.
TEST(MpmCliTest, StopAfterWritesACheckpointEvenWithCheckpointsOff) {
  const RunOutput& reference = ReferenceRun();
  ASSERT_EQ(reference.result.exit_code, 0) << reference.result;
  const std::string dir = TempPath("stop_no_checkpoints");
  const Result stopped =
      RunClient(absl::StrCat("run ", Quote(WriteCase("stop_no_checkpoints", SmallCase())),
                             " --out=", Quote(dir), " --stop-after=10", CommonFlags()));
  ASSERT_EQ(stopped.exit_code, 0) << stopped;
  const std::string checkpoint = dir + "/checkpoint.h5";
  EXPECT_TRUE(fs::exists(checkpoint));
  EXPECT_TRUE(absl::StrContains(stopped.err, absl::StrCat("checkpoint written to ", checkpoint)))
      << stopped.err;
  EXPECT_TRUE(absl::StrContains(stopped.err, absl::StrCat("mpm_client resume ", checkpoint)))
      << stopped.err;
  const Json first = Json::parse(ReadFile(dir + "/run.json"));
  EXPECT_EQ(first["outcome"], "stopped");
  EXPECT_EQ(first["final_step"], 10);

  const Result resumed =
      RunClient(absl::StrCat("resume ", Quote(checkpoint), " --quiet --threads=2"));
  ASSERT_EQ(resumed.exit_code, 0) << resumed;
  EXPECT_TRUE(absl::StrContains(resumed.err, "mpm_client: finished at step 35")) << resumed.err;
  EXPECT_EQ(WithoutWallTime(ReadFile(dir + "/timeseries.csv")),
            WithoutWallTime(ReadFile(reference.dir + "/timeseries.csv")));
  const Json second = Json::parse(ReadFile(dir + "/run.json"));
  EXPECT_EQ(second["command"], "resume");
  EXPECT_EQ(second["outcome"], "finished");
  ASSERT_EQ(second["previous"].size(), 1u) << second.dump(2);
  EXPECT_EQ(second["previous"][0]["outcome"], "stopped");
  EXPECT_EQ(second["previous"][0]["command"], "run");
}

TEST(MpmCliTest, RunJsonRecordsTheRun) {
  const RunOutput& run = ReferenceRun();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const Json r = Json::parse(ReadFile(run.dir + "/run.json"), nullptr, false);
  ASSERT_TRUE(r.is_object()) << ReadFile(run.dir + "/run.json");
  EXPECT_EQ(r["program"], "mpm_client");
  EXPECT_FALSE(r["version"].get<std::string>().empty());
  EXPECT_EQ(r["command"], "run");
  ASSERT_TRUE(r["command_line"].is_array());
  EXPECT_EQ(r["command_line"][1], "run");
  EXPECT_EQ(r["command_line"][3], absl::StrCat("--out=", run.dir));
  EXPECT_FALSE(r["host"].get<std::string>().empty());
  // ISO 8601 UTC, the end not before the start (same format: compares as text).
  const std::string start = r["start"], end = r["end"];
  EXPECT_EQ(start.size(), 24u) << start;
  EXPECT_TRUE(start.ends_with("Z")) << start;
  EXPECT_LE(start, end);
  EXPECT_EQ(r["outcome"], "finished");
  EXPECT_EQ(r["final_step"], 35);
  // The case as run, in canonical form: what `check` prints.
  const Result check = RunClient(absl::StrCat("check ", Quote(TempPath("reference.json"))));
  ASSERT_EQ(check.exit_code, 0) << check;
  EXPECT_EQ(r["case"], Json::parse(check.out));
}

// Values that used to hang, overflow or run out of memory are refused with
// the field named, by check and by run before any work.
TEST(MpmCliTest, OutOfRangeCaseValuesFailCleanly) {
  struct Case {
    std::string name;
    std::function<void(Json&)> edit;
    std::string message;
  };
  for (const Case& c : std::vector<Case>{
           {"end_time", [](Json& j) { j["solver"]["end_time"] = 1e308; },
            "/solver/end_time: must be in (0, 1000000], got 1e+308"},
           {"min_steps",
            [](Json& j) {
              j["rve"] = {{"min_steps", 1e15}};
            },
            "/rve/min_steps: must be an integer in 0..100000, got 1e+15"},
           {"memory",
            [](Json& j) {
              j["grid"]["cells"] = {10000, 10000};
              j["regions"][0]["upper"] = {10000, 10000};
            },
            "/grid: the case needs about "},
       }) {
    Json j = SmallCase();
    c.edit(j);
    const std::string path = WriteCase(absl::StrCat("bound_", c.name), j);
    const Result check = RunClient(absl::StrCat("check ", Quote(path)));
    EXPECT_EQ(check.exit_code, 1) << c.name << ": " << check;
    EXPECT_TRUE(check.err.starts_with(absl::StrCat("mpm_client: ", path, ": ", c.message)))
        << c.name << ": " << check.err;
    const std::string out_dir = TempPath(absl::StrCat("bound_", c.name, "_out"));
    const Result run =
        RunClient(absl::StrCat("run ", Quote(path), " --out=", Quote(out_dir), CommonFlags()));
    EXPECT_EQ(run.exit_code, 1) << c.name << ": " << run;
    EXPECT_EQ(run.err, check.err) << c.name;
  }
  const Result memory = RunClient(absl::StrCat("check ", Quote(TempPath("bound_memory.json"))));
  EXPECT_TRUE(absl::StrContains(memory.err, "more than the limit of 32 GiB")) << memory.err;

  // A step count beyond the limit, known only once Δt is: refused at the start.
  Json j = SmallCase();
  j["solver"]["time_step"] = 1e-9;
  j["solver"]["end_time"] = 1e3;  // 1e12 steps
  const Result steps =
      RunClient(absl::StrCat("run ", Quote(WriteCase("bound_steps", j)),
                             " --quiet --out=", Quote(TempPath("bound_steps_out")), CommonFlags()));
  EXPECT_EQ(steps.exit_code, 1) << steps;
  EXPECT_TRUE(absl::StrContains(steps.err, "MPM steps, more than the limit of 1000000000"))
      << steps.err;
}

// A checkpoint that cannot be written (here: a file size limit, as a full
// disk would) fails the run with the file named, exit 1, no crash at exit.
TEST(MpmCliTest, FailedCheckpointWriteExitsOneWithoutCrashing) {
  ASSERT_EQ(ReferenceRun().result.exit_code, 0);  // the template is cached
  Json c = SmallCase();
  c["output"]["checkpoint_every"] = 10;
  const std::string dir = TempPath("full_disk");
  WriteCase("full_disk", c);
  // 150 blocks of 512 bytes hold frame 0 and 10 but not the checkpoint;
  // SIGXFSZ ignored: writes past the limit fail with EFBIG, as with ENOSPC.
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat("trap '' XFSZ; ulimit -f 150; ", Quote(MPM_CLIENT_PATH), " run ",
                   Quote(TempPath("full_disk.json")), " --out=", Quote(dir), " --quiet",
                   CommonFlags(), " 2>&1"));
  EXPECT_EQ(run.exit_code, 1) << run.out;
  EXPECT_TRUE(absl::StrContains(run.out, absl::StrCat("writing ", dir, "/checkpoint.h5")))
      << run.out;
  EXPECT_FALSE(fs::exists(dir + "/checkpoint.h5"));
  const Json record = Json::parse(ReadFile(dir + "/run.json"), nullptr, false);
  EXPECT_EQ(record["outcome"], "failed") << record;
}

// ---------------------------------------------------------------------------
// Remote servers.

TEST(MpmCliTest, UnreachableServerFailsNamingIt) {
  const std::string dir = TempPath("unreachable");
  const Result r = RunClient(absl::StrCat("run ", Quote(WriteCase("unreachable", SmallCase())),
                                          " --out=", Quote(dir), " --servers=127.0.0.1:1 --quiet",
                                          CommonFlags()));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "RVE server 127.0.0.1:1 is unreachable")) << r.err;
  EXPECT_FALSE(fs::exists(dir + "/timeseries.csv"));
}

// A running rve_server (testing_util::ServerProcess) for the children to
// use; from then on gRPC polls briefly, so that the children notice a closed
// channel quickly.
testing_util::ServerProcess StartServer(std::vector<std::string> extra_args = {}) {
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);
  static int count = 0;
  return testing_util::ServerProcess(
      RVE_SERVER_PATH, TempPath(absl::StrCat("server", ++count, ".log")), std::move(extra_args));
}

// Two rve_server processes share the RVEs; the results are the embedded
// server's, bit for bit.
TEST(MpmCliTest, RemoteServersGiveTheEmbeddedResult) {
  const RunOutput& reference = ReferenceRun();
  ASSERT_EQ(reference.result.exit_code, 0) << reference.result;
  testing_util::ServerProcess a = StartServer(), b = StartServer();
  ASSERT_FALSE(a.address().empty());
  ASSERT_FALSE(b.address().empty());
  const std::string dir = TempPath("remote");
  const Result r = RunClient(absl::StrCat("run ", Quote(WriteCase("remote", SmallCase())),
                                          " --out=", Quote(dir), " --servers=", a.address(), ",",
                                          b.address(), " --quiet", CommonFlags()));
  ASSERT_EQ(r.exit_code, 0) << r << "\nserver logs:\n" << a.Log() << b.Log();
  EXPECT_TRUE(absl::StrContains(r.err, "creating 4 RVEs on 2 server(s)")) << r.err;
  EXPECT_TRUE(absl::StrContains(r.err, "mpm_client: finished at step 35")) << r.err;
  const std::string expected = WithoutWallTime(ReadFile(reference.dir + "/timeseries.csv"));
  ASSERT_FALSE(expected.empty());
  EXPECT_EQ(WithoutWallTime(ReadFile(dir + "/timeseries.csv")), expected);
  EXPECT_EQ(a.Stop(), 0) << a.Log();
  EXPECT_EQ(b.Stop(), 0) << b.Log();
}

// deploy/local_cluster.sh: N servers on loopback ports, the case across
// them (mpm_client options passed on), every server stopped at the end; the
// result is the embedded run's.
TEST(MpmCliTest, LocalClusterScriptRunsACaseOnLoopbackServersAndStopsThem) {
  const RunOutput& reference = ReferenceRun();
  ASSERT_EQ(reference.result.exit_code, 0) << reference.result;
  const std::string dir = TempPath("local_cluster");
  const std::string build = fs::path(MPM_CLIENT_PATH).parent_path().parent_path().string();
  const std::string err_path = TempPath("local_cluster_stderr.txt");
  testing_util::CommandResult run = testing_util::RunCommand(absl::StrCat(
      "RVEHUB_BUILD=", Quote(build), " bash ", Quote(RVEHUB_SOURCE_DIR "/deploy/local_cluster.sh"),
      " 3 ", Quote(WriteCase("local_cluster", SmallCase())), " ", Quote(dir), " --quiet",
      CommonFlags(), " 2>", Quote(err_path)));
  const std::string err = ReadFile(err_path);
  ASSERT_EQ(run.exit_code, 0) << err;
  EXPECT_TRUE(absl::StrContains(err, "creating 4 RVEs on 3 server(s)")) << err;
  const std::vector<std::string> addresses =
      absl::StrSplit(ReadFile(dir + "/servers/addresses"), '\n', absl::SkipEmpty());
  ASSERT_EQ(addresses.size(), 3u);
  for (const std::string& a : addresses) EXPECT_TRUE(absl::StartsWith(a, "127.0.0.1:")) << a;
  for (absl::string_view pid :
       absl::StrSplit(ReadFile(dir + "/servers/pids"), '\n', absl::SkipEmpty())) {
    int p = 0;
    ASSERT_TRUE(absl::SimpleAtoi(pid, &p));
    EXPECT_NE(kill(p, 0), 0) << "server " << p << " still runs";
  }
  EXPECT_EQ(WithoutWallTime(ReadFile(dir + "/timeseries.csv")),
            WithoutWallTime(ReadFile(reference.dir + "/timeseries.csv")));
  // A server that ignores SIGTERM (one that missed it while starting) is
  // killed after the script's 10 s grace instead of hanging it: a fake
  // build whose server ignores the signal and whose client exits 3.
  const fs::path fake = TempPath("fake_build");
  fs::create_directories(fake / "rve_server" / "server");
  fs::create_directories(fake / "mpm_client");
  std::ofstream(fake / "rve_server" / "server" / "rve_server")
      << "#!/bin/bash\ntrap '' TERM\necho 'listening on 127.0.0.1:1'\nexec sleep 120\n";
  std::ofstream(fake / "mpm_client" / "mpm_client") << "#!/bin/bash\nexit 3\n";
  fs::permissions(fake / "rve_server" / "server" / "rve_server", fs::perms::owner_all);
  fs::permissions(fake / "mpm_client" / "mpm_client", fs::perms::owner_all);
  const std::string stuck = TempPath("local_cluster_stuck");
  const auto start = std::chrono::steady_clock::now();
  const testing_util::CommandResult bounded = testing_util::RunCommand(
      absl::StrCat("RVEHUB_BUILD=", Quote(fake.string()), " timeout 60 bash ",
                   Quote(RVEHUB_SOURCE_DIR "/deploy/local_cluster.sh"), " 1 case.json ",
                   Quote(stuck), " 2>/dev/null"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(bounded.exit_code, 3);  // the client's status; 124: the script hung
  EXPECT_LT(seconds, 30.0);
  int stuck_pid = 0;
  ASSERT_TRUE(
      absl::SimpleAtoi(absl::StripAsciiWhitespace(ReadFile(stuck + "/servers/pids")), &stuck_pid));
  EXPECT_NE(kill(stuck_pid, 0), 0) << "server " << stuck_pid << " still runs";
  // A usage error is the script's own.
  EXPECT_EQ(testing_util::RunCommand(
                absl::StrCat("bash ", Quote(RVEHUB_SOURCE_DIR "/deploy/local_cluster.sh"),
                             " zero x y 2>/dev/null"))
                .exit_code,
            2);
}

TEST(MpmCliTest, TokenFileIsSentToTheServers) {
  const std::string token = TempPath("token");
  std::ofstream(token) << "mpm-s3cret\n";
  testing_util::ServerProcess server = StartServer({absl::StrCat("--auth-token-file=", token)});
  ASSERT_FALSE(server.address().empty());
  const std::string run = absl::StrCat(
      "run ", Quote(WriteCase("token", SmallCase())), " --out=", Quote(TempPath("token_out")),
      " --servers=", server.address(), " --stop-after=1 --quiet", CommonFlags());
  const Result refused = RunClient(run);
  EXPECT_EQ(refused.exit_code, 1) << refused;
  EXPECT_TRUE(absl::StrContains(refused.err, server.address())) << refused.err;
  const Result accepted = RunClient(absl::StrCat(run, " --token-file=", Quote(token)));
  EXPECT_EQ(accepted.exit_code, 0) << accepted;
  EXPECT_TRUE(absl::StrContains(accepted.err, "mpm_client: stopped at step 1,")) << accepted.err;
  // An unreadable token file is a failure (exit 1), before any work.
  const std::string missing = TempPath("no_token");
  const Result no_file = RunClient(absl::StrCat(run, " --token-file=", Quote(missing)));
  EXPECT_EQ(no_file.exit_code, 1) << no_file;
  EXPECT_TRUE(absl::StrContains(no_file.err, missing)) << no_file.err;
  // A directory given as the token file had aborted the client (an uncaught
  // read error).
  const Result directory = RunClient(absl::StrCat(run, " --token-file=", Quote(ScratchDir())));
  EXPECT_EQ(directory.exit_code, 1) << directory;
  EXPECT_TRUE(absl::StrContains(directory.err, "is a directory")) << directory.err;
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

}  // namespace
}  // namespace rvehub::mpm
