// The case's "rve" section: how the RVEs are driven.
#include <string>

#include "absl/status/status.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

Fields<RveSpec> RveFields() {
  // I above 0.1 is a dense flow, not a quasi-static RVE; more than 10^5 DEM
  // steps per increment is a mistake, not a setting.
  return {
      NumberField("max_inertial_number", &RveSpec::max_inertial_number, Need::kOptional,
                  Range{0.0, 0.1}),
      IntegerField("min_steps", &RveSpec::min_steps, 0, 100000),
      NumberField("max_stretch", &RveSpec::max_stretch, Need::kOptional, Range{0.0, 0.5}),
      FlagField("real_time", &RveSpec::real_time),
      FlagField("full_state_every_step", &RveSpec::full_state_every_step),
      NumberField("max_void_ratio", &RveSpec::max_void_ratio, Need::kOptional, Range{0.0, 10.0}),
  };
}

}  // namespace

absl::Status ParseRve(const Json& j, const std::string& ptr, RveSpec* rve) {
  RETURN_IF_ERROR(ReadFields(j, ptr, RveFields(), rve).status());
  // Below the densest 2-D disc packings (e ≈ 0.1) it would be no cap but a
  // different material.
  if (rve->max_void_ratio > 0.0 && rve->max_void_ratio < 0.1) {
    return Bad(ptr + "/max_void_ratio", "must be 0 (no cap) or in [0.1, 10], got ",
               Num(rve->max_void_ratio));
  }
  // A stretch of more than half in one MPM step is a broken continuum, not
  // an increment; below 0.01 nearly every flow would stop.
  if (rve->max_stretch > 0.0 && rve->max_stretch < 0.01) {
    return Bad(ptr + "/max_stretch", "must be 0 (the template's) or in [0.01, 0.5], got ",
               Num(rve->max_stretch));
  }
  return absl::OkStatus();
}

OrderedJson WriteRve(const RveSpec& rve) { return WriteFields(RveFields(), rve); }

}  // namespace rvehub::mpm::case_internal
