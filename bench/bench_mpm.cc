// Time to solution of mpm_client cases (figures only, never pass/fail).
//
// Runs cases on an embedded server (and, with --remote, on one rve_server on
// loopback started in this process) and prints for each: set-up time (RVE
// creation), MPM steps, wall time, RVE increments per second, DEM steps per
// increment (mean and histogram) and where the wall time went (DEM engine,
// service/transport/idle workers, grid, output), the split mpm_client prints
// at the end of every run.
//
// --baseline also runs each case with the settings before the time-to-solution
// work (rve.min_steps = 20 in every RVE) in the same process and prints the
// speed-up; compare the answers with bench/compare_runs.py on the outputs
// (kept in /tmp/bench_mpm_<case>[_baseline]).
//
//   build/bench/bench_mpm [--steps=N] [--full] [--baseline] [--remote] [--threads=N]
//                         [CASE.json ...]
// --steps: MPM steps per case (default 0: to the case's end time). Default
// cases: the CI-sized ones (single-element-biaxial, footing-dense-ci,
// biaxial-specimen-ci, column-collapse-ci); --full: footing-coarse,
// biaxial-specimen-medium and its -fast variant, column-collapse-full,
// footing-dense (about an hour; give --steps to sample them).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "mpm_client/case/case.h"
#include "mpm_client/run/simulation.h"
#include "rve_server/common/process.h"
#include "rve_server/service/server.h"

namespace {

namespace mpm = rvehub::mpm;

struct Row {
  std::string name;
  double setup_s = 0.0;  // Simulation::Start: templates, RVE creation, Δt, outputs
  mpm::SimulationSummary sum;
};

bool RunCase(const std::string& path, const std::vector<std::string>& servers, int threads,
             long steps, bool baseline, const std::string& label, std::vector<Row>* rows) {
  absl::StatusOr<mpm::CaseSpec> spec = mpm::LoadCase(path);
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", std::string(spec.status().message()).c_str());
    return false;
  }
  spec->output.checkpoint_every = 0;
  spec->output.frame_every = 1 << 30;  // frames at start and end only
  if (baseline) spec->rve.min_steps = 20;
  mpm::SimulationOptions o;
  o.out_dir = (std::filesystem::temp_directory_path() /
               ("bench_mpm_" + spec->name + (baseline ? "_baseline" : "")))
                  .string();
  o.template_cache_dir = (std::filesystem::temp_directory_path() / "bench_mpm_templates").string();
  o.servers = servers;
  o.threads = threads;
  o.stop_after_steps = steps;
  o.progress = false;
  o.log = [](const std::string&) {};
  const auto t0 = std::chrono::steady_clock::now();
  absl::StatusOr<std::unique_ptr<mpm::Simulation>> sim = mpm::Simulation::Start(*spec, o);
  const double setup_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!sim.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), std::string(sim.status().message()).c_str());
    return false;
  }
  absl::StatusOr<mpm::SimulationSummary> sum = (*sim)->StepToEnd();
  if (!sum.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), std::string(sum.status().message()).c_str());
    return false;
  }
  rows->push_back({spec->name + " " + label + (baseline ? " baseline" : "") + " (" +
                       std::to_string((*sim)->solver().points().size()) + " RVEs)",
                   setup_s, *sum});
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  rvehub::SetUpLongRunningProcess();  // as rve_server and mpm_client run
  long steps = 0;
  int threads = 0;
  bool remote = false, full = false, baseline = false;
  std::vector<std::string> cases;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--steps=", 8) == 0) {
      steps = std::atol(argv[i] + 8);
    } else if (std::strncmp(argv[i], "--threads=", 10) == 0) {
      threads = std::atoi(argv[i] + 10);
    } else if (std::strcmp(argv[i], "--remote") == 0) {
      remote = true;
    } else if (std::strcmp(argv[i], "--full") == 0) {
      full = true;
    } else if (std::strcmp(argv[i], "--baseline") == 0) {
      baseline = true;
    } else if (argv[i][0] == '-') {
      std::fprintf(stderr, "unknown flag %s\n", argv[i]);
      return 2;
    } else {
      cases.emplace_back(argv[i]);
    }
  }
  if (cases.empty()) {
    const std::vector<std::string> names =
        full ? std::vector<std::string>{"footing-coarse", "biaxial-specimen-medium",
                                        "biaxial-specimen-medium-fast", "column-collapse-full",
                                        "footing-dense"}
             : std::vector<std::string>{"single-element-biaxial", "footing-dense-ci",
                                        "biaxial-specimen-ci", "column-collapse-ci"};
    for (const std::string& n : names)
      cases.push_back(std::string(RVEHUB_SOURCE_DIR) + "/cases/" + n + ".json");
  }
  std::unique_ptr<rvehub::service::RveServer> server;
  if (remote) {
    rvehub::service::ServerConfig config;
    config.listen = "127.0.0.1:0";
    config.registry.threads = threads > 0 ? threads : 2;
    absl::StatusOr<std::unique_ptr<rvehub::service::RveServer>> s =
        rvehub::service::RveServer::Start(config);
    if (!s.ok()) {
      std::fprintf(stderr, "server: %s\n", std::string(s.status().message()).c_str());
      return 1;
    }
    server = *std::move(s);
  }
  std::vector<Row> rows;
  for (const std::string& c : cases) {
    for (bool base : {false, true}) {
      if (base && !baseline) continue;
      if (!RunCase(c, {}, threads, steps, base, "embedded", &rows)) return 1;
      if (remote && !RunCase(c, {server->address()}, threads, steps, base, "loopback", &rows))
        return 1;
    }
  }
  std::printf("%-52s %8s %7s %9s %10s %12s %9s\n", "case", "setup s", "steps", "wall s",
              "wall ms/st", "RVE incr/s", "DEM st/inc");
  for (const Row& r : rows) {
    const double n = static_cast<double>(std::max<std::int64_t>(1, r.sum.steps));
    const rvehub::client::ApplyStats& st = r.sum.rve_stats;
    std::printf("%-52s %8.1f %7lld %9.1f %10.3f %12.0f %9.2f\n", r.name.c_str(), r.setup_s,
                static_cast<long long>(r.sum.steps), r.sum.wall_s, 1e3 * r.sum.wall_s / n,
                r.sum.rve_evaluations / std::max(r.sum.wall_s, 1e-12),
                static_cast<double>(st.dem_steps) /
                    static_cast<double>(std::max<std::int64_t>(1, st.increments)));
  }
  std::printf("\n");
  for (const Row& r : rows) {
    std::printf("%s\n  %s\n", r.name.c_str(), mpm::FormatTimeSplit(r.sum).c_str());
  }
  if (baseline) {
    std::printf(
        "\nspeed-up over the baseline settings (same steps; wall time, set-up excluded):\n");
    for (std::size_t k = 0; k + 1 < rows.size(); k += remote ? 4 : 2) {
      const Row& now = rows[k];
      const Row& base = rows[k + (remote ? 2 : 1)];
      std::printf("  %-52s %6.2fx stepping, %6.2fx set-up\n", now.name.c_str(),
                  base.sum.wall_s / std::max(now.sum.wall_s, 1e-12),
                  base.setup_s / std::max(now.setup_s, 1e-12));
    }
  }
  if (server != nullptr) (void)server->Stop(std::chrono::seconds(1));
  return 0;
}
