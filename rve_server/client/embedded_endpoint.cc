#include "rve_server/client/embedded_endpoint.h"

#include <memory>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"

namespace rvehub::client {
namespace {

// The registry's types are the server's; the client's are its own. These
// copy between the two (a few hundred bytes per RVE; Apply's on the workers,
// where 7776 of them had taken 1.2 ms of each MPM step on the caller).
service::InitialStress ToRegistry(const InitialStress& s) {
  service::InitialStress out;
  out.kind = s.kind == InitialStress::Kind::kIsotropic ? service::InitialStress::Kind::kIsotropic
             : s.kind == InitialStress::Kind::kK0      ? service::InitialStress::Kind::kK0
                                                       : service::InitialStress::Kind::kTemplate;
  out.pressure = s.pressure;
  out.vertical_compression = s.vertical_compression;
  out.k0 = s.k0;
  return out;
}

void FromRegistry(service::RveOutcome&& o, RveOutcome& out) {
  out.id = o.id;
  out.status = std::move(o.status);
  out.step = o.step;
  out.state = std::move(o.state);
  out.deformation_gradient = o.deformation_gradient;
  out.engine_seconds = o.engine_seconds;
}

std::vector<RveOutcome> FromRegistry(std::vector<service::RveOutcome>&& outcomes) {
  std::vector<RveOutcome> out(outcomes.size());
  for (std::size_t k = 0; k < outcomes.size(); ++k) FromRegistry(std::move(outcomes[k]), out[k]);
  return out;
}

// An Apply already done inside StartApply.
class DoneApply final : public PendingApply {
 public:
  DoneApply(absl::StatusOr<std::vector<RveOutcome>> result, double seconds)
      : result_(std::move(result)), seconds_(seconds) {}
  absl::StatusOr<std::vector<RveOutcome>> Finish() override { return std::move(result_); }
  double seconds() const override { return seconds_; }

 private:
  absl::StatusOr<std::vector<RveOutcome>> result_;
  double seconds_;
};

class EmbeddedEndpoint final : public RveEndpoint {
 public:
  explicit EmbeddedEndpoint(std::shared_ptr<service::Registry> registry)
      : registry_(std::move(registry)) {}

  std::string name() const override { return "embedded"; }
  int workers() const override { return registry_->options().threads; }
  bool in_process() const override { return true; }
  std::string label() const override { return "embedded RVE registry"; }

  absl::Status PutTemplate(const store::TemplateRecord& record) override {
    return Error(registry_->PutTemplate(record, /*replace=*/true).status());
  }

  absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial,
      const std::optional<dem::Controls>& controls) override {
    std::vector<service::InitialStress> stresses;
    stresses.reserve(initial.size());
    for (const InitialStress& s : initial) stresses.push_back(ToRegistry(s));
    absl::StatusOr<std::vector<service::RveOutcome>> out =
        registry_->Create(run, template_name, ids, stresses, controls, /*want_state=*/true);
    if (!out.ok()) return Error(out.status());
    return FromRegistry(*std::move(out));
  }

  std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step,
                                           std::span<const Increment> increments,
                                           const dem::ApplyOptions& options,
                                           absl::Duration deadline) override {
    const absl::Time start = absl::Now();
    service::CancelFn cancelled;
    if (deadline != absl::InfiniteDuration()) {
      const absl::Time end = absl::Now() + deadline;
      cancelled = [end]() -> absl::Status {
        if (absl::Now() > end) return absl::DeadlineExceededError("the call's deadline passed");
        return absl::OkStatus();
      };
    }
    std::vector<service::Increment> batch(increments.size());
    for (std::size_t k = 0; k < increments.size(); ++k) {
      batch[k].id = increments[k].id;
      batch[k].delta_f = increments[k].delta_f;
    }
    std::vector<RveOutcome> out(batch.size());
    const absl::Status applied = registry_->ApplyEach(
        run, step, service::ApplyMode::kCommit, options, batch, cancelled,
        [&out](std::size_t k, service::RveOutcome&& o) { FromRegistry(std::move(o), out[k]); });
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!applied.ok()) return std::make_unique<DoneApply>(Error(applied), seconds);
    return std::make_unique<DoneApply>(std::move(out), seconds);
  }

  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) override {
    absl::StatusOr<std::vector<service::RveOutcome>> out = registry_->Get(run, ids, want_tangent);
    if (!out.ok()) return Error(out.status());
    return FromRegistry(*std::move(out));
  }

  absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                      const RecordSink& sink) override {
    return Error(registry_->Export(run, ids, sink));
  }

  absl::Status Import(std::vector<store::RveRecord> records) override {
    return Error(registry_->Import(std::move(records)).status());
  }

  absl::Status Drop(absl::string_view run, std::span<const std::int64_t> ids) override {
    return Error(registry_->Drop(run, ids).status());
  }

  absl::Status Ping(absl::Duration) override { return absl::OkStatus(); }

 private:
  absl::Status Error(const absl::Status& s) const { return Labelled(label(), s); }

  std::shared_ptr<service::Registry> registry_;
};

}  // namespace

std::unique_ptr<RveEndpoint> MakeEmbeddedEndpoint(std::shared_ptr<service::Registry> registry) {
  return std::make_unique<EmbeddedEndpoint>(std::move(registry));
}

std::unique_ptr<RveEndpoint> MakeEmbeddedEndpoint(const EmbeddedOptions& options) {
  service::RegistryOptions registry;
  registry.threads = options.threads;
  return MakeEmbeddedEndpoint(std::make_shared<service::Registry>(registry));
}

}  // namespace rvehub::client
