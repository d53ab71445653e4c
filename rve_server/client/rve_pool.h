// The RVEs of one run of a continuum client spread over RVE endpoints: point
// k (a material point of an MPM run, a Gauss point of a FEM run) has RVE id k
// and lives on one endpoint. A client's solver sees only this class: per call
// one batch per endpoint with all endpoints in flight at once (a step's
// COMMIT, or the TRIALs of an implicit solver's iterations before it),
// retries of lost replies, results in point order; and the assignment of
// points to endpoints, its balancing, and the moves and restores with which
// a client recovers from a lost endpoint.
//
// Results are bit-identical whatever the endpoints and their number: each RVE
// is advanced on its own by a deterministic engine, and states cross the wire
// exactly. Not thread-safe: one solver thread calls it. Errors name point k
// "material point k", as the servers do (the wire's material-point ids).
#ifndef RVEHUB_RVE_SERVER_CLIENT_RVE_POOL_H_
#define RVEHUB_RVE_SERVER_CLIENT_RVE_POOL_H_

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/time/time.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "rve_server/values/state.h"

namespace rvehub::client {

// What the increments of a run cost: DEM steps per increment (the
// quasi-static criterion and min_steps decide them) and the engine's time.
// The pool keeps one for COMMITs and one for TRIALs.
struct ApplyStats {
  // Histogram bins of DEM steps per increment: upper bounds 1, 2, 4, 8, …, 2^11, then more.
  static constexpr int kBins = 13;
  std::int64_t increments = 0;  // RVE increments computed (committed or tried)
  std::int64_t dem_steps = 0;   // DEM steps over those increments
  double engine_seconds = 0.0;  // Σ engine wall time per RVE (summed over workers), s
  std::int64_t histogram[kBins] = {};
  // Bin of an increment of `steps` DEM steps: 0 for ≤ 1, k for (2^(k−1), 2^k].
  static int Bin(std::int64_t steps);
  // Upper bound of bin k (steps); the last bin has none (-1).
  static std::int64_t BinUpper(int k);
  void Add(const ApplyStats& other);
  // What was added since `start` (an earlier copy of this one).
  ApplyStats Since(const ApplyStats& start) const;
};

struct PoolOptions {
  absl::Duration apply_deadline = absl::Minutes(10);  // per attempt of one endpoint's batch
  int max_attempts = 4;  // tries of a batch that fails transiently, at least 1
  absl::Duration backoff = absl::Milliseconds(200);  // before the 2nd try; doubled after each
  dem::ApplyOptions apply_options;                   // sent with every Apply and Trial
  // Adaptive deadline of an Apply or Trial attempt: `deadline_factor` × the
  // slowest endpoint batch of the last few of them, at least
  // min_apply_deadline, at most apply_deadline (which alone applies before
  // the first step and when the factor is 0). A hung server is then found in seconds, not minutes;
  // a batch that is slow for good reason costs a replay (RelaxDeadline).
  // The calls that move states (Get, ExportAll, ImportAll, DropAll,
  // Migrate, Restore: recovery points, moves, restores) get a deadline by
  // the same rule from the slowest of their own last few calls: a server
  // stopped during one is found as soon as during a step. So do an
  // endpoint's consolidating Create calls after its first:
  // `deadline_factor` × the slowest round of consolidations (one per
  // worker) it has done so far × the call's rounds, at least
  // min_apply_deadline (creation may take longer than apply_deadline, so
  // that is no cap there).
  double deadline_factor = 0.0;
  absl::Duration min_apply_deadline = absl::Seconds(10);
};

// Worth sending the same batch again (a COMMIT is safe by its step numbers,
// a TRIAL changes nothing): the server may be restarting, the reply was
// lost, or the deadline passed. The server itself never answers Internal
// (registry errors are all other codes), so Internal is gRPC reporting a
// broken stream.
bool IsTransient(const absl::Status& status);

class RvePool {
 public:
  RvePool(std::vector<std::unique_ptr<RveEndpoint>> endpoints, std::string run_id,
          PoolOptions options = {});
  RvePool(const RvePool&) = delete;
  RvePool& operator=(const RvePool&) = delete;

  int num_endpoints() const { return static_cast<int>(endpoints_.size()); }
  RveEndpoint& endpoint(int k) { return *endpoints_[k]; }
  const std::string& run_id() const { return run_id_; }
  const PoolOptions& options() const { return options_; }
  // E.g. to ask for tangents from some step on.
  void set_apply_options(const dem::ApplyOptions& apply) { options_.apply_options = apply; }
  // ApplyOptions::stress_only of the next Applies and Trials.
  void set_stress_only(bool stress_only) { options_.apply_options.stress_only = stress_only; }

  // Points 0..n−1 onto the live endpoints, balancing the summed
  // cost per worker (any unit, e.g. expected DEM steps or measured engine
  // seconds): greedy longest processing time — points by cost descending
  // (ties: lower index first), each to the endpoint whose cost per worker
  // would be least (ties: lower endpoint index). A cost that is not finite
  // and >= 0 counts as 0. Without live endpoints, nothing is assigned.
  void Assign(std::span<const double> cost);
  // The assignment Assign would make, without making it.
  std::vector<int> PlanAssignment(std::span<const double> cost) const;
  // An explicit assignment (point → endpoint index), e.g. on resume;
  // InvalidArgument (nothing changed) for an index out of range or a lost
  // endpoint.
  absl::Status SetAssignment(std::vector<int> endpoint_of_point);
  // Σ cost per worker of the busiest endpoint under `assignment`: a step's
  // makespan in the cost's unit. An endpoint index out of range counts
  // nothing.
  double Makespan(std::span<const int> assignment, std::span<const double> cost) const;

  // Endpoint liveness. An endpoint whose call failed for good with a
  // transient error (unreachable, connection reset, deadline passed, after
  // the retries) is reported by TakeFailed; the caller decides to MarkLost
  // it. A lost endpoint gets no points and no calls until MarkAlive.
  std::vector<int> TakeFailed();
  // The error that last had endpoint k noted for TakeFailed (OK when none):
  // each lost endpoint's own, where a call's error is the first endpoint's.
  const absl::Status& last_failure(int k) const { return last_failure_[k]; }
  void MarkLost(int k);
  void MarkAlive(int k);
  bool lost(int k) const { return lost_[k]; }
  int num_alive() const;
  // Doubles the adaptive Apply deadline from now on (up to apply_deadline):
  // after a deadline missed by a server that was slow, not hung.
  void RelaxDeadline() { deadline_scale_ *= 2; }
  // The deadline the next Apply attempt gets.
  absl::Duration NextApplyDeadline() const;
  // The deadline the next call that moves states gets.
  absl::Duration NextStateCallDeadline() const;

  // Moves RVEs to `endpoint_of_point` (live endpoints): each moved point's
  // record (of `records`, the full states of every point, by id, as
  // ExportAll gives them) is imported on its new endpoint, then dropped
  // from its old one. On error the assignment is unchanged and RVEs may be
  // on both endpoints: Restore puts everything right.
  absl::Status Migrate(std::vector<int> endpoint_of_point, std::span<const RveRecord> records);
  // Every RVE replaced by `records` (one per point): the run is dropped on
  // every live endpoint, then ImportAll.
  absl::Status Restore(std::vector<RveRecord> records);
  const std::vector<int>& assignment() const { return assignment_; }
  std::int64_t num_points() const { return static_cast<std::int64_t>(assignment_.size()); }
  // The points on endpoint k, ascending (the order they are sent in).
  std::span<const std::int64_t> points_of(int k) const { return points_[k]; }

  // Every template to every endpoint (endpoints concurrently), replacing
  // those of the same names.
  absl::Status UploadTemplates(std::span<const TemplateRecord> templates);

  // Creates the run's RVEs: template per point (or one for all) and initial
  // stress per point (empty: the template's state; one for all; or one per
  // point, e.g. geostatic). `controls` (by template name): the controls of
  // that template's new RVEs; a template not named keeps its own. Without an
  // assignment, assigns equal costs first. States after creation, in point
  // order.
  // Consolidation is the slow part, one per distinct initial stress (per
  // template and endpoint): those are sent in calls of a few at a time, and
  // `progress(done, total)` (optional; first with done = 0, then after each
  // call, from the endpoints' threads, one call at a time) counts the
  // consolidations finished. A remote endpoint's calls after its first
  // have the adaptive deadline (PoolOptions): a server that hangs during
  // creation ends it with DeadlineExceeded naming the server, not hours on.
  using CreateProgress = std::function<void(std::int64_t done, std::int64_t total)>;
  absl::StatusOr<std::vector<dem::RveState>> Create(
      std::span<const std::string> template_per_point,
      std::span<const InitialStress> initial_per_point = {},
      const std::map<std::string, dem::Controls>& controls = {},
      const CreateProgress& progress = {});

  // COMMITs step `step` (≥ 1) with ΔF per point ([-], plane strain): one
  // batch per endpoint, all in flight at once; a batch failing transiently is
  // sent again as it was (the server answers RVEs already committed from
  // memory). The first error by endpoint index, once all have finished; a
  // per-RVE error names the endpoint, the point and why. States in point
  // order, each with its tangent when `want_tangent` or the apply options
  // ask for it.
  absl::StatusOr<std::vector<dem::RveState>> Apply(std::int64_t step,
                                                   std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent = false);

  // TRIALs step `step` with ΔF per point: the state each RVE would reach
  // from its committed step `step` − 1 (RveEndpoint::StartApply, kTrial),
  // with its tangent when `want_tangent` (or the apply options ask for it);
  // no RVE changes. For an implicit client's Newton iterations: any number
  // of TRIALs of a step, then the COMMIT of the converged ΔF, which returns
  // the states a TRIAL of that ΔF (and the same options) did, bit for bit.
  // Sent as Apply sends (one batch per endpoint, all in flight at once, the
  // same retries: a TRIAL is always safe to send again); an RVE not at
  // `step` − 1 (one that committed `step` already, or is further behind)
  // fails with FailedPrecondition naming the endpoint and the point.
  // States in point order.
  absl::StatusOr<std::vector<dem::RveState>> Trial(std::int64_t step,
                                                   std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent);

  // Current states in point order.
  absl::StatusOr<std::vector<dem::RveState>> Get(bool want_tangent);

  // Full states of every point, sorted by id.
  absl::StatusOr<std::vector<RveRecord>> ExportAll();
  // One record per point (ids 0..n−1), placed by the current assignment
  // (without one: equal costs over the records) and renamed into this run.
  absl::Status ImportAll(std::vector<RveRecord> records);
  // Drops the run on every endpoint (one hosting none is fine).
  absl::Status DropAll();

  // RVE increments committed by Apply since construction (TRIALs are not
  // counted here: trial_stats).
  std::int64_t evaluations() const { return evaluations_; }
  // Their DEM steps and engine time since construction.
  const ApplyStats& apply_stats() const { return stats_; }
  // The same for the RVE increments tried by Trial (increments: one per
  // point and Trial that succeeded).
  const ApplyStats& trial_stats() const { return trial_stats_; }
  // Worker threads over all endpoints.
  int total_workers() const;
  // The measures below count what the servers did, so COMMITs and TRIALs
  // alike: an implicit client's iterations load them as much as its steps.
  // Wall time of each endpoint's batch in the last Apply or Trial (retries
  // included), s.
  const std::vector<double>& last_apply_seconds() const { return last_apply_seconds_; }
  // Wall time spent inside Apply and Trial overall, s.
  double total_apply_seconds() const { return total_apply_seconds_; }
  // Engine seconds per point since construction (measured by the servers).
  const std::vector<double>& point_engine_seconds() const { return point_seconds_; }
  // Work per point since construction: Σ DEM steps × the point's size (see
  // SetPointSizes; 1 until set), particle-steps. What balancing goes by: it
  // follows the engine time (a step costs about the same per particle) but
  // is exact, where time measured beside other processes on shared cores is
  // noisy.
  const std::vector<double>& point_work() const { return point_work_; }
  // Particles per point (e.g. from the templates or exported records).
  void SetPointSizes(std::vector<double> sizes) { point_size_ = std::move(sizes); }
  // Per endpoint since construction: wall time of its Apply and Trial
  // batches and its RVEs' engine seconds, s.
  const std::vector<double>& endpoint_busy_seconds() const { return busy_seconds_; }
  const std::vector<double>& endpoint_engine_seconds() const { return engine_seconds_; }

 private:
  // Runs fn(k) for every live endpoint k, concurrently when there are
  // several; the first error by endpoint index. Endpoints failing
  // transiently are noted for TakeFailed.
  absl::Status ForEachEndpoint(const std::function<absl::Status(int)>& fn);
  // ForEachEndpoint for calls that move states: they get
  // NextStateCallDeadline and, when they succeed, are measured for the next.
  absl::Status ForEachStateCall(const std::function<absl::Status(int)>& fn);
  absl::Status OnEachEndpoint(const std::function<absl::Status(int)>& fn, bool state_call);
  // The adaptive deadline for a call expected to take `seconds`: that ×
  // deadline_factor, at least min_apply_deadline, × deadline_scale_, at
  // most `cap`.
  absl::Duration AdaptiveDeadline(double seconds, absl::Duration cap) const;
  // AdaptiveDeadline of the slowest of `recent` calls, capped at
  // apply_deadline; apply_deadline alone before any or with the factor 0.
  absl::Duration DeadlineAfter(const std::vector<double>& recent) const;
  // Apply and Trial: one batch per endpoint, all in flight at once, retried.
  absl::StatusOr<std::vector<dem::RveState>> ApplyBatches(ApplyMode mode, std::int64_t step,
                                                          std::span<const Eigen::Matrix3d> delta_f,
                                                          bool want_tangent);
  // The result of endpoint k's batch (`what`: "step 3", "trial of step 3"):
  // OK with states into `out` and counts into `stats`, or the error,
  // `transient` when a retry of the same batch may cure it.
  absl::Status Judge(int k, absl::string_view what, absl::StatusOr<std::vector<RveOutcome>>& result,
                     std::vector<dem::RveState>& out, ApplyStats& stats, bool& transient);
  // Notes endpoint k for TakeFailed when `s` is transient.
  void NoteFailure(int k, const absl::Status& s);
  // A whole-call error of endpoint k, with what was being done and the
  // endpoint named (endpoints name themselves; a wrapper might not).
  absl::Status CallError(int k, const absl::Status& s, absl::string_view what) const;
  // The error for a failed outcome on endpoint k, naming the point.
  absl::Status PointError(int k, const RveOutcome& o, absl::string_view what) const;
  // States into `out` (point order) from the outcomes for `ids` on endpoint
  // k; the first failed outcome (in `ids` order) is the error.
  absl::Status Collect(int k, std::span<const std::int64_t> ids, std::vector<RveOutcome>& outcomes,
                       absl::string_view what, std::vector<dem::RveState>& out) const;

  std::vector<std::unique_ptr<RveEndpoint>> endpoints_;
  const std::string run_id_;
  PoolOptions options_;
  std::vector<int> assignment_;                    // point → endpoint
  std::vector<std::vector<std::int64_t>> points_;  // endpoint → points, ascending
  std::int64_t evaluations_ = 0;
  ApplyStats stats_;
  ApplyStats trial_stats_;
  std::vector<double> last_apply_seconds_;
  double total_apply_seconds_ = 0.0;
  std::vector<bool> lost_;
  std::vector<absl::Status> last_failure_;    // per endpoint, see last_failure()
  std::vector<int> failed_;                   // noted since the last TakeFailed, ascending
  std::vector<double> recent_batch_seconds_;  // the slowest batch of the last few steps
  std::vector<double> recent_state_seconds_;  // the slowest endpoint of the last few state calls
  // Per endpoint, the slowest round of consolidations (one per worker) its
  // Create calls took so far, s.
  std::vector<double> round_seconds_;
  double deadline_scale_ = 1.0;
  std::vector<double> point_seconds_, point_work_, point_size_, busy_seconds_, engine_seconds_;
};

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_RVE_POOL_H_
