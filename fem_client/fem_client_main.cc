// fem_client: runs an implicit FEM×DEM case (Guo & Zhao 2014) on RVE
// servers (an embedded one by default).
//
//   fem_client run cases/fem-single-element.json --out=out/fem-se
//   fem_client run CASE --out=DIR --servers=host1:50051,host2:50051
//   fem_client resume DIR/checkpoint.h5 --out=DIR
//   fem_client check CASE
//   fem_client summarise CASE --out=DIR
#include <cstdio>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client_run/checks.h"
#include "client_run/out_dir_lock.h"
#include "client_run/run_record.h"
#include "fem_client/case/case.h"
#include "fem_client/run/output.h"
#include "fem_client/run/simulation.h"
#include "rve_server/client/channel.h"
#include "rve_server/common/address.h"
#include "rve_server/common/flags.h"
#include "rve_server/common/process.h"
#include "rve_server/common/status_macros.h"
#include "rvehub/version.h"  // RVEHUB_GIT_DESCRIBE, generated at build time

// The options (kUsage documents them); cli::ParseArgs reads them with
// hyphens (--stop-after).
ABSL_FLAG(std::string, out, "", "output directory");
ABSL_FLAG(std::string, servers, "", "RVE servers, HOST:PORT,...");
ABSL_FLAG(int, threads, 0, "workers of the embedded server");
ABSL_FLAG(std::string, token_file, "", "bearer token file");
ABSL_FLAG(std::string, tls_ca, "", "CA certificate (PEM)");
ABSL_FLAG(double, timeout, 600, "deadline of one batched RVE call, s");
ABSL_FLAG(std::string, template_cache, "", "template cache directory");
ABSL_FLAG(int64_t, stop_after, 0, "stop after N load steps");
ABSL_FLAG(bool, quiet, false, "no progress lines");
ABSL_FLAG(bool, no_recovery, false, "a lost server ends the run");
// Repeatable: cli::ParseArgs keeps each occurrence as typed (Args::repeated).
ABSL_FLAG(std::vector<std::string>, set, {}, "case overrides PATH=VALUE");

namespace rvehub::fem {
namespace {

constexpr char kUsage[] =
    R"(fem_client — implicit FEM×DEM simulations (Guo & Zhao 2014) on RVE servers

Usage:
  fem_client run CASE.json --out=DIR [options]   run a case (cases/FEM_FORMAT.md)
  fem_client resume CHECKPOINT.h5 [options]      continue a run from its checkpoint
  fem_client check CASE.json [--set=...]         validate a case file and print it in full
  fem_client summarise CASE.json --out=DIR       (re)write DIR/summary.json and plot.png from
                                                 DIR/timeseries.csv, then the case's checks
                                                 against it (pass or FAIL; exit status 3 when
                                                 one fails)
  fem_client --help

Options (run, resume):
  --out=DIR            output directory (run: required; resume: default the checkpoint's
                       directory, whose outputs go on after its step). Written there: timeseries.csv (a row per
                       load step: strains, the platen's and lateral stresses, Newton
                       iterations and errors, monitored Gauss points), iterations.csv (every
                       Newton iteration's E_d and E_f), summary.json (peak,
                       iterations per step, wall time), plot.png, results.h5 + results.xdmf
                       (every Gauss point's fields per frame; open results.xdmf in ParaView),
                       packings-STEP.h5 (the RVEs of output.packings per frame), run.json
                       (the run record: case, version, command line, host, start and end),
                       checkpoint.h5 (every output.checkpoint_every load steps and at the end)
  --servers=H:P,...    RVE servers to use (rve_server). Default: one embedded server in
                       this process, no network
  --threads=N          workers of the embedded server (default: all cores)
  --token-file=FILE    bearer token for the servers
  --tls-ca=FILE        CA certificate (PEM) to verify TLS servers
  --timeout=SECONDS    deadline of one batched RVE call (a Newton iteration's TRIALs, a
                       step's COMMITs) at most (default 600)
  --template-cache=DIR where prepared RVE templates are cached (default DIR/templates)
  --stop-after=N       stop after N load steps, writing DIR/checkpoint.h5 there (to resume)
  --no-recovery        with --servers, a lost server ends the run. Default: the run goes
                       back to the last load step (a recovery point kept after each), its RVEs
                       restored onto the servers left, and goes on as it would have without
                       the failure, bit for bit; a lost server that answers again rejoins
  --quiet              no progress lines

Option (run, check, summarise, resume):
  --set=PATH=VALUE     override one case field before the case is validated; repeatable.
                       PATH is a JSON pointer or dotted: --set=/mesh/elements=[10,15],
                       --set=loading.axial_strain_step=5e-4, --set=solver.tangent=perturbation.
                       A resume continues the case it was written with and may change only
                       the Newton settings: solver.tangent, perturbation, predictor,
                       tolerance, force_tolerance, max_iterations, max_cutbacks, unconverged

Exit status: 0 done, 1 failure (message on stderr), 2 usage error.
)";

using cli::Args;

constexpr char kThreadsRule[] = "must be an integer in 1..1024";
constexpr char kTimeoutRule[] = "must be a number of seconds in (0, 1e7]";
constexpr char kStopAfterRule[] = "must be a positive integer";

struct Command {
  std::string name;    // run, check, summarise, help
  std::string target;  // the case file
  Args args;
};

absl::StatusOr<Command> Parse(int argc, char** argv) {
  Command c;
  // --help wins over anything else on the line.
  if (cli::WantsHelp(argc, argv, 1)) {
    c.name = "help";
    return c;
  }
  cli::ArgSpec spec;
  spec.allowed = {"out",     "servers",        "threads",    "token-file", "tls-ca",
                  "timeout", "template-cache", "stop-after", "quiet",      "no-recovery",
                  "set"};
  spec.repeatable = {"set"};
  spec.bare = {"quiet", "no-recovery"};
  spec.rules = {
      {"threads", kThreadsRule}, {"timeout", kTimeoutRule}, {"stop-after", kStopAfterRule}};
  ASSIGN_OR_RETURN(Args args, cli::ParseArgs(argc, argv, 1, spec));
  c.args = std::move(args);
  std::vector<std::string>& positional = c.args.positional;
  if (positional.size() > 2) {
    return absl::InvalidArgumentError(absl::StrCat("unexpected argument '", positional[2], "'"));
  }
  if (positional.empty()) return absl::InvalidArgumentError("no command (see --help)");
  c.name = positional[0];
  if (c.name != "run" && c.name != "resume" && c.name != "check" && c.name != "summarise") {
    return absl::InvalidArgumentError(absl::StrCat("unknown command '", c.name, "'"));
  }
  if (positional.size() < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat(c.name, " needs a ", c.name == "resume" ? "checkpoint" : "case file"));
  }
  c.target = positional[1];
  if (c.name == "check") {
    for (const auto& [key, value] : c.args.text) {
      return absl::InvalidArgumentError(
          absl::StrCat("check takes no options (got --", key, "), only --set"));
    }
  }
  if (c.name == "summarise") {
    for (const auto& [key, value] : c.args.text) {
      if (key != "out") {
        return absl::InvalidArgumentError(
            absl::StrCat("summarise takes only --out and --set (got --", key, ")"));
      }
    }
    if (!c.args.contains("out")) return absl::InvalidArgumentError("summarise needs --out=DIR");
  }
  if (c.name == "run" && !c.args.contains("out")) {
    return absl::InvalidArgumentError("--out=DIR is required");
  }
  return c;
}

// The case overrides of --set, in the order given.
absl::StatusOr<std::vector<CaseOverride>> Overrides(const Args& a) {
  std::vector<CaseOverride> out;
  auto it = a.repeated.find("set");
  if (it == a.repeated.end()) return out;
  for (const std::string& text : it->second) {
    ASSIGN_OR_RETURN(CaseOverride o, ParseOverride(text));
    out.push_back(std::move(o));
  }
  return out;
}

// The run options from the flags; usage errors only (files are read later).
absl::StatusOr<FemSimulationOptions> Options(const Args& a) {
  FemSimulationOptions o;
  o.out_dir = absl::GetFlag(FLAGS_out);
  if (a.contains("out") && o.out_dir.empty()) {
    return absl::InvalidArgumentError("--out=DIR needs a directory");
  }
  if (a.contains("servers")) {
    for (absl::string_view s :
         absl::StrSplit(absl::GetFlag(FLAGS_servers), ',', absl::SkipWhitespace())) {
      RETURN_IF_ERROR(ValidateAddress("--servers", s, PortZero::kRefused));
      o.servers.emplace_back(s);
    }
    if (o.servers.empty()) return absl::InvalidArgumentError("--servers lists no server");
  }
  if (a.contains("threads")) {
    o.threads = absl::GetFlag(FLAGS_threads);
    if (o.threads < 1 || o.threads > 1024) {
      return absl::InvalidArgumentError(absl::StrCat("--threads ", kThreadsRule));
    }
  }
  if (a.contains("timeout")) {
    o.apply_timeout_s = absl::GetFlag(FLAGS_timeout);
    if (!(o.apply_timeout_s > 0) || o.apply_timeout_s > 1e7) {
      return absl::InvalidArgumentError(absl::StrCat("--timeout ", kTimeoutRule));
    }
  }
  if (a.contains("stop-after")) {
    o.stop_after_steps = absl::GetFlag(FLAGS_stop_after);
    if (o.stop_after_steps < 1) {
      return absl::InvalidArgumentError(absl::StrCat("--stop-after ", kStopAfterRule));
    }
  }
  if (a.contains("template-cache")) o.template_cache_dir = absl::GetFlag(FLAGS_template_cache);
  o.progress = !a.contains("quiet");
  o.recovery = !a.contains("no-recovery");
  return o;
}

int Fail(const absl::Status& s, int code) {
  std::fprintf(stderr, "fem_client: %s\n", std::string(s.message()).c_str());
  return code;
}

// The token and CA files of the flags; an unreadable one is a failure
// (exit 1), not a usage error.
int AddClientOptions(FemSimulationOptions& options) {
  absl::StatusOr<client::ClientOptions> client_options =
      client::ClientOptionsFromFiles(absl::GetFlag(FLAGS_token_file), absl::GetFlag(FLAGS_tls_ca));
  if (!client_options.ok()) return Fail(client_options.status(), 1);
  options.client = *std::move(client_options);
  return 0;
}

int StepToEnd(FemSimulation& sim, const FemSimulationOptions& options,
              client_run::RunRecord& record);

int Resume(const Command& command, std::span<const CaseOverride> overrides, int argc, char** argv) {
  absl::StatusOr<FemSimulationOptions> options = Options(command.args);
  if (!options.ok()) return Fail(options.status(), 2);
  if (options->out_dir.empty()) {
    options->out_dir = std::filesystem::path(command.target).parent_path().string();
    if (options->out_dir.empty()) options->out_dir = ".";
  }
  if (int code = AddClientOptions(*options); code != 0) return code;
  // Before the lock, which makes the output directory.
  if (absl::Status s = CheckResumableOverrides(overrides); !s.ok()) return Fail(s, 2);
  if (absl::Status s = client_run::CheckCheckpointFile(command.target); !s.ok()) return Fail(s, 1);
  client_run::RunRecord record("fem_client", RVEHUB_GIT_DESCRIBE, argc, argv, command.name);
  options->on_checkpoint = std::bind_front(&client_run::RunRecord::Checkpointed, &record);
  // As a run's: a second run or resume into the directory is refused.
  absl::StatusOr<client_run::OutDirLock> out_lock =
      client_run::OutDirLock::Acquire(options->out_dir);
  if (!out_lock.ok()) return Fail(out_lock.status(), 1);
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim =
      FemSimulation::Resume(command.target, *options, overrides);
  if (!sim.ok()) {
    out_lock->ReleaseAndRemoveIfUnused();
    return Fail(sim.status(), 1);
  }
  record.Started(options->out_dir, ToJson((*sim)->spec()), /*resumed=*/true);
  return StepToEnd(**sim, *options, record);
}

int Main(int argc, char** argv) {
  SetUpLongRunningProcess();
  absl::StatusOr<Command> command = Parse(argc, argv);
  if (!command.ok()) return Fail(command.status(), 2);
  for (const std::string& warning : command->args.warnings) {
    std::fprintf(stderr, "fem_client: warning: %s\n", warning.c_str());
  }
  if (command->name == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  absl::StatusOr<std::vector<CaseOverride>> overrides = Overrides(command->args);
  if (!overrides.ok()) return Fail(overrides.status(), 2);
  if (command->name == "resume") return Resume(*command, *overrides, argc, argv);
  absl::StatusOr<FemCase> spec = LoadFemCase(command->target, *overrides);
  if (command->name == "check") {
    if (!spec.ok()) return Fail(spec.status(), 1);
    std::printf("%s\n", ToJson(*spec).c_str());
    return 0;
  }
  if (command->name == "summarise") {
    if (!spec.ok()) return Fail(spec.status(), 1);
    absl::StatusOr<Summary> summary = WriteFemRunOutputs(*spec, command->args.text.at("out"));
    if (!summary.ok()) return Fail(summary.status(), 1);
    if (!client_run::PrintSummaryAndChecks(*summary, spec->checks)) {
      std::fprintf(stderr, "fem_client: a check failed (see the check: lines)\n");
      return client_run::kCheckFailedExitCode;
    }
    return 0;
  }
  absl::StatusOr<FemSimulationOptions> options = Options(command->args);
  if (!options.ok()) return Fail(options.status(), 2);
  if (!spec.ok()) return Fail(spec.status(), 1);
  if (int code = AddClientOptions(*options); code != 0) return code;
  client_run::RunRecord record("fem_client", RVEHUB_GIT_DESCRIBE, argc, argv, command->name);
  options->on_checkpoint = std::bind_front(&client_run::RunRecord::Checkpointed, &record);
  // Held until the run ends, before anything is written there: a second run
  // into the directory is refused now rather than failing part way.
  absl::StatusOr<client_run::OutDirLock> out_lock =
      client_run::OutDirLock::Acquire(options->out_dir);
  if (!out_lock.ok()) return Fail(out_lock.status(), 1);
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(*spec, *options);
  if (!sim.ok()) {
    out_lock->ReleaseAndRemoveIfUnused();
    return Fail(sim.status(), 1);
  }
  record.Started(options->out_dir, ToJson(*spec), /*resumed=*/false);
  return StepToEnd(**sim, *options, record);
}

// Steps a started or resumed run to its end and reports it.
int StepToEnd(FemSimulation& sim, const FemSimulationOptions& options,
              client_run::RunRecord& record) {
  absl::StatusOr<FemRunSummary> summary = sim.StepToEnd();
  if (!summary.ok()) {
    record.Failed(std::string(summary.status().message()));
    return Fail(summary.status(), 1);
  }
  const client_run::TimeSplit& split = summary->split;
  record.Finished(summary->finished ? "finished" : "stopped",
                  {{"final_step", summary->final_step},
                   {"total_steps", summary->total_steps},
                   {"iterations", summary->iterations},
                   {"cutbacks", summary->cutbacks},
                   {"unconverged", summary->unconverged},
                   {"wall_s", split.wall_s}});
  std::fprintf(
      stderr,
      "fem_client: %s at load step %lld of %lld; %lld Newton iterations (%.2f per step), "
      "%lld cut-backs, %lld sub-steps accepted unconverged, %lld TRIALs in %.1f s wall (RVE "
      "calls %.1f s, %.1f %%)\n",
      summary->finished ? "finished" : "stopped", static_cast<long long>(summary->final_step),
      static_cast<long long>(summary->total_steps), static_cast<long long>(summary->iterations),
      summary->steps > 0
          ? static_cast<double>(summary->iterations) / static_cast<double>(summary->steps)
          : 0.0,
      static_cast<long long>(summary->cutbacks), static_cast<long long>(summary->unconverged),
      static_cast<long long>(summary->trials), split.wall_s, split.rve_s,
      split.wall_s > 0 ? 100.0 * split.rve_s / split.wall_s : 0.0);
  std::fprintf(stderr, "fem_client: %s\n",
               client_run::FormatTimeSplit(split, "FEM (assembly, solves)").c_str());
  std::fprintf(stderr, "fem_client: outputs in %s\n", options.out_dir.c_str());
  return 0;
}

}  // namespace
}  // namespace rvehub::fem

int main(int argc, char** argv) { return rvehub::fem::Main(argc, argv); }
