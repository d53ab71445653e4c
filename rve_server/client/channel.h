// Client side of rvehub.v1: channels with the server's transport settings
// (TLS, message size), per-call metadata (bearer token, deadline) and the
// grpc::Status → absl::Status mapping, shared by rve_cli and tests so that
// every client talks to a server the same way.
#ifndef RVEHUB_RVE_SERVER_CLIENT_CHANNEL_H_
#define RVEHUB_RVE_SERVER_CLIENT_CHANNEL_H_

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::client {

struct ClientOptions {
  std::string token;       // bearer token; empty: no authorization metadata
  std::string tls_ca_pem;  // CA certificate(s) to verify the server; empty: plaintext
  // Largest message sent or received, bytes (the server's limit is the same
  // by default; an export chunk or element-test result may be large).
  // Non-positive: unlimited.
  std::int64_t max_message_bytes = 64 << 20;
};

// A channel to `target` ("HOST:PORT"): TLS verified against tls_ca_pem when
// it is set, else plaintext, with the message size limits of `options`.
// Connection happens lazily on the first call.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, const ClientOptions& options);

// Readies `ctx` for one call: "authorization: Bearer <token>" metadata when a
// token is set, and a deadline `deadline` from now (none when non-positive).
// A ClientContext serves one call only, so this is called per call.
void Prepare(grpc::ClientContext& ctx, const ClientOptions& options,
             std::chrono::milliseconds deadline);

// grpc::Status → absl::Status: the codes are numbered alike, the message is
// kept.
absl::Status FromGrpc(const grpc::Status& status);

// Options from files: the token file's contents without surrounding
// whitespace (empty is an error) and the PEM CA file as is. An empty path
// leaves that option unset. NotFound / PermissionDenied when a file cannot be
// read, InvalidArgument for an empty one.
absl::StatusOr<ClientOptions> ClientOptionsFromFiles(const std::string& token_file,
                                                     const std::string& tls_ca_file);

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_CHANNEL_H_
