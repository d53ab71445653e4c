#include "mpm_client/core/explicit_solver.h"

#include <algorithm>
#include <vector>

#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

using Eigen::Matrix2d;
using Eigen::Vector2d;

// Nodes lighter than this fraction of the lightest point are inactive: their
// velocity would be force/(tiny mass), the small-mass instability.
constexpr double kInactiveMassFraction = 1e-10;

}  // namespace

ExplicitSolver::ExplicitSolver() : Solver(kInactiveMassFraction) {}

absl::Status ExplicitSolver::Step() {
  RETURN_IF_ERROR(CheckReady());
  RETURN_IF_ERROR(EvaluateShapes());  // S_Ip, ∇S_Ip at the step's start (eqs. 14–15)
  MapToGrid();                        // (a) m_I, p_I, v_I^n = p_I/m_I
  ConstrainStart();                   // walls and bodies on v^n
  // (b) dH = Δt Σ_I ∇S_Ip v_I^n, σ_p from the model (eq. 30), one batched update.
  RETURN_IF_ERROR(UpdateStress());
  RETURN_IF_ERROR(ComputeNodalForces());            // (c) f_int + f_ext (eqs. 12–13)
  IntegrateNodalVelocities();                       // (c) v^{n+1} = v^n + Δt f/m (eq. 10)
  Constrain(node_velocity_new_, time_ + dt_, 1.0);  // walls and bodies on v^{n+1}
  MapToPoints();                                    // (d) v_p (eq. 19), x_p (eq. 16)
  return FinishStep();
}

void ExplicitSolver::MapToGrid() {
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const double scale = solver_.mass_scale;
  std::fill(node_mass_.begin(), node_mass_.end(), 0.0);
  std::fill(node_velocity_.begin(), node_velocity_.end(), Vector2d::Zero());
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    const double mass = scale * mp.mass[p];
    const Vector2d momentum = mass * mp.velocity[p];
    for (int k = 0; k < s.count; ++k) {
      node_mass_[s.node[k]] += s.weight[k] * mass;
      node_velocity_[s.node[k]] += s.weight[k] * momentum;
    }
  }
  for (int i = 0; i < nodes; ++i) {
    node_velocity_[i] = Active(i) ? Vector2d(node_velocity_[i] / node_mass_[i]) : Vector2d::Zero();
  }
}

absl::Status ExplicitSolver::ComputeNodalForces() {
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const int nodes = NodeCount(grid_);
  const Vector2d body = BodyAcceleration();
  for (int i = 0; i < nodes; ++i) node_force_[i] = node_mass_[i] * body;
  const std::vector<Matrix2d> sigma = ForceStresses();
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    const Matrix2d sigma_v = sigma[p] * mp.volume[p];
    for (int k = 0; k < s.count; ++k) node_force_[s.node[k]] -= sigma_v * s.gradient[k];
  }
  return AddLoadForces();
}

void ExplicitSolver::IntegrateNodalVelocities() {
  const int nodes = NodeCount(grid_);
  for (int i = 0; i < nodes; ++i) {
    node_velocity_new_[i] =
        Active(i) ? Vector2d(node_velocity_[i] + (dt_ / node_mass_[i]) * node_force_[i])
                  : Vector2d::Zero();
  }
}

void ExplicitSolver::MapToPoints() {
  MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  const double alpha = solver_.pic_fraction;
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    Vector2d v_pic = Vector2d::Zero(), dv = Vector2d::Zero();
    for (int k = 0; k < s.count; ++k) {
      v_pic += s.weight[k] * node_velocity_new_[s.node[k]];
      dv += s.weight[k] * (node_velocity_new_[s.node[k]] - node_velocity_[s.node[k]]);
    }
    mp.position[p] = KeepOffWalls(mp.position[p], mp.position[p] + dt_ * v_pic);
    mp.velocity[p] = alpha * v_pic + (1.0 - alpha) * (mp.velocity[p] + dv);
  }
}

}  // namespace rvehub::mpm
