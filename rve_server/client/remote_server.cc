#include "rve_server/client/remote_server.h"

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
#include "rve_server/client/record_stream.h"
#include "rve_server/common/names.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/wire/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::client {
namespace {

// Messages to and from the values: rve_server/wire/convert.h.

absl::StatusOr<RveOutcome> OutcomeFromProto(const v1::RveResult& r) {
  RveOutcome o;
  if (absl::Status s = wire::FromProto(r, &o); !s.ok()) {
    return absl::DataLossError(
        absl::StrCat("reply for material point ", r.id(), " is malformed: ", s.message()));
  }
  return o;
}

ServerInfo ServerInfoFromProto(const v1::ServerInfo& i) {
  ServerInfo out;
  out.version = i.version();
  out.api_version = i.api_version();
  out.threads = i.threads();
  out.num_rves = i.num_rves();
  out.max_rves = i.max_rves();
  out.memory_bytes = i.memory_bytes();
  out.max_memory_bytes = i.max_memory_bytes();
  out.num_runs = i.num_runs();
  out.num_templates = i.num_templates();
  out.max_templates = i.max_templates();
  out.max_batch = i.max_batch();
  out.max_message_bytes = i.max_message_bytes();
  out.uptime_seconds = i.uptime_seconds();
  out.auth_required = i.auth_required();
  out.tls = i.tls();
  return out;
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

}  // namespace

struct RemoteServer::Impl {
  Impl(std::string address, ClientOptions options, RemoteOptions remote)
      : address(std::move(address)),
        options(std::move(options)),
        remote(remote),
        call_timeout(remote.call_timeout),
        create_timeout(remote.create_timeout),
        stub(v1::RveService::NewStub(MakeChannel(this->address, this->options))) {}

  std::string label() const { return absl::StrCat("RVE server ", address); }

  // A ClientContext serves one call: this readies one (token, deadline).
  void Ready(grpc::ClientContext& ctx, absl::Duration timeout) const {
    Prepare(ctx, options, DeadlineOf(timeout));
  }

  // One unary call with the call deadline.
  template <typename Request, typename Response>
  absl::Status Call(grpc::Status (v1::RveService::Stub::*method)(grpc::ClientContext*,
                                                                 const Request&, Response*),
                    const Request& request, Response* response) const {
    grpc::ClientContext ctx;
    Ready(ctx, call_timeout);
    return FromGrpc((stub.get()->*method)(&ctx, request, response));
  }

  // Calls `send(begin, end)` for consecutive batches [begin, end) of `n`
  // items, max_batch at most each, until one fails. An empty call is still
  // one (empty) message: the server's answer to it is the call's, as for the
  // embedded registry.
  absl::Status InBatches(std::size_t n,
                         const std::function<absl::Status(std::size_t, std::size_t)>& send) const {
    const std::size_t batch = static_cast<std::size_t>(max_batch);
    std::size_t begin = 0;
    do {
      const std::size_t end = std::min(n, begin + batch);
      RETURN_IF_ERROR(send(begin, end));
      begin = end;
    } while (begin < n);
    return absl::OkStatus();
  }

  absl::StatusOr<std::int64_t> DropIds(absl::string_view run,
                                       std::span<const std::int64_t> ids) const {
    v1::DropRequest req;
    req.set_run_id(std::string(run));
    for (std::int64_t id : ids) req.add_ids(id);
    v1::DropResponse resp;
    RETURN_IF_ERROR(Call(&v1::RveService::Stub::Drop, req, &resp));
    return resp.dropped();
  }

  const std::string address;
  const ClientOptions options;
  const RemoteOptions remote;
  absl::Duration call_timeout;    // of the calls but Create and Apply
  absl::Duration create_timeout;  // of Create
  std::unique_ptr<v1::RveService::Stub> stub;
  int workers = 1;
  std::int64_t max_batch = 1;           // RVEs per message, set by Connect
  std::int64_t chunk_budget_bytes = 0;  // bytes of records per import chunk
};

RemoteServer::RemoteServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RemoteServer::~RemoteServer() = default;

absl::StatusOr<std::unique_ptr<RemoteServer>> RemoteServer::Connect(const std::string& address,
                                                                    const ClientOptions& options,
                                                                    const RemoteOptions& remote) {
  auto impl = std::make_unique<Impl>(address, options, remote);
  grpc::ClientContext ctx;
  impl->Ready(ctx, remote.connect_timeout);
  v1::ServerInfo info;
  const absl::Status s = FromGrpc(impl->stub->GetServerInfo(&ctx, v1::ServerInfoRequest(), &info));
  if (absl::IsUnavailable(s) || absl::IsDeadlineExceeded(s)) {
    return absl::UnavailableError(absl::StrCat(impl->label(), " is unreachable: ", s.message(),
                                               " (", absl::StatusCodeToString(s.code()), ")"));
  }
  // Other refusals (a wrong token, say) keep their code: retrying is no cure.
  if (!s.ok()) return Labelled(impl->label(), s);
  if (info.api_version() != "rvehub.v1") {
    return absl::FailedPreconditionError(absl::StrCat(
        impl->label(), ": speaks API \"", info.api_version(), "\", this client rvehub.v1"));
  }
  impl->workers = std::max(1, info.threads());
  impl->max_batch = std::max<std::int64_t>(1, remote.max_batch);
  if (info.max_batch() > 0) impl->max_batch = std::min(impl->max_batch, info.max_batch());
  impl->chunk_budget_bytes =
      ImportChunkBudget(info.max_message_bytes(), impl->options.max_message_bytes);
  return std::unique_ptr<RemoteServer>(new RemoteServer(std::move(impl)));
}

std::string RemoteServer::name() const { return impl_->address; }
std::string RemoteServer::label() const { return impl_->label(); }
int RemoteServer::workers() const { return impl_->workers; }
absl::Status RemoteServer::Error(const absl::Status& s) const { return Labelled(label(), s); }
void RemoteServer::SetCallTimeout(absl::Duration timeout) { impl_->call_timeout = timeout; }
void RemoteServer::SetCreateTimeout(absl::Duration timeout) { impl_->create_timeout = timeout; }

absl::Status RemoteServer::PutTemplate(const TemplateRecord& record) {
  return UploadTemplate(record, /*replace=*/true).status();
}

absl::StatusOr<TemplateInfo> RemoteServer::UploadTemplate(const TemplateRecord& record,
                                                          bool replace) const {
  v1::UploadTemplateRequest req;
  req.mutable_entry()->set_name(record.name);
  req.mutable_entry()->set_description(record.description);
  wire::ToProto(record.packing, req.mutable_entry()->mutable_packing());
  req.set_replace(replace);
  v1::TemplateInfo info;
  RETURN_IF_ERROR(Error(impl_->Call(&v1::RveService::Stub::UploadTemplate, req, &info)));
  return wire::FromProto(info);
}

absl::StatusOr<std::vector<RveOutcome>> RemoteServer::Create(
    absl::string_view run, absl::string_view template_name, std::span<const std::int64_t> ids,
    std::span<const InitialStress> initial, const std::optional<dem::Controls>& controls) {
  if (initial.size() > 1 && initial.size() != ids.size()) {
    return Error(absl::InvalidArgumentError(
        absl::StrCat("initial stresses: give none, one for all or one per id (", ids.size(),
                     "), not ", initial.size())));
  }
  // Per-point "template" states alone are no initial stress at all.
  if (initial.size() > 1 && std::all_of(initial.begin(), initial.end(), [](const InitialStress& s) {
        return s.kind == InitialStress::Kind::kTemplate;
      })) {
    initial = {};
  }
  std::vector<RveOutcome> out;
  out.reserve(ids.size());
  const absl::Status status = impl_->InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
    v1::CreateRvesRequest req;
    req.set_run_id(std::string(run));
    req.set_template_name(std::string(template_name));
    for (std::size_t k = begin; k < end; ++k) req.add_ids(ids[k]);
    // The server knows no "template" kind: such entries are left out.
    if (initial.size() == 1 && initial[0].kind != InitialStress::Kind::kTemplate) {
      wire::ToProto(initial[0], req.mutable_initial_stress());
    } else if (initial.size() > 1) {
      for (std::size_t k = begin; k < end; ++k) {
        if (initial[k].kind == InitialStress::Kind::kTemplate) {
          return absl::InvalidArgumentError(
              absl::StrCat("material point ", ids[k],
                           ": per-point initial stresses must all be isotropic or K0 on a server"));
        }
        wire::ToProto(initial[k], req.add_initial_stresses());
      }
    }
    if (controls.has_value()) wire::ToProto(*controls, req.mutable_controls());
    req.set_want_state(true);
    v1::CreateRvesResponse resp;
    grpc::ClientContext ctx;
    impl_->Ready(ctx, impl_->create_timeout);
    absl::Status s = FromGrpc(impl_->stub->CreateRves(&ctx, req, &resp));
    if (s.ok()) s = AppendOutcomes(resp.results(), ids.subspan(begin, end - begin), &out);
    // Creation is all or nothing on the server per message: drop the
    // earlier messages' RVEs too (best effort) so it is for the call.
    if (!s.ok() && begin > 0) (void)impl_->DropIds(run, ids.subspan(0, begin));
    return s;
  });
  if (!status.ok()) return Error(status);
  return out;
}

std::unique_ptr<PendingApply> RemoteServer::StartApply(absl::string_view run, std::int64_t step,
                                                       ApplyMode mode,
                                                       std::span<const Increment> increments,
                                                       const dem::ApplyOptions& options,
                                                       absl::Duration deadline) {
  auto call = std::make_unique<RemoteApply>(label());
  const std::size_t n = increments.size();
  const std::size_t batch = static_cast<std::size_t>(impl_->max_batch);
  // An empty call is still one (empty) message: the server's answer to it
  // is the call's, as for the embedded registry.
  std::size_t begin = 0;
  do {
    const std::size_t end = std::min(n, begin + batch);
    RemoteApply::Message& m = call->Add();
    m.request.set_run_id(std::string(run));
    m.request.set_step(step);
    m.request.set_mode(wire::ToProto(mode));
    wire::ToProto(options, m.request.mutable_options());
    m.ids.reserve(end - begin);
    for (std::size_t k = begin; k < end; ++k) {
      v1::Increment* inc = m.request.add_increments();
      inc->set_id(increments[k].id);
      wire::ToProto(increments[k].delta_f, inc->mutable_delta_f());
      m.ids.push_back(increments[k].id);
    }
    // Messages of one call share its deadline (they all leave now).
    impl_->Ready(m.context, deadline);
    begin = end;
  } while (begin < n);
  call->SendAll(*impl_->stub);
  return call;
}

absl::StatusOr<std::vector<RveOutcome>> RemoteServer::Get(absl::string_view run,
                                                          std::span<const std::int64_t> ids,
                                                          bool want_tangent) {
  std::vector<RveOutcome> out;
  out.reserve(ids.size());
  const absl::Status status = impl_->InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
    v1::GetStatesRequest req;
    req.set_run_id(std::string(run));
    for (std::size_t k = begin; k < end; ++k) req.add_ids(ids[k]);
    req.set_want_tangent(want_tangent);
    v1::GetStatesResponse resp;
    absl::Status s = impl_->Call(&v1::RveService::Stub::GetStates, req, &resp);
    if (s.ok()) s = AppendOutcomes(resp.results(), ids.subspan(begin, end - begin), &out);
    return s;
  });
  if (!status.ok()) return Error(status);
  return out;
}

absl::Status RemoteServer::Export(absl::string_view run, std::span<const std::int64_t> ids,
                                  const RecordSink& sink) {
  v1::ExportRequest req;
  req.set_run_id(std::string(run));
  for (std::int64_t id : ids) req.add_ids(id);
  grpc::ClientContext ctx;
  impl_->Ready(ctx, impl_->call_timeout);
  std::unique_ptr<grpc::ClientReader<v1::RveChunk>> reader = impl_->stub->Export(&ctx, req);
  return Error(ReadExport(ctx, *reader, run, sink, FromGrpc));
}

absl::Status RemoteServer::Import(std::vector<RveRecord> records) {
  return ImportRecords(std::move(records)).status();
}

absl::StatusOr<ImportSummary> RemoteServer::ImportRecords(std::vector<RveRecord> records) const {
  grpc::ClientContext ctx;
  impl_->Ready(ctx, impl_->call_timeout);
  v1::ImportResponse resp;
  std::unique_ptr<grpc::ClientWriter<v1::RveChunk>> writer = impl_->stub->Import(&ctx, &resp);
  ImportSummary summary;
  RETURN_IF_ERROR(Error(WriteImport(
      ctx, *writer, records.size(),
      [&](std::size_t k, v1::RveRecord* out) {
        wire::ToProto(records[k], out);
        records[k] = RveRecord();  // the copy in `out` is all that is needed now
      },
      impl_->chunk_budget_bytes, FromGrpc, &summary.chunks)));
  summary.imported = resp.imported();
  return summary;
}

absl::Status RemoteServer::Drop(absl::string_view run, std::span<const std::int64_t> ids) {
  return DropRves(run, ids).status();
}

absl::StatusOr<std::int64_t> RemoteServer::DropRves(absl::string_view run,
                                                    std::span<const std::int64_t> ids) const {
  std::int64_t dropped = 0;
  RETURN_IF_ERROR(Error(impl_->InBatches(ids.size(), [&](std::size_t begin, std::size_t end) {
    ASSIGN_OR_RETURN(std::int64_t n, impl_->DropIds(run, ids.subspan(begin, end - begin)));
    dropped += n;
    return absl::OkStatus();
  })));
  return dropped;
}

absl::Status RemoteServer::Ping(absl::Duration timeout) {
  grpc::ClientContext ctx;
  impl_->Ready(ctx, timeout);
  v1::ServerInfo info;
  const absl::Status s = FromGrpc(impl_->stub->GetServerInfo(&ctx, v1::ServerInfoRequest(), &info));
  if (s.ok()) return s;
  return absl::UnavailableError(absl::StrCat(label(), " does not answer: ", s.message()));
}

absl::StatusOr<ServerInfo> RemoteServer::GetServerInfo() const {
  v1::ServerInfo info;
  RETURN_IF_ERROR(
      Error(impl_->Call(&v1::RveService::Stub::GetServerInfo, v1::ServerInfoRequest(), &info)));
  return ServerInfoFromProto(info);
}

namespace {

// The next page's token, or Internal where a server's token would not move
// on (the pages are in key order): a loop that never ends otherwise.
absl::Status CheckNextPage(const std::string& token, const std::string& next) {
  if (next.empty() || next > token) return absl::OkStatus();
  return absl::InternalError(absl::StrCat("the server's next page token ", QuotedName(next),
                                          " does not follow the last one ", QuotedName(token)));
}

}  // namespace

absl::StatusOr<std::vector<RunInfo>> RemoteServer::ListRuns() const {
  std::vector<RunInfo> runs;
  v1::ListRunsRequest request;
  do {  // every page (a server replies with as many as fit in a message)
    v1::ListRunsResponse response;
    RETURN_IF_ERROR(Error(impl_->Call(&v1::RveService::Stub::ListRuns, request, &response)));
    for (const v1::RunInfo& r : response.runs()) runs.push_back(wire::FromProto(r));
    RETURN_IF_ERROR(Error(CheckNextPage(request.page_token(), response.next_page_token())));
    request.set_page_token(response.next_page_token());
  } while (!request.page_token().empty());
  return runs;
}

absl::StatusOr<std::vector<TemplateInfo>> RemoteServer::ListTemplates() const {
  std::vector<TemplateInfo> templates;
  v1::ListTemplatesRequest request;
  do {  // every page, as ListRuns
    v1::ListTemplatesResponse response;
    RETURN_IF_ERROR(Error(impl_->Call(&v1::RveService::Stub::ListTemplates, request, &response)));
    for (const v1::TemplateInfo& t : response.templates()) templates.push_back(wire::FromProto(t));
    RETURN_IF_ERROR(Error(CheckNextPage(request.page_token(), response.next_page_token())));
    request.set_page_token(response.next_page_token());
  } while (!request.page_token().empty());
  return templates;
}

absl::StatusOr<std::vector<dem::ElementTestRow>> RemoteServer::RunElementTest(
    const std::string& template_name, const dem::ElementTestSpec& spec,
    const std::function<void(double fraction)>& progress) const {
  v1::ElementTestRequest request;
  wire::ToProto(spec, &request);
  request.set_template_name(template_name);
  grpc::ClientContext ctx;
  impl_->Ready(ctx, impl_->call_timeout);
  std::unique_ptr<grpc::ClientReader<v1::ElementTestUpdate>> reader =
      impl_->stub->RunElementTest(&ctx, request);
  std::vector<dem::ElementTestRow> rows;
  v1::ElementTestUpdate update;
  while (reader->Read(&update)) {
    if (progress) progress(update.progress());
    for (const v1::ElementTestRow& row : update.rows()) rows.push_back(wire::FromProto(row));
  }
  RETURN_IF_ERROR(Error(FromGrpc(reader->Finish())));
  return rows;
}

}  // namespace rvehub::client
