// RveSnapshot templates of a case (any continuum client's): read from
// template files, or prepared in code from a named parameter set and seed and
// cached as template files (so a second run, or another case on the same
// material, does not prepare again).
#ifndef RVEHUB_CLIENT_RUN_TEMPLATES_H_
#define RVEHUB_CLIENT_RUN_TEMPLATES_H_

#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "client_case/spec/rve_spec.h"
#include "rve_server/values/record.h"

namespace rvehub::client_run {

using client_case::TemplateSpec;

// One record per spec, in order, each named after its TemplateSpec::name.
// `cache_dir` holds prepared templates as "<parameter_set>-seed<N>.h5",
// with "-p<P>Pa", "-e<E>" and "-<N>discs" where the spec sets pressure,
// void_ratio or particles (created when missing). `log` receives one line per preparation.
// `created_by` names the program in the cache files it writes.
absl::StatusOr<std::vector<TemplateRecord>> ResolveTemplates(
    const std::vector<TemplateSpec>& specs, const std::string& cache_dir,
    const std::function<void(const std::string&)>& log = {},
    const std::string& created_by = "rvehub");

// Where a run caches prepared templates: `cache_dir` (--template-cache), else
// <out_dir>/templates.
std::string TemplateCacheDir(const std::string& cache_dir, const std::string& out_dir);

// Dry bulk density of a packing's material, kg/m³: ρ_s·A_solid/A_cell,
// i.e. ρ_s/(1 + e) with e the 2-D void ratio.
double BulkDensity(const dem::RveSnapshot& packing);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_TEMPLATES_H_
