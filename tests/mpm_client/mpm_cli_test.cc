// The mpm_client binary (mpm_client/mpm_client_main.cc), run as a child
// process: usage and exit codes, `check` and its JSON-pointer messages, values
// out of range, and a failed checkpoint write.
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
#include "tests/mpm_client/mpm_cli_test_util.h"
#include "tests/support/process_util.h"

namespace rvehub::mpm::cli_test {
namespace {

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

// A checkpoint that is not there is refused before the output directory
// (by default the checkpoint's) is made.
TEST(MpmCliTest, AMissingCheckpointMakesNoDirectory) {
  const std::string dir = TempPath("no_such_run");
  const Result r = RunClient(absl::StrCat("resume ", Quote(dir + "/checkpoint.h5")));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "/checkpoint.h5: no such checkpoint file")) << r;
  EXPECT_FALSE(fs::exists(dir));
}

// A file that is not a checkpoint, resumed into a new directory: refused,
// and the directory the lock made for it is gone again.
TEST(MpmCliTest, AnUnreadableCheckpointLeavesNoNewDirectory) {
  const std::string bad = TempPath("not_a_checkpoint.h5");
  std::ofstream(bad) << "not HDF5";
  const std::string out = TempPath("resumed_from_nothing");
  const Result r = RunClient(absl::StrCat("resume ", Quote(bad), " --out=", Quote(out)));
  EXPECT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "not_a_checkpoint.h5")) << r;
  EXPECT_FALSE(fs::exists(out));
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

}  // namespace
}  // namespace rvehub::mpm::cli_test
