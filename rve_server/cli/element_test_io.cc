#include "rve_server/cli/element_test_io.h"

#include <cstdio>
#include <functional>
#include <memory>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "toolkit/plot.h"

namespace rvehub::cli {

using dem::ElementTestKind;
using dem::ElementTestRow;

const char kElementTestCsvHeader[] =
    "step,axial_strain,vol_strain,sxx,syy,sxy,p,q,void_ratio,coordination,fabric_xx,fabric_yy,"
    "fabric_xy,Fa,permeability,shear_strain";

absl::Status WriteTextFile(const std::string& path, absl::string_view text) {
  std::unique_ptr<FILE, int (*)(FILE*)> file(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!file) return absl::UnavailableError(absl::StrCat("cannot open '", path, "' for writing"));
  std::fwrite(text.data(), 1, text.size(), file.get());
  if (std::ferror(file.get()) || std::fclose(file.release()) != 0) {
    return absl::UnavailableError(absl::StrCat("error while writing '", path, "'"));
  }
  return absl::OkStatus();
}

absl::Status WriteElementTestCsv(const std::string& path, const std::vector<ElementTestRow>& rows) {
  std::string text = absl::StrCat(kElementTestCsvHeader, "\n");
  for (const ElementTestRow& r : rows) {
    // %.10g keeps the columns exact enough to re-derive moduli from them.
    absl::StrAppendFormat(
        &text,
        "%d,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,"
        "%.10g\n",
        r.step, r.axial_strain_comp, r.vol_strain_comp, r.sxx_comp, r.syy_comp, r.sxy_comp,
        r.p_comp, r.q, r.void_ratio, r.coordination, r.fabric_xx, r.fabric_yy, r.fabric_xy,
        r.fabric_anisotropy, r.permeability, r.shear_strain);
  }
  return WriteTextFile(path, text);
}

absl::Status WriteElementTestPlot(const std::string& path, ElementTestKind kind,
                                  const std::string& title,
                                  const std::vector<ElementTestRow>& rows) {
  using Getter = std::function<double(const ElementTestRow&)>;
  auto series = [&](const std::string& label, const Getter& x, const Getter& y, double scale_x,
                    double scale_y) {
    plot::Series s{label, {}, {}};
    for (const ElementTestRow& r : rows) {
      s.x.push_back(x(r) * scale_x);
      s.y.push_back(y(r) * scale_y);
    }
    return s;
  };
  const Getter axial = [](const ElementTestRow& r) { return r.axial_strain_comp; };
  const Getter vol = [](const ElementTestRow& r) { return r.vol_strain_comp; };
  const Getter shear = [](const ElementTestRow& r) { return r.shear_strain; };
  const Getter p = [](const ElementTestRow& r) { return r.p_comp; };
  const Getter q = [](const ElementTestRow& r) { return r.q; };
  const Getter sxx = [](const ElementTestRow& r) { return r.sxx_comp; };
  const Getter syy = [](const ElementTestRow& r) { return r.syy_comp; };
  const Getter tau = [](const ElementTestRow& r) { return -r.sxy_comp; };
  const Getter e = [](const ElementTestRow& r) { return r.void_ratio; };
  const Getter z = [](const ElementTestRow& r) { return r.coordination; };
  const Getter fa = [](const ElementTestRow& r) { return r.fabric_anisotropy; };

  Getter x = axial;
  std::string x_label = "axial strain (%)";
  if (kind == ElementTestKind::kIsotropic) {
    x = vol;
    x_label = "volumetric strain (%)";
  } else if (kind == ElementTestKind::kUndrainedSimpleShear ||
             kind == ElementTestKind::kCyclicSimpleShear) {
    x = shear;
    x_label = "shear strain (%)";
  }
  std::vector<plot::Panel> panels;
  const bool shear_test = x_label.starts_with("shear");
  if (shear_test) {
    panels.push_back({title + ": shear stress",
                      x_label,
                      "tau = sigma_xy (kPa)",
                      {series("tau", x, tau, 100, 1e-3)}});
    panels.push_back({"stress path", "p (kPa)", "tau (kPa)", {series("tau", p, tau, 1e-3, 1e-3)}});
    panels.push_back({"mean stress", x_label, "p (kPa)", {series("p", x, p, 100, 1e-3)}});
  } else {
    panels.push_back({title + ": stresses",
                      x_label,
                      "stress (kPa)",
                      {series("sigma_yy", x, syy, 100, 1e-3), series("sigma_xx", x, sxx, 100, 1e-3),
                       series("q", x, q, 100, 1e-3)}});
    panels.push_back({"volume change",
                      x_label,
                      "volumetric strain (%, compression +)",
                      {series("eps_v", x, vol, 100, 100)}});
    panels.push_back({"stress path", "p (kPa)", "q (kPa)", {series("q", p, q, 1e-3, 1e-3)}});
  }
  panels.push_back({"void ratio", x_label, "e", {series("e", x, e, 100, 1)}});
  panels.push_back({"coordination number", x_label, "Z", {series("Z", x, z, 100, 1)}});
  panels.push_back({"fabric anisotropy", x_label, "Fa", {series("Fa", x, fa, 100, 1)}});
  return plot::WritePng(path, panels, {.columns = 3, .panel_width = 480, .panel_height = 360});
}

}  // namespace rvehub::cli
