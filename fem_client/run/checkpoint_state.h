// A FEM×DEM run's state as the named flat arrays of a simulation checkpoint
// (store/sim_checkpoint.h), bit-exact, and back.
//
// Keys. ints: steps, committed_step (the RVEs' committed step, which
// cut-backs advance past the load steps) (1 each); has_tangent (1 per Gauss
// point: whether the committed response carries one). doubles: nodes,
// displacement (2 per node, m); stress (9 per Gauss point, Pa, row major),
// tangent (81 per Gauss point that has one, Pa, column major); f_int, f_ext,
// residual (2 per node, N/m); platen_force (1 per forced platen, N/m);
// initial_tangents (81 per Gauss point, or none); and of the RVEs' committed
// states, what the outputs read: rve_stress (9, Pa), rve_void_ratio,
// rve_coordination, rve_fabric_anisotropy (1 each, per Gauss point).
#ifndef RVEHUB_FEM_CLIENT_RUN_CHECKPOINT_STATE_H_
#define RVEHUB_FEM_CLIENT_RUN_CHECKPOINT_STATE_H_

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "fem_client/core/static_solver.h"
#include "rve_server/values/state.h"

namespace rvehub::fem {

using NamedDoubles = std::map<std::string, std::vector<double>>;
using NamedInts = std::map<std::string, std::vector<std::int64_t>>;

struct RunState {
  SolverState solver;
  std::int64_t committed_step = 0;
  std::vector<dem::RveState> rves;  // the fields the outputs read (keys above)
};

// The state's arrays, replacing those keys'.
void PutRunState(const RunState& s, NamedDoubles& doubles, NamedInts& ints);
// Back from the arrays of PutRunState. InvalidArgument naming the key for
// one missing or of a length that does not fit the others; the solver
// checks the values themselves (StaticSolver::Restore).
absl::StatusOr<RunState> GetRunState(const NamedDoubles& doubles, const NamedInts& ints);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_RUN_CHECKPOINT_STATE_H_
