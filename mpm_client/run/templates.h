// RveSnapshot templates of a case: read from template files, or prepared in code
// from a named parameter set and seed and cached as template files (so a
// second run, or another case on the same material, does not prepare again).
#ifndef RVEHUB_MPM_CLIENT_RUN_TEMPLATES_H_
#define RVEHUB_MPM_CLIENT_RUN_TEMPLATES_H_

#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "mpm_client/core/model.h"
#include "rve_server/values/record.h"

namespace rvehub::mpm {

// One record per spec, in order, each named after its TemplateSpec::name.
// `cache_dir` holds prepared templates as "<parameter_set>-seed<N>.h5",
// with "-p<P>Pa", "-e<E>" and "-<N>discs" where the spec sets pressure,
// void_ratio or particles (created when missing). `log` receives one line per preparation.
absl::StatusOr<std::vector<TemplateRecord>> ResolveTemplates(
    const std::vector<TemplateSpec>& specs, const std::string& cache_dir,
    const std::function<void(const std::string&)>& log = {});

// Dry bulk density of a packing's material, kg/m³: ρ_s·A_solid/A_cell,
// i.e. ρ_s/(1 + e) with e the 2-D void ratio.
double BulkDensity(const dem::RveSnapshot& packing);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_RUN_TEMPLATES_H_
