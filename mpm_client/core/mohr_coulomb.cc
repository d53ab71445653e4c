#include "mpm_client/core/mohr_coulomb.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "mpm_client/core/elastic.h"

namespace rvehub::mpm {

namespace {

// The share of the way from peak to residual at plastic strain κ, [0, 1].
double Softened(const MohrCoulombParameters& m, double kappa) {
  return m.softening_strain > 0.0 ? std::min(1.0, kappa / m.softening_strain) : 0.0;
}

}  // namespace

double FrictionAt(const MohrCoulombParameters& m, double kappa) {
  return m.friction + (m.residual_friction - m.friction) * Softened(m, kappa);
}

double DilatancyAt(const MohrCoulombParameters& m, double kappa) {
  return m.dilatancy + (m.residual_dilatancy - m.dilatancy) * Softened(m, kappa);
}

Eigen::Matrix3d MohrCoulombStressUpdate(const Eigen::Matrix3d& stress,
                                        const Eigen::Matrix3d& delta_f,
                                        const MohrCoulombParameters& material, double& kappa) {
  const double lambda = LameLambda(material.youngs, material.poisson);
  const double shear = ShearModulus(material.youngs, material.poisson);
  Eigen::Matrix3d trial = ElasticStressUpdate(stress, delta_f, lambda, shear);
  const double s = 0.5 * (trial(0, 0) + trial(1, 1));                // Pa, tension +
  const double half_difference = 0.5 * (trial(0, 0) - trial(1, 1));  // Pa
  const double tau = std::hypot(half_difference, trial(0, 1));       // Pa
  const double phi = FrictionAt(material, kappa), psi = DilatancyAt(material, kappa);
  const double sin_phi = std::sin(phi), sin_psi = std::sin(psi);
  const double f = tau + s * sin_phi - material.cohesion * std::cos(phi);
  if (f <= 0.0) return trial;
  const double bulk_2d = lambda + shear;  // Δs = (λ + G)·Δεv in plane strain
  double multiplier = f / (shear + bulk_2d * sin_phi * sin_psi);  // Δλ, [-]
  double new_tau = tau - shear * multiplier;
  double new_s = s - bulk_2d * multiplier * sin_psi;
  if (new_tau < 0.0) {
    // Beyond the apex: the cone's tip, s = c cot φ (c cos φ / sin φ), with the
    // volume change that leaves the plane's mean stress there.
    new_tau = 0.0;
    new_s = sin_phi > 0.0 ? material.cohesion * std::cos(phi) / sin_phi : s;
    multiplier = sin_psi > 0.0 ? (s - new_s) / (bulk_2d * sin_psi) : 0.0;
  }
  const double scale = tau > 0.0 ? new_tau / tau : 0.0;
  Eigen::Matrix3d out = trial;
  out(0, 0) = new_s + scale * half_difference;
  out(1, 1) = new_s - scale * half_difference;
  out(0, 1) = out(1, 0) = scale * trial(0, 1);
  // σzz: only the elastic part of the volume change, Δεv^p = Δλ sin ψ.
  out(2, 2) = trial(2, 2) - lambda * multiplier * sin_psi;
  kappa += multiplier;
  return out;
}

absl::Status MohrCoulombModel::Update(std::int64_t /*step*/,
                                      std::span<const Eigen::Matrix3d> delta_f,
                                      std::span<PointResponse> out) {
  const MohrCoulombParameters& m = material_;
  if (!(m.youngs > 0.0) || !(m.poisson > -1.0 && m.poisson < 0.5) ||
      !(m.friction >= 0.0 && m.friction < 0.5 * std::numbers::pi) ||
      !(m.dilatancy >= 0.0 && m.dilatancy <= m.friction) || !(m.cohesion >= 0.0) ||
      !(m.softening_strain >= 0.0) ||
      (m.softening_strain > 0.0 &&
       (!(m.residual_friction >= 0.0 && m.residual_friction <= m.friction) ||
        !(m.residual_dilatancy >= 0.0 && m.residual_dilatancy <= m.dilatancy &&
          m.residual_dilatancy <= m.residual_friction)))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Mohr-Coulomb model: E = ", m.youngs, ", nu = ", m.poisson, ", phi = ", m.friction,
        ", psi = ", m.dilatancy, ", c = ", m.cohesion, ", phi_r = ", m.residual_friction,
        ", psi_r = ", m.residual_dilatancy, ", kappa_r = ", m.softening_strain, " are invalid"));
  }
  // Refused before anything changes: a wrong count leaves stress and κ as they were.
  if ((!stress_.empty() && stress_.size() != delta_f.size()) || out.size() != delta_f.size()) {
    return absl::InvalidArgumentError(absl::StrCat("Mohr-Coulomb model has ", stress_.size(),
                                                   " points, update has ", delta_f.size()));
  }
  if (stress_.empty()) stress_.assign(delta_f.size(), Eigen::Matrix3d::Zero());
  if (kappa_.size() != stress_.size()) kappa_.assign(stress_.size(), 0.0);
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    stress_[p] = MohrCoulombStressUpdate(stress_[p], delta_f[p], m, kappa_[p]);
    out[p] = PointResponse();
    out[p].stress = stress_[p];
  }
  return absl::OkStatus();
}

}  // namespace rvehub::mpm
