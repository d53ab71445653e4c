// The RVEs a server hosts, keyed by (run id, material-point id), with their
// commit/trial step protocol, templates and limits. Plain C++ over the engine
// (no gRPC, no HDF5): the gRPC service translates to it, and an in-process
// client can use it directly.
#ifndef RVEHUB_RVE_SERVER_SERVICE_REGISTRY_H_
#define RVEHUB_RVE_SERVER_SERVICE_REGISTRY_H_

#include <Eigen/Dense>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/container/btree_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/synchronization/mutex.h"
#include "rve_server/common/names.h"
#include "rve_server/engine/rve.h"
#include "rve_server/service/worker_pool.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/record.h"

namespace rvehub::service {

// Workers one registry may run: beyond a machine's cores they add nothing,
// and a thread count in the tens of thousands fails to start (it aborted
// rve_server --threads=100000).
inline constexpr int kMaxThreads = 1024;

struct RegistryOptions {
  int threads = 1;                    // workers evaluating a batch, 1..kMaxThreads
  std::int64_t max_rves = 1'000'000;  // hosted RVEs at most
  // Resident estimate of all RVEs and templates at most, bytes.
  std::int64_t max_memory_bytes = 16LL << 30;
  std::int64_t max_templates = 1000;  // templates hosted at most
  std::int64_t max_batch = 100'000;   // RVEs per call at most
};

// A batch call's values (values/increment.h), the client endpoints' too.
using ::rvehub::ApplyMode;
using ::rvehub::Increment;
using ::rvehub::InitialStress;
using ::rvehub::RveOutcome;

struct RegistryStats {
  std::int64_t num_rves = 0;
  std::int64_t memory_bytes = 0;
  std::int64_t num_runs = 0;
  std::int64_t num_templates = 0;
};

// OK while the call goes on; DeadlineExceeded or Cancelled once the caller
// gave up (then RVEs not yet started are skipped, and the engine stops long
// increments, consolidations and relaxations between DEM steps, undoing
// them). The same type as dem::Interrupt.
using CancelFn = std::function<absl::Status()>;

// Run ids and template names follow the one rule of rve_server/common/names.h
// (the client checks the same one).
using ::rvehub::ValidateName;

class Registry {
 public:
  explicit Registry(const RegistryOptions& options);
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  const RegistryOptions& options() const { return options_; }

  // Templates. InvalidArgument for a bad name or packing, AlreadyExists
  // unless `replace`, ResourceExhausted for a new one past max_templates or
  // one whose bytes would take the memory account past its limit (templates
  // count in it as RVEs do).
  absl::StatusOr<TemplateInfo> PutTemplate(TemplateRecord record, bool replace);
  // Summaries in name order: those named after `after` (empty: from the
  // first), at most `limit` of them (pages of a list too long for one reply).
  std::vector<TemplateInfo> ListTemplates(absl::string_view after = "",
                                          std::size_t limit = SIZE_MAX) const;
  std::vector<TemplateRecord> AllTemplates() const;
  // NotFound naming the template when it is not hosted.
  absl::StatusOr<TemplateRecord> FindTemplate(absl::string_view name) const;

  // Creates RVEs from a template, optionally consolidated (in parallel) to
  // initial stresses — none, one for all, or one per id (geostatic starts:
  // each point its own depth) — and with other controls. All or nothing:
  // NotFound (template), AlreadyExists (id in the run, or twice in the
  // request), ResourceExhausted (limits), InvalidArgument (malformed).
  absl::StatusOr<std::vector<RveOutcome>> Create(absl::string_view run_id,
                                                 absl::string_view template_name,
                                                 std::span<const std::int64_t> ids,
                                                 std::span<const InitialStress> initial,
                                                 const std::optional<dem::Controls>& controls,
                                                 bool want_state, const CancelFn& cancelled = {});

  // One increment for a batch (see proto ApplyRequest for the protocol).
  // Whole-call errors change no RVE; per-RVE outcomes otherwise.
  absl::StatusOr<std::vector<RveOutcome>> Apply(absl::string_view run_id, std::int64_t step,
                                                ApplyMode mode, const dem::ApplyOptions& options,
                                                std::span<const Increment> increments,
                                                const CancelFn& cancelled = {});
  // Apply handing each RVE's outcome to done(k, outcome), k its index in
  // `increments`, on the worker that computed it instead of collecting them,
  // so that a caller converts outcomes in parallel: `done` runs concurrently
  // for distinct k, once per increment. A whole-call error returns before
  // any `done`; `done` running out of memory is the call's error then.
  using OutcomeFn = std::function<void(std::size_t, RveOutcome&&)>;
  absl::Status ApplyEach(absl::string_view run_id, std::int64_t step, ApplyMode mode,
                         const dem::ApplyOptions& options, std::span<const Increment> increments,
                         const CancelFn& cancelled, const OutcomeFn& done);

  // Current states; empty ids: the whole run (sorted by id). Unknown ids get
  // a NotFound outcome; an unknown run is NotFound for the call. Ids given
  // twice or more than max_batch ids are InvalidArgument (so for Export and
  // Drop).
  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run_id,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) const;

  // Full states, one record at a time to `sink` (in id order; empty ids: the
  // whole run). Stops at the first error of `sink`.
  absl::Status Export(absl::string_view run_id, std::span<const std::int64_t> ids,
                      const std::function<absl::Status(RveRecord&&)>& sink) const;
  // Every RVE of every run (for checkpoints), sorted by (run, id).
  absl::Status ExportAll(const std::function<absl::Status(RveRecord&&)>& sink) const;

  // All or nothing: InvalidArgument naming a malformed record, AlreadyExists
  // when a (run, id) is hosted or repeated, ResourceExhausted beyond limits.
  absl::StatusOr<std::int64_t> Import(std::vector<RveRecord> records);

  // Drops RVEs (empty ids: the whole run); NotFound for an unknown run or id
  // (then nothing is dropped). Returns how many were dropped.
  absl::StatusOr<std::int64_t> Drop(absl::string_view run_id, std::span<const std::int64_t> ids);

  // Runs in id order: those after `after` (empty: from the first), at most
  // `limit` of them.
  std::vector<RunInfo> ListRuns(absl::string_view after = "", std::size_t limit = SIZE_MAX) const;
  // RVEs hosted for a run (0 for an unknown run).
  std::int64_t CountRves(absl::string_view run_id) const;
  RegistryStats Stats() const;

 private:
  struct Entry {
    mutable absl::Mutex mu;
    dem::Rve rve ABSL_GUARDED_BY(mu);
    std::int64_t step ABSL_GUARDED_BY(mu) = 0;
    Eigen::Matrix3d last_delta_f ABSL_GUARDED_BY(mu) = Eigen::Matrix3d::Identity();
    // Result of the last COMMIT, returned again for a retry of that step.
    std::optional<dem::RveState> last_result ABSL_GUARDED_BY(mu);
    bool last_stress_only ABSL_GUARDED_BY(mu) = false;  // last_result has the stress alone
    // Bytes of this RVE in the registry's memory account, followed after
    // every COMMIT that changes them (a doubled cell). Written under both
    // `mu` and the registry's lock, so read under either.
    std::int64_t memory_bytes = 0;
    bool hosted = true;  // false once dropped (under the registry's lock)
    // Work of the last increment, (DEM steps + 1) × particles: the guess for
    // the next one, by which Apply hands out the longest first. Read without
    // the lock; it orders the work only, never a result.
    std::atomic<std::int64_t> last_work{0};
    explicit Entry(dem::Rve r) : rve(std::move(r)) {}
  };
  using EntryPtr = std::shared_ptr<Entry>;
  // Sorted ids (ListRuns, Get and Export answer in id order) at a few cache
  // lines a lookup: Apply finds every id of its batch before the workers start.
  using Run = absl::btree_map<std::int64_t, EntryPtr>;

  // Entries of `ids` in a run (empty: all), or NotFound naming the missing.
  absl::StatusOr<std::vector<std::pair<std::int64_t, EntryPtr>>> Lookup(
      absl::string_view run_id, std::span<const std::int64_t> ids) const;
  absl::Status CheckCapacity(std::int64_t count, std::int64_t bytes) const
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);
  // An increment of `e` by ΔF that would double its cell (rve.h) grows it
  // about as many times: OK when the growth fits the memory limit, reserved
  // in the account when `reserve` (a COMMIT; a TRIAL's copy only checks),
  // else ResourceExhausted naming the point and the limit (nothing changed).
  absl::Status ReserveGrowth(Entry& e, std::int64_t id, const Eigen::Matrix3d& delta_f,
                             bool reserve, std::int64_t& reserved);
  // Sets e's bytes in the account to its RVE's own, giving back `reserved`
  // (e.mu held).
  void Reaccount(Entry& e, std::int64_t reserved);
  // AlreadyExists naming ids the run has, else CheckCapacity for them.
  absl::Status CheckRoom(absl::string_view run_id, std::span<const std::int64_t> ids,
                         std::int64_t bytes) const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_);

  const RegistryOptions options_;
  mutable WorkerPool pool_;
  mutable absl::Mutex mu_;
  std::map<std::string, Run, std::less<>> runs_ ABSL_GUARDED_BY(mu_);
  struct Template {
    TemplateRecord record;
    TemplateInfo summary;    // computed once, on upload
    std::int64_t bytes = 0;  // in the memory account
  };
  std::map<std::string, Template, std::less<>> templates_ ABSL_GUARDED_BY(mu_);
  std::int64_t num_rves_ ABSL_GUARDED_BY(mu_) = 0;
  std::int64_t memory_bytes_ ABSL_GUARDED_BY(mu_) = 0;  // RVEs' and templates'
};

}  // namespace rvehub::service

#endif  // RVEHUB_RVE_SERVER_SERVICE_REGISTRY_H_
