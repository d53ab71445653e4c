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
#include <functional>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client_run/checks.h"
#include "client_run/out_dir_lock.h"
#include "client_run/run_record.h"
#include "mpm_client/case/case.h"
#include "mpm_client/run/output.h"
#include "mpm_client/run/simulation.h"
#include "mpm_client/run/summary.h"
#include "nlohmann/json.hpp"
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
ABSL_FLAG(int64_t, stop_after, 0, "stop after N steps");
ABSL_FLAG(double, end_time, 0, "resume: the run's new end time, s");
ABSL_FLAG(double, cfl, 0, "resume: a new CFL number");
ABSL_FLAG(std::string, f_bar, "", "resume: F-bar from here on (none, nodal)");
ABSL_FLAG(double, nonlocal_radius, 0, "resume: nonlocal strain radius from here on, m");
ABSL_FLAG(double, nonlocal_fraction, 0.5, "resume: share of the nonlocal average from here on");
ABSL_FLAG(bool, quiet, false, "no progress lines");
ABSL_FLAG(bool, no_recovery, false, "a lost server ends the run");
ABSL_FLAG(double, min_timeout, 10, "floor of the adaptive RVE call deadline, s");
// Repeatable: cli::ParseArgs keeps each occurrence as typed (Args::repeated).
ABSL_FLAG(std::vector<std::string>, set, {}, "case overrides PATH=VALUE");

namespace rvehub::mpm {
namespace {

constexpr char kUsage[] = R"(mpm_client — multiscale MPM×DEM simulations on RVE servers

Usage:
  mpm_client run CASE.json --out=DIR [options]   run a case
  mpm_client resume CHECKPOINT.h5 [options]       continue a run from its checkpoint
  mpm_client check CASE.json [--set=...]         validate a case file and print it in full
  mpm_client summarise CASE.json --out=DIR       (re)write DIR/summary.json and plot.png from
                                                 DIR/timeseries.csv, and print the case's
                                                 checks against it (pass or FAIL, ours, the
                                                 reference, the tolerance, the source)
  mpm_client --help

Options (run, resume):
  --out=DIR            output directory (run: required; resume: default the checkpoint's
                       directory). Written there: results.h5 + results.xdmf (material-point
                       fields per frame; open results.xdmf in ParaView), timeseries.csv,
                       plot.png, run.json (the run record: case, version, command line,
                       host, start and end), checkpoint.h5 (when the case sets
                       output.checkpoint_every, or at --stop-after)
  --servers=H:P,...    RVE servers to use (rve_server). Default: one embedded server in
                       this process, no network
  --threads=N          workers of the embedded server (default: all cores)
  --token-file=FILE    bearer token for the servers
  --tls-ca=FILE        CA certificate (PEM) to verify TLS servers
  --timeout=SECONDS    deadline of one batched RVE call at most (default 600)
  --min-timeout=SECONDS
                       with --servers, the deadline adapts to the measured calls (20 × the
                       slowest of the last steps) but is never below this (default 10): a
                       hung server is given up on after two such deadlines
  --no-recovery        with --servers, a lost server ends the run. Default: the client keeps
                       a recovery point in memory (about 2 % of the run time), moves a lost
                       server's RVEs onto the others, replays the steps since, and lets the
                       server rejoin when it answers again; results are bit-identical
  --template-cache=DIR where prepared RVE templates are cached (default DIR/templates)
  --stop-after=N       stop after N steps, writing DIR/checkpoint.h5 there (to resume)
  --quiet              no progress lines

Option (resume):
  --end-time=SECONDS   run on to this time instead of the case's end_time (after the
                       checkpoint's time); the checkpoints written from then on carry it
  --cfl=NUMBER         go on with this CFL number (the case's solver.cfl; its time step
                       scales by the ratio): e.g. a run that became unstable, resumed from
                       a checkpoint before, with a smaller step
  --f-bar=none|nodal   go on with this F-bar (the case's solver.f_bar): e.g. a run whose
                       points get squeezed or opened alone, resumed with nodal F-bar
  --nonlocal-radius=M  go on with this nonlocal strain radius in m (the case's
                       solver.nonlocal_radius; 0 turns it off)
  --nonlocal-fraction=F  go on with this share of the nonlocal average in (0, 1] (the
                       case's solver.nonlocal_fraction)

Option (run, check):
  --set=PATH=VALUE     override one case field before the case is validated; repeatable.
                       PATH is a JSON pointer or dotted: --set=/rve/min_steps=4,
                       --set=regions.0.density=1600, --set=solver.shape=gimp

Exit status: 0 done, 1 failure (message on stderr), 2 usage error, 3 summarise: the outputs
were written but a check failed. A finished run prints the same check lines and exits 0.
)";

using cli::Args;

// The options that take a value parse into their flag first; a value the
// flag cannot read gets the same message as one out of range.
constexpr char kThreadsRule[] = "must be an integer in 1..1024";
constexpr char kTimeoutRule[] = "must be a number of seconds in (0, 1e7]";
constexpr char kStopAfterRule[] = "must be a positive integer";
constexpr char kEndTimeRule[] = "must be a time in (0, 1e6] s";
constexpr char kCflRule[] = "must be a number in (0, 1]";
constexpr char kNonlocalRadiusRule[] = "must be a length in [0, 1e3] m";
constexpr char kNonlocalFractionRule[] = "must be a number in (0, 1]";

struct Command {
  std::string name;    // run, resume, check, help
  std::string target;  // the case file or checkpoint
  Args args;
};

absl::StatusOr<Command> Parse(int argc, char** argv) {
  Command c;
  // --help wins over anything else on the line (as in rve_cli).
  if (cli::WantsHelp(argc, argv, 1)) {
    c.name = "help";
    return c;
  }
  cli::ArgSpec spec;
  spec.allowed = {"out",
                  "servers",
                  "threads",
                  "token-file",
                  "tls-ca",
                  "timeout",
                  "min-timeout",
                  "template-cache",
                  "stop-after",
                  "quiet",
                  "no-recovery",
                  "set",
                  "end-time",
                  "cfl",
                  "f-bar",
                  "nonlocal-radius",
                  "nonlocal-fraction"};
  spec.repeatable = {"set"};
  spec.bare = {"quiet", "no-recovery"};
  spec.rules = {{"threads", kThreadsRule},
                {"timeout", kTimeoutRule},
                {"min-timeout", kTimeoutRule},
                {"stop-after", kStopAfterRule},
                {"end-time", kEndTimeRule},
                {"cfl", kCflRule},
                {"nonlocal-radius", kNonlocalRadiusRule},
                {"nonlocal-fraction", kNonlocalFractionRule}};
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
  // Options that change a checkpointed run's case: a fresh run sets the
  // case field itself.
  constexpr std::pair<const char*, const char*> kResumeOnly[] = {
      {"end-time", "end_time"},
      {"cfl", "cfl"},
      {"f-bar", "f_bar"},
      {"nonlocal-radius", "nonlocal_radius"},
      {"nonlocal-fraction", "nonlocal_fraction"}};
  for (const auto& [flag, field] : kResumeOnly) {
    if (c.name != "resume" && c.args.contains(flag)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--", flag, " is for resume (a run sets solver.", field, " in its case, or --set it)"));
    }
  }
  if (c.name == "resume" && c.args.contains("set")) {
    return absl::InvalidArgumentError(
        "resume takes no --set (a checkpoint continues the case it was written with)");
  }
  return c;
}

// summarise: summary.json and plot.png of a finished run in `dir` from its
// timeseries.csv (e.g. after giving the case its φ'), printed as the run
// prints them, then the case's checks against it. True when every check
// passes (or the case has none).
absl::StatusOr<bool> Summarise(const std::string& case_path,
                               const std::vector<CaseOverride>& overrides, const std::string& dir) {
  ASSIGN_OR_RETURN(const CaseSpec spec, LoadCase(case_path, overrides));
  ASSIGN_OR_RETURN(const Summary summary, WriteRunOutputs(spec, dir));
  return client_run::PrintSummaryAndChecks(summary, spec.checks);
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

// The run options from the flags; usage errors only (files are read by
// LoadClientOptions).
absl::StatusOr<SimulationOptions> Options(const Args& a) {
  SimulationOptions o;
  if (a.contains("out")) {
    o.out_dir = absl::GetFlag(FLAGS_out);
    if (o.out_dir.empty()) return absl::InvalidArgumentError("--out=DIR needs a directory");
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
  if (a.contains("min-timeout")) {
    o.min_apply_timeout_s = absl::GetFlag(FLAGS_min_timeout);
    if (!(o.min_apply_timeout_s > 0) || o.min_apply_timeout_s > 1e7) {
      return absl::InvalidArgumentError(absl::StrCat("--min-timeout ", kTimeoutRule));
    }
  }
  o.recovery = !a.contains("no-recovery");
  if (a.contains("stop-after")) {
    o.stop_after_steps = absl::GetFlag(FLAGS_stop_after);
    if (o.stop_after_steps < 1) {
      return absl::InvalidArgumentError(absl::StrCat("--stop-after ", kStopAfterRule));
    }
  }
  if (a.contains("end-time")) {
    o.end_time = absl::GetFlag(FLAGS_end_time);
    if (!(o.end_time > 0) || o.end_time > 1e6) {
      return absl::InvalidArgumentError(absl::StrCat("--end-time ", kEndTimeRule));
    }
  }
  if (a.contains("cfl")) {
    o.cfl = absl::GetFlag(FLAGS_cfl);
    if (!(o.cfl > 0) || o.cfl > 1)
      return absl::InvalidArgumentError(absl::StrCat("--cfl ", kCflRule));
  }
  if (a.contains("f-bar")) {
    absl::StatusOr<FBar> f_bar = FBarFromName(absl::GetFlag(FLAGS_f_bar));
    if (!f_bar.ok())
      return absl::InvalidArgumentError(absl::StrCat("--f-bar ", f_bar.status().message()));
    o.f_bar = *f_bar;
  }
  if (a.contains("nonlocal-radius")) {
    const double radius = absl::GetFlag(FLAGS_nonlocal_radius);
    if (!(radius >= 0) || radius > 1e3) {
      return absl::InvalidArgumentError(absl::StrCat("--nonlocal-radius ", kNonlocalRadiusRule));
    }
    o.nonlocal_radius = radius;
  }
  if (a.contains("nonlocal-fraction")) {
    const double fraction = absl::GetFlag(FLAGS_nonlocal_fraction);
    if (!(fraction > 0) || fraction > 1) {
      return absl::InvalidArgumentError(
          absl::StrCat("--nonlocal-fraction ", kNonlocalFractionRule));
    }
    o.nonlocal_fraction = fraction;
  }
  if (a.contains("template-cache")) o.template_cache_dir = absl::GetFlag(FLAGS_template_cache);
  o.progress = !a.contains("quiet");
  return o;
}

// The token and CA certificate for the servers, read from their files.
absl::StatusOr<client::ClientOptions> LoadClientOptions() {
  return client::ClientOptionsFromFiles(absl::GetFlag(FLAGS_token_file),
                                        absl::GetFlag(FLAGS_tls_ca));
}

int Fail(const absl::Status& s, int code) {
  std::fprintf(stderr, "mpm_client: %s\n", std::string(s.message()).c_str());
  return code;
}

int Main(int argc, char** argv) {
  SetUpLongRunningProcess();
  absl::StatusOr<Command> command = Parse(argc, argv);
  if (!command.ok()) return Fail(command.status(), 2);
  for (const std::string& warning : command->args.warnings) {
    std::fprintf(stderr, "mpm_client: warning: %s\n", warning.c_str());
  }
  if (command->name == "help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  absl::StatusOr<std::vector<CaseOverride>> overrides = Overrides(command->args);
  if (!overrides.ok()) return Fail(overrides.status(), 2);
  if (command->name == "check") {
    absl::StatusOr<CaseSpec> spec = LoadCase(command->target, *overrides);
    if (!spec.ok()) return Fail(spec.status(), 1);
    std::printf("%s\n", ToJson(*spec).c_str());
    return 0;
  }
  if (command->name == "summarise") {
    const absl::StatusOr<bool> passed =
        Summarise(command->target, *overrides, command->args.text.at("out"));
    if (!passed.ok()) return Fail(passed.status(), 1);
    if (!*passed) {
      std::fprintf(stderr, "mpm_client: a check failed (see the check: lines)\n");
      return client_run::kCheckFailedExitCode;
    }
    return 0;
  }
  absl::StatusOr<SimulationOptions> options = Options(command->args);
  if (!options.ok()) return Fail(options.status(), 2);
  if (command->name == "run" && !command->args.contains("out")) {
    return Fail(absl::InvalidArgumentError("--out=DIR is required"), 2);
  }
  // An unreadable token or CA file is a failure, not a usage error.
  absl::StatusOr<client::ClientOptions> client_options = LoadClientOptions();
  if (!client_options.ok()) return Fail(client_options.status(), 1);
  options->client = *std::move(client_options);
  client_run::RunRecord record("mpm_client", RVEHUB_GIT_DESCRIBE, argc, argv, command->name);
  options->on_checkpoint = std::bind_front(&client_run::RunRecord::Checkpointed, &record);
  absl::StatusOr<CaseSpec> spec;
  if (command->name == "run") {
    spec = LoadCase(command->target, *overrides);
    if (!spec.ok()) return Fail(spec.status(), 1);
  } else if (!command->args.contains("out")) {
    // The checkpoint's directory ("/" for /checkpoint.h5, "." for a bare name).
    const std::filesystem::path dir = std::filesystem::path(command->target).parent_path();
    options->out_dir = dir.empty() ? "." : dir.string();
  }
  if (command->name == "resume") {
    if (absl::Status s = client_run::CheckCheckpointFile(command->target); !s.ok()) {
      return Fail(s, 1);
    }
  }
  // Held until the run ends, before anything is written there: a second run
  // into the directory is refused now rather than failing part way.
  absl::StatusOr<client_run::OutDirLock> out_lock =
      client_run::OutDirLock::Acquire(options->out_dir);
  if (!out_lock.ok()) return Fail(out_lock.status(), 1);
  absl::StatusOr<std::unique_ptr<Simulation>> sim =
      command->name == "run" ? Simulation::Start(*spec, *options)
                             : Simulation::Resume(command->target, *options);
  if (!sim.ok()) {
    out_lock->ReleaseAndRemoveIfUnused();
    return Fail(sim.status(), 1);
  }
  record.Started(options->out_dir, ToJson((*sim)->spec()), command->name == "resume");
  absl::StatusOr<SimulationSummary> summary = (*sim)->StepToEnd();
  if (!summary.ok()) {
    record.Failed(std::string(summary.status().message()));
    return Fail(summary.status(), 1);
  }
  record.Finished(summary->finished ? "finished" : "stopped", {{"final_step", summary->final_step},
                                                               {"final_time", summary->final_time},
                                                               {"wall_s", summary->wall_s}});
  std::fprintf(stderr,
               "mpm_client: %s at step %lld, t = %.6g s; %lld steps in %.1f s wall (RVE calls "
               "%.1f s, %.1f %%), %lld RVE evaluations\n",
               summary->finished ? "finished" : "stopped",
               static_cast<long long>(summary->final_step), summary->final_time,
               static_cast<long long>(summary->steps), summary->wall_s, summary->rve_s,
               summary->wall_s > 0 ? 100.0 * summary->rve_s / summary->wall_s : 0.0,
               static_cast<long long>(summary->rve_evaluations));
  std::fprintf(stderr, "mpm_client: %s\n", FormatTimeSplit(*summary).c_str());
  if (summary->recovery_points > 0) {
    std::fprintf(stderr,
                 "mpm_client: servers lost %d, rejoined %d; %lld steps replayed; %lld RVEs moved "
                 "between servers; %d recovery points, %.2f s with recoveries (%.1f %% of wall)\n",
                 summary->servers_lost, summary->servers_rejoined,
                 static_cast<long long>(summary->steps_replayed),
                 static_cast<long long>(summary->rves_moved), summary->recovery_points,
                 summary->recovery_s,
                 summary->wall_s > 0 ? 100.0 * summary->recovery_s / summary->wall_s : 0.0);
  }
  std::fprintf(stderr, "mpm_client: outputs in %s\n", options->out_dir.c_str());
  return 0;
}

}  // namespace
}  // namespace rvehub::mpm

int main(int argc, char** argv) { return rvehub::mpm::Main(argc, argv); }
