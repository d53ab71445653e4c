// An RVE server: the registry, the gRPC service, grpc's health checking and
// reflection services, authentication and TLS, and checkpointing of all RVEs
// to a directory. Used by the rve_server binary and by tests (port 0 picks a
// free port).
#ifndef RVEHUB_RVE_SERVER_SERVICE_SERVER_H_
#define RVEHUB_RVE_SERVER_SERVICE_SERVER_H_

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "rve_server/common/version.h"
#include "rve_server/service/registry.h"
#include "rve_server/service/rve_service.h"

namespace rvehub::service {

inline constexpr const char* kServerVersion = kVersion;

struct ServerConfig {
  std::string listen = "127.0.0.1:50051";  // HOST:PORT; port 0 picks a free one
  RegistryOptions registry;
  std::int64_t max_message_bytes = 64 << 20;  // per message, both ways, 1 MiB..2 GiB − 1
  std::string auth_token;                     // empty: no authentication
  // With a token: grpc.health.v1.Health answers without it (it tells only
  // SERVING or NOT_SERVING), for orchestrators' probes (Kubernetes' gRPC
  // probes carry no metadata). Everything else still needs the token.
  bool health_without_token = false;
  std::string tls_cert_pem;  // both set: TLS; else plaintext
  std::string tls_key_pem;
  std::string checkpoint_dir;  // set: locked and loaded on start, saved on Stop
};

class RveServer {
 public:
  // Loads the checkpoint directory's files when present, then listens.
  // InvalidArgument for a listen address that is not HOST:PORT with a port in
  // 0..65535 (ValidateAddress), threads outside 1..kMaxThreads, a max RVEs,
  // memory, batch or templates below 1, a message size outside its range, or one of the
  // TLS certificate and key without the other; PermissionDenied for a
  // checkpoint directory that cannot be made or written into;
  // FailedPrecondition for one that another server holds (a server holds
  // its checkpoint directory, locked, from Start to its destruction).
  static absl::StatusOr<std::unique_ptr<RveServer>> Start(const ServerConfig& config);
  ~RveServer();

  int port() const { return port_; }
  std::string address() const;  // host:port actually bound
  Registry& registry() { return *registry_; }

  // Drains: health turns NOT_SERVING, new calls are refused, calls in flight
  // get until `grace` to finish (then are cancelled); with a checkpoint
  // directory, every RVE and template is then saved. Idempotent.
  absl::Status Stop(std::chrono::milliseconds grace = std::chrono::seconds(30));

  // Blocks until Stop has shut the gRPC server down.
  void Wait();

  // Writes rves.h5 and templates.h5 into `dir` (atomically each).
  absl::Status SaveCheckpoint(const std::string& dir);
  // Loads them when present (a missing file is not an error).
  absl::Status LoadCheckpoint(const std::string& dir);

 private:
  RveServer() = default;

  ServerConfig config_;
  std::unique_ptr<Registry> registry_;
  std::unique_ptr<RveServiceImpl> service_;
  std::unique_ptr<grpc::Service> reflection_v1_;  // grpc.reflection.v1, forwarded to v1alpha
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  bool stopped_ = false;
  int checkpoint_lock_fd_ = -1;  // the checkpoint directory's lock file, held while >= 0
};

}  // namespace rvehub::service

#endif  // RVEHUB_RVE_SERVER_SERVICE_SERVER_H_
