// RVE records with values no run can have (tampered with, or corrupt): a
// negative or huge committed step or DEM step count, a NaN or infinite
// value of the state. An Import of one is INVALID_ARGUMENT naming the field
// and value, and imports nothing; a checkpoint file holding one stops the
// server's start, naming the file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "store/checkpoint.h"
#include "tests/rve_server/service/service_harness.h"

namespace rvehub::service::testing {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t k2Pow62 = std::int64_t{1} << 62;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

// Imports `record` (one chunk) into run "copy".
grpc::Status ImportOne(Harness& h, v1::RveRecord record) {
  record.set_run_id("copy");
  v1::RveChunk chunk;
  chunk.set_total_records(1);
  *chunk.add_records() = std::move(record);
  return RawImport(*h.channel(), *h.Context(), {chunk.SerializeAsString()});
}

std::vector<std::string> RunIds(Harness& h) {
  v1::ListRunsResponse runs;
  EXPECT_TRUE(h.stub().ListRuns(h.Context().get(), {}, &runs).ok());
  std::vector<std::string> ids;
  for (const v1::RunInfo& r : runs.runs()) ids.push_back(r.run_id());
  return ids;
}

TEST(TamperedStateTest, ImportRefusesOutOfRangeStepsAndNonFiniteValues) {
  Harness h;
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("source", {0}).ok());
  const v1::RveRecord exported = h.ExportOne("source", 0);
  ASSERT_EQ(exported.last_delta_f_size(), 9);
  struct Case {
    const char* what;
    std::function<void(v1::RveRecord&)> tamper;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"negative step", [](v1::RveRecord& r) { r.set_step(-1); },
       "step = -1 must lie in 0..9007199254740992 (2^53)"},
      {"step 2^62", [](v1::RveRecord& r) { r.set_step(k2Pow62); },
       "step = 4611686018427387904 must lie in 0..9007199254740992"},
      {"step past 2^53", [](v1::RveRecord& r) { r.set_step(kMaxStep + 1); },
       "step = 9007199254740993 must lie in 0.."},
      {"NaN in the last ΔF", [](v1::RveRecord& r) { r.set_last_delta_f(4, kNaN); },
       "last_delta_f[4] = nan is not finite"},
      {"infinite last ΔF",
       [](v1::RveRecord& r) { r.set_last_delta_f(0, std::numeric_limits<double>::infinity()); },
       "last_delta_f[0] = inf is not finite"},
      {"negative DEM step count",
       [](v1::RveRecord& r) { r.mutable_packing()->set_total_steps(-5); },
       "total_steps = -5 must lie in 0..9007199254740992"},
      {"DEM step count 2^62",
       [](v1::RveRecord& r) { r.mutable_packing()->set_total_steps(k2Pow62); },
       "total_steps = 4611686018427387904 must lie in 0.."},
      {"NaN velocity", [](v1::RveRecord& r) { r.mutable_packing()->set_vx(3, kNaN); },
       "vx[3] = nan is not finite"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    v1::RveRecord record = exported;
    c.tamper(record);
    const grpc::Status s = ImportOne(h, record);
    ExpectError(s, grpc::StatusCode::INVALID_ARGUMENT, c.message);
    ExpectError(s, grpc::StatusCode::INVALID_ARGUMENT, "material point 0");
    EXPECT_EQ(h.NumRves(), 1);
    EXPECT_EQ(RunIds(h), std::vector<std::string>{"source"});
  }
}

// The largest step is a run's; the step after it is refused by Apply as it
// is by Import, rather than wrapping or passing 2^53 to clients.
TEST(TamperedStateTest, StepsStopAtTwoToThe53) {
  Harness h;
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("source", {0}).ok());
  v1::RveRecord record = h.ExportOne("source", 0);
  record.set_step(kMaxStep);
  ASSERT_TRUE(ImportOne(h, record).ok());
  v1::ApplyResponse resp;
  for (std::int64_t step : {kMaxStep + 1, k2Pow62, std::numeric_limits<std::int64_t>::max()}) {
    ExpectError(h.Apply("copy", step, v1::APPLY_MODE_COMMIT, {0}, Compress(1e-4), &resp),
                grpc::StatusCode::INVALID_ARGUMENT,
                absl::StrCat("step ", step, " must be <= 9007199254740992"));
  }
  // The RVE stays at its step.
  v1::GetStatesRequest get;
  get.set_run_id("copy");
  get.add_ids(0);
  v1::GetStatesResponse got;
  ASSERT_TRUE(h.stub().GetStates(h.Context().get(), get, &got).ok());
  ASSERT_EQ(got.results_size(), 1);
  EXPECT_EQ(got.results(0).step(), kMaxStep);
}

class TamperedCheckpointTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           absl::StrCat("rvehub_tampered_", getpid(), "_",
                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // RveServer::Start on the directory: its error (OK when it started).
  absl::Status Start() {
    SetLogEnabled(false);
    ServerConfig config;
    config.listen = "127.0.0.1:0";
    config.checkpoint_dir = dir_.string();
    absl::StatusOr<std::unique_ptr<RveServer>> s = RveServer::Start(config);
    return s.status();
  }

  static RveRecord Record() {
    RveRecord r;
    r.run_id = "run";
    r.id = 4;
    r.step = 12;
    r.packing = dem::testing_util::SquareLattice(3, 2e-3, [](int, int) { return 1e-3; });
    return r;
  }

  void WriteRves(const RveRecord& r) {
    ASSERT_TRUE(store::WriteRves((dir_ / "rves.h5").string(), {&r, 1}, {"test", ""}).ok());
  }

  fs::path dir_;
};

TEST_F(TamperedCheckpointTest, OutOfRangeValuesInRvesStopTheStartNamingTheFile) {
  const std::string file = (dir_ / "rves.h5").string();
  struct Case {
    const char* what;
    std::function<void(RveRecord&)> tamper;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"negative step", [](RveRecord& r) { r.step = -3; }, "step = -3 must lie in 0.."},
      {"step 2^62", [](RveRecord& r) { r.step = k2Pow62; },
       "step = 4611686018427387904 must lie in 0..9007199254740992"},
      {"NaN last ΔF", [](RveRecord& r) { r.last_delta_f(1, 2) = kNaN; },
       "last_delta_f[5] = nan is not finite"},
      {"DEM step count 2^62", [](RveRecord& r) { r.packing.total_steps = k2Pow62; },
       "total_steps = 4611686018427387904 must lie in 0.."},
      {"NaN angle", [](RveRecord& r) { r.packing.theta[2] = kNaN; },
       "theta[2] = nan is not finite"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    RveRecord r = Record();
    c.tamper(r);
    WriteRves(r);
    const absl::Status s = Start();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
    EXPECT_NE(s.message().find(absl::StrCat("restoring ", file,
                                            ": record 0 (run \"run\", "
                                            "material point 4): ")),
              std::string::npos)
        << s;
    EXPECT_NE(s.message().find(c.message), std::string::npos) << s;
  }
  // The untampered record: the server starts (the refused starts left no
  // lock behind).
  WriteRves(Record());
  EXPECT_TRUE(Start().ok());
}

TEST_F(TamperedCheckpointTest, OutOfRangeValuesInTemplatesStopTheStartNamingTheFile) {
  TemplateRecord t;
  t.name = "lattice";
  t.packing = Record().packing;
  t.packing.total_steps = k2Pow62;
  const std::string file = (dir_ / "templates.h5").string();
  ASSERT_TRUE(store::WriteTemplates(file, {&t, 1}, {"test", ""}).ok());
  const absl::Status s = Start();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
  EXPECT_NE(s.message().find(absl::StrCat("restoring ", file, ": template \"lattice\": ")),
            std::string::npos)
      << s;
  EXPECT_NE(s.message().find("total_steps = 4611686018427387904 must lie in 0.."),
            std::string::npos)
      << s;
}

}  // namespace
}  // namespace rvehub::service::testing
