#include "mpm_client/run/output.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "mpm_client/run/summary.h"
#include "rve_server/common/status_macros.h"
#include "toolkit/plot.h"

namespace rvehub::mpm {

namespace {

absl::Status WriteCasePlot(const CaseSpec& spec,
                           const std::map<std::string, std::vector<double>>& cols,
                           const Summary& summary, const std::string& csv_path,
                           const std::string& png_path) {
  const OutputSpec& out = spec.output;
  if (out.plot == "none") return absl::OkStatus();
  auto column = [&](const std::string& name) -> absl::StatusOr<std::vector<double>> {
    auto it = cols.find(name);
    if (it == cols.end()) {
      return absl::InvalidArgumentError(absl::StrCat(csv_path, " has no column ", name));
    }
    return it->second;
  };
  auto scaled = [](std::vector<double> v, double f) {
    for (double& x : v) x *= f;
    return v;
  };
  const std::string& name = spec.name;
  std::vector<plot::Panel> panels;
  if (out.plot == "stress-strain") {
    ASSIGN_OR_RETURN(const std::vector<double> eyy, column("mean_eyy"));
    ASSIGN_OR_RETURN(const std::vector<double> exx, column("mean_exx"));
    ASSIGN_OR_RETURN(const std::vector<double> syy, column("mean_syy"));
    ASSIGN_OR_RETURN(const std::vector<double> sxx, column("mean_sxx"));
    std::vector<double> ev(eyy.size());
    for (std::size_t i = 0; i < ev.size(); ++i) ev[i] = 100.0 * (eyy[i] + exx[i]);
    const std::vector<double> axial = scaled(eyy, 100.0);
    // The paper's nominal curve: the platen's force over the specimen's
    // width against its travel over the height (the biaxial summary's).
    if (!spec.bodies.empty()) {
      ASSIGN_OR_RETURN(NominalCurve curve, PlatenCurve(spec, cols));
      plot::Panel nominal{absl::StrCat(name, ": nominal stress-strain"),
                          "platen travel / height (%)",
                          "platen force / width (kPa)",
                          {{"platen", scaled(std::move(curve.strain), 100.0),
                            scaled(std::move(curve.stress), 1e-3)}}};
      if (!out.reference_curve.empty()) {
        // The DEM element test on the same RVE (rve_cli element-test CSV).
        ASSIGN_OR_RETURN(const auto reference, ReadCsvColumns(out.reference_curve));
        const auto strain = reference.find("axial_strain"), syy = reference.find("syy");
        if (strain == reference.end() || syy == reference.end()) {
          return absl::InvalidArgumentError(
              absl::StrCat(out.reference_curve,
                           " has no axial_strain or syy column (rve_cli element-test CSV)"));
        }
        nominal.series.push_back(
            {"DEM element test", scaled(strain->second, 100.0), scaled(syy->second, 1e-3)});
      }
      panels.push_back(std::move(nominal));
    }
    panels.push_back({absl::StrCat(name, ": mean of all points"),
                      "axial strain eyy (%)",
                      "stress (kPa, compression +)",
                      {{"syy", axial, scaled(syy, 1e-3)}, {"sxx", axial, scaled(sxx, 1e-3)}}});
    panels.push_back({absl::StrCat(name, ": volumetric strain"),
                      "axial strain eyy (%)",
                      "ev = exx + eyy (%, compression +)",
                      {{"ev", axial, ev}}});
  } else if (out.plot == "load-settlement") {
    ASSIGN_OR_RETURN(const std::vector<double> fy, column(out.plot_body + "_fy"));
    ASSIGN_OR_RETURN(const std::vector<double> dy, column(out.plot_body + "_dy"));
    const double area = out.plot_width * spec.solver.thickness;  // m²
    const std::vector<double> d = scaled(dy, -1.0);
    const std::map<std::string, double> figures(summary.begin(), summary.end());
    if (SummaryKind(out) == "footing" && figures.contains("surcharge_Pa")) {
      // q/q_s against d with Prandtl's N_q and the ultimate load marked.
      const double qs = figures.at("surcharge_Pa");
      plot::Panel panel{absl::StrCat(name, ": load-settlement of ", out.plot_body),
                        "settlement d (m)",
                        "q / q_s",
                        {{"MPM x DEM", d, scaled(fy, 1.0 / (area * qs))}}};
      const double d_end = d.empty() ? 0.0 : *std::max_element(d.begin(), d.end());
      if (figures.contains("N_q_prandtl")) {
        const double nq = figures.at("N_q_prandtl");
        panel.series.push_back({"Prandtl N_q", {0.0, d_end}, {nq, nq}});
      }
      if (figures.contains("N_q_reduced")) {  // local shear, punching
        const double nq = figures.at("N_q_reduced");
        panel.series.push_back({"Terzaghi N'_q (local)", {0.0, d_end}, {nq, nq}});
      }
      const double du = figures.at("settlement_at_ultimate_m"), nu = figures.at("N_q");
      panel.series.push_back({"ultimate load", {du, du}, {0.0, nu}});
      panels.push_back(std::move(panel));
    } else if (SummaryKind(out) == "pipe") {
      ASSIGN_OR_RETURN(const std::vector<double> fx, column(out.plot_body + "_fx"));
      ASSIGN_OR_RETURN(const std::vector<double> dx, column(out.plot_body + "_dx"));
      const double t = 1e-3 / spec.solver.thickness;  // kN per m of pipe
      panels.push_back({absl::StrCat(name, ": vertical"),
                        "downward displacement (m)",
                        "vertical force of the soil (kN/m)",
                        {{out.plot_body, d, scaled(fy, t)}}});
      panels.push_back({absl::StrCat(name, ": horizontal"),
                        "displacement to the left (m)",
                        "horizontal force of the soil (kN/m)",
                        {{out.plot_body, scaled(dx, -1.0), scaled(fx, t)}}});
    } else {
      panels.push_back({absl::StrCat(name, ": load-settlement of ", out.plot_body),
                        "settlement (m)",
                        "q = fy / (B t) (kPa)",
                        {{out.plot_body, d, scaled(fy, 1e-3 / area)}}});
    }
  } else if (out.plot == "collapse") {
    ASSIGN_OR_RETURN(const std::vector<double> t, column("time"));
    ASSIGN_OR_RETURN(const std::vector<double> front, column("front_x"));
    ASSIGN_OR_RETURN(const std::vector<double> ke, column("kinetic_energy"));
    panels.push_back(
        {absl::StrCat(name, ": front"), "time (s)", "front x (m)", {{"front", t, front}}});
    panels.push_back({absl::StrCat(name, ": kinetic energy"),
                      "time (s)",
                      "kinetic energy (J)",
                      {{"E_k", t, ke}}});
  } else {
    return absl::InvalidArgumentError(absl::StrCat("unknown plot kind '", out.plot, "'"));
  }
  return plot::WritePng(png_path, panels);
}

}  // namespace

absl::StatusOr<Summary> WriteRunOutputs(const CaseSpec& spec, const std::string& dir) {
  const std::string csv = dir + "/timeseries.csv";
  ASSIGN_OR_RETURN(const auto columns, ReadCsvColumns(csv));
  absl::StatusOr<Summary> summarised = Summarise(spec, columns);
  if (!summarised.ok()) {  // e.g. a run too short for its curve: the run itself ended
    return absl::Status(summarised.status().code(),
                        absl::StrCat("no summary from ", csv, ": ", summarised.status().message()));
  }
  Summary summary = *std::move(summarised);
  if (!summary.empty()) RETURN_IF_ERROR(WriteSummary(dir + "/summary.json", spec.name, summary));
  RETURN_IF_ERROR(WriteCasePlot(spec, columns, summary, csv, dir + "/plot.png"));
  return summary;
}

}  // namespace rvehub::mpm
