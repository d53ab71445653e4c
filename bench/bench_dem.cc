// Throughput and memory benchmarks of the DEM engine (figures only, never
// pass/fail). See bench/README.md for what each benchmark measures.
//
//   BM_ShearSetDense        engine, undrained simple shear of the SET-dense RVE
//   BM_FixedCellSetDense    engine at fixed cell (same work as the baseline)
//   BM_BaselineAllPairs     plain reference DEM: AoS, all pairs every step
//   BM_BatchApply64         64 RVEs × one small ΔF over the server's worker pool
//   BM_ApplySmallIncrement  one MPM-sized increment (min_steps 1 or 20); ...StressOnly:
//                           the same measuring the stress alone
//   BM_ApplyManyRves        one-step increments on 1 or 4096 RVEs in turn (cache misses)
//   BM_MemoryPerRve         RSS growth and Rve::MemoryBytes() per 400-disc RVE
//
// After the runs a summary line prints the engine/baseline ratio, the batch
// speed-up and the memory figures next to the project's goals.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "rve_server/service/worker_pool.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"

namespace {

namespace dem = rvehub::dem;
namespace service = rvehub::service;

constexpr std::int64_t kShearSteps = 1000;    // DEM steps per iteration (engine)
constexpr std::int64_t kBaselineSteps = 100;  // DEM steps per iteration (baseline)
constexpr int kBatchSize = 64;
constexpr int kMemoryCopies = 1000;
constexpr double kGoalParticleSteps = 30e6;  // ≥ 30 M particle-steps/s/core
constexpr double kGoalBytesPerRve = 64e3;    // ≤ 64 KB per 400-disc RVE

// The prepared SET-dense packing, made once per process (takes seconds).
const dem::RveSnapshot& DensePacking() {
  static const dem::RveSnapshot packing = [] {
    absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet("SET-dense");
    if (!set.ok()) {
      std::fprintf(stderr, "SET-dense: %s\n", set.status().ToString().c_str());
      std::exit(1);
    }
    dem::PreparationReport report;
    absl::StatusOr<dem::RveSnapshot> p = dem::PreparePacking(*set, {}, &report);
    if (!p.ok()) {
      std::fprintf(stderr, "PreparePacking(SET-dense): %s\n", p.status().ToString().c_str());
      std::exit(1);
    }
    std::fprintf(stderr,
                 "prepared SET-dense: N = %zu, e0 = %.4f, p0 = %.1f kPa, Z = %.2f, %lld steps\n",
                 p->radius.size(), report.void_ratio, report.pressure / 1e3, report.coordination,
                 static_cast<long long>(report.steps));
    return *std::move(p);
  }();
  return packing;
}

dem::Rve MakeRve() {
  absl::StatusOr<dem::Rve> rve = dem::Rve::Create(DensePacking());
  if (!rve.ok()) {
    std::fprintf(stderr, "Rve::Create: %s\n", rve.status().ToString().c_str());
    std::exit(1);
  }
  return *std::move(rve);
}

// ---------------------------------------------------------------------------
// Plain reference DEM: array of structs, all-pairs search with the minimum
// image every step, tangential history in an N×N array, the engine's linear
// contact law (kn = E·r*, kt = ratio·kn, Coulomb cap, lever arms to the
// contact point), local non-viscous damping and leapfrog, at a fixed cell.
struct RefParticle {
  double sx, sy;         // reduced coordinates, wrapped into [0, 1)
  double vx, vy, omega;  // m/s, rad/s
  double r, inv_m, inv_i;
  double fx, fy, torque;
};

class ReferenceDem {
 public:
  ReferenceDem(const dem::RveSnapshot& p, double dt)
      : m_(p.material), h_(p.cell), hinv_(p.cell.inverse()), dt_(dt), n_(p.radius.size()) {
    const double kPi = 3.14159265358979323846;
    for (std::size_t i = 0; i < n_; ++i) {
      const double r = p.radius[i];
      const double mass = m_.density * kPi * r * r * m_.thickness * p.controls.mass_scale;
      parts_.push_back({p.sx[i] - std::floor(p.sx[i]), p.sy[i] - std::floor(p.sy[i]), p.vx[i],
                        p.vy[i], p.omega[i], r, 1.0 / mass, 2.0 / (mass * r * r), 0, 0, 0});
    }
    ft_.assign(n_ * n_, 0.0);
    for (const dem::ContactHistory& c : p.contacts) ft_[c.i * n_ + c.j] = c.tangential_force;
  }

  void Step() {
    for (RefParticle& a : parts_) a.fx = a.fy = a.torque = 0.0;
    for (std::size_t i = 0; i < n_; ++i) {
      RefParticle& a = parts_[i];
      for (std::size_t j = i + 1; j < n_; ++j) {
        RefParticle& b = parts_[j];
        double dsx = b.sx - a.sx, dsy = b.sy - a.sy;
        if (dsx > 0.5) dsx -= 1.0;
        if (dsx < -0.5) dsx += 1.0;
        if (dsy > 0.5) dsy -= 1.0;
        if (dsy < -0.5) dsy += 1.0;
        const double dx = h_(0, 0) * dsx + h_(0, 1) * dsy, dy = h_(1, 0) * dsx + h_(1, 1) * dsy;
        const double d2 = dx * dx + dy * dy, rsum = a.r + b.r;
        double& ft = ft_[i * n_ + j];
        if (d2 >= rsum * rsum) {
          ft = 0.0;
          continue;
        }
        const double dist = std::sqrt(d2), overlap = rsum - dist;
        const double nx = dx / dist, ny = dy / dist, tx = -ny, ty = nx;
        const double kn = m_.young_modulus * 2.0 * a.r * b.r / (a.r + b.r);
        const double fn = kn * overlap, li = a.r - 0.5 * overlap, lj = b.r - 0.5 * overlap;
        const double vt = (b.vx - a.vx) * tx + (b.vy - a.vy) * ty - (a.omega * li + b.omega * lj);
        const double limit = m_.friction * fn;
        ft = std::clamp(ft + m_.stiffness_ratio * kn * vt * dt_, -limit, limit);
        const double fx = -fn * nx + ft * tx, fy = -fn * ny + ft * ty;  // on a
        a.fx += fx;
        a.fy += fy;
        a.torque += li * ft;
        b.fx -= fx;
        b.fy -= fy;
        b.torque += lj * ft;
      }
    }
    const double alpha = m_.damping;
    auto damped = [alpha](double f, double v) {
      return f - alpha * std::abs(f) * ((v > 0.0) - (v < 0.0));
    };
    for (RefParticle& a : parts_) {
      a.vx += dt_ * damped(a.fx, a.vx) * a.inv_m;
      a.vy += dt_ * damped(a.fy, a.vy) * a.inv_m;
      a.omega += dt_ * damped(a.torque, a.omega) * a.inv_i;
      const double dx = dt_ * a.vx, dy = dt_ * a.vy;
      a.sx += hinv_(0, 0) * dx + hinv_(0, 1) * dy;
      a.sy += hinv_(1, 0) * dx + hinv_(1, 1) * dy;
      a.sx -= std::floor(a.sx);
      a.sy -= std::floor(a.sy);
    }
  }

  std::size_t num_particles() const { return n_; }
  // Pairs with tangential history (in a packing at rest: the contacts).
  std::size_t Contacts() const {
    return std::count_if(ft_.begin(), ft_.end(), [](double f) { return f != 0.0; });
  }
  Eigen::Vector2d Position(std::size_t i) const {
    return h_ * Eigen::Vector2d(parts_[i].sx, parts_[i].sy);
  }

 private:
  dem::Material m_;
  Eigen::Matrix2d h_, hinv_;
  double dt_;
  std::size_t n_;
  std::vector<RefParticle> parts_;
  std::vector<double> ft_;  // ft_[i·N + j], i < j
};
// ---------------------------------------------------------------------------

// Undrained simple shear: εxx = εyy = 0, L_xy from I = 1e-3 at 100 kPa.
dem::CellControl SimpleShear(const dem::Rve& rve) {
  dem::CellControl control;
  control.xx = {dem::ControlMode::kStrainRate, 0.0};
  control.yy = {dem::ControlMode::kStrainRate, 0.0};
  control.xy = {dem::ControlMode::kStrainRate, rve.QuasiStaticStrainRate(1e-3, 1e5)};
  return control;
}

void EngineCounters(benchmark::State& state, const dem::Rve& rve, const dem::RveState& last) {
  const double steps = static_cast<double>(state.iterations() * kShearSteps);
  state.counters["particle_steps_per_second"] =
      benchmark::Counter(steps * rve.num_particles(), benchmark::Counter::kIsRate);
  state.counters["steps_per_second"] = benchmark::Counter(steps, benchmark::Counter::kIsRate);
  state.counters["neighbour_pairs"] = static_cast<double>(rve.num_neighbour_pairs());
  state.counters["contacts"] = static_cast<double>(last.num_contacts);
}

// Shears one RVE on and on: each iteration adds γ ≈ 1.3 % (1000 steps); the
// RVE is fresh at the start of each run, so a run covers γ ≈ 0 to a few ×10 %.
void BM_ShearSetDense(benchmark::State& state) {
  dem::Rve rve = MakeRve();
  dem::CellControl control = SimpleShear(rve);
  dem::RveState last;
  for (auto _ : state) {
    last = rve.Run(control, kShearSteps);
    benchmark::DoNotOptimize(last);
  }
  EngineCounters(state, rve, last);
  // γ reached at the end of the run (cell flips make h itself unsuitable).
  state.counters["shear_strain"] =
      control.xy.value * rve.time_step() * static_cast<double>(state.iterations() * kShearSteps);
}
BENCHMARK(BM_ShearSetDense)->Unit(benchmark::kMillisecond);

// The engine doing what the baseline does: DEM steps at a fixed cell.
void BM_FixedCellSetDense(benchmark::State& state) {
  dem::Rve rve = MakeRve();
  dem::CellControl control;  // all strain rates 0
  dem::RveState last;
  for (auto _ : state) {
    last = rve.Run(control, kShearSteps);
    benchmark::DoNotOptimize(last);
  }
  EngineCounters(state, rve, last);
}
BENCHMARK(BM_FixedCellSetDense)->Unit(benchmark::kMillisecond);

void BM_BaselineAllPairs(benchmark::State& state) {
  const dem::Rve rve = MakeRve();
  ReferenceDem ref(DensePacking(), rve.time_step());
  for (auto _ : state) {
    for (std::int64_t k = 0; k < kBaselineSteps; ++k) ref.Step();
    benchmark::ClobberMemory();
  }
  const double steps = static_cast<double>(state.iterations() * kBaselineSteps);
  state.counters["particle_steps_per_second"] =
      benchmark::Counter(steps * ref.num_particles(), benchmark::Counter::kIsRate);
  state.counters["steps_per_second"] = benchmark::Counter(steps, benchmark::Counter::kIsRate);
  state.counters["contacts"] = static_cast<double>(ref.Contacts());
}
BENCHMARK(BM_BaselineAllPairs)->Unit(benchmark::kMillisecond);

void BM_BatchApply64(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  std::vector<dem::Rve> rves(kBatchSize, MakeRve());
  std::vector<dem::Rve*> ptrs;
  for (dem::Rve& r : rves) ptrs.push_back(&r);
  Eigen::Matrix3d delta_f;
  delta_f << 1.0, 1e-4, 0.0, 0.0, 1.0 - 5e-5, 0.0, 0.0, 0.0, 1.0;
  const std::vector<Eigen::Matrix3d> increments(kBatchSize, delta_f);
  std::int64_t steps = 0;
  service::WorkerPool pool(threads);
  std::vector<absl::StatusOr<dem::RveState>> results(kBatchSize, absl::UnknownError("not run"));
  for (auto _ : state) {
    pool.ParallelFor(ptrs.size(),
                     [&](std::size_t k) { results[k] = ptrs[k]->Apply(increments[k], {}); });
    for (const absl::StatusOr<dem::RveState>& r : results) {
      if (!r.ok()) {
        state.SkipWithError(r.status().ToString().c_str());
        break;
      }
      steps += r->steps;
    }
  }
  const double increments_done = static_cast<double>(state.iterations()) * kBatchSize;
  state.counters["rve_increments_per_second"] =
      benchmark::Counter(increments_done, benchmark::Counter::kIsRate);
  state.counters["particle_steps_per_second"] = benchmark::Counter(
      static_cast<double>(steps) * rves[0].num_particles(), benchmark::Counter::kIsRate);
  state.counters["steps_per_apply"] = increments_done > 0 ? steps / increments_done : 0.0;
}
BENCHMARK(BM_BatchApply64)
    ->ArgName("threads")
    ->Apply([](benchmark::internal::Benchmark* b) {
      const int hw = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
      b->Arg(1);
      if (hw > 1) b->Arg(hw);
    })
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// Homogenisation of the sheared packing: Rve::Observe (the fused loop run
// after every increment) against the same sums formed from Rve::Contacts()
// with Eigen, as the definitions read (the way Observe was written before).
dem::Rve ShearedRve() {
  dem::Rve rve = MakeRve();
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 2e-3;
  (void)rve.Apply(shear);
  return rve;
}

void BM_ObserveSetDense(benchmark::State& state) {
  const dem::Rve rve = ShearedRve();
  for (auto _ : state) benchmark::DoNotOptimize(rve.Observe());
}
BENCHMARK(BM_ObserveSetDense)->Unit(benchmark::kMicrosecond);

void BM_ObserveByDefinition(benchmark::State& state) {
  const dem::Rve rve = ShearedRve();
  for (auto _ : state) {
    Eigen::Matrix2d stress = Eigen::Matrix2d::Zero(), fabric = Eigen::Matrix2d::Zero();
    std::vector<Eigen::Vector2d> resultant(rve.num_particles(), Eigen::Vector2d::Zero());
    double force_sum = 0.0, unbalanced = 0.0;
    for (const dem::ContactForce& c : rve.Contacts()) {
      const Eigen::Vector2d f = c.ForceOnI();
      stress += f * c.branch.transpose();
      fabric += c.normal * c.normal.transpose();
      force_sum += f.norm();
      resultant[c.i] += f;
      resultant[c.j] -= f;
    }
    for (const Eigen::Vector2d& r : resultant) unbalanced += std::hypot(r.x(), r.y());
    benchmark::DoNotOptimize(stress);
    benchmark::DoNotOptimize(fabric);
    benchmark::DoNotOptimize(unbalanced / force_sum);
  }
}
BENCHMARK(BM_ObserveByDefinition)->Unit(benchmark::kMicrosecond);

// The MPM-sized increment the benchmarks below apply: simple shear 1e-6 with
// a little compression, [-].
Eigen::Matrix3d SmallIncrement() {
  Eigen::Matrix3d delta_f = Eigen::Matrix3d::Identity();
  delta_f(0, 1) = 1e-6;
  delta_f(1, 1) = 1.0 - 5e-7;
  return delta_f;
}

// SmallIncrement() applied again and again to one RVE with `min_steps`.
void ApplySmallIncrements(benchmark::State& state, std::int64_t min_steps,
                          const dem::ApplyOptions& options) {
  dem::RveSnapshot packing = DensePacking();
  packing.controls.min_steps = min_steps;
  dem::Rve rve = *dem::Rve::Create(packing);
  const Eigen::Matrix3d delta_f = SmallIncrement();
  std::int64_t steps = 0;
  for (auto _ : state) {
    absl::StatusOr<dem::RveState> s = rve.Apply(delta_f, options);
    if (!s.ok()) {
      state.SkipWithError(s.status().ToString().c_str());
      break;
    }
    steps += s->steps;
  }
  state.counters["steps_per_apply"] =
      static_cast<double>(steps) /
      static_cast<double>(std::max<std::int64_t>(1, state.iterations()));
}

// One MPM-sized increment (strain 1e-6) with the quasi-static criterion
// alone (min_steps 1): one DEM step plus the homogenisation.
void BM_ApplySmallIncrement(benchmark::State& state) {
  ApplySmallIncrements(state, state.range(0), {});
}
BENCHMARK(BM_ApplySmallIncrement)
    ->ArgName("min_steps")
    ->Arg(1)
    ->Arg(20)
    ->Unit(benchmark::kMicrosecond);

// The one-step increment with ApplyOptions::stress_only, as an MPM step
// between outputs asks for it: the last step sums the stress alone.
void BM_ApplySmallIncrementStressOnly(benchmark::State& state) {
  dem::ApplyOptions options;
  options.stress_only = true;
  ApplySmallIncrements(state, 1, options);
}
BENCHMARK(BM_ApplySmallIncrementStressOnly)->Unit(benchmark::kMicrosecond);

// One-step increments (min_steps 1) on `rves` RVEs in turn, as an MPM step
// walks its points: with thousands of RVEs each increment starts from data
// that left the caches since its RVE's last increment (the footing-dense case
// holds 7776 RVEs, ~0.5 GB). The ratio to rves:1 is the price of that.
void BM_ApplyManyRves(benchmark::State& state) {
  dem::RveSnapshot packing = DensePacking();
  packing.controls.min_steps = 1;
  std::vector<dem::Rve> rves(static_cast<std::size_t>(state.range(0)), *dem::Rve::Create(packing));
  const Eigen::Matrix3d delta_f = SmallIncrement();
  std::size_t next = 0;
  for (auto _ : state) {
    absl::StatusOr<dem::RveState> s = rves[next].Apply(delta_f);
    if (!s.ok()) {
      state.SkipWithError(s.status().ToString().c_str());
      break;
    }
    next = next + 1 == rves.size() ? 0 : next + 1;
  }
}
BENCHMARK(BM_ApplyManyRves)->ArgName("rves")->Arg(1)->Arg(4096)->Unit(benchmark::kMicrosecond);

// Resident set size, bytes (/proc/self/statm: second field, in pages).
double ResidentBytes() {
  std::ifstream statm("/proc/self/statm");
  long size = 0, resident = 0;
  statm >> size >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE));
}

// Timed: creating 1000 RVEs from the packing. Counters: RSS growth and
// Rve::MemoryBytes() per RVE. malloc_trim first, so that heap freed by earlier
// benchmarks is not silently reused and hidden from the RSS growth.
void BM_MemoryPerRve(benchmark::State& state) {
  const dem::RveSnapshot& packing = DensePacking();
  double rss = 0.0, state_bytes = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    malloc_trim(0);
    std::vector<dem::Rve> rves;
    rves.reserve(kMemoryCopies);
    const double before = ResidentBytes();
    state.ResumeTiming();
    for (int k = 0; k < kMemoryCopies; ++k) rves.push_back(*dem::Rve::Create(packing));
    state.PauseTiming();
    rss = (ResidentBytes() - before) / kMemoryCopies;
    state_bytes = static_cast<double>(rves.back().MemoryBytes());
    rves.clear();
    state.ResumeTiming();
  }
  state.counters["rss_bytes_per_rve"] = rss;
  state.counters["state_bytes_per_rve"] = state_bytes;
}
BENCHMARK(BM_MemoryPerRve)->Iterations(1)->Unit(benchmark::kMillisecond);

// Console reporter that also keeps each benchmark's counters (the median
// aggregate when repetitions are on, else the mean over the runs).
class SummaryReporter : public benchmark::ConsoleReporter {
 public:
  explicit SummaryReporter(OutputOptions options) : ConsoleReporter(options) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (run.error_occurred) continue;
      const std::string name = run.run_name.str();
      Entry& e = entries_[name];
      if (run.run_type == Run::RT_Aggregate) {
        if (run.aggregate_name != "median") continue;
        e.median = true;
        e.sum.clear();
        e.count = 1;
        for (const auto& [key, c] : run.counters) e.sum[key] = c.value;
        e.sum["us"] = CpuMicroseconds(run);
      } else if (!e.median) {
        ++e.count;
        for (const auto& [key, c] : run.counters) e.sum[key] += c.value;
        e.sum["us"] += CpuMicroseconds(run);
      }
    }
  }
  // Counter `key` of benchmark `name`, NaN when it did not run.
  double Get(const std::string& name, const std::string& key) const {
    auto it = entries_.find(name);
    if (it == entries_.end() || it->second.count == 0) return std::nan("");
    auto c = it->second.sum.find(key);
    return c == it->second.sum.end() ? std::nan("") : c->second / it->second.count;
  }

 private:
  // CPU time per iteration, µs ("us" in Get).
  static double CpuMicroseconds(const Run& run) {
    return run.GetAdjustedCPUTime() * 1e6 / benchmark::GetTimeUnitMultiplier(run.time_unit);
  }
  struct Entry {
    bool median = false;
    int count = 0;
    std::map<std::string, double> sum;
  };
  std::map<std::string, Entry> entries_;
};

// Same state, 100 fixed-cell steps in the engine and in the baseline: the
// largest position difference shows that both integrate the same model.
double BaselineAgreement() {
  dem::Rve rve = MakeRve();
  ReferenceDem ref(DensePacking(), rve.time_step());
  dem::CellControl control;
  constexpr int kSteps = 100;
  rve.Run(control, kSteps);
  for (int k = 0; k < kSteps; ++k) ref.Step();
  const Eigen::Matrix2d h = rve.cell(), hinv = h.inverse();
  double worst = 0.0;
  for (int i = 0; i < rve.num_particles(); ++i) {
    Eigen::Vector2d ds = hinv * (ref.Position(i) - rve.Position(i));
    ds -= ds.array().round().matrix();
    worst = std::max(worst, (h * ds).norm());
  }
  return worst;
}

void PrintSummary(const SummaryReporter& r) {
  const double engine = r.Get("BM_ShearSetDense", "particle_steps_per_second");
  const double fixed = r.Get("BM_FixedCellSetDense", "particle_steps_per_second");
  const double base = r.Get("BM_BaselineAllPairs", "particle_steps_per_second");
  const int hw = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const std::string parallel = "BM_BatchApply64/threads:" + std::to_string(hw) + "/real_time";
  const double inc1 = r.Get("BM_BatchApply64/threads:1/real_time", "rve_increments_per_second");
  const double incn = r.Get(parallel, "rve_increments_per_second");
  const double rss = r.Get("BM_MemoryPerRve/iterations:1", "rss_bytes_per_rve");
  const double bytes = r.Get("BM_MemoryPerRve/iterations:1", "state_bytes_per_rve");
  std::printf("\nSummary (%d hardware threads)\n", hw);
  std::printf("  engine shear        %8.2f M particle-steps/s/core   (goal >= %.0f M)\n",
              engine / 1e6, kGoalParticleSteps / 1e6);
  std::printf("  engine fixed cell   %8.2f M particle-steps/s/core\n", fixed / 1e6);
  std::printf("  baseline all-pairs  %8.2f M particle-steps/s/core\n", base / 1e6);
  std::printf("  ratio engine/baseline: shear %.1fx, fixed cell %.1fx\n", engine / base,
              fixed / base);
  std::printf("  batch of 64: %.1f increments/s on 1 thread, %.1f on %d (speed-up %.2fx)\n", inc1,
              incn, hw, incn / inc1);
  // An increment of one DEM step costs a plain step plus the homogenisation
  // (the sums of its last contact pass, then Observe) and Apply's own work
  // (polar split, rotation, state).
  const double step_us = 1e6 / r.Get("BM_FixedCellSetDense", "steps_per_second");
  const double observe_us = r.Get("BM_ObserveSetDense", "us");
  const double definition_us = r.Get("BM_ObserveByDefinition", "us");
  const double one_us = r.Get("BM_ApplySmallIncrement/min_steps:1", "us");
  const double twenty_us = r.Get("BM_ApplySmallIncrement/min_steps:20", "us");
  const double lean_us = r.Get("BM_ApplySmallIncrementStressOnly", "us");
  std::printf(
      "  increment of one DEM step: %.2f us = plain step %.2f us + %.2f us (%.2f steps: "
      "homogenisation in the step's contact pass, Observe %.2f us, Apply's own work); "
      "a homogenisation pass of its own would cost %.2f us (%.2f steps)\n",
      one_us, step_us, one_us - step_us, (one_us - step_us) / step_us, observe_us, definition_us,
      definition_us / step_us);
  std::printf("  increment of strain 1e-6: %.2f us with min_steps 1, %.2f us with 20 (%.1fx)\n",
              one_us, twenty_us, twenty_us / one_us);
  std::printf(
      "  the same measuring the stress alone (between an MPM run's outputs): %.2f us = plain "
      "step + %.2f us (%.2f steps)\n",
      lean_us, lean_us - step_us, (lean_us - step_us) / step_us);
  std::printf("  memory per 400-disc RVE: RSS %.1f KB, state %.1f KB   (goal <= %.0f KB)\n",
              rss / 1e3, bytes / 1e3, kGoalBytesPerRve / 1e3);
  if (!std::isnan(base)) {
    std::printf("  baseline vs engine after 100 fixed-cell steps: max |dx| = %.2e m\n",
                BaselineAgreement());
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  DensePacking();  // prepare before any timing
  // Tabular counters; colour only on a terminal (--benchmark_color does not
  // reach a reporter made here).
  SummaryReporter reporter(isatty(STDOUT_FILENO) ? benchmark::ConsoleReporter::OO_ColorTabular
                                                 : benchmark::ConsoleReporter::OO_Tabular);
  benchmark::RunSpecifiedBenchmarks(&reporter);
  PrintSummary(reporter);
  benchmark::Shutdown();
  return 0;
}
