// Energy conservation of the DEM integrator (rve_server/engine/rve.cc): a
// frictionless, undamped packing at a fixed cell is a Hamiltonian system of
// linear springs, so kinetic + elastic energy (Rve::last_step_energy) must be
// conserved up to the O((ωΔt)²) error of the leapfrog/velocity-Verlet scheme.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <utility>

#include "absl/status/statusor.h"
#include "gtest/gtest.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"

namespace rvehub::dem {
namespace {

constexpr int kSteps = 10000;

// Velocity-Verlet's energy error is O((ωΔt)²) with Δt = factor·sqrt(m/kn).
// Measured max |E − E0|/E0 over 1e4 steps for this set-up (fluctuation
// kinetic energy 2–5 % of E0): factor 0.5 → ~2e-3, 0.2 → ~2e-4,
// 0.1 → 5.4e-5, 0.05 → 1.3e-5, 0.02 → ~2e-6. 0.05 meets the 1e-4 bound
// with a 7× margin (0.1 would leave < 2×).
constexpr double kTimeStepFactor = 0.05;
constexpr double kTolerance = 1e-4;  // relative to E0, over kSteps steps

// SET-dense prepared without friction (frictionless compaction), so that the
// packing is in equilibrium with normal forces only. 400 discs, ~0.3 s.
const RveSnapshot& Frictionless() {
  static const RveSnapshot* packing = [] {
    absl::StatusOr<ParameterSet> set = FindParameterSet("SET-dense");
    EXPECT_TRUE(set.ok()) << set.status();
    set->material.friction = 0.0;
    set->preparation.target_void_ratio = 0.0;  // <= 0: compact without friction only
    absl::StatusOr<RveSnapshot> p = PreparePacking(*set);
    EXPECT_TRUE(p.ok()) << p.status();
    return new RveSnapshot(p.ok() ? *std::move(p) : RveSnapshot{});
  }();
  return *packing;
}

// Uniform in [−1, 1) from the top 53 bits: the same on every platform.
double Symmetric(std::mt19937_64& rng) {
  return 2.0 * (static_cast<double>(rng() >> 11) * 0x1.0p-53) - 1.0;
}

// The frictionless packing with damping α, Δt factor, and seeded random
// velocities (about 0.1 m/s, zero total momentum) and spins.
RveSnapshot Agitated(double damping, double time_step_factor) {
  RveSnapshot p = Frictionless();
  p.material.damping = damping;
  p.controls.time_step_factor = time_step_factor;
  std::mt19937_64 rng(20240611);
  const std::size_t n = p.radius.size();
  double mass = 0.0, px = 0.0, py = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    p.vx[i] = 0.17 * Symmetric(rng);  // m/s: kinetic energy ≈ 5 % of the elastic
    p.vy[i] = 0.17 * Symmetric(rng);
    p.omega[i] = 20.0 * Symmetric(rng);          // rad/s
    const double m = p.radius[i] * p.radius[i];  // ∝ mass (same ρ and thickness)
    mass += m;
    px += m * p.vx[i];
    py += m * p.vy[i];
  }
  for (std::size_t i = 0; i < n; ++i) {
    p.vx[i] -= px / mass;
    p.vy[i] -= py / mass;
  }
  for (ContactHistory& c : p.contacts) c.tangential_force = 0.0;  // frictionless
  return p;
}

double Total(const StepEnergy& e) { return e.kinetic + e.elastic; }

struct EnergyRun {
  double e0 = 0.0;           // J, after the first step
  double max_rel_error = 0;  // max |E − E0|/E0
  double final_rel_change = 0;
  double kinetic_min = 0, kinetic_max = 0;                    // J
  Eigen::Vector2d momentum_change = Eigen::Vector2d::Zero();  // kg m/s
  double momentum_scale = 0;                                  // Σ m|v| at the start, kg m/s
};

// Runs kSteps at a fixed cell. `hertz_young` > 0 switches the contact law to
// Hertz–Mindlin with that E (the packing is then off equilibrium, which does
// not matter for energy conservation).
EnergyRun RunAtFixedCell(double damping, double time_step_factor, double hertz_young = 0.0) {
  RveSnapshot start = Agitated(damping, time_step_factor);
  if (hertz_young > 0) {
    start.material.model = ContactModel::kHertzMindlin;
    start.material.young_modulus = hertz_young;
  }
  absl::StatusOr<Rve> rve = Rve::Create(start);
  EXPECT_TRUE(rve.ok()) << rve.status();
  if (!rve.ok()) return {};
  auto momentum = [](const RveSnapshot& p) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    double scale = 0.0;
    for (std::size_t i = 0; i < p.radius.size(); ++i) {
      const double m =
          p.material.density * std::numbers::pi * p.radius[i] * p.radius[i] * p.material.thickness;
      sum += m * Eigen::Vector2d(p.vx[i], p.vy[i]);
      scale += m * std::hypot(p.vx[i], p.vy[i]);
    }
    return std::pair(sum, scale);
  };
  rve->set_track_energy(true);
  CellControl fixed;  // all strain rates 0: fixed cell
  rve->Run(fixed, 1);
  EnergyRun out;
  out.e0 = Total(rve->last_step_energy());
  out.kinetic_min = out.kinetic_max = rve->last_step_energy().kinetic;
  for (int k = 1; k < kSteps; ++k) {
    rve->Run(fixed, 1);
    const StepEnergy& e = rve->last_step_energy();
    out.max_rel_error = std::max(out.max_rel_error, std::abs(Total(e) - out.e0) / out.e0);
    out.kinetic_min = std::min(out.kinetic_min, e.kinetic);
    out.kinetic_max = std::max(out.kinetic_max, e.kinetic);
  }
  out.final_rel_change = (Total(rve->last_step_energy()) - out.e0) / out.e0;
  const auto [p0, scale] = momentum(start);
  out.momentum_change = momentum(rve->ToSnapshot()).first - p0;
  out.momentum_scale = scale;
  return out;
}

TEST(EnergyTest, ConservedWithoutFrictionAndDamping) {
  const EnergyRun r = RunAtFixedCell(/*damping=*/0.0, kTimeStepFactor);
  ASSERT_GT(r.e0, 0.0);
  EXPECT_LT(r.max_rel_error, kTolerance);
  // Not trivially conserved: energy does flow between kinetic and elastic
  // (the kinetic part varies by more than 100× the tolerance of E0).
  EXPECT_GT(r.kinetic_max - r.kinetic_min, 100 * kTolerance * r.e0);
  // Newton's third law: contact forces cancel in pairs, so momentum is
  // conserved to round-off (1e4 steps of sums of ~1e-2 kg m/s terms).
  EXPECT_LT(r.momentum_change.norm(), 1e-12 * r.momentum_scale);  // measured 3e-16
}

TEST(EnergyTest, ErrorScalesWithTheTimeStepSquared) {
  const EnergyRun coarse = RunAtFixedCell(0.0, 2 * kTimeStepFactor);
  const EnergyRun fine = RunAtFixedCell(0.0, kTimeStepFactor);
  ASSERT_GT(fine.max_rel_error, 0.0);
  // Second order: halving Δt divides the error by ≈ 4 (measured 4.0); a
  // first-order scheme would give 2.
  const double ratio = coarse.max_rel_error / fine.max_rel_error;
  EXPECT_GT(ratio, 3.0);
  EXPECT_LT(ratio, 5.3);
}

// Hertz–Mindlin springs store (2/5)·fn·δ and are conservative too. E = 70 GPa
// makes the Hertz forces exceed the linear ones (p rises to ~560 kPa): the
// packing vibrates strongly (kinetic energy 0.09–0.25 J of E0 ≈ 7.6 J).
// Measured max error 1.9e-5 at factor 0.1 and 4.4e-6 at 0.05.
TEST(EnergyTest, HertzMindlinIsConservativeToo) {
  const EnergyRun r = RunAtFixedCell(/*damping=*/0.0, kTimeStepFactor, /*hertz_young=*/70e9);
  ASSERT_GT(r.e0, 0.0);
  EXPECT_LT(r.max_rel_error, kTolerance);
  EXPECT_GT(r.kinetic_max - r.kinetic_min, 100 * kTolerance * r.e0);
}

// The bookkeeping itself: the reported energy is ½Σ kn δ² at the positions
// the forces were evaluated at, and ½Σ m u² + ½Σ I w² with the synchronous
// velocities u = (v_before + v_after)/2 of that step (velocity Verlet).
TEST(EnergyTest, StepEnergyIsThatOfTheForceEvaluation) {
  absl::StatusOr<Rve> rve = Rve::Create(Agitated(/*damping=*/0.0, kTimeStepFactor));
  ASSERT_TRUE(rve.ok()) << rve.status();
  // Off by default: the step then measures no energy at all.
  EXPECT_EQ(rve->last_step_energy().kinetic, 0.0);
  rve->set_track_energy(true);
  CellControl fixed;
  rve->Run(fixed, 5);
  const RveSnapshot before = rve->ToSnapshot();
  double elastic = 0.0;  // J
  for (const ContactForce& c : rve->Contacts()) elastic += 0.5 * c.normal_force * c.overlap;
  rve->Run(fixed, 1);
  const RveSnapshot after = rve->ToSnapshot();
  double kinetic = 0.0;  // J
  for (std::size_t i = 0; i < before.radius.size(); ++i) {
    const double r = before.radius[i];
    const double m = before.material.density * std::numbers::pi * r * r * before.material.thickness;
    const double ux = 0.5 * (before.vx[i] + after.vx[i]), uy = 0.5 * (before.vy[i] + after.vy[i]);
    const double uw = 0.5 * (before.omega[i] + after.omega[i]);
    kinetic += 0.5 * m * (ux * ux + uy * uy) + 0.25 * m * r * r * uw * uw;  // I = ½ m r²
  }
  const StepEnergy& e = rve->last_step_energy();
  // Same formulas summed in a different order: round-off only.
  EXPECT_NEAR(e.elastic, elastic, 1e-12 * elastic);
  EXPECT_NEAR(e.kinetic, kinetic, 1e-12 * kinetic);
  EXPECT_GT(e.kinetic, 0.01 * e.elastic);  // both parts matter here
}

// The same check must fail when energy is really dissipated: local damping
// α = 0.1 removes a few percent of E0 over the run.
TEST(EnergyTest, DampingDissipatesMeasurably) {
  const EnergyRun r = RunAtFixedCell(/*damping=*/0.1, kTimeStepFactor);
  ASSERT_GT(r.e0, 0.0);
  EXPECT_GT(r.max_rel_error, 100 * kTolerance);
  EXPECT_LT(r.final_rel_change, -100 * kTolerance);  // lost, not gained
}

}  // namespace
}  // namespace rvehub::dem
