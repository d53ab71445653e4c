// Applies deformation increments to many RVEs over a pool of threads. Each
// RVE is advanced by exactly one thread and RVEs share no state, so results
// are bit-identical whatever the thread count.
#ifndef RVEHUB_RVE_SERVER_ENGINE_BATCH_H_
#define RVEHUB_RVE_SERVER_ENGINE_BATCH_H_

#include <Eigen/Dense>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "rve_server/engine/rve.h"

namespace rvehub::dem {

// results[k] is rves[k]->Apply(delta_f[k], options). InvalidArgument (and no
// RVE touched) when the spans differ in length or threads < 1.
absl::StatusOr<std::vector<absl::StatusOr<RveState>>> ApplyBatch(
    std::span<Rve* const> rves, std::span<const Eigen::Matrix3d> delta_f,
    const ApplyOptions& options, int threads);

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_BATCH_H_
