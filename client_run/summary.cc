#include "client_run/summary.h"

#include <algorithm>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "nlohmann/json.hpp"

namespace rvehub::client_run {

absl::StatusOr<Summary> PeakSummary(std::span<const double> strain,
                                    std::span<const double> stress) {
  if (stress.size() != strain.size()) {
    return absl::InvalidArgumentError("stress and strain columns differ in length");
  }
  if (stress.empty()) return absl::InvalidArgumentError("the stress-strain curve has no rows");
  const std::size_t peak = std::max_element(stress.begin(), stress.end()) - stress.begin();
  return Summary{{"peak_stress_Pa", stress[peak]},
                 {"peak_strain", strain[peak]},
                 {"final_stress_Pa", stress.back()},
                 {"final_strain", strain.back()}};
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

}  // namespace rvehub::client_run
