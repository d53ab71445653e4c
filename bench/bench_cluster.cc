// Several RVE servers (figures only, never pass/fail): parallel
// efficiency of one case on 1, 2 and 3 rve_server processes of one worker
// each on loopback, what that predicts for more hosts, the share of the run
// the client's recovery points cost, and the time to detect and recover from
// a server killed (SIGKILL) or hung (SIGSTOP) mid-run.
//
//   build/bench/bench_cluster [--case=NAME] [--max-servers=N] [--strike-step=K]
//
// --case: a case of cases/ (default footing-dense-ci; footing-coarse is a
// larger one). --strike-step: the MPM step after which a server is struck
// (default: half the run). The baseline, in the same process, is the same
// case on one server of one worker; outputs go to /tmp/bench_cluster_*.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "mpm_client/case/case.h"
#include "mpm_client/run/output.h"
#include "mpm_client/run/simulation.h"
#include "rve_server/common/process.h"

extern char** environ;

namespace {

namespace fs = std::filesystem;
namespace mpm = rvehub::mpm;
using Clock = std::chrono::steady_clock;

// An rve_server child on a free loopback port with one worker; SIGTERM and
// reaped at destruction.
class Server {
 public:
  explicit Server(const std::string& log) {
    std::vector<std::string> args = {RVE_SERVER_PATH, "--listen=127.0.0.1:0", "--threads=1",
                                     "--drain-seconds=1"};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    int out[2];
    if (pipe2(out, O_CLOEXEC) != 0) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    close(out[1]);
    FILE* f = fdopen(out[0], "r");
    char line[256] = {0};
    // The server's first line: "listening on HOST:PORT".
    if (pid_ > 0 && std::fgets(line, sizeof line, f) != nullptr) {
      const std::string text(line);
      const std::string prefix = "listening on ";
      if (text.starts_with(prefix)) {
        address_ = text.substr(prefix.size(), text.find('\n') - prefix.size());
      }
    }
    std::fclose(f);
  }
  ~Server() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    kill(pid_, SIGCONT);
    waitpid(pid_, nullptr, 0);
  }
  void Signal(int sig) const { kill(pid_, sig); }
  const std::string& address() const { return address_; }

 private:
  pid_t pid_ = -1;
  std::string address_;
};

// Log lines with the time they came, for detection and recovery times.
struct Log {
  std::mutex mu;
  std::vector<std::pair<Clock::time_point, std::string>> lines;
  void Add(const std::string& l) {
    std::lock_guard<std::mutex> lock(mu);
    lines.emplace_back(Clock::now(), l);
  }
  // When the first line containing `words` came (nullopt: none).
  std::optional<Clock::time_point> When(const std::string& words) {
    std::lock_guard<std::mutex> lock(mu);
    for (const auto& [t, l] : lines)
      if (absl::StrContains(l, words)) return t;
    return std::nullopt;
  }
};

std::int64_t LastRowStep(const std::string& out) {
  absl::StatusOr<std::map<std::string, std::vector<double>>> ts =
      mpm::ReadCsvColumns(out + "/timeseries.csv");
  if (!ts.ok() || !ts->contains("step") || ts->at("step").empty()) return 0;  // none yet
  return static_cast<std::int64_t>(ts->at("step").back());
}

struct Result {
  bool ok = false;
  mpm::SimulationSummary sum;
  double detect_s = NAN;   // strike → "lost" in the log
  double recover_s = NAN;  // "lost" → "recovered" in the log
};

// Runs the case on `n` server processes (0: embedded, one worker); `strike`
// (optional) hits server 1 once the run passed `strike_step`.
Result Run(const mpm::CaseSpec& spec, int n, const std::string& label, std::int64_t strike_step,
           int strike_signal, double min_timeout_s) {
  Result r;
  const std::string out = (fs::temp_directory_path() / ("bench_cluster_" + label)).string();
  fs::remove_all(out);
  fs::create_directories(out);
  std::vector<std::unique_ptr<Server>> servers;
  mpm::SimulationOptions o;
  o.out_dir = out;
  o.template_cache_dir = (fs::temp_directory_path() / "bench_cluster_templates").string();
  o.threads = 1;
  o.min_apply_timeout_s = min_timeout_s;
  o.probe_interval_s = 1;
  for (int k = 0; k < n; ++k) {
    servers.push_back(std::make_unique<Server>(absl::StrCat(out, "/server-", k, ".log")));
    if (servers.back()->address().empty()) {
      std::fprintf(stderr, "rve_server did not start (%s)\n", RVE_SERVER_PATH);
      return r;
    }
    o.servers.push_back(servers.back()->address());
  }
  Log log;
  o.log = [&log](const std::string& l) { log.Add(l); };
  absl::StatusOr<std::unique_ptr<mpm::Simulation>> sim = mpm::Simulation::Start(spec, o);
  if (!sim.ok()) {
    std::fprintf(stderr, "%s: %s\n", label.c_str(), std::string(sim.status().message()).c_str());
    return r;
  }
  std::atomic<bool> done{false};
  Clock::time_point struck;
  std::thread striker;
  if (strike_signal != 0) {
    striker = std::thread([&] {
      for (int i = 0; i < 600000 && !done; ++i) {  // bounded: 10 min
        if (LastRowStep(out) >= strike_step) {
          struck = Clock::now();
          servers[1]->Signal(strike_signal);
          if (strike_signal == SIGSTOP) {
            for (int j = 0; j < 6000 && !log.When("lost (run at step"); ++j)
              std::this_thread::sleep_for(std::chrono::milliseconds(10));
            servers[1]->Signal(SIGCONT);
          }
          return;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
  }
  absl::StatusOr<mpm::SimulationSummary> sum = (*sim)->StepToEnd();
  done = true;
  if (striker.joinable()) striker.join();
  if (!sum.ok()) {
    std::fprintf(stderr, "%s: %s\n", label.c_str(), std::string(sum.status().message()).c_str());
    return r;
  }
  r.ok = true;
  r.sum = *sum;
  if (strike_signal != 0) {
    const std::optional<Clock::time_point> lost = log.When("lost (run at step");
    const std::optional<Clock::time_point> back = log.When("recovered in");
    if (lost) r.detect_s = std::chrono::duration<double>(*lost - struck).count();
    if (lost && back) r.recover_s = std::chrono::duration<double>(*back - *lost).count();
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  rvehub::SetUpLongRunningProcess();  // as rve_server and mpm_client run
  std::string name = "footing-dense-ci";
  int max_servers = 3;
  std::int64_t strike_step = -1;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--case=", 7) == 0) {
      name = argv[i] + 7;
    } else if (std::strncmp(argv[i], "--max-servers=", 14) == 0) {
      max_servers = std::max(2, std::atoi(argv[i] + 14));
    } else if (std::strncmp(argv[i], "--strike-step=", 14) == 0) {
      strike_step = std::atoll(argv[i] + 14);
    } else {
      std::fprintf(stderr, "unknown argument %s\n", argv[i]);
      return 2;
    }
  }
  absl::StatusOr<mpm::CaseSpec> spec =
      mpm::LoadCase(std::string(RVEHUB_SOURCE_DIR) + "/cases/" + name + ".json");
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", std::string(spec.status().message()).c_str());
    return 1;
  }
  spec->output.checkpoint_every = 0;
  spec->output.progress_every = 1 << 30;
  std::printf(
      "case %s on this machine (%u hardware threads); servers: rve_server processes on "
      "127.0.0.1, 1 worker each\n\n",
      name.c_str(), std::thread::hardware_concurrency());

  // Parallel efficiency.
  std::vector<Result> scaling;
  std::printf("%-10s %9s %12s %9s %11s %14s %12s\n", "servers", "wall s", "RVE incr/s", "speed-up",
              "efficiency", "recovery pts", "pts share");
  for (int n = 1; n <= max_servers; ++n) {
    Result r = Run(*spec, n, absl::StrCat("n", n), 0, 0, 10);
    if (!r.ok) return 1;
    scaling.push_back(r);
    const double speedup = scaling[0].sum.wall_s / r.sum.wall_s;
    std::printf("%-10d %9.2f %12.0f %9.2f %10.0f%% %14d %11.1f%% %11lld\n", n, r.sum.wall_s,
                r.sum.rve_evaluations / r.sum.wall_s, speedup, 100 * speedup / n,
                r.sum.recovery_points, 100 * r.sum.recovery_s / r.sum.wall_s,
                static_cast<long long>(r.sum.rves_moved));
  }
  // Amdahl from the one-server run: what does not shrink with servers (the
  // grid, the outputs, the client's side of the calls and the recovery
  // points) against the RVE work that does.
  const mpm::SimulationSummary& one = scaling[0].sum;
  const double engine = one.rve_stats.engine_seconds;  // one worker: wall of the DEM
  const double serial = std::max(0.0, one.wall_s - engine) / one.wall_s;
  std::printf(
      "\none server: DEM %.2f s of %.2f s wall; the rest (grid, output, service, "
      "recovery points) %.1f %%\n",
      engine, one.wall_s, 100 * serial);
  std::printf("predicted speed-up with one core per server (Amdahl, that share fixed):");
  for (int n : {2, 4, 8, 16, 32})
    std::printf("  %d: %.1fx", n, 1.0 / (serial + (1.0 - serial) / n));
  std::printf("\n");
  // Karp–Flatt: the serial share the measured 2-server speed-up implies
  // (server-side service work parallelises, unlike in the bound above).
  if (scaling.size() >= 2) {
    const double s2 = scaling[0].sum.wall_s / scaling[1].sum.wall_s;
    const double e = (1.0 / s2 - 0.5) / 0.5;
    std::printf("measured on 2 servers: serial share %.1f %% (Karp-Flatt); with it:", 100 * e);
    for (int n : {4, 8, 16, 32}) std::printf("  %d: %.1fx", n, 1.0 / (e + (1.0 - e) / n));
    std::printf("\n");
  }
  std::printf("(this machine has %u cores: beyond them the measured efficiency falls)\n\n",
              std::thread::hardware_concurrency());

  // Faults on 3 servers.
  const std::int64_t steps = static_cast<std::int64_t>(
      std::ceil(spec->solver.end_time / std::max(1e-12, one.final_time / one.final_step) - 1e-9));
  const std::int64_t at = strike_step > 0 ? strike_step : steps / 2;
  const Result& clean = scaling[std::min(max_servers, 3) - 1];
  for (auto [signal, label, floor] :
       {std::tuple{SIGKILL, "SIGKILL", 10.0}, std::tuple{SIGSTOP, "SIGSTOP", 2.0}}) {
    Result r =
        Run(*spec, std::min(max_servers, 3), std::string("strike_") + label, at, signal, floor);
    if (!r.ok) return 1;
    std::printf(
        "%s to server 1 of %d after step %lld (deadline floor %.0f s): lost after %.2f s, "
        "recovered %.3f s later; %lld steps replayed; rejoined %d, RVEs moved %lld; "
        "wall %.2f s against %.2f s without the fault (+%.2f s)\n",
        label, std::min(max_servers, 3), static_cast<long long>(at), floor, r.detect_s, r.recover_s,
        static_cast<long long>(r.sum.steps_replayed), r.sum.servers_rejoined,
        static_cast<long long>(r.sum.rves_moved), r.sum.wall_s, clean.sum.wall_s,
        r.sum.wall_s - clean.sum.wall_s);
  }
  return 0;
}
