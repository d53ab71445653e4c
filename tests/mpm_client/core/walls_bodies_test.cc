// Walls, rigid bodies and body contact at the soil's surface in the explicit
// MPM solver: supports, friction, shaken bases, platens and reactions.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "mpm_client/core/body_contact.h"
#include "mpm_client/core/elastic.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/shape.h"
#include "mpm_client/core/solver.h"
#include "tests/mpm_client/core/solver_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm {
namespace {

using Eigen::Matrix2d;
using Eigen::Vector2d;

// --- walls and bodies

TEST(WallTest, BlockAtRestOnFixedBaseCarriesItsWeight) {
  const double rho = 2000.0, g = 9.81, youngs = 2e6, nu = 0.3;
  CaseSpec spec = BlockCase(0.05, 16, 12, Vector2d(0.2, 0.0), Vector2d(0.6, 0.4), 2, rho);
  spec.solver.gravity = Vector2d(0.0, -g);
  spec.solver.pic_fraction = 1.0;
  spec.solver.time_step = 0.2 * 0.05 / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  const double weight = TotalMass(solver->points()) * g;
  RunSteps(*solver, 1500);
  const Vector2d r = solver->Reactions()[0];
  std::printf("base reaction %.4f N, weight %.4f N (%+.3f %%), kinetic energy %.3g J\n", -r.y(),
              weight, 100.0 * (-r.y() / weight - 1.0), solver->KineticEnergy());
  EXPECT_NEAR(-r.y(), weight, 0.01 * weight);  // the soil pushes the base down
  EXPECT_NEAR(r.x(), 0.0, 1e-3 * weight);
}

// Mass scaling: s times the inertia, the real weight. The CFL step grows by
// sqrt(s), the block still rests on its real weight, and it settles under
// gravity at g/s (its first step's velocity: Δt·g/s).
TEST(WallTest, AMassScaledBlockRestsOnItsRealWeightWithLongerSteps) {
  const double rho = 2000.0, g = 9.81, youngs = 2e6, nu = 0.3, scale = 100.0;
  CaseSpec spec = BlockCase(0.05, 16, 12, Vector2d(0.2, 0.0), Vector2d(0.6, 0.4), 2, rho);
  spec.solver.gravity = Vector2d(0.0, -g);
  spec.solver.pic_fraction = 1.0;
  spec.solver.wave_modulus = PWaveModulus(youngs, nu);
  spec.solver.cfl = 0.2;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> plain = MakeSolver(spec, &model);
  spec.solver.mass_scale = scale;
  std::unique_ptr<Solver> scaled = MakeSolver(spec, &model);
  EXPECT_NEAR(scaled->dt() / plain->dt(), std::sqrt(scale), 1e-12);
  const double weight = TotalMass(scaled->points()) * g;
  ASSERT_TRUE(scaled->Step().ok());
  double vy = 0.0;  // the top points are still free of the base's wave
  for (std::size_t p = 0; p < scaled->points().size(); ++p)
    vy = std::min(vy, scaled->points().velocity[p].y());
  EXPECT_NEAR(vy, -scaled->dt() * g / scale, 1e-9 * scaled->dt() * g);
  RunSteps(*scaled, 1500);
  const Vector2d r = scaled->Reactions()[0];
  std::printf("mass-scaled block: base reaction %.4f N, weight %.4f N (%+.3f %%)\n", -r.y(), weight,
              100.0 * (-r.y() / weight - 1.0));
  EXPECT_NEAR(-r.y(), weight, 0.01 * weight);
  EXPECT_NEAR(r.x(), 0.0, 1e-3 * weight);
}

TEST(BodyTest, RoughBodyPushedIntoABlockIsResisted) {
  const double rho = 2000.0, youngs = 2e6, nu = 0.3;
  CaseSpec spec = BlockCase(0.05, 16, 12, Vector2d(0.2, 0.0), Vector2d(0.6, 0.4), 2, rho);
  spec.solver.pic_fraction = 0.2;
  spec.solver.time_step = 0.2 * 0.05 / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  spec.bodies = {
      RoughBlock("footing", Vector2d(0.4, 0.45), Vector2d(0.1, 0.05), Vector2d(0.0, -0.05))};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  double impulse = 0.0;
  for (int i = 0; i < 400; ++i) {
    ASSERT_TRUE(solver->Step().ok());
    impulse += solver->Reactions()[1].y() * solver->dt();
  }
  const Vector2d d = solver->BodyDisplacement(0);
  EXPECT_NEAR(d.y(), -0.05 * solver->time(), 1e-15);
  const double mean = impulse / solver->time();
  const double last = solver->Reactions()[1].y();
  std::printf("footing: settlement %.3g m, mean reaction %.4g N, last %.4g N\n", -d.y(), mean,
              last);
  // The soil pushes the footing up, against its motion, and harder with depth.
  EXPECT_GT(mean, 0.0);
  EXPECT_GT(last, mean);
  // Below it, the base carries the load down.
  EXPECT_LT(solver->Reactions()[0].y(), 0.0);
}

TEST(WallTest, BlockSlidingOnFrictionalBaseDeceleratesAtMuG) {
  const double rho = 2000.0, g = 9.81, youngs = 5e6, nu = 0.3, mu = 0.3, h = 0.05;
  const double top = 0.2;
  CaseSpec spec = BlockCase(h, 30, 8, Vector2d(0.2, 0.0), Vector2d(0.6, top), 2, rho);
  spec.solver.gravity = Vector2d(0.0, -g);
  // Some PIC damping: with little, friction-induced rocking grows and the
  // bilateral base then holds the lifting heel, loading the toe more.
  spec.solver.pic_fraction = 0.2;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kFrictional, mu)};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(1.0, 0.0)});
  model.SetStress(Geostatic(solver->points(), rho, g, top, nu));
  const double mass = TotalMass(solver->points());
  auto mean_velocity = [&] { return Momentum(solver->points()).x() / mass; };
  const double t1 = 0.05, t2 = 0.25;
  RunSteps(*solver, static_cast<int>(std::round(t1 / solver->dt())));
  const double v1 = mean_velocity(), time1 = solver->time();
  RunSteps(*solver, static_cast<int>(std::round((t2 - t1) / solver->dt())));
  const double v2 = mean_velocity(), time2 = solver->time();
  const double decel = (v1 - v2) / (time2 - time1);
  std::printf("sliding block: deceleration %.4f m/s2, mu g = %.4f (%+.2f %%)\n", decel, mu * g,
              100.0 * (decel / (mu * g) - 1.0));
  EXPECT_NEAR(decel, mu * g, 0.03 * mu * g);
  EXPECT_GT(v2, 0.0);  // still sliding
}

// At t = 1/f, where a table shaken at v = A sin 2πft is near zero velocity
// and pulls hardest, the base's reaction is the block's inertia: −Rx ≈ M dv/dt
// within 5 %. `mass` in kg, `amplitude` in m/s, `frequency` in Hz.
void ExpectBaseCarriesInertia(Solver& solver, double mass, double amplitude, double frequency) {
  RunTo(solver, 1.0 / frequency);
  const double accel = 2.0 * std::numbers::pi * frequency * amplitude *
                       std::cos(2.0 * std::numbers::pi * frequency * solver.time());
  EXPECT_NEAR(-solver.Reactions()[0].x(), mass * accel, 0.05 * mass * std::abs(accel));
}

// A stiff block on a rough shaken base (a shaking table, v = A sin 2πft):
// the block follows the base. Its mean velocity at the quarter and three
// quarter periods is ±A and its vertical motion nil; the base's reaction is
// the block's inertia, M dv/dt. Measured: the mean velocity equals the base's to 1e-5 m/s.
TEST(WallTest, BlockOnAShakenRoughBaseFollowsIt) {
  const double rho = 2000.0, youngs = 1e9, nu = 0.3, h = 0.05, amplitude = 0.1, frequency = 1.0;
  CaseSpec spec = BlockCase(h, 20, 8, Vector2d(0.25, 0.0), Vector2d(0.75, 0.2), 2, rho);
  spec.solver.pic_fraction = 1.0;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
  Wall base = MakeWall(1, 0.0, ContactKind::kRough);
  base.shaking_amplitude = Vector2d(amplitude, 0.0);
  base.shaking_frequency = frequency;
  spec.walls = {base};
  EXPECT_NEAR(WallVelocity(base, 0.25 / frequency).x(), amplitude, 1e-15);
  EXPECT_EQ(WallVelocity(MakeWall(1, 0.0, ContactKind::kRough), 0.25).norm(), 0.0);
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  const double mass = TotalMass(solver->points());
  for (double quarter : {0.25, 0.75}) {
    RunTo(*solver, quarter / frequency);
    const Vector2d v = Momentum(solver->points()) / mass;
    const double expected =
        amplitude * std::sin(2.0 * std::numbers::pi * frequency * solver->time());
    std::printf("shaken base at t = %.4f s: block velocity %.5f m/s, base %.5f m/s\n",
                solver->time(), v.x(), expected);
    EXPECT_NEAR(v.x(), expected, 0.01 * amplitude);
    EXPECT_NEAR(v.y(), 0.0, 1e-6 * amplitude);
  }
  ExpectBaseCarriesInertia(*solver, mass, amplitude, frequency);
}

// The same block when the whole grid rides the table (SolverSpec::
// shaking_amplitude, the box's frame): it stays at rest relative to the box
// (its mean velocity there within 1 % of the amplitude at the quarter
// periods) while the base again carries its inertia, −Rx ≈ M dv/dt; the
// frame's displacement is the velocity's integral.
TEST(WallTest, BlockInAShakenBoxsFrameStaysAtRestInIt) {
  const double rho = 2000.0, youngs = 1e9, nu = 0.3, h = 0.05, amplitude = 0.1, frequency = 1.0;
  CaseSpec spec = BlockCase(h, 20, 8, Vector2d(0.25, 0.0), Vector2d(0.75, 0.2), 2, rho);
  spec.solver.pic_fraction = 1.0;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.solver.shaking_amplitude = Vector2d(amplitude, 0.0);
  spec.solver.shaking_frequency = frequency;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  EXPECT_NEAR(FrameDisplacement(spec.solver, 0.5 / frequency).x(),
              amplitude / (std::numbers::pi * frequency), 1e-15);
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  const double mass = TotalMass(solver->points());
  for (double quarter : {0.25, 0.75}) {
    RunTo(*solver, quarter / frequency);
    const Vector2d v = Momentum(solver->points()) / mass;
    EXPECT_NEAR(v.x(), 0.0, 0.01 * amplitude) << "t " << solver->time();
    EXPECT_NEAR(v.y(), 0.0, 1e-6 * amplitude);
  }
  ExpectBaseCarriesInertia(*solver, mass, amplitude, frequency);
}

TEST(WallTest, ReactionsCloseTheMomentumBalance) {
  // Δ(Σ m v) = (M g − Σ reactions)·Δt every step, whatever the contacts.
  const double rho = 2000.0, g = 9.81, youngs = 2e6, nu = 0.3, h = 0.05;
  CaseSpec spec = BlockCase(h, 16, 12, Vector2d(0.2, 0.0), Vector2d(0.6, 0.4), 2, rho);
  spec.solver.gravity = Vector2d(0.0, -g);
  spec.solver.pic_fraction = 0.3;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kFrictional, 0.5),
                MakeWall(0, 0.2, ContactKind::kSmooth), MakeWall(0, 0.6, ContactKind::kRough)};
  RigidBody pipe;
  pipe.name = "pipe";
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.center = Vector2d(0.4, 0.45);
  pipe.radius = 0.06;
  pipe.contact = ContactKind::kFrictional;
  pipe.friction = 0.3;
  pipe.velocity = {{0.0, Vector2d(0.05, -0.2)}};
  spec.bodies = {pipe};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(0.1, 0.0)});
  const double mass = TotalMass(solver->points());
  double worst = 0.0, body = 0.0;
  for (int i = 0; i < 300; ++i) {
    const Vector2d before = Momentum(solver->points());
    ASSERT_TRUE(solver->Step().ok());
    Vector2d external = mass * spec.solver.gravity;
    for (const Vector2d& r : solver->Reactions()) external -= r;
    const Vector2d change = Momentum(solver->points()) - before;
    worst = std::max(worst, (change - external * solver->dt()).norm() / (mass * g * solver->dt()));
    body += solver->Reactions()[3].y();
  }
  EXPECT_LT(worst, 1e-10);
  EXPECT_GT(body, 0.0);  // the soil resists the pipe going down
}

// --- body contact at the soil's surface

TEST(BodyContactTest, GapsToRectanglesAndCircles) {
  RigidBody box;
  box.half_size = Vector2d(0.5, 0.25);
  const Vector2d c(1.0, 2.0), lp(0.1, 0.05);
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
  // Below the base: the gap is the distance less the point's half-height.
  BodyGap g = GapToBody(box, c, Vector2d(1.2, 1.5), I, lp);
  EXPECT_DOUBLE_EQ(g.gap, 0.25 - 0.05);
  EXPECT_EQ(g.normal, Vector2d(0.0, -1.0));
  EXPECT_TRUE(g.face.isApprox(Vector2d(1.2, 1.55)));
  // Beside it, the half-width counts.
  g = GapToBody(box, c, Vector2d(1.8, 2.1), I, lp);
  EXPECT_NEAR(g.gap, 0.3 - 0.1, 1e-15);
  EXPECT_EQ(g.normal, Vector2d(1.0, 0.0));
  // Off a corner: the distance to the corner along the diagonal, less the
  // reach of the box's inscribed ellipse in that direction.
  g = GapToBody(box, c, Vector2d(1.5 + 0.3, 1.75 - 0.4), I, lp);
  EXPECT_NEAR(g.gap, 0.5 - std::hypot(0.6 * 0.1, 0.8 * 0.05), 1e-15);
  EXPECT_TRUE(g.normal.isApprox(Vector2d(0.6, -0.8)));
  // Inside, near the base: negative, towards the nearest face.
  g = GapToBody(box, c, Vector2d(1.0, 1.8), I, lp);
  EXPECT_NEAR(g.gap, -0.05 - 0.05, 1e-15);
  EXPECT_EQ(g.normal, Vector2d(0.0, -1.0));
  RigidBody pipe;
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.radius = 0.5;
  g = GapToBody(pipe, c, c + Vector2d(0.6, 0.8), I, lp);
  EXPECT_NEAR(g.gap, 0.5 - std::hypot(0.6 * 0.1, 0.8 * 0.05), 1e-15);
  EXPECT_TRUE(g.normal.isApprox(Vector2d(0.6, 0.8)));
}

// A sheared point's material reaches as far as the ellipse through its
// faces' midpoints, not as far as the stretched box its shape functions use.
TEST(BodyContactTest, ShearedPointsReachAsFarAsTheirMaterial) {
  const Vector2d lp0(0.025, 0.025);
  Eigen::Matrix2d shear;
  shear << 1.0, 3.0, 0.0, 1.0;  // simple shear γ = 3 along x
  // Normal to the shear plane the material keeps its half-height; the
  // stretched box would reach lp0·|F e_y| = 0.025·√10.
  EXPECT_DOUBLE_EQ(DomainExtent(shear, lp0, Vector2d(0.0, 1.0)), 0.025);
  EXPECT_NEAR(CurrentHalfSize(shear, lp0).y(), 0.025 * std::sqrt(10.0), 1e-15);
  // Along it, the slanted faces' midpoints at x ± 0.075 and x ± 0.025.
  EXPECT_NEAR(DomainExtent(shear, lp0, Vector2d(1.0, 0.0)), 0.025 * std::sqrt(10.0), 1e-15);
  // The box that holds the slanted parallelogram, for the broad phase.
  EXPECT_TRUE(DomainBound(shear, lp0).isApprox(Vector2d(0.1, 0.025)));
  // Uniform stretch: the half-sizes stretch with it.
  const Eigen::Matrix2d stretch = Eigen::Vector2d(1.2, 0.8).asDiagonal();
  EXPECT_DOUBLE_EQ(DomainExtent(stretch, lp0, Vector2d(0.0, -1.0)), 0.02);
  // A rotation keeps the reach of the inscribed circle, in every direction.
  const double a = 0.3;
  Eigen::Matrix2d rot;
  rot << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  EXPECT_NEAR(DomainExtent(rot, lp0, Vector2d(0.6, 0.8)), 0.025, 1e-15);
  // Under a pipe the point 0.04 m below its surface is 0.015 m clear of it,
  // sheared or not; the stretched box would put it 0.039 m into contact.
  RigidBody pipe;
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.radius = 0.5;
  const Vector2d c(4.5, 3.0), x = c - Vector2d(0.0, 0.54);
  EXPECT_NEAR(GapToBody(pipe, c, x, shear, lp0).gap, 0.015, 1e-15);
  EXPECT_NEAR(GapToBody(pipe, c, x, Eigen::Matrix2d::Identity(), CurrentHalfSize(shear, lp0)).gap,
              0.04 - 0.025 * std::sqrt(10.0), 1e-15);
}

// A footing resting on a layer of points: an edge through the middle of a
// cell lets the contact push that cell's soil half a cell beyond it,
// whatever the points per cell; an edge on a node line, nothing beyond.
TEST(BodyContactTest, CornerOverhangOfAFootingEdgeInsideACell) {
  // Two rows of cells of h = 0.2 m, surface at y = 0.4 m.
  constexpr double h = 0.2;
  auto layer = [](int per_cell, std::vector<Vector2d>& x, std::vector<Vector2d>& lp) {
    x.clear();
    lp.clear();
    const double s = h / per_cell;
    for (int i = 0; i < 5 * per_cell; ++i) {
      for (int j = 0; j < 2 * per_cell; ++j) {
        x.emplace_back((i + 0.5) * s, (j + 0.5) * s);
        lp.emplace_back(0.5 * s, 0.5 * s);
      }
    }
  };
  std::vector<Vector2d> x, lp;
  const Vector2d origin = Vector2d::Zero();
  RigidBody footing;  // x in [0, 2w], bottom at `bottom`
  auto overhang = [&](double w, double bottom) {
    footing.half_size = Vector2d(w, 0.5);
    return CornerOverhang(footing, Vector2d(w, bottom + 0.5), x, lp, origin, h);
  };
  layer(1, x, lp);
  EXPECT_NEAR(overhang(0.25, 0.4), 0.1, 1e-12);   // edge at 0.5, in the cell 0.4-0.6
  EXPECT_EQ(overhang(0.2, 0.4), 0.0);             // edge at 0.4, a node line
  EXPECT_NEAR(overhang(0.23, 0.4), 0.14, 1e-12);  // edge at 0.46
  EXPECT_EQ(overhang(0.25, 0.7), 0.0);            // more than a cell above the surface
  layer(2, x, lp);
  // Between two points' boxes, but inside a cell the grid moves as one.
  EXPECT_NEAR(overhang(0.25, 0.4), 0.1, 1e-12);
  EXPECT_EQ(overhang(0.3, 0.4), 0.0);
  // A wall pushed sideways into the layer's end at x = 1 m: its bottom
  // corner at y = 0.25 m is inside the cells of the second row (0.2-0.4).
  RigidBody wall;
  wall.half_size = Vector2d(0.1, 0.5);
  EXPECT_NEAR(CornerOverhang(wall, Vector2d(1.1, 0.75), x, lp, origin, h), 0.05, 1e-12);
  // A platen wider than the layer: no soil at its corners.
  RigidBody platen;
  platen.half_size = Vector2d(0.7, 0.1);
  EXPECT_EQ(CornerOverhang(platen, Vector2d(0.45, 0.5), x, lp, origin, h), 0.0);
  RigidBody pipe;
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.radius = 0.25;
  EXPECT_EQ(CornerOverhang(pipe, Vector2d(0.5, 0.65), x, lp, origin, h), 0.0);
}

// The share of a node's hat a body fills (the saturated free-surface test):
// ½ on a flat face through the node, ¼ at a corner, the in-grid part of
// the hat inside; a circle by quadrature, exact away from its rim.
TEST(BodyContactTest, ShareOfANodeInsideABody) {
  const double h = 0.1;
  const Vector2d lower(0.0, 0.0), upper(2.0, 2.0);
  RigidBody box;
  box.half_size = Vector2d(0.5, 0.25);
  const Vector2d c(1.0, 1.0);  // the box spans [0.5, 1.5] × [0.75, 1.25]
  EXPECT_DOUBLE_EQ(BodyShareOfNode(box, c, Vector2d(1.0, 1.0), h, lower, upper), 1.0);
  EXPECT_DOUBLE_EQ(BodyShareOfNode(box, c, Vector2d(1.0, 0.75), h, lower, upper), 0.5);
  EXPECT_DOUBLE_EQ(BodyShareOfNode(box, c, Vector2d(1.5, 0.75), h, lower, upper), 0.25);
  EXPECT_DOUBLE_EQ(BodyShareOfNode(box, c, Vector2d(1.0, 0.65), h, lower, upper), 0.0);
  // Half a cell into the body: the hat's ∫ from −½ to 1, 7/8.
  EXPECT_DOUBLE_EQ(BodyShareOfNode(box, c, Vector2d(1.0, 0.8), h, lower, upper), 0.875);
  // At the grid's edge only the in-grid half of the hat counts.
  RigidBody wide;
  wide.half_size = Vector2d(5.0, 0.25);
  EXPECT_DOUBLE_EQ(BodyShareOfNode(wide, c, Vector2d(0.0, 1.0), h, lower, upper), 0.5);
  RigidBody pipe;
  pipe.shape = RigidBody::Shape::kCircle;
  pipe.radius = 0.5;
  EXPECT_DOUBLE_EQ(BodyShareOfNode(pipe, c, c, h, lower, upper), 1.0);
  EXPECT_DOUBLE_EQ(BodyShareOfNode(pipe, c, c + Vector2d(0.0, 0.7), h, lower, upper), 0.0);
  // On the rim of a circle ten cells in radius: nearly a flat face.
  EXPECT_NEAR(BodyShareOfNode(pipe, c, c + Vector2d(0.0, 0.5), h, lower, upper), 0.5, 0.02);
}

// An elastic column under a smooth platen that starts on its surface and
// moves down 1.5 cells: the points' mean nominal strain follows the platen's
// displacement over the height also while the platen lies between node rows
// (the old node-inside-the-body rule gave the strain of the node rows:
// late, then a jump), and the platen's load, averaged over 40 steps (a
// node row emptying as the surface passes it makes single steps flicker by
// up to ~9 %), has no jump at the grid lines. GIMP only: with linear shape
// functions a node row that the soil leaves keeps a vanishing mass (the
// cell-crossing problem) and the contact impulses there feed it.
TEST(BodyTest, PlatenStrainsAColumnAsItMovesBetweenNodeRows) {
  const double rho = 2000.0, youngs = 2e6, nu = 0.3, h = 0.05, height = 0.4, v = 0.05;
  CaseSpec spec = BlockCase(h, 6, 12, Vector2d(0.0, 0.0), Vector2d(0.2, height), 2, rho);
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.pic_fraction = 0.05;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kSmooth), MakeWall(0, 0.0, ContactKind::kSmooth),
                MakeWall(0, 0.2, ContactKind::kSmooth)};
  RigidBody platen;
  platen.name = "platen";
  platen.center = Vector2d(0.1, height + 0.05);
  platen.half_size = Vector2d(0.2, 0.05);
  platen.contact = ContactKind::kSmooth;
  platen.velocity = {{0.0, Vector2d::Zero()}, {0.2, Vector2d(0.0, -v)}};
  spec.bodies = {platen};
  LinearElasticModel model(youngs, nu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  constexpr int kWindow = 40;
  const double modulus = PWaveModulus(youngs, nu) * 0.2;  // N per unit log strain
  double worst = 0.0, worst_load = 0.0, load = 0.0, log_strain = 0.0;
  while (solver->BodyDisplacement(0).y() > -1.5 * h) {
    ASSERT_TRUE(solver->Step().ok());
    const double platen_strain = -solver->BodyDisplacement(0).y() / height;
    double strain = 0.0;
    for (const Matrix2d& f : solver->points().F) strain += 1.0 - f(1, 1);
    strain /= static_cast<double>(solver->points().size());
    if (platen_strain > 0.02) worst = std::max(worst, std::abs(strain / platen_strain - 1.0));
    load += solver->Reactions()[3].y() / kWindow;
    log_strain += -std::log(1.0 - strain) / kWindow;
    if (solver->step() % kWindow == 0) {
      // The hypoelastic model integrates the rate of deformation:
      // σyy = M·ln(1/(1 − ε)), window means of both.
      if (platen_strain > 0.02) {
        worst_load = std::max(worst_load, std::abs(load / (modulus * log_strain) - 1.0));
      }
      load = log_strain = 0.0;
    }
  }
  std::printf(
      "platen: worst |nominal strain / platen strain - 1| = %.3g; worst |load / "
      "(M·ln(1/(1 - ε))·A) - 1| over %d-step means %.3g\n",
      worst, kWindow, worst_load);
  EXPECT_LT(worst, 0.01);
  EXPECT_LT(worst_load, 0.02);
}

// Contacts are unilateral: a platen pressed into a block and then lifted
// pulls nothing up. Its vertical reaction never turns tensile and is zero
// once it has left the surface.
// An elastic block (E = 2 MPa, ν = 0.3, 0.3 m tall, from x0 to x1) on a
// rough base, and a 0.1 m thick platen on its top, pressed down at 5 cm/s
// for 0.1 s and then moved at `then`.
constexpr double kPlatenYoungs = 2e6, kPlatenNu = 0.3;
CaseSpec PlatenCase(double x0, double x1, double center_x, double half_width, ContactKind contact,
                    double mu, const Vector2d& then) {
  const double rho = 2000.0, h = 0.05;
  CaseSpec spec = BlockCase(h, static_cast<int>(std::lround((x1 + 0.1) / h)), 10, Vector2d(x0, 0.0),
                            Vector2d(x1, 0.3), 2, rho);
  spec.solver.pic_fraction = 0.05;
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(kPlatenYoungs, kPlatenNu) / rho);
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  RigidBody platen;
  platen.name = "platen";
  platen.center = Vector2d(center_x, 0.35);
  platen.half_size = Vector2d(half_width, 0.05);
  platen.contact = contact;
  platen.friction = mu;
  platen.velocity = {{0.0, Vector2d(0.0, -0.05)}, {0.1, Vector2d(0.0, -0.05)}, {0.1001, then}};
  spec.bodies = {platen};
  return spec;
}

TEST(BodyTest, SoilLetsGoOfARisingBody) {
  const CaseSpec spec =
      PlatenCase(0.0, 0.4, 0.2, 0.1, ContactKind::kRough, 0.0, Vector2d(0.0, 0.05));
  LinearElasticModel model(kPlatenYoungs, kPlatenNu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  double most_tensile = 0.0, pressed = 0.0;
  while (solver->time() < 0.3) {
    ASSERT_TRUE(solver->Step().ok());
    const double fy = solver->Reactions()[1].y();  // + : the soil pushes the platen up
    if (solver->time() < 0.1) pressed = std::max(pressed, fy);
    most_tensile = std::min(most_tensile, fy);
  }
  std::printf("rising platen: largest push %.4g N, most tensile %.3g N, last %.3g N\n", pressed,
              most_tensile, solver->Reactions()[1].y());
  EXPECT_GT(pressed, 0.0);
  EXPECT_GE(most_tensile, -1e-9 * pressed);
  EXPECT_EQ(solver->Reactions()[1], Vector2d::Zero());  // 1 cm clear of the soil by now
}

// Coulomb at the surface: a frictional platen wider than a block, pressed
// onto it and then dragged sideways, pulls the block's top along with at
// most μ times its normal force, and with μ times it once sliding.
TEST(BodyTest, FrictionalPlatenDragsTheSurfaceWithMuTimesItsLoad) {
  const double mu = 0.3;
  const CaseSpec spec =
      PlatenCase(0.1, 0.9, 0.5, 0.5, ContactKind::kFrictional, mu, Vector2d(0.5, 0.0));
  LinearElasticModel model(kPlatenYoungs, kPlatenNu);
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
  double highest = 0.0, sliding = 0.0;
  int rows = 0;
  while (solver->time() < 0.2) {
    ASSERT_TRUE(solver->Step().ok());
    const Vector2d r = solver->Reactions()[1];
    if (r.y() > 0.0) highest = std::max(highest, std::abs(r.x()) / r.y());
    if (solver->time() > 0.15) {
      sliding += -r.x() / r.y();  // the soil holds the platen back: fx < 0
      ++rows;
    }
  }
  sliding /= rows;
  std::printf("frictional platen: largest |fx|/fy %.6f, while sliding %.6f, mu %.2f\n", highest,
              sliding, mu);
  EXPECT_LE(highest, mu * (1.0 + 1e-9));
  EXPECT_NEAR(sliding, mu, 0.01 * mu);
}

// A GIMP point next to a wall at the grid's edge moves with its domain's
// mean velocity; where its domain reaches past the wall line (clipped to
// the grid) that mean does not vanish at the line, so its centre crept
// through it and off the grid (the collapse cases padded a fixed cell row
// below the base for this). Stress-free grains whose domains were stretched
// vertically (F_yy = 3, lp_y = 0.375 h, more than the bottom row's height)
// falling onto such a base must stay on the grid, above the base.
TEST(WallTest, GimpPointsDoNotCreepThroughAWallAtTheGridEdge) {
  const double h = 0.05;
  CaseSpec spec = BlockCase(h, 8, 8, Vector2d(0.1, 0.0), Vector2d(0.3, 0.2), 4);
  spec.solver.shape = ShapeKind::kGimp;
  spec.solver.gravity = Vector2d(0.0, -9.81);
  spec.solver.pic_fraction = 1.0;
  spec.solver.time_step = 1e-3;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kSmooth)};
  ZeroStressModel model;
  std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(0.0, -1.0)});
  for (Matrix2d& f : solver->mutable_points().F) f(1, 1) = 3.0;
  double lowest = 1.0;
  for (int i = 0; i < 300; ++i) {
    const absl::Status s = solver->Step();
    ASSERT_TRUE(s.ok()) << "step " << solver->step() << ": " << s;
    for (const Vector2d& x : solver->points().position) lowest = std::min(lowest, x.y());
  }
  std::printf("stretched stress-free grains on a base at the grid edge: lowest centre y = %.3g m\n",
              lowest);
  EXPECT_GE(lowest, 0.0);
}

TEST(WallTest, UnilateralBaseLetsTheSoilLeaveABilateralOneHolds) {
  const double rho = 2000.0, youngs = 2e6, nu = 0.3, h = 0.05, g = 9.81, v0 = 0.5;
  for (bool unilateral : {true, false}) {
    CaseSpec spec = BlockCase(h, 8, 10, Vector2d(0.1, 0.0), Vector2d(0.3, 0.2), 2, rho);
    spec.solver.gravity = Vector2d(0.0, -g);
    spec.solver.pic_fraction = 1.0;
    spec.solver.time_step = 0.2 * h / std::sqrt(PWaveModulus(youngs, nu) / rho);
    spec.walls = {MakeWall(1, 0.0, ContactKind::kSmooth)};
    spec.walls[0].unilateral = unilateral;
    LinearElasticModel model(youngs, nu);
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model, {Vector2d(0.0, v0)});
    const double mass = TotalMass(solver->points());
    RunSteps(*solver, 150);  // still rising: v0/g = 0.051 s
    const double v = Momentum(solver->points()).y() / mass;
    std::printf("%s base: mean velocity %.5f m/s after %.4f s (free flight %.5f)\n",
                unilateral ? "unilateral" : "bilateral", v, solver->time(),
                v0 - g * solver->time());
    if (unilateral) {
      EXPECT_NEAR(v, v0 - g * solver->time(), 1e-9);
      EXPECT_EQ(solver->Reactions()[0], Vector2d::Zero());
    } else {
      EXPECT_LT(v, 0.5 * (v0 - g * solver->time()));  // the base holds the bottom row back
    }
  }
}

}  // namespace
}  // namespace rvehub::mpm
