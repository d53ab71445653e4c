#include <google/protobuf/arena.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/strings/str_cat.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/clock.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/client/record_stream.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/service/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::client {
namespace {

// Messages to and from the batch values: rve_server/service/convert.h.

absl::StatusOr<RveOutcome> OutcomeFromProto(const v1::RveResult& r) {
  RveOutcome o;
  if (absl::Status s = service::FromProto(r, &o); !s.ok()) {
    return absl::DataLossError(
        absl::StrCat("reply for material point ", r.id(), " is malformed: ", s.message()));
  }
  return o;
}

// Outcomes of a reply, which must answer `expected` ids in order.
absl::Status AppendOutcomes(const google::protobuf::RepeatedPtrField<v1::RveResult>& results,
                            std::span<const std::int64_t> expected, std::vector<RveOutcome>* out) {
  if (!expected.empty() && static_cast<std::size_t>(results.size()) != expected.size()) {
    return absl::DataLossError(
        absl::StrCat("reply has ", results.size(), " results for ", expected.size(), " RVEs"));
  }
  for (int k = 0; k < results.size(); ++k) {
    ASSIGN_OR_RETURN(RveOutcome o, OutcomeFromProto(results[k]));
    if (!expected.empty() && o.id != expected[k]) {
      return absl::DataLossError(
          absl::StrCat("reply result ", k, " is for material point ", o.id, ", not ", expected[k]));
    }
    out->push_back(std::move(o));
  }
  return absl::OkStatus();
}

// A gRPC deadline for a duration: none for an infinite one, else ≥ 1 ms.
std::chrono::milliseconds DeadlineOf(absl::Duration d) {
  if (d >= absl::Hours(24 * 365)) return std::chrono::milliseconds(0);
  return std::chrono::milliseconds(std::max<std::int64_t>(1, absl::ToInt64Milliseconds(d)));
}

// The messages of one Apply, in flight together through gRPC's callback
// API: no thread waits on a server; Finish blocks only its caller.
class RemoteApply final : public PendingApply {
 public:
  struct Message {
    grpc::ClientContext context;
    v1::ApplyRequest request;
    // The reply's thousands of small messages live on one arena: parsed
    // without a malloc each and freed in a few blocks.
    google::protobuf::Arena arena;
    v1::ApplyResponse* response = google::protobuf::Arena::CreateMessage<v1::ApplyResponse>(&arena);
    grpc::Status status;
    std::vector<std::int64_t> ids;  // the request's, in order
  };

  explicit RemoteApply(std::string label) : label_(std::move(label)), start_(absl::Now()) {}
  // Waits for callbacks still pending (they refer to this call).
  ~RemoteApply() override {
    bool pending;
    {
      absl::MutexLock lock(&mu_);
      pending = pending_ > 0;
    }
    // Not under mu_: a cancelled call's callback takes it.
    if (pending) {
      for (const std::unique_ptr<Message>& m : messages_) m->context.TryCancel();
    }
    absl::MutexLock lock(&mu_);
    mu_.Await(absl::Condition(this, &RemoteApply::Done));
  }

  Message& Add() { return *messages_.emplace_back(std::make_unique<Message>()); }

  void SendAll(v1::RveService::Stub& stub) {
    {
      absl::MutexLock lock(&mu_);
      pending_ = static_cast<int>(messages_.size());
    }
    for (const std::unique_ptr<Message>& m : messages_) {
      Message* message = m.get();
      stub.async()->Apply(&message->context, &message->request, message->response,
                          [this, message](grpc::Status status) {
                            absl::MutexLock lock(&mu_);
                            message->status = std::move(status);
                            if (--pending_ == 0) end_ = absl::Now();
                          });
    }
  }

  double seconds() const override {
    absl::MutexLock lock(&mu_);
    return absl::ToDoubleSeconds(end_ - start_);
  }

  absl::StatusOr<std::vector<RveOutcome>> Finish() override {
    {
      absl::MutexLock lock(&mu_);
      mu_.Await(absl::Condition(this, &RemoteApply::Done));
    }
    std::vector<RveOutcome> out;
    std::size_t total = 0;
    for (const std::unique_ptr<Message>& m : messages_) total += m->ids.size();
    out.reserve(total);
    // The first error in message order, as if they had gone one by one.
    for (const std::unique_ptr<Message>& m : messages_) {
      absl::Status s = FromGrpc(m->status);
      if (s.ok()) s = AppendOutcomes(m->response->results(), m->ids, &out);
      if (!s.ok()) return Labelled(label_, s);
    }
    return out;
  }

 private:
  bool Done() const ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) { return pending_ == 0; }

  const std::string label_;
  const absl::Time start_;
  std::vector<std::unique_ptr<Message>> messages_;
  mutable absl::Mutex mu_;
  int pending_ ABSL_GUARDED_BY(mu_) = 0;
  absl::Time end_ ABSL_GUARDED_BY(mu_);
};

class RemoteEndpoint final : public RveEndpoint {
 public:
  RemoteEndpoint(std::string address, ClientOptions options, RemoteOptions remote)
      : address_(std::move(address)),
        options_(std::move(options)),
        remote_(remote),
        call_timeout_(remote.call_timeout),
        create_timeout_(remote.create_timeout),
        stub_(v1::RveService::NewStub(MakeChannel(address_, options_))) {}

  // Asks the server for its limits; the reason when it does not answer.
  absl::Status Connect() {
    grpc::ClientContext ctx;
    Prepare(ctx, options_, DeadlineOf(remote_.connect_timeout));
    v1::ServerInfo info;
    const absl::Status s = FromGrpc(stub_->GetServerInfo(&ctx, v1::ServerInfoRequest(), &info));
    if (absl::IsUnavailable(s) || absl::IsDeadlineExceeded(s)) {
      return absl::UnavailableError(absl::StrCat(label(), " is unreachable: ", s.message(), " (",
                                                 absl::StatusCodeToString(s.code()), ")"));
    }
    // Other refusals (a wrong token, say) keep their code: retrying is no cure.
    if (!s.ok()) return Error(s);
    if (info.api_version() != "rvehub.v1") {
      return absl::FailedPreconditionError(absl::StrCat(
          label(), ": speaks API \"", info.api_version(), "\", this client rvehub.v1"));
    }
    workers_ = std::max(1, info.threads());
    max_batch_ = std::max<std::int64_t>(1, remote_.max_batch);
    if (info.max_batch() > 0) max_batch_ = std::min(max_batch_, info.max_batch());
    chunk_budget_bytes_ = ImportChunkBudget(info.max_message_bytes(), options_.max_message_bytes);
    return absl::OkStatus();
  }

  std::string name() const override { return address_; }
  int workers() const override { return workers_; }
  std::string label() const override { return absl::StrCat("RVE server ", address_); }

  absl::Status PutTemplate(const store::TemplateRecord& record) override {
    v1::UploadTemplateRequest req;
    req.mutable_entry()->set_name(record.name);
    req.mutable_entry()->set_description(record.description);
    service::ToProto(record.packing, req.mutable_entry()->mutable_packing());
    req.set_replace(true);
    v1::TemplateInfo info;
    grpc::ClientContext ctx;
    Ready(ctx, call_timeout_);
    return Error(FromGrpc(stub_->UploadTemplate(&ctx, req, &info)));
  }

  absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial,
      const std::optional<dem::Controls>& controls) override {
    if (initial.size() > 1 && initial.size() != ids.size()) {
      return Error(absl::InvalidArgumentError(
          absl::StrCat("initial stresses: give none, one for all or one per id (", ids.size(),
                       "), not ", initial.size())));
    }
    // Per-point "template" states alone are no initial stress at all.
    if (initial.size() > 1 &&
        std::all_of(initial.begin(), initial.end(), [](const InitialStress& s) {
          return s.kind == InitialStress::Kind::kTemplate;
        })) {
      initial = {};
    }
    std::vector<RveOutcome> out;
    out.reserve(ids.size());
    const absl::Status status = InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
      v1::CreateRvesRequest req;
      req.set_run_id(std::string(run));
      req.set_template_name(std::string(template_name));
      for (std::size_t k = begin; k < end; ++k) req.add_ids(ids[k]);
      // The server knows no "template" kind: such entries are left out.
      if (initial.size() == 1 && initial[0].kind != InitialStress::Kind::kTemplate) {
        service::ToProto(initial[0], req.mutable_initial_stress());
      } else if (initial.size() > 1) {
        for (std::size_t k = begin; k < end; ++k) {
          if (initial[k].kind == InitialStress::Kind::kTemplate) {
            return absl::InvalidArgumentError(absl::StrCat(
                "material point ", ids[k],
                ": per-point initial stresses must all be isotropic or K0 on a server"));
          }
          service::ToProto(initial[k], req.add_initial_stresses());
        }
      }
      if (controls.has_value()) service::ToProto(*controls, req.mutable_controls());
      req.set_want_state(true);
      v1::CreateRvesResponse resp;
      grpc::ClientContext ctx;
      Ready(ctx, create_timeout_);
      absl::Status s = FromGrpc(stub_->CreateRves(&ctx, req, &resp));
      if (s.ok()) s = AppendOutcomes(resp.results(), ids.subspan(begin, end - begin), &out);
      // Creation is all or nothing on the server per message: drop the
      // earlier messages' RVEs too (best effort) so it is for the call.
      if (!s.ok() && begin > 0) (void)DropIds(run, ids.subspan(0, begin));
      return s;
    });
    if (!status.ok()) return Error(status);
    return out;
  }

  std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step,
                                           std::span<const Increment> increments,
                                           const dem::ApplyOptions& options,
                                           absl::Duration deadline) override {
    auto call = std::make_unique<RemoteApply>(label());
    const std::size_t n = increments.size();
    const std::size_t batch = static_cast<std::size_t>(max_batch_);
    // An empty call is still one (empty) message: the server's answer to it
    // is the call's, as for the embedded registry.
    std::size_t begin = 0;
    do {
      const std::size_t end = std::min(n, begin + batch);
      RemoteApply::Message& m = call->Add();
      m.request.set_run_id(std::string(run));
      m.request.set_step(step);
      m.request.set_mode(v1::APPLY_MODE_COMMIT);
      service::ToProto(options, m.request.mutable_options());
      m.ids.reserve(end - begin);
      for (std::size_t k = begin; k < end; ++k) {
        v1::Increment* inc = m.request.add_increments();
        inc->set_id(increments[k].id);
        service::ToProto(increments[k].delta_f, inc->mutable_delta_f());
        m.ids.push_back(increments[k].id);
      }
      // Messages of one call share its deadline (they all leave now).
      Ready(m.context, deadline);
      begin = end;
    } while (begin < n);
    call->SendAll(*stub_);
    return call;
  }

  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) override {
    std::vector<RveOutcome> out;
    out.reserve(ids.size());
    const absl::Status status = InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
      v1::GetStatesRequest req;
      req.set_run_id(std::string(run));
      for (std::size_t k = begin; k < end; ++k) req.add_ids(ids[k]);
      req.set_want_tangent(want_tangent);
      v1::GetStatesResponse resp;
      grpc::ClientContext ctx;
      Ready(ctx, call_timeout_);
      absl::Status s = FromGrpc(stub_->GetStates(&ctx, req, &resp));
      if (s.ok()) s = AppendOutcomes(resp.results(), ids.subspan(begin, end - begin), &out);
      return s;
    });
    if (!status.ok()) return Error(status);
    return out;
  }

  absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                      const RecordSink& sink) override {
    v1::ExportRequest req;
    req.set_run_id(std::string(run));
    for (std::int64_t id : ids) req.add_ids(id);
    grpc::ClientContext ctx;
    Ready(ctx, call_timeout_);
    std::unique_ptr<grpc::ClientReader<v1::RveChunk>> reader = stub_->Export(&ctx, req);
    return Error(ReadExport(ctx, *reader, run, sink, FromGrpc));
  }

  absl::Status Import(std::vector<store::RveRecord> records) override {
    grpc::ClientContext ctx;
    Ready(ctx, call_timeout_);
    v1::ImportResponse resp;
    std::unique_ptr<grpc::ClientWriter<v1::RveChunk>> writer = stub_->Import(&ctx, &resp);
    return Error(WriteImport(
        ctx, *writer, records.size(),
        [&](std::size_t k, v1::RveRecord* out) {
          service::ToProto(records[k], out);
          records[k] = store::RveRecord();  // the copy in `out` is all that is needed now
        },
        chunk_budget_bytes_, FromGrpc));
  }

  absl::Status Drop(absl::string_view run, std::span<const std::int64_t> ids) override {
    return InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
      return DropIds(run, ids.subspan(begin, end - begin));
    });
  }

  void SetCallTimeout(absl::Duration timeout) override { call_timeout_ = timeout; }
  void SetCreateTimeout(absl::Duration timeout) override { create_timeout_ = timeout; }

  absl::Status Ping(absl::Duration timeout) override {
    grpc::ClientContext ctx;
    Ready(ctx, timeout);
    v1::ServerInfo info;
    const absl::Status s = FromGrpc(stub_->GetServerInfo(&ctx, v1::ServerInfoRequest(), &info));
    if (s.ok()) return s;
    return absl::UnavailableError(absl::StrCat(label(), " does not answer: ", s.message()));
  }

 private:
  // Calls `send(begin, end)` for consecutive batches [begin, end) of `n`
  // items, max_batch_ at most each, until one fails. An empty call is still
  // one (empty) message: the server's answer to it is the call's, as for the
  // embedded registry.
  absl::Status InBatches(std::size_t n,
                         const std::function<absl::Status(std::size_t, std::size_t)>& send) const {
    const std::size_t batch = static_cast<std::size_t>(max_batch_);
    std::size_t begin = 0;
    do {
      const std::size_t end = std::min(n, begin + batch);
      RETURN_IF_ERROR(send(begin, end));
      begin = end;
    } while (begin < n);
    return absl::OkStatus();
  }

  void Ready(grpc::ClientContext& ctx, absl::Duration timeout) const {
    Prepare(ctx, options_, DeadlineOf(timeout));
  }

  absl::Status Error(const absl::Status& s) const { return Labelled(label(), s); }

  absl::Status DropIds(absl::string_view run, std::span<const std::int64_t> ids) {
    v1::DropRequest req;
    req.set_run_id(std::string(run));
    for (std::int64_t id : ids) req.add_ids(id);
    v1::DropResponse resp;
    grpc::ClientContext ctx;
    Ready(ctx, call_timeout_);
    return Error(FromGrpc(stub_->Drop(&ctx, req, &resp)));
  }

  const std::string address_;
  const ClientOptions options_;
  const RemoteOptions remote_;
  absl::Duration call_timeout_;    // of the calls but Create and Apply
  absl::Duration create_timeout_;  // of Create
  std::unique_ptr<v1::RveService::Stub> stub_;
  int workers_ = 1;
  std::int64_t max_batch_ = 1;           // RVEs per message, set by Connect
  std::int64_t chunk_budget_bytes_ = 0;  // bytes of records per import chunk
};

}  // namespace

absl::StatusOr<std::unique_ptr<RveEndpoint>> MakeRemoteEndpoint(const std::string& address,
                                                                const ClientOptions& options,
                                                                const RemoteOptions& remote) {
  auto endpoint = std::make_unique<RemoteEndpoint>(address, options, remote);
  RETURN_IF_ERROR(endpoint->Connect());
  return endpoint;
}

}  // namespace rvehub::client
