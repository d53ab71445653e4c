// A solver's state as named flat arrays, bit-exact: what an MPM checkpoint
// (store/sim_checkpoint.h) and a recovery point hold of it, and back.
//
// Keys. doubles: time, dt (1 each); per point: position, velocity,
// half_size0 (x, y), mass, volume, volume0, deformation_gradient (4, row
// major), stress, response_stress (9, row major), void_ratio,
// fabric_anisotropy, mean_rotation, coordination, permeability; per load:
// load_traction (2), load_length0, load_ramp_time; reactions (2 per wall and
// body); the two-phase scheme's (saturated cases) also fluid_velocity (2),
// pore_pressure, porosity0, position0 (2), vertical_stress0 per point and
// node_pressure per grid node (NaN: inactive in the last step). ints: step
// (1); region per point; load_point, load_normal_axis, load_normal_sign,
// load_source per load.
#ifndef RVEHUB_MPM_CLIENT_CORE_SOLVER_CHECKPOINT_H_
#define RVEHUB_MPM_CLIENT_CORE_SOLVER_CHECKPOINT_H_

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/solver.h"

namespace rvehub::mpm {

// The solver's whole state (keys above), replacing those keys' arrays.
void ExportSolverState(const Solver& solver, std::map<std::string, std::vector<double>>& doubles,
                       std::map<std::string, std::vector<std::int64_t>>& ints);
// Back into a solver made for the same case. InvalidArgument for a state
// with a key missing, an array of the wrong length or values the solver
// would refuse; a bad state changes nothing.
absl::Status ImportSolverState(Solver& solver,
                               const std::map<std::string, std::vector<double>>& doubles,
                               const std::map<std::string, std::vector<std::int64_t>>& ints);
// A solver for `spec` (Solver::ForCase) with the state of ExportSolverState.
absl::StatusOr<std::unique_ptr<Solver>> SolverFromState(
    const CaseSpec& spec, const std::map<std::string, std::vector<double>>& doubles,
    const std::map<std::string, std::vector<std::int64_t>>& ints, StressModel* model);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_SOLVER_CHECKPOINT_H_
