// Requests that once knocked the server over, each kept as a test:
// a huge cell, unbounded work, amplification by repeated ids, malformed
// import streams, unanswerable commits (retries included), unguarded health
// Watch, long ids, and what Stop says about the RVEs it drops. A real server
// on loopback.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "health_probe.grpc.pb.h"
#include "rve_server/engine/rve.h"
#include "tests/rve_server/service/service_harness.h"

namespace rvehub::service::testing {
namespace {

using wire::FromProto;
using wire::ToProto;

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Two 1 mm discs in a 1000 m cell (the neighbour grid would need ~1e11 bins).
v1::Packing HugeCellPacking() {
  dem::RveSnapshot p;
  p.cell = Eigen::Matrix2d::Identity() * 1000.0;
  p.reference_cell = p.cell;
  p.radius = {1e-3, 1e-3};
  p.sx = {0.1, 0.6};
  p.sy = {0.1, 0.6};
  p.vx = p.vy = p.omega = p.theta = {0.0, 0.0};
  v1::Packing out;
  ToProto(p, &out);
  return out;
}

v1::RveRecord Record(const std::string& run, std::int64_t id, const v1::Packing& packing) {
  v1::RveRecord r;
  r.set_run_id(run);
  r.set_id(id);
  for (double v : {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}) r.add_last_delta_f(v);
  *r.mutable_packing() = packing;
  return r;
}

// A small template (a lattice of `cols` × `rows` 0.5 mm discs 2 mm apart,
// 10 DEM steps per increment): as large a state as any packing's at a
// fraction of the memory and time, for tests that need many RVEs.
grpc::Status UploadLattice(Harness& h, const std::string& name, int cols = 4, int rows = 4) {
  dem::RveSnapshot p;
  constexpr double kSpacing = 2e-3;  // m
  p.cell << cols * kSpacing, 0, 0, rows * kSpacing;
  p.reference_cell = p.cell;
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      p.radius.push_back(0.5e-3);
      p.sx.push_back((x + 0.5) / cols);
      p.sy.push_back((y + 0.5) / rows);
    }
  }
  p.vx = p.vy = p.omega = p.theta = std::vector<double>(p.radius.size(), 0.0);
  p.controls.min_steps = 10;
  v1::UploadTemplateRequest req;
  req.mutable_entry()->set_name(name);
  ToProto(p, req.mutable_entry()->mutable_packing());
  v1::TemplateInfo info;
  return h.stub().UploadTemplate(h.Context().get(), req, &info);
}

// The most RVEs per Apply the server's reply size allows (from its refusal
// of a batch far too large, which changes nothing).
std::int64_t MaxReplyCount(Harness& h, bool tangent) {
  std::vector<std::int64_t> ids(5000);  // a request within the limit, a reply not
  for (std::size_t k = 0; k < ids.size(); ++k) ids[k] = static_cast<std::int64_t>(k);
  v1::ApplyRequest req = Harness::Commit("none", 1, ids, Compress(1e-4));
  req.mutable_options()->set_want_tangent(tangent);
  v1::ApplyResponse resp;
  const grpc::Status s = h.stub().Apply(h.Context().get(), req, &resp);
  const std::string& m = s.error_message();
  const std::size_t at = m.find("ask for at most ");
  EXPECT_NE(at, std::string::npos) << m;
  return at == std::string::npos ? 0 : std::stoll(m.substr(at + 16));
}

class HardeningTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(h_.Upload().ok());
    ASSERT_TRUE(h_.Create("keep", {1, 2}).ok());
  }
  Harness h_;
};

// 1. A huge cell is refused alike on every path, and the server lives on.
TEST_F(HardeningTest, HugeCellIsRefusedOnEveryPathAndNothingIsLost) {
  {
    v1::UploadTemplateRequest req;
    req.mutable_entry()->set_name("huge");
    *req.mutable_entry()->mutable_packing() = HugeCellPacking();
    v1::TemplateInfo info;
    ExpectError(h_.stub().UploadTemplate(h_.Context().get(), req, &info),
                grpc::StatusCode::INVALID_ARGUMENT, "cell is too large for its particles");
  }
  {
    v1::RveChunk chunk;
    chunk.set_total_records(1);
    *chunk.add_records() = Record("huge", 1, HugeCellPacking());
    ExpectError(RawImport(*h_.channel(), *h_.Context(), {chunk.SerializeAsString()}),
                grpc::StatusCode::INVALID_ARGUMENT, "cell is too large for its particles");
  }
  EXPECT_EQ(h_.NumRves(), 2) << "the hosted RVEs must survive";
  EXPECT_FALSE(h_.ExportBytes("keep", 1).empty());
}

// 2. Parameters outside their documented ranges are refused up front.
TEST_F(HardeningTest, UnboundedWorkIsRefusedWithTheFieldNamed) {
  auto create = [&](const std::function<void(v1::CreateRvesRequest&)>& edit) {
    v1::CreateRvesRequest req;
    req.set_run_id("bounds");
    req.set_template_name(kTemplate);
    req.add_ids(1);
    edit(req);
    v1::CreateRvesResponse resp;
    return h_.stub().CreateRves(h_.Context().get(), req, &resp);
  };
  auto controls = [](v1::CreateRvesRequest& req) {
    ToProto(dem::Controls{}, req.mutable_controls());
    return req.mutable_controls();
  };
  ExpectError(create([&](auto& r) { controls(r)->set_min_steps(1'000'000'000'000); }),
              grpc::StatusCode::INVALID_ARGUMENT, "min_steps");
  ExpectError(create([&](auto& r) { controls(r)->set_max_inertial_number(1e-42); }),
              grpc::StatusCode::INVALID_ARGUMENT, "max_inertial_number");
  ExpectError(create([&](auto& r) { controls(r)->set_pressure_floor(1e-300); }),
              grpc::StatusCode::INVALID_ARGUMENT, "pressure_floor");
  ExpectError(create([](auto& r) { r.mutable_initial_stress()->set_pressure(1e24); }),
              grpc::StatusCode::INVALID_ARGUMENT, "initial pressure");
  ExpectError(create([](auto& r) {
                r.mutable_initial_stress()->mutable_k0()->set_vertical_compression(1e24);
                r.mutable_initial_stress()->mutable_k0()->set_k0(0.5);
              }),
              grpc::StatusCode::INVALID_ARGUMENT, "K0 state");
  v1::ServerInfo info;
  ASSERT_TRUE(h_.stub().GetServerInfo(h_.Context().get(), {}, &info).ok());
  EXPECT_EQ(info.num_runs(), 1) << "no run may have been created";

  v1::ApplyResponse resp;
  v1::ApplyRequest relax = Harness::Commit("keep", 1, {1}, Compress(1e-4));
  relax.mutable_options()->set_relax(true);
  relax.mutable_options()->set_relax_tolerance(1e-300);
  ExpectError(h_.stub().Apply(h_.Context().get(), relax, &resp), grpc::StatusCode::INVALID_ARGUMENT,
              "relax_tolerance");
  relax.mutable_options()->set_relax_tolerance(1e-4);
  relax.mutable_options()->set_relax_max_steps(std::int64_t{1} << 62);
  ExpectError(h_.stub().Apply(h_.Context().get(), relax, &resp), grpc::StatusCode::INVALID_ARGUMENT,
              "relax_max_steps");
  relax.mutable_options()->set_relax_max_steps(0);
  relax.mutable_options()->set_max_inertial_number(1e-42);
  ExpectError(h_.stub().Apply(h_.Context().get(), relax, &resp), grpc::StatusCode::INVALID_ARGUMENT,
              "max_inertial_number");
  relax.mutable_options()->set_max_inertial_number(0);
  relax.mutable_options()->set_duration(-1);
  ExpectError(h_.stub().Apply(h_.Context().get(), relax, &resp), grpc::StatusCode::INVALID_ARGUMENT,
              "duration");

  v1::ElementTestRequest test;
  test.set_template_name(kTemplate);
  test.set_test(v1::ELEMENT_TEST_DRAINED_BIAXIAL);
  test.set_inertial_number(1e-42);
  auto ctx = h_.Context();
  auto reader = h_.stub().RunElementTest(ctx.get(), test);
  v1::ElementTestUpdate update;
  while (reader->Read(&update)) {
  }
  ExpectError(reader->Finish(), grpc::StatusCode::INVALID_ARGUMENT, "inertial_number");
  test.set_inertial_number(1e-3);
  test.set_confining_pressure(1e24);
  auto ctx2 = h_.Context();
  auto reader2 = h_.stub().RunElementTest(ctx2.get(), test);
  while (reader2->Read(&update)) {
  }
  ExpectError(reader2->Finish(), grpc::StatusCode::INVALID_ARGUMENT, "confining");
  // 2-D RVEs have no z axis; an axis the enum does not name is refused too.
  test.set_confining_pressure(0);
  test.set_axis(v1::LOADING_AXIS_Z);
  auto ctx3 = h_.Context();
  auto reader3 = h_.stub().RunElementTest(ctx3.get(), test);
  while (reader3->Read(&update)) {
  }
  ExpectError(reader3->Finish(), grpc::StatusCode::INVALID_ARGUMENT, "axis z needs a 3-D RVE");
  test.set_axis(static_cast<v1::LoadingAxis>(7));
  auto ctx4 = h_.Context();
  auto reader4 = h_.stub().RunElementTest(ctx4.get(), test);
  while (reader4->Read(&update)) {
  }
  ExpectError(reader4->Finish(), grpc::StatusCode::INVALID_ARGUMENT,
              "axis must name a loading axis, got 7");
}

// 2. A long increment (a relaxation to a tolerance it never reaches) stops
// at the call's deadline: the worker is free again and the RVE unchanged.
TEST(HardeningDeadline, LongRelaxationStopsAtTheDeadlineAndChangesNothing) {
  ServerConfig config;
  config.registry.threads = 1;  // a worker left running would block the next call
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("r", {1, 2}).ok());
  const std::string before = h.ExportBytes("r", 1);
  ASSERT_FALSE(before.empty());
  v1::ApplyRequest req = Harness::Commit("r", 1, {1}, Compress(1e-4));
  req.mutable_options()->set_relax(true);
  req.mutable_options()->set_relax_tolerance(1e-12);  // never reached
  req.mutable_options()->set_relax_max_steps(10'000'000);
  v1::ApplyResponse resp;
  const auto t0 = Clock::now();
  // Either the client's deadline ends the call, or (on a loaded machine) the
  // server sees it pass first and answers with the RVE stopped.
  const grpc::Status first =
      h.stub().Apply(h.Context(std::chrono::milliseconds(500)).get(), req, &resp);
  EXPECT_TRUE(first.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ||
              (first.ok() && resp.failed() == 1 &&
               resp.results(0).code() == static_cast<int>(absl::StatusCode::kDeadlineExceeded)))
      << first.error_code() << " " << first.error_message() << " failed " << resp.failed();
  // The next call needs the only worker: it gets it within moments.
  ASSERT_TRUE(h.stub()
                  .Apply(h.Context(std::chrono::seconds(20)).get(),
                         Harness::Commit("r", 1, {2}, Compress(1e-4)), &resp)
                  .ok());
  EXPECT_EQ(resp.failed(), 0);
  EXPECT_LT(Seconds(t0), 10.0) << "the stopped relaxation kept the worker";
  EXPECT_EQ(h.ExportBytes("r", 1), before) << "a stopped increment must leave the RVE as it was";
  v1::GetStatesRequest get;
  get.set_run_id("r");
  get.add_ids(1);
  v1::GetStatesResponse states;
  ASSERT_TRUE(h.stub().GetStates(h.Context().get(), get, &states).ok());
  EXPECT_EQ(states.results(0).step(), 0);
}

// 3. A repeated id is an error, not a multiplied reply; so is a huge list.
TEST(HardeningAmplification, RepeatedOrTooManyIdsAreRefused) {
  ServerConfig config;
  config.registry.max_batch = 16;
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("r", {1, 2}).ok());
  std::vector<std::int64_t> repeated(1000, 1);
  repeated.push_back(2);
  repeated.push_back(2);
  {
    v1::ExportRequest req;
    req.set_run_id("r");
    for (std::int64_t id : std::vector<std::int64_t>{1, 2, 1}) req.add_ids(id);
    auto ctx = h.Context();
    auto reader = h.stub().Export(ctx.get(), req);
    v1::RveChunk chunk;
    int records = 0;
    while (reader->Read(&chunk)) records += chunk.records_size();
    ExpectError(reader->Finish(), grpc::StatusCode::INVALID_ARGUMENT, "repeated in the request: 1");
    EXPECT_EQ(records, 0);
  }
  {
    v1::GetStatesRequest req;
    req.set_run_id("r");
    for (std::int64_t id : std::vector<std::int64_t>{2, 1, 2}) req.add_ids(id);
    v1::GetStatesResponse resp;
    ExpectError(h.stub().GetStates(h.Context().get(), req, &resp),
                grpc::StatusCode::INVALID_ARGUMENT, "repeated in the request: 2");
    req.clear_ids();
    for (std::int64_t id : repeated) req.add_ids(id);
    ExpectError(h.stub().GetStates(h.Context().get(), req, &resp),
                grpc::StatusCode::INVALID_ARGUMENT, "exceed the server's max batch of 16");
  }
  {
    v1::DropRequest req;
    req.set_run_id("r");
    for (std::int64_t id : std::vector<std::int64_t>{1, 1}) req.add_ids(id);
    v1::DropResponse resp;
    ExpectError(h.stub().Drop(h.Context().get(), req, &resp), grpc::StatusCode::INVALID_ARGUMENT,
                "repeated");
  }
  EXPECT_EQ(h.NumRves(), 2);
}

// 4. A malformed import stream imports nothing and says why.
TEST_F(HardeningTest, MalformedImportStreamsImportNothing) {
  const std::string exported = h_.ExportBytes("keep", 1);
  v1::RveChunk source;
  ASSERT_TRUE(source.ParseFromString(exported));
  ASSERT_EQ(source.records_size(), 1);
  auto chunk = [&](std::int64_t total, const std::string& run, std::int64_t id) {
    v1::RveChunk c;
    if (total != 0) c.set_total_records(total);
    v1::RveRecord* r = c.add_records();
    *r = source.records(0);
    r->set_run_id(run);
    r->set_id(id);
    return c.SerializeAsString();
  };
  const std::string garbage("\xff\xff\xff\xff\x0f garbage", 14);
  struct Case {
    const char* what;
    std::vector<std::string> messages;
    const char* words;
  };
  const Case cases[] = {
      {"no total_records, garbage, a third chunk",
       {chunk(0, "imp", 1), garbage, chunk(0, "imp", 2)},
       "the first chunk must set total_records"},
      {"a valid chunk then garbage", {chunk(1, "imp", 1), garbage}, "not a valid RveChunk"},
      {"a negative total", {chunk(-1, "imp", 1)}, "got -1"},
      {"fewer records than declared", {chunk(2, "imp", 1)}, "declared 2 records but carried 1"},
      {"more records than declared", {chunk(1, "imp", 1), chunk(0, "imp", 2)}, "more than the 1"},
      {"a second total", {chunk(2, "imp", 1), chunk(3, "imp", 2)}, "declares total_records 3"},
      {"no chunks", {}, "no chunks"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    ExpectError(RawImport(*h_.channel(), *h_.Context(), c.messages),
                grpc::StatusCode::INVALID_ARGUMENT, c.words);
    v1::ListRunsResponse runs;
    ASSERT_TRUE(h_.stub().ListRuns(h_.Context().get(), {}, &runs).ok());
    EXPECT_EQ(runs.runs_size(), 1) << "nothing may have been imported";
    EXPECT_EQ(h_.NumRves(), 2);
  }
  // The same stream, well formed, imports both (and bit for bit).
  v1::ImportResponse resp;
  ASSERT_TRUE(
      RawImport(*h_.channel(), *h_.Context(), {chunk(2, "imp", 1), chunk(0, "imp", 2)}, &resp)
          .ok());
  EXPECT_EQ(resp.imported(), 2);
  v1::RveChunk back;
  ASSERT_TRUE(back.ParseFromString(h_.ExportBytes("imp", 2)));
  EXPECT_EQ(back.records(0).packing().SerializeAsString(),
            source.records(0).packing().SerializeAsString());
}

// Apply reads its request's bytes itself (to parse it onto an arena): bytes
// that are no ApplyRequest are the client's error and change nothing; a
// valid request's results come back in its order, not the workers'.
TEST_F(HardeningTest, MalformedApplyRequestIsRefusedAndChangesNothing) {
  const std::string garbage("\xff\xff\xff\xff\x0f garbage", 14);
  ExpectError(RawUnary(*h_.channel(), *h_.Context(), "/rvehub.v1.RveService/Apply", garbage),
              grpc::StatusCode::INVALID_ARGUMENT, "not a valid ApplyRequest");
  v1::GetStatesRequest get;
  get.set_run_id("keep");
  v1::GetStatesResponse states;
  ASSERT_TRUE(h_.stub().GetStates(h_.Context().get(), get, &states).ok());
  ASSERT_EQ(states.results_size(), 2);
  for (const v1::RveResult& r : states.results()) EXPECT_EQ(r.step(), 0) << "id " << r.id();

  v1::ApplyResponse resp;
  ASSERT_TRUE(
      h_.stub()
          .Apply(h_.Context().get(), Harness::Commit("keep", 1, {2, 1}, Compress(1e-4)), &resp)
          .ok());
  ASSERT_EQ(resp.results_size(), 2);
  EXPECT_EQ(resp.failed(), 0);
  EXPECT_EQ(resp.results(0).id(), 2);
  EXPECT_EQ(resp.results(1).id(), 1);
  for (const v1::RveResult& r : resp.results()) {
    EXPECT_EQ(r.code(), 0) << r.message();
    EXPECT_EQ(r.step(), 1);
    EXPECT_GT(r.state().mean_pressure(), 0.0);
  }
}

// 5. A COMMIT whose reply could not be sent is refused before it commits.
TEST(HardeningReplySize, OversizedReplyIsRefusedBeforeCommitting) {
  ServerConfig config;
  config.max_message_bytes = 1 << 20;
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("r", {0, 1}).ok());
  std::vector<std::int64_t> ids;
  for (int k = 0; k < 2000; ++k) ids.push_back(k);  // only 0 and 1 exist
  v1::ApplyRequest req = Harness::Commit("r", 1, ids, Compress(1e-4));
  req.mutable_options()->set_want_tangent(true);
  v1::ApplyResponse resp;
  ExpectError(h.stub().Apply(h.Context().get(), req, &resp), grpc::StatusCode::INVALID_ARGUMENT,
              "over the server's message limit");
  v1::GetStatesRequest get;
  get.set_run_id("r");
  v1::GetStatesResponse states;
  ASSERT_TRUE(h.stub().GetStates(h.Context().get(), get, &states).ok());
  ASSERT_EQ(states.results_size(), 2);
  for (const v1::RveResult& r : states.results()) EXPECT_EQ(r.step(), 0) << "nothing committed";
  // Split as the message says, the commit goes through and can be answered.
  req = Harness::Commit("r", 1, {0, 1}, Compress(1e-4));
  req.mutable_options()->set_want_tangent(true);
  ASSERT_TRUE(h.stub().Apply(h.Context().get(), req, &resp).ok());
  EXPECT_EQ(resp.failed(), 0);
}

// 9. A retried COMMIT answers what it asks for: a batch without tangents
// that repeats RVEs first committed with tangents was sized without them,
// and returning the stored tangents made it unanswerable (every retry
// RESOURCE_EXHAUSTED) after the rest of the batch had committed.
TEST(HardeningReplySize, RetryWithoutTangentOfACommitWithTangentsIsAnswered) {
  ServerConfig config;
  config.max_message_bytes = 1 << 20;
  Harness h(config);
  ASSERT_TRUE(UploadLattice(h, "lattice").ok());
  const std::int64_t with_tangent = MaxReplyCount(h, true);
  const std::int64_t without = MaxReplyCount(h, false);
  ASSERT_GT(with_tangent, 100);
  ASSERT_GT(without, 2 * with_tangent) << "a tangent doubles a result at least";
  std::vector<std::int64_t> all(static_cast<std::size_t>(without));
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = static_cast<std::int64_t>(k);
  const std::vector<std::int64_t> first(all.begin(), all.begin() + with_tangent);
  v1::CreateRvesRequest create;
  create.set_run_id("r");
  create.set_template_name("lattice");
  for (std::int64_t id : all) create.add_ids(id);
  v1::CreateRvesResponse created;
  ASSERT_TRUE(h.stub().CreateRves(h.Context().get(), create, &created).ok());

  v1::ApplyResponse tangents;
  ASSERT_TRUE(h.Apply("r", 1, v1::APPLY_MODE_COMMIT, first, Compress(1e-4), &tangents, true).ok());
  ASSERT_EQ(tangents.failed(), 0);
  ASSERT_EQ(tangents.results(0).state().tangent_size(), 81);
  v1::ApplyResponse resp;
  const grpc::Status s = h.Apply("r", 1, v1::APPLY_MODE_COMMIT, all, Compress(1e-4), &resp);
  ASSERT_TRUE(s.ok()) << s.error_code() << " " << s.error_message();
  ASSERT_EQ(resp.results_size(), without);
  EXPECT_EQ(resp.failed(), 0);
  // The retried ones: the stored results bit for bit, without the tangent
  // this call did not ask for.
  for (std::int64_t k = 0; k < with_tangent; ++k) {
    v1::RveResult expected = tangents.results(static_cast<int>(k));
    expected.mutable_state()->clear_tangent();
    expected.set_engine_seconds(resp.results(static_cast<int>(k)).engine_seconds());
    ASSERT_EQ(resp.results(static_cast<int>(k)).SerializeAsString(), expected.SerializeAsString())
        << "id " << k;
  }
  // Retried again, the whole batch answers the same.
  v1::ApplyResponse again;
  ASSERT_TRUE(h.Apply("r", 1, v1::APPLY_MODE_COMMIT, all, Compress(1e-4), &again).ok());
  EXPECT_EQ(again.failed(), 0);
  for (int k = 0; k < again.results_size(); ++k) {
    v1::RveResult a = again.results(k), b = resp.results(k);
    a.set_engine_seconds(0);
    b.set_engine_seconds(0);
    ASSERT_EQ(a.SerializeAsString(), b.SerializeAsString()) << "id " << k;
  }
  // Asked for the tangent again, the retry returns the stored one.
  v1::ApplyResponse stored;
  ASSERT_TRUE(h.Apply("r", 1, v1::APPLY_MODE_COMMIT, {0}, Compress(1e-4), &stored, true).ok());
  EXPECT_EQ(stored.results(0).state().SerializeAsString(),
            tangents.results(0).state().SerializeAsString());
}

// The server's memory account, bytes.
std::int64_t MemoryBytes(Harness& h) {
  v1::ServerInfo info;
  EXPECT_TRUE(h.stub().GetServerInfo(h.Context().get(), {}, &info).ok());
  return info.memory_bytes();
}

// 10. A ΔF that squeezes a cell thinner than twice the pair cutoff doubles
// the RVE: the memory account follows it, and a doubling past the limit is
// refused as a creation would be (it went unaccounted, and the limit no
// longer held).
TEST(HardeningMemory, CellDoublingIsAccountedAndRefusedPastTheLimit) {
  // 64 discs in one row, the cell 2.3 mm high (twice the cutoff is 2.25
  // mm): a 4 % squeeze doubles it. Few DEM steps (duration).
  v1::ApplyRequest squeeze = Harness::Commit("r", 1, {1}, Compress(0.04));
  squeeze.mutable_options()->set_duration(1e-6);
  auto upload = [](Harness& h) {
    dem::RveSnapshot p;
    p.cell << 64 * 2e-3, 0, 0, 2.3e-3;
    p.reference_cell = p.cell;
    for (int x = 0; x < 64; ++x) {
      p.radius.push_back(0.5e-3);
      p.sx.push_back((x + 0.5) / 64);
      p.sy.push_back(0.5);
    }
    p.vx = p.vy = p.omega = p.theta = std::vector<double>(p.radius.size(), 0.0);
    p.controls.min_steps = 10;
    v1::UploadTemplateRequest req;
    req.mutable_entry()->set_name(kTemplate);
    ToProto(p, req.mutable_entry()->mutable_packing());
    v1::TemplateInfo info;
    return h.stub().UploadTemplate(h.Context().get(), req, &info);
  };
  // Sizes measured on a server without a limit: the template's account, an
  // RVE's, and the doubled RVE's.
  std::int64_t base = 0, single = 0, doubled = 0;
  {
    Harness probe;
    ASSERT_TRUE(upload(probe).ok());
    base = MemoryBytes(probe);
    ASSERT_TRUE(probe.Create("r", {1}).ok());
    single = MemoryBytes(probe) - base;
    v1::ApplyResponse resp;
    ASSERT_TRUE(probe.stub().Apply(probe.Context().get(), squeeze, &resp).ok());
    ASSERT_EQ(resp.failed(), 0) << resp.results(0).message();
    ASSERT_EQ(probe.SnapshotOf("r", 1).radius.size(), 128u) << "the squeeze doubles the cell";
    doubled = MemoryBytes(probe) - base;
    ASSERT_GT(doubled, single + single / 2) << "the account follows the doubling";
  }
  // Room for two RVEs and one doubling, not for a third RVE besides.
  ServerConfig config;
  config.registry.max_memory_bytes = base + single + doubled + single / 2;
  Harness h(config);
  ASSERT_TRUE(upload(h).ok());
  ASSERT_TRUE(h.Create("r", {1, 2}).ok());
  v1::ApplyResponse resp;
  ASSERT_TRUE(h.stub().Apply(h.Context().get(), squeeze, &resp).ok());
  ASSERT_EQ(resp.failed(), 0) << resp.results(0).message();
  EXPECT_EQ(MemoryBytes(h), base + single + doubled);
  ExpectError(h.Create("r", {3}), grpc::StatusCode::RESOURCE_EXHAUSTED, "memory limit");
  // RVE 2's doubling would pass the limit: refused, the RVE as it was.
  const std::string before = h.ExportBytes("r", 2);
  squeeze.mutable_increments(0)->set_id(2);
  for (v1::ApplyMode mode : {v1::APPLY_MODE_TRIAL, v1::APPLY_MODE_COMMIT}) {
    squeeze.set_mode(mode);
    ASSERT_TRUE(h.stub().Apply(h.Context().get(), squeeze, &resp).ok());
    EXPECT_EQ(resp.failed(), 1);
    EXPECT_EQ(resp.results(0).code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_EQ(resp.results(0).step(), 0);
    for (const char* words : {"material point 2", "doubling it (64 to 128 particles",
                              "over its limit of", "stays at its committed step"}) {
      EXPECT_NE(resp.results(0).message().find(words), std::string::npos)
          << resp.results(0).message();
    }
  }
  EXPECT_EQ(h.ExportBytes("r", 2), before);
  EXPECT_EQ(MemoryBytes(h), base + single + doubled);
  // Dropping the doubled RVE gives its bytes back; then RVE 2 may double.
  v1::DropRequest drop;
  drop.set_run_id("r");
  drop.add_ids(1);
  v1::DropResponse dropped;
  ASSERT_TRUE(h.stub().Drop(h.Context().get(), drop, &dropped).ok());
  EXPECT_EQ(MemoryBytes(h), base + single);
  ASSERT_TRUE(h.stub().Apply(h.Context().get(), squeeze, &resp).ok());
  EXPECT_EQ(resp.failed(), 0) << resp.results(0).message();
  EXPECT_EQ(MemoryBytes(h), base + doubled);
}

// 11. Templates count in the memory account and their number is capped:
// 1,500 were taken under a 16 MiB limit (RSS 21 → 96 MB).
TEST(HardeningMemory, TemplatesCountInTheMemoryAccountAndAreCapped) {
  ServerConfig config;
  config.registry.max_memory_bytes = 16 << 20;
  Harness h(config);
  v1::UploadTemplateRequest req;
  *req.mutable_entry() = MakeTemplate();
  req.mutable_entry()->set_description(std::string(4096, 'd'));
  v1::TemplateInfo info;
  grpc::Status s;
  int uploaded = 0;
  for (; uploaded < 1500; ++uploaded) {
    req.mutable_entry()->set_name(absl::StrCat("t", uploaded));
    s = h.stub().UploadTemplate(h.Context().get(), req, &info);
    if (!s.ok()) break;
  }
  ExpectError(s, grpc::StatusCode::RESOURCE_EXHAUSTED, "over its limit of 16777216 bytes");
  EXPECT_NE(s.error_message().find(absl::StrCat("template \"t", uploaded, "\"")), std::string::npos)
      << s.error_message();
  EXPECT_GT(uploaded, 10);
  v1::ServerInfo server;
  ASSERT_TRUE(h.stub().GetServerInfo(h.Context().get(), {}, &server).ok());
  EXPECT_EQ(server.num_templates(), uploaded);
  EXPECT_LE(server.memory_bytes(), server.max_memory_bytes());
  EXPECT_GT(server.memory_bytes(),
            server.max_memory_bytes() - 2 * (server.memory_bytes() / uploaded))
      << "each template's bytes are in the account";
  v1::CreateRvesRequest create;
  create.set_run_id("r");
  create.set_template_name("t0");
  create.add_ids(1);
  v1::CreateRvesResponse created;
  ExpectError(h.stub().CreateRves(h.Context().get(), create, &created),
              grpc::StatusCode::RESOURCE_EXHAUSTED, "memory limit");
  // Replacing one takes its bytes out first: the same template fits again.
  req.mutable_entry()->set_name("t0");
  req.set_replace(true);
  EXPECT_TRUE(h.stub().UploadTemplate(h.Context().get(), req, &info).ok());
  v1::ServerInfo replaced;
  ASSERT_TRUE(h.stub().GetServerInfo(h.Context().get(), {}, &replaced).ok());
  EXPECT_EQ(replaced.memory_bytes(), server.memory_bytes());

  // The number is capped too (max_templates), whatever their size.
  config.registry.max_memory_bytes = 1LL << 30;
  config.registry.max_templates = 3;
  Harness few(config);
  req.set_replace(false);
  for (int k = 0; k < 3; ++k) {
    req.mutable_entry()->set_name(absl::StrCat("t", k));
    ASSERT_TRUE(few.stub().UploadTemplate(few.Context().get(), req, &info).ok());
  }
  req.mutable_entry()->set_name("t3");
  ExpectError(few.stub().UploadTemplate(few.Context().get(), req, &info),
              grpc::StatusCode::RESOURCE_EXHAUSTED, "hosts 3 templates, its limit");
  req.mutable_entry()->set_name("t1");
  req.set_replace(true);
  EXPECT_TRUE(few.stub().UploadTemplate(few.Context().get(), req, &info).ok())
      << "replacing one stays within the limit";
  ASSERT_TRUE(few.stub().GetServerInfo(few.Context().get(), {}, &server).ok());
  EXPECT_EQ(server.num_templates(), 3);
  EXPECT_EQ(server.max_templates(), 3);
}

// 12. The bytes held by unfinished Import streams are bounded together:
// six streams, each below the memory limit alone, held 381 MB under
// --max-memory-mb=64.
TEST(HardeningMemory, ImportStreamsShareOneBudget) {
  ServerConfig config;
  config.registry.max_memory_bytes = 4 << 20;
  config.max_message_bytes = 1 << 20;
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("keep", {1}).ok());
  v1::RveChunk one;
  ASSERT_TRUE(one.ParseFromString(h.ExportBytes("keep", 1)));
  // A chunk of about 0.9 MiB; each stream declares more records than it
  // sends, and stays open.
  v1::RveChunk chunk;
  chunk.set_total_records(1000);
  for (int k = 0; chunk.ByteSizeLong() < (9 << 20) / 10; ++k) {
    v1::RveRecord* r = chunk.add_records();
    *r = one.records(0);
    r->set_run_id("imp");
    r->set_id(k);
  }
  const std::string bytes = chunk.SerializeAsString();
  const auto size = static_cast<std::int64_t>(bytes.size());
  auto server_info = [&] {
    v1::ServerInfo info;
    EXPECT_TRUE(h.stub().GetServerInfo(h.Context().get(), {}, &info).ok());
    return info;
  };
  const v1::ServerInfo before = server_info();
  const std::int64_t budget = before.max_memory_bytes() - before.memory_bytes();
  const std::int64_t fit = budget / size;
  ASSERT_GE(fit, 2);
  ASSERT_LT(fit, 6);
  struct Stream {
    std::unique_ptr<grpc::ClientContext> ctx;
    grpc::ByteBuffer response;
    std::unique_ptr<grpc::ClientWriter<grpc::ByteBuffer>> writer;
  };
  std::vector<Stream> streams(6);
  for (std::int64_t k = 0; k < 6; ++k) {
    Stream& s = streams[static_cast<std::size_t>(k)];
    s.ctx = h.Context();
    s.writer.reset(grpc::internal::ClientWriterFactory<grpc::ByteBuffer>::Create(
        h.channel().get(),
        grpc::internal::RpcMethod("/rvehub.v1.RveService/Import",
                                  grpc::internal::RpcMethod::CLIENT_STREAMING),
        s.ctx.get(), &s.response));
    grpc::Slice slice(bytes);
    (void)s.writer->Write(grpc::ByteBuffer(&slice, 1));
    if (k < fit) {  // held: wait until the server has read it
      const auto until = Clock::now() + std::chrono::seconds(30);
      while (server_info().import_bytes() < (k + 1) * size && Clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      ASSERT_EQ(server_info().import_bytes(), (k + 1) * size);
    } else {  // past the budget: refused, what the others hold unchanged
      s.writer->WritesDone();
      ExpectError(s.writer->Finish(), grpc::StatusCode::RESOURCE_EXHAUSTED,
                  absl::StrCat("at most the room left under the server's memory limit, ", budget,
                               " bytes"));
      EXPECT_EQ(server_info().import_bytes(), fit * size);
    }
  }
  // Ended, the held streams give their bytes back; an import then fits.
  for (std::int64_t k = 0; k < fit; ++k) {
    Stream& s = streams[static_cast<std::size_t>(k)];
    s.ctx->TryCancel();
    EXPECT_FALSE(s.writer->Finish().ok());
  }
  const auto until = Clock::now() + std::chrono::seconds(30);
  while (server_info().import_bytes() != 0 && Clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(server_info().import_bytes(), 0);
  v1::RveChunk small;
  small.set_total_records(1);
  *small.add_records() = chunk.records(0);
  v1::ImportResponse imported;
  ASSERT_TRUE(RawImport(*h.channel(), *h.Context(), {small.SerializeAsString()}, &imported).ok());
  EXPECT_EQ(imported.imported(), 1);
}

// 6. health.Watch needs the token as Check does.
TEST(HardeningAuth, HealthWatchNeedsTheToken) {
  ServerConfig config;
  config.auth_token = "s3cret-token";
  Harness h(config);
  auto health = grpc::health::v1::Health::NewStub(h.channel());
  grpc::health::v1::HealthCheckRequest req;
  grpc::health::v1::HealthCheckResponse resp;
  // Without the token or with a wrong one: ended at once with
  // UNAUTHENTICATED, as Check is, before any serving status is sent.
  for (const char* token : {"", "wrong-token"}) {
    for (const char* service : {"", "rvehub.v1.RveService"}) {
      grpc::ClientContext ctx;
      ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
      if (*token != '\0') ctx.AddMetadata("authorization", absl::StrCat("Bearer ", token));
      req.set_service(service);
      auto reader = health->Watch(&ctx, req);
      EXPECT_FALSE(reader->Read(&resp)) << "an unauthenticated Watch must get no status";
      ExpectError(reader->Finish(), grpc::StatusCode::UNAUTHENTICATED,
                  "/grpc.health.v1.Health/Watch needs \"authorization: Bearer <token>\"");
    }
  }
  req.clear_service();
  {
    auto ctx = h.Context(std::chrono::seconds(10));
    auto reader = health->Watch(ctx.get(), req);
    ASSERT_TRUE(reader->Read(&resp));
    EXPECT_EQ(resp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
    ctx->TryCancel();
    (void)reader->Finish();
  }
}

// 6. Our own streaming methods still answer UNAUTHENTICATED without the token.
TEST(HardeningAuth, StreamingMethodsSayUnauthenticated) {
  ServerConfig config;
  config.auth_token = "s3cret-token";
  Harness h(config);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  v1::ExportRequest req;
  req.set_run_id("r");
  auto reader = h.stub().Export(&ctx, req);
  v1::RveChunk chunk;
  EXPECT_FALSE(reader->Read(&chunk));
  ExpectError(reader->Finish(), grpc::StatusCode::UNAUTHENTICATED, "Bearer");
}

// 7. Ids and names have bounded lengths, and errors never echo them whole.
TEST_F(HardeningTest, LongIdsAreRefusedWithoutBeingEchoed) {
  const std::string long_id(10'000, 'a');
  constexpr std::size_t kMaxMessage = 400;
  auto expect_short = [&](const grpc::Status& s, const char* what) {
    SCOPED_TRACE(what);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << s.error_message();
    EXPECT_LT(s.error_message().size(), kMaxMessage) << s.error_message();
    EXPECT_NE(s.error_message().find("10000"), std::string::npos) << s.error_message();
  };
  {
    v1::GetStatesRequest req;
    req.set_run_id(long_id);
    v1::GetStatesResponse resp;
    expect_short(h_.stub().GetStates(h_.Context().get(), req, &resp), "GetStates");
  }
  {
    v1::ApplyResponse resp;
    expect_short(h_.stub().Apply(h_.Context().get(),
                                 Harness::Commit(long_id, 1, {1}, Compress(1e-4)), &resp),
                 "Apply");
  }
  {
    v1::DropRequest req;
    req.set_run_id(long_id);
    v1::DropResponse resp;
    expect_short(h_.stub().Drop(h_.Context().get(), req, &resp), "Drop");
  }
  {
    v1::ExportRequest req;
    req.set_run_id(long_id);
    auto ctx = h_.Context();
    auto reader = h_.stub().Export(ctx.get(), req);
    v1::RveChunk chunk;
    while (reader->Read(&chunk)) {
    }
    expect_short(reader->Finish(), "Export");
  }
  {
    v1::CreateRvesRequest req;
    req.set_run_id("r");
    req.set_template_name(long_id);
    req.add_ids(1);
    v1::CreateRvesResponse resp;
    expect_short(h_.stub().CreateRves(h_.Context().get(), req, &resp), "CreateRves template");
    req.set_run_id(long_id);
    req.set_template_name(kTemplate);
    expect_short(h_.stub().CreateRves(h_.Context().get(), req, &resp), "CreateRves run");
  }
  {
    v1::ElementTestRequest req;
    req.set_template_name(long_id);
    req.set_test(v1::ELEMENT_TEST_ISOTROPIC);
    auto ctx = h_.Context();
    auto reader = h_.stub().RunElementTest(ctx.get(), req);
    v1::ElementTestUpdate u;
    while (reader->Read(&u)) {
    }
    expect_short(reader->Finish(), "RunElementTest");
  }
  {
    v1::RveChunk source;
    ASSERT_TRUE(source.ParseFromString(h_.ExportBytes("keep", 1)));
    source.mutable_records(0)->set_run_id(long_id);
    source.set_total_records(1);
    expect_short(RawImport(*h_.channel(), *h_.Context(), {source.SerializeAsString()}), "Import");
  }
  {  // Not printable: escaped, not echoed raw.
    v1::GetStatesRequest req;
    req.set_run_id(std::string("bad\n\x01id", 7));
    v1::GetStatesResponse resp;
    const grpc::Status s = h_.stub().GetStates(h_.Context().get(), req, &resp);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(s.error_message().find('\n'), std::string::npos) << s.error_message();
  }
  EXPECT_EQ(h_.NumRves(), 2);
}

// 8. Stop without a checkpoint directory says that it drops the RVEs.
TEST(HardeningStop, StopWithoutCheckpointSaysWhatItDrops) {
  Harness h;
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("r", {1, 2, 3}).ok());
  SetLogEnabled(true);
  ::testing::internal::CaptureStderr();
  EXPECT_TRUE(h.server().Stop(std::chrono::seconds(1)).ok());
  const std::string log = ::testing::internal::GetCapturedStderr();
  SetLogEnabled(false);
  EXPECT_EQ(log.find("checkpoint=ok"), std::string::npos) << log;
  EXPECT_NE(log.find("no checkpoint directory"), std::string::npos) << log;
  EXPECT_NE(log.find("dropped_rves=3"), std::string::npos) << log;
}

// 2. A drain whose grace runs out stops engine work in flight.
TEST(HardeningStop, DrainEndsWhenTheGraceDoesDespiteALongCall) {
  ServerConfig config;
  config.registry.threads = 1;
  Harness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("r", {1}).ok());
  v1::ApplyRequest req = Harness::Commit("r", 1, {1}, Compress(1e-4));
  req.mutable_options()->set_relax(true);
  req.mutable_options()->set_relax_tolerance(1e-12);
  req.mutable_options()->set_relax_max_steps(10'000'000);
  grpc::Status long_call;
  v1::ApplyResponse resp;
  std::thread client([&] {
    grpc::ClientContext ctx;  // no deadline: only the drain can end it
    long_call = h.stub().Apply(&ctx, req, &resp);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the call is in the engine
  const auto t0 = Clock::now();
  EXPECT_TRUE(h.server().Stop(std::chrono::milliseconds(500)).ok());
  EXPECT_LT(Seconds(t0), 5.0) << "Stop waited for the engine beyond the grace";
  client.join();
  // The call fails, or its reply says the RVE was stopped (the drain's
  // cancellation reached the engine before the transport closed).
  EXPECT_TRUE(!long_call.ok() || (resp.failed() == 1 && resp.results(0).code() != 0))
      << long_call.error_code() << " " << long_call.error_message() << " failed " << resp.failed();
}

}  // namespace
}  // namespace rvehub::service::testing
