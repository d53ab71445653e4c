// Running rve_cli as a subprocess, and a real rve_server with a stub on it,
// for the rve_cli tests.
#ifndef RVEHUB_TESTS_RVE_SERVER_CLI_CLI_TEST_UTIL_H_
#define RVEHUB_TESTS_RVE_SERVER_CLI_CLI_TEST_UTIL_H_

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "rve_server/client/channel.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/service/registry.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "tests/support/process_util.h"

namespace rvehub::cli::cli_test {

using testing_util::ReadFile;

struct Result {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs rve_cli with `args` (already shell-quoted where needed); `output` has
// stdout and stderr together, or stdout only when `stdout_only`.
inline Result RunCli(const std::string& args, bool stdout_only = false) {
  testing_util::CommandResult r = testing_util::RunCommand(
      absl::StrCat("'", RVE_CLI_PATH, "' ", args, stdout_only ? " 2>/dev/null" : " 2>&1"));
  return {r.exit_code, std::move(r.out)};
}

// A path in the test's temporary directory, unique per process.
inline std::string TempPath(const std::string& name) {
  return absl::StrCat(testing::TempDir(), "/cli_test_", getpid(), "_", name);
}

// Reads the CSV as rows of numbers (header dropped).
inline std::vector<std::vector<double>> ParseRows(const std::string& csv) {
  std::vector<std::vector<double>> rows;
  const std::vector<std::string> lines = absl::StrSplit(csv, '\n', absl::SkipEmpty());
  for (std::size_t k = 1; k < lines.size(); ++k) {
    std::vector<double> row;
    for (absl::string_view cell : absl::StrSplit(lines[k], ',')) {
      double v = NAN;
      EXPECT_TRUE(absl::SimpleAtod(cell, &v)) << "line " << k << ": '" << cell << "'";
      row.push_back(v);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

// Column indices of the CSV.
inline constexpr int kStep = 0, kAxial = 1, kVol = 2, kSyy = 4, kShear = 15, kColumns = 16;

// ---------------------------------------------------------------------------
// Against real servers.

// A running rve_server (testing_util::ServerProcess) and a stub on it; its
// log is removed at destruction unless the test failed.
class Server {
 public:
  explicit Server(std::vector<std::string> extra_args = {})
      : process_(RVE_SERVER_PATH, NextLogPath(), std::move(extra_args)),
        stub_(v1::RveService::NewStub(client::MakeChannel(process_.address(), {}))) {}
  ~Server() {
    Stop();
    if (!testing::Test::HasFailure()) std::remove(process_.log_path().c_str());
  }
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // SIGTERM and wait; the exit status (−1 when it did not exit normally).
  int Stop() {
    // Our idle connection would hold the server's drain up for seconds.
    stub_.reset();
    return process_.Stop();
  }

  const std::string& address() const { return process_.address(); }
  std::string server_flag() const { return absl::StrCat("--server=", address()); }
  v1::RveService::Stub& stub() { return *stub_; }
  std::string Log() const { return process_.Log(); }

 private:
  static std::string NextLogPath() {
    static int count = 0;
    return TempPath(absl::StrCat("server", ++count, ".log"));
  }

  testing_util::ServerProcess process_;
  std::unique_ptr<v1::RveService::Stub> stub_;
};

inline std::unique_ptr<grpc::ClientContext> Ctx() {
  auto ctx = std::make_unique<grpc::ClientContext>();
  client::Prepare(*ctx, {}, std::chrono::seconds(60));
  return ctx;
}

// rve_cli prepare --out (SET-dense, ~0.5 s) and upload-template; the name.
inline std::string PrepareAndUpload(const Server& server, int seed) {
  const std::string file = TempPath(absl::StrCat("template", seed, ".h5"));
  const Result prepared =
      RunCli(absl::StrCat("prepare --material=SET-dense --seed=", seed, " --out='", file, "'"));
  EXPECT_EQ(prepared.exit_code, 0) << prepared.output;
  const std::string name = absl::StrCat("SET-dense-seed", seed);
  EXPECT_TRUE(absl::StrContains(prepared.output, absl::StrCat("template ", name, "\n")))
      << prepared.output;
  const Result uploaded =
      RunCli(absl::StrCat("upload-template ", server.server_flag(), " --file='", file, "'"));
  EXPECT_EQ(uploaded.exit_code, 0) << uploaded.output;
  std::remove(file.c_str());
  return name;
}

inline void CreateRves(Server& server, const std::string& run, const std::string& template_name,
                       const std::vector<std::int64_t>& ids) {
  v1::CreateRvesRequest request;
  request.set_run_id(run);
  request.set_template_name(template_name);
  for (std::int64_t id : ids) request.add_ids(id);
  v1::CreateRvesResponse response;
  const grpc::Status s = server.stub().CreateRves(Ctx().get(), request, &response);
  ASSERT_TRUE(s.ok()) << s.error_message();
}

// Commits `step` for `ids` with a small compression; the results.
inline v1::ApplyResponse Compress(Server& server, const std::string& run, std::int64_t step,
                                  const std::vector<std::int64_t>& ids) {
  v1::ApplyRequest request;
  request.set_run_id(run);
  request.set_step(step);
  request.set_mode(v1::APPLY_MODE_COMMIT);
  request.mutable_options()->set_want_tangent(true);
  for (std::int64_t id : ids) {
    v1::Increment* inc = request.add_increments();
    inc->set_id(id);
    for (double v : {1.0, 0.0, 0.0, 0.0, 1.0 - 1e-4, 0.0, 0.0, 0.0, 1.0}) inc->add_delta_f(v);
  }
  v1::ApplyResponse response;
  const grpc::Status s = server.stub().Apply(Ctx().get(), request, &response);
  EXPECT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(response.failed(), 0);
  return response;
}

// The serialized records of a run, one Export call per RVE (so that the
// server's own chunking does not matter here).
inline std::vector<std::string> ExportRun(Server& server, const std::string& run,
                                          const std::vector<std::int64_t>& ids) {
  std::vector<std::string> records;
  for (std::int64_t id : ids) {
    v1::ExportRequest request;
    request.set_run_id(run);
    request.add_ids(id);
    auto ctx = Ctx();
    auto reader = server.stub().Export(ctx.get(), request);
    v1::RveChunk chunk;
    while (reader->Read(&chunk)) {
      for (const v1::RveRecord& r : chunk.records()) records.push_back(r.SerializeAsString());
    }
    const grpc::Status s = reader->Finish();
    EXPECT_TRUE(s.ok()) << s.error_message();
  }
  return records;
}

// Same bits, value by value.
inline void ExpectSameBits(const std::vector<std::vector<double>>& a,
                           const std::vector<std::vector<double>>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].size(), b[k].size()) << "row " << k;
    for (std::size_t c = 0; c < a[k].size(); ++c) {
      EXPECT_EQ(std::memcmp(&a[k][c], &b[k][c], sizeof(double)), 0)
          << "row " << k << " column " << c << ": " << a[k][c] << " vs " << b[k][c];
    }
  }
}

}  // namespace rvehub::cli::cli_test

#endif  // RVEHUB_TESTS_RVE_SERVER_CLI_CLI_TEST_UTIL_H_
