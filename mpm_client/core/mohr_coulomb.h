// An elastic–plastic Mohr–Coulomb material in plane strain, perfectly
// plastic or softening, for checks of the solver against plasticity's closed
// forms (Prandtl's N_c = 2 + π of a Tresca soil, φ = 0) and for soils that
// stand in for an RVE's peak and critical state: no RVEs behind it.
#ifndef RVEHUB_MPM_CLIENT_CORE_MOHR_COULOMB_H_
#define RVEHUB_MPM_CLIENT_CORE_MOHR_COULOMB_H_

#include <Eigen/Dense>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "mpm_client/core/solver.h"

namespace rvehub::mpm {

struct MohrCoulombParameters {
  double youngs = 0.0;     // E, Pa
  double poisson = 0.0;    // ν, [-]
  double friction = 0.0;   // φ, rad, in [0, π/2)
  double dilatancy = 0.0;  // ψ, rad, in [0, φ]: ψ = φ associated flow
  double cohesion = 0.0;   // c, Pa, ≥ 0
  // Strain softening: φ and ψ fall linearly with the accumulated plastic
  // multiplier κ (the plastic shear strain, [-]) from their peak values
  // above to φ_r and ψ_r, reached at κ = softening_strain, and stay there.
  // softening_strain 0: none (elastic–perfectly plastic).
  double residual_friction = 0.0;   // φ_r, rad, in [0, φ]
  double residual_dilatancy = 0.0;  // ψ_r, rad, in [0, min(ψ, φ_r)]
  double softening_strain = 0.0;    // κ_r, [-], ≥ 0
};

// φ and ψ (rad) at accumulated plastic strain κ.
double FrictionAt(const MohrCoulombParameters& material, double kappa);
double DilatancyAt(const MohrCoulombParameters& material, double kappa);

// One stress update (Pa, tension +): the rotation of ΔF applied to σ, then
// the elastic trial of ElasticStressUpdate, returned to the in-plane yield
// surface f = τ + s sin φ − c cos φ ≤ 0, where s = (σxx + σyy)/2 and
// τ = sqrt(((σxx − σyy)/2)² + σxy²) (Mohr's circle of the plane: the
// plane-strain criterion when σzz is the intermediate stress, as associated
// flow keeps it). The flow potential g = τ + s sin ψ: the plastic multiplier
// Δλ = f_trial / (G + (λ + G) sin φ sin ψ) takes G·Δλ off τ and
// (λ + G)·Δλ·sin ψ off s, σzz following the elastic part of the volume
// change. A trial beyond the apex (τ would turn negative) returns to it:
// σ = c cot φ in the plane (zero without cohesion). Exact for a single step
// of this piecewise-linear surface. φ and ψ are those at the point's
// accumulated plastic strain `kappa` at the step's start; Δλ is added to it.
Eigen::Matrix3d MohrCoulombStressUpdate(const Eigen::Matrix3d& stress,
                                        const Eigen::Matrix3d& delta_f,
                                        const MohrCoulombParameters& material, double& kappa);

class MohrCoulombModel : public StressModel {
 public:
  explicit MohrCoulombModel(const MohrCoulombParameters& material) : material_(material) {}

  // The stress of every point (Pa, tension +); zero if never set.
  void SetStress(std::vector<Eigen::Matrix3d> stress) { stress_ = std::move(stress); }
  const std::vector<Eigen::Matrix3d>& stress() const { return stress_; }
  // Each point's accumulated plastic strain κ, [-].
  const std::vector<double>& plastic_strain() const { return kappa_; }

  // InvalidArgument for E ≤ 0, ν outside (−1, 0.5), φ outside [0, π/2), ψ
  // outside [0, φ], c < 0, residual angles outside their ranges, a negative
  // softening strain, or a point count that differs from the stresses set;
  // the stresses and plastic strains are then left as they were.
  absl::Status Update(std::int64_t step, std::span<const Eigen::Matrix3d> delta_f,
                      std::span<PointResponse> out) override;

 private:
  MohrCoulombParameters material_;
  std::vector<Eigen::Matrix3d> stress_;
  std::vector<double> kappa_;
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CORE_MOHR_COULOMB_H_
