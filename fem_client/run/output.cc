#include "fem_client/run/output.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "client_run/timeseries.h"
#include "rve_server/common/status_macros.h"
#include "toolkit/plot.h"

namespace rvehub::fem {
namespace {

using Columns = std::map<std::string, std::vector<double>>;

absl::StatusOr<const std::vector<double>*> Column(const Columns& columns, const std::string& name) {
  const auto it = columns.find(name);
  if (it == columns.end() || it->second.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("timeseries has no column ", name));
  }
  return &it->second;
}

bool IsShear(const FemCase& c) { return c.loading.kind != LoadingKind::kCompression; }

std::vector<double> Scaled(std::vector<double> v, double f) {
  for (double& x : v) x *= f;
  return v;
}

}  // namespace

std::vector<std::string> TimeseriesColumns(const FemCase& c) {
  std::vector<std::string> columns = {"step",
                                      "axial_strain",
                                      "vol_strain",
                                      "shear_strain",
                                      "platen_force_per_width_Pa",
                                      "lateral_stress_Pa",
                                      "mean_p_Pa",
                                      "mean_q_Pa",
                                      "mean_void_ratio",
                                      "iterations",
                                      "error_d",
                                      "error_f",
                                      "cutbacks",
                                      "unconverged",
                                      "trials",
                                      "dem_steps_per_trial",
                                      "wall_step_s"};
  for (std::int64_t k : c.output.monitor) {
    for (const char* name : {"_sxx_Pa", "_syy_Pa", "_sxy_Pa", "_void_ratio"}) {
      columns.push_back(absl::StrCat("gp", k, name));
    }
  }
  return columns;
}

absl::StatusOr<Summary> SummariseFem(const FemCase& c, const Columns& columns) {
  ASSIGN_OR_RETURN(const std::vector<double>* step, Column(columns, "step"));
  ASSIGN_OR_RETURN(const std::vector<double>* stress, Column(columns, "platen_force_per_width_Pa"));
  Summary out;
  if (!IsShear(c)) {
    ASSIGN_OR_RETURN(const std::vector<double>* strain, Column(columns, "axial_strain"));
    ASSIGN_OR_RETURN(out, client_run::PeakSummary(*strain, *stress));
  } else {
    ASSIGN_OR_RETURN(const std::vector<double>* gamma, Column(columns, "shear_strain"));
    ASSIGN_OR_RETURN(const std::vector<double>* p, Column(columns, "mean_p_Pa"));
    if (gamma->size() != stress->size() || p->size() != stress->size()) {
      return absl::InvalidArgumentError("the shear columns differ in length");
    }
    const auto [low, high] = std::minmax_element(stress->begin(), stress->end());
    double largest_gamma = 0.0;
    for (double g : *gamma) largest_gamma = std::max(largest_gamma, std::abs(g));
    out = {{"peak_shear_stress_Pa", *high}, {"peak_shear_strain", (*gamma)[high - stress->begin()]},
           {"min_shear_stress_Pa", *low},   {"final_shear_strain", gamma->back()},
           {"final_mean_p_Pa", p->back()},  {"max_abs_shear_strain", largest_gamma}};
    if (c.loading.kind == LoadingKind::kCyclicShear) {
      // Fractional where a stress-controlled run stops at end_shear_strain:
      // the cycles to that strain, as G&Z count them.
      out.emplace_back("cycles", step->back() / static_cast<double>(c.loading.steps_per_cycle));
    }
  }
  // The solver's figures over the steps' rows (row 0 has no step).
  const std::size_t rows = step->size();
  if (rows < 2) return absl::InvalidArgumentError("the timeseries has no load step");
  double iterations = 0.0, most = 0.0, cutbacks = 0.0, unconverged = 0.0, trials = 0.0,
         dem_steps = 0.0, wall = 0.0;
  for (const char* name :
       {"iterations", "cutbacks", "unconverged", "trials", "dem_steps_per_trial", "wall_step_s"}) {
    ASSIGN_OR_RETURN(const std::vector<double>* column, Column(columns, name));
    if (column->size() != rows) {
      return absl::InvalidArgumentError(absl::StrCat("column ", name, " differs in length"));
    }
  }
  for (std::size_t r = 1; r < rows; ++r) {
    const double n = columns.at("iterations")[r], t = columns.at("trials")[r];
    iterations += n;
    most = std::max(most, n);
    cutbacks += columns.at("cutbacks")[r];
    unconverged += columns.at("unconverged")[r];
    trials += t;
    dem_steps += t * columns.at("dem_steps_per_trial")[r];
    wall += columns.at("wall_step_s")[r];
  }
  const double steps_recorded = static_cast<double>(rows - 1);
  out.emplace_back("load_steps", step->back());
  out.emplace_back("iterations_mean", iterations / steps_recorded);
  out.emplace_back("iterations_max", most);
  out.emplace_back("iterations_total", iterations);
  out.emplace_back("cutbacks_total", cutbacks);
  out.emplace_back("unconverged_total", unconverged);
  out.emplace_back("trials_total", trials);
  out.emplace_back("dem_steps_per_trial", trials > 0 ? dem_steps / trials : 0.0);
  out.emplace_back("wall_s", wall);
  return out;
}

namespace {

// The element-test CSV of the case's reference curve, its columns `x` and `y`
// (strain scaled to %, stress to kPa) as a series; InvalidArgument when it
// lacks them.
absl::StatusOr<plot::Series> ReferenceSeries(const std::string& path, const std::string& x,
                                             const std::string& y, double y_scale) {
  ASSIGN_OR_RETURN(const Columns reference, client_run::ReadCsvColumns(path));
  const auto xs = reference.find(x), ys = reference.find(y);
  if (xs == reference.end() || ys == reference.end()) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, " has no ", x, " or ", y, " column (rve_cli element-test CSV)"));
  }
  return plot::Series{"DEM element test", Scaled(xs->second, 100.0), Scaled(ys->second, y_scale)};
}

absl::Status WritePlot(const FemCase& c, const Columns& columns, const std::string& png) {
  const OutputSpec& out = c.output;
  if (out.plot == PlotKind::kNone) return absl::OkStatus();
  const std::string& name = c.name;
  std::vector<plot::Panel> panels;
  ASSIGN_OR_RETURN(const std::vector<double>* stress, Column(columns, "platen_force_per_width_Pa"));
  if (out.plot == PlotKind::kStressStrain) {
    ASSIGN_OR_RETURN(const std::vector<double>* axial, Column(columns, "axial_strain"));
    ASSIGN_OR_RETURN(const std::vector<double>* ev, Column(columns, "vol_strain"));
    ASSIGN_OR_RETURN(const std::vector<double>* lateral, Column(columns, "lateral_stress_Pa"));
    ASSIGN_OR_RETURN(const std::vector<double>* iterations, Column(columns, "iterations"));
    const std::vector<double> strain = Scaled(*axial, 100.0);
    plot::Panel sigma{absl::StrCat(name, ": nominal stress-strain"),
                      "axial strain (%)",
                      "stress (kPa, compression +)",
                      {{"platen force / width", strain, Scaled(*stress, 1e-3)},
                       {"lateral stress", strain, Scaled(*lateral, 1e-3)}}};
    plot::Panel volume{absl::StrCat(name, ": volumetric strain"),
                       "axial strain (%)",
                       "ev (%, compression +)",
                       {{"FEM x DEM", strain, Scaled(*ev, 100.0)}}};
    if (!out.reference_curve.empty()) {
      // The DEM element test on the same RVE.
      ASSIGN_OR_RETURN(plot::Series s,
                       ReferenceSeries(out.reference_curve, "axial_strain", "syy", 1e-3));
      sigma.series.push_back(std::move(s));
      ASSIGN_OR_RETURN(plot::Series v,
                       ReferenceSeries(out.reference_curve, "axial_strain", "vol_strain", 100.0));
      volume.series.push_back(std::move(v));
    }
    panels.push_back(std::move(sigma));
    panels.push_back(std::move(volume));
    // Row 0 has no step.
    std::vector<double> x(strain.begin() + 1, strain.end()),
        n(iterations->begin() + 1, iterations->end());
    panels.push_back({absl::StrCat(name, ": Newton iterations"),
                      "axial strain (%)",
                      "iterations per load step",
                      {{"iterations", std::move(x), std::move(n)}}});
  } else {
    ASSIGN_OR_RETURN(const std::vector<double>* gamma, Column(columns, "shear_strain"));
    ASSIGN_OR_RETURN(const std::vector<double>* p, Column(columns, "mean_p_Pa"));
    const std::vector<double> tau = Scaled(*stress, 1e-3);
    plot::Panel loops{absl::StrCat(name, ": shear stress-strain"),
                      "shear strain (%)",
                      "tau (kPa)",
                      {{"FEM x DEM", Scaled(*gamma, 100.0), tau}}};
    if (!out.reference_curve.empty()) {
      // The element test's sxy is compression + (−σxy); τ is σxy.
      ASSIGN_OR_RETURN(plot::Series s,
                       ReferenceSeries(out.reference_curve, "shear_strain", "sxy", -1e-3));
      loops.series.push_back(std::move(s));
    }
    panels.push_back(std::move(loops));
    panels.push_back({absl::StrCat(name, ": stress path"),
                      "mean effective stress p (kPa)",
                      "tau (kPa)",
                      {{"FEM x DEM", Scaled(*p, 1e-3), tau}}});
  }
  return plot::WritePng(png, panels);
}

}  // namespace

absl::StatusOr<Summary> WriteFemRunOutputs(const FemCase& c, const std::string& dir) {
  const std::string csv = dir + "/timeseries.csv";
  ASSIGN_OR_RETURN(const Columns columns, client_run::ReadCsvColumns(csv));
  absl::StatusOr<Summary> summary = SummariseFem(c, columns);
  if (!summary.ok()) {
    return absl::Status(summary.status().code(),
                        absl::StrCat("no summary from ", csv, ": ", summary.status().message()));
  }
  RETURN_IF_ERROR(client_run::WriteSummary(dir + "/summary.json", c.name, *summary));
  RETURN_IF_ERROR(WritePlot(c, columns, dir + "/plot.png"));
  return summary;
}

}  // namespace rvehub::fem
