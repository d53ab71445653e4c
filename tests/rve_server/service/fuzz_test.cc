// A bounded fuzz run of every RPC against a loopback server: random and
// mutated protobuf messages and raw bytes, from a fixed seed. Every call
// must end with a status other than UNKNOWN or INTERNAL (bad input is the
// client's error), and the server must answer health and a valid request
// afterwards.
//
// The default run is short (4000 calls, about 10 s on two
// cores). For release checks run a longer one, e.g.
//   RVEHUB_FUZZ_ITERATIONS=100000 RVEHUB_FUZZ_SEED=7 build/tests/fuzz_test
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"
#include "google/protobuf/reflection.h"
#include "health_probe.grpc.pb.h"
#include "tests/rve_server/service/service_harness.h"
#include "tests/support/env_util.h"

namespace rvehub::service::testing {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

using rvehub::testing_env::EnvInt;

class Fuzzer {
 public:
  explicit Fuzzer(std::uint64_t seed) : rng_(seed) {}

  std::uint64_t Next() { return rng_(); }
  bool Chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  std::size_t Below(std::size_t n) { return n == 0 ? 0 : rng_() % n; }

  double Double() {
    static const double kSpecial[] = {0.0,
                                      -0.0,
                                      1.0,
                                      -1.0,
                                      1e-300,
                                      1e300,
                                      -1e300,
                                      1e24,
                                      1e-42,
                                      0.5,
                                      1e-4,
                                      std::numeric_limits<double>::infinity(),
                                      -std::numeric_limits<double>::infinity(),
                                      std::numeric_limits<double>::quiet_NaN(),
                                      std::numeric_limits<double>::denorm_min(),
                                      std::numeric_limits<double>::max()};
    if (Chance(0.5)) return kSpecial[Below(std::size(kSpecial))];
    return std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng_),
                      static_cast<int>(Below(80)) - 40);
  }

  std::int64_t Int() {
    static const std::int64_t kSpecial[] = {0,
                                            1,
                                            -1,
                                            2,
                                            1'000'000'000'000,
                                            std::int64_t{1} << 62,
                                            std::numeric_limits<std::int64_t>::max(),
                                            std::numeric_limits<std::int64_t>::min()};
    if (Chance(0.6)) return kSpecial[Below(std::size(kSpecial))];
    return static_cast<std::int64_t>(rng_() >> Below(64));
  }

  std::string String() {
    static const std::string kNames[] = {"f", "r", kTemplate, "", "..", "a b", "x\n"};
    if (Chance(0.5)) return kNames[Below(std::size(kNames))];
    std::string s(Chance(0.1) ? 300 + Below(2000) : Below(40), 'a');
    for (char& c : s) c = static_cast<char>(Chance(0.9) ? 'a' + Below(26) : Below(256));
    return s;
  }

  // Sets random fields of `m` (sub-messages to `depth`).
  void Randomise(Message* m, int depth) {
    const auto* d = m->GetDescriptor();
    const auto* r = m->GetReflection();
    for (int k = 0; k < d->field_count(); ++k) {
      const FieldDescriptor* f = d->field(k);
      if (!Chance(0.4)) continue;
      const int count = f->is_repeated() ? static_cast<int>(Chance(0.1) ? Below(40) : Below(4)) : 1;
      for (int n = 0; n < count; ++n) SetOne(m, r, f, depth);
    }
  }

  // Byte-level mutations of a serialised message.
  std::string Mutate(std::string s) {
    const int edits = 1 + static_cast<int>(Below(4));
    for (int e = 0; e < edits; ++e) {
      switch (Below(5)) {
        case 0:
          if (!s.empty()) s[Below(s.size())] = static_cast<char>(Next());
          break;
        case 1:
          if (!s.empty()) s.resize(Below(s.size()));
          break;
        case 2:
          s.insert(Below(s.size() + 1), std::string(1 + Below(8), static_cast<char>(Next())));
          break;
        case 3:
          if (!s.empty()) {
            const std::size_t at = Below(s.size());
            s += s.substr(at, Below(64));  // repeated fields grow, fields repeat
          }
          break;
        default:
          if (!s.empty()) s.erase(Below(s.size()), 1 + Below(8));
          break;
      }
    }
    return s;
  }

  std::string RawBytes() {
    std::string s(Below(200), '\0');
    for (char& c : s) c = static_cast<char>(Next());
    return s;
  }

 private:
  void SetOne(Message* m, const google::protobuf::Reflection* r, const FieldDescriptor* f,
              int depth) {
    const bool rep = f->is_repeated();
    switch (f->cpp_type()) {
      case FieldDescriptor::CPPTYPE_DOUBLE:
        rep ? r->AddDouble(m, f, Double()) : r->SetDouble(m, f, Double());
        break;
      case FieldDescriptor::CPPTYPE_FLOAT:
        rep ? r->AddFloat(m, f, static_cast<float>(Double()))
            : r->SetFloat(m, f, static_cast<float>(Double()));
        break;
      case FieldDescriptor::CPPTYPE_INT64:
        rep ? r->AddInt64(m, f, Int()) : r->SetInt64(m, f, Int());
        break;
      case FieldDescriptor::CPPTYPE_UINT64:
        rep ? r->AddUInt64(m, f, static_cast<std::uint64_t>(Int()))
            : r->SetUInt64(m, f, static_cast<std::uint64_t>(Int()));
        break;
      case FieldDescriptor::CPPTYPE_INT32:
        rep ? r->AddInt32(m, f, static_cast<std::int32_t>(Int()))
            : r->SetInt32(m, f, static_cast<std::int32_t>(Int()));
        break;
      case FieldDescriptor::CPPTYPE_UINT32:
        rep ? r->AddUInt32(m, f, static_cast<std::uint32_t>(Int()))
            : r->SetUInt32(m, f, static_cast<std::uint32_t>(Int()));
        break;
      case FieldDescriptor::CPPTYPE_BOOL:
        rep ? r->AddBool(m, f, Chance(0.5)) : r->SetBool(m, f, Chance(0.5));
        break;
      case FieldDescriptor::CPPTYPE_ENUM:
        rep ? r->AddEnumValue(m, f, static_cast<int>(Int() % 8))
            : r->SetEnumValue(m, f, static_cast<int>(Int() % 8));
        break;
      case FieldDescriptor::CPPTYPE_STRING:
        rep ? r->AddString(m, f, String()) : r->SetString(m, f, String());
        break;
      case FieldDescriptor::CPPTYPE_MESSAGE:
        if (depth <= 0) break;
        Randomise(rep ? r->AddMessage(m, f) : r->MutableMessage(m, f), depth - 1);
        break;
    }
  }

  std::mt19937_64 rng_;
};

// One RPC of the fuzz run: its path, kind, and a valid request to mutate.
struct Rpc {
  std::string path;
  grpc::internal::RpcMethod::RpcType type;
  std::function<std::unique_ptr<Message>()> valid;
};

template <typename T>
std::function<std::unique_ptr<Message>()> Valid(std::function<void(T&)> fill) {
  return [fill] {
    auto m = std::make_unique<T>();
    fill(*m);
    return std::unique_ptr<Message>(std::move(m));
  };
}

std::vector<Rpc> AllRpcs(const v1::RveRecord& record) {
  using RT = grpc::internal::RpcMethod;
  const std::string s = "/rvehub.v1.RveService/";
  return {
      {s + "UploadTemplate", RT::NORMAL_RPC, Valid<v1::UploadTemplateRequest>([](auto& r) {
         *r.mutable_entry() = MakeTemplate();
         r.mutable_entry()->set_name("fuzzed");
         r.set_replace(true);
       })},
      {s + "ListTemplates", RT::NORMAL_RPC, Valid<v1::ListTemplatesRequest>([](auto&) {})},
      {s + "CreateRves", RT::NORMAL_RPC, Valid<v1::CreateRvesRequest>([](auto& r) {
         r.set_run_id("c");
         r.set_template_name(kTemplate);
         r.add_ids(7);
       })},
      {s + "Apply", RT::NORMAL_RPC,
       Valid<v1::ApplyRequest>([](auto& r) { r = Harness::Commit("f", 1, {0}, Compress(1e-4)); })},
      {s + "GetStates", RT::NORMAL_RPC, Valid<v1::GetStatesRequest>([](auto& r) {
         r.set_run_id("f");
         r.add_ids(1);
       })},
      {s + "Export", RT::SERVER_STREAMING, Valid<v1::ExportRequest>([](auto& r) {
         r.set_run_id("f");
         r.add_ids(2);
       })},
      {s + "Import", RT::CLIENT_STREAMING, Valid<v1::RveChunk>([record](auto& r) {
         r.set_total_records(1);
         *r.add_records() = record;
       })},
      {s + "Drop", RT::NORMAL_RPC, Valid<v1::DropRequest>([](auto& r) {
         r.set_run_id("f");
         r.add_ids(3);
       })},
      {s + "ListRuns", RT::NORMAL_RPC, Valid<v1::ListRunsRequest>([](auto&) {})},
      {s + "GetServerInfo", RT::NORMAL_RPC, Valid<v1::ServerInfoRequest>([](auto&) {})},
      {s + "RunElementTest", RT::SERVER_STREAMING, Valid<v1::ElementTestRequest>([](auto& r) {
         r.set_template_name(kTemplate);
         r.set_test(v1::ELEMENT_TEST_ISOTROPIC);
         r.set_rows(4);
         r.set_max_strain(1e-3);
       })},
      {"/grpc.health.v1.Health/Check", RT::NORMAL_RPC,
       Valid<grpc::health::v1::HealthCheckRequest>([](auto&) {})},
  };
}

// Sends `bytes` as the request (Import: as each of `bytes`), returns the status.
grpc::Status Call(grpc::Channel& channel, const Rpc& rpc, const std::vector<std::string>& bytes,
                  std::chrono::milliseconds timeout) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + timeout);
  using RT = grpc::internal::RpcMethod;
  const grpc::internal::RpcMethod method(rpc.path.c_str(), rpc.type);
  switch (rpc.type) {
    case RT::NORMAL_RPC:
      return RawUnary(channel, ctx, rpc.path, bytes.empty() ? "" : bytes[0]);
    case RT::CLIENT_STREAMING:
      return RawImport(channel, ctx, bytes);
    default: {
      grpc::Slice slice(bytes.empty() ? "" : bytes[0]);
      grpc::ByteBuffer request(&slice, 1), reply;
      std::unique_ptr<grpc::ClientReader<grpc::ByteBuffer>> reader(
          grpc::internal::ClientReaderFactory<grpc::ByteBuffer>::Create(&channel, method, &ctx,
                                                                        request));
      for (int k = 0; k < 100'000 && reader->Read(&reply); ++k) {
      }
      return reader->Finish();
    }
  }
}

TEST(Fuzz, EveryRpcSurvivesRandomAndMutatedRequests) {
  const std::int64_t iterations = EnvInt("RVEHUB_FUZZ_ITERATIONS", 4000);
  const std::uint64_t seed = static_cast<std::uint64_t>(EnvInt("RVEHUB_FUZZ_SEED", 1));
  ServerConfig config;
  config.registry.threads = 2;
  config.registry.max_batch = 64;
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("f", {0, 1, 2, 3}).ok());
  v1::RveChunk exported;
  ASSERT_TRUE(exported.ParseFromString(h.ExportBytes("f", 1)));
  v1::RveRecord record = exported.records(0);
  record.set_run_id("imported");
  const std::vector<Rpc> rpcs = AllRpcs(record);

  Fuzzer fuzz(seed);
  std::map<std::string, std::map<int, int>> codes;  // per RPC: code → count
  for (std::int64_t it = 0; it < iterations; ++it) {
    const Rpc& rpc = rpcs[fuzz.Below(rpcs.size())];
    std::vector<std::string> bytes;
    const int messages =
        rpc.type == grpc::internal::RpcMethod::CLIENT_STREAMING ? 1 + fuzz.Below(3) : 1;
    const std::size_t how = fuzz.Below(3);
    for (int m = 0; m < messages; ++m) {
      std::unique_ptr<Message> msg = rpc.valid();
      if (how == 0) {  // random field values
        fuzz.Randomise(msg.get(), 3);
        bytes.push_back(msg->SerializeAsString());
      } else if (how == 1) {  // a valid request, mutated bytes
        bytes.push_back(fuzz.Mutate(msg->SerializeAsString()));
      } else {
        bytes.push_back(fuzz.RawBytes());
      }
    }
    // An element test or a relaxation may legitimately take long: the short
    // deadline bounds the run (and exercises the server's cancellation).
    const grpc::Status s = Call(*h.channel(), rpc, bytes, std::chrono::milliseconds(1500));
    ++codes[rpc.path][s.error_code()];
    ASSERT_NE(s.error_code(), grpc::StatusCode::UNKNOWN)
        << rpc.path << " iteration " << it << ": " << s.error_message();
    ASSERT_NE(s.error_code(), grpc::StatusCode::INTERNAL)
        << rpc.path << " iteration " << it << ": " << s.error_message();
    ASSERT_NE(s.error_code(), grpc::StatusCode::UNAVAILABLE)
        << rpc.path << " iteration " << it << ": " << s.error_message();
  }
  for (const auto& [path, by_code] : codes) {
    std::string line = path + ":";
    for (const auto& [code, n] : by_code)
      line += " " + std::to_string(code) + "×" + std::to_string(n);
    std::printf("%s\n", line.c_str());
  }

  // Still alive and serving: health, and a valid commit on a fresh run.
  auto health = grpc::health::v1::Health::NewStub(h.channel());
  grpc::health::v1::HealthCheckResponse hresp;
  ASSERT_TRUE(health->Check(h.Context().get(), {}, &hresp).ok());
  EXPECT_EQ(hresp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
  ASSERT_TRUE(h.Create("after-fuzz", {1}).ok());
  v1::ApplyResponse resp;
  ASSERT_TRUE(
      h.stub()
          .Apply(h.Context().get(), Harness::Commit("after-fuzz", 1, {1}, Compress(1e-4)), &resp)
          .ok());
  EXPECT_EQ(resp.failed(), 0);
  EXPECT_EQ(resp.results(0).step(), 1);
}

}  // namespace
}  // namespace rvehub::service::testing
