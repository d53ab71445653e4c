// Work on single packings in a client's own process, offered in values so
// that clients need not know the engine: preparing a template from a named
// parameter set (rve_cli prepare, mpm_client's and fem_client's case
// templates), observing a packing's state, and an element test on a local
// RVE (rve_cli element-test without --server).
#ifndef RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_
#define RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "rve_server/values/element_test.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/record.h"
#include "rve_server/values/state.h"

namespace rvehub::embedded {

// The one way to make a template from a named parameter set and a seed:
// the engine's PrepareTemplate (engine/prepare.h: its errors and ranges),
// named by TemplateName and described by TemplateDescription
// (values/preparation.h). `report`, when given, receives the preparation's
// report; `progress` its lines, the first "N discs, seed S".
absl::StatusOr<TemplateRecord> PrepareTemplate(
    absl::string_view parameter_set, std::uint64_t seed, const dem::TemplateVariant& variant = {},
    dem::PreparationReport* report = nullptr,
    const std::function<void(const std::string&)>& progress = {});

// The homogenised state of a packing as it is (the tangent when asked).
// InvalidArgument for a packing the engine refuses (ValidatePacking).
absl::StatusOr<dem::RveState> Observe(const dem::RveSnapshot& packing, bool want_tangent);

// Runs `spec` on an RVE made from `packing` (engine/element_test.h: the
// ranges, the consolidation first, the rows). `progress` sees the fraction
// done, 0..1.
absl::StatusOr<std::vector<dem::ElementTestRow>> RunElementTest(
    dem::RveSnapshot packing, const dem::ElementTestSpec& spec,
    const std::function<void(double)>& progress = {});

}  // namespace rvehub::embedded

#endif  // RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_
