// An in-process RVE server on loopback with a client, for the service's
// tests (service_test, hardening_test, fuzz_test).
#ifndef RVEHUB_TESTS_RVE_SERVER_SERVICE_SERVICE_HARNESS_H_
#define RVEHUB_TESTS_RVE_SERVER_SERVICE_SERVICE_HARNESS_H_

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/client_unary_call.h>
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "rve_server/service/log.h"
#include "rve_server/service/server.h"
#include "rve_server/wire/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "tests/support/rpc_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::service::testing {

using wire::FromProto;
using wire::ToProto;

inline constexpr char kTemplate[] = "set-dense";

// The SET-dense template with few DEM steps per increment.
inline v1::Template MakeTemplate() {
  dem::RveSnapshot p = dem::testing_util::Prepared("SET-dense");
  p.controls.min_steps = 10;
  v1::Template t;
  t.set_name(kTemplate);
  t.set_description("SET-dense seed 1, min_steps 10");
  ToProto(p, t.mutable_packing());
  return t;
}

// Axial compression increment εyy = −e (plane strain), [-].
inline std::vector<double> Compress(double e) { return {1, 0, 0, 0, 1 - e, 0, 0, 0, 1}; }

class Harness {
 public:
  explicit Harness(ServerConfig config = {}) {
    SetLogEnabled(false);
    config.listen = "127.0.0.1:0";
    absl::StatusOr<std::unique_ptr<RveServer>> s = RveServer::Start(config);
    EXPECT_TRUE(s.ok()) << s.status();
    server_ = *std::move(s);
    channel_ = grpc::CreateChannel(server_->address(), grpc::InsecureChannelCredentials());
    stub_ = v1::RveService::NewStub(channel_);
    token_ = config.auth_token;
  }

  v1::RveService::Stub& stub() { return *stub_; }
  std::shared_ptr<grpc::Channel> channel() { return channel_; }
  RveServer& server() { return *server_; }

  std::unique_ptr<grpc::ClientContext> Context(
      std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
    auto ctx = std::make_unique<grpc::ClientContext>();
    if (!token_.empty()) ctx->AddMetadata("authorization", "Bearer " + token_);
    ctx->set_deadline(std::chrono::system_clock::now() + timeout);
    return ctx;
  }

  grpc::Status Upload() {
    v1::UploadTemplateRequest req;
    *req.mutable_entry() = MakeTemplate();
    v1::TemplateInfo info;
    return stub_->UploadTemplate(Context().get(), req, &info);
  }

  grpc::Status Create(const std::string& run, const std::vector<std::int64_t>& ids,
                      v1::CreateRvesResponse* resp = nullptr) {
    v1::CreateRvesRequest req;
    req.set_run_id(run);
    req.set_template_name(kTemplate);
    for (std::int64_t id : ids) req.add_ids(id);
    v1::CreateRvesResponse local;
    return stub_->CreateRves(Context().get(), req, resp ? resp : &local);
  }

  // One increment per id at `step` in `mode`.
  grpc::Status Apply(const std::string& run, std::int64_t step, v1::ApplyMode mode,
                     const std::vector<std::int64_t>& ids, const std::vector<double>& delta_f,
                     v1::ApplyResponse* resp, bool tangent = false) {
    v1::ApplyRequest req = Commit(run, step, ids, delta_f);
    req.set_mode(mode);
    req.mutable_options()->set_want_tangent(tangent);
    return stub_->Apply(Context().get(), req, resp);
  }

  v1::RveRecord ExportOne(const std::string& run, std::int64_t id) {
    return service::ExportOne(*stub_, *Context(), run, id);
  }

  dem::RveSnapshot SnapshotOf(const std::string& run, std::int64_t id) {
    absl::StatusOr<dem::RveSnapshot> p = FromProto(ExportOne(run, id).packing());
    EXPECT_TRUE(p.ok()) << p.status();
    return p.ok() ? *p : dem::RveSnapshot{};
  }

  // One increment per id, COMMIT at `step`.
  static v1::ApplyRequest Commit(const std::string& run, std::int64_t step,
                                 const std::vector<std::int64_t>& ids,
                                 const std::vector<double>& delta_f) {
    v1::ApplyRequest req;
    req.set_run_id(run);
    req.set_step(step);
    req.set_mode(v1::APPLY_MODE_COMMIT);
    for (std::int64_t id : ids) {
      v1::Increment* inc = req.add_increments();
      inc->set_id(id);
      for (double v : delta_f) inc->add_delta_f(v);
    }
    return req;
  }

  // RVEs hosted in all runs.
  std::int64_t NumRves() {
    v1::ServerInfo info;
    EXPECT_TRUE(stub_->GetServerInfo(Context().get(), {}, &info).ok());
    return info.num_rves();
  }

  // Serialised Export of one RVE ("" when the export fails).
  std::string ExportBytes(const std::string& run, std::int64_t id) {
    v1::ExportRequest req;
    req.set_run_id(run);
    req.add_ids(id);
    auto ctx = Context();
    std::unique_ptr<grpc::ClientReader<v1::RveChunk>> reader = stub_->Export(ctx.get(), req);
    v1::RveChunk chunk;
    std::string out;
    while (reader->Read(&chunk)) out += chunk.SerializeAsString();
    return reader->Finish().ok() ? out : "";
  }

 private:
  std::unique_ptr<RveServer> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::RveService::Stub> stub_;
  std::string token_;
};

// Expects `status` to carry `code` and a message containing `words`.
inline void ExpectError(const grpc::Status& status, grpc::StatusCode code,
                        const std::string& words) {
  EXPECT_EQ(status.error_code(), code) << status.error_message();
  EXPECT_NE(status.error_message().find(words), std::string::npos)
      << "\"" << status.error_message() << "\" lacks \"" << words << "\"";
}

// Raw bytes to a unary method ("/rvehub.v1.RveService/Apply"), bypassing the
// typed stubs, so that any byte string can be sent.
inline grpc::Status RawUnary(grpc::Channel& channel, grpc::ClientContext& ctx,
                             const std::string& method, const std::string& bytes) {
  grpc::Slice slice(bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  return grpc::internal::BlockingUnaryCall<grpc::ByteBuffer, grpc::ByteBuffer>(
      &channel, grpc::internal::RpcMethod(method.c_str(), grpc::internal::RpcMethod::NORMAL_RPC),
      &ctx, request, &response);
}

// Raw messages to Import (a client stream), then its status.
inline grpc::Status RawImport(grpc::Channel& channel, grpc::ClientContext& ctx,
                              const std::vector<std::string>& messages,
                              v1::ImportResponse* resp = nullptr) {
  grpc::ByteBuffer response;
  std::unique_ptr<grpc::ClientWriter<grpc::ByteBuffer>> writer(
      grpc::internal::ClientWriterFactory<grpc::ByteBuffer>::Create(
          &channel,
          grpc::internal::RpcMethod("/rvehub.v1.RveService/Import",
                                    grpc::internal::RpcMethod::CLIENT_STREAMING),
          &ctx, &response));
  for (const std::string& m : messages) {
    grpc::Slice slice(m);
    if (!writer->Write(grpc::ByteBuffer(&slice, 1))) break;
  }
  writer->WritesDone();
  grpc::Status s = writer->Finish();
  if (s.ok() && resp != nullptr) {
    (void)grpc::SerializationTraits<v1::ImportResponse>::Deserialize(&response, resp);
  }
  return s;
}

}  // namespace rvehub::service::testing

#endif  // RVEHUB_TESTS_RVE_SERVER_SERVICE_SERVICE_HARNESS_H_
