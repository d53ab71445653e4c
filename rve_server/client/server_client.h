// A server as an administrator or a tool sees it (rve_cli): its info, runs
// and templates, one RVE's state, whole-run export and import, drops, and
// element tests run on the server. RveEndpoint (endpoint.h) is the MPM
// client's view of the same server; this one keeps each call to one RPC
// with a deadline of its own and names the call and server in its errors.
// No protobuf here: plain, engine and store types only.
#ifndef RVEHUB_RVE_SERVER_CLIENT_SERVER_CLIENT_H_
#define RVEHUB_RVE_SERVER_CLIENT_SERVER_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/types.h"
#include "rve_server/common/names.h"
#include "rve_server/engine/element_test.h"
#include "store/record.h"

namespace rvehub::client {

// Checks a run id or template name as servers do (the one rule of
// rve_server/common/names.h), so a client refuses a name before the work that
// would end in its upload.
using ::rvehub::ValidateName;

// GetServerInfo: the server's version, limits and load.
struct ServerInfo {
  std::string version;      // the server's version
  std::string api_version;  // "rvehub.v1"
  int threads = 0;          // worker threads
  std::int64_t num_rves = 0;
  std::int64_t max_rves = 0;
  std::int64_t memory_bytes = 0;  // resident estimate of all RVEs, bytes
  std::int64_t max_memory_bytes = 0;
  std::int64_t num_runs = 0;
  std::int64_t num_templates = 0;
  std::int64_t max_batch = 0;  // RVEs per call at most
  std::int64_t max_message_bytes = 0;
  double uptime_seconds = 0.0;  // s
  bool auth_required = false;
  bool tls = false;
};

// One hosted run.
struct RunInfo {
  std::string run_id;
  std::int64_t num_rves = 0;
  std::int64_t min_step = 0;  // smallest committed step of its RVEs
  std::int64_t max_step = 0;  // largest
};

// One template as the server summarises it.
struct TemplateInfo {
  std::string name;
  std::string description;
  std::string material_name;
  std::int64_t num_particles = 0;
  double void_ratio = 0.0;     // [-]
  double mean_pressure = 0.0;  // p, compression +, Pa
};

// What an Import stream did.
struct ImportSummary {
  std::int64_t imported = 0;  // RVEs the server imported
  std::int64_t chunks = 0;    // stream messages sent
};

// One server reached over gRPC. Creating one makes no call (the channel
// connects on the first). Every call gets `timeout` as its deadline
// (non-positive: none). A failed call's status keeps the server's code and
// message, followed by " (RPC on HOST:PORT)", e.g. "... (ListRuns on
// 127.0.0.1:50051)". Calls may run concurrently from several threads (each
// has its own context; the stub is thread-safe).
class ServerClient {
 public:
  ServerClient(std::string target, ClientOptions options, std::chrono::milliseconds timeout);
  ~ServerClient();
  ServerClient(ServerClient&&) noexcept;
  ServerClient& operator=(ServerClient&&) noexcept;

  // "HOST:PORT", as given.
  const std::string& target() const { return target_; }
  const ClientOptions& options() const { return options_; }

  absl::StatusOr<ServerInfo> GetServerInfo() const;
  // In the server's order.
  absl::StatusOr<std::vector<RunInfo>> ListRuns() const;
  absl::StatusOr<std::vector<TemplateInfo>> ListTemplates() const;

  // Uploads one template (AlreadyExists for a name in use unless `replace`)
  // and returns the server's summary of it.
  absl::StatusOr<TemplateInfo> UploadTemplate(const store::TemplateRecord& record,
                                              bool replace) const;

  // The state of RVE `id` of run `run` (tangent when asked). The outcome's
  // status is the server's verdict on that RVE (NotFound for an unknown id);
  // the call's status is the call's. DataLoss for a malformed reply.
  absl::StatusOr<RveOutcome> GetState(const std::string& run, std::int64_t id,
                                      bool want_tangent) const;

  // Every record of run `run` through the Export stream, in the server's
  // order, one at a time to `sink` (see ReadExport in record_stream.h).
  absl::Status ExportRun(const std::string& run, const RecordSink& sink) const;

  // Imports `records` in one stream, all or nothing (AlreadyExists when a
  // (run, id) is hosted), in chunks that stay below the smaller of the
  // server's (asked with GetServerInfo first) and this client's message
  // limits.
  absl::StatusOr<ImportSummary> Import(std::span<const store::RveRecord* const> records) const;

  // Drops RVEs `ids` of run `run` (empty: every RVE of the run) and returns
  // how many went. NotFound for an unknown run.
  absl::StatusOr<std::int64_t> Drop(const std::string& run,
                                    std::span<const std::int64_t> ids) const;

  // Runs `spec` on a fresh RVE of template `template_name` on the server.
  // `progress` (optional) sees the fraction done, 0..1, as updates arrive;
  // the rows come back in order once the test ends.
  absl::StatusOr<std::vector<dem::ElementTestRow>> RunElementTest(
      const std::string& template_name, const dem::ElementTestSpec& spec,
      const std::function<void(double fraction)>& progress) const;

 private:
  struct Stub;  // the gRPC stub: protobuf stays out of this header

  std::string target_;
  ClientOptions options_;
  std::chrono::milliseconds timeout_;
  std::unique_ptr<Stub> stub_;
};

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_SERVER_CLIENT_H_
