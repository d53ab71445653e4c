// mpm_client: runs a multiscale MPM×DEM case on RVE servers (an embedded one
// by default) and resumes it from a checkpoint.
//
//   mpm_client run cases/single-element-biaxial.json --out=out/se
//   mpm_client run CASE --out=DIR --servers=host1:50051,host2:50051
//   mpm_client resume out/se/checkpoint.h5
//   mpm_client check CASE
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/synchronization/mutex.h"
#include "mpm_client/case.h"
#include "mpm_client/simulation.h"
#include "rve_server/client/channel.h"

namespace rvehub::mpm {
namespace {

constexpr char kUsage[] = R"(mpm_client — multiscale MPM×DEM simulations on RVE servers

Usage:
  mpm_client run CASE.json --out=DIR [options]   run a case
  mpm_client resume CHECKPOINT.h5 [options]       continue a run from its checkpoint
  mpm_client check CASE.json                      validate a case file and print it in full
  mpm_client --help

Options (run, resume):
  --out=DIR            output directory (run: required; resume: default the checkpoint's
                       directory). Written there: results.h5 + results.xdmf (material-point
                       fields per frame; open results.xdmf in ParaView), timeseries.csv,
                       plot.png, checkpoint.h5 (when the case sets output.checkpoint_every)
  --servers=H:P,...    RVE servers to use (rve_server). Default: one embedded server in
                       this process, no network
  --threads=N          workers of the embedded server (default: all cores)
  --token-file=FILE    bearer token for the servers
  --tls-ca=FILE        CA certificate (PEM) to verify TLS servers
  --timeout=SECONDS    deadline of one batched RVE call (default 600)
  --template-cache=DIR where prepared RVE templates are cached (default DIR/templates)
  --stop-after=N       stop after N steps (writing a checkpoint if checkpoints are on)
  --quiet              no progress lines

Exit status: 0 done, 1 failure (message on stderr), 2 usage error.
)";

struct Args {
  std::string command;
  std::string target;
  std::map<std::string, std::string> flags;
};

absl::StatusOr<Args> Parse(int argc, char** argv) {
  Args a;
  const std::set<std::string> known = {"out",    "servers", "threads",        "token-file",
                                       "tls-ca", "timeout", "template-cache", "stop-after",
                                       "quiet"};
  // --help wins over anything else on the line (as in rve_cli).
  for (int i = 1; i < argc; ++i) {
    if (std::string arg = argv[i]; arg == "--help" || arg == "-h") {
      a.command = "help";
      return a;
    }
  }
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg.starts_with("--")) {
      std::string key = arg.substr(2), value;
      if (std::size_t eq = key.find('='); eq != std::string::npos) {
        value = key.substr(eq + 1);
        key = key.substr(0, eq);
      } else if (key != "quiet") {
        return absl::InvalidArgumentError(
            absl::StrCat("--", key, " needs a value (--", key, "=...)"));
      }
      if (key == "quiet" && arg.find('=') != std::string::npos) {
        return absl::InvalidArgumentError("--quiet takes no value");
      }
      if (!known.contains(key)) {
        return absl::InvalidArgumentError(absl::StrCat("unknown option --", key, " (see --help)"));
      }
      a.flags[key] = value;
    } else if (a.command.empty()) {
      a.command = arg;
    } else if (a.target.empty()) {
      a.target = arg;
    } else {
      return absl::InvalidArgumentError(absl::StrCat("unexpected argument '", arg, "'"));
    }
  }
  if (a.command.empty()) return absl::InvalidArgumentError("no command (see --help)");
  if (a.command != "run" && a.command != "resume" && a.command != "check") {
    return absl::InvalidArgumentError(absl::StrCat("unknown command '", a.command, "'"));
  }
  if (a.target.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat(a.command, " needs a ", a.command == "resume" ? "checkpoint" : "case file"));
  }
  if (a.command == "check" && !a.flags.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("check takes no options (got --", a.flags.begin()->first, ")"));
  }
  return a;
}

const std::string* Flag(const Args& a, const char* key) {
  auto it = a.flags.find(key);
  return it == a.flags.end() ? nullptr : &it->second;
}

// The run options from the flags; usage errors only (files are read by
// LoadClientOptions).
absl::StatusOr<RunOptions> Options(const Args& a) {
  RunOptions o;
  auto flag = [&](const char* k) { return Flag(a, k); };
  if (const std::string* v = flag("out")) {
    if (v->empty()) return absl::InvalidArgumentError("--out=DIR needs a directory");
    o.out_dir = *v;
  }
  if (const std::string* v = flag("servers")) {
    for (absl::string_view s : absl::StrSplit(*v, ',', absl::SkipWhitespace())) {
      o.servers.emplace_back(s);
    }
    if (o.servers.empty()) return absl::InvalidArgumentError("--servers lists no server");
  }
  if (const std::string* v = flag("threads")) {
    if (!absl::SimpleAtoi(*v, &o.threads) || o.threads < 1 || o.threads > 1024) {
      return absl::InvalidArgumentError("--threads must be an integer in 1..1024");
    }
  }
  if (const std::string* v = flag("timeout")) {
    if (!absl::SimpleAtod(*v, &o.apply_timeout_s) || !(o.apply_timeout_s > 0) ||
        o.apply_timeout_s > 1e7) {
      return absl::InvalidArgumentError("--timeout must be a number of seconds in (0, 1e7]");
    }
  }
  if (const std::string* v = flag("stop-after")) {
    if (!absl::SimpleAtoi(*v, &o.stop_after_steps) || o.stop_after_steps < 1) {
      return absl::InvalidArgumentError("--stop-after must be a positive integer");
    }
  }
  if (const std::string* v = flag("template-cache")) o.template_cache_dir = *v;
  o.progress = flag("quiet") == nullptr;
  return o;
}

// The token and CA certificate for the servers, read from their files.
absl::StatusOr<client::ClientOptions> LoadClientOptions(const Args& a) {
  const std::string* token = Flag(a, "token-file");
  const std::string* ca = Flag(a, "tls-ca");
  return client::ClientOptionsFromFiles(token ? *token : "", ca ? *ca : "");
}

int Fail(const absl::Status& s, int code) {
  std::fprintf(stderr, "mpm_client: %s\n", std::string(s.message()).c_str());
  return code;
}

int Main(int argc, char** argv) {
  // Debian's Abseil is built with mutex deadlock detection on: a graph update
  // per lock, and the embedded registry locks every RVE every step (~2 % of
  // footing-full). The tests keep it on.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
  absl::StatusOr<Args> args = Parse(argc, argv);
  if (!args.ok()) return Fail(args.status(), 2);
  if (args->command == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (args->command == "check") {
    absl::StatusOr<CaseSpec> spec = LoadCase(args->target);
    if (!spec.ok()) return Fail(spec.status(), 1);
    std::printf("%s\n", ToJson(*spec).c_str());
    return 0;
  }
  absl::StatusOr<RunOptions> options = Options(*args);
  if (!options.ok()) return Fail(options.status(), 2);
  if (args->command == "run" && !args->flags.contains("out")) {
    return Fail(absl::InvalidArgumentError("--out=DIR is required"), 2);
  }
  // An unreadable token or CA file is a failure, not a usage error.
  absl::StatusOr<client::ClientOptions> client_options = LoadClientOptions(*args);
  if (!client_options.ok()) return Fail(client_options.status(), 1);
  options->client = *std::move(client_options);
  absl::StatusOr<std::unique_ptr<Simulation>> sim;
  if (args->command == "run") {
    absl::StatusOr<CaseSpec> spec = LoadCase(args->target);
    if (!spec.ok()) return Fail(spec.status(), 1);
    sim = Simulation::Start(*spec, *options);
  } else {
    if (!args->flags.contains("out")) {
      // The checkpoint's directory ("/" for /checkpoint.h5, "." for a bare name).
      const std::filesystem::path dir = std::filesystem::path(args->target).parent_path();
      options->out_dir = dir.empty() ? "." : dir.string();
    }
    sim = Simulation::Resume(args->target, *options);
  }
  if (!sim.ok()) return Fail(sim.status(), 1);
  absl::StatusOr<RunSummary> summary = (*sim)->Run();
  if (!summary.ok()) return Fail(summary.status(), 1);
  std::fprintf(stderr,
               "mpm_client: %s at step %lld, t = %.6g s; %lld steps in %.1f s wall (RVE calls "
               "%.1f s, %.1f %%), %lld RVE evaluations\n",
               summary->finished ? "finished" : "stopped",
               static_cast<long long>(summary->final_step), summary->final_time,
               static_cast<long long>(summary->steps), summary->wall_s, summary->rve_s,
               summary->wall_s > 0 ? 100.0 * summary->rve_s / summary->wall_s : 0.0,
               static_cast<long long>(summary->rve_evaluations));
  std::fprintf(stderr, "mpm_client: %s\n", FormatTimeSplit(*summary).c_str());
  std::fprintf(stderr, "mpm_client: outputs in %s\n", options->out_dir.c_str());
  return 0;
}

}  // namespace
}  // namespace rvehub::mpm

int main(int argc, char** argv) { return rvehub::mpm::Main(argc, argv); }
