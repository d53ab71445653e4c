#include "rve_server/client/server_client.h"

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/client/record_stream.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/service/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::client {
namespace {

// Message reading for the client's own types; engine and store types go
// through rve_server/service/convert.h.

ServerInfo FromProto(const v1::ServerInfo& i) {
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
  out.max_batch = i.max_batch();
  out.max_message_bytes = i.max_message_bytes();
  out.uptime_seconds = i.uptime_seconds();
  out.auth_required = i.auth_required();
  out.tls = i.tls();
  return out;
}

TemplateInfo FromProto(const v1::TemplateInfo& t) {
  TemplateInfo out;
  out.name = t.name();
  out.description = t.description();
  out.material_name = t.material_name();
  out.num_particles = t.num_particles();
  out.void_ratio = t.void_ratio();
  out.mean_pressure = t.mean_pressure();
  return out;
}

}  // namespace

struct ServerClient::Stub {
  std::unique_ptr<v1::RveService::Stub> stub;

  // A ClientContext serves one call; this readies one (token, deadline).
  void Ready(const ServerClient& c, grpc::ClientContext& ctx) const {
    Prepare(ctx, c.options_, c.timeout_);
  }

  // A failed call's status, its message followed by the call and server.
  static absl::Status Check(const ServerClient& c, const grpc::Status& s, absl::string_view rpc) {
    if (s.ok()) return absl::OkStatus();
    const absl::Status a = FromGrpc(s);
    return absl::Status(a.code(), absl::StrCat(a.message(), " (", rpc, " on ", c.target_, ")"));
  }

  template <typename Request, typename Response>
  absl::Status Call(const ServerClient& c, absl::string_view rpc,
                    grpc::Status (v1::RveService::Stub::*method)(grpc::ClientContext*,
                                                                 const Request&, Response*),
                    const Request& request, Response* response) const {
    grpc::ClientContext ctx;
    Ready(c, ctx);
    return Check(c, (stub.get()->*method)(&ctx, request, response), rpc);
  }
};

ServerClient::ServerClient(std::string target, ClientOptions options,
                           std::chrono::milliseconds timeout)
    : target_(std::move(target)),
      options_(std::move(options)),
      timeout_(timeout),
      stub_(std::make_unique<Stub>()) {
  stub_->stub = v1::RveService::NewStub(MakeChannel(target_, options_));
}

ServerClient::~ServerClient() = default;
ServerClient::ServerClient(ServerClient&&) noexcept = default;
ServerClient& ServerClient::operator=(ServerClient&&) noexcept = default;

absl::StatusOr<ServerInfo> ServerClient::GetServerInfo() const {
  v1::ServerInfo info;
  if (absl::Status s = stub_->Call(*this, "GetServerInfo", &v1::RveService::Stub::GetServerInfo,
                                   v1::ServerInfoRequest(), &info);
      !s.ok()) {
    return s;
  }
  return FromProto(info);
}

absl::StatusOr<std::vector<RunInfo>> ServerClient::ListRuns() const {
  v1::ListRunsResponse response;
  if (absl::Status s = stub_->Call(*this, "ListRuns", &v1::RveService::Stub::ListRuns,
                                   v1::ListRunsRequest(), &response);
      !s.ok()) {
    return s;
  }
  std::vector<RunInfo> runs;
  runs.reserve(response.runs_size());
  for (const v1::RunInfo& r : response.runs()) {
    runs.push_back({r.run_id(), r.num_rves(), r.min_step(), r.max_step()});
  }
  return runs;
}

absl::StatusOr<std::vector<TemplateInfo>> ServerClient::ListTemplates() const {
  v1::ListTemplatesResponse response;
  if (absl::Status s = stub_->Call(*this, "ListTemplates", &v1::RveService::Stub::ListTemplates,
                                   v1::ListTemplatesRequest(), &response);
      !s.ok()) {
    return s;
  }
  std::vector<TemplateInfo> templates;
  templates.reserve(response.templates_size());
  for (const v1::TemplateInfo& t : response.templates()) templates.push_back(FromProto(t));
  return templates;
}

absl::StatusOr<TemplateInfo> ServerClient::UploadTemplate(const store::TemplateRecord& record,
                                                          bool replace) const {
  v1::UploadTemplateRequest request;
  request.mutable_entry()->set_name(record.name);
  request.mutable_entry()->set_description(record.description);
  service::ToProto(record.packing, request.mutable_entry()->mutable_packing());
  request.set_replace(replace);
  v1::TemplateInfo info;
  if (absl::Status s = stub_->Call(*this, "UploadTemplate", &v1::RveService::Stub::UploadTemplate,
                                   request, &info);
      !s.ok()) {
    return s;
  }
  return FromProto(info);
}

absl::StatusOr<RveOutcome> ServerClient::GetState(const std::string& run, std::int64_t id,
                                                  bool want_tangent) const {
  v1::GetStatesRequest request;
  request.set_run_id(run);
  request.add_ids(id);
  request.set_want_tangent(want_tangent);
  v1::GetStatesResponse response;
  if (absl::Status s =
          stub_->Call(*this, "GetStates", &v1::RveService::Stub::GetStates, request, &response);
      !s.ok()) {
    return s;
  }
  if (response.results_size() != 1) {
    return absl::InternalError(
        absl::StrCat("GetStates returned ", response.results_size(), " results for one id"));
  }
  const v1::RveResult& r = response.results(0);
  RveOutcome out;
  out.id = r.id();
  out.step = r.step();
  out.engine_seconds = r.engine_seconds();
  if (r.code() != 0) {
    out.status = absl::Status(static_cast<absl::StatusCode>(r.code()), r.message());
    return out;
  }
  if (absl::Status s = service::FromProto(r.state(), &out.state, &out.deformation_gradient);
      !s.ok()) {
    return absl::DataLossError(absl::StrCat("GetStates reply for material point ", r.id(),
                                            " is malformed: ", s.message(), " (on ", target_, ")"));
  }
  return out;
}

absl::Status ServerClient::ExportRun(const std::string& run, const RecordSink& sink) const {
  v1::ExportRequest request;
  request.set_run_id(run);
  grpc::ClientContext ctx;
  stub_->Ready(*this, ctx);
  std::unique_ptr<grpc::ClientReader<v1::RveChunk>> reader = stub_->stub->Export(&ctx, request);
  return ReadExport(ctx, *reader, run, sink, [&](const grpc::Status& s) {
    return Stub::Check(*this, s, absl::StrCat("Export of run \"", run, "\""));
  });
}

absl::StatusOr<ImportSummary> ServerClient::Import(
    std::span<const store::RveRecord* const> records) const {
  ASSIGN_OR_RETURN(ServerInfo info, GetServerInfo());
  const std::int64_t budget = ImportChunkBudget(info.max_message_bytes, options_.max_message_bytes);
  grpc::ClientContext ctx;
  stub_->Ready(*this, ctx);
  v1::ImportResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::RveChunk>> writer = stub_->stub->Import(&ctx, &response);
  ImportSummary summary;
  if (absl::Status s = WriteImport(
          ctx, *writer, records.size(),
          [&](std::size_t k, v1::RveRecord* out) { service::ToProto(*records[k], out); }, budget,
          [&](const grpc::Status& s) { return Stub::Check(*this, s, "Import"); }, &summary.chunks);
      !s.ok()) {
    return s;
  }
  summary.imported = response.imported();
  return summary;
}

absl::StatusOr<std::int64_t> ServerClient::Drop(const std::string& run,
                                                std::span<const std::int64_t> ids) const {
  v1::DropRequest request;
  request.set_run_id(run);
  for (std::int64_t id : ids) request.add_ids(id);
  v1::DropResponse response;
  if (absl::Status s = stub_->Call(*this, "Drop", &v1::RveService::Stub::Drop, request, &response);
      !s.ok()) {
    return s;
  }
  return response.dropped();
}

absl::StatusOr<std::vector<dem::ElementTestRow>> ServerClient::RunElementTest(
    const std::string& template_name, const dem::ElementTestSpec& spec,
    const std::function<void(double fraction)>& progress) const {
  v1::ElementTestRequest request;
  service::ToProto(spec, &request);
  request.set_template_name(template_name);
  grpc::ClientContext ctx;
  stub_->Ready(*this, ctx);
  std::unique_ptr<grpc::ClientReader<v1::ElementTestUpdate>> reader =
      stub_->stub->RunElementTest(&ctx, request);
  std::vector<dem::ElementTestRow> rows;
  v1::ElementTestUpdate update;
  while (reader->Read(&update)) {
    if (progress) progress(update.progress());
    for (const v1::ElementTestRow& row : update.rows()) rows.push_back(service::FromProto(row));
  }
  RETURN_IF_ERROR(Stub::Check(*this, reader->Finish(), "RunElementTest"));
  return rows;
}

}  // namespace rvehub::client
