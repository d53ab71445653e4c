// mpm_client runs as a child process: one short run of a small single-element
// case and its outputs, summarise, --set and --stop-after, a run stopped and
// resumed from its checkpoint, the run record, and runs on real rve_server
// processes whose timeseries equal the embedded server's.
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

// The case's checks against summary.json: summarise prints each (pass or
// FAIL, ours, the reference, the tolerance, the source) and exits 0 when all
// pass, 3 when one fails (the outputs still written); the same check moved
// off our value fails, so a test on the exit status can fail. A finished run
// prints the same lines and exits 0.
TEST(MpmCliTest, SummariseExitsThreeWhenACheckFails) {
  const RunOutput& run = ReferenceRun();
  ASSERT_EQ(run.result.exit_code, 0) << run.result;
  const Json summary = Json::parse(ReadFile(run.dir + "/summary.json"));
  const double peak = summary["peak_stress_Pa"].get<double>();
  Json c = SmallCase();
  c["checks"] = Json::array({{{"quantity", "peak_stress_Pa"},
                              {"reference", peak * 1.01},
                              {"relative_tolerance", 0.02},
                              {"source", "its own run"}},
                             {{"quantity", "final_strain"},
                              {"reference", "peak_strain"},
                              {"absolute_tolerance", 1.0},
                              {"source", "within 100 % strain of the peak"}}});
  const std::string case_path = WriteCase("checked", c);
  const std::string dir = TempPath("checked");
  fs::create_directories(dir);
  fs::copy_file(run.dir + "/timeseries.csv", dir + "/timeseries.csv");
  const Result pass =
      RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(dir)));
  EXPECT_EQ(pass.exit_code, 0) << pass;
  EXPECT_TRUE(absl::StrContains(pass.out, "check: pass peak_stress_Pa = ")) << pass.out;
  EXPECT_TRUE(absl::StrContains(pass.out, " ± 2 % = ")) << pass.out;
  EXPECT_TRUE(absl::StrContains(pass.out, "; its own run)")) << pass.out;
  EXPECT_TRUE(absl::StrContains(pass.out, "check: pass final_strain = ")) << pass.out;

  // 3 % above ours: outside ± 2 %.
  const Result fail = RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(dir),
                                             " --set=/checks/0/reference=", peak * 1.03));
  EXPECT_EQ(fail.exit_code, 3) << fail;
  EXPECT_TRUE(absl::StrContains(fail.out, "check: FAIL peak_stress_Pa = ")) << fail.out;
  EXPECT_TRUE(absl::StrContains(fail.out, "check: pass final_strain = ")) << fail.out;
  EXPECT_TRUE(absl::StrContains(fail.err, "a check failed")) << fail.err;
  EXPECT_TRUE(fs::exists(dir + "/summary.json"));
  // A figure the summary does not have fails too.
  const Result missing = RunClient(absl::StrCat(
      "summarise ", Quote(case_path), " --out=", Quote(dir), " --set=/checks/1/quantity=\"N_q\""));
  EXPECT_EQ(missing.exit_code, 3) << missing;
  EXPECT_TRUE(absl::StrContains(missing.out, "check: FAIL N_q: N_q is not in summary.json"))
      << missing.out;
  // A bad check is a bad case: refused with its pointer, exit 1.
  const Result bad = RunClient(absl::StrCat("summarise ", Quote(case_path), " --out=", Quote(dir),
                                            " --set=/checks/0/relative_tolerance=0"));
  EXPECT_EQ(bad.exit_code, 1) << bad;
  EXPECT_TRUE(absl::StrContains(bad.err, "/checks/0/relative_tolerance: must be in (0, 10]"))
      << bad.err;

  // The run prints them at its end.
  const std::string run_dir = TempPath("checked-run");
  const Result ran = RunClient(
      absl::StrCat("run ", Quote(case_path), " --out=", Quote(run_dir), " --quiet", CommonFlags()));
  EXPECT_EQ(ran.exit_code, 0) << ran;
  EXPECT_TRUE(absl::StrContains(ran.err + ran.out, "check: pass final_strain = ")) << ran;
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
  // The stop's checkpoint, as a run killed after it would have recorded it.
  ASSERT_TRUE(first.contains("last_checkpoint")) << first.dump(2);
  EXPECT_EQ(first["last_checkpoint"]["step"], 10);
  EXPECT_GE(first["last_checkpoint"]["wall_s"].get<double>(), 0.0);
  EXPECT_LE(first["last_checkpoint"]["wall_s"].get<double>(), first["wall_s"].get<double>());

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
}  // namespace rvehub::mpm::cli_test
