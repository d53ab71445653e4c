// fem_client's run on rve_server processes on loopback addresses surviving
// a lost server: one killed (SIGKILL) between load steps or during one, the
// run goes back to its recovery point, restores the RVEs onto the server
// left and ends with the embedded run's outputs bit for bit; with
// --no-recovery the loss ends the run naming the step; with every server
// killed the run waits (bounded) and then ends saying how to resume.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/synchronization/mutex.h"
#include "client_run/timeseries.h"
#include "fem_client/case/case.h"
#include "fem_client/run/simulation.h"
#include "store/results.h"
#include "tests/fem_client/run/fem_run_test_util.h"
#include "tests/support/log_lines.h"
#include "tests/support/process_util.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;
using run_test::Columns;
using run_test::ReadColumns;
using testing_util::ServerProcess;

std::string Scratch(const std::string& name) {
  return run_test::ScratchPath("fem_fault_test", name);
}

using testing_util::LogLines;

FemSimulationOptions Options(const std::string& out, LogLines* log) {
  FemSimulationOptions o;
  o.out_dir = out;
  o.threads = 2;
  o.template_cache_dir = (fs::path(testing::TempDir()) / "fem_test_templates").string();
  o.log = [log](const std::string& line) { log->Add(line); };
  return o;
}

FemCase Load() {
  absl::StatusOr<FemCase> c =
      LoadFemCase(std::string(RVEHUB_SOURCE_DIR "/cases/fem-biaxial-coarse-ci.json"));
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? *c : FemCase{};
}

absl::StatusOr<FemRunSummary> RunCase(const FemSimulationOptions& o) {
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(Load(), o);
  if (!sim.ok()) return sim.status();
  return (*sim)->StepToEnd();
}

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

// Timeseries (wall time aside), iterations and frames, bit for bit.
void ExpectSameOutputs(const std::string& a, const std::string& b) {
  for (const char* file : {"/timeseries.csv", "/iterations.csv"}) {
    absl::StatusOr<Columns> ca = client_run::ReadCsvColumns(a + file);
    absl::StatusOr<Columns> cb = client_run::ReadCsvColumns(b + file);
    ASSERT_TRUE(ca.ok() && cb.ok()) << file;
    ASSERT_EQ(ca->size(), cb->size()) << file;
    for (const auto& [name, values] : *ca) {
      if (name == "wall_step_s") continue;
      EXPECT_TRUE(SameBits(values, cb->at(name))) << file << " " << name;
    }
  }
  absl::StatusOr<std::vector<store::ResultFrame>> fa = store::ReadResults(a + "/results.h5");
  absl::StatusOr<std::vector<store::ResultFrame>> fb = store::ReadResults(b + "/results.h5");
  ASSERT_TRUE(fa.ok() && fb.ok());
  ASSERT_EQ(fa->size(), fb->size());
  for (std::size_t k = 0; k < fa->size(); ++k) {
    EXPECT_EQ((*fa)[k].step, (*fb)[k].step);
    for (std::size_t f = 0; f < (*fa)[k].fields.size(); ++f) {
      EXPECT_TRUE(SameBits((*fa)[k].fields[f].values, (*fb)[k].fields[f].values))
          << (*fa)[k].fields[f].name;
    }
  }
}

std::string Reference() {
  static const std::string* dir = [] {
    auto* d = new std::string(Scratch("reference"));
    LogLines log;
    absl::StatusOr<FemRunSummary> s = RunCase(Options(*d, &log));
    EXPECT_TRUE(s.ok() && s->finished) << s.status();
    return d;
  }();
  return *dir;
}

// Two servers; `victim` killed once the run logs `when` (from the run's
// own thread: between load steps) or, with `during`, a moment after it
// (from another thread: inside the next step's Newton iterations).
struct Faulted {
  absl::StatusOr<FemRunSummary> summary = absl::UnknownError("not run");
  std::string out;
  LogLines log;
};
void RunWithFault(const std::string& name, const std::string& when, bool during, bool recovery,
                  Faulted& f) {
  f.out = Scratch(name);
  ServerProcess a(RVE_SERVER_PATH, f.out + "-a.log"), b(RVE_SERVER_PATH, f.out + "-b.log");
  ASSERT_FALSE(a.address().empty()) << a.Log();
  ASSERT_FALSE(b.address().empty()) << b.Log();
  FemSimulationOptions o = Options(f.out, &f.log);
  o.servers = {a.address(), b.address()};
  o.recovery = recovery;
  std::atomic<bool> struck{false};
  o.log = [&](const std::string& line) {
    f.log.Add(line);
    if (!during && !struck && absl::StrContains(line, when)) {
      struck = true;
      b.Signal(SIGKILL);
    }
  };
  std::atomic<bool> done{false};
  std::thread striker([&] {
    // Bounded: gives up when the run ends or after 120 s.
    for (int i = 0; during && i < 12000 && !done; ++i) {
      if (f.log.Has(when)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(30));
        struck = true;
        b.Signal(SIGKILL);
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  });
  f.summary = [&] {
    absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(Load(), o);
    if (!sim.ok()) return absl::StatusOr<FemRunSummary>(sim.status());
    return (*sim)->StepToEnd();
  }();
  done = true;
  striker.join();
  EXPECT_TRUE(struck) << f.log.All();
  EXPECT_EQ(a.Stop(), 0) << a.Log();
}

TEST(FemFaultTest, AServerKilledBetweenStepsIsRecoveredFromBitIdentically) {
  const std::string reference = Reference();
  Faulted f;
  RunWithFault("between", "load step 2/5", /*during=*/false, /*recovery=*/true, f);
  ASSERT_TRUE(f.summary.ok()) << f.summary.status() << "\n" << f.log.All();
  EXPECT_TRUE(f.summary->finished);
  EXPECT_EQ(f.summary->servers_lost, 1);
  EXPECT_EQ(f.summary->steps, 5);
  EXPECT_TRUE(f.log.Has("lost (load step 3)")) << f.log.All();
  EXPECT_TRUE(f.log.Has("32 RVEs restored from load step 2 onto 127.0.0.1:")) << f.log.All();
  ExpectSameOutputs(reference, f.out);
}

TEST(FemFaultTest, AServerKilledDuringAStepIsRecoveredFromBitIdentically) {
  const std::string reference = Reference();
  Faulted f;
  RunWithFault("during", "load step 3/5", /*during=*/true, /*recovery=*/true, f);
  ASSERT_TRUE(f.summary.ok()) << f.summary.status() << "\n" << f.log.All();
  EXPECT_TRUE(f.summary->finished);
  EXPECT_EQ(f.summary->servers_lost, 1);
  EXPECT_TRUE(f.log.Has("restored from load step")) << f.log.All();
  ExpectSameOutputs(reference, f.out);
}

TEST(FemFaultTest, WithoutRecoveryALostServerEndsTheRunNamingTheStep) {
  Faulted f;
  RunWithFault("no-recovery", "load step 2/5", /*during=*/false, /*recovery=*/false, f);
  ASSERT_FALSE(f.summary.ok());
  EXPECT_EQ(f.summary.status().code(), absl::StatusCode::kUnavailable) << f.summary.status();
  EXPECT_TRUE(absl::StrContains(f.summary.status().message(), "load step 3")) << f.summary.status();
  // The outputs end at the last step done.
  absl::StatusOr<Columns> ts = client_run::ReadCsvColumns(f.out + "/timeseries.csv");
  ASSERT_TRUE(ts.ok());
  EXPECT_EQ(ts->at("step").back(), 2);
}

// Every server killed: the run waits server_wait_s for one to answer, then
// ends, saying how to go on.
TEST(FemFaultTest, EveryServerLostEndsTheRunAfterTheWait) {
  const std::string out = Scratch("all");
  ServerProcess a(RVE_SERVER_PATH, out + "-a.log");
  ASSERT_FALSE(a.address().empty()) << a.Log();
  LogLines log;
  FemSimulationOptions o = Options(out, &log);
  o.servers = {a.address()};
  o.server_wait_s = 2;
  bool struck = false;
  o.log = [&](const std::string& line) {
    log.Add(line);
    if (!struck && absl::StrContains(line, "load step 1/5")) {
      struck = true;
      a.Signal(SIGKILL);
    }
  };
  const auto t0 = std::chrono::steady_clock::now();
  absl::StatusOr<FemRunSummary> s = RunCase(o);
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kUnavailable) << s.status();
  EXPECT_TRUE(absl::StrContains(s.status().message(), "every RVE server is lost")) << s.status();
  EXPECT_TRUE(absl::StrContains(s.status().message(), "fem_client resume")) << s.status();
  EXPECT_LT(waited, 60.0);
}

}  // namespace
}  // namespace rvehub::fem
