// Element tests as values: which test, its loading and the rows it records,
// in the geomechanics convention (compression positive, Pa; strains positive
// in compression). The engine runs them (engine/element_test.h); the wire,
// the server and the clients pass them on.
#ifndef RVEHUB_RVE_SERVER_VALUES_ELEMENT_TEST_H_
#define RVEHUB_RVE_SERVER_VALUES_ELEMENT_TEST_H_

#include <cstdint>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub::dem {

enum class ElementTestKind {
  kDrainedBiaxial,        // σxx held at the confining stress, εyy strain-controlled
                          // (or σyy held and εxx controlled: ElementTestSpec::axis)
  kIsotropic,             // εxx = εyy strain-controlled compression
  kOedometer,             // εyy strain-controlled, εxx = 0 (or x and y swapped)
  kUndrainedSimpleShear,  // constant volume, γ = F_xy strain-controlled
  kCyclicSimpleShear,     // constant volume, γ reversed at ± an amplitude
};
enum class CyclicControl { kStrain, kStress };

struct ElementTestSpec {
  ElementTestKind kind = ElementTestKind::kDrainedBiaxial;
  double confining = 100e3;       // Pa (compression +): consolidation and lateral stress
  double max_strain = 0.1;        // axial (biaxial, oedometer), volumetric (isotropic) or γ
  double inertial_number = 1e-3;  // shearing rate from I = γ̇ d sqrt(ρ/p), [-]
  int rows = 400;                 // rows recorded over max_strain (monotonic tests)
  // Loading axis of the biaxial and oedometer tests: 1 = y (the usual
  // vertical), 0 = x (σyy then held in the biaxial test). A small packing's
  // strength depends on the direction it is loaded in (its fabric); the
  // rows' axial strain is along this axis, the stress columns stay xx, yy.
  int axis = 1;
  // Cyclic simple shear:
  CyclicControl cyclic_control = CyclicControl::kStrain;
  double amplitude = 0.005;  // γ amplitude, or τ = σxy amplitude in Pa
  int cycles = 5;
};

struct ElementTestRow {
  std::int64_t step = 0;
  // Soil mechanics' signs, compression positive, which the names carry
  // (_comp): the engine's stress is tension-positive (σ_comp = −σ).
  // 1 − F_aa along the test's axis a (F_yy by default), 1 − det F, [-]
  double axial_strain_comp = 0, vol_strain_comp = 0;
  double sxx_comp = 0, syy_comp = 0, sxy_comp = 0;  // Pa
  double p_comp = 0;                                // Pa, −tr σ/2
  double q = 0;                                     // Pa, sqrt(½ s:s), sign-free
  double void_ratio = 0, coordination = 0;
  double fabric_xx = 0, fabric_yy = 0, fabric_xy = 0, fabric_anisotropy = 0;
  double permeability = 0;  // m/s
  double shear_strain = 0;  // γ = F_xy
};

absl::StatusOr<ElementTestKind> ParseElementTestKind(absl::string_view name);

// Whether a test loads one axis (ElementTestSpec::axis applies): the drained
// biaxial and oedometer tests.
bool HasLoadingAxis(ElementTestKind kind);

// Bounds on one test's work and output (see RunElementTest).
inline constexpr std::int64_t kMaxElementTestSteps = 1'000'000'000;
inline constexpr std::int64_t kMaxElementTestRows = 2'000'000;  // rows recorded at most

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_VALUES_ELEMENT_TEST_H_
