#include "mpm_client/run/summary.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>

#include "absl/strings/str_cat.h"
#include "client_run/summary.h"
#include "mpm_client/core/two_phase.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

using Columns = std::map<std::string, std::vector<double>>;

absl::StatusOr<const std::vector<double>*> Column(const Columns& columns, const std::string& name) {
  const auto it = columns.find(name);
  if (it == columns.end() || it->second.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("timeseries has no column ", name));
  }
  return &it->second;
}

// A column that must hold `rows` rows, one per row of the time column.
absl::StatusOr<const std::vector<double>*> Column(const Columns& columns, const std::string& name,
                                                  std::size_t rows) {
  ASSIGN_OR_RETURN(const std::vector<double>* column, Column(columns, name));
  if (column->size() != rows)
    return absl::InvalidArgumentError(
        absl::StrCat(name, " has ", column->size(), " rows, time ", rows));
  return column;
}

// The body a summary reads: output.plot_body, else the case's first body.
absl::StatusOr<std::string> SummaryBody(const CaseSpec& spec) {
  if (!spec.output.plot_body.empty()) return spec.output.plot_body;
  if (spec.bodies.empty()) return absl::InvalidArgumentError("the summary needs a body");
  return spec.bodies.front().name;
}

// The footing's full width B, m: plot_width, or twice that for a half model
// (the footing body's left edge on the grid's left edge, the symmetry plane).
double FootingWidth(const CaseSpec& spec, const std::string& body) {
  for (const RigidBody& b : spec.bodies) {
    if (b.name != body || b.shape != RigidBody::Shape::kRectangle) continue;
    const double left = b.center.x() - b.half_size.x();  // m
    if (std::abs(left - spec.grid.origin.x()) <= 1e-9 * spec.grid.cell_size) {
      return 2.0 * spec.output.plot_width;
    }
  }
  return spec.output.plot_width;
}

// The least-squares line q = slope·d + intercept through the rows whose d is
// in [lo, hi]; false with fewer than 3 rows or no spread in d.
bool FitLine(const std::vector<double>& d, const std::vector<double>& q, double lo, double hi,
             double* slope, double* intercept) {
  double n = 0, sd = 0, sq = 0, sdd = 0, sdq = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (d[i] < lo || d[i] > hi) continue;
    n += 1;
    sd += d[i];
    sq += q[i];
    sdd += d[i] * d[i];
    sdq += d[i] * q[i];
  }
  const double det = n * sdd - sd * sd;
  if (n < 3 || !(det > 0)) return false;
  *slope = (n * sdq - sd * sq) / det;
  *intercept = (sq - *slope * sd) / n;
  return true;
}

// The surcharge: the pressure on the ground surface (the first +y
// traction pushing down), Pa; 0 without one.
double Surcharge(const CaseSpec& spec) {
  for (const SurfaceTraction& t : spec.tractions) {
    if (t.normal_axis == 1 && t.normal_sign == 1 && -t.traction.y() > 0.0) return -t.traction.y();
  }
  return 0.0;
}

absl::StatusOr<Summary> Footing(const CaseSpec& spec, const Columns& columns) {
  ASSIGN_OR_RETURN(const std::string body, SummaryBody(spec));
  ASSIGN_OR_RETURN(const std::vector<double>* fy, Column(columns, body + "_fy"));
  ASSIGN_OR_RETURN(const std::vector<double>* dy, Column(columns, body + "_dy"));
  const double area = spec.output.plot_width * spec.solver.thickness;  // m²
  std::vector<double> q(fy->size()), d(dy->size());
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = (*fy)[i] / area;
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = -(*dy)[i];
  // The load jumps each time the footing crosses a node row: average over
  // one cell of settlement, or a fifth of a shorter curve.
  const auto [dmin, dmax] = std::minmax_element(d.begin(), d.end());
  const double span = std::min(spec.grid.cell_size, 0.2 * (*dmax - *dmin));  // m
  ASSIGN_OR_RETURN(const UltimateLoad ultimate, FindUltimateLoad(d, q, span));
  Summary out;
  const double surcharge = Surcharge(spec);  // Pa
  if (surcharge > 0.0) out.emplace_back("N_q", ultimate.load / surcharge);
  out.emplace_back("ultimate_load_Pa", ultimate.load);
  out.emplace_back("settlement_at_ultimate_m", ultimate.settlement);
  out.emplace_back("ultimate_is_peak", ultimate.peak ? 1.0 : 0.0);
  if (spec.output.phi_deg > 0.0) {
    out.emplace_back("phi_deg", spec.output.phi_deg);
    const double phi = spec.output.phi_deg * std::numbers::pi / 180.0;  // rad
    out.emplace_back("N_q_prandtl", PrandtlNq(phi));
    out.emplace_back("N_q_reduced", ReducedNq(phi));
  }
  if (surcharge > 0.0) out.emplace_back("surcharge_Pa", surcharge);
  // The knee of the curve, where the tangent to its start (the rows to
  // d = 0.02·B) meets the tangent to its second half (a least-squares line
  // each): the ultimate load of a curve without a peak as liang-zhao-mpm-dem
  // §3.3 reads the medium and soft footings. Left out when the two do not
  // meet on the curve (the start no stiffer than the end).
  const double width = FootingWidth(spec, body);  // m
  double a1 = 0, b1 = 0, a2 = 0, b2 = 0;
  if (FitLine(d, q, *dmin, *dmin + 0.02 * width, &a1, &b1) &&
      FitLine(d, q, 0.5 * (*dmin + *dmax), *dmax, &a2, &b2) && a1 > a2) {
    const double knee = (b2 - b1) / (a1 - a2);  // m
    if (knee >= *dmin && knee <= *dmax) {
      const double load = a1 * knee + b1;  // Pa
      out.emplace_back("knee_load_Pa", load);
      out.emplace_back("settlement_at_knee_m", knee);
      if (surcharge > 0.0) out.emplace_back("N_q_knee", load / surcharge);
    }
  }
  // The load at d/B = 0.1 (liang-zhao-mpm-dem §3.3 reads the medium and soft
  // footings there, which have no peak): its mean over one cell of
  // settlement around it, so that a grid crossing's jump does not decide it;
  // left out when the curve stops short of that window.
  const double tenth = 0.1 * width;               // m
  const double half = 0.5 * spec.grid.cell_size;  // m
  if (*dmax >= tenth + half) {
    double sum = 0.0;
    int rows = 0;
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (std::abs(d[i] - tenth) <= half) {
        sum += q[i];
        ++rows;
      }
    }
    if (rows > 0) {
      out.emplace_back("load_at_tenth_width_Pa", sum / rows);
      if (surcharge > 0.0) out.emplace_back("N_q_at_tenth_width", sum / rows / surcharge);
    }
  }
  return out;
}

// The median of values, or 0 for none.
double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

absl::StatusOr<Summary> Pipe(const CaseSpec& spec, const Columns& columns) {
  ASSIGN_OR_RETURN(const std::string body, SummaryBody(spec));
  ASSIGN_OR_RETURN(const std::vector<double>* fx, Column(columns, body + "_fx"));
  ASSIGN_OR_RETURN(const std::vector<double>* fy, Column(columns, body + "_fy"));
  ASSIGN_OR_RETURN(const std::vector<double>* dx, Column(columns, body + "_dx"));
  ASSIGN_OR_RETURN(const std::vector<double>* dy, Column(columns, body + "_dy"));
  const std::size_t n = fx->size();
  if (fy->size() != n || dx->size() != n || dy->size() != n) {
    return absl::InvalidArgumentError("the pipe's force and displacement columns differ in length");
  }
  double hx = 0.0, vy = 0.0;
  for (double f : *fx) hx = std::max(hx, std::abs(f));
  for (double f : *fy) vy = std::max(vy, std::abs(f));
  Summary out{{"peak_vertical_force_N", vy}, {"peak_horizontal_force_N", hx}};
  // The stages: penetration while the body has not moved sideways (1e-4 m),
  // lateral movement after.
  constexpr double kSideways = 1e-4;  // m
  std::vector<std::size_t> pen;
  double travel = 0.0;  // m, sideways at the end
  for (std::size_t i = 0; i < n; ++i) {
    if (std::abs((*dx)[i]) <= kSideways) pen.push_back(i);
    travel = std::max(travel, std::abs((*dx)[i]));
  }
  // The row-to-row force has spikes (stress waves, nodes entering contact):
  // the penetration peak is that of its mean over one cell of penetration.
  double peak = -std::numeric_limits<double>::infinity(), depth = 0.0;
  for (std::size_t i : pen) {
    double sum = 0.0;
    int count = 0;
    for (std::size_t j : pen) {
      if (std::abs((*dy)[j] - (*dy)[i]) <= 0.5 * spec.grid.cell_size) {
        sum += (*fy)[j];
        ++count;
      }
    }
    if (sum / count > peak) {
      peak = sum / count;
      depth = -(*dy)[i];
    }
  }
  if (!pen.empty()) {
    out.emplace_back("penetration_peak_force_N", peak);
    out.emplace_back("penetration_peak_depth_m", depth);
  }
  // The lateral stage's steady forces: medians over the second half of the
  // sideways travel (the paper's Fig. 21: after a quick rise).
  std::vector<double> vertical, horizontal;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::abs((*dx)[i]) > kSideways && std::abs((*dx)[i]) >= 0.5 * travel) {
      vertical.push_back((*fy)[i]);
      horizontal.push_back(std::abs((*fx)[i]));
    }
  }
  if (!vertical.empty()) {
    out.emplace_back("lateral_vertical_force_N", Median(vertical));
    out.emplace_back("lateral_horizontal_force_N", Median(horizontal));
    out.emplace_back("lateral_travel_m", travel);
  }
  return out;
}

absl::StatusOr<Summary> Collapse(const CaseSpec& spec, const Columns& columns) {
  if (spec.regions.empty())
    return absl::InvalidArgumentError("the collapse summary needs a region");
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* farthest, Column(columns, "front_x"));
  // The main deposit's front where the run wrote it (runs before it: the
  // farthest point).
  const std::vector<double>* front = farthest;
  if (columns.contains("deposit_front_x")) {
    ASSIGN_OR_RETURN(front, Column(columns, "deposit_front_x"));
  }
  const MaterialRegion& column = spec.regions.front();
  const double d0 = column.upper.x() - column.lower.x();  // m
  // The front columns hold point centres: add the initial half spacing.
  const double half = 0.5 * InitialPointSpacing(spec);
  // A front column's last row as a distance from the column's wall, m, and
  // from when it stayed within 1 % of d0 of it, s.
  const auto final_distance = [&](const std::vector<double>& x) {
    return x.back() + half - column.lower.x();
  };
  const auto stop_time = [&](const std::vector<double>& x) {
    return FrontStopTime(*time, x, 0.01 * d0);
  };
  const double df = final_distance(*front);
  const double stop = stop_time(*front);
  // A front still moving at the end "stops" at the last row: the run-out is
  // then a lower bound. At rest means unmoved over the last 10 % of the run.
  const double at_rest = time->empty() || stop <= 0.9 * time->back() ? 1.0 : 0.0;
  Summary out{{"runout_normalised", (df - d0) / d0},
              {"final_front_m", df + column.lower.x()},
              {"farthest_point_m", farthest->back() + half},
              {"front_stop_time_s", stop},
              {"front_at_rest", at_rest}};
  // The same read by mass, and when that front came to rest.
  for (const int percent : kMassFrontPercents) {
    const std::string name = MassFrontColumn(percent);
    if (!columns.contains(name)) continue;
    ASSIGN_OR_RETURN(const std::vector<double>* x, Column(columns, name));
    out.emplace_back(absl::StrCat("runout_normalised_mass", percent),
                     (final_distance(*x) - d0) / d0);
    out.emplace_back(absl::StrCat("front_stop_time_mass", percent, "_s"), stop_time(*x));
  }
  // The solid's kinetic-energy peak and when it came (liang-zhao-wu-soga-2023
  // Fig. 13 compares a saturated column's with the dry one's).
  if (columns.contains("kinetic_energy")) {
    ASSIGN_OR_RETURN(const std::vector<double>* ke,
                     Column(columns, "kinetic_energy", time->size()));
    if (!ke->empty()) {
      const auto peak = std::max_element(ke->begin(), ke->end());
      out.emplace_back("kinetic_energy_peak_J", *peak);
      out.emplace_back("kinetic_energy_peak_time_s", (*time)[peak - ke->begin()]);
    }
  }
  return out;
}

// The mean of y over the rows whose time lies in (t − window, t] for each
// row's t: a trailing running mean by time, whatever the rows' spacing.
std::vector<double> TrailingMean(const std::vector<double>& time, const std::vector<double>& y,
                                 double window) {
  std::vector<double> out(y.size());
  double sum = 0.0;
  std::size_t first = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    sum += y[i];
    while (time[first] <= time[i] - window) sum -= y[first++];
    out[i] = sum / static_cast<double>(i - first + 1);
  }
  return out;
}

absl::StatusOr<Summary> Shaking(const CaseSpec& spec, const Columns& columns) {
  if (!(spec.solver.shaking_frequency > 0.0))
    return absl::InvalidArgumentError("the shaking summary needs solver.shaking_frequency");
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* settlement, Column(columns, "surface_settlement"));
  // The ratio swings with every half cycle of the shake; its level is the
  // mean over two whole cycles (liang-zhao-wu-soga-2023 Fig. 8 reads
  // "fluctuations around" a level).
  const double window = 2.0 / spec.solver.shaking_frequency;  // s
  Summary out{{"surface_settlement_m", settlement->back()}};
  // Levels count from the first row with two whole cycles behind it (the
  // last row for a shorter run): a part-cycle mean is still a swing.
  std::size_t first = 0;
  while (first + 1 < time->size() && (*time)[first] - time->front() < window) ++first;
  for (const PressureMonitor& m : spec.phases.monitors) {
    ASSIGN_OR_RETURN(const std::vector<double>* ratio,
                     Column(columns, m.name + "_excess_ratio", time->size()));
    const std::vector<double> level = TrailingMean(*time, *ratio, window);
    const auto peak = std::max_element(level.begin() + first, level.end());
    out.emplace_back(m.name + "_excess_ratio_peak", *peak);
    out.emplace_back(m.name + "_excess_ratio_peak_time_s", (*time)[peak - level.begin()]);
    out.emplace_back(m.name + "_excess_ratio_final", level.back());
  }
  return out;
}

// The wave's travel time between two monitors: the lag s (rows) that
// maximises Σ_i a_i·b_(i+s) over the rows within the window, s < n/2, refined
// by a parabola through the peak; its speed the monitors' distance over it.
absl::StatusOr<Summary> Wave(const CaseSpec& spec, const Columns& columns) {
  const OutputSpec& out = spec.output;
  const auto position = [&](const std::string& name) -> absl::StatusOr<Eigen::Vector2d> {
    for (const PressureMonitor& m : spec.phases.monitors) {
      if (m.name == name) return m.position;
    }
    return absl::InvalidArgumentError(
        absl::StrCat("the wave summary's monitor ", name, " is not among phases.monitors"));
  };
  ASSIGN_OR_RETURN(const Eigen::Vector2d from, position(out.wave_from));
  ASSIGN_OR_RETURN(const Eigen::Vector2d to, position(out.wave_to));
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* a,
                   Column(columns, out.wave_from + "_uy", time->size()));
  ASSIGN_OR_RETURN(const std::vector<double>* b,
                   Column(columns, out.wave_to + "_uy", time->size()));
  std::size_t n = 0;
  while (n < time->size() && (*time)[n] - time->front() <= out.wave_window) ++n;
  constexpr std::size_t kMinRows = 8;
  if (n < kMinRows)
    return absl::InvalidArgumentError(absl::StrCat("the wave summary needs at least ", kMinRows,
                                                   " rows within wave_window, has ", n));
  // A lag in rows is a time only on evenly spaced rows (one Δt, every N steps).
  const double dt = ((*time)[n - 1] - time->front()) / static_cast<double>(n - 1);  // s
  for (std::size_t i = 1; i < n; ++i) {
    if (std::abs((*time)[i] - (*time)[i - 1] - dt) > 1e-6 * dt)
      return absl::InvalidArgumentError(
          absl::StrCat("the wave summary needs evenly spaced rows; row ", i, " is not"));
  }
  std::vector<double> corr(n / 2);
  for (std::size_t s = 0; s < corr.size(); ++s) {
    double sum = 0.0;
    for (std::size_t i = 0; i + s < n; ++i) sum += (*a)[i] * (*b)[i + s];
    corr[s] = sum;
  }
  const std::size_t peak = std::max_element(corr.begin(), corr.end()) - corr.begin();
  double lag = static_cast<double>(peak);  // rows
  if (peak > 0 && peak + 1 < corr.size()) {
    const double c0 = corr[peak - 1], c1 = corr[peak], c2 = corr[peak + 1];
    const double curvature = c0 - 2.0 * c1 + c2;
    if (curvature < 0.0) lag += 0.5 * (c0 - c2) / curvature;
  }
  if (!(lag > 0.0))
    return absl::InvalidArgumentError(absl::StrCat("the u_y traces of ", out.wave_from, " and ",
                                                   out.wave_to, " do not lag within wave_window"));
  const double lag_s = lag * dt;
  return Summary{{"surface_wave_lag_s", lag_s},
                 {"surface_wave_speed_m_per_s", (to - from).norm() / lag_s}};
}

absl::StatusOr<Summary> Consolidation(const CaseSpec& spec, const Columns& columns) {
  if (spec.regions.empty())
    return absl::InvalidArgumentError("the consolidation summary needs a region");
  if (spec.solver.gravity.norm() != 0.0)
    return absl::InvalidArgumentError(
        "the consolidation summary reads Terzaghi's weightless layer: solver.gravity must be zero");
  if (!(spec.output.constrained_modulus > 0.0))
    return absl::InvalidArgumentError(
        "the consolidation summary needs output.constrained_modulus (M of c_v = k·M/(ρ_f·g))");
  const double surcharge = Surcharge(spec);  // Pa
  if (!(surcharge > 0.0))
    return absl::InvalidArgumentError("the consolidation summary needs a +y surcharge traction");
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* syy, Column(columns, "mean_syy"));
  ASSIGN_OR_RETURN(const std::vector<double>* settlement,
                   Column(columns, "surface_settlement", time->size()));
  // The load the water carries at first: the surcharge less what the RVEs
  // already hold (compression +).
  const double p0 = surcharge - syy->front();  // Pa
  if (!(p0 > 0.0))
    return absl::InvalidArgumentError(absl::StrCat(
        "the consolidation summary needs a surcharge above the RVEs' first mean σyy (p0 = ", p0,
        " Pa)"));
  const MaterialRegion& layer = spec.regions.front();
  const double height = layer.upper.y() - layer.lower.y();  // m, drained at its top
  const double modulus = spec.output.constrained_modulus;   // Pa
  const double cv =
      spec.phases.permeability * modulus / (spec.phases.fluid_density * kDarcyGravity);  // m²/s
  Summary out{
      {"p0_Pa", p0}, {"c_v_m2_per_s", cv}, {"final_tv", cv * time->back() / (height * height)}};
  // The worst distance from Terzaghi once the wave of the load's first
  // instants has passed (liang-zhao-wu-soga-2023 §4.1 compares from
  // Tv = 0.04 on; before that the mixture's inertia still shows).
  double pressure_error = 0.0, consolidation_error = 0.0;
  for (const PressureMonitor& m : spec.phases.monitors) {
    ASSIGN_OR_RETURN(const std::vector<double>* p, Column(columns, m.name + "_p", time->size()));
    const double z = (layer.upper.y() - m.position.y()) / height;  // [-], from the drained top
    for (std::size_t i = 0; i < time->size(); ++i) {
      const double tv = cv * (*time)[i] / (height * height);
      if (tv < kTerzaghiFromTv) continue;
      pressure_error =
          std::max(pressure_error, std::abs((*p)[i] - TerzaghiExcessPressure(p0, z, tv)) / p0);
    }
  }
  for (std::size_t i = 0; i < time->size(); ++i) {
    const double tv = cv * (*time)[i] / (height * height);
    if (tv < kTerzaghiFromTv) continue;
    const double degree = (*settlement)[i] / (p0 * height / modulus);
    consolidation_error =
        std::max(consolidation_error, std::abs(degree - TerzaghiDegreeOfConsolidation(tv)));
  }
  out.emplace_back("pore_pressure_error_max", pressure_error);
  out.emplace_back("degree_of_consolidation_error_max", consolidation_error);
  return out;
}

absl::StatusOr<Summary> ConstantRateOfStrain(const CaseSpec& spec, const Columns& columns) {
  if (spec.regions.empty()) return absl::InvalidArgumentError("the crs summary needs a region");
  if (!spec.phases.saturated)
    return absl::InvalidArgumentError("the crs summary needs a saturated case (phases)");
  if (spec.solver.gravity.norm() != 0.0)
    return absl::InvalidArgumentError(
        "the crs summary reads a weightless layer: solver.gravity must be zero");
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* syy, Column(columns, "mean_syy", time->size()));
  // The platen's stress and its travel over the layer's height, as the
  // biaxial summary reads them.
  ASSIGN_OR_RETURN(const NominalCurve curve, PlatenCurve(spec, columns));
  const std::size_t n = time->size();
  if (curve.strain.size() != n || curve.stress.size() != n)
    return absl::InvalidArgumentError("the crs summary needs the platen's columns on every row");
  if (n < 2 || !((*time)[n - 1] > (*time)[n - 2]))
    return absl::InvalidArgumentError("the crs summary needs two rows at different times");
  const MaterialRegion& layer = spec.regions.front();
  const double initial_height = layer.upper.y() - layer.lower.y();     // m
  const double height = initial_height * (1.0 - curve.strain.back());  // m, now
  const double speed = initial_height * (curve.strain[n - 1] - curve.strain[n - 2]) /
                       ((*time)[n - 1] - (*time)[n - 2]);  // m/s
  if (!(height > 0.0) || !(speed > 0.0))
    return absl::InvalidArgumentError(
        absl::StrCat("the crs summary needs the platen moving down over a layer (speed ", speed,
                     " m/s, height ", height, " m at the end)"));
  const double rate = speed / height;  // 1/s
  const auto steady = [&](double z) {  // Pa, z in m above the drained base
    return SteadyConstantRateOfStrainPressure(rate, height, z, spec.phases.permeability,
                                              spec.phases.fluid_density);
  };
  const double p_top = steady(height);
  // At the last row, as far as the monitors show it (their case positions).
  double pressure_error = 0.0;
  for (const PressureMonitor& m : spec.phases.monitors) {
    ASSIGN_OR_RETURN(const std::vector<double>* p, Column(columns, m.name + "_p", n));
    const double z = m.position.y() - layer.lower.y();
    pressure_error = std::max(pressure_error, std::abs(p->back() - steady(z)) / p_top);
  }
  // The platen carries the total stress: the skeleton's σ'yy plus the
  // water's mean, ⅔ p(H) at the steady state (compression +).
  return Summary{{"strain_rate_per_s", rate},
                 {"steady_top_pore_pressure_Pa", p_top},
                 {"pore_pressure_error_max", pressure_error},
                 {"platen_stress_Pa", curve.stress.back()},
                 {"steady_total_stress_Pa", syy->back() + 2.0 / 3.0 * p_top}};
}

absl::StatusOr<Summary> Biaxial(const CaseSpec& spec, const Columns& columns) {
  std::vector<double> stress, strain;  // Pa and [-], compression +
  if (!spec.bodies.empty() && !spec.regions.empty()) {
    ASSIGN_OR_RETURN(NominalCurve curve, PlatenCurve(spec, columns));
    stress = std::move(curve.stress);
    strain = std::move(curve.strain);
  } else {
    ASSIGN_OR_RETURN(const std::vector<double>* syy, Column(columns, "mean_syy"));
    ASSIGN_OR_RETURN(const std::vector<double>* eyy, Column(columns, "mean_eyy"));
    stress = *syy;
    strain = *eyy;
  }
  // The peak as every client reads a nominal curve (client_run/summary.h).
  return client_run::PeakSummary(strain, stress);
}

}  // namespace

absl::StatusOr<NominalCurve> PlatenCurve(const CaseSpec& spec, const Columns& columns) {
  if (spec.regions.empty()) return absl::InvalidArgumentError("the platen curve needs a region");
  ASSIGN_OR_RETURN(const std::string body, SummaryBody(spec));
  ASSIGN_OR_RETURN(const std::vector<double>* fy, Column(columns, body + "_fy"));
  ASSIGN_OR_RETURN(const std::vector<double>* dy, Column(columns, body + "_dy"));
  const MaterialRegion& r = spec.regions.front();
  const double width = r.upper.x() - r.lower.x(), height = r.upper.y() - r.lower.y();
  NominalCurve curve;
  for (double f : *fy) curve.stress.push_back(f / (width * spec.solver.thickness));
  for (double d : *dy) curve.strain.push_back(-d / height);
  return curve;
}

double PrandtlNq(double phi) {
  const double t = std::tan(std::numbers::pi / 4 + phi / 2);
  return t * t * std::exp(std::numbers::pi * std::tan(phi));
}

double ReducedNq(double phi) { return PrandtlNq(std::atan(2.0 / 3.0 * std::tan(phi))); }

absl::StatusOr<UltimateLoad> FindUltimateLoad(std::span<const double> settlement,
                                              std::span<const double> load, double span) {
  const std::size_t n = load.size();
  if (n < 3 || settlement.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat("a load-settlement curve needs >= 3 rows of ",
                                                   "both columns (", settlement.size(), ", ", n,
                                                   ")"));
  }
  if (!(span >= 0.0)) return absl::InvalidArgumentError("the smoothing span must be >= 0");
  // A running median of 3 rows removes single-row flicker (a node row
  // emptying as the surface passes it), then a centred mean of 5 rows.
  std::vector<double> median(load.begin(), load.end());
  for (std::size_t i = 1; i + 1 < n; ++i) {
    median[i] = std::max(std::min(load[i - 1], load[i]),
                         std::min(std::max(load[i - 1], load[i]), load[i + 1]));
  }
  constexpr std::size_t kHalf = 2;
  std::vector<double> light(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= kHalf ? i - kHalf : 0, hi = std::min(n - 1, i + kHalf);
    double sum = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) sum += median[k];
    light[i] = sum / static_cast<double>(hi - lo + 1);
  }
  // The contiguous rows within span/2 of row i's settlement, as many on
  // each side (a window one row longer on one side would shift the mean).
  const auto within = [&](std::size_t i) {
    std::size_t lo = i, hi = i;
    while (lo > 0 && std::abs(settlement[lo - 1] - settlement[i]) <= 0.5 * span) --lo;
    while (hi + 1 < n && std::abs(settlement[hi + 1] - settlement[i]) <= 0.5 * span) ++hi;
    const std::size_t side = std::min(i - lo, hi - i);
    return std::pair{i - side, i + side};
  };
  // Then a centred mean over the span (the load's period as the footing
  // crosses grid rows), to locate the ultimate load.
  std::vector<double> smooth(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto [lo, hi] = within(i);
    double sum = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) sum += light[k];
    smooth[i] = sum / static_cast<double>(hi - lo + 1);
  }
  // Slopes between rows whose settlement grows, away from the ends where the
  // means are one-sided.
  const double first = settlement.front(), last = settlement.back();
  std::vector<std::pair<std::size_t, double>> slopes;
  for (std::size_t i = kHalf; i + 1 + kHalf < n; ++i) {
    const double dd = settlement[i + 1] - settlement[i];
    if (!(dd > 0.0) || !(settlement[i] > 0.0)) continue;
    if (settlement[i] - first < 0.5 * span || last - settlement[i + 1] < 0.5 * span) continue;
    slopes.emplace_back(i, (smooth[i + 1] - smooth[i]) / dd);
  }
  if (slopes.empty()) {
    if (span > 0.0 && last - first < span) {
      return absl::InvalidArgumentError(absl::StrCat("the curve's settlement (", last - first,
                                                     " m) is shorter than the smoothing span (",
                                                     span, " m)"));
    }
    return absl::InvalidArgumentError("the settlement never grows");
  }
  // The median of the slopes after each one (the steady slope the curve
  // keeps), by two heaps from the end.
  std::vector<double> rest(slopes.size(), 0.0);
  std::priority_queue<double> below;                                       // max-heap
  std::priority_queue<double, std::vector<double>, std::greater<>> above;  // min-heap
  for (std::size_t k = slopes.size(); k-- > 0;) {
    if (!below.empty()) {
      rest[k] = below.size() > above.size() ? below.top() : 0.5 * (below.top() + above.top());
    }
    const double s = slopes[k].second;
    if (below.empty() || s <= below.top()) {
      below.push(s);
    } else {
      above.push(s);
    }
    if (below.size() > above.size() + 1) {
      above.push(below.top());
      below.pop();
    } else if (above.size() > below.size()) {
      below.push(above.top());
      above.pop();
    }
  }
  // The first slope at or below zero (a peak) or below the steady slope
  // after it; the load there is the lightly smoothed curve's largest within
  // the span, so that the wide mean does not shave a peak.
  for (std::size_t k = 0; k < slopes.size(); ++k) {
    const double s = slopes[k].second;
    if (s > std::max(0.0, rest[k])) continue;
    const auto [lo, hi] = within(slopes[k].first);
    std::size_t best = lo;
    for (std::size_t j = lo; j <= hi; ++j) {
      if (light[j] > light[best]) best = j;
    }
    return UltimateLoad{best, light[best], settlement[best], s <= 0.0};
  }
  // Only the last slope can be above every later one's median (0 here).
  const std::size_t i = slopes.back().first;
  return UltimateLoad{i, light[i], settlement[i], false};
}

double InitialPointSpacing(const CaseSpec& spec) {
  if (spec.regions.empty()) return 0.0;
  return spec.grid.cell_size / spec.regions.front().points_per_cell_side;
}

double MainDepositFront(std::span<const Eigen::Vector2d> position,
                        std::span<const std::uint8_t> skip, double link) {
  // Points binned on cells of side `link`, sorted by cell (then index): a
  // point's neighbours within `link` lie in the 3 × 3 cells around its own.
  using Key = std::pair<std::int64_t, std::int64_t>;
  std::vector<std::pair<Key, std::size_t>> binned;
  if (!(link > 0.0) || !std::isfinite(link)) return -std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < position.size(); ++p) {
    if ((!skip.empty() && skip[p]) || !position[p].allFinite()) continue;
    binned.push_back({{static_cast<std::int64_t>(std::floor(position[p].x() / link)),
                       static_cast<std::int64_t>(std::floor(position[p].y() / link))},
                      p});
  }
  if (binned.empty()) return -std::numeric_limits<double>::infinity();
  std::sort(binned.begin(), binned.end());
  std::vector<std::size_t> parent(position.size());
  for (std::size_t p = 0; p < parent.size(); ++p) parent[p] = p;
  const auto root = [&](std::size_t p) {
    while (parent[p] != p) p = parent[p] = parent[parent[p]];
    return p;
  };
  for (const auto& [key, p] : binned) {
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const Key cell{key.first + dx, key.second + dy};
        auto it =
            std::lower_bound(binned.begin(), binned.end(), std::make_pair(cell, std::size_t{0}));
        for (; it != binned.end() && it->first == cell; ++it) {
          const std::size_t q = it->second;
          if (q <= p || (position[q] - position[p]).squaredNorm() > link * link) continue;
          const std::size_t a = root(p), b = root(q);
          if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the lower index roots
        }
      }
    }
  }
  std::vector<std::size_t> size(position.size(), 0);
  for (const auto& entry : binned) ++size[root(entry.second)];
  std::size_t main = root(binned.front().second);
  for (std::size_t r = 0; r < size.size(); ++r) {
    if (size[r] > size[main] || (size[r] == size[main] && r < main)) main = r;
  }
  double front = -std::numeric_limits<double>::infinity();
  for (const auto& entry : binned) {
    if (root(entry.second) == main) front = std::max(front, position[entry.second].x());
  }
  return front;
}

double MassFront(std::span<const Eigen::Vector2d> position, std::span<const double> mass,
                 std::span<const std::uint8_t> skip, double share) {
  constexpr double kNone = -std::numeric_limits<double>::infinity();
  if (!(share > 0.0 && share <= 1.0) || mass.size() != position.size()) return kNone;
  std::vector<std::pair<double, std::size_t>> order;  // (x, index): ties by index
  for (std::size_t p = 0; p < position.size(); ++p) {
    if ((!skip.empty() && skip[p]) || !position[p].allFinite() || !std::isfinite(mass[p]) ||
        !(mass[p] > 0.0)) {
      continue;
    }
    order.push_back({position[p].x(), p});
  }
  if (order.empty()) return kNone;
  std::sort(order.begin(), order.end());
  // Both sums in x order, so that the points' order does not round them
  // differently; the last point closes it whatever the rounding.
  double total = 0.0;  // kg
  for (const auto& entry : order) total += mass[entry.second];
  double behind = 0.0;
  for (std::size_t k = 0; k + 1 < order.size(); ++k) {
    behind += mass[order[k].second];
    if (behind >= share * total) return order[k].first;
  }
  return order.back().first;
}

std::string MassFrontColumn(int percent) { return absl::StrCat("mass_front_", percent, "_x"); }

double FrontStopTime(std::span<const double> time, std::span<const double> front,
                     double tolerance) {
  if (time.empty() || front.size() != time.size()) return 0.0;
  std::size_t k = front.size() - 1;
  while (k > 0 && std::abs(front[k - 1] - front.back()) <= tolerance) --k;
  return time[k];
}

std::string SummaryKind(const OutputSpec& out) {
  if (!out.summary.empty()) return out.summary;
  if (out.plot == "load-settlement") return "footing";
  if (out.plot == "stress-strain") return "biaxial";
  return "none";
}

absl::StatusOr<Summary> Summarise(const CaseSpec& spec, const Columns& columns) {
  const std::string kind = SummaryKind(spec.output);
  if (kind == "footing") return Footing(spec, columns);
  if (kind == "pipe") return Pipe(spec, columns);
  if (kind == "collapse") return Collapse(spec, columns);
  if (kind == "biaxial") return Biaxial(spec, columns);
  if (kind == "shaking") return Shaking(spec, columns);
  if (kind == "consolidation") return Consolidation(spec, columns);
  if (kind == "crs") return ConstantRateOfStrain(spec, columns);
  if (kind == "wave") return Wave(spec, columns);
  if (kind == "none") return Summary{};
  return absl::InvalidArgumentError(absl::StrCat("unknown summary kind '", kind, "'"));
}

}  // namespace rvehub::mpm
