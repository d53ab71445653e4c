// Client-side cost of mpm_client (figures only, never pass/fail).
//
// Runs cases for a number of MPM steps on an embedded server (and, with
// --remote, on one rve_server on loopback started in this process) and
// prints the wall time per step split into
//   rve     time inside the batched RVE calls (DEM work + for remote servers
//           transport and protobuf),
//   output  results frames, timeseries rows, checkpoints,
//   client  the rest: grid work (P2G, velocity gradients, forces, G2P),
// the client share (client / wall, goal ≤ 5 %) and RVE evaluations per
// second. The remote run's extra wall time over the embedded one is the
// marshalling and transport the embedded server avoids.
//
//   build/bench/bench_mpm [--steps=200] [--remote] [--threads=N] [CASE.json ...]
// Default cases: cases/single-element-biaxial.json and cases/footing-ci.json.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "mpm_client/case.h"
#include "mpm_client/simulation.h"
#include "rve_server/service/server.h"

namespace {

namespace mpm = rvehub::mpm;

struct Row {
  std::string name;
  mpm::RunSummary sum;
};

bool RunCase(const std::string& path, const std::vector<std::string>& servers, int threads,
             long steps, const std::string& label, std::vector<Row>* rows) {
  absl::StatusOr<mpm::CaseSpec> spec = mpm::LoadCase(path);
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", std::string(spec.status().message()).c_str());
    return false;
  }
  spec->output.checkpoint_every = 0;
  spec->output.frame_every = 1 << 30;  // frames at start and end only
  mpm::RunOptions o;
  o.out_dir = (std::filesystem::temp_directory_path() / ("bench_mpm_" + spec->name)).string();
  o.template_cache_dir = (std::filesystem::temp_directory_path() / "bench_mpm_templates").string();
  o.servers = servers;
  o.threads = threads;
  o.stop_after_steps = steps;
  o.progress = false;
  o.log = [](const std::string&) {};
  absl::StatusOr<std::unique_ptr<mpm::Simulation>> sim = mpm::Simulation::Start(*spec, o);
  if (!sim.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), std::string(sim.status().message()).c_str());
    return false;
  }
  absl::StatusOr<mpm::RunSummary> sum = (*sim)->Run();
  if (!sum.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), std::string(sum.status().message()).c_str());
    return false;
  }
  rows->push_back({spec->name + " " + label + " (" +
                       std::to_string((*sim)->solver().points().size()) + " RVEs)",
                   *sum});
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  long steps = 200;
  int threads = 0;
  bool remote = false;
  std::vector<std::string> cases;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--steps=", 8) == 0) {
      steps = std::atol(argv[i] + 8);
    } else if (std::strncmp(argv[i], "--threads=", 10) == 0) {
      threads = std::atoi(argv[i] + 10);
    } else if (std::strcmp(argv[i], "--remote") == 0) {
      remote = true;
    } else {
      cases.emplace_back(argv[i]);
    }
  }
  if (cases.empty()) {
    cases = {std::string(RVEHUB_SOURCE_DIR) + "/cases/single-element-biaxial.json",
             std::string(RVEHUB_SOURCE_DIR) + "/cases/footing-ci.json"};
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
    if (!RunCase(c, {}, threads, steps, "embedded", &rows)) return 1;
    if (remote && !RunCase(c, {server->address()}, threads, steps, "loopback", &rows)) return 1;
  }
  std::printf("%-44s %7s %10s %10s %10s %10s %8s %12s\n", "case", "steps", "wall ms/st",
              "rve ms/st", "out ms/st", "client ms", "client%", "RVE evals/s");
  for (const Row& r : rows) {
    const double n = static_cast<double>(r.sum.steps);
    const double client = r.sum.wall_s - r.sum.rve_s - r.sum.output_s;
    std::printf("%-44s %7lld %10.3f %10.3f %10.3f %10.4f %7.2f%% %12.0f\n", r.name.c_str(),
                static_cast<long long>(r.sum.steps), 1e3 * r.sum.wall_s / n, 1e3 * r.sum.rve_s / n,
                1e3 * r.sum.output_s / n, 1e3 * client / n, 100.0 * client / r.sum.wall_s,
                r.sum.rve_evaluations / r.sum.wall_s);
  }
  if (server != nullptr) (void)server->Stop(std::chrono::seconds(1));
  return 0;
}
