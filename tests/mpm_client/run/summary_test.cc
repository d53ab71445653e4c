// The headline figures of summary.json from hand-made timeseries columns,
// and the timeseries reader that `summarise` feeds them from.
#include "mpm_client/run/summary.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "mpm_client/core/two_phase.h"
#include "mpm_client/run/output.h"

namespace rvehub::mpm {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

TEST(SummaryTest, PrandtlNqMatchesThePaper) {
  // liang-zhao-mpm-dem §3.3: φ' = 28.1° gives 14.8; cases/friction_angle.py
  // gives 22.31 for footing-dense's 31.67°.
  EXPECT_NEAR(PrandtlNq(28.1 * kDeg), 14.88, 0.005);
  EXPECT_NEAR(PrandtlNq(31.67 * kDeg), 22.30, 0.005);
  EXPECT_DOUBLE_EQ(PrandtlNq(0.0), 1.0);
  // Local shear and punching (eq. 47): the paper's 3.7 and 3.1 for the
  // medium (20.8°) and soft (18.2°) packings.
  EXPECT_NEAR(ReducedNq(20.8 * kDeg), 3.66, 0.01);
  EXPECT_NEAR(ReducedNq(18.2 * kDeg), 3.07, 0.01);
  EXPECT_DOUBLE_EQ(ReducedNq(0.0), 1.0);
}

TEST(SummaryTest, UltimateLoadOfACurveWithAPeakIsThePeak) {
  std::vector<double> d, q;
  for (int i = 0; i <= 100; ++i) {
    d.push_back(0.01 * i);
    q.push_back(100.0 * (1.0 - (d.back() - 0.5) * (d.back() - 0.5) / 0.25));
  }
  absl::StatusOr<UltimateLoad> u = FindUltimateLoad(d, q);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_TRUE(u->peak);
  // The smoothing flattens the top over a few rows: the peak within a row
  // of d = 0.5 and within 0.1 % of the load there.
  EXPECT_NEAR(u->settlement, 0.5, 0.0101);
  EXPECT_NEAR(u->load, 100.0, 0.1);
}

TEST(SummaryTest, OneFlickeringRowIsNoPeakAndARisingCurveEndsAtItsSmallestSlope) {
  // Slope 10 up to d = 0.3, then 1: the ultimate load is where the slope
  // settles at its minimum, just past the knee (within the smoothing window).
  std::vector<double> d, q;
  for (int i = 0; i <= 100; ++i) {
    d.push_back(0.01 * i);
    q.push_back(d.back() <= 0.3 ? 10.0 * d.back() : 3.0 + (d.back() - 0.3));
  }
  absl::StatusOr<UltimateLoad> u = FindUltimateLoad(d, q);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_FALSE(u->peak);
  EXPECT_GE(u->settlement, 0.3);
  EXPECT_LE(u->settlement, 0.33) << u->settlement;
  // One row on the rising part dips by 5 % (as a node row emptying makes
  // it): no peak there.
  q[20] *= 0.95;
  u = FindUltimateLoad(d, q);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_FALSE(u->peak);
  EXPECT_GE(u->settlement, 0.3);
  EXPECT_FALSE(FindUltimateLoad(std::vector<double>{0, 1}, std::vector<double>{0, 1}).ok());
}

TEST(SummaryTest, AGridCrossingsJumpIsNoPeakWhenSmoothedOverItsPeriod) {
  // A knee at d = 0.2 m (slope 10 then 1), and every h = 0.1 m of
  // settlement the load drops by 10 % over 0.02 m, as when the footing
  // crosses a node row: sustained for 7 rows, no row filter removes it.
  constexpr double h = 0.1;
  std::vector<double> d, q;
  for (int i = 0; i <= 500; ++i) {
    d.push_back(0.003 * i);
    const double base = d.back() <= 0.2 ? 10.0 * d.back() : 2.0 + (d.back() - 0.2);
    const double phase = std::fmod(d.back(), h);
    q.push_back(phase > 0.05 && phase < 0.07 ? 0.9 * base : base);
  }
  // Without the span a jump on the steep part reads as a peak.
  absl::StatusOr<UltimateLoad> u = FindUltimateLoad(d, q);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_TRUE(u->peak);
  EXPECT_LT(u->settlement, 0.2);
  // Over one period: the knee, where the slope settles at 1 (found within
  // half a span past it, the span blurring the knee), and the load there:
  // the curve's top within the next half span.
  u = FindUltimateLoad(d, q, h);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_FALSE(u->peak);
  EXPECT_GE(u->settlement, 0.2);
  EXPECT_LE(u->settlement, 0.2 + 1.5 * h) << u->settlement;
  EXPECT_NEAR(u->load, 2.0 + (u->settlement - 0.2), 0.01);
  EXPECT_FALSE(FindUltimateLoad(d, q, -h).ok());
  const absl::StatusOr<UltimateLoad> too_long = FindUltimateLoad(d, q, 2.0);  // the curve: 1.5 m
  ASSERT_FALSE(too_long.ok());
  EXPECT_NE(too_long.status().message().find("shorter than the smoothing span (2 m)"),
            std::string::npos)
      << too_long.status();
}

TEST(SummaryTest, AWideSpanDoesNotShaveAPeak) {
  // A sharp peak of 100 at 0.5 m: the span locates it and the load reported
  // is the 5-row curve's top (98.6: the row filters round a sharp top by a
  // row's rise), not the wide mean's (~91 here).
  std::vector<double> d, q;
  for (int i = 0; i <= 200; ++i) {
    d.push_back(0.005 * i);
    q.push_back(100.0 - 100.0 * std::abs(d.back() - 0.5) / 0.5);
  }
  absl::StatusOr<UltimateLoad> u = FindUltimateLoad(d, q, 0.1);
  ASSERT_TRUE(u.ok()) << u.status();
  EXPECT_TRUE(u->peak);
  EXPECT_NEAR(u->settlement, 0.5, 0.0051);
  EXPECT_NEAR(u->load, 98.6, 0.01);
}

TEST(SummaryTest, FrontStopsWhenItStaysWithinTheTolerance) {
  const std::vector<double> t = {0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8};
  const std::vector<double> x = {1.0, 1.2, 1.5, 1.8, 1.9, 1.95, 1.96, 1.96, 1.96};
  EXPECT_DOUBLE_EQ(FrontStopTime(t, x, 0.02), 0.5);
  EXPECT_DOUBLE_EQ(FrontStopTime(t, x, 0.001), 0.6);
}

CaseSpec Region(double width, double height, int ppc, double h) {
  CaseSpec spec;
  spec.name = "test";
  spec.grid.cell_size = h;
  MaterialRegion r;
  r.upper = Eigen::Vector2d(width, height);
  r.points_per_cell_side = ppc;
  spec.regions.push_back(r);
  return spec;
}

// The same with a rigid body named `body` (bodies' forces are read by name).
CaseSpec RegionWithBody(double width, double height, int ppc, double h, const std::string& body) {
  CaseSpec spec = Region(width, height, ppc, h);
  RigidBody b;
  b.name = body;
  spec.bodies.push_back(b);
  return spec;
}

// A deposit of 10 × 3 points 0.1 m apart with a sheet running out along
// its base, points 0.19 m apart (linked at 0.2 m), then one point 0.25 m
// past the sheet (scatter) and a pair far off (a second, smaller set).
TEST(SummaryTest, MainDepositFrontDropsScatterPoints) {
  std::vector<Eigen::Vector2d> x;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 10; ++i) x.emplace_back(0.1 * i, 0.1 * j);
  }
  for (int k = 1; k <= 5; ++k) x.emplace_back(0.9 + 0.19 * k, 0.0);  // to 1.85 m
  x.emplace_back(2.1, 0.0);
  x.emplace_back(3.0, 0.5);
  x.emplace_back(3.1, 0.5);
  EXPECT_DOUBLE_EQ(MainDepositFront(x, {}, 0.2), 0.9 + 0.19 * 5);
  // A longer link reaches the scatter point; a shorter one cuts the sheet.
  EXPECT_DOUBLE_EQ(MainDepositFront(x, {}, 0.26), 2.1);
  EXPECT_DOUBLE_EQ(MainDepositFront(x, {}, 0.15), 0.9);
  // A parked point takes no part: without the sheet's third point the
  // deposit ends at its second.
  std::vector<std::uint8_t> skip(x.size(), 0);
  skip[30 + 2] = 1;
  EXPECT_DOUBLE_EQ(MainDepositFront(x, skip, 0.2), 0.9 + 0.19 * 2);
  // The order of the points does not matter.
  std::vector<Eigen::Vector2d> reversed(x.rbegin(), x.rend());
  EXPECT_DOUBLE_EQ(MainDepositFront(reversed, {}, 0.2), 0.9 + 0.19 * 5);
  // Negative coordinates bin alike; no points: −∞.
  std::vector<Eigen::Vector2d> shifted;
  for (const Eigen::Vector2d& p : x) shifted.push_back(p - Eigen::Vector2d(5.0, 5.0));
  EXPECT_DOUBLE_EQ(MainDepositFront(shifted, {}, 0.2), 0.9 + 0.19 * 5 - 5.0);
  EXPECT_EQ(MainDepositFront({}, {}, 0.2), -std::numeric_limits<double>::infinity());
  // A non-finite position is left out; a link that is no length gives −∞.
  std::vector<Eigen::Vector2d> with_nan = x;
  with_nan.emplace_back(std::nan(""), 0.0);
  with_nan.emplace_back(std::numeric_limits<double>::infinity(), 0.0);
  EXPECT_DOUBLE_EQ(MainDepositFront(with_nan, {}, 0.2), 0.9 + 0.19 * 5);
  for (double bad : {0.0, -0.2, std::nan(""), std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(MainDepositFront(x, {}, bad), -std::numeric_limits<double>::infinity()) << bad;
  }
}

// Ten points of 1 kg at x = 0, 0.1, …, 0.9 m and a sheet of five of
// 0.2 kg to 1.4 m: 11 kg in all.
TEST(SummaryTest, MassFrontIsWhereAShareOfTheMassLiesBehind) {
  std::vector<Eigen::Vector2d> x;
  std::vector<double> m;
  for (int i = 0; i < 10; ++i) {
    x.emplace_back(0.1 * i, 0.0);
    m.push_back(1.0);
  }
  for (int k = 1; k <= 5; ++k) {
    x.emplace_back(0.9 + 0.1 * k, 0.05);
    m.push_back(0.2);
  }
  // 10 kg lie behind 0.9 m (0.909 of 11), 10.8 kg behind 1.3 m (0.982).
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 0.9), 0.9);
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 0.95), 0.9 + 0.1 * 3);  // 10.6 kg; 10.4 at 1.1 m
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 0.98), 1.3);
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 0.99), 1.4);
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 1.0), 1.4);
  EXPECT_DOUBLE_EQ(MassFront(x, m, {}, 0.05), 0.0);
  // Mass, not the count of points: with equal masses 0.9 of 15 points lie
  // behind the 14th point, 1.3 m.
  const std::vector<double> equal(x.size(), 1.0);
  EXPECT_DOUBLE_EQ(MassFront(x, equal, {}, 0.9), 1.3);
  // "At least": half of four points lies behind the second.
  EXPECT_DOUBLE_EQ(MassFront(std::span<const Eigen::Vector2d>(x).first(4),
                             std::span<const double>(equal).first(4), {}, 0.5),
                   0.1);
  // The order of the points does not matter.
  std::vector<Eigen::Vector2d> rx(x.rbegin(), x.rend());
  std::vector<double> rm(m.rbegin(), m.rend());
  EXPECT_DOUBLE_EQ(MassFront(rx, rm, {}, 0.98), 1.3);
  // A parked point, a non-finite position and a mass that is no mass take no
  // part: without the sheet's last point 10.8 of 10.8 kg lie behind 1.3 m.
  std::vector<std::uint8_t> skip(x.size(), 0);
  skip.back() = 1;
  EXPECT_DOUBLE_EQ(MassFront(x, m, skip, 0.99), 1.3);
  std::vector<Eigen::Vector2d> bad_x = x;
  std::vector<double> bad_m = m;
  for (double v : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    bad_x.emplace_back(v, 0.0);
    bad_m.push_back(1.0);
    bad_x.emplace_back(5.0, 0.0);
    bad_m.push_back(v);
  }
  bad_x.emplace_back(6.0, 0.0);
  bad_m.push_back(0.0);
  bad_x.emplace_back(7.0, 0.0);
  bad_m.push_back(-1.0);
  EXPECT_DOUBLE_EQ(MassFront(bad_x, bad_m, {}, 0.99), 1.4);
  // No points, masses that do not match the points, a share outside (0, 1]: −∞.
  constexpr double kNone = -std::numeric_limits<double>::infinity();
  EXPECT_EQ(MassFront({}, {}, {}, 0.98), kNone);
  EXPECT_EQ(MassFront(x, std::span<const double>(m).first(3), {}, 0.98), kNone);
  for (double share : {0.0, -0.5, 1.01, std::nan("")}) {
    EXPECT_EQ(MassFront(x, m, {}, share), kNone) << share;
  }
}

TEST(SummaryTest, FootingCollapseBiaxialAndPipeFigures) {
  // Footing: B·t = 0.5 m², 20 kPa surcharge, φ' 30°.
  CaseSpec footing = Region(3, 2, 1, 0.25);
  footing.output.plot = "load-settlement";
  footing.output.plot_body = "footing";
  footing.output.plot_width = 0.5;
  footing.output.phi_deg = 30.0;
  SurfaceTraction surcharge;
  surcharge.normal_axis = 1;
  surcharge.normal_sign = 1;
  surcharge.traction = Eigen::Vector2d(0.0, -20e3);
  footing.tractions.push_back(surcharge);
  std::map<std::string, std::vector<double>> cols;
  for (int i = 0; i <= 40; ++i) {
    const double d = 0.005 * i;
    cols["footing_dy"].push_back(-d);
    cols["footing_fy"].push_back(0.5 * 200e3 * std::min(d, 0.1) / 0.1 *
                                 (d > 0.1 ? 1 - (d - 0.1) : 1));
  }
  absl::StatusOr<Summary> s = Summarise(footing, cols);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  // A sharp peak (200 kPa at 0.1 m) is rounded off by the smoothing.
  EXPECT_NEAR(m["ultimate_load_Pa"], 200e3, 0.02 * 200e3);
  EXPECT_NEAR(m["settlement_at_ultimate_m"], 0.1, 0.0151);
  EXPECT_NEAR(m["N_q"], m["ultimate_load_Pa"] / 20e3, 1e-12);
  EXPECT_NEAR(m["N_q_prandtl"], 18.40, 0.01);
  EXPECT_NEAR(m["N_q_reduced"], ReducedNq(30.0 * kDeg), 1e-12);
  EXPECT_EQ(m["phi_deg"], 30.0);
  // A full model (no footing body at the grid's edge): B = plot_width =
  // 0.5 m, so d/B = 0.1 at 0.05 m, the mean over 0.05 ± 0.125 m of the
  // rising curve and the peak.
  double sum = 0.0;
  int rows = 0;
  for (int i = 0; i <= 40; ++i) {
    if (std::abs(0.005 * i - 0.05) <= 0.125) {
      sum += cols["footing_fy"][i] / 0.5;
      ++rows;
    }
  }
  EXPECT_NEAR(m["load_at_tenth_width_Pa"], sum / rows, 1e-6);
  EXPECT_NEAR(m["N_q_at_tenth_width"], sum / rows / 20e3, 1e-9);
  // The knee: the start (d ≤ 0.02·B = 0.01 m) rises at 2 MPa/m from 0, the
  // second half (d ≥ 0.1 m) falls at 200 kPa/m from 220 kPa at d = 0: they
  // meet at d = 220/2200 m = 0.1 m, 200 kPa.
  EXPECT_NEAR(m["settlement_at_knee_m"], 0.1, 1e-9);
  EXPECT_NEAR(m["knee_load_Pa"], 200e3, 1e-6);
  EXPECT_NEAR(m["N_q_knee"], 10.0, 1e-9);
  // A half model, the footing from the grid's left edge: B = 1 m, and the
  // curve (to 0.2 m) stops short of 0.1 m + half a cell (0.125 m).
  RigidBody half;
  half.name = "footing";
  half.center = Eigen::Vector2d(0.25, 0.6);
  half.half_size = Eigen::Vector2d(0.25, 0.1);
  footing.bodies.push_back(half);
  s = Summarise(footing, cols);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  EXPECT_FALSE(m.contains("N_q_at_tenth_width"));
  footing.grid.cell_size = 0.1;  // now 0.1 ± 0.05 m lies on the curve
  s = Summarise(footing, cols);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  sum = 0.0;
  rows = 0;
  for (int i = 0; i <= 40; ++i) {
    if (std::abs(0.005 * i - 0.1) <= 0.05) {
      sum += cols["footing_fy"][i] / 0.5;
      ++rows;
    }
  }
  EXPECT_NEAR(m["N_q_at_tenth_width"], sum / rows / 20e3, 1e-9);

  // Collapse: a 1 m column of 0.25 m cells with 2 points per side (half
  // spacing 0.0625 m), the front stopping at 1.7375 + 0.0625 = 1.8 m.
  CaseSpec collapse = Region(1, 1, 2, 0.25);
  collapse.output.summary = "collapse";
  // The figures by name (empty, and the test failed, on an error).
  const auto by_name = [](const CaseSpec& spec,
                          const std::map<std::string, std::vector<double>>& cols) {
    const absl::StatusOr<Summary> result = Summarise(spec, cols);
    EXPECT_TRUE(result.ok()) << result.status();
    return result.ok() ? std::map<std::string, double>(result->begin(), result->end())
                       : std::map<std::string, double>();
  };
  std::map<std::string, std::vector<double>> c;
  c["time"] = {0.0, 0.5, 1.0, 1.5};
  c["front_x"] = {0.9375, 1.5, 1.7375, 1.7375};
  m = by_name(collapse, c);
  EXPECT_NEAR(m["runout_normalised"], 0.8, 1e-12);
  EXPECT_DOUBLE_EQ(m["front_stop_time_s"], 1.0);
  EXPECT_EQ(m["front_at_rest"], 1.0);
  // Still moving at the end: it "stops" at the last row, not at rest.
  c["front_x"] = {0.9375, 1.5, 1.7375, 1.9};
  m = by_name(collapse, c);
  EXPECT_DOUBLE_EQ(m["front_stop_time_s"], 1.5);
  EXPECT_EQ(m["front_at_rest"], 0.0);
  // With the main deposit's front written, the run-out is its: a point
  // thrown to 2.4375 m no longer counts, but is reported.
  c["front_x"] = {0.9375, 1.5, 2.0, 2.4375};
  c["deposit_front_x"] = {0.9375, 1.5, 1.7375, 1.7375};
  m = by_name(collapse, c);
  EXPECT_NEAR(m["runout_normalised"], 0.8, 1e-12);
  EXPECT_NEAR(m["final_front_m"], 1.8, 1e-12);
  EXPECT_NEAR(m["farthest_point_m"], 2.5, 1e-12);
  EXPECT_DOUBLE_EQ(m["front_stop_time_s"], 1.0);
  EXPECT_EQ(m["front_at_rest"], 1.0);
  EXPECT_FALSE(m.contains("runout_normalised_mass98"));
  // With the fronts read by mass written, their run-outs and stop times too:
  // here the 98 % front rests from 0.5 s (within 1 % of d0 from there).
  c["mass_front_98_x"] = {0.9375, 1.33, 1.3375, 1.3375};
  c["mass_front_99_x"] = {0.9375, 1.3, 1.5375, 1.5375};
  m = by_name(collapse, c);
  EXPECT_NEAR(m["runout_normalised"], 0.8, 1e-12);
  EXPECT_NEAR(m["runout_normalised_mass98"], 0.4, 1e-12);
  EXPECT_NEAR(m["runout_normalised_mass99"], 0.6, 1e-12);
  EXPECT_DOUBLE_EQ(m["front_stop_time_mass98_s"], 0.5);
  EXPECT_DOUBLE_EQ(m["front_stop_time_mass99_s"], 1.0);
  EXPECT_DOUBLE_EQ(m["front_stop_time_s"], 1.0);
  EXPECT_FALSE(m.contains("kinetic_energy_peak_J"));
  // With the kinetic energy written (J per metre of thickness), its peak and
  // the time of that row.
  c["kinetic_energy"] = {0.0, 950.0, 120.0, 3.0};
  m = by_name(collapse, c);
  EXPECT_EQ(m["kinetic_energy_peak_J"], 950.0);
  EXPECT_EQ(m["kinetic_energy_peak_time_s"], 0.5);
  // A column shorter than time's is refused by name.
  c["kinetic_energy"] = {0.0, 950.0};
  const absl::StatusOr<Summary> short_ke = Summarise(collapse, c);
  ASSERT_FALSE(short_ke.ok());
  EXPECT_TRUE(absl::StrContains(short_ke.status().message(), "kinetic_energy"))
      << short_ke.status();

  // Biaxial with a platen: force over the width, travel over the height.
  CaseSpec biaxial = RegionWithBody(0.05, 0.1, 1, 0.0125, "platen");
  biaxial.output.plot = "stress-strain";
  std::map<std::string, std::vector<double>> b;
  b["platen_dy"] = {0.0, -0.001, -0.002, -0.003};
  b["platen_fy"] = {0.0, 10e3, 14e3, 12e3};
  s = Summarise(biaxial, b);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  EXPECT_DOUBLE_EQ(m["peak_stress_Pa"], 14e3 / 0.05);
  EXPECT_DOUBLE_EQ(m["peak_strain"], 0.02);
  EXPECT_DOUBLE_EQ(m["final_strain"], 0.03);

  // Pipe: the largest magnitudes.
  biaxial.output.summary = "pipe";
  b["platen_fx"] = {0.0, -3.0, 5.0, -7.0};
  b["platen_dx"] = {0.0, 0.0, 0.0, 0.0};
  s = Summarise(biaxial, b);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  EXPECT_DOUBLE_EQ(m["peak_horizontal_force_N"], 7.0);
  EXPECT_DOUBLE_EQ(m["peak_vertical_force_N"], 14e3);

  // A missing column is named.
  b.erase("platen_fx");
  s = Summarise(biaxial, b);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("platen_fx"), std::string::npos) << s.status();
}

TEST(SummaryTest, PipeStagesSmoothedPeakAndLateralMedians) {
  // Cells of 0.125 m: the penetration peak is a mean over 0.125 m of it.
  CaseSpec pipe = RegionWithBody(3, 1, 1, 0.125, "pipe");
  pipe.output.summary = "pipe";
  std::map<std::string, std::vector<double>> c;
  auto row = [&c](double dx, double dy, double fx, double fy) {
    c["pipe_dx"].push_back(dx);
    c["pipe_dy"].push_back(dy);
    c["pipe_fx"].push_back(fx);
    c["pipe_fy"].push_back(fy);
  };
  // Penetration to 0.2 m: the force rises to 100 kN at 0.08 m and stays,
  // with a one-row spike of 400 kN at 0.01 m.
  for (int i = 0; i <= 40; ++i) {
    const double d = 0.005 * i;
    row(0.0, -d, 10.0, i == 2 ? 400e3 : 100e3 * std::min(d / 0.08, 1.0));
  }
  // Then 0.15 m to the left: 50 kN resisting and 20 kN up, each with a spike.
  for (int k = 1; k <= 30; ++k) {
    row(-0.005 * k, -0.2, k == 20 ? 200e3 : 50e3, k == 25 ? -80e3 : 20e3);
  }
  absl::StatusOr<Summary> s = Summarise(pipe, c);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  EXPECT_DOUBLE_EQ(m["peak_vertical_force_N"], 400e3);  // the spike's row
  EXPECT_DOUBLE_EQ(m["peak_horizontal_force_N"], 200e3);
  // The spike's window (0 to 0.07 m) averages 70 kN; the plateau's 100.
  EXPECT_NEAR(m["penetration_peak_force_N"], 100e3, 1e-6);
  EXPECT_GE(m["penetration_peak_depth_m"], 0.14);
  EXPECT_LE(m["penetration_peak_depth_m"], 0.165);
  EXPECT_DOUBLE_EQ(m["lateral_vertical_force_N"], 20e3);
  EXPECT_DOUBLE_EQ(m["lateral_horizontal_force_N"], 50e3);
  EXPECT_DOUBLE_EQ(m["lateral_travel_m"], 0.15);

  // Without a lateral stage there are no lateral figures.
  for (auto& [name, values] : c) values.resize(41);
  s = Summarise(pipe, c);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  EXPECT_EQ(m.count("lateral_vertical_force_N"), 0u);
  EXPECT_NEAR(m["penetration_peak_force_N"], 100e3, 1e-6);

  // Columns of different lengths are refused.
  c["pipe_dx"].pop_back();
  EXPECT_FALSE(Summarise(pipe, c).ok());
}

TEST(SummaryTest, ShakingLevelsAreTwoCycleMeansOfTheSwingingRatio) {
  // A box shaken at 2.5 Hz, rows every 0.01 s for 10 s: monitor B's ratio
  // swings by ±0.3 at the shake's frequency around a level that climbs to
  // 0.4 at 4 s and falls back to 0.1 at 10 s; C's stays at 0 ± 0.05.
  CaseSpec spec;
  spec.output.summary = "shaking";
  spec.solver.shaking_frequency = 2.5;  // Hz
  spec.phases.monitors = {{"B", {1.0, 0.5}}, {"C", {1.0, 0.0125}}};
  std::map<std::string, std::vector<double>> c;
  const auto level = [](double t) { return t < 4.0 ? 0.1 * t : 0.4 - 0.05 * (t - 4.0); };
  for (int i = 0; i <= 1000; ++i) {
    const double t = 0.01 * i;  // s
    const double swing = std::sin(2.0 * std::numbers::pi * 2.5 * t);
    c["time"].push_back(t);
    c["surface_settlement"].push_back(1e-3 * t);
    c["B_excess_ratio"].push_back(level(t) + 0.3 * swing);
    c["C_excess_ratio"].push_back(0.05 * swing);
  }
  absl::StatusOr<Summary> s = Summarise(spec, c);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  EXPECT_DOUBLE_EQ(m["surface_settlement_m"], 0.01);
  // Two whole cycles (0.8 s, 80 rows) cancel the swing; the level's peak is
  // the window whose ends lie at equal levels, (3.733 s, 4.533 s]: 0.3867.
  EXPECT_NEAR(m["B_excess_ratio_peak"], 0.3867, 1e-3);
  EXPECT_NEAR(m["B_excess_ratio_peak_time_s"], 4.533, 0.011);
  EXPECT_NEAR(m["B_excess_ratio_final"], 0.4 - 0.05 * (9.6 - 4.0), 1e-3);
  EXPECT_NEAR(m["C_excess_ratio_peak"], 0.0, 1e-3);
  EXPECT_NEAR(m["C_excess_ratio_final"], 0.0, 1e-3);

  // A monitor's column missing is named; an unshaken case is refused.
  c.erase("C_excess_ratio");
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "C_excess_ratio")) << s.status();
  spec.solver.shaking_frequency = 0.0;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "shaking_frequency")) << s.status();
}

TEST(SummaryTest, WaveSpeedIsTheMonitorsDistanceOverTheLagOfTheirTraces) {
  // R3 and R7, 4 m apart on the surface, rows every 1 ms: a pulse passes R3
  // at 0.05 s and R7, weaker and broader, 0.0503 s later (79.52 m/s); a
  // larger reflected pulse reaches R7 at 0.3 s, after the 0.2 s window.
  CaseSpec spec;
  spec.output.summary = "wave";
  spec.output.wave_from = "R3";
  spec.output.wave_to = "R7";
  spec.output.wave_window = 0.2;  // s
  spec.phases.monitors = {{"R3", {13.5, 10.0}}, {"R7", {17.5, 10.0}}};
  const auto pulse = [](double t, double at, double width) {
    return std::exp(-std::pow((t - at) / width, 2));
  };
  std::map<std::string, std::vector<double>> c;
  for (int i = 0; i <= 500; ++i) {
    const double t = 1e-3 * i;  // s
    c["time"].push_back(t);
    c["R3_uy"].push_back(-1e-3 * pulse(t, 0.05, 0.01));  // m, down −
    c["R7_uy"].push_back(-0.5e-3 * pulse(t, 0.1003, 0.012) - 2e-3 * pulse(t, 0.3, 0.01));
  }
  absl::StatusOr<Summary> s = Summarise(spec, c);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  // The parabola through three samples of a Gaussian peak: within 2 % of a row.
  EXPECT_NEAR(m["surface_wave_lag_s"], 0.0503, 2e-5);
  EXPECT_NEAR(m["surface_wave_speed_m_per_s"], 4.0 / 0.0503, 0.05);

  // The window is what keeps the reflection out: over the whole run the
  // larger pulse's lag wins.
  spec.output.wave_window = 0.5;
  s = Summarise(spec, c);
  ASSERT_TRUE(s.ok()) << s.status();
  m = std::map<std::string, double>(s->begin(), s->end());
  EXPECT_NEAR(m["surface_wave_lag_s"], 0.25, 2e-3);

  // Unevenly spaced rows, a missing trace and a window of too few rows are named.
  spec.output.wave_window = 0.2;
  std::map<std::string, std::vector<double>> uneven = c;
  uneven["time"][7] += 4e-4;
  s = Summarise(spec, uneven);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "evenly spaced rows; row 7")) << s.status();
  spec.output.wave_window = 0.005;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "at least 8 rows")) << s.status();
  c.erase("R7_uy");
  spec.output.wave_window = 0.2;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "R7_uy")) << s.status();
}

TEST(SummaryTest, ConsolidationIsMeasuredAgainstTerzaghiFromTv004) {
  // A 1 m layer, k = 1e-3 m/s, M = 9.81 MPa: c_v = 1 m²/s, so Tv = t. The
  // RVEs hold 100 kPa of the 110 kPa surcharge: p0 = 10 kPa. The monitors
  // follow Terzaghi but for 2 % of p0 at the base from Tv = 0.2 on and
  // 30 % at Tv = 0.01 (the early wave, not compared); the settlement is
  // 0.01 behind U(Tv).
  CaseSpec spec = Region(0.02, 1.0, 2, 0.02);
  spec.output.summary = "consolidation";
  spec.output.constrained_modulus = 9.81e6;  // Pa
  spec.phases.permeability = 1e-3;           // m/s
  SurfaceTraction surcharge;
  surcharge.normal_axis = 1;
  surcharge.traction = Eigen::Vector2d(0.0, -110e3);
  spec.tractions.push_back(surcharge);
  spec.phases.monitors = {{"base", {0.01, 0.0}}, {"middle", {0.01, 0.5}}};
  const double p0 = 10e3;  // Pa
  std::map<std::string, std::vector<double>> c;
  for (const double t : {0.0, 0.01, 0.05, 0.1, 0.2, 0.5, 1.0}) {
    c["time"].push_back(t);
    c["mean_syy"].push_back(100e3);
    c["base_p"].push_back(TerzaghiExcessPressure(p0, 1.0, t) + (t >= 0.2    ? 0.02 * p0
                                                                : t == 0.01 ? 0.3 * p0
                                                                            : 0.0));
    c["middle_p"].push_back(TerzaghiExcessPressure(p0, 0.5, t));
    c["surface_settlement"].push_back((TerzaghiDegreeOfConsolidation(t) - 0.01) * p0 / 9.81e6);
  }
  absl::StatusOr<Summary> s = Summarise(spec, c);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  EXPECT_DOUBLE_EQ(m["p0_Pa"], p0);
  EXPECT_NEAR(m["c_v_m2_per_s"], 1.0, 1e-12);
  EXPECT_NEAR(m["final_tv"], 1.0, 1e-12);
  EXPECT_NEAR(m["pore_pressure_error_max"], 0.02, 1e-9);
  EXPECT_NEAR(m["degree_of_consolidation_error_max"], 0.01, 1e-9);

  // Columns of different lengths and a surcharge the RVEs already hold are
  // refused, naming what is wrong.
  c["middle_p"].pop_back();
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "middle_p has 6 rows")) << s.status();
  c["middle_p"].push_back(0.0);
  c["mean_syy"][0] = 110e3;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "p0 = 0")) << s.status();
  c["mean_syy"][0] = 100e3;

  // Terzaghi's layer is weightless and needs M and a surcharge.
  spec.solver.gravity = Eigen::Vector2d(0.0, -9.81);
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "gravity")) << s.status();
  spec.solver.gravity = Eigen::Vector2d::Zero();
  spec.output.constrained_modulus = 0.0;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "constrained_modulus")) << s.status();
}

TEST(SummaryTest, ConstantRateOfStrainIsMeasuredAgainstTheSteadyPressure) {
  // A 0.1 m x 1 m layer under a platen at 1 mm/s, 0.999 m high at the end:
  // p(H) = speed·ρ_f·g·H/(2k) = 1e-3·9810·0.999/2e-3 = 4900.095 Pa. The top
  // monitor reads 2 % of that above the steady pressure at its height.
  CaseSpec spec = RegionWithBody(0.1, 1.0, 2, 0.1, "platen");
  spec.output.summary = "crs";
  spec.phases.saturated = true;
  spec.phases.permeability = 1e-3;  // m/s
  spec.phases.monitors = {{"top", {0.05, 1.0}}, {"middle", {0.05, 0.5}}};
  const double height = 0.999, rate = 1e-3 / height, p_top = 4900.095;  // m, 1/s, Pa
  const auto steady = [&](double z) {
    return SteadyConstantRateOfStrainPressure(rate, height, z, 1e-3, 1000.0);
  };
  std::map<std::string, std::vector<double>> c = {{"time", {0.9, 1.0}},
                                                  {"mean_syy", {119e3, 120e3}},
                                                  {"platen_fy", {12.4e3, 12.5e3}},
                                                  {"platen_dy", {-0.0009, -0.001}},
                                                  {"top_p", {0.0, steady(1.0) + 0.02 * p_top}},
                                                  {"middle_p", {0.0, steady(0.5)}}};
  absl::StatusOr<Summary> s = Summarise(spec, c);
  ASSERT_TRUE(s.ok()) << s.status();
  std::map<std::string, double> m(s->begin(), s->end());
  EXPECT_NEAR(m["strain_rate_per_s"], rate, 1e-12);
  EXPECT_NEAR(m["steady_top_pore_pressure_Pa"], p_top, 1e-6);
  EXPECT_NEAR(m["pore_pressure_error_max"], 0.02, 1e-12);
  EXPECT_NEAR(m["platen_stress_Pa"], 125e3, 1e-6);
  EXPECT_NEAR(m["steady_total_stress_Pa"], 120e3 + 2.0 / 3.0 * p_top, 1e-6);

  // A platen that does not move down, a dry or a heavy layer are refused.
  c["platen_dy"] = {-0.001, -0.001};
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "moving down")) << s.status();
  c["platen_dy"] = {-0.0009, -0.001};
  spec.solver.gravity = Eigen::Vector2d(0.0, -9.81);
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "gravity")) << s.status();
  spec.solver.gravity = Eigen::Vector2d::Zero();
  spec.phases.saturated = false;
  s = Summarise(spec, c);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(absl::StrContains(s.status().message(), "saturated")) << s.status();
}

// summarise reads DIR/timeseries.csv back: a damaged file is refused with
// the row and column, never summarised from made-up values. A NaN pasted
// into a footing's load column used to pass and flip ultimate_is_peak.
TEST(TimeseriesReaderTest, DamagedRowsAreDataLossNamingRowAndColumn) {
  const std::string path = ::testing::TempDir() + "/summary_test_timeseries.csv";
  auto read = [&](const std::string& text) {
    std::ofstream(path, std::ios::trunc) << text;
    return ReadCsvColumns(path);
  };
  const auto good = read("time,load,front_x\n0,1.5,-inf\n0.1,2.5,3\n");
  ASSERT_TRUE(good.ok()) << good.status();
  EXPECT_EQ(good->at("load"), (std::vector<double>{1.5, 2.5}));
  EXPECT_EQ(good->at("front_x")[0], -std::numeric_limits<double>::infinity());  // no material

  const std::vector<std::pair<std::string, std::string>> damaged = {
      {"", " is empty"},
      {"time,load,front_x\n0,1.5\n", " row 2 has 2 values for 3 columns"},
      {"time,load,front_x\n0,1.5,2\n0.1,2x5,3\n", " row 3 column load: not a number"},
      {"time,load,front_x\n0,nan,2\n", " row 2 column load: NaN, which no run writes"},
      {"time,load,front_x\n0,1,-NaN\n", " row 2 column front_x: NaN, which no run writes"},
  };
  for (const auto& [text, message] : damaged) {
    const auto r = read(text);
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_EQ(r.status().code(), absl::StatusCode::kDataLoss) << r.status();
    EXPECT_TRUE(absl::EndsWith(r.status().message(), message)) << r.status();
  }
  // A directory in the file's place opens, then fails to read: not "empty".
  const std::string dir = ::testing::TempDir() + "/summary_test_directory.csv";
  std::filesystem::create_directories(dir);
  const auto directory = ReadCsvColumns(dir);
  EXPECT_EQ(directory.status().code(), absl::StatusCode::kUnavailable) << directory.status();
  EXPECT_EQ(directory.status().message(), "cannot read " + dir + ": Is a directory");
  std::filesystem::remove(dir);
}

}  // namespace
}  // namespace rvehub::mpm
