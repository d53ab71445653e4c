// The RVE service with a real server on loopback: creation, commit/trial
// protocol, safe retries, export/import continuation, bad input, auth,
// concurrency, deadlines, health.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <limits>
#include <memory>
#include <thread>

#include "health_probe.grpc.pb.h"
#include "rve_server/common/text_file.h"
#include "rve_server/service/log.h"
#include "rve_server/service/server.h"
#include "rve_server/wire/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "tests/rve_server/service/service_harness.h"
#include "tests/support/rpc_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::service {
namespace {

using wire::FromProto;
using wire::ToProto;

using dem::testing_util::ExpectIdenticalPackings;
using dem::testing_util::Prepared;

using testing::Compress;
using testing::ExpectError;
using testing::kTemplate;
using testing::MakeTemplate;
using ServerHarness = testing::Harness;

bool SameBits(const google::protobuf::RepeatedField<double>& a,
              const google::protobuf::RepeatedField<double>& b) {
  if (a.size() != b.size()) return false;
  // memcmp must not see the null data() of an empty field, even for 0 bytes.
  const std::size_t bytes = sizeof(double) * static_cast<std::size_t>(a.size());
  return bytes == 0 || std::memcmp(a.data(), b.data(), bytes) == 0;
}

// Same homogenised state, bit for bit (the serialised messages are equal).
void ExpectSameState(const v1::RveState& a, const v1::RveState& b, const std::string& where) {
  EXPECT_EQ(a.SerializeAsString(), b.SerializeAsString()) << where;
  EXPECT_TRUE(SameBits(a.stress(), b.stress())) << where;
}

class ServiceTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(h_.Upload().ok()); }
  ServerHarness h_;
};

TEST_F(ServiceTest, CreateApplyGetRoundTrip) {
  v1::CreateRvesResponse created;
  ASSERT_TRUE(h_.Create("run-a", {1, 2, 3}, &created).ok());
  ASSERT_EQ(created.results_size(), 3);
  EXPECT_EQ(created.results(0).step(), 0);

  v1::ApplyResponse applied;
  ASSERT_TRUE(h_.Apply("run-a", 1, v1::APPLY_MODE_COMMIT, {1, 2, 3}, Compress(1e-4), &applied,
                       /*tangent=*/true)
                  .ok());
  ASSERT_EQ(applied.results_size(), 3);
  EXPECT_EQ(applied.failed(), 0);
  for (const v1::RveResult& r : applied.results()) {
    EXPECT_EQ(r.code(), 0) << r.message();
    EXPECT_EQ(r.step(), 1);
    ASSERT_EQ(r.state().stress_size(), 9);
    ASSERT_EQ(r.state().tangent_size(), 81);
    // Compressed along y: σyy more compressive (tension +) than the 100 kPa start.
    EXPECT_LT(r.state().stress(4), -100e3 * 1.01);
    EXPECT_NEAR(r.state().deformation_gradient(4), 1 - 1e-4, 1e-15);
    EXPECT_EQ(r.state().stress(8), 0.0);           // plane strain, no σzz from a 2-D RVE
    EXPECT_GT(r.state().tangent(9 * 4 + 4), 1e7);  // D_yyyy of order 10–100 MPa
  }
  // Same template, same increment: same result for every material point.
  ExpectSameState(applied.results(0).state(), applied.results(2).state(), "ids 1 and 3");

  v1::GetStatesRequest get;
  get.set_run_id("run-a");
  get.add_ids(2);
  v1::GetStatesResponse got;
  ASSERT_TRUE(h_.stub().GetStates(h_.Context().get(), get, &got).ok());
  ASSERT_EQ(got.results_size(), 1);
  EXPECT_EQ(got.results(0).step(), 1);
  EXPECT_TRUE(SameBits(got.results(0).state().stress(), applied.results(1).state().stress()));

  v1::ListRunsResponse runs;
  ASSERT_TRUE(h_.stub().ListRuns(h_.Context().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).num_rves(), 3);
  EXPECT_EQ(runs.runs(0).min_step(), 1);

  v1::ServerInfo info;
  ASSERT_TRUE(h_.stub().GetServerInfo(h_.Context().get(), {}, &info).ok());
  EXPECT_EQ(info.num_rves(), 3);
  EXPECT_EQ(info.num_templates(), 1);
  EXPECT_EQ(info.api_version(), "rvehub.v1");
  EXPECT_GT(info.memory_bytes(), 3 * 20000);
  EXPECT_LT(info.memory_bytes(), 3 * 200000);
}

// The batch values cross the wire both ways through convert.h alone: an
// outcome and an initial stress come back as they went.
TEST(ServiceConvert, OutcomesAndInitialStressesRoundTrip) {
  RveOutcome ok;
  ok.id = 7;
  ok.step = 3;
  ok.engine_seconds = 2.5e-5;
  ok.state.stress << -1e5, 2e3, 0, 2e3, -1.2e5, 0, 0, 0, 0;
  ok.state.void_ratio = 0.181;
  ok.deformation_gradient(0, 1) = 1e-3;
  v1::RveResult wire;
  ToProto(ok, &wire);
  RveOutcome back;
  ASSERT_TRUE(FromProto(wire, &back).ok());
  EXPECT_EQ(back.id, 7);
  EXPECT_EQ(back.step, 3);
  EXPECT_EQ(back.engine_seconds, 2.5e-5);
  EXPECT_TRUE(back.status.ok());
  EXPECT_EQ(back.state.stress, ok.state.stress);
  EXPECT_EQ(back.state.void_ratio, 0.181);
  EXPECT_EQ(back.deformation_gradient, ok.deformation_gradient);

  RveOutcome failed;
  failed.id = 8;
  failed.step = 2;
  failed.status = absl::FailedPreconditionError("det ΔF = -1 must be > 0");
  wire.Clear();
  ToProto(failed, &wire);
  wire.set_engine_seconds(std::numeric_limits<double>::quiet_NaN());
  ASSERT_TRUE(FromProto(wire, &back).ok());
  EXPECT_EQ(back.id, 8);
  EXPECT_EQ(back.step, 2);
  EXPECT_EQ(back.status, failed.status);
  EXPECT_EQ(back.engine_seconds, 0.0);  // a non-finite time is no measurement

  wire.Clear();
  ToProto(ok, &wire);
  wire.mutable_state()->mutable_stress()->RemoveLast();
  EXPECT_FALSE(FromProto(wire, &back).ok());  // a tensor without 9 values

  for (const InitialStress& s : {InitialStress{InitialStress::Kind::kIsotropic, 1.5e5, 0.0, 0.0},
                                 InitialStress{InitialStress::Kind::kK0, 0.0, 2e4, 0.45}}) {
    v1::InitialStress m;
    ToProto(s, &m);
    absl::StatusOr<InitialStress> r = FromProto(m);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_EQ(r->kind, s.kind);
    EXPECT_EQ(r->pressure, s.pressure);
    EXPECT_EQ(r->vertical_compression, s.vertical_compression);
    EXPECT_EQ(r->k0, s.k0);
  }
  v1::InitialStress none;
  ToProto(InitialStress{}, &none);  // kTemplate: nothing on the wire
  EXPECT_FALSE(FromProto(none).ok());
}

TEST_F(ServiceTest, CreationConsolidatesToIsotropicAndK0States) {
  v1::CreateRvesRequest req;
  req.set_run_id("geo");
  req.set_template_name(kTemplate);
  req.add_ids(1);
  req.add_ids(2);
  req.set_want_state(true);
  req.mutable_initial_stress()->mutable_k0()->set_vertical_compression(150e3);
  req.mutable_initial_stress()->mutable_k0()->set_k0(0.5);
  v1::CreateRvesResponse resp;
  ASSERT_TRUE(h_.stub().CreateRves(h_.Context().get(), req, &resp).ok());
  ASSERT_EQ(resp.results_size(), 2);
  for (const v1::RveResult& r : resp.results()) {
    const v1::RveState& s = r.state();
    // Within the consolidation tolerance (1 % of p = 1125 Pa), tension +.
    EXPECT_NEAR(s.stress(4), -150e3, 1125.0);
    EXPECT_NEAR(s.stress(0), -75e3, 1125.0);
    EXPECT_NEAR(s.stress(1), 0.0, 1125.0);
    // F is measured from the consolidated state.
    EXPECT_EQ(s.deformation_gradient(0), 1.0);
    EXPECT_EQ(s.deformation_gradient(4), 1.0);
  }
  // Both from the same template and target: identical RVEs.
  ExpectSameState(resp.results(0).state(), resp.results(1).state(), "K0 ids 1 and 2");

  req.set_run_id("iso");
  req.mutable_initial_stress()->set_pressure(200e3);
  ASSERT_TRUE(h_.stub().CreateRves(h_.Context().get(), req, &resp).ok());
  EXPECT_NEAR(resp.results(0).state().mean_pressure(), 200e3, 2000.0);
  EXPECT_LT(resp.results(0).state().deviator_stress(), 2000.0);

  req.set_run_id("bad");
  req.mutable_initial_stress()->set_pressure(-5);
  ExpectError(h_.stub().CreateRves(h_.Context().get(), req, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "initial pressure");
}

TEST_F(ServiceTest, CreationConsolidatesEachRveToItsOwnGeostaticPressure) {
  // p = ρ·g·h at three depths (the client computes it), one per id.
  const std::vector<double> pressure = {50e3, 100e3, 150e3};
  v1::CreateRvesRequest req;
  req.set_run_id("geostatic");
  req.set_template_name(kTemplate);
  req.set_want_state(true);
  for (int k = 0; k < 3; ++k) {
    req.add_ids(10 + k);
    req.add_initial_stresses()->set_pressure(pressure[k]);
  }
  v1::CreateRvesResponse resp;
  ASSERT_TRUE(h_.stub().CreateRves(h_.Context().get(), req, &resp).ok());
  ASSERT_EQ(resp.results_size(), 3);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(resp.results(k).id(), 10 + k);
    EXPECT_NEAR(resp.results(k).state().mean_pressure(), pressure[k], 0.01 * pressure[k]);
  }

  // Bad: a count that is neither one nor one per id; a bad entry named by
  // its id; both forms at once. Nothing is created.
  v1::CreateRvesRequest two = req;
  two.set_run_id("bad");
  two.mutable_initial_stresses()->RemoveLast();
  ExpectError(h_.stub().CreateRves(h_.Context().get(), two, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "one per id (3), not 2");
  v1::CreateRvesRequest nan = req;
  nan.set_run_id("bad");
  nan.mutable_initial_stresses(1)->set_pressure(std::numeric_limits<double>::quiet_NaN());
  ExpectError(h_.stub().CreateRves(h_.Context().get(), nan, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "material point 11: initial pressure");
  v1::CreateRvesRequest both = req;
  both.set_run_id("bad");
  both.mutable_initial_stress()->set_pressure(1e5);
  ExpectError(h_.stub().CreateRves(h_.Context().get(), both, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "not both");
  v1::ListRunsResponse runs;
  ASSERT_TRUE(h_.stub().ListRuns(h_.Context().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).run_id(), "geostatic");
}

TEST_F(ServiceTest, RepeatedCommitReturnsStoredResultWithoutRecomputing) {
  ASSERT_TRUE(h_.Create("r", {7}).ok());
  v1::ApplyResponse first, again;
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {7}, Compress(2e-4), &first).ok());
  const dem::RveSnapshot after_first = h_.SnapshotOf("r", 7);
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {7}, Compress(2e-4), &again).ok());
  EXPECT_EQ(again.results(0).code(), 0);
  EXPECT_EQ(again.results(0).step(), 1);
  ExpectSameState(first.results(0).state(), again.results(0).state(), "retry");
  // Not recomputed: the DEM state (step counter included) did not move.
  ExpectIdenticalPackings(after_first, h_.SnapshotOf("r", 7), "after retry");

  // A "retry" with another ΔF is a client error, not a retry.
  v1::ApplyResponse other;
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {7}, Compress(3e-4), &other).ok());
  EXPECT_EQ(other.results(0).code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_NE(other.results(0).message().find("different"), std::string::npos);
  // Skipping a step: FAILED_PRECONDITION carrying the current step.
  v1::ApplyResponse skip;
  ASSERT_TRUE(h_.Apply("r", 3, v1::APPLY_MODE_COMMIT, {7}, Compress(1e-4), &skip).ok());
  EXPECT_EQ(skip.failed(), 1);
  EXPECT_EQ(skip.results(0).code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(skip.results(0).step(), 1);
  EXPECT_NE(skip.results(0).message().find("is at step 1"), std::string::npos);
  ExpectIdenticalPackings(after_first, h_.SnapshotOf("r", 7), "after refused calls");
}

TEST_F(ServiceTest, TrialLeavesStateUnchangedAndMatchesCommit) {
  ASSERT_TRUE(h_.Create("r", {1}).ok());
  const dem::RveSnapshot before = h_.SnapshotOf("r", 1);
  v1::ApplyResponse t1, t2, c;
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_TRIAL, {1}, Compress(3e-4), &t1, true).ok());
  ASSERT_EQ(t1.results(0).code(), 0) << t1.results(0).message();
  EXPECT_EQ(t1.results(0).step(), 0);  // nothing committed
  ExpectIdenticalPackings(before, h_.SnapshotOf("r", 1), "after trial");
  // A second trial (another Newton iteration) from the same committed state.
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_TRIAL, {1}, Compress(3e-4), &t2, true).ok());
  ExpectSameState(t1.results(0).state(), t2.results(0).state(), "two trials");
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1}, Compress(3e-4), &c, true).ok());
  ExpectSameState(t1.results(0).state(), c.results(0).state(), "trial vs commit");
  EXPECT_EQ(c.results(0).step(), 1);
}

TEST(ServiceExportImport, ContinuationOnAnotherServerIsBitIdentical) {
  ServerHarness a, b;
  ASSERT_TRUE(a.Upload().ok());
  ASSERT_TRUE(a.Create("run", {5, 6}).ok());
  // Some history first: shear and compression.
  const std::vector<double> shear = {1, 2e-4, 0, 0, 1, 0, 0, 0, 1};
  v1::ApplyResponse r;
  std::int64_t step = 0;
  for (int k = 0; k < 5; ++k) {
    ASSERT_TRUE(a.Apply("run", ++step, v1::APPLY_MODE_COMMIT, {5, 6}, shear, &r).ok());
    ASSERT_EQ(r.failed(), 0);
  }
  // Export both to server b.
  v1::ExportRequest ereq;
  ereq.set_run_id("run");
  auto ectx = a.Context();
  auto reader = a.stub().Export(ectx.get(), ereq);
  std::vector<v1::RveChunk> chunks;
  v1::RveChunk chunk;
  while (reader->Read(&chunk)) chunks.push_back(chunk);
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_FALSE(chunks.empty());
  EXPECT_EQ(chunks[0].total_records(), 2);
  v1::ImportResponse imported;
  auto ictx = b.Context();
  auto writer = b.stub().Import(ictx.get(), &imported);
  for (const v1::RveChunk& c : chunks) ASSERT_TRUE(writer->Write(c));
  ASSERT_TRUE(writer->WritesDone());
  ASSERT_TRUE(writer->Finish().ok());
  EXPECT_EQ(imported.imported(), 2);

  // Continue 100 steps on both; every result must agree bit for bit.
  v1::ApplyResponse ra, rb;
  for (int k = 0; k < 100; ++k) {
    ++step;
    const std::vector<double>& f = (k % 2 == 0) ? shear : Compress(5e-5);
    ASSERT_TRUE(a.Apply("run", step, v1::APPLY_MODE_COMMIT, {5, 6}, f, &ra).ok());
    ASSERT_TRUE(b.Apply("run", step, v1::APPLY_MODE_COMMIT, {5, 6}, f, &rb).ok());
    ASSERT_EQ(ra.failed(), 0);
    ASSERT_EQ(rb.failed(), 0);
    ASSERT_TRUE(SameBits(ra.results(0).state().stress(), rb.results(0).state().stress()))
        << "step " << step;
  }
  ExpectSameState(ra.results(1).state(), rb.results(1).state(), "after 100 steps");
  ExpectIdenticalPackings(a.SnapshotOf("run", 6), b.SnapshotOf("run", 6), "after 100 steps");
  // The retry protocol survives the move: b knows step and ΔF of the last commit.
  v1::ApplyResponse retry;
  ASSERT_TRUE(b.Apply("run", step, v1::APPLY_MODE_COMMIT, {5}, Compress(5e-5), &retry).ok());
  EXPECT_EQ(retry.results(0).code(), 0) << retry.results(0).message();
}

TEST(ServiceDeterminism, ResultsDoNotDependOnThreadCount) {
  ServerConfig one;
  one.registry.threads = 1;
  ServerConfig two;
  two.registry.threads = 2;
  ServerHarness a(one), b(two);
  ASSERT_TRUE(a.Upload().ok());
  ASSERT_TRUE(b.Upload().ok());
  std::vector<std::int64_t> ids;
  for (int k = 0; k < 8; ++k) ids.push_back(k);
  ASSERT_TRUE(a.Create("d", ids).ok());
  ASSERT_TRUE(b.Create("d", ids).ok());
  v1::ApplyResponse ra, rb;
  // Different ΔF per RVE, in one batch.
  for (std::int64_t step = 1; step <= 3; ++step) {
    v1::ApplyRequest req;
    req.set_run_id("d");
    req.set_step(step);
    req.set_mode(v1::APPLY_MODE_COMMIT);
    for (std::int64_t id : ids) {
      v1::Increment* inc = req.add_increments();
      inc->set_id(id);
      for (double v : {1.0, 1e-4 * id, 0.0, 0.0, 1.0 - 5e-5 * id, 0.0, 0.0, 0.0, 1.0})
        inc->add_delta_f(v);
    }
    ASSERT_TRUE(a.stub().Apply(a.Context().get(), req, &ra).ok());
    ASSERT_TRUE(b.stub().Apply(b.Context().get(), req, &rb).ok());
  }
  ASSERT_EQ(ra.results_size(), 8);
  for (int k = 0; k < 8; ++k) {
    ExpectSameState(ra.results(k).state(), rb.results(k).state(), "id " + std::to_string(k));
  }
}

TEST_F(ServiceTest, BadInputGetsSpecificCodeAndChangesNothing) {
  ASSERT_TRUE(h_.Create("r", {1, 2}).ok());
  const dem::RveSnapshot before = h_.SnapshotOf("r", 1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  v1::ApplyResponse resp;
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1, 2}, {1, 0, 0, 0, nan, 0, 0, 0, 1}, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "not finite");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1}, {-1, 0, 0, 0, 1, 0, 0, 0, 1}, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "det");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1}, {1, 0, 0, 0, 1}, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "9 values");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1}, {1, 0, 0, 0, 1, 0, 0, 0, 1.1}, &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "plane strain");
  ExpectError(h_.Apply("nope", 1, v1::APPLY_MODE_COMMIT, {1}, Compress(1e-4), &resp),
              grpc::StatusCode::NOT_FOUND, "unknown run \"nope\"");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1, 99}, Compress(1e-4), &resp),
              grpc::StatusCode::NOT_FOUND, "no material points 99");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1, 1}, Compress(1e-4), &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "repeated");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {}, Compress(1e-4), &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "empty batch");
  ExpectError(h_.Apply("r", 1, v1::APPLY_MODE_UNSPECIFIED, {1}, Compress(1e-4), &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "mode");
  ExpectError(h_.Apply("r", 0, v1::APPLY_MODE_COMMIT, {1}, Compress(1e-4), &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "step 0");
  {
    v1::ApplyRequest req;
    req.set_run_id("r");
    req.set_step(1);
    req.set_mode(v1::APPLY_MODE_COMMIT);
    req.mutable_options()->set_relax_tolerance(-1.0);
    v1::Increment* inc = req.add_increments();
    inc->set_id(1);
    for (double v : Compress(1e-4)) inc->add_delta_f(v);
    ExpectError(h_.stub().Apply(h_.Context().get(), req, &resp), grpc::StatusCode::INVALID_ARGUMENT,
                "apply options");
  }
  // Too large a stretch for one increment: the engine refuses that RVE alone.
  ASSERT_TRUE(h_.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1}, Compress(0.2), &resp).ok());
  EXPECT_EQ(resp.results(0).code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(resp.results(0).step(), 0);

  ExpectError(h_.Create("r", {2, 3}), grpc::StatusCode::ALREADY_EXISTS, "already has");
  ExpectError(h_.Create("r", {4, 4}), grpc::StatusCode::ALREADY_EXISTS, "repeated");
  ExpectError(h_.Create("bad run id", {1}), grpc::StatusCode::INVALID_ARGUMENT, "run id");
  {
    v1::CreateRvesRequest req;
    req.set_run_id("r2");
    req.set_template_name("missing");
    req.add_ids(1);
    v1::CreateRvesResponse out;
    ExpectError(h_.stub().CreateRves(h_.Context().get(), req, &out), grpc::StatusCode::NOT_FOUND,
                "unknown template \"missing\"");
  }
  {  // Uploading the same name again without replace.
    v1::UploadTemplateRequest req;
    *req.mutable_entry() = MakeTemplate();
    v1::TemplateInfo info;
    ExpectError(h_.stub().UploadTemplate(h_.Context().get(), req, &info),
                grpc::StatusCode::ALREADY_EXISTS, "replace");
  }
  {  // Import: a record whose arrays disagree, and a stream shorter than declared.
    v1::RveRecord good = h_.ExportOne("r", 1);
    good.set_run_id("other");
    v1::RveRecord bad = good;
    bad.mutable_packing()->mutable_sx()->RemoveLast();
    auto import = [&](const std::vector<v1::RveChunk>& chunks) {
      v1::ImportResponse resp;
      auto ctx = h_.Context();
      auto w = h_.stub().Import(ctx.get(), &resp);
      for (const v1::RveChunk& c : chunks) w->Write(c);
      w->WritesDone();
      return w->Finish();
    };
    v1::RveChunk c1;
    c1.set_total_records(2);
    *c1.add_records() = good;
    *c1.add_records() = bad;
    c1.mutable_records(1)->set_id(2);
    ExpectError(import({c1}), grpc::StatusCode::INVALID_ARGUMENT, "packing.sx has 399");
    v1::RveChunk c2;
    c2.set_total_records(3);
    *c2.add_records() = good;
    ExpectError(import({c2}), grpc::StatusCode::INVALID_ARGUMENT, "declared 3");
    v1::RveChunk c3;
    c3.set_total_records(1);
    *c3.add_records() = h_.ExportOne("r", 1);  // (r, 1) is hosted already
    ExpectError(import({c3}), grpc::StatusCode::ALREADY_EXISTS, "already has material point 1");
    v1::GetStatesRequest get;
    get.set_run_id("other");
    v1::GetStatesResponse got;
    ExpectError(h_.stub().GetStates(h_.Context().get(), get, &got), grpc::StatusCode::NOT_FOUND,
                "unknown run");  // nothing of the failed imports landed
  }
  {
    v1::DropRequest drop;
    drop.set_run_id("r");
    drop.add_ids(1);
    drop.add_ids(42);
    v1::DropResponse out;
    ExpectError(h_.stub().Drop(h_.Context().get(), drop, &out), grpc::StatusCode::NOT_FOUND, "42");
  }
  ExpectIdenticalPackings(before, h_.SnapshotOf("r", 1), "after every refused call");
  v1::ListRunsResponse runs;
  ASSERT_TRUE(h_.stub().ListRuns(h_.Context().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).num_rves(), 2);
  EXPECT_EQ(runs.runs(0).max_step(), 0);
}

TEST(ServiceLimits, OversizedBatchAndCapacity) {
  ServerConfig config;
  config.registry.max_batch = 3;
  config.registry.max_rves = 4;
  ServerHarness h(config);
  ASSERT_TRUE(h.Upload().ok());
  ExpectError(h.Create("r", {1, 2, 3, 4}), grpc::StatusCode::INVALID_ARGUMENT, "max batch of 3");
  ASSERT_TRUE(h.Create("r", {1, 2, 3}).ok());
  ExpectError(h.Create("r", {4, 5}), grpc::StatusCode::RESOURCE_EXHAUSTED, "limit of 4");
  v1::ApplyResponse resp;
  ExpectError(h.Apply("r", 1, v1::APPLY_MODE_COMMIT, {1, 2, 3, 4}, Compress(1e-4), &resp),
              grpc::StatusCode::INVALID_ARGUMENT, "max batch of 3");
  // Dropping makes room again.
  v1::DropRequest drop;
  drop.set_run_id("r");
  drop.add_ids(3);
  v1::DropResponse dropped;
  ASSERT_TRUE(h.stub().Drop(h.Context().get(), drop, &dropped).ok());
  EXPECT_EQ(dropped.dropped(), 1);
  EXPECT_TRUE(h.Create("r", {4, 5}).ok());

  ServerConfig small_memory;
  small_memory.registry.max_memory_bytes = 100000;  // room for one 400-disc RVE
  ServerHarness m(small_memory);
  ASSERT_TRUE(m.Upload().ok());
  ExpectError(m.Create("r", {1, 2, 3}), grpc::StatusCode::RESOURCE_EXHAUSTED, "memory limit");
}

TEST(ServiceAuth, TokenRequiredWhenSet) {
  ServerConfig config;
  config.auth_token = "s3cret-token";
  ServerHarness h(config);
  ASSERT_TRUE(h.Upload().ok());  // the harness sends the token
  v1::ServerInfo info;
  {
    grpc::ClientContext ctx;
    ExpectError(h.stub().GetServerInfo(&ctx, {}, &info), grpc::StatusCode::UNAUTHENTICATED,
                "Bearer");
  }
  {
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer wrong-token!");
    ExpectError(h.stub().GetServerInfo(&ctx, {}, &info), grpc::StatusCode::UNAUTHENTICATED,
                "Bearer");
  }
  {  // An unauthenticated create changes nothing.
    grpc::ClientContext ctx;
    v1::CreateRvesRequest req;
    req.set_run_id("r");
    req.set_template_name(kTemplate);
    req.add_ids(1);
    v1::CreateRvesResponse out;
    EXPECT_EQ(h.stub().CreateRves(&ctx, req, &out).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }
  ASSERT_TRUE(h.stub().GetServerInfo(h.Context().get(), {}, &info).ok());
  EXPECT_TRUE(info.auth_required());
  EXPECT_EQ(info.num_rves(), 0);
  // grpc's own health service is guarded too.
  auto health = grpc::health::v1::Health::NewStub(h.channel());
  grpc::health::v1::HealthCheckRequest hreq;
  grpc::health::v1::HealthCheckResponse hresp;
  {
    grpc::ClientContext ctx;
    EXPECT_EQ(health->Check(&ctx, hreq, &hresp).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }
  ASSERT_TRUE(health->Check(h.Context().get(), hreq, &hresp).ok());
  EXPECT_EQ(hresp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

// For orchestrators' probes (Kubernetes' gRPC probes send no metadata):
// health answers without the token, nothing else does.
TEST(ServiceAuth, HealthWithoutTokenOpensHealthOnly) {
  ServerConfig config;
  config.auth_token = "s3cret-token";
  config.health_without_token = true;
  ServerHarness h(config);
  auto health = grpc::health::v1::Health::NewStub(h.channel());
  grpc::health::v1::HealthCheckRequest hreq;
  hreq.set_service("rvehub.v1.RveService");
  grpc::health::v1::HealthCheckResponse hresp;
  {
    grpc::ClientContext ctx;
    ASSERT_TRUE(health->Check(&ctx, hreq, &hresp).ok());
    EXPECT_EQ(hresp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
  }
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ExpectError(h.stub().GetServerInfo(&ctx, {}, &info), grpc::StatusCode::UNAUTHENTICATED, "Bearer");
}

TEST(ServiceAuth, OpenWithoutToken) {
  ServerHarness h;
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(h.stub().GetServerInfo(&ctx, {}, &info).ok());
  EXPECT_FALSE(info.auth_required());
  auto health = grpc::health::v1::Health::NewStub(h.channel());
  grpc::ClientContext hctx;
  grpc::health::v1::HealthCheckRequest hreq;
  hreq.set_service("rvehub.v1.RveService");
  grpc::health::v1::HealthCheckResponse hresp;
  ASSERT_TRUE(health->Check(&hctx, hreq, &hresp).ok());
  EXPECT_EQ(hresp.status(), grpc::health::v1::HealthCheckResponse::SERVING);
}

TEST(ServiceTls, EncryptedCallsWithTokenWork) {
  // A throw-away self-signed certificate for 127.0.0.1 (openssl is one of
  // deploy/install_deps.sh's packages).
  const std::string dir = ::testing::TempDir() + "rvehub_tls_" + std::to_string(getpid());
  const std::string cmd = "mkdir -p " + dir +
                          " && openssl req -x509 -newkey rsa:2048 -nodes -keyout " + dir +
                          "/key.pem -out " + dir +
                          "/cert.pem -days 1 -subj /CN=localhost -addext "
                          "subjectAltName=IP:127.0.0.1 >/dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "openssl could not make a certificate";
  absl::StatusOr<std::string> cert = rvehub::ReadTextFile(dir + "/cert.pem");
  absl::StatusOr<std::string> key = rvehub::ReadTextFile(dir + "/key.pem");
  ASSERT_TRUE(cert.ok() && key.ok());
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.tls_cert_pem = *cert;
  config.tls_key_pem = *key;
  config.auth_token = "tls-token";
  SetLogEnabled(false);
  absl::StatusOr<std::unique_ptr<RveServer>> server = RveServer::Start(config);
  ASSERT_TRUE(server.ok()) << server.status();
  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = *cert;
  auto stub =
      v1::RveService::NewStub(grpc::CreateChannel((*server)->address(), grpc::SslCredentials(ssl)));
  v1::ServerInfo info;
  {
    grpc::ClientContext ctx;
    ctx.AddMetadata("authorization", "Bearer tls-token");
    ASSERT_TRUE(stub->GetServerInfo(&ctx, {}, &info).ok());
    EXPECT_TRUE(info.tls());
  }
  {  // A plaintext client cannot talk to the TLS port.
    auto plain = v1::RveService::NewStub(
        grpc::CreateChannel((*server)->address(), grpc::InsecureChannelCredentials()));
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(2));
    ctx.AddMetadata("authorization", "Bearer tls-token");
    EXPECT_FALSE(plain->GetServerInfo(&ctx, {}, &info).ok());
  }
  std::system(("rm -rf " + dir).c_str());
}

TEST(ServiceConcurrency, TwoClientsOnTwoRunsDoNotInterfere) {
  ServerHarness h;
  ASSERT_TRUE(h.Upload().ok());
  ASSERT_TRUE(h.Create("alpha", {1, 2, 3, 4}).ok());
  ASSERT_TRUE(h.Create("beta", {1, 2, 3, 4}).ok());
  // Reference: the same sequence alone on a fresh server.
  ServerHarness ref;
  ASSERT_TRUE(ref.Upload().ok());
  ASSERT_TRUE(ref.Create("alpha", {1, 2, 3, 4}).ok());
  const std::vector<double> fa = Compress(1e-4);
  const std::vector<double> fb = {1, 1e-4, 0, 0, 1, 0, 0, 0, 1};
  constexpr int kSteps = 20;
  v1::ApplyResponse last_a, last_b, last_ref;
  auto drive = [&](const std::string& run, const std::vector<double>& f, v1::ApplyResponse* out,
                   bool* ok) {
    // Each client its own channel, as separate processes would have.
    auto channel = grpc::CreateChannel(h.server().address(), grpc::InsecureChannelCredentials());
    auto stub = v1::RveService::NewStub(channel);
    *ok = true;
    for (int s = 1; s <= kSteps; ++s) {
      v1::ApplyRequest req;
      req.set_run_id(run);
      req.set_step(s);
      req.set_mode(v1::APPLY_MODE_COMMIT);
      for (int id = 1; id <= 4; ++id) {
        v1::Increment* inc = req.add_increments();
        inc->set_id(id);
        for (double v : f) inc->add_delta_f(v);
      }
      grpc::ClientContext ctx;
      if (!stub->Apply(&ctx, req, out).ok() || out->failed() != 0) *ok = false;
    }
  };
  bool ok_a = false, ok_b = false;
  std::thread ta(drive, "alpha", fa, &last_a, &ok_a);
  std::thread tb(drive, "beta", fb, &last_b, &ok_b);
  ta.join();
  tb.join();
  EXPECT_TRUE(ok_a);
  EXPECT_TRUE(ok_b);
  for (int s = 1; s <= kSteps; ++s) {
    ASSERT_TRUE(ref.Apply("alpha", s, v1::APPLY_MODE_COMMIT, {1, 2, 3, 4}, fa, &last_ref).ok());
  }
  ExpectSameState(last_a.results(3).state(), last_ref.results(3).state(), "alpha vs alone");
  EXPECT_FALSE(SameBits(last_a.results(0).state().stress(), last_b.results(0).state().stress()));
  v1::ListRunsResponse runs;
  ASSERT_TRUE(h.stub().ListRuns(h.Context().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 2);
  for (const v1::RunInfo& r : runs.runs()) {
    EXPECT_EQ(r.min_step(), kSteps) << r.run_id();
    EXPECT_EQ(r.max_step(), kSteps) << r.run_id();
  }
}

TEST(ServiceDeadline, UnfinishedRvesStayCommittedAndARetryCompletes) {
  ServerConfig config;
  config.registry.threads = 1;
  ServerHarness h(config);
  ASSERT_TRUE(h.Upload().ok());
  std::vector<std::int64_t> ids;
  for (int k = 0; k < 64; ++k) ids.push_back(k);
  ASSERT_TRUE(h.Create("r", ids).ok());
  v1::ApplyRequest req;
  req.set_run_id("r");
  req.set_step(1);
  req.set_mode(v1::APPLY_MODE_COMMIT);
  for (std::int64_t id : ids) {
    v1::Increment* inc = req.add_increments();
    inc->set_id(id);
    for (double v : Compress(2e-3)) inc->add_delta_f(v);  // a few hundred DEM steps each
  }
  v1::ApplyResponse resp;
  {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(30));
    // On a loaded machine the server may see the deadline pass early and
    // answer before the client gives up, the RVEs not reached skipped.
    const grpc::Status s = h.stub().Apply(&ctx, req, &resp);
    EXPECT_TRUE(s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ||
                (s.ok() && resp.failed() > 0))
        << s.error_code() << " " << s.error_message() << " failed " << resp.failed();
  }
  // Let the server finish the call (RVEs in progress complete; the rest are skipped).
  v1::ListRunsResponse runs;
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ASSERT_TRUE(h.stub().ListRuns(h.Context().get(), {}, &runs).ok());
  ASSERT_EQ(runs.runs_size(), 1);
  EXPECT_EQ(runs.runs(0).min_step(), 0) << "the deadline should have stopped the batch early";
  // The retry completes every RVE: done ones return their stored results.
  ASSERT_TRUE(h.stub().Apply(h.Context().get(), req, &resp).ok());
  EXPECT_EQ(resp.failed(), 0);
  for (int k = 1; k < 64; ++k) {
    ExpectSameState(resp.results(0).state(), resp.results(k).state(), "id " + std::to_string(k));
  }
}

}  // namespace
}  // namespace rvehub::service
