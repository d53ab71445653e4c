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
#include "rve_server/values/element_test.h"

namespace rvehub::dem {

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
absl::StatusOr<std::vector<ElementTestRow>> RunElementTest(
    Rve& rve, const ElementTestSpec& spec, const std::function<void(double)>& progress = {},
    const Interrupt& interrupt = {});

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_ELEMENT_TEST_H_
