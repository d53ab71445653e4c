#include "rve_server/embedded/endpoint.h"

#include <memory>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"

namespace rvehub::embedded {
namespace {

using client::Labelled;
using client::PendingApply;
using client::RecordSink;
using client::RveEndpoint;

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

  absl::Status PutTemplate(const TemplateRecord& record) override {
    return Error(registry_->PutTemplate(record, /*replace=*/true).status());
  }

  absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial,
      const std::optional<dem::Controls>& controls) override {
    absl::StatusOr<std::vector<RveOutcome>> out =
        registry_->Create(run, template_name, ids, initial, controls, /*want_state=*/true);
    if (!out.ok()) return Error(out.status());
    return out;
  }

  std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step, ApplyMode mode,
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
    std::vector<RveOutcome> out(increments.size());
    const absl::Status applied =
        registry_->ApplyEach(run, step, mode, options, increments, cancelled,
                             [&out](std::size_t k, RveOutcome&& o) { out[k] = std::move(o); });
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!applied.ok()) return std::make_unique<DoneApply>(Error(applied), seconds);
    return std::make_unique<DoneApply>(std::move(out), seconds);
  }

  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) override {
    absl::StatusOr<std::vector<RveOutcome>> out = registry_->Get(run, ids, want_tangent);
    if (!out.ok()) return Error(out.status());
    return out;
  }

  absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                      const RecordSink& sink) override {
    return Error(registry_->Export(run, ids, sink));
  }

  absl::Status Import(std::vector<RveRecord> records) override {
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

std::unique_ptr<RveEndpoint> MakeEndpoint(std::shared_ptr<service::Registry> registry) {
  return std::make_unique<EmbeddedEndpoint>(std::move(registry));
}

std::unique_ptr<RveEndpoint> MakeEndpoint(const EmbeddedOptions& options) {
  service::RegistryOptions registry;
  registry.threads = options.threads;
  return MakeEndpoint(std::make_shared<service::Registry>(registry));
}

}  // namespace rvehub::embedded
