#include "rve_server/service/registry.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <new>
#include <optional>
#include <set>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "absl/base/casts.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/prepare.h"

namespace rvehub::service {
namespace {

constexpr std::size_t kMaxDescriptionBytes = 4096;
constexpr int kMaxListedIds = 8;  // ids named in one error message at most

}  // namespace

namespace {

// "1, 2, 3 and 5 more" for error messages.
std::string ListIds(const std::vector<std::int64_t>& ids) {
  const std::size_t shown = std::min<std::size_t>(ids.size(), kMaxListedIds);
  std::string s = absl::StrJoin(ids.begin(), ids.begin() + shown, ", ");
  if (ids.size() > shown) absl::StrAppend(&s, " and ", ids.size() - shown, " more");
  return s;
}

// Duplicates among ids, sorted.
std::vector<std::int64_t> Repeated(std::span<const std::int64_t> ids) {
  std::vector<std::int64_t> sorted(ids.begin(), ids.end());
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::int64_t> repeated;
  for (std::size_t k = 1; k < sorted.size(); ++k) {
    if (sorted[k] == sorted[k - 1] && (repeated.empty() || repeated.back() != sorted[k]))
      repeated.push_back(sorted[k]);
  }
  return repeated;
}

absl::Status UnknownRun(absl::string_view run_id) {
  return absl::NotFoundError(absl::StrCat("unknown run ", QuotedName(run_id)));
}

// Runs fn, turning an allocation failure into ResourceExhausted. A last line
// of defence only (validation refuses what would need that much): an
// exception escaping a worker thread would end the process and every RVE.
template <typename F>
absl::Status NoThrow(F&& fn) {
  try {
    return fn();
  } catch (const std::bad_alloc&) {
    return absl::ResourceExhaustedError("the server ran out of memory for this request");
  } catch (const std::length_error&) {
    return absl::ResourceExhaustedError("the request needs a larger array than the server allows");
  }
}

// InvalidArgument for too many ids in one request or an id given twice
// (repeats would multiply the reply).
absl::Status CheckIdList(std::span<const std::int64_t> ids, std::int64_t max_batch) {
  if (static_cast<std::int64_t>(ids.size()) > max_batch) {
    return absl::InvalidArgumentError(absl::StrCat(
        ids.size(), " ids in one request exceed the server's max batch of ", max_batch));
  }
  if (std::vector<std::int64_t> rep = Repeated(ids); !rep.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("material-point ids repeated in the request: ", ListIds(rep)));
  }
  return absl::OkStatus();
}

// Why an RVE was not computed, or OK to go on.
absl::Status CheckCancelled(const CancelFn& cancelled) {
  if (!cancelled) return absl::OkStatus();
  absl::Status s = cancelled();
  if (s.ok()) return s;
  return absl::Status(s.code(), absl::StrCat(s.message(),
                                             ": this RVE was not computed and stays at its "
                                             "committed step"));
}

// Bytes a hosted template holds: its record (the packing's arrays) and its
// summary's strings.
std::int64_t TemplateBytes(const TemplateRecord& t, const TemplateInfo& summary) {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  const dem::RveSnapshot& p = t.packing;
  return static_cast<std::int64_t>(
      sizeof(TemplateRecord) + sizeof(TemplateInfo) + t.name.capacity() + t.description.capacity() +
      p.material.name.capacity() + bytes(p.radius) + bytes(p.sx) + bytes(p.sy) + bytes(p.vx) +
      bytes(p.vy) + bytes(p.omega) + bytes(p.theta) + bytes(p.contacts) + summary.name.capacity() +
      summary.description.capacity() + summary.material_name.capacity());
}

TemplateInfo Summarise(const TemplateRecord& t, const dem::RveState& s) {
  return {t.name,
          t.description,
          t.packing.material.name,
          static_cast<std::int64_t>(t.packing.radius.size()),
          s.void_ratio,
          s.MeanPressure()};
}

}  // namespace

Registry::Registry(const RegistryOptions& options) : options_(options), pool_(options.threads) {}

absl::StatusOr<TemplateInfo> Registry::PutTemplate(TemplateRecord record, bool replace) {
  RETURN_IF_ERROR(ValidateName("template name", record.name));
  if (record.description.size() > kMaxDescriptionBytes) {
    return absl::InvalidArgumentError(absl::StrCat("template description has ",
                                                   record.description.size(), " bytes; at most ",
                                                   kMaxDescriptionBytes));
  }
  // Creating an RVE validates every field and array of the packing.
  absl::StatusOr<dem::Rve> rve = absl::InvalidArgumentError("not built");
  if (absl::Status made = NoThrow([&] {
        rve = dem::Rve::Create(record.packing);
        return absl::OkStatus();
      });
      !made.ok()) {
    return made;
  }
  if (!rve.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("template ", QuotedName(record.name), ": ", rve.status().message()));
  }
  const TemplateInfo summary = Summarise(record, rve->Observe());
  const std::int64_t bytes = TemplateBytes(record, summary);
  absl::MutexLock lock(&mu_);
  auto existing = templates_.find(record.name);
  if (!replace && existing != templates_.end()) {
    return absl::AlreadyExistsError(absl::StrCat("template ", QuotedName(record.name),
                                                 " exists; upload with replace to overwrite it"));
  }
  if (existing == templates_.end() &&
      static_cast<std::int64_t>(templates_.size()) >= options_.max_templates) {
    return absl::ResourceExhaustedError(
        absl::StrCat("template ", QuotedName(record.name), ": the server hosts ", templates_.size(),
                     " templates, its limit; replace one (upload with ",
                     "replace) or start the server with a higher limit"));
  }
  const std::int64_t replaced = existing == templates_.end() ? 0 : existing->second.bytes;
  if (memory_bytes_ - replaced + bytes > options_.max_memory_bytes) {
    return absl::ResourceExhaustedError(
        absl::StrCat("template ", QuotedName(record.name), " (", bytes,
                     " bytes) would take the server's memory account from ", memory_bytes_, " to ",
                     memory_bytes_ - replaced + bytes, " bytes, over its limit of ",
                     options_.max_memory_bytes, " bytes"));
  }
  memory_bytes_ += bytes - replaced;
  std::string name = record.name;
  templates_.insert_or_assign(std::move(name), Template{std::move(record), summary, bytes});
  return summary;
}

std::vector<TemplateInfo> Registry::ListTemplates(absl::string_view after,
                                                  std::size_t limit) const {
  absl::MutexLock lock(&mu_);
  std::vector<TemplateInfo> out;
  for (auto t = templates_.upper_bound(after); t != templates_.end() && out.size() < limit; ++t)
    out.push_back(t->second.summary);
  return out;
}

std::vector<TemplateRecord> Registry::AllTemplates() const {
  absl::MutexLock lock(&mu_);
  std::vector<TemplateRecord> out;
  for (const auto& [name, t] : templates_) out.push_back(t.record);
  return out;
}

absl::StatusOr<TemplateRecord> Registry::FindTemplate(absl::string_view name) const {
  RETURN_IF_ERROR(ValidateName("template name", name));
  absl::MutexLock lock(&mu_);
  auto t = templates_.find(name);
  if (t == templates_.end()) {
    return absl::NotFoundError(
        absl::StrCat("unknown template ", QuotedName(name),
                     "; upload it first (ListTemplates shows the known ones)"));
  }
  return t->second.record;
}

absl::Status Registry::CheckRoom(absl::string_view run_id, std::span<const std::int64_t> ids,
                                 std::int64_t bytes) const {
  auto run = runs_.find(run_id);
  if (run != runs_.end()) {
    std::vector<std::int64_t> taken;
    for (std::int64_t id : ids)
      if (run->second.contains(id)) taken.push_back(id);
    if (!taken.empty()) {
      return absl::AlreadyExistsError(absl::StrCat(
          "run ", QuotedName(run_id), " already has material points ", ListIds(taken)));
    }
  }
  return CheckCapacity(static_cast<std::int64_t>(ids.size()), bytes);
}

absl::Status Registry::CheckCapacity(std::int64_t count, std::int64_t bytes) const {
  if (num_rves_ + count > options_.max_rves) {
    return absl::ResourceExhaustedError(absl::StrCat("adding ", count, " RVEs to the ", num_rves_,
                                                     " hosted would exceed the server's limit of ",
                                                     options_.max_rves));
  }
  if (memory_bytes_ + bytes > options_.max_memory_bytes) {
    return absl::ResourceExhaustedError(
        absl::StrCat("adding ", count, " RVEs (", bytes, " bytes) to the ", memory_bytes_,
                     " bytes hosted would exceed the server's memory limit of ",
                     options_.max_memory_bytes, " bytes"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<RveOutcome>> Registry::Create(
    absl::string_view run_id, absl::string_view template_name, std::span<const std::int64_t> ids,
    std::span<const InitialStress> initial, const std::optional<dem::Controls>& controls,
    bool want_state, const CancelFn& cancelled) {
  RETURN_IF_ERROR(ValidateName("run id", run_id));
  if (ids.empty()) return absl::InvalidArgumentError("no material-point ids to create");
  if (static_cast<std::int64_t>(ids.size()) > options_.max_batch) {
    return absl::InvalidArgumentError(absl::StrCat(
        "batch of ", ids.size(), " RVEs exceeds the server's max batch of ", options_.max_batch));
  }
  if (std::vector<std::int64_t> rep = Repeated(ids); !rep.empty()) {
    return absl::AlreadyExistsError(
        absl::StrCat("material-point ids repeated in the request: ", ListIds(rep)));
  }
  if (initial.size() > 1 && initial.size() != ids.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("initial stresses: give none, one for all or one per id (", ids.size(),
                     "), not ", initial.size()));
  }
  for (std::size_t k = 0; k < initial.size(); ++k) {
    if (absl::Status s = Validate(initial[k]); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(
          initial.size() > 1 ? absl::StrCat("material point ", ids[k], ": ") : "", s.message()));
    }
  }
  if (controls.has_value()) {
    RETURN_IF_ERROR(dem::Validate(*controls));
  }

  ASSIGN_OR_RETURN(TemplateRecord found, FindTemplate(template_name));
  dem::RveSnapshot base = std::move(found.packing);
  std::int64_t bytes_each = 0;
  if (controls.has_value()) base.controls = *controls;
  ASSIGN_OR_RETURN(dem::Rve prototype, dem::Rve::Create(base));
  bytes_each = static_cast<std::int64_t>(prototype.MemoryBytes());
  const std::int64_t n = static_cast<std::int64_t>(ids.size());
  {
    absl::MutexLock lock(&mu_);
    RETURN_IF_ERROR(CheckRoom(run_id, ids, n * bytes_each));
  }

  // Consolidation is the expensive part. Every new RVE starts from the same
  // template, so identical targets give identical RVEs: each distinct target
  // is consolidated once (one work item each) and copied to the ids that ask
  // for it. A geostatic start has one target per depth, not per point.
  const InitialStress none;
  auto target_of = [&](std::size_t k) -> const InitialStress& {
    return initial.empty() ? none : initial[initial.size() == 1 ? 0 : k];
  };
  auto key_of = [&](std::size_t k) {
    const InitialStress& t = target_of(k);
    return std::tuple(static_cast<int>(t.kind), absl::bit_cast<std::uint64_t>(t.pressure),
                      absl::bit_cast<std::uint64_t>(t.vertical_compression),
                      absl::bit_cast<std::uint64_t>(t.k0));
  };
  std::vector<std::size_t> unique_of(ids.size());  // index into `distinct`
  std::vector<std::size_t> distinct;               // first k of each distinct target
  {
    std::map<decltype(key_of(0)), std::size_t> seen;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      auto [it, inserted] = seen.try_emplace(key_of(k), distinct.size());
      if (inserted) distinct.push_back(k);
      unique_of[k] = it->second;
    }
  }
  std::vector<std::optional<dem::Rve>> consolidated(distinct.size());
  std::vector<absl::Status> status(distinct.size());
  auto consolidate_one = [&](std::size_t u) {
    if (absl::Status c = CheckCancelled(cancelled); !c.ok()) {
      status[u] = c;
      return;
    }
    dem::Rve rve = prototype;
    absl::StatusOr<dem::RveState> s = dem::RveState{};
    const InitialStress& target = target_of(distinct[u]);
    const absl::Status guarded = NoThrow([&] {
      if (target.kind == InitialStress::Kind::kIsotropic) {
        s = dem::ConsolidateIsotropic(rve, target.pressure, 1e-4, nullptr, cancelled,
                                      dem::kSettleSteps);
      } else if (target.kind == InitialStress::Kind::kK0) {
        s = dem::ConsolidateToStress(rve, target.k0 * target.vertical_compression,
                                     target.vertical_compression, 1e-4, nullptr, cancelled,
                                     dem::kSettleSteps);
      }
      return absl::OkStatus();
    });
    if (!guarded.ok()) s = guarded;
    if (!s.ok()) {
      status[u] = s.status();
      return;
    }
    rve.ResetReference();  // F is measured from the consolidated state
    consolidated[u].emplace(std::move(rve));
  };
  pool_.ParallelFor(distinct.size(), [&](std::size_t u) {
    const absl::Status guarded = NoThrow([&] {
      consolidate_one(u);
      return absl::OkStatus();
    });
    if (!guarded.ok()) status[u] = guarded;
  });
  for (std::size_t u = 0; u < distinct.size(); ++u) {
    if (!status[u].ok()) {
      return absl::Status(
          status[u].code(),
          absl::StrCat("creating material point ", ids[distinct[u]], ": ", status[u].message()));
    }
  }

  // Made before the registry's lock is taken: an entry's lock is only ever
  // taken before it (Apply accounts a doubled cell under both).
  std::vector<RveOutcome> out(ids.size());
  std::vector<EntryPtr> entries(ids.size());
  for (std::size_t k = 0; k < ids.size(); ++k) {
    entries[k] = std::make_shared<Entry>(*consolidated[unique_of[k]]);
    entries[k]->memory_bytes = bytes_each;
    out[k].id = ids[k];
    if (want_state) {
      absl::MutexLock entry_lock(&entries[k]->mu);
      out[k].state = entries[k]->rve.Observe();
    }
  }
  {
    absl::MutexLock lock(&mu_);
    // Another call may have created some of these ids or used the capacity
    // while this one consolidated.
    RETURN_IF_ERROR(CheckRoom(run_id, ids, n * bytes_each));
    Run& run = runs_[std::string(run_id)];
    for (std::size_t k = 0; k < ids.size(); ++k) run.emplace(ids[k], std::move(entries[k]));
    num_rves_ += n;
    memory_bytes_ += n * bytes_each;
  }
  return out;
}

absl::StatusOr<std::vector<std::pair<std::int64_t, Registry::EntryPtr>>> Registry::Lookup(
    absl::string_view run_id, std::span<const std::int64_t> ids) const {
  absl::MutexLock lock(&mu_);
  auto run = runs_.find(run_id);
  if (run == runs_.end()) {
    return UnknownRun(run_id);
  }
  std::vector<std::pair<std::int64_t, EntryPtr>> out;
  if (ids.empty()) {
    for (const auto& [id, e] : run->second) out.emplace_back(id, e);
    return out;
  }
  std::vector<std::int64_t> missing;
  for (std::int64_t id : ids) {
    auto e = run->second.find(id);
    if (e == run->second.end()) {
      missing.push_back(id);
    } else {
      out.emplace_back(id, e->second);
    }
  }
  if (!missing.empty()) {
    return absl::NotFoundError(
        absl::StrCat("run ", QuotedName(run_id), " has no material points ", ListIds(missing)));
  }
  return out;
}

absl::StatusOr<std::vector<RveOutcome>> Registry::Apply(absl::string_view run_id, std::int64_t step,
                                                        ApplyMode mode,
                                                        const dem::ApplyOptions& options,
                                                        std::span<const Increment> increments,
                                                        const CancelFn& cancelled) {
  // Not sized for a batch over the limit (ApplyEach refuses it).
  const bool sized = static_cast<std::int64_t>(increments.size()) <= options_.max_batch;
  std::vector<RveOutcome> out(sized ? increments.size() : 0);
  RETURN_IF_ERROR(ApplyEach(run_id, step, mode, options, increments, cancelled,
                            [&out](std::size_t k, RveOutcome&& o) { out[k] = std::move(o); }));
  return out;
}

absl::Status Registry::ApplyEach(absl::string_view run_id, std::int64_t step, ApplyMode mode,
                                 const dem::ApplyOptions& options,
                                 std::span<const Increment> increments, const CancelFn& cancelled,
                                 const OutcomeFn& done) {
  if (increments.empty()) return absl::InvalidArgumentError("empty batch: no increments");
  if (static_cast<std::int64_t>(increments.size()) > options_.max_batch) {
    return absl::InvalidArgumentError(absl::StrCat("batch of ", increments.size(),
                                                   " increments exceeds the server's max batch of ",
                                                   options_.max_batch));
  }
  RETURN_IF_ERROR(ValidateName("run id", run_id));
  if (step < 1) return absl::InvalidArgumentError(absl::StrCat("step ", step, " must be >= 1"));
  if (step > kMaxStep) {
    return absl::InvalidArgumentError(
        absl::StrCat("step ", step, " must be <= ", kMaxStep, " (2^53)"));
  }
  if (absl::Status s = dem::Validate(options); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("apply options: ", s.message()));
  }
  std::vector<std::int64_t> ids;
  ids.reserve(increments.size());
  for (const Increment& inc : increments) {
    if (absl::Status s = dem::ValidateDeltaF(inc.delta_f); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("material point ", inc.id, ": ", s.message()));
    }
    ids.push_back(inc.id);
  }
  if (std::vector<std::int64_t> rep = Repeated(ids); !rep.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("material-point ids repeated in the batch: ", ListIds(rep)));
  }
  ASSIGN_OR_RETURN(auto entries, Lookup(run_id, ids));

  // Longest first: a batch whose last RVE taken is a long one ends with the
  // other workers idle (a shear band's RVEs take tens of DEM steps where the
  // rest take one). Each RVE's last increment predicts its next, one without
  // an increment yet is guessed at the batch's mean (all alike when none has
  // run); the workers take runs of similar total work by the same guesses.
  // The results do not depend on the order.
  std::vector<double> work(increments.size());
  double known = 0, counted = 0;
  for (std::size_t k = 0; k < work.size(); ++k) {
    work[k] = static_cast<double>(entries[k].second->last_work.load(std::memory_order_relaxed));
    known += work[k] > 0 ? work[k] : 0.0;
    counted += work[k] > 0 ? 1.0 : 0.0;
  }
  const double guess = counted > 0 ? known / counted : 1.0;
  for (double& w : work) w = w > 0 ? w : guess;
  std::vector<std::size_t> order(increments.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return work[a] > work[b]; });
  std::vector<double> cost(order.size());  // in the order taken
  for (std::size_t j = 0; j < order.size(); ++j) cost[j] = work[order[j]];
  // The first outcome the caller could not take (out of memory): the call's
  // error, although its RVEs have moved on (a retry returns their results).
  absl::Mutex failed_mu;
  absl::Status failed;
  auto record_work = [](Entry& e, const dem::RveState& s) {
    e.last_work.store((s.steps + 1) * e.rve.num_particles(), std::memory_order_relaxed);
  };
  auto apply_one = [&](std::size_t k, RveOutcome& o) {
    const Increment& inc = increments[k];
    Entry& e = *(entries)[k].second;
    o.id = inc.id;
    absl::MutexLock lock(&e.mu);
    o.step = e.step;
    const bool retry = mode == ApplyMode::kCommit && e.step == step;
    if (retry) {
      // A retried COMMIT must be the same increment, bit for bit.
      if (e.last_delta_f != inc.delta_f) {
        o.status = absl::FailedPreconditionError(
            absl::StrCat("material point ", inc.id, " already committed step ", step,
                         " with a different ΔF; its current step is ", e.step));
        return;
      }
      if (e.last_result.has_value() && e.last_stress_only == options.stress_only &&
          (!options.want_tangent || e.last_result->tangent.has_value())) {
        o.state = *e.last_result;
        // Only what this request asked for: a tangent stored by a first
        // COMMIT that asked for it would make the reply larger than the
        // service sized it (and the retry unanswerable).
        if (!options.want_tangent) o.state.tangent.reset();
      } else {  // after a restore, or asked otherwise: the committed state observed again
        o.state = options.stress_only ? e.rve.ObserveStress(options.want_tangent)
                                      : e.rve.Observe(options.want_tangent);
      }
      o.deformation_gradient.topLeftCorner<2, 2>() = e.rve.DeformationGradient();
      return;
    }
    if (e.step != step - 1) {
      o.status = absl::FailedPreconditionError(absl::StrCat("material point ", inc.id,
                                                            " is at step ", e.step, "; step ", step,
                                                            " needs it at step ", step - 1));
      return;
    }
    if (absl::Status c = CheckCancelled(cancelled); !c.ok()) {
      o.status = c;
      return;
    }
    std::int64_t reserved = 0;
    if (absl::Status room =
            ReserveGrowth(e, inc.id, inc.delta_f, mode == ApplyMode::kCommit, reserved);
        !room.ok()) {
      o.status = room;
      return;
    }
    // The account follows a committed RVE's size however this ends (an
    // allocation failure included); before e.mu is let go.
    struct Settle {
      Registry* registry;
      Entry* entry;
      const std::int64_t* reserved;
      bool commit;
      ~Settle() {
        if (commit) registry->Reaccount(*entry, *reserved);
      }
    } settle{this, &e, &reserved, mode == ApplyMode::kCommit};
    // Asked between DEM steps of a long increment; the engine undoes it.
    dem::Interrupt interrupt;
    if (cancelled) {
      interrupt = [&cancelled]() -> absl::Status {
        absl::Status s = cancelled();
        if (s.ok()) return s;
        return absl::Status(s.code(), absl::StrCat(s.message(),
                                                   ": this RVE was stopped part-way and stays at "
                                                   "its committed step"));
      };
    }
    const auto engine_start = std::chrono::steady_clock::now();
    auto engine_seconds = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - engine_start).count();
    };
    if (mode == ApplyMode::kTrial) {
      // The committed state stays as it is; the trial runs on a copy held by
      // this worker thread, whose buffers the next trial's copy reuses.
      thread_local std::optional<dem::Rve> scratch;
      if (scratch.has_value()) {
        *scratch = e.rve;
      } else {
        scratch.emplace(e.rve);
      }
      dem::Rve& trial = *scratch;
      absl::StatusOr<dem::RveState> s = trial.Apply(inc.delta_f, options, interrupt);
      o.engine_seconds = engine_seconds();
      if (!s.ok()) {
        o.status = s.status();
        return;
      }
      record_work(e, *s);
      o.state = *std::move(s);
      o.deformation_gradient.topLeftCorner<2, 2>() = trial.DeformationGradient();
      return;
    }
    absl::StatusOr<dem::RveState> s = e.rve.Apply(inc.delta_f, options, interrupt);
    o.engine_seconds = engine_seconds();
    if (!s.ok()) {  // the engine leaves the RVE untouched on error
      o.status = s.status();
      return;
    }
    record_work(e, *s);
    e.step = step;
    e.last_delta_f = inc.delta_f;
    e.last_result = *s;
    e.last_stress_only = options.stress_only;
    o.step = step;
    o.state = *std::move(s);
    o.deformation_gradient.topLeftCorner<2, 2>() = e.rve.DeformationGradient();
  };
  pool_.ParallelFor(
      increments.size(),
      [&](std::size_t j) {
        const std::size_t k = order[j];
        RveOutcome o;
        absl::Status guarded = NoThrow([&] {
          apply_one(k, o);
          return absl::OkStatus();
        });
        if (!guarded.ok()) o.status = guarded;
        // Converting the outcome is the caller's, on this worker.
        absl::Status handed = NoThrow([&] {
          done(k, std::move(o));
          return absl::OkStatus();
        });
        if (!handed.ok()) {
          absl::MutexLock lock(&failed_mu);
          if (failed.ok()) failed = handed;
        }
      },
      cost);
  return failed;
}

absl::Status Registry::ReserveGrowth(Entry& e, std::int64_t id, const Eigen::Matrix3d& delta_f,
                                     bool reserve, std::int64_t& reserved) {
  const std::int64_t particles = e.rve.num_particles();
  const std::int64_t after = e.rve.ParticlesAfterApply(delta_f);
  if (after <= particles) return absl::OkStatus();
  // Everything an RVE holds is per particle or per contact, and doubles
  // with the cell.
  const std::int64_t growth =
      static_cast<std::int64_t>(e.rve.MemoryBytes()) * (after / particles - 1);
  absl::MutexLock lock(&mu_);
  if (memory_bytes_ + growth > options_.max_memory_bytes) {
    return absl::ResourceExhaustedError(
        absl::StrCat("material point ", id,
                     ": ΔF squeezes its cell thinner than twice the pair cutoff, and "
                     "doubling it (",
                     particles, " to ", after, " particles, about ", growth,
                     " more bytes) would take the server's memory account from ", memory_bytes_,
                     " to ", memory_bytes_ + growth, " bytes, over its limit of ",
                     options_.max_memory_bytes, " bytes; the RVE stays at its committed step"));
  }
  if (reserve) {
    memory_bytes_ += growth;
    reserved = growth;
  }
  return absl::OkStatus();
}

void Registry::Reaccount(Entry& e, std::int64_t reserved) {
  const std::int64_t bytes = static_cast<std::int64_t>(e.rve.MemoryBytes());
  if (reserved == 0 && bytes == e.memory_bytes) return;  // the usual increment: no lock
  absl::MutexLock lock(&mu_);
  memory_bytes_ -= reserved;
  if (e.hosted) memory_bytes_ += bytes - e.memory_bytes;  // a dropped RVE left the account
  e.memory_bytes = bytes;
}

absl::StatusOr<std::vector<RveOutcome>> Registry::Get(absl::string_view run_id,
                                                      std::span<const std::int64_t> ids,
                                                      bool want_tangent) const {
  RETURN_IF_ERROR(ValidateName("run id", run_id));
  RETURN_IF_ERROR(CheckIdList(ids, options_.max_batch));
  std::vector<std::pair<std::int64_t, EntryPtr>> entries;
  {
    absl::MutexLock lock(&mu_);
    auto run = runs_.find(run_id);
    if (run == runs_.end()) {
      return UnknownRun(run_id);
    }
    if (ids.empty()) {
      for (const auto& [id, e] : run->second) entries.emplace_back(id, e);
    } else {
      for (std::int64_t id : ids) {
        auto e = run->second.find(id);
        entries.emplace_back(id, e == run->second.end() ? nullptr : e->second);
      }
    }
  }
  std::vector<RveOutcome> out(entries.size());
  pool_.ParallelFor(entries.size(), [&](std::size_t k) {
    RveOutcome& o = out[k];
    o.id = entries[k].first;
    o.status = NoThrow([&] {
      if (entries[k].second == nullptr) {
        return absl::NotFoundError(
            absl::StrCat("run ", QuotedName(run_id), " has no material point ", o.id));
      }
      Entry& e = *entries[k].second;
      absl::MutexLock lock(&e.mu);
      o.step = e.step;
      o.state = e.rve.Observe(want_tangent);
      o.deformation_gradient.topLeftCorner<2, 2>() = e.rve.DeformationGradient();
      return absl::OkStatus();
    });
  });
  return out;
}

absl::Status Registry::Export(absl::string_view run_id, std::span<const std::int64_t> ids,
                              const std::function<absl::Status(RveRecord&&)>& sink) const {
  RETURN_IF_ERROR(ValidateName("run id", run_id));
  RETURN_IF_ERROR(CheckIdList(ids, options_.max_batch));
  ASSIGN_OR_RETURN(auto entries, Lookup(run_id, ids));
  for (const auto& [id, e] : entries) {
    RveRecord r;
    r.run_id = std::string(run_id);
    r.id = id;
    {
      absl::MutexLock lock(&e->mu);
      r.step = e->step;
      r.last_delta_f = e->last_delta_f;
      r.packing = e->rve.ToSnapshot();
    }
    RETURN_IF_ERROR(sink(std::move(r)));
  }
  return absl::OkStatus();
}

absl::Status Registry::ExportAll(const std::function<absl::Status(RveRecord&&)>& sink) const {
  std::vector<std::string> run_ids;
  {
    absl::MutexLock lock(&mu_);
    for (const auto& [id, run] : runs_) run_ids.push_back(id);
  }
  for (const std::string& run : run_ids) {
    absl::Status s = Export(run, {}, sink);
    if (absl::IsNotFound(s)) continue;  // dropped meanwhile
    if (!s.ok()) return s;
  }
  return absl::OkStatus();
}

absl::StatusOr<std::int64_t> Registry::Import(std::vector<RveRecord> records) {
  if (records.empty()) return absl::InvalidArgumentError("import of no RVEs");
  // Validate and build every RVE before touching the registry.
  std::vector<std::optional<dem::Rve>> made(records.size());
  std::vector<absl::Status> status(records.size());
  auto build_one = [&](std::size_t k) {
    const RveRecord& r = records[k];
    absl::Status s = ValidateName("run id", r.run_id);
    if (s.ok() && (r.step < 0 || r.step > kMaxStep)) {
      s = absl::InvalidArgumentError(
          absl::StrCat("step = ", r.step, " must lie in 0..", kMaxStep, " (2^53)"));
    }
    for (int c = 0; s.ok() && c < 9; ++c) {
      if (const double v = r.last_delta_f(c / 3, c % 3); !std::isfinite(v)) {
        s = absl::InvalidArgumentError(
            absl::StrCat("last_delta_f[", c, "] = ", v, " is not finite (3×3, row-major)"));
      }
    }
    if (s.ok()) {
      s = NoThrow([&] {
        ASSIGN_OR_RETURN(dem::Rve rve, dem::Rve::Create(r.packing));
        made[k].emplace(std::move(rve));
        return absl::OkStatus();
      });
    }
    if (!s.ok()) {
      const absl::StatusCode code = absl::IsResourceExhausted(s)
                                        ? absl::StatusCode::kResourceExhausted
                                        : absl::StatusCode::kInvalidArgument;
      status[k] = absl::Status(code, absl::StrCat("record ", k, " (run ", QuotedName(r.run_id),
                                                  ", material point ", r.id, "): ", s.message()));
    }
  };
  pool_.ParallelFor(records.size(), [&](std::size_t k) {
    const absl::Status guarded = NoThrow([&] {
      build_one(k);
      return absl::OkStatus();
    });
    if (!guarded.ok()) status[k] = guarded;
  });
  for (const absl::Status& s : status)
    if (!s.ok()) return s;
  std::set<std::pair<absl::string_view, std::int64_t>> seen;
  std::int64_t bytes = 0;
  for (std::size_t k = 0; k < records.size(); ++k) {
    if (!seen.emplace(records[k].run_id, records[k].id).second) {
      return absl::AlreadyExistsError(absl::StrCat("run ", QuotedName(records[k].run_id),
                                                   ", material point ", records[k].id,
                                                   " appears twice in the import"));
    }
    bytes += static_cast<std::int64_t>(made[k]->MemoryBytes());
  }
  const std::int64_t n = static_cast<std::int64_t>(records.size());
  // Made before the registry's lock is taken (see Create).
  std::vector<EntryPtr> entries(records.size());
  for (std::size_t k = 0; k < records.size(); ++k) {
    entries[k] = std::make_shared<Entry>(std::move(*made[k]));
    absl::MutexLock entry_lock(&entries[k]->mu);
    entries[k]->memory_bytes = static_cast<std::int64_t>(entries[k]->rve.MemoryBytes());
    entries[k]->step = records[k].step;
    entries[k]->last_delta_f = records[k].last_delta_f;
  }
  absl::MutexLock lock(&mu_);
  for (const RveRecord& r : records) {
    auto run = runs_.find(r.run_id);
    if (run != runs_.end() && run->second.contains(r.id)) {
      return absl::AlreadyExistsError(absl::StrCat("run ", QuotedName(r.run_id),
                                                   " already has material point ", r.id,
                                                   "; drop it before importing"));
    }
  }
  RETURN_IF_ERROR(CheckCapacity(n, bytes));
  for (std::size_t k = 0; k < records.size(); ++k)
    runs_[records[k].run_id].emplace(records[k].id, std::move(entries[k]));
  num_rves_ += n;
  memory_bytes_ += bytes;
  return n;
}

absl::StatusOr<std::int64_t> Registry::Drop(absl::string_view run_id,
                                            std::span<const std::int64_t> ids) {
  RETURN_IF_ERROR(ValidateName("run id", run_id));
  RETURN_IF_ERROR(CheckIdList(ids, options_.max_batch));
  absl::MutexLock lock(&mu_);
  auto run = runs_.find(run_id);
  if (run == runs_.end()) {
    return UnknownRun(run_id);
  }
  std::vector<std::int64_t> missing;
  for (std::int64_t id : ids)
    if (!run->second.contains(id)) missing.push_back(id);
  if (!missing.empty()) {
    return absl::NotFoundError(
        absl::StrCat("run ", QuotedName(run_id), " has no material points ", ListIds(missing)));
  }
  std::int64_t dropped = 0;
  auto drop = [&](Run::iterator it) {
    memory_bytes_ -= it->second->memory_bytes;
    it->second->hosted = false;  // an increment in flight no longer accounts it
    --num_rves_;
    ++dropped;
    return run->second.erase(it);
  };
  if (ids.empty()) {
    for (auto it = run->second.begin(); it != run->second.end();) it = drop(it);
  } else {
    for (std::int64_t id : ids) {
      auto it = run->second.find(id);
      if (it != run->second.end()) drop(it);
    }
  }
  if (run->second.empty()) runs_.erase(run);
  return dropped;
}

std::vector<RunInfo> Registry::ListRuns(absl::string_view after, std::size_t limit) const {
  std::vector<std::pair<std::string, std::vector<EntryPtr>>> runs;
  {
    absl::MutexLock lock(&mu_);
    for (auto r = runs_.upper_bound(after); r != runs_.end() && runs.size() < limit; ++r) {
      std::vector<EntryPtr> entries;
      for (const auto& [mp, e] : r->second) entries.push_back(e);
      runs.emplace_back(r->first, std::move(entries));
    }
  }
  std::vector<RunInfo> out;
  for (const auto& [id, entries] : runs) {
    RunInfo r{id, static_cast<std::int64_t>(entries.size()), 0, 0};
    bool first = true;
    for (const EntryPtr& e : entries) {
      absl::MutexLock lock(&e->mu);
      r.min_step = first ? e->step : std::min(r.min_step, e->step);
      r.max_step = first ? e->step : std::max(r.max_step, e->step);
      first = false;
    }
    out.push_back(std::move(r));
  }
  return out;
}

std::int64_t Registry::CountRves(absl::string_view run_id) const {
  absl::MutexLock lock(&mu_);
  auto run = runs_.find(run_id);
  return run == runs_.end() ? 0 : static_cast<std::int64_t>(run->second.size());
}

RegistryStats Registry::Stats() const {
  absl::MutexLock lock(&mu_);
  return {num_rves_, memory_bytes_, static_cast<std::int64_t>(runs_.size()),
          static_cast<std::int64_t>(templates_.size())};
}

}  // namespace rvehub::service
