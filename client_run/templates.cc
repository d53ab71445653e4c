#include "client_run/templates.h"

#include <cmath>
#include <filesystem>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "rve_server/embedded/packings.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"

namespace rvehub::client_run {
namespace {

// The record of a template file: the one named `name`, or its only one.
absl::StatusOr<TemplateRecord> FromFile(const TemplateSpec& spec) {
  absl::StatusOr<std::vector<TemplateRecord>> records = store::ReadTemplates(spec.file);
  if (!records.ok()) {
    return absl::Status(records.status().code(),
                        absl::StrCat("template '", spec.name, "': ", records.status().message()));
  }
  if (spec.template_name.empty()) {
    if (records->size() != 1) {
      return absl::InvalidArgumentError(absl::StrCat("template '", spec.name, "': ", spec.file,
                                                     " holds ", records->size(),
                                                     " templates; name one with template_name"));
    }
    return std::move(records->front());
  }
  for (TemplateRecord& r : *records) {
    if (r.name == spec.template_name) return std::move(r);
  }
  return absl::NotFoundError(absl::StrCat("template '", spec.name, "': ", spec.file,
                                          " has no template named '", spec.template_name, "'"));
}

absl::StatusOr<TemplateRecord> Prepared(const TemplateSpec& spec, const std::string& cache_dir,
                                        const std::function<void(const std::string&)>& log,
                                        const std::string& created_by) {
  const dem::TemplateVariant variant{.pressure = spec.pressure,
                                     .void_ratio = spec.void_ratio,
                                     .num_particles = spec.particles,
                                     .rolling_eta = spec.rolling_eta};
  const std::string stem = dem::TemplateName(spec.parameter_set, spec.seed, variant);
  const std::string path = (std::filesystem::path(cache_dir) / (stem + ".h5")).string();
  // The cache only saves time: one that cannot be looked into or read is
  // prepared again (and overwritten where it can be) below.
  if (absl::StatusOr<bool> cached_file = PathExists(path); !cached_file.ok()) {
    if (log) log(absl::StrCat("template cache unusable (", cached_file.status().message(), ")"));
  } else if (*cached_file) {
    absl::StatusOr<std::vector<TemplateRecord>> cached = store::ReadTemplates(path);
    if (cached.ok() && cached->size() == 1) return std::move(cached->front());
    if (log) log(absl::StrCat("template cache ", path, " unusable, preparing again"));
  }
  if (log) log(absl::StrFormat("preparing template %s (%s)...", spec.name, spec.parameter_set));
  dem::PreparationReport report;
  // The first progress line ("N discs, seed S") is the one worth a log line.
  bool announced = false;
  absl::StatusOr<TemplateRecord> prepared = embedded::PrepareTemplate(
      spec.parameter_set, spec.seed, variant, &report, [&](const std::string& line) {
        if (log && !announced) log(absl::StrCat("  ", line));
        announced = true;
      });
  if (!prepared.ok()) {
    return absl::Status(prepared.status().code(), absl::StrCat("preparing template '", spec.name,
                                                               "': ", prepared.status().message()));
  }
  if (log) log(absl::StrFormat("  e0 = %.4f at p0 = %.0f Pa", report.void_ratio, report.pressure));
  TemplateRecord record = *std::move(prepared);
  std::error_code ec;
  std::filesystem::create_directories(cache_dir, ec);
  store::FileInfo info;
  info.created_by = created_by;
  // The cache only saves time: a failure to write it is not an error.
  if (absl::Status s =
          store::WriteTemplates(path, std::span<const TemplateRecord>(&record, 1), info);
      !s.ok() && log) {
    log(absl::StrCat("could not cache the template: ", s.message()));
  }
  return record;
}

}  // namespace

absl::StatusOr<std::vector<TemplateRecord>> ResolveTemplates(
    const std::vector<TemplateSpec>& specs, const std::string& cache_dir,
    const std::function<void(const std::string&)>& log, const std::string& created_by) {
  std::vector<TemplateRecord> out;
  out.reserve(specs.size());
  for (const TemplateSpec& spec : specs) {
    ASSIGN_OR_RETURN(TemplateRecord r, spec.file.empty()
                                           ? Prepared(spec, cache_dir, log, created_by)
                                           : FromFile(spec));
    r.name = spec.name;
    out.push_back(std::move(r));
  }
  return out;
}

std::string TemplateCacheDir(const std::string& cache_dir, const std::string& out_dir) {
  return cache_dir.empty() ? out_dir + "/templates" : cache_dir;
}

double BulkDensity(const dem::RveSnapshot& packing) {
  const double cell_area = std::abs(packing.cell.determinant());  // m²
  return packing.material.density * dem::SolidArea(packing.radius) / cell_area;
}

}  // namespace rvehub::client_run
