#include "mpm_client/summary.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "nlohmann/json.hpp"
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

// The body a summary reads: output.plot_body, else the case's first body.
absl::StatusOr<std::string> SummaryBody(const CaseSpec& spec) {
  if (!spec.output.plot_body.empty()) return spec.output.plot_body;
  if (spec.bodies.empty()) return absl::InvalidArgumentError("the summary needs a body");
  return spec.bodies.front().name;
}

absl::StatusOr<Summary> Footing(const CaseSpec& spec, const Columns& columns) {
  ASSIGN_OR_RETURN(const std::string body, SummaryBody(spec));
  ASSIGN_OR_RETURN(const std::vector<double>* fy, Column(columns, body + "_fy"));
  ASSIGN_OR_RETURN(const std::vector<double>* dy, Column(columns, body + "_dy"));
  const double area = spec.output.plot_width * spec.solver.thickness;  // m²
  std::vector<double> q(fy->size()), d(dy->size());
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = (*fy)[i] / area;
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = -(*dy)[i];
  ASSIGN_OR_RETURN(const UltimateLoad ultimate, FindUltimateLoad(d, q));
  Summary out;
  // The surcharge: the pressure on the ground surface (a +y traction).
  double surcharge = 0.0;
  for (const SurfaceTraction& t : spec.tractions) {
    if (t.normal_axis == 1 && t.normal_sign == 1 && -t.traction.y() > 0.0) {
      surcharge = -t.traction.y();
      break;
    }
  }
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
  return out;
}

absl::StatusOr<Summary> Pipe(const CaseSpec& spec, const Columns& columns) {
  ASSIGN_OR_RETURN(const std::string body, SummaryBody(spec));
  ASSIGN_OR_RETURN(const std::vector<double>* fx, Column(columns, body + "_fx"));
  ASSIGN_OR_RETURN(const std::vector<double>* fy, Column(columns, body + "_fy"));
  double hx = 0.0, vy = 0.0;
  for (double f : *fx) hx = std::max(hx, std::abs(f));
  for (double f : *fy) vy = std::max(vy, std::abs(f));
  return Summary{{"peak_vertical_force_N", vy}, {"peak_horizontal_force_N", hx}};
}

absl::StatusOr<Summary> Collapse(const CaseSpec& spec, const Columns& columns) {
  if (spec.regions.empty())
    return absl::InvalidArgumentError("the collapse summary needs a region");
  ASSIGN_OR_RETURN(const std::vector<double>* time, Column(columns, "time"));
  ASSIGN_OR_RETURN(const std::vector<double>* front, Column(columns, "front_x"));
  const MaterialRegion& column = spec.regions.front();
  const double d0 = column.upper.x() - column.lower.x();  // m
  // The front column holds point centres: add the initial half spacing.
  const double half = 0.5 * spec.grid.cell_size / column.points_per_cell_side;
  const double df = front->back() + half - column.lower.x();
  const double stop = FrontStopTime(*time, *front, 0.01 * d0);
  // A front still moving at the end "stops" at the last row: the run-out is
  // then a lower bound. At rest means unmoved over the last 10 % of the run.
  const double at_rest = time->empty() || stop <= 0.9 * time->back() ? 1.0 : 0.0;
  return Summary{{"runout_normalised", (df - d0) / d0},
                 {"final_front_m", df + column.lower.x()},
                 {"front_stop_time_s", stop},
                 {"front_at_rest", at_rest}};
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
  if (stress.size() != strain.size()) {
    return absl::InvalidArgumentError("stress and strain columns differ in length");
  }
  const std::size_t peak = std::max_element(stress.begin(), stress.end()) - stress.begin();
  return Summary{{"peak_stress_Pa", stress[peak]},
                 {"peak_strain", strain[peak]},
                 {"final_stress_Pa", stress.back()},
                 {"final_strain", strain.back()}};
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
                                              std::span<const double> load, int window) {
  const std::size_t n = load.size();
  if (n < 3 || settlement.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat("a load-settlement curve needs >= 3 rows of ",
                                                   "both columns (", settlement.size(), ", ", n,
                                                   ")"));
  }
  // A running median of 3 rows removes single-row flicker (a node row
  // emptying as the surface passes it), then a centred mean smooths.
  std::vector<double> median(load.begin(), load.end());
  for (std::size_t i = 1; i + 1 < n; ++i) {
    median[i] = std::max(std::min(load[i - 1], load[i]),
                         std::min(std::max(load[i - 1], load[i]), load[i + 1]));
  }
  const std::size_t half = static_cast<std::size_t>(std::max(window, 1) / 2);
  std::vector<double> smooth(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= half ? i - half : 0, hi = std::min(n - 1, i + half);
    double sum = 0.0;
    for (std::size_t k = lo; k <= hi; ++k) sum += median[k];
    smooth[i] = sum / static_cast<double>(hi - lo + 1);
  }
  // Slopes between rows whose settlement grows; the first that is <= 0 marks
  // the peak. Else the steady part: the first slope within 5 % of the slopes'
  // range above the smallest (noise makes the very smallest one arbitrary).
  // (Rows within half a window of the ends, where the mean is one-sided,
  // stay out.)
  std::vector<std::pair<std::size_t, double>> slopes;
  for (std::size_t i = half; i + 1 + half < n; ++i) {
    const double dd = settlement[i + 1] - settlement[i];
    if (!(dd > 0.0) || !(settlement[i] > 0.0)) continue;
    const double slope = (smooth[i + 1] - smooth[i]) / dd;
    if (slope <= 0.0) return UltimateLoad{i, smooth[i], settlement[i], true};
    slopes.emplace_back(i, slope);
  }
  if (slopes.empty()) return absl::InvalidArgumentError("the settlement never grows");
  double lo = slopes.front().second, hi = lo;
  for (const auto& [i, slope] : slopes) lo = std::min(lo, slope), hi = std::max(hi, slope);
  for (const auto& [i, slope] : slopes) {
    if (slope <= lo + 0.05 * (hi - lo)) return UltimateLoad{i, smooth[i], settlement[i], false};
  }
  return absl::InternalError("unreachable");
}

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
  if (kind == "none") return Summary{};
  return absl::InvalidArgumentError(absl::StrCat("unknown summary kind '", kind, "'"));
}

absl::Status WriteSummary(const std::string& path, const std::string& case_name,
                          const Summary& summary) {
  nlohmann::ordered_json j;
  j["case"] = case_name;
  for (const auto& [key, value] : summary) j[key] = value;
  std::ofstream f(path, std::ios::trunc);
  f << j.dump(2) << "\n";
  f.close();
  if (!f) return absl::InternalError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

}  // namespace rvehub::mpm
