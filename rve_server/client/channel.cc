#include "rve_server/client/channel.h"

#include <algorithm>
#include <climits>

#include "absl/strings/str_cat.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"

namespace rvehub::client {

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target,
                                           const ClientOptions& options) {
  grpc::ChannelArguments args;
  // gRPC's default receive limit (4 MiB) is far below an export chunk.
  const int limit =
      options.max_message_bytes <= 0
          ? -1
          : static_cast<int>(std::min<std::int64_t>(options.max_message_bytes, INT_MAX));
  args.SetMaxReceiveMessageSize(limit);
  args.SetMaxSendMessageSize(limit);
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.tls_ca_pem.empty()) {
    credentials = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = options.tls_ca_pem;
    credentials = grpc::SslCredentials(ssl);
  }
  return grpc::CreateCustomChannel(target, credentials, args);
}

void Prepare(grpc::ClientContext& ctx, const ClientOptions& options,
             std::chrono::milliseconds deadline) {
  // Plain metadata rather than call credentials: gRPC refuses call
  // credentials on plaintext channels, and a token over plaintext on a
  // trusted network (or a loopback port) is a supported setup.
  if (!options.token.empty())
    ctx.AddMetadata("authorization", absl::StrCat("Bearer ", options.token));
  if (deadline.count() > 0) ctx.set_deadline(std::chrono::system_clock::now() + deadline);
}

absl::Status FromGrpc(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

absl::StatusOr<ClientOptions> ClientOptionsFromFiles(const std::string& token_file,
                                                     const std::string& tls_ca_file) {
  ClientOptions options;
  if (!token_file.empty()) {
    ASSIGN_OR_RETURN(std::string token, ReadTokenFile(token_file));
    options.token = std::move(token);
  }
  if (!tls_ca_file.empty()) {
    ASSIGN_OR_RETURN(std::string pem, ReadTextFile(tls_ca_file, "TLS CA file"));
    if (pem.empty()) {
      return absl::InvalidArgumentError(absl::StrCat("TLS CA file '", tls_ca_file, "' is empty"));
    }
    options.tls_ca_pem = std::move(pem);
  }
  return options;
}

}  // namespace rvehub::client
