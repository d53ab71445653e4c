// Averaged strain increments in the explicit MPM solver: F-bar (the volume
// change averaged over the nodes, solver.f_bar) and the nonlocal average over a
// radius (solver.nonlocal_radius).
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
#include "mpm_client/core/nonlocal.h"
#include "mpm_client/core/shape.h"
#include "mpm_client/core/solver.h"
#include "tests/mpm_client/core/solver_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm {
namespace {

using Eigen::Matrix2d;
using Eigen::Matrix3d;
using Eigen::Vector2d;

// --- F-bar: the volume change averaged over the nodes (solver.f_bar)

// Shapes of one point per cell at the cell centres of an n × n grid of
// cells of 0.1 m, with GIMP half-sizes of half a cell.
std::vector<ShapeValues> CellCentreShapes(const GridSpec& grid, ShapeKind kind) {
  std::vector<ShapeValues> shapes(grid.nx * grid.ny);
  const double h = grid.cell_size;
  for (int j = 0; j < grid.ny; ++j) {
    for (int i = 0; i < grid.nx; ++i) {
      const Vector2d x = grid.origin + h * Vector2d(i + 0.5, j + 0.5);
      EXPECT_TRUE(
          EvaluateShape(grid, kind, x, Vector2d::Constant(0.5 * h), shapes[i + grid.nx * j]));
    }
  }
  return shapes;
}

TEST(FBarTest, KeepsAHomogeneousIncrementAndShearAndSharesOnePointsSqueeze) {
  GridSpec grid;
  grid.cell_size = 0.1;
  grid.nx = grid.ny = 7;
  for (ShapeKind kind : {ShapeKind::kLinear, ShapeKind::kGimp}) {
    SCOPED_TRACE(kind == ShapeKind::kGimp ? "gimp" : "linear");
    const std::vector<ShapeValues> shapes = CellCentreShapes(grid, kind);
    const std::size_t n = shapes.size();
    std::vector<double> volume(n, 0.01);  // m³
    volume[3] = 0.012;                    // one point larger: weights by volume
    // A homogeneous increment (squeeze, shear, rotation) stays as it is.
    Matrix2d uniform;
    uniform << 0.998, 0.004, -0.001, 0.997;
    std::vector<Matrix2d> df(n, uniform);
    AverageVolumeChange(shapes, volume, NodeCount(grid), df);
    for (std::size_t p = 0; p < n; ++p) EXPECT_LT((df[p] - uniform).norm(), 1e-15) << p;
    // One point in the middle squeezed by 1 % with a shear, the others at rest.
    const std::size_t middle = 3 + 7 * 3;
    Matrix2d squeeze;
    squeeze << 0.995, 0.003, 0.0, 0.995;
    df.assign(n, Matrix2d::Identity());
    df[middle] = squeeze;
    // A parked point (no nodes) keeps its increment.
    std::vector<ShapeValues> with_parked = shapes;
    with_parked[0].count = 0;
    df[0] = squeeze;
    double before = 0.0;
    for (std::size_t p = 1; p < n; ++p) before += volume[p] * (df[p].determinant() - 1.0);
    AverageVolumeChange(with_parked, volume, NodeCount(grid), df);
    EXPECT_EQ(df[0], squeeze);
    double after = 0.0, neighbours = 0.0;
    for (std::size_t p = 1; p < n; ++p) {
      after += volume[p] * (df[p].determinant() - 1.0);
      if (p != middle && df[p].determinant() < 1.0 - 1e-6) neighbours += 1.0;
    }
    // The total volume change stays (the weights sum to one at every point);
    // the point keeps a share and its neighbours take the rest.
    EXPECT_NEAR(after, before, 1e-15);
    const double j = df[middle].determinant();
    EXPECT_GT(j, 0.995 * 0.995);
    EXPECT_LT(j, 1.0 - 1e-4);
    EXPECT_EQ(neighbours, 8.0);  // the 3 × 3 block around it: linear and GIMP alike
    // Its shape change is its own: the increment is only scaled.
    const double c = df[middle](0, 0) / squeeze(0, 0);
    EXPECT_LT((df[middle] - c * squeeze).norm(), 1e-15);
  }
}

// 6 × 5 cells of 0.1 m, for the nodal-average tests.
GridSpec SixByFive() {
  GridSpec grid;
  grid.cell_size = 0.1;
  grid.nx = 6;
  grid.ny = 5;
  return grid;
}

// The force side uses the same average on the mean stress: the map must be
// its own adjoint in the volume-weighted product (Σ w a b̄ = Σ w ā b), or the
// internal forces would not do the work the packings take.
TEST(FBarTest, TheNodalAverageIsSelfAdjointAndKeepsConstants) {
  const GridSpec grid = SixByFive();
  const std::vector<ShapeValues> shapes = CellCentreShapes(grid, ShapeKind::kGimp);
  const std::size_t n = shapes.size();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  std::vector<double> w(n), a(n), b(n);
  for (std::size_t p = 0; p < n; ++p) {
    w[p] = 0.01 * u(rng);
    a[p] = u(rng) - 1.0;
    b[p] = 1e5 * u(rng);
  }
  const std::vector<double> a_bar = NodalAverage(shapes, w, a, NodeCount(grid));
  const std::vector<double> b_bar = NodalAverage(shapes, w, b, NodeCount(grid));
  double ab = 0.0, ba = 0.0, spread = 0.0, spread_bar = 0.0;
  for (std::size_t p = 0; p < n; ++p) {
    ab += w[p] * a[p] * b_bar[p];
    ba += w[p] * a_bar[p] * b[p];
    spread += w[p] * a[p] * a[p];
    spread_bar += w[p] * a_bar[p] * a_bar[p];
  }
  EXPECT_NEAR(ab, ba, 1e-13 * std::abs(ab));
  EXPECT_LT(spread_bar, 0.5 * spread);  // a noisy field is smoothed
  const std::vector<double> constant(n, 2.5);
  for (double c : NodalAverage(shapes, w, constant, NodeCount(grid))) EXPECT_NEAR(c, 2.5, 1e-15);
}

// A point of weight 0 (one that has come apart, HasComeApart) keeps its own
// value and moves no other point's average: the others average as if it
// were not there, bit for bit.
TEST(FBarTest, APointOfWeightZeroKeepsItsValueAndMovesNoOther) {
  const GridSpec grid = SixByFive();
  const std::vector<ShapeValues> shapes = CellCentreShapes(grid, ShapeKind::kGimp);
  const std::size_t n = shapes.size();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  std::vector<double> w(n), a(n);
  for (std::size_t p = 0; p < n; ++p) {
    w[p] = 0.01 * u(rng);
    a[p] = 1e5 * u(rng);
  }
  const std::size_t apart = 2 + 6 * 2;  // inside: its nodes have other points
  std::vector<double> w_out = w;
  w_out[apart] = 0.0;
  std::vector<double> a_big = a;
  a_big[apart] = 1e9;  // whatever it holds
  const std::vector<double> with = NodalAverage(shapes, w, a, NodeCount(grid));
  const std::vector<double> out = NodalAverage(shapes, w_out, a_big, NodeCount(grid));
  std::vector<ShapeValues> without_shapes;
  std::vector<double> without_w, without_a;
  for (std::size_t p = 0; p < n; ++p) {
    if (p == apart) continue;
    without_shapes.push_back(shapes[p]);
    without_w.push_back(w[p]);
    without_a.push_back(a[p]);
  }
  const std::vector<double> without =
      NodalAverage(without_shapes, without_w, without_a, NodeCount(grid));
  EXPECT_EQ(out[apart], 1e9);
  EXPECT_NE(with[apart], a[apart]);  // with its weight it is averaged
  for (std::size_t p = 0, q = 0; p < n; ++p) {
    if (p == apart) continue;
    EXPECT_EQ(out[p], without[q++]) << p;
  }
  // Alone on its nodes (a grid of one point): nothing to average with.
  const std::vector<ShapeValues> one = {shapes[apart]};
  EXPECT_EQ(
      NodalAverage(one, std::vector<double>{0.0}, std::vector<double>{3.0}, NodeCount(grid))[0],
      3.0);
}

// A block of 8 × 6 cells of 0.1 m, one point per cell, on a rough base,
// under a rough platen 0.2 m wide pushed down at 1 m/s (Δt = 1 ms, FLIP):
// the points under it are squeezed, those beside it not.
CaseSpec PlatenOnABlock() {
  CaseSpec spec = BlockCase(0.1, 8, 6, Vector2d(0.0, 0.0), Vector2d(0.8, 0.4), 1);
  spec.solver.pic_fraction = 0.0;
  spec.solver.time_step = 1e-3;
  spec.walls = {MakeWall(1, 0.0, ContactKind::kRough)};
  spec.bodies = {
      RoughBlock("platen", Vector2d(0.4, 0.45), Vector2d(0.1, 0.05), Vector2d(0.0, -1.0))};
  return spec;
}

TEST(FBarTest, TheSolverGivesPointsTheAveragedVolumeChange) {
  // A column of one point per cell squeezed by a rough platen: the points
  // under it are squeezed, those beside it not. With F-bar their RVEs get a
  // smoother volume change with the same total.
  CaseSpec spec = PlatenOnABlock();
  std::map<FBar, std::vector<Matrix3d>> increments;
  std::vector<double> volume;
  for (FBar f : {FBar::kNone, FBar::kNodal}) {
    spec.solver.f_bar = f;
    RecordingModel model(0.2);
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
    volume = solver->points().volume;
    ASSERT_TRUE(solver->Step().ok());
    increments[f] = model.last();
    // The points' volumes follow what their RVEs got.
    for (std::size_t p = 0; p < volume.size(); ++p) {
      EXPECT_NEAR(solver->points().volume[p], volume[p] * model.last()[p].determinant(), 1e-15);
    }
  }
  double total[2] = {0.0, 0.0}, most[2] = {0.0, 0.0};
  for (FBar f : {FBar::kNone, FBar::kNodal}) {
    const int k = f == FBar::kNodal ? 1 : 0;
    for (std::size_t p = 0; p < volume.size(); ++p) {
      const double dv = increments[f][p].determinant() - 1.0;
      total[k] += volume[p] * dv;
      most[k] = std::max(most[k], std::abs(dv));
    }
  }
  std::printf("volume change: none %.6g m³ (largest |ΔJ| %.4g), nodal %.6g m³ (%.4g)\n", total[0],
              most[0], total[1], most[1]);
  EXPECT_LT(total[0], -1e-6);
  EXPECT_NEAR(total[1], total[0], 1e-12 * std::abs(total[0]));
  EXPECT_LT(most[1], 0.8 * most[0]);
}
// Over one step from velocities v0 to `after`: the kinetic energy's change
// Σ m v0·Δv and the packings' work Σ V σ:(ΔF − I) with the increments the
// model took, and Σ |V σ:(ΔF − I)| as their scale, J per unit thickness.
struct Work {
  double kinetic, packings, scale;
};
Work StepWork(const std::vector<double>& mass, const std::vector<Vector2d>& v0,
              const MaterialPoints& after, const std::vector<Matrix3d>& increments,
              const std::vector<Matrix3d>& stress) {
  Work w{0.0, 0.0, 0.0};
  for (std::size_t p = 0; p < mass.size(); ++p) {
    w.kinetic += mass[p] * v0[p].dot(after.velocity[p] - v0[p]);
    const Matrix2d strain = increments[p].topLeftCorner<2, 2>() - Matrix2d::Identity();
    const double work =
        after.volume[p] * (stress[p].topLeftCorner<2, 2>().cwiseProduct(strain)).sum();
    w.packings += work;
    w.scale += std::abs(work);
  }
  return w;
}

// The internal forces must do the work the packings take. Over one free step
// (no walls, loads or gravity; FLIP) Σ_p m_p v_p·Δv_p = Δt Σ_I f_I·v_I, and
// the packings take Σ_p V_p σ_p:(ΔF_p − I) = −Δt Σ_I f_I·v_I to first order
// in Δt, whatever their stresses. With F-bar that holds only where the
// forces use the nodal average of the mean stress, the adjoint of the
// volume-change map (Solver::ForceStresses, which the saturated step shares);
// with the nonlocal strain, where they use the stresses averaged by the same
// map. Dropping the average, or flipping its sign, breaks the balance here
// by 0.7–1.4 % of the work, some 200 times the tolerance (the balance holds
// to 1e-8 of it).
TEST(FBarTest, TheForcesDoTheWorkThePackingsTake) {
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(k == 0 ? "local" : k == 1 ? "f_bar" : "nonlocal");
    CaseSpec spec = BlockCase(0.1, 10, 8, Vector2d(0.2, 0.2), Vector2d(0.8, 0.6), 2);
    spec.solver.pic_fraction = 0.0;
    spec.solver.time_step = 1e-7;
    if (k == 1) spec.solver.f_bar = FBar::kNodal;
    if (k == 2) spec.solver.nonlocal_radius = 0.12;
    absl::StatusOr<MaterialPoints> points = FillRegions(spec);
    ASSERT_TRUE(points.ok()) << points.status();
    const std::size_t n = points->size();
    // A smooth velocity field with a varying divergence, and stresses that
    // vary from point to point (compression, 50–200 kPa, with shear).
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<Matrix3d> stress(n, Matrix3d::Zero());
    for (std::size_t p = 0; p < n; ++p) {
      const Vector2d x = points->position[p];
      points->velocity[p] = Vector2d(0.3 * std::sin(5.0 * x.x()) * std::cos(3.0 * x.y()),
                                     0.2 * std::cos(4.0 * x.x()) + 0.5 * x.x() * x.y());
      const double mean = -1.25e5 + 7.5e4 * u(rng), shear = 3e4 * u(rng), dev = 3e4 * u(rng);
      stress[p](0, 0) = mean + dev;
      stress[p](1, 1) = mean - dev;
      stress[p](0, 1) = stress[p](1, 0) = shear;
      stress[p](2, 2) = mean;
    }
    const std::vector<Vector2d> v0 = points->velocity;
    std::vector<double> mass = points->mass;
    FixedStressModel model(stress);
    absl::StatusOr<std::unique_ptr<Solver>> solver =
        Solver::Create(spec, *std::move(points), &model);
    ASSERT_TRUE(solver.ok()) << solver.status();
    ASSERT_TRUE((*solver)->Step().ok());
    const MaterialPoints& after = (*solver)->points();
    const auto [kinetic, packings, scale] = StepWork(mass, v0, after, model.last(), stress);
    std::printf("%s: kinetic %.9g J, packings %.9g J (sum of |work| %.4g J)\n",
                k == 0   ? "local"
                : k == 1 ? "f_bar"
                         : "nonlocal",
                kinetic, packings, scale);
    EXPECT_GT(std::abs(packings), 0.05 * scale);
    EXPECT_NEAR(kinetic, -packings, 1e-5 * scale);
  }
}

// F-bar leaves out a point whose packing carries no stress at e >= 1
// (HasComeApart): it takes its own volume change, and its force uses its own
// (zero) stress rather than a share of its neighbours' mean stress, which,
// times its own swollen volume, pushed it apart further (collapse-saturated-
// medium: e = 115, then a blow-up). The forces still do the work the
// packings take. Checked on the block of the test above, one inner point
// (index 11) made a stress-free packing at e = 1.5 (left out) or 0.9 (kept).
TEST(FBarTest, APointThatHasComeApartTakesItsOwnIncrementAndNoShare) {
  for (const double e : {1.5, 0.9}) {
    SCOPED_TRACE(e);
    CaseSpec spec = BlockCase(0.1, 10, 8, Vector2d(0.2, 0.2), Vector2d(0.8, 0.6), 2);
    spec.solver.pic_fraction = 0.0;
    spec.solver.time_step = 1e-7;
    absl::StatusOr<MaterialPoints> points = FillRegions(spec);
    ASSERT_TRUE(points.ok()) << points.status();
    const std::size_t n = points->size(), apart = 11;
    std::vector<Matrix3d> stress(n, Matrix3d::Zero());
    for (std::size_t p = 0; p < n; ++p) {
      const Vector2d x = points->position[p];
      points->velocity[p] = Vector2d(0.3 * std::sin(5.0 * x.x()) * std::cos(3.0 * x.y()),
                                     0.2 * std::cos(4.0 * x.x()) + 0.5 * x.x() * x.y());
      if (p == apart) continue;
      stress[p].diagonal() = Eigen::Vector3d(-1e5 - 1e3 * p, -1.2e5, -1.1e5);
      points->response[p].stress = stress[p];
    }
    points->response[apart].stress.setZero();
    points->response[apart].void_ratio = e;
    ASSERT_EQ(HasComeApart(points->response[apart]), e >= 1.0);
    const std::vector<Vector2d> v0 = points->velocity;
    const std::vector<double> mass = points->mass;
    // The same step without F-bar gives each point its own increment.
    CaseSpec plain = spec;
    spec.solver.f_bar = FBar::kNodal;
    FixedStressModel model(stress), model_plain(stress);
    absl::StatusOr<std::unique_ptr<Solver>> solver = Solver::Create(spec, *points, &model);
    absl::StatusOr<std::unique_ptr<Solver>> own =
        Solver::Create(plain, *std::move(points), &model_plain);
    ASSERT_TRUE(solver.ok()) << solver.status();
    ASSERT_TRUE(own.ok()) << own.status();
    ASSERT_TRUE((*solver)->Step().ok());
    ASSERT_TRUE((*own)->Step().ok());
    const bool left_out = e >= 1.0;
    EXPECT_EQ(model.last()[apart] == model_plain.last()[apart], left_out);
    const Matrix2d force_stress = (*solver)->ForceStresses()[apart];
    EXPECT_EQ(force_stress == Matrix2d::Zero(), left_out);
    if (!left_out) {
      EXPECT_LT(force_stress.trace(), -1e4);  // Pa: a share of the block's
    }
    const MaterialPoints& after = (*solver)->points();
    const auto [kinetic, packings, scale] = StepWork(mass, v0, after, model.last(), stress);
    EXPECT_NEAR(kinetic, -packings, 1e-5 * scale);
  }
}

// --- nonlocal strain: increments averaged over a radius (solver.nonlocal_radius)

// A jittered lattice of points 0.1 m apart (nx × ny) with volumes about 0.01 m³.
struct PointCloud {
  std::vector<Vector2d> position;
  std::vector<double> volume;
  std::vector<std::uint8_t> active;
};
PointCloud Jittered(int nx, int ny, unsigned seed) {
  PointCloud c;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02), size(0.8, 1.2);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      c.position.push_back(Vector2d(0.1 * i + jitter(rng), 0.1 * j + jitter(rng)));
      c.volume.push_back(0.01 * size(rng));
      c.active.push_back(1);
    }
  }
  return c;
}

TEST(NonlocalTest, TheMapFindsEveryPairWithinTheRadiusAndKeepsTheOwnShareNonNegative) {
  PointCloud c = Jittered(12, 9, 3);
  c.active[17] = 0;  // parked: neither a neighbour nor averaged
  const double radius = 0.25;
  const NonlocalMap map = NonlocalMap::Build(c.position, c.volume, c.active, radius, 1.0, 1.0);
  ASSERT_EQ(map.size(), c.position.size());
  EXPECT_TRUE(map.Neighbours(17).empty());
  std::size_t pairs = 0;
  for (std::size_t p = 0; p < c.position.size(); ++p) {
    // The bins find what a search over all pairs finds, in index order
    // within each bin column.
    std::vector<std::int32_t> expected;
    for (std::size_t q = 0; q < c.position.size(); ++q) {
      if (q != p && c.active[p] && c.active[q] && (c.position[q] - c.position[p]).norm() < radius) {
        expected.push_back(static_cast<std::int32_t>(q));
      }
    }
    std::vector<std::int32_t> found(map.Neighbours(p).begin(), map.Neighbours(p).end());
    std::sort(found.begin(), found.end());
    EXPECT_EQ(found, expected) << p;
    pairs += found.size();
    double share = 0.0;
    for (std::size_t k = 0; k < found.size(); ++k) {
      const std::int32_t q = map.Neighbours(p)[k];
      const double c_pq = map.Coefficients(p)[k];
      share += c_pq;
      // V_p c_pq = V_q c_qp: the map is symmetric in the volume-weighted sum.
      const auto back = map.Neighbours(q);
      const std::size_t at = std::find(back.begin(), back.end(), p) - back.begin();
      ASSERT_LT(at, back.size());
      EXPECT_NEAR(c.volume[p] * c_pq, c.volume[q] * map.Coefficients(q)[at],
                  1e-15 * c.volume[p] * c_pq);
    }
    EXPECT_LE(share, 1.0 - c.volume[p] / 0.25) << p;  // the own share ≥ V_p/S∞ > 0
  }
  // About 5 neighbours at 0.1 m spacing inside a radius of 2.5 spacings:
  // π·2.5² − 1 ≈ 18.6 in the interior, fewer at the edges.
  EXPECT_GT(pairs, 12 * c.position.size());
}

TEST(NonlocalTest, TheAverageKeepsConstantsAndTheTotalIsSelfAdjointAndSmooths) {
  const PointCloud c = Jittered(10, 8, 7);
  const std::size_t n = c.position.size();
  const NonlocalMap map = NonlocalMap::Build(c.position, c.volume, c.active, 0.25, 1.0, 1.0);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> a(n), b(n), a_bar(n), b_bar(n);
  for (std::size_t p = 0; p < n; ++p) {
    a[p] = u(rng);
    b[p] = 1e5 * u(rng);
  }
  map.Apply(a, a_bar);
  map.Apply(b, b_bar);
  double ab = 0.0, ba = 0.0, total = 0.0, total_bar = 0.0, spread = 0.0, spread_bar = 0.0;
  for (std::size_t p = 0; p < n; ++p) {
    ab += c.volume[p] * a[p] * b_bar[p];
    ba += c.volume[p] * a_bar[p] * b[p];
    total += c.volume[p] * a[p];
    total_bar += c.volume[p] * a_bar[p];
    spread += c.volume[p] * a[p] * a[p];
    spread_bar += c.volume[p] * a_bar[p] * a_bar[p];
  }
  EXPECT_NEAR(ab, ba, 1e-12 * std::abs(1e5 * spread));
  EXPECT_NEAR(total_bar, total, 1e-15 * n);  // Σ V a is kept
  EXPECT_LT(spread_bar, 0.3 * spread);       // a noisy field is smoothed
  const std::vector<double> constant(n, 2.5);
  std::vector<double> out(n);
  map.Apply(constant, out);
  for (double v : out) EXPECT_EQ(v, 2.5);  // bit for bit
  // A spike reaches exactly the points within the radius.
  std::vector<double> spike(n, 0.0);
  const std::size_t middle = 4 + 10 * 4;
  spike[middle] = 1.0;
  map.Apply(spike, out);
  for (std::size_t p = 0; p < n; ++p) {
    const bool near = (c.position[p] - c.position[middle]).norm() < 0.25;
    if (p == middle) {
      EXPECT_GT(out[p], 0.0);
      EXPECT_LT(out[p], 0.5);
    } else {
      EXPECT_EQ(out[p] > 0.0, near) << p;
    }
  }
}

// The full average nearly annuls a field alternating from point to point
// (what such a strain meets is what the map leaves of it); the blend with a
// fraction m keeps 1 − m (1 + 0.06) of it.
TEST(NonlocalTest, AFractionKeepsAPointToPointAlternationThatTheFullAverageAnnuls) {
  PointCloud c;
  for (int j = 0; j < 15; ++j) {
    for (int i = 0; i < 15; ++i) {
      c.position.push_back(Vector2d(0.1 * i, 0.1 * j));
      c.volume.push_back(0.01);
      c.active.push_back(1);
    }
  }
  const std::size_t n = c.position.size(), middle = 7 + 15 * 7;
  std::vector<double> alternating(n), out(n);
  for (std::size_t p = 0; p < n; ++p) alternating[p] = (p % 2 == 0) ? 1.0 : -1.0;
  for (double m : {1.0, 0.5}) {
    const NonlocalMap map = NonlocalMap::Build(c.position, c.volume, c.active, 0.2, 1.0, m);
    map.Apply(alternating, out);
    // ℓ = 2h: 4 neighbours at h with w = 9/16, 4 at √2 h with 1/4, S∞ = 4.25 h²:
    // (1 − 4·9/16 + 4/4)/4.25 = −1/17 of it with m = 1.
    std::printf("m = %.1f: the alternation keeps %.4f of itself\n", m, out[middle]);
    EXPECT_NEAR(out[middle], 1.0 - m * (1.0 + 1.0 / 17.0), 1e-12);
  }
}

TEST(NonlocalTest, AnIncrementsStrainIsAveragedAndItsRotationKept) {
  const PointCloud c = Jittered(7, 7, 1);
  const std::size_t n = c.position.size();
  const NonlocalMap map = NonlocalMap::Build(c.position, c.volume, c.active, 0.25, 1.0, 1.0);
  // A homogeneous increment (squeeze, shear, rotation) stays bit for bit.
  Matrix2d uniform;
  uniform << 0.998, 0.004, -0.001, 0.997;
  std::vector<Matrix2d> df(n, uniform);
  AverageStrainIncrement(map, df);
  for (const Matrix2d& d : df) EXPECT_EQ(d, uniform);
  // One point sheared and rotated, the others at rest: its neighbours take a
  // share of the shear strain, none of the rotation.
  const std::size_t middle = 3 + 7 * 3;
  Matrix2d shear;
  shear << 1.0, 0.01, -0.004, 1.0;  // strain xy 0.003, spin 0.007
  df.assign(n, Matrix2d::Identity());
  df[middle] = shear;
  AverageStrainIncrement(map, df);
  const auto skew = [](const Matrix2d& d) { return 0.5 * (d(0, 1) - d(1, 0)); };
  EXPECT_DOUBLE_EQ(skew(df[middle]), 0.007);
  EXPECT_GT(df[middle](0, 1) + df[middle](1, 0), 0.0);
  EXPECT_LT(df[middle](0, 1) + df[middle](1, 0), 0.5 * 0.006);
  int sheared = 0;
  for (std::size_t p = 0; p < n; ++p) {
    if (p == middle) continue;
    EXPECT_EQ(skew(df[p]), 0.0) << p;
    EXPECT_EQ(df[p].diagonal(), Vector2d(1.0, 1.0)) << p;
    if (df[p](0, 1) > 0.0) ++sheared;
  }
  EXPECT_EQ(sheared, static_cast<int>(map.Neighbours(middle).size()));
}

TEST(NonlocalTest, TheSolverGivesPointsTheAveragedStrain) {
  // The rough platen of FBarTest: with a nonlocal radius of two cells the
  // points' RVEs get a smoother strain with the same total volume change,
  // the more so the larger the fraction.
  CaseSpec spec = PlatenOnABlock();
  const std::pair<double, double> settings[] = {{0.0, 1.0}, {0.2, 1.0}, {0.2, 0.5}};
  double total[3], most[3];
  for (int k = 0; k < 3; ++k) {
    spec.solver.nonlocal_radius = settings[k].first;
    spec.solver.nonlocal_fraction = settings[k].second;
    RecordingModel model(0.2);
    std::unique_ptr<Solver> solver = MakeSolver(spec, &model);
    const std::vector<double> volume = solver->points().volume;
    ASSERT_TRUE(solver->Step().ok());
    total[k] = most[k] = 0.0;
    for (std::size_t p = 0; p < volume.size(); ++p) {
      const Matrix3d& d = model.last()[p];
      EXPECT_NEAR(solver->points().volume[p], volume[p] * d.determinant(), 1e-15);
      total[k] += volume[p] * (d(0, 0) + d(1, 1) - 2.0);  // Σ V tr ε, m³
      most[k] = std::max(most[k], (0.5 * (d + d.transpose()) - Matrix3d::Identity()).norm());
    }
  }
  std::printf(
      "Σ V tr ε (largest |ε|): local %.6g m³ (%.4g), m = 1 %.6g m³ (%.4g), m = 0.5 %.6g m³ "
      "(%.4g)\n",
      total[0], most[0], total[1], most[1], total[2], most[2]);
  EXPECT_LT(total[0], -1e-6);
  EXPECT_NEAR(total[1], total[0], 1e-12 * std::abs(total[0]));
  EXPECT_NEAR(total[2], total[0], 1e-12 * std::abs(total[0]));
  EXPECT_LT(most[1], 0.8 * most[0]);  // 0.72 of it
  EXPECT_LT(most[2], 0.9 * most[0]);  // 0.86
  EXPECT_GT(most[2], most[1]);
}

// The strain the points take and the stress the forces use are averaged by
// the same self-adjoint map, so the averaged solver does the work its points
// store: a free elastic block vibrating keeps its energy as the local one
// does (FLIP, no damping).
TEST(NonlocalTest, AFreeElasticBlockKeepsItsEnergy) {
  const double youngs = 1e6, nu = 0.3, rho = 2000.0;
  CaseSpec spec = BlockCase(0.1, 14, 14, Vector2d(0.2, 0.2), Vector2d(1.2, 1.2), 2, rho);
  spec.solver.pic_fraction = 0.0;
  spec.solver.time_step = 0.1 * 0.1 / std::sqrt(PWaveModulus(youngs, nu) / rho);
  const auto energy = [&](const Solver& solver) {
    const MaterialPoints& mp = solver.points();
    double e = solver.KineticEnergy();
    for (std::size_t p = 0; p < mp.size(); ++p) {
      const Matrix3d& sigma = mp.stress[p];
      const Matrix3d strain =
          ((1.0 + nu) * sigma - nu * sigma.trace() * Matrix3d::Identity()) / youngs;
      e += 0.5 * mp.volume[p] * (sigma.array() * strain.array()).sum();
    }
    return e;
  };
  double drift[3] = {0.0, 0.0, 0.0}, strain_energy[3] = {0.0, 0.0, 0.0};
  for (int k = 0; k < 3; ++k) {
    spec.solver.nonlocal_radius = k == 0 ? 0.0 : 0.25;
    spec.solver.nonlocal_fraction = k == 2 ? 0.5 : 1.0;
    LinearElasticModel model(youngs, nu);
    absl::StatusOr<MaterialPoints> points = FillRegions(spec);
    ASSERT_TRUE(points.ok()) << points.status();
    for (std::size_t p = 0; p < points->size(); ++p) {
      const Vector2d x = points->position[p] - Vector2d(0.7, 0.7);
      // A bump in the middle: strains that vary within the radius.
      points->velocity[p] = 0.05 * std::exp(-x.squaredNorm() / 0.02) * Vector2d(x.y(), 0.5 * x.x());
    }
    absl::StatusOr<std::unique_ptr<Solver>> solver =
        Solver::Create(spec, *std::move(points), &model);
    ASSERT_TRUE(solver.ok()) << solver.status();
    const double e0 = energy(**solver);
    double worst = 0.0;
    for (int i = 0; i < 300; ++i) {
      RunSteps(**solver, 1);
      worst = std::max(worst, std::abs(energy(**solver) - e0) / e0);
      strain_energy[k] = std::max(strain_energy[k], 1.0 - (*solver)->KineticEnergy() / e0);
    }
    drift[k] = worst;
  }
  std::printf(
      "largest |E - E0|/E0 over 300 steps: local %.3g, nonlocal m = 1 %.3g, m = 0.5 %.3g; "
      "strain energy up to %.3g, %.3g, %.3g of E0\n",
      drift[0], drift[1], drift[2], strain_energy[0], strain_energy[1], strain_energy[2]);
  for (int k = 1; k < 3; ++k) {
    EXPECT_GT(strain_energy[k], 0.3);  // the bump was squeezed: a test of the forces
    // With the forces on the points' own stresses instead: 0.35 (m = 1).
    EXPECT_LT(drift[k], 2.0 * drift[0] + 1e-4);
  }
}

}  // namespace
}  // namespace rvehub::mpm
