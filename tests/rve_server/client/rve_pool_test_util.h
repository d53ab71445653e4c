// Set-ups the RVE pool tests share: templates and increments, embedded and
// loopback endpoints, an endpoint that fails on purpose, and comparisons.
#ifndef RVEHUB_TESTS_RVE_SERVER_CLIENT_RVE_POOL_TEST_UTIL_H_
#define RVEHUB_TESTS_RVE_SERVER_CLIENT_RVE_POOL_TEST_UTIL_H_

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/client/rve_pool.h"
#include "rve_server/embedded/endpoint.h"
#include "rve_server/service/log.h"
#include "rve_server/service/server.h"
#include "tests/support/test_util.h"

namespace rvehub::client::pool_test {

using dem::testing_util::ExpectIdenticalPackings;
using dem::testing_util::ExpectIdenticalStates;
using dem::testing_util::Prepared;
using dem::testing_util::SameBits;

// Expects `message` to contain `words`.
inline void ExpectContains(absl::string_view message, absl::string_view words) {
  EXPECT_NE(message.find(words), absl::string_view::npos)
      << "\"" << message << "\" lacks \"" << words << "\"";
}

// An idle gRPC client channel reads its socket only from its backup poller
// (every 5 s by default), which would make each server stop here take 5 s.
inline const bool kFastClientPolling = [] {
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);
  return true;
}();

inline constexpr int kPoints = 6;
inline constexpr char kRun[] = "pool-run";

// SET-dense (400 discs) with few DEM steps per increment, under two names
// (the second with other controls) so that one endpoint needs a Create per
// template.
inline std::vector<TemplateRecord> Templates() {
  dem::RveSnapshot p = Prepared("SET-dense");
  p.controls.min_steps = 10;
  std::vector<TemplateRecord> t = {{"set-dense", "SET-dense seed 1, min_steps 10", p}};
  p.controls.min_steps = 12;
  t.push_back({"set-dense-12", "SET-dense seed 1, min_steps 12", p});
  return t;
}

inline std::vector<std::string> TemplatePerPoint() {
  std::vector<std::string> names;
  for (int p = 0; p < kPoints; ++p) names.push_back(p % 3 == 0 ? "set-dense-12" : "set-dense");
  return names;
}

// ΔF of point p at a step: axial compression 1e-4, a little shear and, every
// other step, a small rigid rotation. Plane strain, [-].
inline Eigen::Matrix3d DeltaF(int p, std::int64_t step) {
  Eigen::Matrix3d v = Eigen::Matrix3d::Identity();
  v(1, 1) = 1 - 1e-4;
  v(0, 1) = 2e-5 * (p % 3);
  const double theta = 5e-5 * static_cast<double>((p + step) % 2);  // rad
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r(0, 0) = std::cos(theta);
  r(0, 1) = -std::sin(theta);
  r(1, 0) = std::sin(theta);
  r(1, 1) = std::cos(theta);
  return r * v;
}

inline std::vector<Eigen::Matrix3d> DeltaFs(std::int64_t step) {
  std::vector<Eigen::Matrix3d> f;
  for (int p = 0; p < kPoints; ++p) f.push_back(DeltaF(p, step));
  return f;
}

inline std::shared_ptr<service::Registry> NewRegistry() {
  service::RegistryOptions o;
  o.threads = 1;
  return std::make_shared<service::Registry>(o);
}

// RVE servers on loopback ports.
class Servers {
 public:
  explicit Servers(int n) {
    service::SetLogEnabled(false);
    for (int k = 0; k < n; ++k) {
      service::ServerConfig config;
      config.listen = "127.0.0.1:0";
      config.registry.threads = 1;
      absl::StatusOr<std::unique_ptr<service::RveServer>> s = service::RveServer::Start(config);
      EXPECT_TRUE(s.ok()) << s.status();
      if (s.ok()) servers_.push_back(*std::move(s));
    }
  }
  ~Servers() {
    for (auto& s : servers_) EXPECT_TRUE(s->Stop(std::chrono::milliseconds(500)).ok());
  }
  int size() const { return static_cast<int>(servers_.size()); }
  std::string address(int k) const { return servers_[k]->address(); }

 private:
  std::vector<std::unique_ptr<service::RveServer>> servers_;
};

inline std::unique_ptr<RveEndpoint> Remote(const std::string& address,
                                           const RemoteOptions& remote = {}) {
  absl::StatusOr<std::unique_ptr<RveEndpoint>> e = RemoteServer::Connect(address, {}, remote);
  EXPECT_TRUE(e.ok()) << e.status();
  return e.ok() ? *std::move(e) : nullptr;
}

inline std::vector<std::unique_ptr<RveEndpoint>> RemoteEndpoints(const Servers& servers,
                                                                 const RemoteOptions& remote = {}) {
  std::vector<std::unique_ptr<RveEndpoint>> e;
  for (int k = 0; k < servers.size(); ++k) e.push_back(Remote(servers.address(k), remote));
  return e;
}

inline std::vector<std::unique_ptr<RveEndpoint>> EmbeddedEndpoints(int n) {
  std::vector<std::unique_ptr<RveEndpoint>> e;
  for (int k = 0; k < n; ++k) e.push_back(embedded::MakeEndpoint(NewRegistry()));
  return e;
}

inline PoolOptions QuickRetries() {
  PoolOptions o;
  o.backoff = absl::Milliseconds(1);
  return o;
}

// Uploads the templates and creates the points (equal costs).
inline void Start(RvePool& pool) {
  const std::vector<TemplateRecord> templates = Templates();
  ASSERT_TRUE(pool.UploadTemplates(templates).ok());
  const std::vector<std::string> names = TemplatePerPoint();
  absl::StatusOr<std::vector<dem::RveState>> created = pool.Create(names);
  ASSERT_TRUE(created.ok()) << created.status();
  ASSERT_EQ(created->size(), static_cast<std::size_t>(kPoints));
}

inline std::vector<dem::RveState> ApplyOrDie(RvePool& pool, std::int64_t step) {
  absl::StatusOr<std::vector<dem::RveState>> s = pool.Apply(step, DeltaFs(step));
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *std::move(s) : std::vector<dem::RveState>{};
}

inline void ExpectSameStates(const std::vector<dem::RveState>& a,
                             const std::vector<dem::RveState>& b, const std::string& where) {
  ASSERT_EQ(a.size(), b.size()) << where;
  for (std::size_t p = 0; p < a.size(); ++p)
    ExpectIdenticalStates(a[p], b[p], absl::StrCat(where, ", point ", p));
}

inline void ExpectSameRecords(const std::vector<RveRecord>& a, const std::vector<RveRecord>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].id, static_cast<std::int64_t>(k));
    EXPECT_EQ(a[k].id, b[k].id);
    EXPECT_EQ(a[k].step, b[k].step);
    EXPECT_TRUE(SameBits(a[k].last_delta_f, b[k].last_delta_f)) << "record " << k;
    ExpectIdenticalPackings(a[k].packing, b[k].packing, absl::StrCat("record ", k));
  }
}

// A port on 127.0.0.1 nobody listens on (bound, read, closed).
inline int ClosedPort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  socklen_t len = sizeof(addr);
  EXPECT_EQ(getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  close(fd);
  return ntohs(addr.sin_port);
}

// A finished Apply with a given result.
class DoneApply final : public PendingApply {
 public:
  explicit DoneApply(absl::StatusOr<std::vector<RveOutcome>> r) : r_(std::move(r)) {}
  absl::StatusOr<std::vector<RveOutcome>> Finish() override { return std::move(r_); }
  double seconds() const override { return 0.0; }

 private:
  absl::StatusOr<std::vector<RveOutcome>> r_;
};

inline std::unique_ptr<PendingApply> Done(absl::StatusOr<std::vector<RveOutcome>> r) {
  return std::make_unique<DoneApply>(std::move(r));
}

// Wraps an endpoint and fails Apply calls on purpose.
class FaultyEndpoint final : public RveEndpoint {
 public:
  enum class Fault {
    kNone,
    kLoseFirstReply,  // the first Apply commits, then its reply is "lost"
    kAlwaysUnavailable,
    kRefuse,  // InvalidArgument, as for a malformed request
  };
  FaultyEndpoint(std::unique_ptr<RveEndpoint> inner, Fault fault)
      : inner_(std::move(inner)), fault_(fault) {}

  int apply_calls() const { return apply_calls_; }
  // The last SetCallTimeout's and SetCreateTimeout's (infinite before any).
  absl::Duration call_timeout() const { return call_timeout_; }
  absl::Duration create_timeout() const { return create_timeout_; }

  std::string name() const override { return "faulty"; }
  std::string label() const override { return "faulty endpoint"; }
  int workers() const override { return inner_->workers(); }
  absl::Status PutTemplate(const TemplateRecord& r) override { return inner_->PutTemplate(r); }
  absl::StatusOr<std::vector<RveOutcome>> Create(
      absl::string_view run, absl::string_view t, std::span<const std::int64_t> ids,
      std::span<const InitialStress> initial,
      const std::optional<dem::Controls>& controls) override {
    return inner_->Create(run, t, ids, initial, controls);
  }
  std::unique_ptr<PendingApply> StartApply(absl::string_view run, std::int64_t step, ApplyMode mode,
                                           std::span<const Increment> increments,
                                           const dem::ApplyOptions& options,
                                           absl::Duration deadline) override {
    const int call = ++apply_calls_;
    switch (fault_) {
      case Fault::kNone:
        return inner_->StartApply(run, step, mode, increments, options, deadline);
      case Fault::kLoseFirstReply: {
        absl::StatusOr<std::vector<RveOutcome>> r =
            inner_->Apply(run, step, mode, increments, options, deadline);
        if (call == 1) return Done(absl::UnavailableError("connection reset by peer"));
        return Done(std::move(r));
      }
      case Fault::kAlwaysUnavailable:
        return Done(absl::UnavailableError("connection refused"));
      case Fault::kRefuse:
        return Done(absl::InvalidArgumentError("malformed request"));
    }
    return Done(absl::InternalError("unreachable"));
  }
  absl::StatusOr<std::vector<RveOutcome>> Get(absl::string_view run,
                                              std::span<const std::int64_t> ids,
                                              bool want_tangent) override {
    return inner_->Get(run, ids, want_tangent);
  }
  absl::Status Export(absl::string_view run, std::span<const std::int64_t> ids,
                      const RecordSink& sink) override {
    return inner_->Export(run, ids, sink);
  }
  absl::Status Import(std::vector<RveRecord> records) override {
    return inner_->Import(std::move(records));
  }
  absl::Status Drop(absl::string_view run, std::span<const std::int64_t> ids) override {
    return inner_->Drop(run, ids);
  }
  absl::Status Ping(absl::Duration timeout) override { return inner_->Ping(timeout); }
  void SetCallTimeout(absl::Duration timeout) override { call_timeout_ = timeout; }
  void SetCreateTimeout(absl::Duration timeout) override { create_timeout_ = timeout; }

 private:
  std::unique_ptr<RveEndpoint> inner_;
  const Fault fault_;
  std::atomic<int> apply_calls_{0};
  absl::Duration call_timeout_ = absl::InfiniteDuration();
  absl::Duration create_timeout_ = absl::InfiniteDuration();
};

}  // namespace rvehub::client::pool_test

#endif  // RVEHUB_TESTS_RVE_SERVER_CLIENT_RVE_POOL_TEST_UTIL_H_
