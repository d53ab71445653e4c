// Service overhead of rve_server (figures only, never pass/fail).
//
// A real server on loopback hosts 256 RVEs of the SET-dense template. One
// Apply call advances all of them; we time
//   zero   ΔF = I with Controls::min_steps = 0: no DEM step, so the call is
//          transport + protobuf + registry + the homogenisation of the result;
//   engine the same zero-step increments straight on dem::Rve (no service):
//          the homogenisation alone;
//   full   a default increment (ε_yy = 1e-5, default controls: 20 DEM steps);
//   trial  the same default increment as a TRIAL through the registry (the
//          RVE copied, advanced and dropped), against its COMMIT: what an
//          implicit client's Newton iteration costs over the increment itself.
// and print µs per RVE for each, the service overhead (zero − engine) and its
// share of the compute of a default increment (full − zero + engine). Runs
// with 1 worker thread and with all cores. Each zero-step call (gRPC,
// registry) or engine pass is timed right after a default increment of as
// many other RVEs, so that all meet the caches in the same state, as in a
// run: a warm engine figure made a cold call's cache misses look like
// service.
//
//   build/bench/bench_service [--rves=256] [--reps=20] [--zero-only]
// --zero-only: only the zero-step calls over gRPC, 1 thread (for a profile
// of the service path alone, e.g. under perf record).
#include <google/protobuf/arena.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "rve_server/common/process.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "rve_server/service/log.h"
#include "rve_server/service/server.h"
#include "rve_server/values/material.h"
#include "rve_server/wire/convert.h"
#include "rvehub/v1/rve_service.grpc.pb.h"

namespace {

namespace dem = rvehub::dem;
namespace service = rvehub::service;
namespace wire = rvehub::wire;
namespace v1 = rvehub::v1;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

struct Figures {
  double zero_us = 0, engine_us = 0, full_us = 0;  // per RVE, best of reps
  double registry_us = 0;                          // zero-step batch through the registry, no gRPC
  double ping_us = 0;  // one GetServerInfo round trip (per call, not per RVE)
  // The reply's protobuf work per RVE, best of reps, on one thread: the
  // server's ToProto of the registry's outcomes, serialising, the client's
  // parse onto an arena (what gRPC adds besides transport and its threads).
  double build_us = 0, serialise_us = 0, parse_us = 0;
  // A default increment through the registry as TRIAL and as COMMIT, per RVE.
  double trial_us = 0, commit_us = 0;
};

v1::ApplyRequest Batch(const std::string& run, std::int64_t step, int rves, double strain) {
  v1::ApplyRequest req;
  req.set_run_id(run);
  req.set_step(step);
  req.set_mode(v1::APPLY_MODE_COMMIT);
  for (int id = 0; id < rves; ++id) {
    v1::Increment* inc = req.add_increments();
    inc->set_id(id);
    for (double v : {1.0, 0.0, 0.0, 0.0, 1.0 - strain, 0.0, 0.0, 0.0, 1.0}) inc->add_delta_f(v);
  }
  return req;
}

Figures Measure(const dem::RveSnapshot& packing, int threads, int rves, int reps,
                bool zero_only = false) {
  service::ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.registry.threads = threads;
  absl::StatusOr<std::unique_ptr<service::RveServer>> server = service::RveServer::Start(config);
  if (!server.ok()) {
    std::fprintf(stderr, "cannot start server: %s\n", server.status().ToString().c_str());
    std::exit(1);
  }
  auto channel = grpc::CreateChannel((*server)->address(), grpc::InsecureChannelCredentials());
  auto stub = v1::RveService::NewStub(channel);
  v1::UploadTemplateRequest up;
  up.mutable_entry()->set_name("t");
  wire::ToProto(packing, up.mutable_entry()->mutable_packing());
  v1::TemplateInfo info;
  grpc::ClientContext uctx;
  if (!stub->UploadTemplate(&uctx, up, &info).ok()) std::exit(1);
  auto create = [&](const std::string& run, bool zero_steps) {
    v1::CreateRvesRequest req;
    req.set_run_id(run);
    req.set_template_name("t");
    for (int id = 0; id < rves; ++id) req.add_ids(id);
    dem::Controls c = packing.controls;
    if (zero_steps) c.min_steps = 0;
    wire::ToProto(c, req.mutable_controls());
    v1::CreateRvesResponse resp;
    grpc::ClientContext ctx;
    if (!stub->CreateRves(&ctx, req, &resp).ok()) std::exit(1);
  };
  create("zero", true);
  create("full", false);

  Figures f;
  f.zero_us = f.full_us = f.engine_us = 1e30;
  auto time_call = [&](const v1::ApplyRequest& req) {
    // The reply parsed onto an arena, as the client library does.
    google::protobuf::Arena arena;
    v1::ApplyResponse& resp = *google::protobuf::Arena::CreateMessage<v1::ApplyResponse>(&arena);
    grpc::ClientContext ctx;
    const Clock::time_point t0 = Clock::now();
    const grpc::Status s = stub->Apply(&ctx, req, &resp);
    const double us = Seconds(Clock::now() - t0) * 1e6 / rves;
    if (!s.ok() || resp.failed() != 0) {
      std::fprintf(stderr, "apply failed: %s\n", s.error_message().c_str());
      std::exit(1);
    }
    return us;
  };
  for (int r = 0; r < reps; ++r) {
    f.zero_us = std::min(f.zero_us, time_call(Batch("zero", r + 1, rves, 0.0)));
    if (!zero_only) f.full_us = std::min(f.full_us, time_call(Batch("full", r + 1, rves, 1e-5)));
  }
  if (zero_only) {
    (void)(*server)->Stop(std::chrono::seconds(1));
    return f;
  }
  f.ping_us = 1e30;
  for (int r = 0; r < reps; ++r) {
    v1::ServerInfo info;
    grpc::ClientContext ctx;
    const Clock::time_point t0 = Clock::now();
    if (!stub->GetServerInfo(&ctx, {}, &info).ok()) std::exit(1);
    f.ping_us = std::min(f.ping_us, Seconds(Clock::now() - t0) * 1e6);
  }
  // The registry without gRPC (in-process client path), same increments,
  // each after a default increment of the "full" RVEs as over gRPC: the
  // caches then hold the other RVEs' particles, not these.
  f.registry_us = f.build_us = f.serialise_us = f.parse_us = 1e30;
  {
    std::vector<service::Increment> incs(rves), full_incs(rves);
    for (int k = 0; k < rves; ++k) {
      incs[k].id = full_incs[k].id = k;
      full_incs[k].delta_f(1, 1) = 1.0 - 1e-5;
    }
    for (int r = 0; r < reps; ++r) {
      if (!(*server)
               ->registry()
               .Apply("full", reps + r + 1, service::ApplyMode::kCommit, {}, full_incs)
               .ok()) {
        std::exit(1);
      }
      const Clock::time_point t0 = Clock::now();
      absl::StatusOr<std::vector<service::RveOutcome>> out =
          (*server)->registry().Apply("zero", reps + r + 1, service::ApplyMode::kCommit, {}, incs);
      if (!out.ok()) std::exit(1);
      f.registry_us = std::min(f.registry_us, Seconds(Clock::now() - t0) * 1e6 / rves);
      if (threads != 1) continue;
      Clock::time_point t = Clock::now();
      auto lap = [&t]() {
        const Clock::time_point now = Clock::now();
        const double s = Seconds(now - t);
        t = now;
        return s;
      };
      v1::ApplyResponse resp;
      for (const service::RveOutcome& o : *out) wire::ToProto(o, resp.add_results());
      f.build_us = std::min(f.build_us, lap() * 1e6 / rves);
      std::string bytes;
      resp.SerializeToString(&bytes);
      f.serialise_us = std::min(f.serialise_us, lap() * 1e6 / rves);
      google::protobuf::Arena arena;
      if (!google::protobuf::Arena::CreateMessage<v1::ApplyResponse>(&arena)->ParseFromString(
              bytes)) {
        std::exit(1);
      }
      f.parse_us = std::min(f.parse_us, lap() * 1e6 / rves);
    }
  }
  // TRIAL, then COMMIT, of the same default increment of the "full" RVEs at
  // the step after the last committed one (2·reps so far).
  f.trial_us = f.commit_us = 1e30;
  {
    std::vector<service::Increment> incs(rves);
    for (int k = 0; k < rves; ++k) {
      incs[k].id = k;
      incs[k].delta_f(1, 1) = 1.0 - 1e-5;
    }
    for (int r = 0; r < reps; ++r) {
      const std::int64_t step = 2 * reps + r + 1;
      for (service::ApplyMode mode : {service::ApplyMode::kTrial, service::ApplyMode::kCommit}) {
        const Clock::time_point t0 = Clock::now();
        if (!(*server)->registry().Apply("full", step, mode, {}, incs).ok()) std::exit(1);
        double& best = mode == service::ApplyMode::kTrial ? f.trial_us : f.commit_us;
        best = std::min(best, Seconds(Clock::now() - t0) * 1e6 / rves);
      }
    }
  }
  // The engine alone, same zero-step increments, same number of threads,
  // each pass after a default increment of as many other RVEs (the same
  // cache state as the calls above).
  dem::RveSnapshot zero = packing;
  zero.controls.min_steps = 0;
  std::vector<dem::Rve> engine, others;
  for (int k = 0; k < rves; ++k) {
    engine.push_back(*dem::Rve::Create(zero));
    others.push_back(*dem::Rve::Create(packing));
  }
  Eigen::Matrix3d strain = Eigen::Matrix3d::Identity();
  strain(1, 1) = 1.0 - 1e-5;
  auto pass = [&](std::vector<dem::Rve>& set, const Eigen::Matrix3d& delta_f) {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
      pool.emplace_back([&, t] {
        for (int k = t; k < rves; k += threads) {
          if (!set[k].Apply(delta_f).ok()) std::exit(1);
        }
      });
    }
    for (std::thread& t : pool) t.join();
  };
  for (int r = 0; r < reps; ++r) {
    pass(others, strain);
    const Clock::time_point t0 = Clock::now();
    pass(engine, Eigen::Matrix3d::Identity());
    f.engine_us = std::min(f.engine_us, Seconds(Clock::now() - t0) * 1e6 / rves);
  }
  (void)(*server)->Stop(std::chrono::seconds(1));
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  rvehub::SetUpLongRunningProcess();  // as rve_server and mpm_client run
  int rves = 256, reps = 20;
  bool zero_only = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--zero-only") == 0) zero_only = true;
    if (std::strncmp(argv[i], "--rves=", 7) == 0) rves = std::atoi(argv[i] + 7);
    if (std::strncmp(argv[i], "--reps=", 7) == 0) reps = std::atoi(argv[i] + 7);
  }
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);  // quick drains
  service::SetLogEnabled(false);
  absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet("SET-dense");
  absl::StatusOr<dem::RveSnapshot> packing = dem::PreparePacking(*set);
  if (!packing.ok()) {
    std::fprintf(stderr, "%s\n", packing.status().ToString().c_str());
    return 1;
  }
  std::printf("bench_service: %d RVEs of %zu discs (SET-dense), best of %d calls\n", rves,
              packing->radius.size(), reps);
  std::printf("%8s %12s %12s %12s %12s %14s %14s %10s\n", "threads", "zero us/RVE", "registry us",
              "engine us", "full us/RVE", "overhead us", "compute us", "share");
  if (zero_only) {
    const Figures f = Measure(*packing, 1, rves, reps, /*zero_only=*/true);
    std::printf("zero-step calls over gRPC, 1 thread: %.2f us per RVE\n", f.zero_us);
    return 0;
  }
  const int cores = std::max(1u, std::thread::hardware_concurrency());
  std::vector<int> thread_counts = {1};
  if (cores > 1) thread_counts.push_back(cores);
  for (int threads : thread_counts) {
    const Figures f = Measure(*packing, threads, rves, reps);
    const double overhead = f.zero_us - f.engine_us;             // transport, protobuf, registry
    const double compute = f.full_us - f.zero_us + f.engine_us;  // DEM steps + homogenisation
    std::printf("%8d %12.2f %12.2f %12.2f %12.2f %14.2f %14.2f %9.2f%%   (empty call %.0f us)\n",
                threads, f.zero_us, f.registry_us, f.engine_us, f.full_us, overhead, compute,
                100.0 * overhead / compute, f.ping_us);
    std::printf("         TRIAL %.2f us per RVE, COMMIT %.2f us: TRIAL %+.1f %%\n", f.trial_us,
                f.commit_us, 100.0 * (f.trial_us / f.commit_us - 1.0));
    if (threads == 1) {
      std::printf(
          "         reply protobuf per RVE: ToProto %.2f us, serialise %.2f us, parse %.2f us\n",
          f.build_us, f.serialise_us, f.parse_us);
    }
  }
  std::printf(
      "goals: service overhead <= 1 %% of the compute of a default increment; a TRIAL <= 5 %% "
      "more than its COMMIT\n");
  return 0;
}
