// The rve_server binary as users run it: a child process on a free loopback
// port. Health and reflection respond; SIGTERM drains a call in flight and
// writes the checkpoint, and a restart from it continues bit-identically.
// (This binary must not link grpc++_reflection: it carries its own copy of
// the reflection messages to call the server's reflection service.)
#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "health_probe.grpc.pb.h"
#include "reflection_probe.grpc.pb.h"
#include "reflection_v1_probe.grpc.pb.h"
#include "rve_server/wire/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "tests/support/process_util.h"
#include "tests/support/rpc_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::service {
namespace {

using wire::FromProto;
using wire::ToProto;

namespace fs = std::filesystem;

// A drain waits for each connected client to acknowledge the server's GOAWAY;
// an idle gRPC client channel reads its socket only from its backup poller
// (every 5 s by default), which would make each stop here take 5 s.
const bool kFastClientPolling = [] {
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);
  return true;
}();

// A running rve_server child; SIGKILLed if the test did not stop it.
class ServerProcess {
 public:
  explicit ServerProcess(std::vector<std::string> args) {
    int out[2];
    EXPECT_EQ(pipe(out), 0);
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], STDOUT_FILENO);
      close(out[0]);
      close(out[1]);
      std::vector<char*> argv;
      std::string path = RVE_SERVER_PATH;
      argv.push_back(path.data());
      for (std::string& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(path.c_str(), argv.data());
      _exit(127);
    }
    close(out[1]);
    // First stdout line: "listening on HOST:PORT".
    FILE* f = fdopen(out[0], "r");
    char line[256] = {0};
    if (std::fgets(line, sizeof line, f) != nullptr) {
      std::string s(line);
      const std::string prefix = "listening on ";
      if (s.rfind(prefix, 0) == 0) address_ = s.substr(prefix.size(), s.find('\n') - prefix.size());
    }
    std::fclose(f);
    EXPECT_FALSE(address_.empty()) << "the server did not report its address";
    channel_ = grpc::CreateChannel(address_, grpc::InsecureChannelCredentials());
    stub_ = v1::RveService::NewStub(channel_);
  }
  ~ServerProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }

  // SIGTERM, then the exit status (−1 when it did not exit normally).
  int Terminate() {
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  // SIGTERM, then the exit status if it exits within `limit` (−1 when it
  // did not exit normally, −2 when it is still running: then it is killed).
  int TerminateWithin(std::chrono::milliseconds limit) {
    kill(pid_, SIGTERM);
    const auto end = std::chrono::steady_clock::now() + limit;
    int status = 0;
    while (std::chrono::steady_clock::now() < end) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -2;
  }

  v1::RveService::Stub& stub() { return *stub_; }
  std::shared_ptr<grpc::Channel> channel() { return channel_; }
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  std::string address_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::RveService::Stub> stub_;
};

std::unique_ptr<grpc::ClientContext> Ctx() {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  return ctx;
}

v1::ApplyRequest Increments(std::int64_t step, int count, double strain) {
  v1::ApplyRequest req;
  req.set_run_id("run");
  req.set_step(step);
  req.set_mode(v1::APPLY_MODE_COMMIT);
  for (int id = 0; id < count; ++id) {
    v1::Increment* inc = req.add_increments();
    inc->set_id(id);
    for (double v : {1.0, 0.0, 0.0, 0.0, 1.0 - strain, 0.0, 0.0, 0.0, 1.0}) inc->add_delta_f(v);
  }
  return req;
}

v1::RveRecord ExportOne(v1::RveService::Stub& stub, std::int64_t id) {
  return service::ExportOne(stub, *Ctx(), "run", id);
}

// Uploads the SET-dense template "t" (min_steps 10) and creates RVEs
// 0 .. count − 1 of run "run" from it.
grpc::Status CreateRun(v1::RveService::Stub& stub, int count) {
  v1::UploadTemplateRequest up;
  up.mutable_entry()->set_name("t");
  dem::RveSnapshot p = dem::testing_util::Prepared("SET-dense");
  p.controls.min_steps = 10;
  ToProto(p, up.mutable_entry()->mutable_packing());
  v1::TemplateInfo info;
  if (grpc::Status s = stub.UploadTemplate(Ctx().get(), up, &info); !s.ok()) return s;
  v1::CreateRvesRequest create;
  create.set_run_id("run");
  create.set_template_name("t");
  for (int id = 0; id < count; ++id) create.add_ids(id);
  v1::CreateRvesResponse created;
  return stub.CreateRves(Ctx().get(), create, &created);
}

TEST(ServerProcess, HealthAndReflectionRespond) {
  ServerProcess server({"--listen=127.0.0.1:0", "--threads=1"});
  auto health = grpc::health::v1::Health::NewStub(server.channel());
  grpc::health::v1::HealthCheckRequest hreq;
  grpc::health::v1::HealthCheckResponse hresp;
  ASSERT_TRUE(health->Check(Ctx().get(), hreq, &hresp).ok());
  EXPECT_EQ(hresp.status(), grpc::health::v1::HealthCheckResponse::SERVING);

  auto reflection = grpc::reflection::v1alpha::ServerReflection::NewStub(server.channel());
  auto ctx = Ctx();
  auto stream = reflection->ServerReflectionInfo(ctx.get());
  grpc::reflection::v1alpha::ServerReflectionRequest rreq;
  rreq.set_list_services("*");
  ASSERT_TRUE(stream->Write(rreq));
  grpc::reflection::v1alpha::ServerReflectionResponse rresp;
  ASSERT_TRUE(stream->Read(&rresp));
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
  std::vector<std::string> names;
  for (const auto& s : rresp.list_services_response().service()) names.push_back(s.name());
  EXPECT_NE(std::find(names.begin(), names.end(), "rvehub.v1.RveService"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "grpc.health.v1.Health"), names.end());

  // Reflection v1 too (forwarded to v1alpha, whose messages it shares).
  auto reflection_v1 = grpc::reflection::v1::ServerReflection::NewStub(server.channel());
  auto ctx_v1 = Ctx();
  auto stream_v1 = reflection_v1->ServerReflectionInfo(ctx_v1.get());
  grpc::reflection::v1::ServerReflectionRequest req_v1;
  req_v1.set_list_services("*");
  grpc::reflection::v1::ServerReflectionResponse resp_v1;
  for (int k = 0; k < 2; ++k) {  // two requests on one stream, two answers
    ASSERT_TRUE(stream_v1->Write(req_v1));
    ASSERT_TRUE(stream_v1->Read(&resp_v1));
  }
  stream_v1->WritesDone();
  EXPECT_TRUE(stream_v1->Finish().ok());
  names.clear();
  for (const auto& s : resp_v1.list_services_response().service()) names.push_back(s.name());
  EXPECT_NE(std::find(names.begin(), names.end(), "rvehub.v1.RveService"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "grpc.reflection.v1.ServerReflection"),
            names.end());
  EXPECT_EQ(server.Terminate(), 0);
}

TEST(ServerProcess, SigtermDrainsCheckpointsAndRestartContinues) {
  const fs::path dir = fs::temp_directory_path() / ("rvehub_ckpt_" + std::to_string(getpid()));
  fs::remove_all(dir);
  const std::string dir_flag = "--checkpoint-dir=" + dir.string();
  constexpr int kRves = 32;  // step 2 then keeps both workers busy for ~1 s
  v1::ApplyResponse uninterrupted;
  v1::RveRecord before_stop;
  {
    ServerProcess server({"--listen=127.0.0.1:0", "--threads=2", dir_flag});
    ASSERT_TRUE(CreateRun(server.stub(), kRves).ok());
    v1::ApplyResponse r;
    ASSERT_TRUE(server.stub().Apply(Ctx().get(), Increments(1, kRves, 1e-4), &r).ok());
    ASSERT_EQ(r.failed(), 0);

    // A long call in flight when SIGTERM arrives is drained, not cut.
    std::promise<void> started;
    auto in_flight = std::async(std::launch::async, [&] {
      v1::ApplyResponse resp;
      auto ctx = Ctx();
      started.set_value();
      grpc::Status s = server.stub().Apply(ctx.get(), Increments(2, kRves, 0.04), &resp);
      return std::make_pair(s, resp);
    });
    started.get_future().wait();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_EQ(server.Terminate(), 0);
    auto [status, resp] = in_flight.get();
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(resp.failed(), 0);
    EXPECT_EQ(resp.results(0).step(), 2);
  }
  ASSERT_TRUE(fs::exists(dir / "rves.h5"));
  ASSERT_TRUE(fs::exists(dir / "templates.h5"));

  // Reference: the same three steps on a server that never stopped.
  {
    ServerProcess ref({"--listen=127.0.0.1:0", "--threads=1"});
    ASSERT_TRUE(CreateRun(ref.stub(), kRves).ok());
    v1::ApplyResponse r;
    ASSERT_TRUE(ref.stub().Apply(Ctx().get(), Increments(1, kRves, 1e-4), &r).ok());
    ASSERT_TRUE(ref.stub().Apply(Ctx().get(), Increments(2, kRves, 0.04), &r).ok());
    ASSERT_TRUE(ref.stub().Apply(Ctx().get(), Increments(3, kRves, 1e-4), &uninterrupted).ok());
    ASSERT_EQ(uninterrupted.failed(), 0);
    before_stop = ExportOne(ref.stub(), kRves - 1);
    EXPECT_EQ(ref.Terminate(), 0);
  }

  ServerProcess restarted({"--listen=127.0.0.1:0", "--threads=1", dir_flag});
  v1::ListRunsResponse runs;
  ASSERT_TRUE(restarted.stub().ListRuns(Ctx().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).num_rves(), kRves);
  EXPECT_EQ(runs.runs(0).min_step(), 2);
  v1::ListTemplatesResponse templates;
  ASSERT_TRUE(restarted.stub().ListTemplates(Ctx().get(), {}, &templates).ok());
  ASSERT_EQ(templates.templates_size(), 1);
  v1::ApplyResponse continued;
  ASSERT_TRUE(restarted.stub().Apply(Ctx().get(), Increments(3, kRves, 1e-4), &continued).ok());
  ASSERT_EQ(continued.failed(), 0);
  for (int k = 0; k < kRves; ++k) {
    EXPECT_EQ(continued.results(k).state().SerializeAsString(),
              uninterrupted.results(k).state().SerializeAsString())
        << "id " << k;
  }
  EXPECT_EQ(ExportOne(restarted.stub(), kRves - 1).SerializeAsString(),
            before_stop.SerializeAsString());
  EXPECT_EQ(restarted.Terminate(), 0);

  // A damaged checkpoint stops the next start with a clear error (exit 1)
  // instead of serving partial or wrong RVEs.
  {
    std::fstream f(dir / "rves.h5", std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(0, std::ios::end);
    const std::streamoff middle = f.tellg() / 2;
    char c = 0;
    f.seekg(middle);
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x5a);
    f.seekp(middle);
    f.write(&c, 1);
  }
  const std::string log = (dir / "server.log").string();
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, STDERR_FILENO);
    execl(RVE_SERVER_PATH, RVE_SERVER_PATH, "--listen=127.0.0.1:0", dir_flag.c_str(),
          static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("rves.h5"), std::string::npos) << text;
  EXPECT_NE(text.find("level=error"), std::string::npos) << text;
  fs::remove_all(dir);
}

// Two servers on one checkpoint directory would each save their own RVEs
// there at their stop, the last one silently overwriting the other's: a
// second server refuses to start while a running one holds the directory,
// naming it and the holder's pid, and the first one's RVEs survive its stop.
// Once it has stopped, the directory is free for the next start.
TEST(ServerProcess, SecondServerOnAHeldCheckpointDirRefusesToStart) {
  const fs::path dir = fs::temp_directory_path() / ("rvehub_lock_" + std::to_string(getpid()));
  fs::remove_all(dir);
  const std::string dir_flag = "--checkpoint-dir=" + dir.string();
  {
    ServerProcess first({"--listen=127.0.0.1:0", "--threads=1", dir_flag});
    ASSERT_TRUE(CreateRun(first.stub(), 3).ok());
    const testing_util::CommandResult second = testing_util::RunCommand(absl::StrCat(
        "timeout 20 " RVE_SERVER_PATH " --listen=127.0.0.1:0 ", dir_flag, " 2>&1 >/dev/null"));
    EXPECT_EQ(second.exit_code, 1) << second.out;
    EXPECT_NE(
        second.out.find(absl::StrCat("checkpoint directory ", dir.string(),
                                     " is held by another rve_server (pid ", first.pid(), ")")),
        std::string::npos)
        << second.out;
    EXPECT_EQ(first.Terminate(), 0);
  }
  ServerProcess restarted({"--listen=127.0.0.1:0", "--threads=1", dir_flag});
  v1::ListRunsResponse runs;
  ASSERT_TRUE(restarted.stub().ListRuns(Ctx().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).num_rves(), 3);
  EXPECT_EQ(restarted.Terminate(), 0);
  fs::remove_all(dir);
}

// A call busy in the engine (a relaxation to a tolerance it never
// reaches, no client deadline) does not keep a SIGTERM with a 2 s drain
// from ending the process.
TEST(ServerProcess, SigtermWithShortDrainEndsDespiteALongCall) {
  ServerProcess server({"--listen=127.0.0.1:0", "--threads=1", "--drain-seconds=2"});
  ASSERT_TRUE(CreateRun(server.stub(), 1).ok());
  v1::ApplyRequest req = Increments(1, 1, 1e-4);
  req.mutable_options()->set_relax(true);
  req.mutable_options()->set_relax_tolerance(1e-12);
  req.mutable_options()->set_relax_max_steps(10'000'000);
  grpc::Status long_call;
  v1::ApplyResponse resp;
  std::thread client([&] {
    grpc::ClientContext ctx;  // no deadline: only the drain can end it
    long_call = server.stub().Apply(&ctx, req, &resp);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the call is in the engine
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(server.TerminateWithin(std::chrono::seconds(20)), 0);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 8.0) << "the drain should end about when its 2 s grace does";
  client.join();
  // The relaxation did not finish. The drain stops it in the engine, and the
  // server answers the call with that RVE's failure (an OK call whose one
  // result failed, rve_service.proto) when the reply gets out before the
  // channel closes, else the call itself fails: which one is a race (seen
  // both ways under ctest -j2).
  if (long_call.ok()) {
    ASSERT_EQ(resp.results_size(), 1);
    EXPECT_EQ(resp.failed(), 1);
    EXPECT_NE(resp.results(0).code(), 0);
  }
}

// Bad flags end the process with exit 1 and their reason before it listens:
// a missing token file, and values that had started a server on another port
// (gRPC reads a port modulo 65536), with a truncated message limit (4096 MiB
// cast to int: 0) or with a checkpoint directory it cannot write, or aborted
// it (100000 threads). `timeout` ends a server that starts after all.
TEST(ServerProcess, BadFlagsFailToStart) {
  struct Case {
    const char* flags;
    const char* message;
  };
  for (const Case& c : {
           Case{"--listen=127.0.0.1:0 --auth-token-file=/nonexistent/token",
                "cannot read token file '/nonexistent/token'"},
           Case{"--listen=127.0.0.1:70000",
                "listen address: \\\"127.0.0.1:70000\\\" is not HOST:PORT with a port in 0..65535"},
           Case{"--listen=127.0.0.1:", "is not HOST:PORT"},
           Case{"--listen=127.0.0.1:0 --threads=100000", "--threads=100000 must lie in 0..1024"},
           Case{"--listen=127.0.0.1:0 --max-message-mb=4096",
                "--max-message-mb=4096 must lie in 1..2047"},
           Case{"--listen=127.0.0.1:0 --max-memory-mb=9223372036854775807",
                "--max-memory-mb=9223372036854775807 must lie in 1.."},
           Case{"--listen=127.0.0.1:0 --drain-seconds=-1", "--drain-seconds=-1 must be >= 0"},
           // Found only at the stop that was to save every RVE into it.
           Case{"--listen=127.0.0.1:0 --checkpoint-dir=/dev/null",
                "cannot create checkpoint directory /dev/null: Not a directory"},
       }) {
    // stderr (the log) through the pipe, stdout dropped.
    const testing_util::CommandResult r = testing_util::RunCommand(
        absl::StrCat("timeout 20 " RVE_SERVER_PATH " ", c.flags, " 2>&1 >/dev/null"));
    EXPECT_EQ(r.exit_code, 1) << c.flags << ": " << r.out;
    EXPECT_NE(r.out.find("msg=\"cannot start\""), std::string::npos) << c.flags << ": " << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.flags << ": " << r.out;
  }
}

// Options spelled the old way, with underscores, still work: the server
// starts with their values and logs one warning per old name, naming the
// new spelling.
TEST(ServerProcess, OldSpellingWarnsAndRuns) {
  const std::string log =
      (fs::temp_directory_path() / ("rvehub_old_spelling_" + std::to_string(getpid()) + ".log"))
          .string();
  testing_util::ServerProcess server(RVE_SERVER_PATH, log,
                                     {"--max_batch=500", "--max_batch=700", "--max-rves=900"});
  ASSERT_FALSE(server.address().empty()) << server.Log();
  auto stub = v1::RveService::NewStub(
      grpc::CreateChannel(server.address(), grpc::InsecureChannelCredentials()));
  v1::ServerInfo info;
  ASSERT_TRUE(stub->GetServerInfo(Ctx().get(), {}, &info).ok());
  EXPECT_EQ(info.max_batch(), 700);
  EXPECT_EQ(info.max_rves(), 900);
  EXPECT_EQ(server.Stop(), 0);
  const std::string text = server.Log();
  const std::string warning = "level=warn msg=\"--max_batch is now spelled --max-batch\"\n";
  const std::size_t at = text.find(warning);
  EXPECT_NE(at, std::string::npos) << text;
  EXPECT_EQ(text.find(warning, at + 1), std::string::npos) << "one warning per name:\n" << text;
  EXPECT_FALSE(absl::StrContains(text, "max-rves is now")) << text;
  fs::remove(log);
}

// A command line the server cannot read ends it with exit 2 and the reason,
// before it listens; --help anywhere wins (usage on stdout, exit 0).
TEST(ServerProcess, UsageErrorsExitTwoAndHelpExitsZero) {
  struct Case {
    const char* flags;
    const char* message;
  };
  for (const Case& c : {
           Case{"--bogus=1", "unknown option --bogus (see --help)"},
           Case{"--max_memory-mb=64", "unknown option --max_memory-mb (see --help)"},
           Case{"--nohealth_without_token", "unknown option --nohealth_without_token"},
           Case{"--flagfile=/dev/null", "unknown option --flagfile"},
           Case{"--threads=abc", "bad value for --threads: 'abc'"},
           Case{"--threads", "--threads needs a value (--threads=...)"},
           Case{"--listen 127.0.0.1:0", "--listen needs a value"},
           Case{"extra", "unexpected argument 'extra'"},
       }) {
    const testing_util::CommandResult r = testing_util::RunCommand(
        absl::StrCat("timeout 20 " RVE_SERVER_PATH " ", c.flags, " 2>&1 >/dev/null"));
    EXPECT_EQ(r.exit_code, 2) << c.flags << ": " << r.out;
    EXPECT_NE(r.out.find("msg=\"cannot start\""), std::string::npos) << c.flags << ": " << r.out;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.flags << ": " << r.out;
  }
  for (const char* flags : {"--help", "--bogus -h", "--checkpoint_dir=/x --helpfull"}) {
    const testing_util::CommandResult r =
        testing_util::RunCommand(absl::StrCat("timeout 20 " RVE_SERVER_PATH " ", flags, " 2>&1"));
    EXPECT_EQ(r.exit_code, 0) << flags << ": " << r.out;
    EXPECT_TRUE(absl::StrContains(r.out, "--checkpoint-dir=\"\"")) << flags << ": " << r.out;
    EXPECT_FALSE(absl::StrContains(r.out, "is now spelled")) << flags << ": " << r.out;
  }
}

}  // namespace
}  // namespace rvehub::service
