#include "rve_server/engine/batch.h"

#include <algorithm>
#include <atomic>
#include <thread>

#include "absl/strings/str_cat.h"

namespace rvehub::dem {

absl::StatusOr<std::vector<absl::StatusOr<RveState>>> ApplyBatch(
    std::span<Rve* const> rves, std::span<const Eigen::Matrix3d> delta_f,
    const ApplyOptions& options, int threads) {
  if (rves.size() != delta_f.size()) {
    return absl::InvalidArgumentError(absl::StrCat("batch has ", rves.size(), " RVEs but ",
                                                   delta_f.size(), " deformation increments"));
  }
  if (threads < 1)
    return absl::InvalidArgumentError(absl::StrCat("threads = ", threads, " must be >= 1"));
  for (std::size_t k = 0; k < rves.size(); ++k) {
    if (rves[k] == nullptr) return absl::InvalidArgumentError(absl::StrCat("RVE ", k, " is null"));
  }
  // One RVE twice would be advanced by two threads at once.
  std::vector<Rve*> sorted(rves.begin(), rves.end());
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
    return absl::InvalidArgumentError("the same RVE appears twice in one batch");
  }
  std::vector<absl::StatusOr<RveState>> results(rves.size(), absl::UnknownError("not run"));
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t k = next++; k < rves.size(); k = next++) {
      results[k] = rves[k]->Apply(delta_f[k], options);
    }
  };
  const int n = std::min<int>(threads, static_cast<int>(rves.size()));
  std::vector<std::jthread> pool;
  for (int t = 1; t < n; ++t) pool.emplace_back(worker);
  worker();
  pool.clear();  // joins
  return results;
}

}  // namespace rvehub::dem
