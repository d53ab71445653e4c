// One rve_server reached over gRPC: the one remote client of the project.
// It is the RveEndpoint a continuum client drives (templates, Create,
// asynchronous batched Apply, Get, Export, Import, Drop) and offers what a
// tool or an administrator asks besides (the server's info, its runs and
// templates, element tests run on the server). rve_cli, mpm_client and the
// Python-free tests all use it. No protobuf here: values only.
#ifndef RVEHUB_RVE_SERVER_CLIENT_REMOTE_SERVER_H_
#define RVEHUB_RVE_SERVER_CLIENT_REMOTE_SERVER_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/time/time.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/common/names.h"
#include "rve_server/values/element_test.h"
#include "rve_server/values/record.h"

namespace rvehub::client {

// Checks a run id or template name as servers do (the one rule of
// rve_server/common/names.h), so a client refuses a name before the work that
// would end in its upload.
using ::rvehub::ValidateName;

struct RemoteOptions {
  // GetServerInfo on connecting must answer within this.
  absl::Duration connect_timeout = absl::Seconds(5);
  // Deadline of Create, which may consolidate thousands of RVEs to their
  // initial stresses (seconds each).
  absl::Duration create_timeout = absl::Hours(2);
  // Deadline of the other calls (Apply gets its own), element tests included.
  absl::Duration call_timeout = absl::Minutes(10);
  // RVEs per Create/Apply/Get/Drop message at most: about 1 KB each in a
  // reply with a tangent, so 2048 stays far below the default 64 MiB limit.
  // The server's own max batch lowers it further.
  std::int64_t max_batch = 2048;
};

// GetServerInfo: the server's version, limits and load.
struct ServerInfo {
  std::string version;      // the server's version
  std::string api_version;  // "rvehub.v1"
  int threads = 0;          // worker threads
  std::int64_t num_rves = 0;
  std::int64_t max_rves = 0;
  std::int64_t memory_bytes = 0;  // resident estimate of all RVEs and templates, bytes
  std::int64_t max_memory_bytes = 0;
  std::int64_t num_runs = 0;
  std::int64_t num_templates = 0;
  std::int64_t max_templates = 0;  // 0 from a server that does not say
  std::int64_t max_batch = 0;      // RVEs per call at most
  std::int64_t max_message_bytes = 0;
  double uptime_seconds = 0.0;  // s
  bool auth_required = false;
  bool tls = false;
};

// What an Import stream did.
struct ImportSummary {
  std::int64_t imported = 0;  // RVEs the server imported
  std::int64_t chunks = 0;    // stream messages sent
};

// Every error of a RemoteServer starts with "RVE server HOST:PORT: " and
// keeps the server's code and message. Calls may run concurrently from
// several threads (each has its own context; the stub is thread-safe), but
// SetCallTimeout and SetCreateTimeout not while a call is under way.
class RemoteServer final : public RveEndpoint {
 public:
  // A stub for the server at `address` (HOST:PORT), checked with a
  // GetServerInfo call: Unavailable "RVE server HOST:PORT is unreachable:
  // <reason>" when it gets no answer; a refusal (a wrong token:
  // Unauthenticated) keeps its code; FailedPrecondition for a server of
  // another API version.
  static absl::StatusOr<std::unique_ptr<RemoteServer>> Connect(const std::string& address,
                                                               const ClientOptions& options,
                                                               const RemoteOptions& remote = {});
  ~RemoteServer() override;

  // RveEndpoint.
  std::string name() const override;   // HOST:PORT, as given
  std::string label() const override;  // "RVE server HOST:PORT"
  int workers() const override;
  absl::Status PutTemplate(const TemplateRecord& record) override;
  absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial,
      const std::optional<dem::Controls>& controls) override;
  std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step, ApplyMode mode,
                                           std::span<const Increment> increments,
                                           const dem::ApplyOptions& options,
                                           absl::Duration deadline) override;
  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) override;
  absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                      const RecordSink& sink) override;
  absl::Status Import(std::vector<RveRecord> records) override;
  absl::Status Drop(absl::string_view run, std::span<const std::int64_t> ids = {}) override;
  absl::Status Ping(absl::Duration timeout) override;
  void SetCallTimeout(absl::Duration timeout) override;
  void SetCreateTimeout(absl::Duration timeout) override;

  // The server's info now (the limits it was connected with may have
  // changed only by a restart).
  absl::StatusOr<ServerInfo> GetServerInfo() const;
  // In the server's order (runs by id, templates by name), every page of
  // the server's listing.
  absl::StatusOr<std::vector<RunInfo>> ListRuns() const;
  absl::StatusOr<std::vector<TemplateInfo>> ListTemplates() const;
  // Uploads one template (AlreadyExists for a name in use unless `replace`)
  // and returns the server's summary of it.
  absl::StatusOr<TemplateInfo> UploadTemplate(const TemplateRecord& record, bool replace) const;
  // Import, also saying how many RVEs the server took and in how many
  // chunks (each below the smaller of the server's and this client's
  // message limits).
  absl::StatusOr<ImportSummary> ImportRecords(std::vector<RveRecord> records) const;
  // Drop, also saying how many RVEs went.
  absl::StatusOr<std::int64_t> DropRves(absl::string_view run,
                                        std::span<const std::int64_t> ids) const;
  // Runs `spec` on a fresh RVE of template `template_name` on the server.
  // `progress` (optional) sees the fraction done, 0..1, as updates arrive;
  // the rows come back in order once the test ends.
  absl::StatusOr<std::vector<dem::ElementTestRow>> RunElementTest(
      const std::string& template_name, const dem::ElementTestSpec& spec,
      const std::function<void(double fraction)>& progress = {}) const;

 private:
  struct Impl;  // the gRPC stub and the limits learnt on connecting
  explicit RemoteServer(std::unique_ptr<Impl> impl);
  absl::Status Error(const absl::Status& s) const;

  std::unique_ptr<Impl> impl_;
};

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_REMOTE_SERVER_H_
