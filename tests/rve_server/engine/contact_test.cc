// Two-disc contact mechanics of the DEM engine (rve_server/engine/rve.cc and
// contact_law.h): the linear and Hertz–Mindlin normal force, the Love–Weber
// stress of one contact, the Coulomb cap, objectivity of the tangential force
// under rigid rotation, rolling resistance and contact bonds.
//
// Conventions (rve.h, contact_law.h): n points from particle i to particle j,
// t = (−n_y, n_x), the force on i is −fn·n + ft·t, stress is tension-positive.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "gtest/gtest.h"
#include "rve_server/engine/contact_law.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

using testing_util::CreateOrDie;
using testing_util::SquareLattice;

constexpr double kPi = std::numbers::pi;

// Round-off tolerance for quantities computed by a few floating-point
// operations from the same inputs.
constexpr double kRoundOff = 1e-12;

struct PairSpec {
  double r1 = 5e-3;         // m, radius of particle 0 (i)
  double r2 = 5e-3;         // m, radius of particle 1 (j)
  double overlap = 1e-5;    // m
  double angle = 0.0;       // rad, direction of n (i → j)
  double preload_ft = 0.0;  // N, tangential force stored in the contact history
  double time_step_factor = 0.5;
  Material material;
};

// Two discs at rest, centred on the middle of a square cell that is 20 r_max
// wide (well above the 2·(2 r_max + skin·r_min) that Create requires).
RveSnapshot MakePair(const PairSpec& spec) {
  RveSnapshot p;
  p.material = spec.material;
  p.controls.time_step_factor = spec.time_step_factor;
  const double side = 20.0 * std::max(spec.r1, spec.r2);
  p.cell = Eigen::Matrix2d::Identity() * side;
  const Eigen::Vector2d n(std::cos(spec.angle), std::sin(spec.angle));
  const double d = spec.r1 + spec.r2 - spec.overlap;
  const Eigen::Vector2d c(0.5 * side, 0.5 * side);
  const Eigen::Vector2d xi = c - 0.5 * d * n, xj = c + 0.5 * d * n;
  p.radius = {spec.r1, spec.r2};
  p.sx = {xi.x() / side, xj.x() / side};
  p.sy = {xi.y() / side, xj.y() / side};
  p.vx = {0.0, 0.0};
  p.vy = {0.0, 0.0};
  p.omega = {0.0, 0.0};
  p.theta = {0.0, 0.0};
  if (spec.preload_ft != 0.0) {
    ContactHistory h;
    h.i = 0;
    h.j = 1;
    h.tangential_force = spec.preload_ft;
    p.contacts.push_back(h);
  }
  return p;
}

// Runs `steps` DEM steps at a fixed cell.
void StepAtFixedCell(Rve& rve, int steps) {
  CellControl still;  // every component strain-rate controlled at 0
  rve.Run(still, steps);
}

ContactForce OnlyContact(const Rve& rve) {
  const std::vector<ContactForce> c = rve.Contacts();
  EXPECT_EQ(c.size(), 1u);
  return c.empty() ? ContactForce{} : c[0];
}

double Mass(const Material& m, double r) { return m.density * kPi * r * r * m.thickness; }

// --- (a) Linear normal force and the Love–Weber stress of one contact. ---

class LinearPairTest : public testing::TestWithParam<std::pair<double, double>> {};

TEST_P(LinearPairTest, NormalForceIsKnTimesOverlap) {
  PairSpec spec;
  spec.r1 = GetParam().first;
  spec.r2 = GetParam().second;
  spec.overlap = 2e-5;
  spec.angle = 0.3;
  const Rve rve = CreateOrDie(MakePair(spec));
  const ContactForce c = OnlyContact(rve);
  const Material& m = spec.material;
  const double r_star = 2.0 * spec.r1 * spec.r2 / (spec.r1 + spec.r2);
  const double kn = m.young_modulus * r_star;
  EXPECT_EQ(c.i, 0u);
  EXPECT_EQ(c.j, 1u);
  EXPECT_NEAR(c.kn, kn, kRoundOff * kn);
  EXPECT_NEAR(c.kt, m.stiffness_ratio * kn, kRoundOff * kn);
  // The overlap comes from x = h·s of coordinates near 0.5 of a 20 r_max
  // cell: absolute error ~1e-16 × 0.14 m, i.e. ~1e-12 of a 2e-5 m overlap.
  EXPECT_NEAR(c.overlap, spec.overlap, 1e-9 * spec.overlap);
  EXPECT_NEAR(c.normal_force, kn * c.overlap, kRoundOff * kn * c.overlap);
  EXPECT_NEAR(c.normal.x(), std::cos(spec.angle), 1e-12);
  EXPECT_NEAR(c.normal.y(), std::sin(spec.angle), 1e-12);
  EXPECT_EQ(c.tangential_force, 0.0);  // a fresh contact has no tangential history
}

TEST_P(LinearPairTest, StepPushesTheDiscsApartWithFnOverMass) {
  PairSpec spec;
  spec.r1 = GetParam().first;
  spec.r2 = GetParam().second;
  spec.angle = -0.7;
  spec.material.damping = 0.0;
  Rve rve = CreateOrDie(MakePair(spec));
  const ContactForce c = OnlyContact(rve);
  StepAtFixedCell(rve, 1);
  const RveSnapshot after = rve.ToSnapshot();
  const double dt = rve.time_step();
  // Leapfrog from rest: v = dt·F/m, with F_i = −fn·n and F_j = +fn·n.
  const Eigen::Vector2d vi(after.vx[0], after.vy[0]), vj(after.vx[1], after.vy[1]);
  const Eigen::Vector2d expect_i = -dt * c.normal_force / Mass(spec.material, spec.r1) * c.normal;
  const Eigen::Vector2d expect_j = dt * c.normal_force / Mass(spec.material, spec.r2) * c.normal;
  EXPECT_LT((vi - expect_i).norm(), kRoundOff * expect_i.norm());
  EXPECT_LT((vj - expect_j).norm(), kRoundOff * expect_j.norm());
}

TEST_P(LinearPairTest, LoveWeberStressOfThePair) {
  PairSpec spec;
  spec.r1 = GetParam().first;
  spec.r2 = GetParam().second;
  spec.angle = 1.1;
  spec.material.friction = 10.0;  // keep the preload below the Coulomb limit
  spec.preload_ft = 0.3;          // N: exercises the t⊗n part of the stress
  const RveSnapshot packing = MakePair(spec);
  const Rve rve = CreateOrDie(packing);
  const ContactForce c = OnlyContact(rve);
  ASSERT_EQ(c.tangential_force, spec.preload_ft);
  const double volume = packing.cell.determinant() * spec.material.thickness;  // m³
  // Hand formula: F_i = −fn·n + ft·t, branch = d·n, σ = sym(F_i ⊗ branch)/V.
  const double d = spec.r1 + spec.r2 - c.overlap;
  const Eigen::Vector2d n = c.normal, t(-n.y(), n.x());
  const Eigen::Matrix2d f_branch =
      d * (-c.normal_force * n * n.transpose() + c.tangential_force * t * n.transpose());
  const Eigen::Matrix2d expect = 0.5 * (f_branch + f_branch.transpose()) / volume;
  const RveState s = rve.Observe();
  const double scale = expect.norm();
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      EXPECT_NEAR(s.stress(a, b), expect(a, b), kRoundOff * scale) << a << b;
    }
  }
  for (int k = 0; k < 3; ++k) {  // plane strain RVE: no out-of-plane stress
    EXPECT_EQ(s.stress(2, k), 0.0);
    EXPECT_EQ(s.stress(k, 2), 0.0);
  }
  EXPECT_LT(s.stress.trace(), 0.0);  // a compressed contact: tension-positive σ is negative
  EXPECT_NEAR(s.volume, volume, kRoundOff * volume);
  EXPECT_EQ(s.num_contacts, 1);
  EXPECT_TRUE(s.fabric_defined);
  EXPECT_NEAR(s.fabric(0, 1), n.x() * n.y(), 1e-14);  // φ = n⊗n for one contact
}

INSTANTIATE_TEST_SUITE_P(EqualAndUnequalRadii, LinearPairTest,
                         testing::Values(std::pair(5e-3, 5e-3), std::pair(3e-3, 7e-3)));

// --- (b) Coulomb cap. ---

TEST(CoulombTest, PreloadAboveTheLimitIsCappedToMuFn) {
  for (double sign : {1.0, -1.0}) {
    PairSpec spec;
    spec.r1 = 4e-3;
    spec.r2 = 6e-3;
    spec.material.damping = 0.0;
    spec.material.friction = 0.5;
    const double fn =
        LinearNormalStiffness(spec.material.young_modulus, spec.r1, spec.r2) * spec.overlap;  // N
    spec.preload_ft = sign * 5.0 * spec.material.friction * fn;  // 5× the limit
    Rve rve = CreateOrDie(MakePair(spec));
    const ContactForce before = OnlyContact(rve);
    ASSERT_EQ(before.tangential_force, spec.preload_ft);  // Create stores, the step caps
    StepAtFixedCell(rve, 1);
    // The cap uses fn at the positions of the force evaluation (before the
    // step moved the discs).
    const ContactForce after = OnlyContact(rve);
    EXPECT_NEAR(after.tangential_force, sign * spec.material.friction * before.normal_force,
                kRoundOff * spec.material.friction * before.normal_force)
        << "sign " << sign;
  }
}

TEST(CoulombTest, SlidingContactStaysOnTheCoulombLimit) {
  PairSpec spec;
  spec.material.damping = 0.0;
  spec.material.friction = 0.4;
  spec.overlap = 5e-5;
  // Small Δt keeps the free pair in contact: it would otherwise bounce apart
  // within a few steps (quarter normal period ≈ 110 steps at this factor).
  spec.time_step_factor = 0.01;
  RveSnapshot p = MakePair(spec);
  const Rve probe = CreateOrDie(p);
  const double kt = OnlyContact(probe).kt;
  const double fn0 = OnlyContact(probe).normal_force;
  // Particle j slides along +t: ft grows by kt·v·Δt per step and reaches the
  // limit μ·fn in about 4 steps.
  const double v = 0.25 * spec.material.friction * fn0 / (kt * probe.time_step());
  p.vx[1] = -v * std::sin(spec.angle);
  p.vy[1] = v * std::cos(spec.angle);
  Rve rve = CreateOrDie(p);
  double prev_ft = 0.0;
  for (int step = 0; step < 20; ++step) {
    const double fn = OnlyContact(rve).normal_force;  // at the force evaluation of this step
    StepAtFixedCell(rve, 1);
    const double ft = OnlyContact(rve).tangential_force;
    const double limit = spec.material.friction * fn;
    EXPECT_LE(ft, limit * (1 + kRoundOff)) << "step " << step;
    EXPECT_GT(ft, 0.0) << "ft must follow the slip direction +t, step " << step;
    if (step >= 8) {  // sliding: |ft| == μ·fn exactly
      EXPECT_NEAR(ft, limit, kRoundOff * limit) << "step " << step;
    } else if (step == 0) {
      // First step: ft = kt·v·Δt exactly (velocities are those set).
      EXPECT_NEAR(ft, kt * v * rve.time_step(), kRoundOff * ft);
    }
    // ft grows until it slides, then follows μ·fn, which shrinks by < 1 %
    // per step as the free pair slowly separates.
    EXPECT_GE(ft, prev_ft * (1 - 0.01)) << "step " << step;
    prev_ft = ft;
  }
}

// Lowering the friction clamps the stored tangential forces at once, so the
// state right after SetFriction is admissible; a bad μ changes nothing.
TEST(CoulombTest, SetFrictionClampsStoredForces) {
  PairSpec spec;
  spec.material.friction = 0.5;
  spec.preload_ft = -0.4 * LinearNormalStiffness(spec.material.young_modulus, spec.r1, spec.r2) *
                    spec.overlap;  // N, 80 % of the limit at μ = 0.5
  Rve rve = CreateOrDie(MakePair(spec));
  EXPECT_EQ(rve.SetFriction(-0.1).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(rve.SetFriction(std::nan("")).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(rve.material().friction, 0.5);
  ASSERT_TRUE(rve.SetFriction(0.1).ok());
  EXPECT_EQ(rve.material().friction, 0.1);
  const ContactForce c = OnlyContact(rve);
  EXPECT_NEAR(c.tangential_force, -0.1 * c.normal_force, kRoundOff * c.normal_force);
  ASSERT_EQ(rve.ToSnapshot().contacts.size(), 1u);
  EXPECT_NEAR(rve.ToSnapshot().contacts[0].tangential_force, -0.1 * c.normal_force,
              kRoundOff * c.normal_force);
}

// --- (c) Objectivity of the tangential force under rigid rotation. ---

// A pair with a preloaded ft is given a rigid-body rotation: particle
// velocities ω×(x − c) about the pair centre c and spins ω. The contact point
// moves rigidly, so the tangential spring must not load: ft stays constant
// while n turns. Lever arms to the contact point (r − δ/2) are essential:
// with r instead, the slip would be −ω·δ per unit time.
TEST(ObjectivityTest, RigidRotationByVelocitiesKeepsTheTangentialForce) {
  PairSpec spec;
  spec.overlap = 5e-5;  // 1 % of r
  spec.material.damping = 0.0;
  spec.material.friction = 10.0;  // the preload must stay elastic
  // Δt = 1e-5·sqrt(m/kn): the pair's own dynamics (normal and tangential
  // oscillation driven by the preload, periods ~1e5 steps) change fn and ft
  // by < 1e-5 over the 200 steps, so what is left is the rigid motion.
  spec.time_step_factor = 1e-5;
  RveSnapshot p = MakePair(spec);
  const double kn = LinearNormalStiffness(spec.material.young_modulus, spec.r1, spec.r2);
  const double ft0 = 0.5 * kn * spec.overlap;  // N, half of fn
  p.contacts.push_back({0, 1, ft0, 0.0, 0.0});
  const Rve probe = CreateOrDie(p);
  constexpr int kSteps = 200;
  constexpr double kTurn = 0.01;  // rad, total rigid rotation over the run
  const double omega = kTurn / (kSteps * probe.time_step());  // rad/s
  const Eigen::Vector2d centre = 0.5 * (probe.Position(0) + probe.Position(1));
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d r = probe.Position(k) - centre;
    p.vx[k] = -omega * r.y();
    p.vy[k] = omega * r.x();
    p.omega[k] = omega;
  }
  Rve rve = CreateOrDie(p);
  const ContactForce start = OnlyContact(rve);
  ASSERT_EQ(start.tangential_force, ft0);

  // One step uses exactly the set velocities: no slip at all (round-off).
  // Lever arms r instead of r − δ/2 would change ft by kt·ω·δ·Δt ≈ 8e-5 ft0.
  StepAtFixedCell(rve, 1);
  EXPECT_NEAR(OnlyContact(rve).tangential_force, ft0, kRoundOff * ft0);

  double max_dev = 0.0;
  for (int step = 1; step < kSteps; ++step) {
    StepAtFixedCell(rve, 1);
    max_dev = std::max(max_dev, std::abs(OnlyContact(rve).tangential_force - ft0));
  }
  // Free discs cannot rotate rigidly (no centripetal force), so their
  // distance grows as d·sqrt(1 + (ωτ)²); the resulting slip loads ft by
  // kt·d·Θ³/3 ≈ 1.1e-4 ft0 at Θ = 0.01 rad. Wrong lever arms would give
  // kt·δ·Θ ≈ 1.6e-2 ft0; ignoring the spins, kt·d·Θ ≈ 3 ft0.
  EXPECT_LT(max_dev, 1e-3 * ft0);
  const ContactForce end = OnlyContact(rve);
  // The normal turned with the pair: tan(Δangle) = ωτ for free flight.
  const double turned =
      std::atan2(end.normal.y(), end.normal.x()) - std::atan2(start.normal.y(), start.normal.x());
  EXPECT_NEAR(turned, std::atan(kTurn), 1e-3 * kTurn);
  EXPECT_GT(end.normal_force, 0.9 * start.normal_force);  // still firmly in contact
}

// Apply of a pure rotation ΔF = R rotates the cell, the positions and the
// velocities: ft (a scalar along t) must be unchanged and every contact force
// vector rotated by R, compared with the same steps under ΔF = I.
TEST(ObjectivityTest, ApplyOfAPureRotationRotatesTheForceAndKeepsFt) {
  PairSpec spec;
  spec.r1 = 4e-3;
  spec.r2 = 6e-3;
  spec.overlap = 4e-5;
  spec.angle = 0.2;
  spec.material.friction = 10.0;
  spec.material.damping = 0.0;
  spec.time_step_factor = 1e-5;  // the pair barely moves during Apply's min_steps
  spec.preload_ft =
      0.5 * LinearNormalStiffness(spec.material.young_modulus, spec.r1, spec.r2) * spec.overlap;
  RveSnapshot p = MakePair(spec);
  // A common drift plus a normal approach (no tangential relative velocity):
  // Apply must rotate the velocities with the cell, or the approach would
  // turn into tangential slip (Δft ≈ 1e-5 ft0 over the 20 steps).
  const Eigen::Vector2d n(std::cos(spec.angle), std::sin(spec.angle));
  const Eigen::Vector2d drift(0.05, -0.02);  // m/s
  p.vx = {drift.x() + 0.025 * n.x(), drift.x() - 0.025 * n.x()};
  p.vy = {drift.y() + 0.025 * n.y(), drift.y() - 0.025 * n.y()};
  Rve reference = CreateOrDie(p);
  Rve rotated = CreateOrDie(p);
  constexpr double kAngle = 0.4;  // rad, below Controls::max_rotation = 0.5
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
  rot.topLeftCorner<2, 2>() << std::cos(kAngle), -std::sin(kAngle), std::sin(kAngle),
      std::cos(kAngle);
  const Eigen::Matrix2d r2 = rot.topLeftCorner<2, 2>();
  ASSERT_TRUE(reference.Apply(Eigen::Matrix3d::Identity()).ok());
  absl::StatusOr<RveState> s_rot = rotated.Apply(rot);
  ASSERT_TRUE(s_rot.ok()) << s_rot.status();
  const ContactForce a = OnlyContact(reference), b = OnlyContact(rotated);
  // Both ran the same 20 steps of the same dynamics, one in a rotated frame:
  // differences are round-off of the rotation (~1e-16 of |x| ≈ 0.1 m, i.e.
  // ~1e-12 of the 4e-5 m overlap).
  EXPECT_NEAR(b.tangential_force, a.tangential_force, 1e-9 * spec.preload_ft);
  EXPECT_NEAR(b.tangential_force, spec.preload_ft, 1e-6 * spec.preload_ft);
  EXPECT_NEAR(b.normal_force, a.normal_force, 1e-9 * a.normal_force);
  const Eigen::Vector2d fa = r2 * a.ForceOnI(), fb = b.ForceOnI();
  EXPECT_LT((fb - fa).norm(), 1e-9 * fa.norm());
  EXPECT_LT((b.branch - r2 * a.branch).norm(), 1e-12 * a.branch.norm());
  // Stress is rotated as R σ Rᵀ.
  const Eigen::Matrix2d sa = reference.Observe().stress.topLeftCorner<2, 2>();
  const Eigen::Matrix2d sb = s_rot->stress.topLeftCorner<2, 2>();
  EXPECT_LT((sb - r2 * sa * r2.transpose()).norm(), 1e-9 * sa.norm());
  EXPECT_GT((sb - sa).norm(), 0.1 * sa.norm());  // the rotation did change σ
}

// The same for a whole packing with damping: a sheared 4×4 lattice (all
// contacts loaded, tangential history and velocities set), then ΔF = R vs
// ΔF = I. Local damping acts in the cell's rotated frame, so even the damped
// dynamics of the 20 steps are exactly rotated.
TEST(ObjectivityTest, ApplyOfARotationIsObjectiveForADampedPacking) {
  constexpr int kSide = 4;
  constexpr double kR = 5e-3, kSpacing = 2 * kR * 0.998;
  RveSnapshot p = SquareLattice(
      kSide, kSpacing, [](int x, int y) { return kR * (1.0 + 0.002 * ((3 * x + y) % 4)); });
  p.material.damping = 0.1;
  const std::size_t n = p.radius.size();
  Rve start = CreateOrDie(p);
  CellControl shear;
  shear.xy = {ControlMode::kStrainRate, 5e-5 / start.time_step()};
  start.Run(shear, 40);
  RveSnapshot loaded = start.ToSnapshot();
  // Off-balance velocities, so that the net forces and hence the damping
  // forces are not negligible during the 20 steps of Apply.
  for (std::size_t i = 0; i < n; ++i) {
    loaded.vx[i] = 0.02 * std::sin(1.7 * i + 0.3);  // m/s
    loaded.vy[i] = 0.02 * std::cos(2.3 * i);
    loaded.omega[i] = 3.0 * std::sin(0.9 * i);  // rad/s
  }
  Rve reference = CreateOrDie(loaded), rotated = CreateOrDie(loaded);
  constexpr double kAngle = -0.3;
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
  rot.topLeftCorner<2, 2>() << std::cos(kAngle), -std::sin(kAngle), std::sin(kAngle),
      std::cos(kAngle);
  const Eigen::Matrix2d r2 = rot.topLeftCorner<2, 2>();
  const absl::StatusOr<RveState> sa = reference.Apply(Eigen::Matrix3d::Identity());
  const absl::StatusOr<RveState> sb = rotated.Apply(rot);
  ASSERT_TRUE(sa.ok() && sb.ok());
  const std::vector<ContactForce> ca = reference.Contacts(), cb = rotated.Contacts();
  ASSERT_EQ(ca.size(), cb.size());
  ASSERT_GE(ca.size(), 20u);
  double ft_scale = 0.0;
  for (const ContactForce& c : ca) ft_scale = std::max(ft_scale, std::abs(c.tangential_force));
  ASSERT_GT(ft_scale, 0.0);
  for (std::size_t k = 0; k < ca.size(); ++k) {
    EXPECT_EQ(ca[k].i, cb[k].i);
    EXPECT_EQ(ca[k].j, cb[k].j);
    // Round-off of the rotation, ~1e-16 of 0.04 m on overlaps of ~2e-5 m
    // (~1e-12), grown by 20 steps of dynamics.
    EXPECT_NEAR(cb[k].tangential_force, ca[k].tangential_force, 1e-9 * ft_scale) << k;
    EXPECT_NEAR(cb[k].normal_force, ca[k].normal_force, 1e-9 * ca[k].normal_force) << k;
    EXPECT_LT((cb[k].ForceOnI() - r2 * ca[k].ForceOnI()).norm(), 1e-9 * ca[k].normal_force) << k;
  }
  const Eigen::Matrix2d a = sa->stress.topLeftCorner<2, 2>(), b = sb->stress.topLeftCorner<2, 2>();
  EXPECT_LT((b - r2 * a * r2.transpose()).norm(), 1e-9 * a.norm());
  EXPECT_GT(std::abs(a(0, 1)), 1e-3 * a.norm());  // sheared: the rotation does change σ
}

// --- (d) Hertz–Mindlin, rolling resistance and bonds. ---

TEST(KernelTest, HertzMindlinMatchesTheHandFormula) {
  const double young = 70e9, nu = 0.3, r1 = 2e-3, r2 = 5e-3, overlap = 3e-6;
  const double e_star = young / (2.0 * (1.0 - nu * nu));  // 1/E* = 2(1−ν²)/E
  const double g = young / (2.0 * (1.0 + nu));            // shear modulus
  const double g_star = g / (2.0 * (2.0 - nu));           // 1/G* = 2(2−ν)/G
  const double r_star = r1 * r2 / (r1 + r2);              // R*
  const double a = std::sqrt(r_star * overlap);           // contact half-width
  const HertzResponse h = HertzMindlin(young, nu, r1, r2, overlap);
  EXPECT_NEAR(h.fn, 4.0 / 3.0 * e_star * a * overlap, kRoundOff * h.fn);
  EXPECT_NEAR(h.kn, 2.0 * e_star * a, kRoundOff * h.kn);
  EXPECT_NEAR(h.kt, 8.0 * g_star * a, kRoundOff * h.kt);
  // kn is the derivative dfn/dδ: compare with a central difference
  // (truncation ~(h/δ)² = 1e-6 relative).
  const double step = 1e-3 * overlap;
  const double dfn = (HertzMindlin(young, nu, r1, r2, overlap + step).fn -
                      HertzMindlin(young, nu, r1, r2, overlap - step).fn) /
                     (2.0 * step);
  EXPECT_NEAR(h.kn, dfn, 1e-6 * h.kn);
  const HertzResponse none = HertzMindlin(young, nu, r1, r2, -1e-6);
  EXPECT_EQ(none.kn, 0.0);
  EXPECT_EQ(none.kt, 0.0);
}

TEST(KernelTest, LinearRollingBondAndCoulombKernels) {
  EXPECT_DOUBLE_EQ(EffectiveRadius(3e-3, 6e-3), 4e-3);  // 2·3·6/9 mm
  EXPECT_DOUBLE_EQ(LinearNormalStiffness(600e6, 3e-3, 6e-3), 600e6 * 4e-3);
  // kr = kt·r1·r2·β (N·m/rad).
  EXPECT_DOUBLE_EQ(RollingStiffness(2e6, 3e-3, 6e-3, 0.5), 2e6 * 3e-3 * 6e-3 * 0.5);
  // |M| ≤ η·r_min·fn, zero in tension.
  EXPECT_DOUBLE_EQ(RollingLimit(0.05, 3e-3, 6e-3, 40.0), 0.05 * 3e-3 * 40.0);
  EXPECT_DOUBLE_EQ(RollingLimit(0.05, 6e-3, 3e-3, 40.0), 0.05 * 3e-3 * 40.0);
  EXPECT_EQ(RollingLimit(0.05, 3e-3, 6e-3, -40.0), 0.0);
  // Bond strength c·min(r)² (N).
  EXPECT_DOUBLE_EQ(BondStrength(1e6, 3e-3, 6e-3), 1e6 * 9e-6);
  EXPECT_DOUBLE_EQ(BondStrength(1e6, 6e-3, 3e-3), 1e6 * 9e-6);
  // Coulomb: |ft| ≤ μ·max(fn, 0).
  EXPECT_EQ(CoulombCap(3.0, 10.0, 0.5), 3.0);
  EXPECT_EQ(CoulombCap(7.0, 10.0, 0.5), 5.0);
  EXPECT_EQ(CoulombCap(-7.0, 10.0, 0.5), -5.0);
  EXPECT_EQ(CoulombCap(7.0, -10.0, 0.5), 0.0);
}

TEST(HertzEngineTest, ContactForceFollowsHertzMindlin) {
  PairSpec spec;
  spec.r1 = 4e-3;
  spec.r2 = 6e-3;
  spec.overlap = 1e-5;
  spec.angle = 2.0;
  spec.material.model = ContactModel::kHertzMindlin;
  spec.material.young_modulus = 1e9;
  spec.material.poisson_ratio = 0.2;
  const Rve rve = CreateOrDie(MakePair(spec));
  const ContactForce c = OnlyContact(rve);
  const double nu = spec.material.poisson_ratio, e = spec.material.young_modulus;
  const double e_star = e / (2.0 * (1.0 - nu * nu));
  const double g_star = e / (4.0 * (1.0 + nu) * (2.0 - nu));
  const double a = std::sqrt(spec.r1 * spec.r2 / (spec.r1 + spec.r2) * c.overlap);
  EXPECT_NEAR(c.overlap, spec.overlap, 1e-9 * spec.overlap);  // from x = h·s (see above)
  EXPECT_NEAR(c.normal_force, 4.0 / 3.0 * e_star * a * c.overlap, kRoundOff * c.normal_force);
  EXPECT_NEAR(c.kn, 2.0 * e_star * a, kRoundOff * c.kn);
  EXPECT_NEAR(c.kt, 8.0 * g_star * a, kRoundOff * c.kt);
  // Not the linear law: E·r*·δ would be ~20× larger here.
  EXPECT_LT(c.normal_force, 0.5 * LinearNormalStiffness(e, spec.r1, spec.r2) * c.overlap);
}

TEST(RollingTest, MomentIsMinusKrTimesRelativeRotationCappedByTheLimit) {
  PairSpec spec;
  spec.r1 = 4e-3;
  spec.r2 = 6e-3;
  spec.material.rolling_beta = 1.0;
  spec.material.rolling_eta = 0.05;
  spec.material.damping = 0.0;
  spec.material.friction = 10.0;
  const RveSnapshot base = MakePair(spec);
  const Rve probe = CreateOrDie(base);
  const ContactForce c = OnlyContact(probe);
  const double dt = probe.time_step();
  const double kr = RollingStiffness(c.kt, spec.r1, spec.r2, spec.material.rolling_beta);
  const double limit = RollingLimit(spec.material.rolling_eta, spec.r1, spec.r2, c.normal_force);
  // Relative rotation rates giving 30 % of the limit in one step, and 10×.
  for (double fraction : {0.3, 10.0}) {
    RveSnapshot p = base;
    const double rate = fraction * limit / (kr * dt);  // rad/s, ω_i − ω_j
    p.omega = {0.6 * rate, -0.4 * rate};
    Rve rve = CreateOrDie(p);
    StepAtFixedCell(rve, 1);
    const RveSnapshot after = rve.ToSnapshot();
    ASSERT_EQ(after.contacts.size(), 1u);
    const double expect = -std::min(kr * rate * dt, limit);  // resists ω_i − ω_j > 0
    EXPECT_NEAR(after.contacts[0].rolling_moment, expect, kRoundOff * std::abs(expect))
        << "fraction " << fraction;
  }
}

class BondTest : public testing::Test {
 protected:
  static constexpr double kCohesion = 2e6;  // Pa
  // A linear pair, 4 and 6 mm, barely touching, bonded by BondContacts.
  static PairSpec Spec() {
    PairSpec spec;
    spec.r1 = 4e-3;
    spec.r2 = 6e-3;
    spec.overlap = 1e-9;
    spec.material.bond_cohesion = kCohesion;
    spec.material.damping = 0.0;
    spec.material.friction = 0.5;
    spec.time_step_factor = 0.01;  // accurate leapfrog for the pulls below
    return spec;
  }
  static double Strength() { return kCohesion * 4e-3 * 4e-3; }  // c·min(r)², N
  static RveSnapshot Bonded() {
    Rve rve = CreateOrDie(MakePair(Spec()));
    rve.BondContacts();
    return rve.ToSnapshot();
  }
  // The bonded pair with particle j moved along n so that the gap is `gap`.
  static RveSnapshot WithGap(double gap) {
    RveSnapshot p = Bonded();
    const PairSpec spec = Spec();
    const double side = p.cell(0, 0);
    p.sx[1] = p.sx[0] + (spec.r1 + spec.r2 + gap) / side;
    return p;
  }
};

TEST_F(BondTest, BondContactsStoresCMinRSquared) {
  const RveSnapshot p = Bonded();
  ASSERT_EQ(p.contacts.size(), 1u);
  EXPECT_EQ(p.contacts[0].bond_strength, BondStrength(kCohesion, 4e-3, 6e-3));
  EXPECT_NEAR(p.contacts[0].bond_strength, Strength(), kRoundOff * Strength());
  const Rve rve = CreateOrDie(p);
  EXPECT_TRUE(OnlyContact(rve).bonded);
}

TEST_F(BondTest, HoldsTensionBelowTheStrengthAndBreaksAbove) {
  const double kn = LinearNormalStiffness(Spec().material.young_modulus, 4e-3, 6e-3);
  for (double fraction : {0.9, 1.1}) {
    const double gap = fraction * Strength() / kn;  // m: tension kn·gap
    Rve rve = CreateOrDie(WithGap(gap));
    const ContactForce before = OnlyContact(rve);
    EXPECT_TRUE(before.bonded);
    EXPECT_NEAR(before.overlap, -gap, 1e-9 * gap + 1e-15);  // from x = h·s
    EXPECT_NEAR(before.normal_force, -fraction * Strength(), 1e-6 * Strength());
    StepAtFixedCell(rve, 1);
    const RveSnapshot after = rve.ToSnapshot();
    if (fraction < 1.0) {
      ASSERT_EQ(after.contacts.size(), 1u);
      EXPECT_EQ(after.contacts[0].bond_strength, Strength());
      const ContactForce c = OnlyContact(rve);
      EXPECT_TRUE(c.bonded);
      // One step at factor 0.01 closes the gap by ~(ωΔt)² ~ 1e-4 of itself.
      EXPECT_NEAR(c.normal_force, -fraction * Strength(), 1e-3 * Strength());
    } else {
      // Broken: no history left and no force between separated discs.
      EXPECT_TRUE(after.contacts.empty());
      EXPECT_TRUE(rve.Contacts().empty());
      const RveState s = rve.Observe();
      EXPECT_EQ(s.num_contacts, 0);
      EXPECT_EQ(s.stress.norm(), 0.0);
    }
  }
}

TEST_F(BondTest, BondCarriesShearBeyondCoulombUntilItsStrength) {
  for (double fraction : {0.9, 1.1}) {
    RveSnapshot p = Bonded();
    p.contacts[0].tangential_force = fraction * Strength();  // far above μ·fn ≈ 0
    Rve rve = CreateOrDie(p);
    const double fn = OnlyContact(rve).normal_force;
    StepAtFixedCell(rve, 1);
    const RveSnapshot after = rve.ToSnapshot();
    if (fraction < 1.0) {
      ASSERT_EQ(after.contacts.size(), 1u);
      EXPECT_EQ(after.contacts[0].bond_strength, Strength());
      EXPECT_EQ(after.contacts[0].tangential_force, fraction * Strength());  // uncapped
    } else {
      // Broken in shear: from now on frictional, so ft is capped to μ·fn.
      const double cap = Spec().material.friction * fn;
      ASSERT_LE(after.contacts.size(), 1u);
      if (!after.contacts.empty()) {
        EXPECT_EQ(after.contacts[0].bond_strength, 0.0);
        EXPECT_NEAR(after.contacts[0].tangential_force, cap, kRoundOff * Strength());
      }
      for (const ContactForce& c : rve.Contacts()) EXPECT_FALSE(c.bonded);
    }
  }
}

// Pulling the pair apart by velocities: the bond is a linear spring kn in
// tension, so a relative velocity v_rel stretches it to v_rel/ω with
// ω = sqrt(kn/m_red). At 0.5 of the strength it holds and rebounds; at 2× it
// breaks and the discs fly apart.
TEST_F(BondTest, PulledApartByVelocities) {
  const PairSpec spec = Spec();
  const double kn = LinearNormalStiffness(spec.material.young_modulus, spec.r1, spec.r2);
  const double m1 = Mass(spec.material, spec.r1), m2 = Mass(spec.material, spec.r2);
  const double w = std::sqrt(kn * (m1 + m2) / (m1 * m2));  // rad/s
  for (double fraction : {0.5, 2.0}) {
    RveSnapshot p = Bonded();
    const double v_rel = fraction * Strength() / kn * w;  // m/s
    // Momentum-free split of v_rel along n = +x.
    p.vx = {-v_rel * m2 / (m1 + m2), v_rel * m1 / (m1 + m2)};
    Rve rve = CreateOrDie(p);
    // Three quarters of a period of the bond spring, 1.5π/(ωΔt) steps: the
    // peak tension is at a quarter, the peak compression at three quarters.
    const int steps = static_cast<int>(std::ceil(1.5 * kPi / (w * rve.time_step())));
    double min_fn = 0.0;
    bool ever_unbonded = false;
    for (int k = 0; k < steps; ++k) {
      StepAtFixedCell(rve, 1);
      for (const ContactForce& c : rve.Contacts()) min_fn = std::min(min_fn, c.normal_force);
      const RveSnapshot now = rve.ToSnapshot();
      ever_unbonded |= now.contacts.empty() || now.contacts[0].bond_strength == 0.0;
    }
    if (fraction < 1.0) {
      EXPECT_FALSE(ever_unbonded);
      // Peak tension 0.5 S (measured −0.500007 S): leapfrog at ωΔt ≈ 0.01 is
      // accurate to ~1e-4, and sampling the peak between steps costs ~1e-4.
      EXPECT_NEAR(min_fn, -fraction * Strength(), 1e-3 * Strength());
      // Back in compression with the same amplitude (elastic, undamped).
      EXPECT_NEAR(OnlyContact(rve).normal_force, fraction * Strength(), 1e-3 * Strength());
    } else {
      EXPECT_TRUE(ever_unbonded);
      // It broke on the step after the tension first exceeded S; the tension
      // grows by ≈ 0.87·kn·v_rel·Δt ≈ 0.02 S per step there.
      EXPECT_LT(min_fn, -Strength());
      EXPECT_GT(min_fn, -1.03 * Strength());
      EXPECT_TRUE(rve.Contacts().empty());
      EXPECT_EQ(rve.Observe().stress.norm(), 0.0);
      const RveSnapshot end = rve.ToSnapshot();
      EXPECT_GT(end.vx[1] - end.vx[0], 0.0) << "separating";
    }
  }
}

}  // namespace
}  // namespace rvehub::dem
