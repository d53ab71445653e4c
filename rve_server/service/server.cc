#include "rve_server/service/server.h"

#include <fcntl.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/impl/codegen/method_handler.h>
#include <grpcpp/impl/codegen/rpc_service_method.h>
#include <grpcpp/support/server_interceptor.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string_view>
#include <thread>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/synchronization/notification.h"
#include "rve_server/common/address.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "rve_server/service/log.h"
#include "store/checkpoint.h"

namespace rvehub::service {
namespace {

constexpr char kRvesFile[] = "rves.h5";
constexpr char kTemplatesFile[] = "templates.h5";
constexpr char kLockFile[] = "rve_server.lock";

// Guards every method, grpc's own health and reflection services included:
// without the token the reply is replaced by an empty message and the status
// by UNAUTHENTICATED. (Our service also refuses such calls before doing
// anything; grpc's services only read, so replacing their reply suffices.)
// A denied health Watch would otherwise stay open, sending empty messages,
// and never end with that status: its request is replaced by bytes that do
// not parse, so that grpc's health service ends the call at once (with
// INVALID_ARGUMENT, which becomes UNAUTHENTICATED here like any status of a
// denied call) before it watches anything.
// Also turns gRPC's INTERNAL for a request that does not parse into
// INVALID_ARGUMENT: bad input is the client's error, not the server's.
class AuthInterceptor final : public grpc::experimental::Interceptor {
 public:
  AuthInterceptor(grpc::experimental::ServerRpcInfo* info, const std::string* token,
                  bool open_health)
      : info_(info), token_(token), open_health_(open_health) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    using grpc::experimental::InterceptionHookPoints;
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      denied_ = !Authorized(*methods->GetRecvInitialMetadata(), *token_) &&
                !(open_health_ &&
                  std::string_view(info_->method()).starts_with("/grpc.health.v1.Health/"));
      // Only Watch: our own streaming methods refuse with UNAUTHENTICATED.
      denied_watch_ = denied_ && std::string_view(info_->method()) == kHealthWatch;
    }
    if (denied_watch_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE)) {
      // grpc's health service reads its requests as raw bytes (a ByteBuffer):
      // field 1 with wire type 7, which no protobuf parser accepts.
      if (auto* request = static_cast<grpc::ByteBuffer*>(methods->GetRecvMessage())) {
        grpc::Slice unparseable(std::string("\x0f"));
        *request = grpc::ByteBuffer(&unparseable, 1);
      } else if (info_->server_context() != nullptr) {
        info_->server_context()->TryCancel();  // no request to spoil: end it anyhow
      }
    }
    // Only a request read before the handler runs (unary, server streaming):
    // a client stream's end also reads no message.
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE) &&
        methods->GetRecvMessage() == nullptr &&
        (info_->type() == grpc::experimental::ServerRpcInfo::Type::UNARY ||
         info_->type() == grpc::experimental::ServerRpcInfo::Type::SERVER_STREAMING)) {
      unparsed_ = true;
    }
    if (!denied_ && unparsed_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS) &&
        methods->GetSendStatus().error_code() == grpc::StatusCode::INTERNAL) {
      methods->ModifySendStatus(grpc::Status(
          grpc::StatusCode::INVALID_ARGUMENT,
          absl::StrCat(info_->method(), ": the request is not a valid message of its type")));
    }
    if (denied_ && methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_MESSAGE)) {
      grpc::ByteBuffer* buffer = methods->GetSerializedSendMessage();
      if (buffer != nullptr) {
        grpc::Slice empty("");
        *buffer = grpc::ByteBuffer(&empty, 1);
      }
    }
    if (denied_ && methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      methods->ModifySendStatus(grpc::Status(
          grpc::StatusCode::UNAUTHENTICATED,
          absl::StrCat(info_->method(), " needs \"authorization: Bearer <token>\" metadata")));
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  const std::string* token_;
  const bool open_health_;
  static constexpr std::string_view kHealthWatch = "/grpc.health.v1.Health/Watch";

  bool denied_ = false;
  bool denied_watch_ = false;  // a health Watch without the token
  bool unparsed_ = false;      // the request message did not parse
};

class AuthInterceptorFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  AuthInterceptorFactory(std::string token, bool open_health)
      : token_(std::move(token)), open_health_(open_health) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override {
    return new AuthInterceptor(info, &token_, open_health_);
  }

 private:
  const std::string token_;
  const bool open_health_;
};

// grpc.reflection.v1, which current tools ask for first. This gRPC (1.51)
// ships only v1alpha (libgrpc++_reflection exports no v1 symbols), and the
// two protocols' messages are the same on the wire (same fields, same
// numbers), so each v1 stream is forwarded, bytes as they are, to the
// v1alpha service over the server's in-process channel (with the caller's
// token, which the interceptor checks there too).
class ReflectionV1Proxy final : public grpc::Service {
 public:
  ReflectionV1Proxy() {
    using Handler =
        grpc::internal::BidiStreamingHandler<ReflectionV1Proxy, grpc::ByteBuffer, grpc::ByteBuffer>;
    AddMethod(new grpc::internal::RpcServiceMethod(
        "/grpc.reflection.v1.ServerReflection/ServerReflectionInfo",
        grpc::internal::RpcMethod::BIDI_STREAMING,
        new Handler(
            [](ReflectionV1Proxy* self, grpc::ServerContext* ctx,
               grpc::ServerReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>* stream) {
              return self->Forward(ctx, stream);
            },
            this)));
  }
  void set_server(grpc::Server* server) { server_.store(server); }

 private:
  grpc::Status Forward(grpc::ServerContext* ctx,
                       grpc::ServerReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>* stream) {
    grpc::Server* server = server_.load();
    if (server == nullptr) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "starting up");
    std::shared_ptr<grpc::Channel> channel = server->InProcessChannel(grpc::ChannelArguments());
    grpc::ClientContext upstream_ctx;
    upstream_ctx.set_deadline(ctx->deadline());
    auto auth = ctx->client_metadata().find("authorization");
    if (auth != ctx->client_metadata().end()) {
      upstream_ctx.AddMetadata("authorization",
                               std::string(auth->second.data(), auth->second.size()));
    }
    std::unique_ptr<grpc::ClientReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>> upstream(
        grpc::internal::ClientReaderWriterFactory<grpc::ByteBuffer, grpc::ByteBuffer>::Create(
            channel.get(),
            grpc::internal::RpcMethod(
                "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                grpc::internal::RpcMethod::BIDI_STREAMING),
            &upstream_ctx));
    // The reflection protocol answers each request with one response.
    grpc::ByteBuffer request, response;
    while (stream->Read(&request)) {
      if (!upstream->Write(request) || !upstream->Read(&response)) break;
      if (!stream->Write(response)) break;
    }
    upstream->WritesDone();
    return upstream->Finish();
  }

  std::atomic<grpc::Server*> server_{nullptr};
};

// `dir` made if need be: PermissionDenied naming it where it cannot be made
// or written into (a file of that name, /dev/null, a read-only place).
absl::Status MakeCheckpointDir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (!ec && ::access(dir.c_str(), W_OK | X_OK) != 0) {
    ec = std::error_code(errno, std::generic_category());
  }
  if (ec) {
    return absl::PermissionDeniedError(
        absl::StrCat("cannot create checkpoint directory ", dir, ": ", ec.message()));
  }
  return absl::OkStatus();
}

// Locks `dir` for this server (an exclusive flock on its rve_server.lock,
// which then holds this process's pid) and returns the lock file's
// descriptor: two servers on one directory would each save their RVEs at
// their stop, the later one silently replacing the other's. The kernel
// drops the lock when the process ends, however it ends, so a crashed
// server leaves no stale lock. FailedPrecondition naming the directory and
// the holder's pid while another server (or process) holds it.
absl::StatusOr<int> LockCheckpointDir(const std::string& dir) {
  const std::string path = (std::filesystem::path(dir) / kLockFile).string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    return absl::PermissionDeniedError(absl::StrCat("cannot open the lock file ", path,
                                                    " of checkpoint directory ", dir, ": ",
                                                    std::strerror(errno)));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    // The holder writes its pid once it holds the lock: none yet is possible.
    char text[32] = {};
    const ssize_t n = ::pread(fd, text, sizeof text - 1, 0);
    int holder = 0;
    const bool known = n > 0 && absl::SimpleAtoi(absl::StripAsciiWhitespace(text), &holder);
    ::close(fd);
    if (error != EWOULDBLOCK) {
      return absl::UnavailableError(absl::StrCat("cannot lock checkpoint directory ", dir, " (",
                                                 path, "): ", std::strerror(error)));
    }
    return absl::FailedPreconditionError(
        absl::StrCat("checkpoint directory ", dir, " is held by another rve_server",
                     known ? absl::StrCat(" (pid ", holder, ")") : "",
                     ", which saves its RVEs there (lock file ", path,
                     "); give each server a checkpoint directory of its own"));
  }
  const std::string pid = absl::StrCat(::getpid(), "\n");
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    const int error = errno;
    ::close(fd);
    return absl::PermissionDeniedError(
        absl::StrCat("cannot write the lock file ", path, ": ", std::strerror(error)));
  }
  return fd;
}

std::string NowUtc() {
  return absl::FormatTime("%Y-%m-%dT%H:%M:%SZ", absl::Now(), absl::UTCTimeZone());
}

}  // namespace

absl::StatusOr<std::unique_ptr<RveServer>> RveServer::Start(const ServerConfig& config) {
  RETURN_IF_ERROR(ValidateAddress("listen address", config.listen, PortZero::kAllowed));
  if (config.registry.threads < 1 || config.registry.threads > kMaxThreads) {
    return absl::InvalidArgumentError(
        absl::StrCat("threads = ", config.registry.threads, " must lie in 1..", kMaxThreads));
  }
  if (config.registry.max_rves < 1 || config.registry.max_memory_bytes < 1 ||
      config.registry.max_batch < 1 || config.registry.max_templates < 1 ||
      config.max_message_bytes < (1 << 20) ||
      config.max_message_bytes > std::numeric_limits<int>::max()) {
    return absl::InvalidArgumentError(
        "max RVEs, max memory, max batch and max templates must be >= 1 and the max message "
        "size between 1 MiB and 2 GiB - 1 byte (gRPC's limit)");
  }
  if (config.tls_cert_pem.empty() != config.tls_key_pem.empty()) {
    return absl::InvalidArgumentError("TLS needs both a certificate and a key");
  }
  std::unique_ptr<RveServer> s(new RveServer());
  s->config_ = config;
  s->registry_ = std::make_unique<Registry>(config.registry);
  if (!config.checkpoint_dir.empty()) {
    // Made now, so that a directory that cannot be is found at start, not
    // at the stop that was to save every RVE into it.
    RETURN_IF_ERROR(MakeCheckpointDir(config.checkpoint_dir));
    ASSIGN_OR_RETURN(s->checkpoint_lock_fd_, LockCheckpointDir(config.checkpoint_dir));
    RETURN_IF_ERROR(s->LoadCheckpoint(config.checkpoint_dir));
  }
  ServiceOptions options;
  options.version = kServerVersion;
  options.auth_token = config.auth_token;
  options.tls = !config.tls_cert_pem.empty();
  options.max_message_bytes = config.max_message_bytes;
  s->service_ = std::make_unique<RveServiceImpl>(*s->registry_, options);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (options.tls) {
    grpc::SslServerCredentialsOptions ssl;
    ssl.pem_key_cert_pairs.push_back({config.tls_key_pem, config.tls_cert_pem});
    creds = grpc::SslServerCredentials(ssl);
  } else {
    creds = grpc::InsecureServerCredentials();
  }
  builder.AddListeningPort(config.listen, creds, &s->port_);
  builder.RegisterService(s->service_.get());
  auto reflection_v1 = std::make_unique<ReflectionV1Proxy>();
  ReflectionV1Proxy* reflection_v1_proxy = reflection_v1.get();
  s->reflection_v1_ = std::move(reflection_v1);  // outlives the server (member order)
  builder.RegisterService(reflection_v1_proxy);
  builder.SetMaxReceiveMessageSize(static_cast<int>(config.max_message_bytes));
  builder.SetMaxSendMessageSize(static_cast<int>(config.max_message_bytes));
  {  // also without a token: it maps unparseable requests (see AuthInterceptor)
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> f;
    f.push_back(
        std::make_unique<AuthInterceptorFactory>(config.auth_token, config.health_without_token));
    builder.experimental().SetInterceptorCreators(std::move(f));
  }
  s->server_ = builder.BuildAndStart();
  if (s->server_ == nullptr || s->port_ == 0) {
    return absl::UnavailableError(
        absl::StrCat("cannot listen on ", config.listen, " (address in use or not local?)"));
  }
  reflection_v1_proxy->set_server(s->server_.get());
  // Health by service name too, so that probes may ask for ours.
  s->server_->GetHealthCheckService()->SetServingStatus(v1::RveService::service_full_name(), true);
  s->server_->GetHealthCheckService()->SetServingStatus(true);
  const RegistryStats stats = s->registry_->Stats();
  Log("info", "listening",
      {{"address", s->address()},
       {"threads", absl::StrCat(config.registry.threads)},
       {"tls", options.tls ? "on" : "off"},
       {"auth", config.auth_token.empty() ? "off" : "on"},
       {"rves", absl::StrCat(stats.num_rves)},
       {"templates", absl::StrCat(stats.num_templates)},
       {"version", kServerVersion}});
  return s;
}

std::string RveServer::address() const {
  const std::string& l = config_.listen;
  const std::size_t colon = l.rfind(':');
  return absl::StrCat(l.substr(0, colon), ":", port_);
}

RveServer::~RveServer() {
  if (server_ != nullptr && !stopped_) {
    server_->Shutdown(std::chrono::system_clock::now());
    server_->Wait();
  }
  if (checkpoint_lock_fd_ >= 0) ::close(checkpoint_lock_fd_);  // releases the lock
}

absl::Status RveServer::Stop(std::chrono::milliseconds grace) {
  if (stopped_) return absl::OkStatus();
  stopped_ = true;
  Log("info", "draining", {{"grace_ms", absl::StrCat(grace.count())}});
  server_->GetHealthCheckService()->SetServingStatus(false);
  // gRPC cancels the calls still running when the grace ends; calls busy in
  // the engine also stop at their next check (CancelAll), so that the drain
  // ends about when the grace does.
  absl::Notification drained;
  std::thread enforcer([&] {
    if (!drained.WaitForNotificationWithTimeout(absl::FromChrono(grace))) service_->CancelAll();
  });
  server_->Shutdown(std::chrono::system_clock::now() + grace);
  server_->Wait();
  drained.Notify();
  enforcer.join();
  const RegistryStats stats = registry_->Stats();
  if (config_.checkpoint_dir.empty()) {
    // Nothing is saved: say so, with what is lost.
    Log(stats.num_rves > 0 || stats.num_templates > 0 ? "warn" : "info", "stopped",
        {{"checkpoint", "none (no checkpoint directory)"},
         {"dropped_rves", absl::StrCat(stats.num_rves)},
         {"dropped_templates", absl::StrCat(stats.num_templates)}});
    return absl::OkStatus();
  }
  const absl::Status saved = SaveCheckpoint(config_.checkpoint_dir);
  Log(saved.ok() ? "info" : "error", "stopped",
      {{"checkpoint", saved.ok() ? absl::StrCat("saved to ", config_.checkpoint_dir)
                                 : std::string(saved.message())},
       {"rves", absl::StrCat(stats.num_rves)},
       {"templates", absl::StrCat(stats.num_templates)}});
  return saved;
}

void RveServer::Wait() { server_->Wait(); }

absl::Status RveServer::SaveCheckpoint(const std::string& dir) {
  RETURN_IF_ERROR(MakeCheckpointDir(dir));
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<RveRecord> rves;
  absl::Status s = registry_->ExportAll([&](RveRecord&& r) {
    rves.push_back(std::move(r));
    return absl::OkStatus();
  });
  if (!s.ok()) return s;
  const store::FileInfo info{absl::StrCat("rve_server ", kServerVersion), NowUtc(), 0};
  if (s = store::WriteRves((std::filesystem::path(dir) / kRvesFile).string(), rves, info);
      !s.ok()) {
    return s;
  }
  const std::vector<TemplateRecord> templates = registry_->AllTemplates();
  if (s = store::WriteTemplates((std::filesystem::path(dir) / kTemplatesFile).string(), templates,
                                info);
      !s.ok()) {
    return s;
  }
  Log("info", "checkpoint written",
      {{"dir", dir},
       {"rves", absl::StrCat(rves.size())},
       {"templates", absl::StrCat(templates.size())},
       {"seconds",
        absl::StrCat(
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count())}});
  return absl::OkStatus();
}

absl::Status RveServer::LoadCheckpoint(const std::string& dir) {
  const std::string templates_path = (std::filesystem::path(dir) / kTemplatesFile).string();
  const std::string rves_path = (std::filesystem::path(dir) / kRvesFile).string();
  // What a write killed mid-way (kill -9, power loss) left: the checkpoint
  // itself is the previous one, whole (written aside, then renamed).
  store::RemoveStaleTemporaries(templates_path, /*own_too=*/true);
  store::RemoveStaleTemporaries(rves_path, /*own_too=*/true);
  std::int64_t num_templates = 0, num_rves = 0;
  ASSIGN_OR_RETURN(const bool templates_exist, PathExists(templates_path));
  ASSIGN_OR_RETURN(const bool rves_exist, PathExists(rves_path));
  if (templates_exist) {
    ASSIGN_OR_RETURN(std::vector<TemplateRecord> t, store::ReadTemplates(templates_path));
    for (TemplateRecord& r : t) {
      const std::string name = r.name;
      if (absl::StatusOr<TemplateInfo> put = registry_->PutTemplate(std::move(r), true);
          !put.ok()) {
        return absl::Status(put.status().code(),
                            absl::StrCat("restoring ", templates_path, ": template ",
                                         QuotedName(name), ": ", put.status().message()));
      }
      ++num_templates;
    }
  }
  if (rves_exist) {
    ASSIGN_OR_RETURN(std::vector<RveRecord> r, store::ReadRves(rves_path));
    if (!r.empty()) {
      absl::StatusOr<std::int64_t> n = registry_->Import(std::move(r));
      if (!n.ok()) {
        return absl::Status(n.status().code(),
                            absl::StrCat("restoring ", rves_path, ": ", n.status().message()));
      }
      num_rves = *n;
    }
  }
  Log("info", "checkpoint loaded",
      {{"dir", dir}, {"rves", absl::StrCat(num_rves)}, {"templates", absl::StrCat(num_templates)}});
  return absl::OkStatus();
}

}  // namespace rvehub::service
