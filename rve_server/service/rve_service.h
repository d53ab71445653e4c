// The gRPC face of a Registry: translates rvehub.v1 messages to registry
// calls and absl::Status to grpc::Status (the only place that mapping lives).
#ifndef RVEHUB_RVE_SERVER_SERVICE_RVE_SERVICE_H_
#define RVEHUB_RVE_SERVER_SERVICE_RVE_SERVICE_H_

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/status.h"
#include "absl/synchronization/mutex.h"
#include "rve_server/service/registry.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace rvehub::service {

// absl::Status → grpc::Status (codes are numbered alike).
grpc::Status ToGrpc(const absl::Status& s);

struct ServiceOptions {
  std::string version;     // reported by GetServerInfo
  std::string auth_token;  // empty: no authentication
  bool tls = false;        // reported only
  std::int64_t max_message_bytes = 64 << 20;
};

// "authorization: Bearer <token>" check shared by the service and the
// interceptor that guards grpc's own services (health, reflection).
bool Authorized(const std::multimap<grpc::string_ref, grpc::string_ref>& metadata,
                const std::string& token);

class RveServiceImpl final : public v1::RveService::Service {
 public:
  RveServiceImpl(Registry& registry, ServiceOptions options);

  grpc::Status UploadTemplate(grpc::ServerContext* ctx, const v1::UploadTemplateRequest* req,
                              v1::TemplateInfo* resp) override;
  grpc::Status ListTemplates(grpc::ServerContext* ctx, const v1::ListTemplatesRequest* req,
                             v1::ListTemplatesResponse* resp) override;
  grpc::Status CreateRves(grpc::ServerContext* ctx, const v1::CreateRvesRequest* req,
                          v1::CreateRvesResponse* resp) override;
  // Not called: Apply is served by ApplyOnArena (see the constructor).
  grpc::Status Apply(grpc::ServerContext* ctx, const v1::ApplyRequest* req,
                     v1::ApplyResponse* resp) override;
  grpc::Status GetStates(grpc::ServerContext* ctx, const v1::GetStatesRequest* req,
                         v1::GetStatesResponse* resp) override;
  grpc::Status Export(grpc::ServerContext* ctx, const v1::ExportRequest* req,
                      grpc::ServerWriter<v1::RveChunk>* writer) override;
  // Not called: Import is served by ImportBytes (see the constructor).
  grpc::Status Import(grpc::ServerContext* ctx, grpc::ServerReader<v1::RveChunk>* reader,
                      v1::ImportResponse* resp) override;
  grpc::Status Drop(grpc::ServerContext* ctx, const v1::DropRequest* req,
                    v1::DropResponse* resp) override;
  grpc::Status ListRuns(grpc::ServerContext* ctx, const v1::ListRunsRequest* req,
                        v1::ListRunsResponse* resp) override;
  grpc::Status GetServerInfo(grpc::ServerContext* ctx, const v1::ServerInfoRequest* req,
                             v1::ServerInfo* resp) override;
  grpc::Status RunElementTest(grpc::ServerContext* ctx, const v1::ElementTestRequest* req,
                              grpc::ServerWriter<v1::ElementTestUpdate>* writer) override;

  // Makes every call in flight stop at its next cancellation check (between
  // RVEs and between DEM steps) with CANCELLED: a drain whose grace ran out.
  void CancelAll() { cancel_all_.store(true); }

 private:
  // The handlers' bodies; the overrides run them behind GuardHandler.
  grpc::Status DoUploadTemplate(grpc::ServerContext* ctx, const v1::UploadTemplateRequest* req,
                                v1::TemplateInfo* resp);
  grpc::Status DoCreateRves(grpc::ServerContext* ctx, const v1::CreateRvesRequest* req,
                            v1::CreateRvesResponse* resp);
  // Fills resp's results on the registry's workers, each as its RVE is done.
  grpc::Status DoApply(grpc::ServerContext* ctx, const v1::ApplyRequest* req,
                       v1::ApplyResponse* resp);
  // Apply with the request and the reply on one protobuf arena: a reply of
  // thousands of RveResults is then a few blocks to allocate and free, not
  // six heap objects per RVE. Reads and writes the messages' bytes itself.
  grpc::Status ApplyOnArena(grpc::ServerContext* ctx,
                            grpc::ServerUnaryStreamer<grpc::ByteBuffer, grpc::ByteBuffer>* stream);
  grpc::Status DoGetStates(grpc::ServerContext* ctx, const v1::GetStatesRequest* req,
                           v1::GetStatesResponse* resp);
  grpc::Status DoExport(grpc::ServerContext* ctx, const v1::ExportRequest* req,
                        grpc::ServerWriter<v1::RveChunk>* writer);
  // Import reads raw bytes so that an unparseable chunk is told apart from
  // the end of the stream (a typed reader reports both as "no more").
  grpc::Status ImportBytes(grpc::ServerContext* ctx, grpc::ServerReader<grpc::ByteBuffer>* reader,
                           v1::ImportResponse* resp);
  grpc::Status DoDrop(grpc::ServerContext* ctx, const v1::DropRequest* req, v1::DropResponse* resp);
  grpc::Status DoRunElementTest(grpc::ServerContext* ctx, const v1::ElementTestRequest* req,
                                grpc::ServerWriter<v1::ElementTestUpdate>* writer);
  // The call's deadline and cancellation, and CancelAll, as a CancelFn.
  CancelFn Canceller(grpc::ServerContext* ctx) const;
  // INVALID_ARGUMENT when a reply of `count` RveResults (with tangents or
  // not) could exceed the message limit: refused before anything changes.
  grpc::Status CheckReplySize(std::int64_t count, bool want_tangent, const char* what) const;

  // UNAUTHENTICATED unless the call carries the token (when one is set).
  grpc::Status CheckAuth(grpc::ServerContext* ctx) const;

  // The bytes Import streams in flight hold (each keeps its records until
  // its end: all or nothing), shared by all: together at most the room left
  // in the registry's memory account. Reserve adds `bytes` to what a stream
  // holds (`held`), or is RESOURCE_EXHAUSTED naming the budget (nothing
  // added); Release gives a stream's back.
  grpc::Status ReserveImportBytes(std::int64_t bytes, std::int64_t& held);
  void ReleaseImportBytes(std::int64_t held);
  std::int64_t import_bytes() const;

  Registry& registry_;
  const ServiceOptions options_;
  const std::chrono::steady_clock::time_point started_;
  std::atomic<bool> cancel_all_{false};
  mutable absl::Mutex import_mu_;
  std::int64_t import_bytes_ ABSL_GUARDED_BY(import_mu_) = 0;
};

}  // namespace rvehub::service

#endif  // RVEHUB_RVE_SERVER_SERVICE_RVE_SERVICE_H_
