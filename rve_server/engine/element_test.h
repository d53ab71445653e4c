// Element tests on one RVE under mixed stress/strain control of its cell.
// Results use the geomechanics convention: compression positive, Pa; strains
// positive in compression.
#ifndef RVEHUB_RVE_SERVER_ENGINE_ELEMENT_TEST_H_
#define RVEHUB_RVE_SERVER_ENGINE_ELEMENT_TEST_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "rve_server/engine/rve.h"

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

// Consolidates to spec.confining, then runs the test. `progress` receives
// the fraction done in [0, 1]. `interrupt` (optional) is asked between DEM
// steps; its status ends the test. Ranges: confining (0, 1e9] Pa,
// max_strain (0, 0.5) (shear tests (0, 10)) and at least one DEM step's
// strain at the test's rate, inertial_number [1e-6, 0.1], rows [2, 1e6],
// cycles [1, 1e4], axis 0 or 1 (biaxial and oedometer only; the others
// refuse axis 0): InvalidArgument, before the RVE changes. A test that
// would take more than kMaxElementTestSteps DEM steps is refused up front,
// before the RVE changes (monotonic), or stopped there (cyclic) with
// ResourceExhausted.
inline constexpr std::int64_t kMaxElementTestSteps = 1'000'000'000;
inline constexpr std::int64_t kMaxElementTestRows = 2'000'000;  // rows recorded at most
absl::StatusOr<std::vector<ElementTestRow>> RunElementTest(
    Rve& rve, const ElementTestSpec& spec, const std::function<void(double)>& progress = {},
    const Interrupt& interrupt = {});

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_ELEMENT_TEST_H_
