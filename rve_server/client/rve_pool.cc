#include "rve_server/client/rve_pool.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>
#include <thread>
#include <tuple>
#include <utility>

#include "absl/base/casts.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/clock.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::client {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

absl::Status NoRves() {
  return absl::FailedPreconditionError(
      "the pool has no material points yet: Create or ImportAll first");
}

absl::Status NoEndpoints() {
  return absl::FailedPreconditionError("the pool has no RVE endpoints");
}

}  // namespace

bool IsTransient(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDeadlineExceeded:
    case absl::StatusCode::kAborted:
    case absl::StatusCode::kInternal:
      return true;
    default:
      return false;
  }
}

RvePool::RvePool(std::vector<std::unique_ptr<RveEndpoint>> endpoints, std::string run_id,
                 PoolOptions options)
    : endpoints_(std::move(endpoints)),
      run_id_(std::move(run_id)),
      options_(options),
      points_(endpoints_.size()),
      last_apply_seconds_(endpoints_.size(), 0.0),
      lost_(endpoints_.size(), false),
      last_failure_(endpoints_.size()),
      round_seconds_(endpoints_.size(), 0.0),
      busy_seconds_(endpoints_.size(), 0.0),
      engine_seconds_(endpoints_.size(), 0.0) {}

void RvePool::NoteFailure(int k, const absl::Status& s) {
  if (s.ok() || !IsTransient(s)) return;
  last_failure_[k] = s;
  if (std::find(failed_.begin(), failed_.end(), k) == failed_.end()) {
    failed_.insert(std::upper_bound(failed_.begin(), failed_.end(), k), k);
  }
}

std::vector<int> RvePool::TakeFailed() { return std::exchange(failed_, {}); }

void RvePool::MarkLost(int k) { lost_[k] = true; }
void RvePool::MarkAlive(int k) { lost_[k] = false; }

int RvePool::num_alive() const {
  return static_cast<int>(std::count(lost_.begin(), lost_.end(), false));
}

absl::Duration RvePool::AdaptiveDeadline(double seconds, absl::Duration cap) const {
  const absl::Duration d =
      std::max(options_.min_apply_deadline, absl::Seconds(options_.deadline_factor * seconds)) *
      deadline_scale_;
  return std::min(d, cap);
}

absl::Duration RvePool::DeadlineAfter(const std::vector<double>& recent) const {
  if (options_.deadline_factor <= 0 || recent.empty()) return options_.apply_deadline;
  return AdaptiveDeadline(*std::max_element(recent.begin(), recent.end()), options_.apply_deadline);
}

absl::Duration RvePool::NextApplyDeadline() const { return DeadlineAfter(recent_batch_seconds_); }

absl::Duration RvePool::NextStateCallDeadline() const {
  return DeadlineAfter(recent_state_seconds_);
}

namespace {

// Keeps the last few of a measured quantity.
void Remember(std::vector<double>& recent, double value) {
  constexpr std::size_t kRecent = 8;
  if (recent.size() == kRecent) recent.erase(recent.begin());
  recent.push_back(value);
}

}  // namespace

absl::Status RvePool::ForEachEndpoint(const std::function<absl::Status(int)>& fn) {
  return OnEachEndpoint(fn, /*state_call=*/false);
}

absl::Status RvePool::ForEachStateCall(const std::function<absl::Status(int)>& fn) {
  return OnEachEndpoint(fn, /*state_call=*/true);
}

absl::Status RvePool::OnEachEndpoint(const std::function<absl::Status(int)>& fn, bool state_call) {
  std::vector<absl::Status> status(endpoints_.size());
  std::vector<double> seconds(endpoints_.size(), 0.0);
  if (state_call && options_.deadline_factor > 0) {
    const absl::Duration deadline = NextStateCallDeadline();
    for (const std::unique_ptr<RveEndpoint>& e : endpoints_) e->SetCallTimeout(deadline);
  }
  const std::function<absl::Status(int)> timed = [&](int k) {
    const auto start = std::chrono::steady_clock::now();
    absl::Status s = fn(k);
    seconds[k] = SecondsSince(start);
    return s;
  };
  if (endpoints_.size() == 1) {
    if (!lost_[0]) status[0] = timed(0);
  } else {
    // Setup and checkpoint calls only (templates, creation, export, import,
    // drop: a few per run, not per step): a thread per endpoint for the
    // call, which mostly waits on the network or the registry's workers.
    // The per-step Apply needs none (asynchronous calls).
    std::vector<std::thread> threads;
    threads.reserve(endpoints_.size());
    for (int k = 0; k < num_endpoints(); ++k) {
      if (!lost_[k]) threads.emplace_back([&timed, &status, k] { status[k] = timed(k); });
    }
    for (std::thread& t : threads) t.join();
  }
  for (int k = 0; k < num_endpoints(); ++k) NoteFailure(k, status[k]);
  for (const absl::Status& s : status)
    if (!s.ok()) return s;
  if (state_call)
    Remember(recent_state_seconds_, *std::max_element(seconds.begin(), seconds.end()));
  return absl::OkStatus();
}

namespace {
double CostOf(double c) { return std::isfinite(c) && c > 0 ? c : 0.0; }
}  // namespace

std::vector<int> RvePool::PlanAssignment(std::span<const double> cost) const {
  if (num_alive() == 0) return {};
  const std::size_t n = cost.size();
  std::vector<std::int64_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::int64_t a, std::int64_t b) {
    const double ca = CostOf(cost[a]), cb = CostOf(cost[b]);
    return ca != cb ? ca > cb : a < b;
  });
  std::vector<double> load(endpoints_.size(), 0.0);
  std::vector<int> assignment(n);
  for (std::int64_t p : order) {
    const double c = CostOf(cost[p]);
    int best = -1;
    double best_load = 0.0;
    for (int k = 0; k < num_endpoints(); ++k) {
      if (lost_[k]) continue;
      const double l = (load[k] + c) / std::max(1, endpoints_[k]->workers());
      if (best < 0 || l < best_load) {
        best = k;
        best_load = l;
      }
    }
    assignment[p] = best;
    load[best] += c;
  }
  return assignment;
}

void RvePool::Assign(std::span<const double> cost) {
  if (num_alive() == 0) return;
  // In range and live by construction.
  (void)SetAssignment(PlanAssignment(cost));
}

double RvePool::Makespan(std::span<const int> assignment, std::span<const double> cost) const {
  std::vector<double> load(endpoints_.size(), 0.0);
  for (std::size_t p = 0; p < assignment.size() && p < cost.size(); ++p) {
    const int k = assignment[p];
    if (k >= 0 && k < num_endpoints()) load[k] += CostOf(cost[p]);  // else it counts nothing
  }
  double makespan = 0.0;
  for (int k = 0; k < num_endpoints(); ++k) {
    makespan = std::max(makespan, load[k] / std::max(1, endpoints_[k]->workers()));
  }
  return makespan;
}

absl::Status RvePool::SetAssignment(std::vector<int> endpoint_of_point) {
  std::vector<std::vector<std::int64_t>> points(endpoints_.size());
  for (std::size_t p = 0; p < endpoint_of_point.size(); ++p) {
    const int k = endpoint_of_point[p];
    if (k < 0 || k >= num_endpoints()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "material point ", p, " is assigned to endpoint ", k, " of ", num_endpoints()));
    }
    if (lost_[k]) {
      return absl::InvalidArgumentError(absl::StrCat("material point ", p,
                                                     " is assigned to lost endpoint ", k, " (",
                                                     endpoints_[k]->label(), ")"));
    }
    points[k].push_back(static_cast<std::int64_t>(p));
  }
  assignment_ = std::move(endpoint_of_point);
  points_ = std::move(points);
  point_seconds_.resize(assignment_.size(), 0.0);
  point_work_.resize(assignment_.size(), 0.0);
  return absl::OkStatus();
}

absl::Status RvePool::CallError(int k, const absl::Status& s, absl::string_view what) const {
  const std::string label = endpoints_[k]->label();
  if (absl::StartsWith(s.message(), label))
    return absl::Status(s.code(), absl::StrCat(what, ": ", s.message()));
  return absl::Status(s.code(), absl::StrCat(what, ": ", label, ": ", s.message()));
}

absl::Status RvePool::PointError(int k, const RveOutcome& o, absl::string_view what) const {
  return absl::Status(o.status.code(),
                      absl::StrCat(what, ": ", endpoints_[k]->label(), ": material point ", o.id,
                                   ": ", o.status.message()));
}

absl::Status RvePool::Collect(int k, std::span<const std::int64_t> ids,
                              std::vector<RveOutcome>& outcomes, absl::string_view what,
                              std::vector<dem::RveState>& out) const {
  if (outcomes.size() != ids.size()) {
    return absl::DataLossError(absl::StrCat(what, ": ", endpoints_[k]->label(), " answered ",
                                            outcomes.size(), " RVEs of ", ids.size()));
  }
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const RveOutcome& o = outcomes[i];
    if (!o.status.ok()) return PointError(k, o, what);
    if (o.id != ids[i]) {
      return absl::DataLossError(absl::StrCat(what, ": ", endpoints_[k]->label(),
                                              " answered material point ", o.id, " for ", ids[i]));
    }
  }
  for (std::size_t i = 0; i < ids.size(); ++i) out[ids[i]] = std::move(outcomes[i].state);
  return absl::OkStatus();
}

absl::Status RvePool::UploadTemplates(std::span<const TemplateRecord> templates) {
  return ForEachEndpoint([&](int k) -> absl::Status {
    for (const TemplateRecord& t : templates) {
      if (absl::Status s = endpoints_[k]->PutTemplate(t); !s.ok())
        return CallError(k, s, absl::StrCat("uploading template \"", t.name, "\""));
    }
    return absl::OkStatus();
  });
}

namespace {

// The registry consolidates each distinct initial stress of a call once
// (bitwise equal targets); the same key here keeps them in one call.
using StressKey = std::tuple<int, std::uint64_t, std::uint64_t, std::uint64_t>;
StressKey KeyOf(const InitialStress& s) {
  return {static_cast<int>(s.kind), absl::bit_cast<std::uint64_t>(s.pressure),
          absl::bit_cast<std::uint64_t>(s.vertical_compression),
          absl::bit_cast<std::uint64_t>(s.k0)};
}

// One Create call: ids with their initial stresses (none, one for all, or
// one per id) and the distinct stresses among them.
struct CreateCall {
  std::vector<std::int64_t> ids;
  std::vector<InitialStress> initial;
  std::int64_t consolidations = 1;
};

// The calls for `ids` of one template on one endpoint: whole groups of equal
// initial stress, `per_call` groups a call (the last may have fewer), so
// each stress is still consolidated once and the workers stay busy, while
// progress is seen every few consolidations.
std::vector<CreateCall> SplitCreate(const std::vector<std::int64_t>& ids,
                                    std::span<const InitialStress> initial_per_point,
                                    std::int64_t per_call) {
  std::vector<CreateCall> calls;
  if (initial_per_point.size() <= 1) {
    CreateCall& c = calls.emplace_back();
    c.ids = ids;
    c.initial.assign(initial_per_point.begin(), initial_per_point.end());
    return calls;
  }
  std::map<StressKey, std::size_t> group_of;
  std::vector<std::vector<std::int64_t>> groups;  // in order of first appearance
  for (std::int64_t p : ids) {
    auto [it, inserted] = group_of.try_emplace(KeyOf(initial_per_point[p]), groups.size());
    if (inserted) groups.emplace_back();
    groups[it->second].push_back(p);
  }
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (g % per_call == 0) calls.emplace_back().consolidations = 0;
    CreateCall& c = calls.back();
    ++c.consolidations;
    for (std::int64_t p : groups[g]) {
      c.ids.push_back(p);
      c.initial.push_back(initial_per_point[p]);
    }
  }
  return calls;
}

}  // namespace

absl::StatusOr<std::vector<dem::RveState>> RvePool::Create(
    std::span<const std::string> template_per_point,
    std::span<const InitialStress> initial_per_point,
    const std::map<std::string, dem::Controls>& controls, const CreateProgress& progress) {
  if (endpoints_.empty()) return NoEndpoints();
  if (assignment_.empty()) Assign(std::vector<double>(template_per_point.size(), 1.0));
  const std::size_t n = assignment_.size();
  if (template_per_point.size() != 1 && template_per_point.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat("give one template for all or one per point (",
                                                   n, "), not ", template_per_point.size()));
  }
  if (initial_per_point.size() > 1 && initial_per_point.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("give no initial stress, one for all or one per point (", n, "), not ",
                     initial_per_point.size()));
  }
  // Per endpoint: one template at a time, in name order, in calls.
  struct TemplateCalls {
    std::string name;
    std::vector<CreateCall> calls;
  };
  std::vector<std::vector<TemplateCalls>> plan(endpoints_.size());
  std::int64_t total = 0;
  for (int k = 0; k < num_endpoints(); ++k) {
    std::map<std::string, std::vector<std::int64_t>> by_template;
    for (std::int64_t p : points_[k])
      by_template[template_per_point.size() == 1 ? template_per_point[0] : template_per_point[p]]
          .push_back(p);
    // Two consolidations per worker a call: a few calls even for a column's
    // handful of depths (column-collapse-ci: 8 on 2 workers), while the
    // workers' idle tail at the end of each call stays about one
    // consolidation (neighbouring depths cost about the same).
    const std::int64_t per_call = 2 * std::max(1, endpoints_[k]->workers());
    for (const auto& [name, ids] : by_template) {
      plan[k].push_back({name, SplitCreate(ids, initial_per_point, per_call)});
      for (const CreateCall& c : plan[k].back().calls) total += c.consolidations;
    }
  }
  absl::Mutex mu;
  std::int64_t done = 0;
  if (progress) progress(0, total);
  std::vector<dem::RveState> out(n);
  absl::Status s = ForEachEndpoint([&](int k) -> absl::Status {
    for (const TemplateCalls& t : plan[k]) {
      const std::string what = absl::StrCat("creating RVEs of template \"", t.name, "\"");
      auto own = controls.find(t.name);
      for (const CreateCall& c : t.calls) {
        // The call's time is about its rounds of consolidations on the
        // workers. Calls of template states alone consolidate nothing and
        // are no measure.
        const bool consolidates =
            !c.initial.empty() &&
            std::none_of(c.initial.begin(), c.initial.end(), [](const InitialStress& i) {
              return i.kind == InitialStress::Kind::kTemplate;
            });
        const std::int64_t workers = std::max(1, endpoints_[k]->workers());
        const double rounds = static_cast<double>(
            (std::max<std::int64_t>(1, c.consolidations) + workers - 1) / workers);
        if (consolidates && options_.deadline_factor > 0 && round_seconds_[k] > 0) {
          endpoints_[k]->SetCreateTimeout(
              AdaptiveDeadline(round_seconds_[k] * rounds, absl::InfiniteDuration()));
        }
        const auto start = std::chrono::steady_clock::now();
        absl::StatusOr<std::vector<RveOutcome>> r = endpoints_[k]->Create(
            run_id_, t.name, c.ids, c.initial,
            own == controls.end() ? std::nullopt : std::optional<dem::Controls>(own->second));
        if (!r.ok()) return CallError(k, r.status(), what);
        if (consolidates)
          round_seconds_[k] = std::max(round_seconds_[k], SecondsSince(start) / rounds);
        RETURN_IF_ERROR(Collect(k, c.ids, *r, what, out));
        if (progress) {
          absl::MutexLock lock(&mu);
          done += c.consolidations;
          progress(done, total);
        }
      }
    }
    return absl::OkStatus();
  });
  if (!s.ok()) return s;
  return out;
}

int ApplyStats::Bin(std::int64_t steps) {
  int bin = 0;
  while (bin < kBins - 1 && steps > BinUpper(bin)) ++bin;
  return bin;
}

std::int64_t ApplyStats::BinUpper(int k) { return k < kBins - 1 ? std::int64_t{1} << k : -1; }

void ApplyStats::Add(const ApplyStats& other) {
  increments += other.increments;
  dem_steps += other.dem_steps;
  engine_seconds += other.engine_seconds;
  for (int b = 0; b < kBins; ++b) histogram[b] += other.histogram[b];
}

ApplyStats ApplyStats::Since(const ApplyStats& start) const {
  ApplyStats d = *this;
  d.increments -= start.increments;
  d.dem_steps -= start.dem_steps;
  d.engine_seconds -= start.engine_seconds;
  for (int b = 0; b < kBins; ++b) d.histogram[b] -= start.histogram[b];
  return d;
}

int RvePool::total_workers() const {
  int n = 0;
  for (const std::unique_ptr<RveEndpoint>& e : endpoints_) n += e->workers();
  return std::max(1, n);
}

absl::Status RvePool::Judge(int k, absl::string_view what,
                            absl::StatusOr<std::vector<RveOutcome>>& result,
                            std::vector<dem::RveState>& out, ApplyStats& stats, bool& transient) {
  const std::vector<std::int64_t>& ids = points_[k];
  transient = false;
  if (!result.ok()) {
    transient = IsTransient(result.status());
    return CallError(k, result.status(), what);
  }
  // A per-RVE failure of its own (a refused ΔF, a wrong step) is final;
  // RVEs skipped because the deadline passed are completed by a retry.
  const RveOutcome* retry = nullptr;
  for (const RveOutcome& o : *result) {
    if (o.status.ok()) continue;
    if (!IsTransient(o.status)) return PointError(k, o, what);
    if (retry == nullptr) retry = &o;
  }
  if (retry != nullptr) {
    transient = true;
    return PointError(k, *retry, what);
  }
  RETURN_IF_ERROR(Collect(k, ids, *result, what, out));
  for (const RveOutcome& o : *result) {
    ++stats.increments;
    stats.dem_steps += o.state.steps;
    stats.engine_seconds += o.engine_seconds;
    const std::size_t id = static_cast<std::size_t>(o.id);  // checked by Collect
    point_seconds_[id] += o.engine_seconds;
    point_work_[id] +=
        static_cast<double>(o.state.steps) * (id < point_size_.size() ? point_size_[id] : 1.0);
    ++stats.histogram[ApplyStats::Bin(o.state.steps)];
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<dem::RveState>> RvePool::Apply(std::int64_t step,
                                                          std::span<const Eigen::Matrix3d> delta_f,
                                                          bool want_tangent) {
  return ApplyBatches(ApplyMode::kCommit, step, delta_f, want_tangent);
}

absl::StatusOr<std::vector<dem::RveState>> RvePool::Trial(std::int64_t step,
                                                          std::span<const Eigen::Matrix3d> delta_f,
                                                          bool want_tangent) {
  return ApplyBatches(ApplyMode::kTrial, step, delta_f, want_tangent);
}

absl::StatusOr<std::vector<dem::RveState>> RvePool::ApplyBatches(
    ApplyMode mode, std::int64_t step, std::span<const Eigen::Matrix3d> delta_f,
    bool want_tangent) {
  const bool commit = mode == ApplyMode::kCommit;
  const std::string what =
      commit ? absl::StrCat("step ", step) : absl::StrCat("trial of step ", step);
  if (assignment_.empty()) return NoRves();
  const std::size_t n = assignment_.size();
  if (delta_f.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": ", delta_f.size(), " ΔF for ", n, " material points"));
  }
  dem::ApplyOptions options = options_.apply_options;
  options.want_tangent = options.want_tangent || want_tangent;
  const auto start = std::chrono::steady_clock::now();
  std::vector<dem::RveState> out(n);
  std::vector<ApplyStats> stats(endpoints_.size());
  std::fill(last_apply_seconds_.begin(), last_apply_seconds_.end(), 0.0);

  // One batch per endpoint, all in flight at once without a thread each:
  // remote endpoints' calls go out first (gRPC callbacks), then the
  // in-process ones run on their registries' workers, then the caller
  // collects. A batch failing transiently is sent again as it was (the
  // server answers RVEs already committed from memory; a TRIAL is computed
  // again), after a backoff that doubles per attempt.
  struct Batch {
    std::vector<Increment> increments;
    std::unique_ptr<PendingApply> call;
    int attempts = 0;
    bool done = false;
    absl::Status status;
  };
  std::vector<Batch> batches(endpoints_.size());
  for (int k = 0; k < num_endpoints(); ++k) {
    const std::vector<std::int64_t>& ids = points_[k];
    batches[k].done = ids.empty();
    batches[k].increments.resize(ids.size());
    for (std::size_t i = 0; i < ids.size(); ++i) {
      batches[k].increments[i] = {ids[i], delta_f[ids[i]]};
    }
  }
  const int max_attempts = std::max(1, options_.max_attempts);
  absl::Duration backoff = options_.backoff;
  const absl::Duration deadline = NextApplyDeadline();
  for (bool pending = true; pending;) {
    for (bool in_process : {false, true}) {
      for (int k = 0; k < num_endpoints(); ++k) {
        Batch& b = batches[k];
        if (b.done || endpoints_[k]->in_process() != in_process) continue;
        ++b.attempts;
        b.call = endpoints_[k]->StartApply(run_id_, step, mode, b.increments, options, deadline);
      }
    }
    pending = false;
    for (int k = 0; k < num_endpoints(); ++k) {
      Batch& b = batches[k];
      if (b.done) continue;
      absl::StatusOr<std::vector<RveOutcome>> result = b.call->Finish();
      last_apply_seconds_[k] += b.call->seconds();
      b.call.reset();
      bool transient = false;
      b.status = Judge(k, what, result, out, stats[k], transient);
      if (b.status.ok() || !transient) {
        b.done = true;
      } else if (b.attempts >= max_attempts) {
        b.done = true;
        b.status = absl::Status(b.status.code(),
                                absl::StrCat(b.status.message(), " (gave up after ", max_attempts,
                                             max_attempts == 1 ? " attempt)" : " attempts)"));
        NoteFailure(k, b.status);
      } else {
        pending = true;
      }
    }
    if (pending) {
      absl::SleepFor(backoff);
      backoff *= 2;
    }
  }
  for (const ApplyStats& st : stats) {
    if (commit) {
      evaluations_ += st.increments;
      stats_.Add(st);
    } else {
      trial_stats_.Add(st);
    }
  }
  total_apply_seconds_ += SecondsSince(start);
  double slowest = 0.0;
  for (int k = 0; k < num_endpoints(); ++k) {
    busy_seconds_[k] += last_apply_seconds_[k];
    engine_seconds_[k] += stats[k].engine_seconds;
    slowest = std::max(slowest, last_apply_seconds_[k]);
  }
  for (const Batch& b : batches) {
    if (!b.status.ok()) return b.status;  // the first error by endpoint index
  }
  // Successful calls only: a missed deadline must not stretch the next one.
  Remember(recent_batch_seconds_, slowest);
  return out;
}

absl::StatusOr<std::vector<dem::RveState>> RvePool::Get(bool want_tangent) {
  if (assignment_.empty()) return NoRves();
  std::vector<dem::RveState> out(assignment_.size());
  absl::Status s = ForEachStateCall([&](int k) -> absl::Status {
    const std::vector<std::int64_t>& ids = points_[k];
    if (ids.empty()) return absl::OkStatus();
    absl::StatusOr<std::vector<RveOutcome>> r = endpoints_[k]->Get(run_id_, ids, want_tangent);
    if (!r.ok()) return CallError(k, r.status(), "getting states");
    return Collect(k, ids, *r, "getting states", out);
  });
  if (!s.ok()) return s;
  return out;
}

absl::StatusOr<std::vector<RveRecord>> RvePool::ExportAll() {
  if (assignment_.empty()) return NoRves();
  std::vector<std::vector<RveRecord>> parts(endpoints_.size());
  absl::Status s = ForEachStateCall([&](int k) -> absl::Status {
    const std::vector<std::int64_t>& ids = points_[k];
    if (ids.empty()) return absl::OkStatus();  // empty ids would export the whole run
    parts[k].reserve(ids.size());
    absl::Status e = endpoints_[k]->Export(run_id_, ids, [&](RveRecord&& r) {
      parts[k].push_back(std::move(r));
      return absl::OkStatus();
    });
    if (!e.ok()) return CallError(k, e, "exporting RVEs");
    if (parts[k].size() != ids.size()) {
      return absl::DataLossError(absl::StrCat("exporting RVEs: ", endpoints_[k]->label(), " sent ",
                                              parts[k].size(), " of ", ids.size()));
    }
    return absl::OkStatus();
  });
  if (!s.ok()) return s;
  std::vector<RveRecord> out;
  out.reserve(assignment_.size());
  for (std::vector<RveRecord>& part : parts)
    for (RveRecord& r : part) out.push_back(std::move(r));
  std::sort(out.begin(), out.end(),
            [](const RveRecord& a, const RveRecord& b) { return a.id < b.id; });
  return out;
}

absl::Status RvePool::ImportAll(std::vector<RveRecord> records) {
  if (endpoints_.empty()) return NoEndpoints();
  if (assignment_.empty()) Assign(std::vector<double>(records.size(), 1.0));
  const std::size_t n = assignment_.size();
  if (records.size() != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("import of ", records.size(), " RVEs for ", n, " material points"));
  }
  std::vector<bool> seen(n, false);
  for (const RveRecord& r : records) {
    if (r.id < 0 || static_cast<std::size_t>(r.id) >= n) {
      return absl::InvalidArgumentError(
          absl::StrCat("import: material point ", r.id, " is outside 0..", n - 1));
    }
    if (seen[r.id]) {
      return absl::InvalidArgumentError(
          absl::StrCat("import: material point ", r.id, " appears twice"));
    }
    seen[r.id] = true;
  }
  std::sort(records.begin(), records.end(),
            [](const RveRecord& a, const RveRecord& b) { return a.id < b.id; });
  std::vector<std::vector<RveRecord>> parts(endpoints_.size());
  for (RveRecord& r : records) {
    r.run_id = run_id_;
    parts[assignment_[r.id]].push_back(std::move(r));
  }
  return ForEachStateCall([&](int k) -> absl::Status {
    if (parts[k].empty()) return absl::OkStatus();
    if (absl::Status s = endpoints_[k]->Import(std::move(parts[k])); !s.ok())
      return CallError(k, s, "importing RVEs");
    return absl::OkStatus();
  });
}

absl::Status RvePool::DropAll() {
  return ForEachStateCall([&](int k) -> absl::Status {
    absl::Status s = endpoints_[k]->Drop(run_id_);
    if (s.ok() || absl::IsNotFound(s)) return absl::OkStatus();
    return CallError(k, s, "dropping the run");
  });
}

absl::Status RvePool::Restore(std::vector<RveRecord> records) {
  RETURN_IF_ERROR(DropAll());
  return ImportAll(std::move(records));
}

absl::Status RvePool::Migrate(std::vector<int> endpoint_of_point,
                              std::span<const RveRecord> records) {
  const std::size_t n = assignment_.size();
  if (endpoint_of_point.size() != n || records.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat("migration of ", records.size(), " RVEs to ",
                                                   endpoint_of_point.size(), " places for ", n,
                                                   " material points"));
  }
  std::vector<std::vector<RveRecord>> arriving(endpoints_.size());
  std::vector<std::vector<std::int64_t>> leaving(endpoints_.size());
  for (std::size_t p = 0; p < n; ++p) {
    const int to = endpoint_of_point[p], from = assignment_[p];
    if (to < 0 || to >= num_endpoints() || lost_[to]) {
      return absl::InvalidArgumentError(
          absl::StrCat("migration: material point ", p, " to endpoint ", to, ", not a live one"));
    }
    if (records[p].id != static_cast<std::int64_t>(p)) {
      return absl::InvalidArgumentError(
          absl::StrCat("migration: record ", p, " is for material point ", records[p].id));
    }
    if (to == from) continue;
    RveRecord& r = arriving[to].emplace_back(records[p]);
    r.run_id = run_id_;
    leaving[from].push_back(static_cast<std::int64_t>(p));
  }
  RETURN_IF_ERROR(ForEachStateCall([&](int k) -> absl::Status {
    if (arriving[k].empty()) return absl::OkStatus();
    if (absl::Status s = endpoints_[k]->Import(std::move(arriving[k])); !s.ok())
      return CallError(k, s, "moving RVEs in");
    return absl::OkStatus();
  }));
  RETURN_IF_ERROR(ForEachStateCall([&](int k) -> absl::Status {
    if (leaving[k].empty()) return absl::OkStatus();
    if (absl::Status s = endpoints_[k]->Drop(run_id_, leaving[k]); !s.ok())
      return CallError(k, s, "moving RVEs out");
    return absl::OkStatus();
  }));
  return SetAssignment(std::move(endpoint_of_point));
}

}  // namespace rvehub::client
