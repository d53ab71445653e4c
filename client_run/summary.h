// A run's headline figures (DIR/summary.json, any continuum client's): named
// numbers in the order the file lists them, and the peak of a nominal
// stress–strain curve as the biaxial summaries read it.
#ifndef RVEHUB_CLIENT_RUN_SUMMARY_H_
#define RVEHUB_CLIENT_RUN_SUMMARY_H_

#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::client_run {

// Named figures in the order summary.json lists them (SI units in the names).
using Summary = std::vector<std::pair<std::string, double>>;

// A nominal stress–strain curve's peak_stress_Pa and peak_strain (the
// largest stress, its first row), final_stress_Pa and final_strain (the last
// row). Stress in Pa and strain [-], both compression +. InvalidArgument for
// columns of different lengths or none.
absl::StatusOr<Summary> PeakSummary(std::span<const double> strain, std::span<const double> stress);

// summary.json: {"case": name, then the figures as plain keys}.
absl::Status WriteSummary(const std::string& path, const std::string& case_name,
                          const Summary& summary);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_SUMMARY_H_
