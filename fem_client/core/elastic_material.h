// Stand-in materials for tests and checks of the solver: no RVEs behind
// them. Both are objective (a rigid rotation R of a step rotates the
// committed stress to R σ Rᵀ and strains nothing).
#ifndef RVEHUB_FEM_CLIENT_CORE_ELASTIC_MATERIAL_H_
#define RVEHUB_FEM_CLIENT_CORE_ELASTIC_MATERIAL_H_

#include <Eigen/Dense>
#include <memory>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/material.h"
#include "rve_server/common/elasticity.h"

namespace rvehub::fem {

using ::rvehub::LameLambda;
using ::rvehub::PolarRotation;
using ::rvehub::ShearModulus;

// C_ijkl = λ δ_ij δ_kl + G (δ_ik δ_jl + δ_il δ_jk), Pa: isotropic, with the
// minor symmetries.
Tangent IsotropicTangent(double lambda, double shear);

// σ = R σ_n Rᵀ + C : (V − I), Pa: ΔF = V·R (polar, in-plane), the
// increment's strain measured by its left stretch V so that a rigid
// rotation strains nothing; plane strain (ε_zz = 0).
Eigen::Matrix3d LinearElasticStress(const Eigen::Matrix3d& committed,
                                    const Eigen::Matrix3d& delta_f, double lambda, double shear);

// Linear elastic plane strain (E, ν) rotating its committed stress
// objectively. Its tangent is C, exact for small increments (at ΔF = I
// with no prestress).
class LinearElasticMaterial : public GaussPointMaterial {
 public:
  // One point per initial stress (Pa, tension +). InvalidArgument unless
  // E > 0 and −1 < ν < 0.5 and the stresses are finite.
  static absl::StatusOr<std::unique_ptr<LinearElasticMaterial>> Create(
      double youngs, double poisson, std::vector<Eigen::Matrix3d> initial_stress);

  // InvalidArgument when delta_f's size is not the number of points;
  // PointFailure(InvalidArgument) for a ΔF with det ≤ 0 or not finite.
  absl::StatusOr<std::vector<PointResponse>> Trial(std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent) override;
  absl::Status Commit(std::span<const Eigen::Matrix3d> delta_f) override;

  std::span<const Eigen::Matrix3d> stress() const { return stress_; }  // committed

 private:
  LinearElasticMaterial(double lambda, double shear, std::vector<Eigen::Matrix3d> stress)
      : lambda_(lambda), shear_(shear), stress_(std::move(stress)) {}
  double lambda_, shear_;
  std::vector<Eigen::Matrix3d> stress_;
};

// A nonlinear elastic stand-in whose bulk modulus grows under compression,
// K(e) = K0·exp(−α e) with e the volumetric strain (tension +), shear
// modulus G constant. Each step is hyperelastic from the committed state:
// with E = ½(ΔFᵀΔF − I) (Green–Lagrange of the step) and the second
// Piola–Kirchhoff stress on the step's start T = σ_n + S,
//   S = [s(e_n + tr E) − s(e_n)] I + 2G dev E,  s(e) = (K0/α)(1 − exp(−α e)),
//   σ = ΔF T ΔFᵀ / det ΔF,
// and e_{n+1} = e_n + tr E. A polynomial in ΔF but for s, so its exact
// tangent ∂σ/∂ΔF (no minor symmetry) is cheap: the stand-in that shows
// Newton's quadratic convergence.
struct StiffeningState {
  Eigen::Matrix3d stress = Eigen::Matrix3d::Zero();  // Cauchy, Pa
  double volumetric = 0.0;                           // e, [-]
};
struct StiffeningParameters {
  double bulk = 0.0;   // K0, Pa
  double shear = 0.0;  // G, Pa
  double alpha = 0.0;  // α, [-] (0: linear)
};
// The stress after ΔF and, when `tangent` is not null, ∂σ_ij/∂ΔF_kl for
// the in-plane kl (the other columns zero). The state's new e is
// committed.volumetric + tr E (volumetric, optional).
Eigen::Matrix3d StiffeningStress(const StiffeningParameters& p, const StiffeningState& committed,
                                 const Eigen::Matrix3d& delta_f, Tangent* tangent = nullptr,
                                 double* volumetric = nullptr);

class StiffeningElasticMaterial : public GaussPointMaterial {
 public:
  // One point per initial stress (Pa, e = 0). InvalidArgument unless
  // K0 > 0, G > 0, α ≥ 0 are finite and the stresses finite.
  static absl::StatusOr<std::unique_ptr<StiffeningElasticMaterial>> Create(
      const StiffeningParameters& parameters, std::vector<Eigen::Matrix3d> initial_stress);

  // As LinearElasticMaterial's; also PointFailure(OutOfRange) when the
  // stress is not finite (K overflows under extreme compression).
  absl::StatusOr<std::vector<PointResponse>> Trial(std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent) override;
  absl::Status Commit(std::span<const Eigen::Matrix3d> delta_f) override;

  std::span<const StiffeningState> state() const { return state_; }  // committed

 private:
  StiffeningElasticMaterial(const StiffeningParameters& p, std::vector<StiffeningState> state)
      : parameters_(p), state_(std::move(state)) {}
  StiffeningParameters parameters_;
  std::vector<StiffeningState> state_;
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_ELASTIC_MATERIAL_H_
