#include "client_run/time_split.h"

#include <algorithm>
#include <cstdint>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace rvehub::client_run {

std::string FormatTimeSplit(const TimeSplit& s, absl::string_view solver) {
  const double wall = std::max(s.wall_s, 1e-12);
  const double engine = std::min(s.rve_s, s.rve_stats.engine_seconds / std::max(1, s.rve_workers));
  const double service = s.rve_s - engine;
  const double grid = std::max(0.0, s.wall_s - s.rve_s - s.output_s);
  std::string out = absl::StrFormat(
      "time split (wall %.1f s): DEM engine %.1f s (%.1f %%; %.1f core-s over %d workers), "
      "service, transport and idle workers %.1f s (%.1f %%), %s %.1f s (%.1f %%), output %.1f s "
      "(%.1f %%)",
      s.wall_s, engine, 100 * engine / wall, s.rve_stats.engine_seconds, s.rve_workers, service,
      100 * service / wall, solver, grid, 100 * grid / wall, s.output_s, 100 * s.output_s / wall);
  const client::ApplyStats& st = s.rve_stats;
  if (st.increments == 0) return out;
  absl::StrAppendFormat(&out, "\nDEM steps per increment: mean %.2f over %d increments;",
                        static_cast<double>(st.dem_steps) / static_cast<double>(st.increments),
                        st.increments);
  for (int b = 0; b < client::ApplyStats::kBins; ++b) {
    if (st.histogram[b] == 0) continue;
    const std::int64_t upper = client::ApplyStats::BinUpper(b);
    const std::int64_t lower = b == 0 ? 0 : client::ApplyStats::BinUpper(b - 1) + 1;
    const std::string label = upper < 0        ? absl::StrCat(">", lower - 1)
                              : b == 0         ? std::string("<=1")
                              : lower == upper ? absl::StrCat(upper)
                                               : absl::StrCat(lower, "-", upper);
    absl::StrAppendFormat(
        &out, " %s: %.1f %%", label,
        100.0 * static_cast<double>(st.histogram[b]) / static_cast<double>(st.increments));
  }
  return out;
}

}  // namespace rvehub::client_run
