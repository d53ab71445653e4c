// rve_server: hosts DEM RVEs over gRPC (rvehub.v1.RveService).
//   rve_server --listen=0.0.0.0:50051 --threads=16 --checkpoint-dir=/var/lib/rvehub
// SIGTERM or SIGINT drains calls in flight and, with --checkpoint-dir, saves
// every RVE to HDF5 (reloaded on the next start).
#include <algorithm>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/flag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "rve_server/common/flags.h"
#include "rve_server/common/process.h"
#include "rve_server/common/text_file.h"
#include "rve_server/service/log.h"
#include "rve_server/service/server.h"

ABSL_FLAG(std::string, listen, "127.0.0.1:50051", "HOST:PORT to listen on (port 0: any free)");
ABSL_FLAG(int, threads, 0, "worker threads evaluating RVEs (0: all cores)");
ABSL_FLAG(int64_t, max_rves, 1000000, "RVEs hosted at most (beyond: RESOURCE_EXHAUSTED)");
ABSL_FLAG(int64_t, max_memory_mb, 16384,
          "resident memory of RVEs and templates at most, MiB (beyond: RESOURCE_EXHAUSTED)");
ABSL_FLAG(int64_t, max_templates, 1000, "templates hosted at most (beyond: RESOURCE_EXHAUSTED)");
ABSL_FLAG(int64_t, max_batch, 100000, "RVEs per call at most");
ABSL_FLAG(int64_t, max_message_mb, 64, "gRPC message size limit, MiB, both ways");
ABSL_FLAG(std::string, auth_token_file, "",
          "file holding a bearer token; calls must then carry \"authorization: Bearer <token>\"");
ABSL_FLAG(bool, health_without_token, false,
          "with --auth-token-file, grpc.health.v1.Health answers without the token (for "
          "Kubernetes' gRPC probes, which send none); every other call still needs it");
ABSL_FLAG(std::string, tls_cert, "", "PEM certificate chain file (with --tls-key: TLS)");
ABSL_FLAG(std::string, tls_key, "", "PEM private key file");
ABSL_FLAG(std::string, checkpoint_dir, "",
          "directory for rves.h5/templates.h5: loaded on start, written on SIGTERM; held "
          "(rve_server.lock) while the server runs, so a second server on it refuses to start");
ABSL_FLAG(int, drain_seconds, 30, "grace for calls in flight on SIGTERM, s");

namespace {

constexpr char kUsage[] =
    "rve_server — hosts DEM RVEs over gRPC (rvehub.v1.RveService, health, reflection)\n"
    "\n"
    "Usage: rve_server [--listen=HOST:PORT] [--threads=N] [--checkpoint-dir=DIR]\n"
    "                  [--auth-token-file=F] [--tls-cert=F --tls-key=F] [options]\n"
    "\n"
    "SIGTERM or SIGINT: calls in flight finish (up to --drain-seconds), the RVEs are\n"
    "written to --checkpoint-dir, exit 0. Log lines are logfmt on stderr.\n"
    "\n"
    "Options:\n";

// This binary's flags, by name (the libraries linked in define others).
std::vector<absl::CommandLineFlag*> ServerFlags() {
  std::vector<absl::CommandLineFlag*> flags;
  for (const auto& [name, flag] : absl::GetAllFlags()) {
    if (absl::EndsWith(flag->Filename(), "rve_server_main.cc")) flags.push_back(flag);
  }
  std::sort(flags.begin(), flags.end(), [](auto* a, auto* b) { return a->Name() < b->Name(); });
  return flags;
}

// The option's name on the command line: the flag's, with hyphens.
std::string OptionName(const absl::CommandLineFlag& flag) {
  std::string name(flag.Name());
  std::replace(name.begin(), name.end(), '_', '-');
  return name;
}

// Usage and this binary's flags (absl's own --help exits 1 and names each
// flag's source file by its build path).
void PrintUsage() {
  std::fputs(kUsage, stdout);
  for (const absl::CommandLineFlag* f : ServerFlags()) {
    const std::string value = f->DefaultValue();
    std::printf("  --%s=%s\n      %s\n", OptionName(*f).c_str(),
                value.empty() ? "\"\"" : value.c_str(), f->Help().c_str());
  }
  std::fputs(
      "\nThe old spellings with underscores (--checkpoint_dir) still work, with a warning.\n"
      "\nExit status: 0 after a clean stop, 1 when it cannot start or stop cleanly, 2 on an\n"
      "unknown option or a value that does not parse.\n",
      stdout);
}

// The log line of any failure to start; exit status `code`.
int Fail(const absl::Status& s, int code = 1) {
  rvehub::service::Log("error", "cannot start", {{"error", std::string(s.message())}});
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const absl::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h" || arg == "--helpfull") {
      PrintUsage();
      return 0;
    }
  }
  rvehub::cli::ArgSpec spec;
  for (const absl::CommandLineFlag* f : ServerFlags()) spec.allowed.insert(OptionName(*f));
  spec.positional = false;
  const absl::StatusOr<rvehub::cli::Args> args = rvehub::cli::ParseArgs(argc, argv, 1, spec);
  if (!args.ok()) return Fail(args.status(), 2);
  for (const std::string& warning : args->warnings) rvehub::service::Log("warn", warning);
  rvehub::SetUpLongRunningProcess();
  using rvehub::service::ServerConfig;
  ServerConfig config;
  config.listen = absl::GetFlag(FLAGS_listen);
  // The flags' own ranges, before any arithmetic on them (a shift by 20 of
  // a huge --max-memory-mb overflows); RveServer::Start checks the rest.
  const int threads = absl::GetFlag(FLAGS_threads);
  if (threads < 0 || threads > rvehub::service::kMaxThreads) {
    return Fail(
        absl::InvalidArgumentError(absl::StrCat("--threads=", threads, " must lie in 0..",
                                                rvehub::service::kMaxThreads, " (0: all cores)")));
  }
  if (const std::int64_t mb = absl::GetFlag(FLAGS_max_memory_mb); mb < 1 || mb > (1LL << 40)) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--max-memory-mb=", mb, " must lie in 1..", 1LL << 40)));
  }
  if (const std::int64_t mb = absl::GetFlag(FLAGS_max_message_mb); mb < 1 || mb > 2047) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--max-message-mb=", mb, " must lie in 1..2047 (gRPC's limit is 2 GiB)")));
  }
  if (const int s = absl::GetFlag(FLAGS_drain_seconds); s < 0) {
    return Fail(absl::InvalidArgumentError(absl::StrCat("--drain-seconds=", s, " must be >= 0")));
  }
  config.registry.threads =
      threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  config.registry.max_rves = absl::GetFlag(FLAGS_max_rves);
  config.registry.max_memory_bytes = absl::GetFlag(FLAGS_max_memory_mb) << 20;
  config.registry.max_batch = absl::GetFlag(FLAGS_max_batch);
  config.registry.max_templates = absl::GetFlag(FLAGS_max_templates);
  config.max_message_bytes = absl::GetFlag(FLAGS_max_message_mb) << 20;
  config.checkpoint_dir = absl::GetFlag(FLAGS_checkpoint_dir);
  if (const std::string f = absl::GetFlag(FLAGS_auth_token_file); !f.empty()) {
    absl::StatusOr<std::string> token = rvehub::ReadTokenFile(f);
    if (!token.ok()) return Fail(token.status());
    config.auth_token = *token;
  }
  config.health_without_token = absl::GetFlag(FLAGS_health_without_token);
  if (!absl::GetFlag(FLAGS_tls_cert).empty() || !absl::GetFlag(FLAGS_tls_key).empty()) {
    absl::StatusOr<std::string> cert =
        rvehub::ReadTextFile(absl::GetFlag(FLAGS_tls_cert), "TLS certificate");
    if (!cert.ok()) return Fail(cert.status());
    absl::StatusOr<std::string> key = rvehub::ReadTextFile(absl::GetFlag(FLAGS_tls_key), "TLS key");
    if (!key.ok()) return Fail(key.status());
    config.tls_cert_pem = *cert;
    config.tls_key_pem = *key;
  }

  // Block the stop signals in every thread (gRPC's included) and take them
  // synchronously here.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  absl::StatusOr<std::unique_ptr<rvehub::service::RveServer>> server =
      rvehub::service::RveServer::Start(config);
  if (!server.ok()) return Fail(server.status());
  // The bound address on stdout, for scripts that start on port 0.
  std::printf("listening on %s\n", (*server)->address().c_str());
  std::fflush(stdout);

  int signal = 0;
  sigwait(&stop_signals, &signal);
  rvehub::service::Log("info", "signal", {{"signal", signal == SIGTERM ? "SIGTERM" : "SIGINT"}});
  const absl::Status stopped =
      (*server)->Stop(std::chrono::seconds(absl::GetFlag(FLAGS_drain_seconds)));
  return stopped.ok() ? 0 : 1;
}
