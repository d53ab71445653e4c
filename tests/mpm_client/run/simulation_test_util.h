// Set-ups the simulation tests share: shipped cases, fresh output folders,
// short runs, stop-and-resume and loopback servers, and comparisons of their
// checkpoints and frames.
#ifndef RVEHUB_TESTS_MPM_CLIENT_RUN_SIMULATION_TEST_UTIL_H_
#define RVEHUB_TESTS_MPM_CLIENT_RUN_SIMULATION_TEST_UTIL_H_

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "client_run/templates.h"
#include "mpm_client/case/case.h"
#include "mpm_client/core/two_phase.h"
#include "mpm_client/run/output.h"
#include "mpm_client/run/simulation.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/service/server.h"
#include "store/results.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm::sim_test {

namespace fs = std::filesystem;

inline std::string CasePath(const std::string& name) {
  return std::string(RVEHUB_SOURCE_DIR) + "/cases/" + name + ".json";
}

// Prepared templates are shared by all tests of this binary.
inline std::string TemplateCache() {
  return (fs::temp_directory_path() / "rvehub_simulation_test_templates").string();
}

inline std::string FreshDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("rvehub_simulation_test_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(dir);
  return dir.string();
}

inline SimulationOptions Options(const std::string& out) {
  SimulationOptions o;
  o.out_dir = out;
  o.template_cache_dir = TemplateCache();
  o.threads = 2;
  o.progress = false;
  o.log = [](const std::string&) {};
  return o;
}

inline CaseSpec LoadOrDie(const std::string& name) {
  absl::StatusOr<CaseSpec> spec = LoadCase(CasePath(name));
  EXPECT_TRUE(spec.ok()) << spec.status();
  return spec.ok() ? *spec : CaseSpec{};
}

inline std::unique_ptr<Simulation> StartOrDie(const CaseSpec& spec, const SimulationOptions& o) {
  absl::StatusOr<std::unique_ptr<Simulation>> sim = Simulation::Start(spec, o);
  EXPECT_TRUE(sim.ok()) << sim.status();
  return sim.ok() ? *std::move(sim) : nullptr;
}

// The values of a result frame's field `name` (empty, the test failed, if
// the frame has none).
inline std::vector<double> FrameField(const store::ResultFrame& frame, const std::string& name) {
  const auto it = std::find_if(frame.fields.begin(), frame.fields.end(),
                               [&](const store::ResultField& f) { return f.name == name; });
  EXPECT_NE(it, frame.fields.end()) << name;
  return it == frame.fields.end() ? std::vector<double>{} : it->values;
}

// Runs the shipped saturated case `name` to its end in a fresh directory
// `dir` and returns its timeseries columns (empty, the test failed, if not);
// `out_dir` (optional) receives the directory's path.
inline std::map<std::string, std::vector<double>> RunSaturatedCase(const std::string& name,
                                                                   const std::string& dir,
                                                                   std::string* out_dir = nullptr) {
  CaseSpec spec = LoadOrDie(name);
  EXPECT_TRUE(spec.phases.saturated);
  const std::string out = FreshDir(dir);
  if (out_dir != nullptr) *out_dir = out;
  std::unique_ptr<Simulation> sim = StartOrDie(spec, Options(out));
  if (sim == nullptr) return {};
  absl::StatusOr<SimulationSummary> sum = sim->StepToEnd();
  EXPECT_TRUE(sum.ok()) << sum.status();
  if (!sum.ok()) return {};
  EXPECT_TRUE(sum->finished);
  absl::StatusOr<std::map<std::string, std::vector<double>>> ts =
      ReadCsvColumns(out + "/timeseries.csv");
  EXPECT_TRUE(ts.ok()) << ts.status();
  return ts.ok() ? *std::move(ts) : std::map<std::string, std::vector<double>>{};
}

inline void ExpectSameSnapshots(const store::SimCheckpoint& a, const store::SimCheckpoint& b) {
  EXPECT_EQ(a.step, b.step);
  EXPECT_TRUE(dem::testing_util::SameBits(a.time, b.time));
  ASSERT_EQ(a.doubles.size(), b.doubles.size());
  for (const auto& [name, values] : a.doubles) {
    ASSERT_TRUE(b.doubles.contains(name)) << name;
    dem::testing_util::ExpectSameBits(values, b.doubles.at(name), name.c_str());
  }
  EXPECT_EQ(a.ints, b.ints);
  ASSERT_EQ(a.rves.size(), b.rves.size());
  for (std::size_t i = 0; i < a.rves.size(); ++i) {
    EXPECT_EQ(a.rves[i].id, b.rves[i].id);
    EXPECT_EQ(a.rves[i].step, b.rves[i].step);
    dem::testing_util::ExpectIdenticalPackings(a.rves[i].packing, b.rves[i].packing,
                                               "rve " + std::to_string(a.rves[i].id));
  }
}

// A short single-element run: `steps` steps of the case.
inline CaseSpec ShortCase(int steps, double* dt_out = nullptr) {
  CaseSpec spec = LoadOrDie("single-element-biaxial");
  spec.solver.time_step = 2e-3;
  spec.solver.end_time = steps * spec.solver.time_step;
  spec.output.frame_every = 10;
  spec.output.timeseries_every = 5;
  spec.output.checkpoint_every = 0;
  if (dt_out) *dt_out = spec.solver.time_step;
  return spec;
}

// The end state of `spec` run in FreshDir(name) to `stop_after` steps (a
// checkpoint there), then resumed from that checkpoint to the end.
inline absl::StatusOr<store::SimCheckpoint> StopAndResume(const CaseSpec& spec,
                                                          const std::string& name,
                                                          std::int64_t stop_after) {
  SimulationOptions o = Options(FreshDir(name));
  o.stop_after_steps = stop_after;
  {
    ASSIGN_OR_RETURN(std::unique_ptr<Simulation> b, Simulation::Start(spec, o));
    RETURN_IF_ERROR(b->StepToEnd().status());
  }
  o.stop_after_steps = 0;
  ASSIGN_OR_RETURN(std::unique_ptr<Simulation> c,
                   Simulation::Resume(o.out_dir + "/checkpoint.h5", o));
  RETURN_IF_ERROR(c->StepToEnd().status());
  return c->Snapshot();
}

// `count` RVE servers of one thread each on loopback ports, added to
// o.servers (fewer on a failure, which the caller's size check reports).
inline std::vector<std::unique_ptr<service::RveServer>> StartLoopbackServers(int count,
                                                                             SimulationOptions& o) {
  std::vector<std::unique_ptr<service::RveServer>> servers;
  for (int i = 0; i < count; ++i) {
    service::ServerConfig config;
    config.listen = "127.0.0.1:0";
    config.registry.threads = 1;
    absl::StatusOr<std::unique_ptr<service::RveServer>> s = service::RveServer::Start(config);
    EXPECT_TRUE(s.ok()) << s.status();
    if (!s.ok()) break;
    o.servers.push_back((*s)->address());
    servers.push_back(*std::move(s));
  }
  return servers;
}

// The end state of `spec` run in FreshDir(name) on two loopback RVE servers
// (started and stopped here); both must have hosted RVEs.
inline absl::StatusOr<store::SimCheckpoint> RunOnTwoLoopbackServers(const CaseSpec& spec,
                                                                    const std::string& name) {
  SimulationOptions o = Options(FreshDir(name));
  std::vector<std::unique_ptr<service::RveServer>> servers = StartLoopbackServers(2, o);
  absl::StatusOr<store::SimCheckpoint> end = absl::UnavailableError("fewer than 2 servers");
  if (servers.size() == 2) {
    end = [&]() -> absl::StatusOr<store::SimCheckpoint> {
      ASSIGN_OR_RETURN(std::unique_ptr<Simulation> remote, Simulation::Start(spec, o));
      RETURN_IF_ERROR(remote->StepToEnd().status());
      // While the run still holds its RVEs there.
      for (auto& s : servers) {
        if (s->registry().Stats().num_rves == 0) {
          return absl::InternalError("a server hosted no RVE");
        }
      }
      return remote->Snapshot();
    }();
  }
  for (auto& s : servers) EXPECT_TRUE(s->Stop(std::chrono::seconds(1)).ok());
  return end;
}

}  // namespace rvehub::mpm::sim_test

#endif  // RVEHUB_TESTS_MPM_CLIENT_RUN_SIMULATION_TEST_UTIL_H_
