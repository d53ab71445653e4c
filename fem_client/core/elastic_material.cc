#include "fem_client/core/elastic_material.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace rvehub::fem {
namespace {

// What both stand-ins take: one ΔF per point, finite, with det > 0.
absl::Status CheckIncrements(std::span<const Eigen::Matrix3d> delta_f, std::size_t points) {
  if (delta_f.size() != points) {
    return absl::InvalidArgumentError(
        absl::StrCat("the material has ", points, " points, the call gives ", delta_f.size()));
  }
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    if (!delta_f[p].allFinite() || !(delta_f[p].topLeftCorner<2, 2>().determinant() > 0.0)) {
      return PointFailure(absl::InvalidArgumentError(
                              absl::StrCat("ΔF of point ", p, " is not finite or has det ΔF ≤ 0")),
                          static_cast<int>(p));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckStresses(std::span<const Eigen::Matrix3d> stress) {
  for (std::size_t p = 0; p < stress.size(); ++p) {
    if (!stress[p].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("initial stress ", p, " is not finite"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

Tangent IsotropicTangent(double lambda, double shear) {
  Tangent c = Tangent::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int k = 0; k < 3; ++k) {
        for (int l = 0; l < 3; ++l) {
          c(TangentIndex(i, j), TangentIndex(k, l)) =
              lambda * (i == j) * (k == l) + shear * ((i == k) * (j == l) + (i == l) * (j == k));
        }
      }
    }
  }
  return c;
}

Eigen::Matrix3d LinearElasticStress(const Eigen::Matrix3d& committed,
                                    const Eigen::Matrix3d& delta_f, double lambda, double shear) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r.topLeftCorner<2, 2>() = PolarRotation(delta_f.topLeftCorner<2, 2>());
  // V = ΔF Rᵀ; V − I is zero for a rigid rotation, whatever its angle.
  Eigen::Matrix3d strain = delta_f * r.transpose() - Eigen::Matrix3d::Identity();
  strain = 0.5 * (strain + strain.transpose());  // symmetric already, to round-off
  return r * committed * r.transpose() + lambda * strain.trace() * Eigen::Matrix3d::Identity() +
         2.0 * shear * strain;
}

absl::StatusOr<std::unique_ptr<LinearElasticMaterial>> LinearElasticMaterial::Create(
    double youngs, double poisson, std::vector<Eigen::Matrix3d> initial_stress) {
  if (!(youngs > 0.0 && std::isfinite(youngs)) || !(poisson > -1.0 && poisson < 0.5)) {
    return absl::InvalidArgumentError(absl::StrCat("linear elastic: E = ", youngs,
                                                   " Pa, nu = ", poisson,
                                                   ": E must be positive and nu in (-1, 0.5)"));
  }
  if (absl::Status s = CheckStresses(initial_stress); !s.ok()) return s;
  return std::unique_ptr<LinearElasticMaterial>(new LinearElasticMaterial(
      LameLambda(youngs, poisson), ShearModulus(youngs, poisson), std::move(initial_stress)));
}

absl::StatusOr<std::vector<PointResponse>> LinearElasticMaterial::Trial(
    std::span<const Eigen::Matrix3d> delta_f, bool want_tangent) {
  if (absl::Status s = CheckIncrements(delta_f, stress_.size()); !s.ok()) return s;
  std::vector<PointResponse> out(delta_f.size());
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    out[p].stress = LinearElasticStress(stress_[p], delta_f[p], lambda_, shear_);
    if (want_tangent) out[p].tangent = IsotropicTangent(lambda_, shear_);
  }
  return out;
}

absl::Status LinearElasticMaterial::Commit(std::span<const Eigen::Matrix3d> delta_f) {
  if (absl::Status s = CheckIncrements(delta_f, stress_.size()); !s.ok()) return s;
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    stress_[p] = LinearElasticStress(stress_[p], delta_f[p], lambda_, shear_);
  }
  return absl::OkStatus();
}

Eigen::Matrix3d StiffeningStress(const StiffeningParameters& p, const StiffeningState& committed,
                                 const Eigen::Matrix3d& delta_f, Tangent* tangent,
                                 double* volumetric) {
  const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d& f = delta_f;
  // s(e) and s'(e) = K(e); expm1 keeps s accurate for small α e.
  const auto s = [&p](double e) {
    return p.alpha == 0.0 ? p.bulk * e : -p.bulk / p.alpha * std::expm1(-p.alpha * e);
  };
  const auto dev = [&identity](const Eigen::Matrix3d& a) {
    return Eigen::Matrix3d(a - a.trace() / 3.0 * identity);
  };
  const Eigen::Matrix3d green = 0.5 * (f.transpose() * f - identity);
  const double e = committed.volumetric + green.trace();
  const Eigen::Matrix3d t =
      committed.stress + (s(e) - s(committed.volumetric)) * identity + 2.0 * p.shear * dev(green);
  const double j = f.determinant();
  const Eigen::Matrix3d sigma = f * t * f.transpose() / j;
  if (volumetric != nullptr) *volumetric = e;
  if (tangent != nullptr) {
    tangent->setZero();
    const Eigen::Matrix3d f_inv = f.inverse();
    const double bulk = p.bulk * std::exp(-p.alpha * e);  // s'(e)
    for (int k = 0; k < 2; ++k) {
      for (int l = 0; l < 2; ++l) {
        // dΔF = e_k ⊗ e_l: dE = sym(ΔFᵀ dΔF), d(det ΔF)/det ΔF = tr(ΔF⁻¹ dΔF).
        Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
        a(k, l) = 1.0;
        const Eigen::Matrix3d d_green = 0.5 * (a.transpose() * f + f.transpose() * a);
        const Eigen::Matrix3d d_t =
            bulk * d_green.trace() * identity + 2.0 * p.shear * dev(d_green);
        const Eigen::Matrix3d d_sigma =
            (a * t * f.transpose() + f * t * a.transpose() + f * d_t * f.transpose()) / j -
            sigma * f_inv(l, k);
        for (int i = 0; i < 3; ++i) {
          for (int m = 0; m < 3; ++m)
            (*tangent)(TangentIndex(i, m), TangentIndex(k, l)) = d_sigma(i, m);
        }
      }
    }
  }
  return sigma;
}

absl::StatusOr<std::unique_ptr<StiffeningElasticMaterial>> StiffeningElasticMaterial::Create(
    const StiffeningParameters& parameters, std::vector<Eigen::Matrix3d> initial_stress) {
  const StiffeningParameters& q = parameters;
  if (!(q.bulk > 0.0 && std::isfinite(q.bulk)) || !(q.shear > 0.0 && std::isfinite(q.shear)) ||
      !(q.alpha >= 0.0 && std::isfinite(q.alpha))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "stiffening elastic: K0 = ", q.bulk, " Pa, G = ", q.shear, " Pa, alpha = ", q.alpha,
        ": K0 and G must be positive, alpha non-negative, all finite"));
  }
  if (absl::Status s = CheckStresses(initial_stress); !s.ok()) return s;
  std::vector<StiffeningState> state(initial_stress.size());
  for (std::size_t p = 0; p < state.size(); ++p) state[p].stress = initial_stress[p];
  return std::unique_ptr<StiffeningElasticMaterial>(
      new StiffeningElasticMaterial(parameters, std::move(state)));
}

absl::StatusOr<std::vector<PointResponse>> StiffeningElasticMaterial::Trial(
    std::span<const Eigen::Matrix3d> delta_f, bool want_tangent) {
  if (absl::Status s = CheckIncrements(delta_f, state_.size()); !s.ok()) return s;
  std::vector<PointResponse> out(delta_f.size());
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    Tangent d;
    out[p].stress =
        StiffeningStress(parameters_, state_[p], delta_f[p], want_tangent ? &d : nullptr);
    if (!out[p].stress.allFinite() || (want_tangent && !d.allFinite())) {
      return PointFailure(absl::OutOfRangeError(absl::StrCat(
                              "stiffening elastic: the stress of point ", p, " is not finite")),
                          static_cast<int>(p));
    }
    if (want_tangent) out[p].tangent = d;
  }
  return out;
}

absl::Status StiffeningElasticMaterial::Commit(std::span<const Eigen::Matrix3d> delta_f) {
  absl::StatusOr<std::vector<PointResponse>> trial = Trial(delta_f, false);
  if (!trial.ok()) return trial.status();
  for (std::size_t p = 0; p < delta_f.size(); ++p) {
    double e = 0.0;
    state_[p].stress = StiffeningStress(parameters_, state_[p], delta_f[p], nullptr, &e);
    state_[p].volumetric = e;
  }
  return absl::OkStatus();
}

}  // namespace rvehub::fem
