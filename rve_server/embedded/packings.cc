#include "rve_server/embedded/packings.h"

#include <cmath>
#include <utility>

#include "rve_server/common/status_macros.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"

namespace rvehub::embedded {

absl::StatusOr<TemplateRecord> PrepareTemplate(
    absl::string_view parameter_set, std::uint64_t seed, const dem::TemplateVariant& variant,
    dem::PreparationReport* report, const std::function<void(const std::string&)>& progress) {
  dem::PreparationReport r;
  ASSIGN_OR_RETURN(dem::RveSnapshot packing,
                   dem::PrepareTemplate(parameter_set, seed, variant, &r, progress));
  TemplateRecord record;
  record.name = dem::TemplateName(parameter_set, seed, variant);
  record.description =
      dem::TemplateDescription(parameter_set, seed, packing.radius.size(), r, variant);
  record.packing = std::move(packing);
  if (report != nullptr) *report = r;
  return record;
}

absl::StatusOr<dem::RveState> Observe(const dem::RveSnapshot& packing, bool want_tangent) {
  ASSIGN_OR_RETURN(dem::Rve rve, dem::Rve::Create(packing));
  return rve.Observe(want_tangent);
}

absl::StatusOr<PackingForces> ContactForces(const dem::RveSnapshot& packing) {
  ASSIGN_OR_RETURN(dem::Rve rve, dem::Rve::Create(packing));
  PackingForces out;
  out.cell = packing.cell;
  for (std::size_t k = 0; k < packing.radius.size(); ++k) {
    const Eigen::Vector2d s(packing.sx[k] - std::floor(packing.sx[k]),
                            packing.sy[k] - std::floor(packing.sy[k]));
    out.position.push_back(packing.cell * s);
    out.radius.push_back(packing.radius[k]);
  }
  for (const dem::ContactForce& c : rve.Contacts()) {
    out.contacts.push_back({c.i, c.j, c.branch, c.normal_force, c.tangential_force});
  }
  return out;
}

absl::StatusOr<std::vector<dem::ElementTestRow>> RunElementTest(
    dem::RveSnapshot packing, const dem::ElementTestSpec& spec,
    const std::function<void(double)>& progress) {
  ASSIGN_OR_RETURN(dem::Rve rve, dem::Rve::Create(std::move(packing)));
  return dem::RunElementTest(rve, spec, progress);
}

}  // namespace rvehub::embedded
