// The headline figures of a run (DIR/summary.json), from its timeseries.csv:
// what a reader of the paper compares first. Pure functions over columns.
#ifndef RVEHUB_MPM_CLIENT_RUN_SUMMARY_H_
#define RVEHUB_MPM_CLIENT_RUN_SUMMARY_H_

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "client_run/summary.h"
#include "mpm_client/core/model.h"

namespace rvehub::mpm {

// Prandtl's bearing capacity factor of a weightless cohesionless soil,
// N_q = tan²(π/4 + φ/2)·exp(π tan φ), φ in radians.
double PrandtlNq(double phi);
// Terzaghi's factor for local shear and punching: Prandtl's with the reduced
// φ'_r = atan(⅔ tan φ') (liang-zhao-mpm-dem eq. 47), φ in radians.
double ReducedNq(double phi);

// The ultimate load of a load–settlement curve as liang-zhao-mpm-dem §3.3
// takes it (after Vesić): where the slope first reaches zero (a peak) or
// its steady minimum, here the median of the slopes after it. The slopes are
// taken on the curve smoothed by a running median of 3 rows, a centred mean
// of 5 rows and a centred mean over `span` (m of settlement; 0: none), so
// that neither a single row's flicker nor the periodic jump of a grid
// crossing passes for a peak. The load reported is the largest of the
// 5-row curve within span/2 of that point, and its settlement.
// InvalidArgument for fewer than 3 rows, columns of different lengths, a
// negative span, or a curve that never settles more than a span.
struct UltimateLoad {
  std::size_t row = 0;      // in the given columns
  double load = 0.0;        // the lightly smoothed load there
  double settlement = 0.0;  // m
  bool peak = false;        // a peak (slope zero); else the steady slope
};
absl::StatusOr<UltimateLoad> FindUltimateLoad(std::span<const double> settlement,
                                              std::span<const double> load, double span = 0.0);

// The first time from which the front stays within `tolerance` (m) of its
// last value; the last time if it never settles.
double FrontStopTime(std::span<const double> time, std::span<const double> front, double tolerance);

// The front of a flow's main deposit, m: the largest x among the largest
// set of points linked by distances of at most `link` (m), so that points
// thrown clear of the deposit do not count (liang-zhao-mpm-dem eq. 48 takes
// d_f "after removing the scatter points which is not in contact with the
// main deposit"). Points with skip[p] (parked off the grid; skip may be
// empty) and non-finite positions take no part. Of equally large sets, the
// one holding the lowest index. −∞ without points or without a finite
// link > 0. O(n log n), deterministic.
double MainDepositFront(std::span<const Eigen::Vector2d> position,
                        std::span<const std::uint8_t> skip, double link);

// The front of a flow read by mass, m: the smallest x such that the points
// at or behind it hold at least `share` (0 < share ≤ 1) of the points'
// total mass. No single point or link decides it, where the main deposit's
// front turns on whether a thin sheet's points stay linked (the §4.3 dry
// column's moved by 0.16 m when two surface points shifted a few cm).
// Points with skip[p], a non-finite position or a mass that is not finite
// and positive take no part. −∞ without such points or with `share` outside
// (0, 1]. O(n log n), deterministic.
double MassFront(std::span<const Eigen::Vector2d> position, std::span<const double> mass,
                 std::span<const std::uint8_t> skip, double share);
// The shares, in %, whose MassFront collapse runs write, each as the column
// MassFrontColumn(percent) ("mass_front_98_x"); the summary reads them back.
inline constexpr int kMassFrontPercents[] = {98, 99};
std::string MassFrontColumn(int percent);

// The first region's initial point spacing, m: h / points_per_cell_side (0
// without a region). Collapse runs link points within kDepositLinkSpacings
// of it into one deposit (MainDepositFront).
double InitialPointSpacing(const CaseSpec& spec);
inline constexpr double kDepositLinkSpacings = 2.0;

// Tv from which a consolidation run is compared with Terzaghi's solution:
// before it the mixture's inertia, which Terzaghi leaves out, still shows.
inline constexpr double kTerzaghiFromTv = 0.04;

// The summary kind of a case: OutputSpec::summary, or from its plot.
std::string SummaryKind(const OutputSpec& out);

// The paper's nominal biaxial curve of a case with a platen (plot_body, else
// the first body): the platen's force over the first region's width (Pa,
// compression +) against its travel over the region's height ([-]).
// InvalidArgument without a body or region, or without the body's columns.
struct NominalCurve {
  std::vector<double> strain;  // [-]
  std::vector<double> stress;  // Pa
};
absl::StatusOr<NominalCurve> PlatenCurve(const CaseSpec& spec,
                                         const std::map<std::string, std::vector<double>>& columns);

// Named figures in the order summary.json lists them (SI units in the names),
// and summary.json itself: shared with the other clients.
using client_run::Summary;
using client_run::WriteSummary;

// The figures of a case's kind from its timeseries columns (by header):
// footing: N_q, ultimate_load_Pa, settlement_at_ultimate_m, phi_deg and
// N_q_prandtl and N_q_reduced (when the case gives φ'), surcharge_Pa,
// knee_load_Pa, settlement_at_knee_m and N_q_knee (where the tangents to the
// curve's start, to d = 0.02·B, and to its second half meet), and
// load_at_tenth_width_Pa and N_q_at_tenth_width (the mean load over one cell
// of settlement around d/B = 0.1, B the footing's full width: plot_width,
// doubled for a half model; when the curve reaches that far); pipe:
// peak_vertical_force_N, peak_horizontal_force_N (largest magnitudes of what
// the soil exerts on the body, N for the domain thickness, one row),
// penetration_peak_force_N and _depth_m (the largest mean vertical force over
// one cell of penetration while the body has not moved sideways), and with a
// lateral stage lateral_vertical_force_N, lateral_horizontal_force_N (medians,
// the horizontal one's magnitude, over the second half of the sideways
// travel) and lateral_travel_m; collapse:
// runout_normalised (d_f − d_0)/d_0 with d_0 the region's width and d_f the
// main deposit's front at the end (column deposit_front_x; front_x, the
// farthest point, for a timeseries without it) plus the points' initial
// half spacing, final_front_m (d_f from x = 0), farthest_point_m (front_x's
// likewise), front_stop_time_s, front_at_rest (1 when the front was still
// over the last 10 % of the run, else 0: the run-out is a lower bound), and
// where the timeseries has them runout_normalised_mass98 and _mass99 (the
// same with d_f from mass_front_98_x and mass_front_99_x: MassFront) and
// front_stop_time_mass98_s and _mass99_s (FrontStopTime of those columns);
// biaxial: peak_stress_Pa and peak_strain (nominal: the platen's force over
// the region's width, its travel over the region's height; compression +;
// the mean σyy and εyy of the points without a platen), final_stress_Pa,
// final_strain; shaking (a saturated box shaken by solver.shaking_*):
// surface_settlement_m (the last row's) and for each monitor M
// M_excess_ratio_peak and _peak_time_s (the largest level of Δp/σ'yy,0, the
// level a trailing mean over two cycles of the shake, from the first row
// with two cycles behind it) and
// M_excess_ratio_final (the level at the end); consolidation (a weightless
// layer drained at its top under a +y surcharge, Terzaghi's problem):
// p0_Pa (the surcharge less the first row's mean σyy), c_v_m2_per_s
// (k·M/(ρ_f·g), M output.constrained_modulus), final_tv, and from
// Tv = kTerzaghiFromTv on pore_pressure_error_max (the largest distance of a
// monitor's pore pressure from TerzaghiExcessPressure at the monitor's
// depth, over p0) and degree_of_consolidation_error_max (of the surface
// settlement over p0·H/M from TerzaghiDegreeOfConsolidation); crs (a
// weightless layer, the first region, drained at its base under a platen,
// plot_body or the first body, pushed down at a constant rate): at the last
// row strain_rate_per_s (the platen's speed over the layer's height then),
// steady_top_pore_pressure_Pa (SteadyConstantRateOfStrainPressure under the
// platen), pore_pressure_error_max (the largest distance of a monitor's
// pore pressure from the steady one at its case height, over the top's),
// platen_stress_Pa (the platen's force over the region's width, compression
// +) and steady_total_stress_Pa (the last mean σyy plus the steady mean
// pore pressure, ⅔ of the top's: what the platen carries); wave (a
// surface wave passing two monitors, output.wave_from and wave_to):
// surface_wave_lag_s (the lag maximising the cross-correlation of their u_y
// traces within output.wave_window, refined by a parabola through the peak)
// and surface_wave_speed_m_per_s (the monitors' distance in the case over
// it). Empty for "none".
absl::StatusOr<Summary> Summarise(const CaseSpec& spec,
                                  const std::map<std::string, std::vector<double>>& columns);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_RUN_SUMMARY_H_
