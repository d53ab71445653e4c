// The homogenised state of an RVE, what every increment returns: Cauchy
// stress, fabric, void ratio, permeability, coordination and, when asked for,
// the contact tangent. Also the in-plane stress invariants, defined once here.
#ifndef RVEHUB_RVE_SERVER_VALUES_STATE_H_
#define RVEHUB_RVE_SERVER_VALUES_STATE_H_

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <optional>

namespace rvehub::dem {

// Homogenised state of an RVE. Tensors are 3×3 (plane strain): the 2-D RVE
// carries no out-of-plane stress, so σzz = σxz = σyz = 0.
// In-plane invariants of a Cauchy stress (tension +; shared/reference):
// p = −tr σ/2 (Pa, compression +) and q = sqrt(½ s:s) = sqrt(¼(σxx − σyy)² + σxy²) (Pa).
inline double InPlaneMeanPressure(const Eigen::Matrix3d& stress) {
  return -0.5 * (stress(0, 0) + stress(1, 1));
}
inline double InPlaneDeviatorStress(const Eigen::Matrix3d& stress) {
  const double d = stress(0, 0) - stress(1, 1);
  return std::sqrt(0.25 * d * d + stress(0, 1) * stress(0, 1));
}

struct RveState {
  Eigen::Matrix3d stress = Eigen::Matrix3d::Zero();  // Love–Weber Cauchy σ, Pa, tension +
  Eigen::Matrix3d fabric = Eigen::Matrix3d::Zero();  // φ = (1/Nc)Σ n⊗n, [-]
  Eigen::Matrix3d fabric_anisotropy_tensor = Eigen::Matrix3d::Zero();  // 4(φ − I/2), [-]
  double fabric_anisotropy = 0.0;                                      // Fa = sqrt(½ Fa:Fa), [-]
  bool fabric_defined = false;           // false when the RVE has no contacts
  double void_ratio = 0.0;               // e = (A_cell − A_solid)/A_solid, 2-D areas, [-]
  double porosity = 0.0;                 // n = e/(1+e), [-]
  double coordination = 0.0;             // Z = 2·Nc/N, [-]
  double mechanical_coordination = 0.0;  // without rattlers (< 2 contacts), [-]
  double permeability = 0.0;             // k = c·e³/(1+e), m/s
  double mean_rotation = 0.0;            // mean particle rotation since creation, rad (ccw +)
  double kinetic_energy = 0.0;           // J (translational fluctuation + rotational)
  double unbalanced_force_ratio = 0.0;   // mean |Σ F on particle| / mean |contact force|
  std::int64_t num_contacts = 0;
  double volume = 0.0;  // V = A·t, m³
  // Of the call that produced this state:
  std::int64_t steps = 0;         // DEM steps used
  double time_step = 0.0;         // s
  double mass_scale = 1.0;        // density scaling used
  double MeanPressure() const;    // p of `stress`, see InPlaneMeanPressure
  double DeviatorStress() const;  // q of `stress`, see InPlaneDeviatorStress
  // Elastic tangent from contacts, D_ijkl = (1/V)Σ(kn n_i d_j n_k d_l + kt t_i d_j t_k d_l),
  // Pa, stored as D(3i+j, 3k+l). Set only when asked for: most states are
  // copied several times per increment and never need its 648 bytes.
  std::optional<Eigen::Matrix<double, 9, 9>> tangent;
};

inline double RveState::MeanPressure() const { return InPlaneMeanPressure(stress); }
inline double RveState::DeviatorStress() const { return InPlaneDeviatorStress(stress); }

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_VALUES_STATE_H_
