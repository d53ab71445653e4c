#include "rve_server/values/preparation.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace rvehub::dem {

std::string TemplateName(absl::string_view parameter_set, std::uint64_t seed,
                         const TemplateVariant& variant) {
  std::string name = absl::StrCat(parameter_set, "-seed", seed);
  if (variant.pressure > 0) absl::StrAppendFormat(&name, "-p%.6gPa", variant.pressure);
  if (variant.void_ratio > 0) absl::StrAppendFormat(&name, "-e%.6g", variant.void_ratio);
  if (variant.num_particles > 0) absl::StrAppend(&name, "-", variant.num_particles, "discs");
  if (variant.rolling_eta.has_value()) {
    absl::StrAppendFormat(&name, "-eta%.6g", *variant.rolling_eta);
  }
  // %g writes 2e+06 from 1e6 Pa up; '+' is not in a template name's alphabet.
  name.erase(std::remove(name.begin(), name.end(), '+'), name.end());
  return name;
}

std::string TemplateDescription(absl::string_view parameter_set, std::uint64_t seed,
                                std::size_t num_particles, const PreparationReport& report,
                                const TemplateVariant& variant) {
  std::string s =
      absl::StrFormat("material %s, seed %d, %d discs, e0 = %.4f, p0 = %.1f Pa", parameter_set,
                      seed, num_particles, report.void_ratio, report.pressure);
  if (variant.rolling_eta.has_value()) {
    absl::StrAppendFormat(&s, ", rolling eta %g", *variant.rolling_eta);
  }
  return s;
}

}  // namespace rvehub::dem
