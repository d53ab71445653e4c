// Periodic boundary of the DEM engine (rve_server/engine/rve.cc): the minimum
// image of contacts across the cell boundary (orthogonal and sheared cells,
// unwrapped coordinates), invariance of the homogenised state under a change
// of lattice basis, and the cell flips that keep a sheared cell reduced.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "gtest/gtest.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

using testing_util::CreateOrDie;
using testing_util::Prepared;

// --- Contacts across the periodic boundary. ---

struct CrossCase {
  std::string name;
  Eigen::Matrix2d shape;   // cell matrix up to a scale
  Eigen::Vector2d si, sj;  // reduced coordinates of the pair across the boundary
};

// Reduced coordinates are dyadic (k/32), so that s_j − s_i and its minimum
// image are exact: the pair across the boundary and the same pair moved
// inside the cell then have bit-identical branch vectors.
constexpr double kEdge = 1.0 / 32.0;

std::vector<CrossCase> CrossCases() {
  Eigen::Matrix2d square = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d sheared;
  sheared << 1.0, 0.3, 0.0, 1.0;  // simple shear γ = 0.3 (a·b = 0.3|a|²)
  Eigen::Matrix2d general;
  general << 1.0, -0.4, 0.1, 1.05;  // rotated, stretched and sheared
  std::vector<CrossCase> cases;
  for (const auto& [label, shape] :
       {std::pair{"square", square}, {"sheared", sheared}, {"general", general}}) {
    const std::string l = label;
    cases.push_back({l + "_x", shape, {kEdge, 0.5}, {1.0 - kEdge, 0.5}});
    cases.push_back({l + "_y", shape, {0.5, 1.0 - kEdge}, {0.5, kEdge}});
    cases.push_back({l + "_corner", shape, {kEdge, kEdge}, {1.0 - kEdge, 1.0 - kEdge}});
    cases.push_back({l + "_anticorner", shape, {1.0 - kEdge, kEdge}, {kEdge, 1.0 - kEdge}});
  }
  // Cells less than 3 cutoffs across, where the neighbour search falls back
  // from cell lists to all pairs: |Δs| = 10/32 gives a ~0.03 m cell.
  constexpr double kFar = 5.0 / 32.0;
  cases.push_back({"small_square_x", square, {kFar, 0.5}, {1.0 - kFar, 0.5}});
  cases.push_back({"small_sheared_y", sheared, {0.5, 1.0 - kFar}, {0.5, kFar}});
  return cases;
}

// Test names instead of byte dumps in gtest's messages.
void PrintTo(const CrossCase& c, std::ostream* os) { *os << c.name; }

// Minimum image of sj − si (components in [−½, ½]).
Eigen::Vector2d MinImage(const Eigen::Vector2d& si, const Eigen::Vector2d& sj) {
  Eigen::Vector2d d = sj - si;
  return {d.x() - std::round(d.x()), d.y() - std::round(d.y())};
}

// A pair of discs (4 and 6 mm) at si, sj in a cell scaled so that they
// overlap by 0.4 mm, with velocities and spins that make them slide and roll.
RveSnapshot CrossPair(const CrossCase& c, const Eigen::Vector2d& si, const Eigen::Vector2d& sj) {
  constexpr double kR1 = 4e-3, kR2 = 6e-3, kOverlap = 4e-4;
  const double scale = (kR1 + kR2 - kOverlap) / (c.shape * MinImage(c.si, c.sj)).norm();
  RveSnapshot p;
  p.cell = c.shape * scale;
  p.material.damping = 0.0;
  p.controls.time_step_factor = 0.02;  // the pair stays in contact over the 20 steps below
  p.radius = {kR1, kR2};
  p.sx = {si.x(), sj.x()};
  p.sy = {si.y(), sj.y()};
  p.vx = {0.02, -0.01};
  p.vy = {-0.03, 0.015};
  p.omega = {5.0, -2.0};
  p.theta = {0.0, 0.0};
  p.contacts.push_back({0, 1, 0.7, 0.0, 0.0});  // ft = 0.7 N preloaded
  return p;
}

class CrossBoundaryTest : public testing::TestWithParam<CrossCase> {};

TEST_P(CrossBoundaryTest, SameContactAsInsideTheCell) {
  const CrossCase& c = GetParam();
  // The same pair moved to the middle of the cell: same minimum image.
  const Eigen::Vector2d mid(0.5, 0.5);
  const Eigen::Vector2d d = MinImage(c.si, c.sj);
  const RveSnapshot across = CrossPair(c, c.si, c.sj);
  const RveSnapshot inside = CrossPair(c, mid - 0.5 * d, mid + 0.5 * d);
  // And with unwrapped coordinates (sj shifted by lattice vectors).
  const RveSnapshot unwrapped =
      CrossPair(c, c.si + Eigen::Vector2d(-2.0, 1.0), c.sj + Eigen::Vector2d(3.0, -5.0));
  Rve a = CreateOrDie(across), b = CreateOrDie(inside), u = CreateOrDie(unwrapped);
  for (int step = 0; step <= 20; step += 10) {
    const std::vector<ContactForce> ca = a.Contacts(), cb = b.Contacts(), cu = u.Contacts();
    ASSERT_EQ(ca.size(), 1u) << "step " << step;
    ASSERT_EQ(cb.size(), 1u) << "step " << step;
    ASSERT_EQ(cu.size(), 1u) << "step " << step;
    // Before any step the inputs are exact (dyadic), so the contact is
    // bit-identical. After steps, s advances by Δs = h⁻¹·v·Δt whose round-off
    // depends on the binade of s (ulp 1.1e-16 near 0.5–1, 3.5e-18 near 0.03):
    // up to ~3e-17 m per step on a 0.15 m cell, i.e. a few 1e-13 of the
    // ~1.5e-4 m overlap after 20 steps (measured ≤ 7e-13), hence 1e-11.
    // Forces are compared relative to fn, the scale of both fn and ft.
    const double tol = step == 0 ? 0.0 : 1e-11;
    const double branch_scale = ca[0].branch.norm();
    for (const std::vector<ContactForce>* other : {&cb, &cu}) {
      const ContactForce& o = (*other)[0];
      EXPECT_NEAR(o.normal_force, ca[0].normal_force, tol * ca[0].normal_force) << step;
      EXPECT_NEAR(o.tangential_force, ca[0].tangential_force, tol * ca[0].normal_force) << step;
      EXPECT_NEAR(o.branch.x(), ca[0].branch.x(), tol * branch_scale) << step;
      EXPECT_NEAR(o.branch.y(), ca[0].branch.y(), tol * branch_scale) << step;
    }
    // The branch is the short image, not the vector across the cell.
    EXPECT_LT(branch_scale, 1e-2) << step;
    EXPECT_GT(ca[0].overlap, 0.0);
    const Eigen::Matrix3d sa = a.Observe().stress, sb = b.Observe().stress;
    EXPECT_LT((sa - sb).norm(), std::max(tol, 1e-15) * sa.norm()) << step;
    CellControl still;
    a.Run(still, 10);
    b.Run(still, 10);
    u.Run(still, 10);
  }
}

INSTANTIATE_TEST_SUITE_P(Cells, CrossBoundaryTest, testing::ValuesIn(CrossCases()),
                         [](const testing::TestParamInfo<CrossCase>& info) {
                           return info.param.name;
                         });

// --- Equivalent lattice bases. ---

// A change of basis of the same lattice: columns (a', b') = (a, b)·M with M
// unimodular, and s' = M⁻¹·s, so that x = h·s = h'·s' for every particle.
RveSnapshot ChangeBasis(const RveSnapshot& p, const Eigen::Matrix2d& m) {
  RveSnapshot out = p;
  out.cell = p.cell * m;
  out.reference_cell = p.reference_cell * m;  // F = cell·reference⁻¹ is unchanged
  const Eigen::Matrix2d m_inv = m.inverse();  // integer: det M = 1
  for (std::size_t i = 0; i < p.sx.size(); ++i) {
    const Eigen::Vector2d s = m_inv * Eigen::Vector2d(p.sx[i], p.sy[i]);
    out.sx[i] = s.x();
    out.sy[i] = s.y();
  }
  return out;
}

struct BasisCase {
  std::string name;
  Eigen::Matrix2d m;
};

std::vector<BasisCase> BasisCases() {
  Eigen::Matrix2d b_plus_a, b_minus_a, a_plus_b;
  b_plus_a << 1, 1, 0, 1;    // b' = b + a, s'_x = s_x − s_y
  b_minus_a << 1, -1, 0, 1;  // b' = b − a, s'_x = s_x + s_y
  a_plus_b << 1, 0, 1, 1;    // a' = a + b, s'_y = s_y − s_x
  return {{"b_plus_a", b_plus_a}, {"b_minus_a", b_minus_a}, {"a_plus_b", a_plus_b}};
}

// The packing described in the basis h·M gives the same homogenised state,
// and the same dynamics.
void ExpectSameStateInBasis(const RveSnapshot& original, const Eigen::Matrix2d& m) {
  const RveSnapshot skewed = ChangeBasis(original, m);
  ASSERT_NE(skewed.cell, original.cell);
  Rve a = CreateOrDie(original), b = CreateOrDie(skewed);
  const RveState sa = a.Observe(/*want_tangent=*/true), sb = b.Observe(/*want_tangent=*/true);
  // s' = M⁻¹·s adds round-off ~1e-16 × 0.2 m to positions, ~1e-12 of a
  // typical 3e-5 m overlap; summed over ~800 contacts the stress agrees to
  // well within 1e-10.
  EXPECT_LT((sb.stress - sa.stress).norm(), 1e-10 * sa.stress.norm());
  EXPECT_LT((sb.fabric - sa.fabric).norm(), 1e-12);
  ASSERT_TRUE(sa.tangent && sb.tangent);
  EXPECT_LT((*sb.tangent - *sa.tangent).norm(), 1e-10 * sa.tangent->norm());
  EXPECT_EQ(sb.num_contacts, sa.num_contacts);
  EXPECT_NEAR(sb.void_ratio, sa.void_ratio, 1e-12);
  EXPECT_NEAR(sb.volume, sa.volume, 1e-14 * sa.volume);
  EXPECT_GT(sa.num_contacts, 600);  // a real, jammed packing

  // And the dynamics agree: the skewed cell is not reduced, so the first step
  // flips it back; 50 steps of a shear later the states still match (chaotic
  // growth of the initial 1e-16 differences measured ≤ 1e-13, far below the tolerance).
  CellControl shear;
  shear.xy = {ControlMode::kStrainRate, 1e-5 / a.time_step()};
  const RveState ra = a.Run(shear, 50), rb = b.Run(shear, 50);
  EXPECT_LT((rb.stress - ra.stress).norm(), 1e-10 * ra.stress.norm());
  const Eigen::Matrix2d hb = b.cell();
  EXPECT_LE(std::abs(hb.col(0).dot(hb.col(1))), 0.55 * hb.col(0).squaredNorm());
}

// One test over all bases: each test process prepares SET-dense once.
TEST(LatticeBasisTest, SkewedBasisGivesTheSameState) {
  const RveSnapshot& original = Prepared("SET-dense");
  ASSERT_FALSE(original.radius.empty());
  for (const BasisCase& basis : BasisCases()) {
    SCOPED_TRACE(basis.name);
    ExpectSameStateInBasis(original, basis.m);
  }
}

// --- Cell flips under large simple shear. ---

// |a·b| ≤ 0.55·min(|a|², |b|²): the engine's reduction rule (MaybeFlip).
bool IsReduced(const Eigen::Matrix2d& h) {
  const double ab = std::abs(h.col(0).dot(h.col(1)));
  return ab <= 0.55 * h.col(0).squaredNorm() && ab <= 0.55 * h.col(1).squaredNorm();
}

class CellFlipTest : public testing::Test {
 protected:
  static constexpr double kStrainPerStep = 1e-4;  // fast, but keeps the run to ~7000 steps
  struct Record {
    std::vector<double> change;  // |σ_k − σ_{k−1}| (Frobenius), Pa
    int flip_step = -1;          // index of the (first) step that flipped the cell
    int flips = 0;
    RveSnapshot before_flip;  // state at the start of the flip step
    RveState end;
    Eigen::Matrix2d end_cell;
    Eigen::Matrix2d end_f;  // deformation gradient since the prepared state
  };
  // Shears SET-dense to γ = 0.7 at a fixed xy strain rate, step by step.
  static const Record& Sheared() {
    static const Record* record = [] {
      auto* r = new Record;
      if (Prepared("SET-dense").radius.empty()) return r;  // preparation failed (reported there)
      Rve rve = CreateOrDie(Prepared("SET-dense"));
      CellControl control;
      control.xy = {ControlMode::kStrainRate, kStrainPerStep / rve.time_step()};
      RveState prev = rve.Observe();
      const int steps = static_cast<int>(std::lround(0.7 / kStrainPerStep));
      for (int k = 0; k < steps; ++k) {
        const Eigen::Matrix2d h = rve.cell();
        const bool near = std::abs(h.col(0).dot(h.col(1))) > 0.5 * h.col(0).squaredNorm();
        RveSnapshot start;
        if (near && r->flips == 0) start = rve.ToSnapshot();
        const RveState s = rve.Run(control, 1);
        r->change.push_back((s.stress - prev.stress).norm());
        prev = s;
        // A flip replaces b by b − a: its x component jumps by |a|.
        if (std::abs(rve.cell()(0, 1) - h(0, 1)) > 0.5 * h(0, 0)) {
          if (r->flips++ == 0) {
            r->flip_step = k;
            r->before_flip = std::move(start);
          }
        }
      }
      r->end = prev;
      r->end_cell = rve.cell();
      r->end_f = rve.DeformationGradient();
      return r;
    }();
    return *record;
  }
};

TEST_F(CellFlipTest, ShearPastTheThresholdFlipsSmoothlyAndKeepsRunning) {
  const Record& r = Sheared();
  // One flip: at γ ≈ 0.55 (the cell starts square, up to the preparation).
  EXPECT_EQ(r.flips, 1);
  ASSERT_GE(r.flip_step, 0);
  EXPECT_NEAR((r.flip_step + 1) * kStrainPerStep, 0.55, 0.05);
  EXPECT_TRUE(IsReduced(r.end_cell)) << r.end_cell;
  EXPECT_TRUE(r.end.stress.allFinite());
  EXPECT_GT(-r.end.stress.trace() / 2.0, 50e3);  // still a loaded packing, Pa
  EXPECT_GT(r.end.coordination, 3.0);
  EXPECT_TRUE(std::isfinite(r.end.fabric_anisotropy));
  // The cell shape is the same lattice as F·h0: |det| is preserved by simple
  // shear, and the flipped b is b − a.
  EXPECT_NEAR(r.end_cell.determinant(), Prepared("SET-dense").cell.determinant(),
              1e-9 * Prepared("SET-dense").cell.determinant());

  // The deformation gradient is tracked through the flip: F = I + γ e_x⊗e_y
  // with γ = 7000 steps × 1e-4 (round-off of 7000 products (I + Δt·L)).
  const Eigen::Matrix2d f = r.end_f;
  EXPECT_NEAR(f(0, 1), 0.7, 1e-9);
  EXPECT_NEAR(f(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(f(1, 1), 1.0, 1e-12);
  EXPECT_NEAR(f(1, 0), 0.0, 1e-12);

  // The flip is invisible in the stress history.
  ASSERT_GE(r.flip_step, 5);
  ASSERT_LT(r.flip_step + 5, static_cast<int>(r.change.size()));
  // Step-to-step noise of this fast shear is ~0.1 % of p; the flip step must
  // look like its neighbours. Losing contacts or their tangential history in
  // the flip would jump σ by ~10 % of p.
  double neighbours = 0.0;
  for (int k = r.flip_step - 5; k <= r.flip_step + 5; ++k) {
    if (k != r.flip_step) neighbours = std::max(neighbours, r.change[k]);
  }
  EXPECT_GT(neighbours, 0.0);
  EXPECT_LE(r.change[r.flip_step], 2.0 * neighbours)
      << "flip step " << r.flip_step << " changed σ by " << r.change[r.flip_step] << " Pa";
}

// The flip is an exact relabelling: the step that flips gives the same state
// as the same step taken from the packing already described in the flipped
// basis (b' = b − a, s'_x = s_x + s_y).
TEST_F(CellFlipTest, FlipStepEqualsAStepInThePreFlippedBasis) {
  const Record& r = Sheared();
  ASSERT_FALSE(r.before_flip.radius.empty());
  Eigen::Matrix2d m;
  m << 1, -1, 0, 1;
  Rve flips = CreateOrDie(r.before_flip);
  Rve pre_flipped = CreateOrDie(ChangeBasis(r.before_flip, m));
  CellControl control;
  control.xy = {ControlMode::kStrainRate, kStrainPerStep / flips.time_step()};
  const Eigen::Matrix2d h0 = flips.cell();
  const RveState a = flips.Run(control, 1);
  const RveState b = pre_flipped.Run(control, 1);
  EXPECT_LT(flips.cell()(0, 1), h0(0, 1) - 0.5 * h0(0, 0)) << "did not flip: b' = b − a";
  // Same lattice basis afterwards, and the same state up to round-off of s'.
  EXPECT_LT((flips.cell() - pre_flipped.cell()).norm(), 1e-14 * h0.norm());
  EXPECT_LT((flips.DeformationGradient() - pre_flipped.DeformationGradient()).norm(), 1e-14);
  EXPECT_LT((a.stress - b.stress).norm(), 1e-10 * a.stress.norm());
  EXPECT_EQ(a.num_contacts, b.num_contacts);
  const RveSnapshot pa = flips.ToSnapshot(), pb = pre_flipped.ToSnapshot();
  ASSERT_EQ(pa.contacts.size(), pb.contacts.size());
  double max_ft = 0.0, max_dft = 0.0;
  for (std::size_t k = 0; k < pa.contacts.size(); ++k) {
    EXPECT_EQ(pa.contacts[k].i, pb.contacts[k].i);
    EXPECT_EQ(pa.contacts[k].j, pb.contacts[k].j);
    max_ft = std::max(max_ft, std::abs(pa.contacts[k].tangential_force));
    max_dft = std::max(max_dft,
                       std::abs(pa.contacts[k].tangential_force - pb.contacts[k].tangential_force));
  }
  EXPECT_GT(max_ft, 0.0);  // the history is alive (material friction)
  EXPECT_LT(max_dft, 1e-9 * max_ft);
}

// Apply spreads one increment over many DEM steps; a flip during them
// re-bases the cell, and the rest of the increment must follow the same cell
// path in the new basis (it used to return to the old basis without the
// particles' relabelling: the packing jumped by a whole cell, p × 5).
TEST(CellFlipApplyTest, SimpleShearThroughApplyIsContinuousAcrossAFlip) {
  ASSERT_FALSE(Prepared("SET-dense").radius.empty());
  Rve rve = CreateOrDie(Prepared("SET-dense"));
  Eigen::Matrix3d df = Eigen::Matrix3d::Identity();
  df(0, 1) = 5e-3;  // simple shear, γ per call
  RveState prev = rve.Observe();
  std::vector<double> change;
  int flips = 0, flip_call = -1;
  std::int64_t min_steps = 1 << 30;
  for (int k = 0; k < 140; ++k) {
    const Eigen::Matrix2d h = rve.cell();
    absl::StatusOr<RveState> s = rve.Apply(df);
    ASSERT_TRUE(s.ok()) << s.status();
    min_steps = std::min(min_steps, s->steps);
    change.push_back((s->stress - prev.stress).norm());
    prev = *s;
    if (std::abs(rve.cell()(0, 1) - h(0, 1)) > 0.5 * h(0, 0)) {
      ++flips;
      flip_call = k;
    }
  }
  ASSERT_GT(min_steps, 1) << "the flip must fall inside a multi-step increment";
  EXPECT_EQ(flips, 1);
  ASSERT_GE(flip_call, 5);
  ASSERT_LT(flip_call + 5, static_cast<int>(change.size()));
  // F = I + 0.7 e_x⊗e_y, through the flip.
  const Eigen::Matrix2d f = rve.DeformationGradient();
  EXPECT_NEAR(f(0, 1), 0.7, 1e-9);
  EXPECT_NEAR(f(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(f(1, 1), 1.0, 1e-12);
  double neighbours = 0.0;
  for (int k = flip_call - 5; k <= flip_call + 5; ++k) {
    if (k != flip_call) neighbours = std::max(neighbours, change[k]);
  }
  EXPECT_LE(change[flip_call], 3.0 * neighbours)
      << "flip in call " << flip_call << " changed σ by " << change[flip_call] << " Pa";
  EXPECT_GT(prev.MeanPressure(), 30e3);  // still a loaded packing
  EXPECT_LT(prev.MeanPressure(), 1e6);
}

// --- Cell doubling: two copies of the cell side by side are the same
// infinite packing, so the homogenised state and F must not change, and the
// doubled RVE must go on as the single one does (a wrong copy of the
// contact history across the edge shows as a jump in σ). ---

TEST(CellDoublingTest, DoubledCellIsTheSamePacking) {
  ASSERT_FALSE(Prepared("SET-dense").radius.empty());
  Rve sheared = CreateOrDie(Prepared("SET-dense"));
  Eigen::Matrix3d df = Eigen::Matrix3d::Identity();
  df(0, 1) = 0.02;  // simple shear: tangential history and a sheared cell
  ASSERT_TRUE(sheared.Apply(df).ok());
  ASSERT_TRUE(sheared.Apply(df).ok());
  const RveState before = sheared.Observe();
  const std::size_t history = sheared.ToSnapshot().contacts.size();
  ASSERT_GT(history, 100u);
  for (int axis : {0, 1}) {
    SCOPED_TRACE(axis);
    Rve single = sheared;
    Rve doubled = sheared;
    ASSERT_TRUE(doubled.DoubleCell(axis).ok());
    EXPECT_EQ(doubled.num_particles(), 2 * single.num_particles());
    EXPECT_EQ(doubled.ToSnapshot().contacts.size(), 2 * history);
    EXPECT_LT((doubled.DeformationGradient() - single.DeformationGradient()).norm(), 1e-14);
    const RveState after = doubled.Observe();
    EXPECT_EQ(after.num_contacts, 2 * before.num_contacts);
    EXPECT_LT((after.stress - before.stress).norm(), 1e-12 * before.stress.norm());
    EXPECT_LT((after.fabric - before.fabric).norm(), 1e-12);
    EXPECT_NEAR(after.void_ratio, before.void_ratio, 1e-14);
    EXPECT_NEAR(after.coordination, before.coordination, 1e-12);
    // A short increment more: both go on alike (over a long one, rounding
    // differences of the summation order grow chaotically, ~1e-7 in 0.02).
    Eigen::Matrix3d small = Eigen::Matrix3d::Identity();
    small(0, 1) = 2e-4;
    absl::StatusOr<RveState> a = single.Apply(small);
    absl::StatusOr<RveState> b = doubled.Apply(small);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->steps, b->steps);
    EXPECT_LE(a->steps, 100);
    EXPECT_GT((a->stress - before.stress).norm(), 1e-3 * before.stress.norm());  // it moved
    EXPECT_LT((b->stress - a->stress).norm(), 1e-9 * a->stress.norm());
  }
}

TEST(CellDoublingTest, CellSqueezedFlatDoublesAndGoesOn) {
  ASSERT_FALSE(Prepared("SET-dense").radius.empty());
  Rve rve = CreateOrDie(Prepared("SET-dense"));
  const int n0 = rve.num_particles();
  const Eigen::Matrix2d h0 = rve.cell();
  Eigen::Matrix3d df = Eigen::Matrix3d::Identity();
  df(1, 1) = 0.975;  // isochoric squeeze: the cell gets thin in y
  df(0, 0) = 1.0 / 0.975;
  ApplyOptions fast;
  fast.max_inertial_number = 1e-2;
  RveState prev = rve.Observe();
  std::vector<double> change;
  int doubling_call = -1;
  for (int k = 0; k < 120 && doubling_call < 0; ++k) {
    absl::StatusOr<RveState> s = rve.Apply(df, fast);
    ASSERT_TRUE(s.ok()) << "call " << k << ": " << s.status();
    change.push_back((s->stress - prev.stress).norm());
    prev = *s;
    if (rve.num_particles() != n0) doubling_call = k;
  }
  ASSERT_GE(doubling_call, 5) << "the squeeze must double the cell";
  EXPECT_EQ(rve.num_particles(), 2 * n0);
  // F_yy = 0.975^(k+1): F follows the calls through the doubling.
  EXPECT_NEAR(rve.DeformationGradient()(1, 1), std::pow(0.975, doubling_call + 1), 1e-9);
  EXPECT_NEAR(rve.DeformationGradient()(0, 1), 0.0, 1e-12);
  // Twice the area (isochoric ΔF), in whatever lattice basis it ended.
  EXPECT_NEAR(rve.cell().determinant(), 2.0 * h0.determinant(), 1e-9 * h0.determinant());
  for (int k = 0; k < 5; ++k) {
    absl::StatusOr<RveState> s = rve.Apply(df, fast);
    ASSERT_TRUE(s.ok()) << s.status();
    change.push_back((s->stress - prev.stress).norm());
    prev = *s;
  }
  double neighbours = 0.0;
  for (int k = doubling_call - 5; k <= doubling_call + 5; ++k) {
    if (k != doubling_call) neighbours = std::max(neighbours, change[k]);
  }
  EXPECT_LE(change[doubling_call], 3.0 * neighbours)
      << "doubling in call " << doubling_call << " changed σ by " << change[doubling_call] << " Pa";
  EXPECT_GT(prev.MeanPressure(), 10e3);
}

}  // namespace
}  // namespace rvehub::dem
