// The "rve" section: how the RVEs are driven.
#include <string>

#include "absl/status/status.h"
#include "client_case/sections.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/values/snapshot.h"
#include "toolkit/field_table.h"

namespace rvehub::client_case {
namespace {

using fields::Bad;
using fields::Fields;
using fields::FlagField;
using fields::IntegerField;
using fields::Json;
using fields::Need;
using fields::Num;
using fields::NumberField;
using fields::OrderedJson;
using fields::Range;
using fields::ReadFields;
using fields::WriteFields;

Fields<RveSpec> RveFields(const RveKeys& keys) {
  // I above 0.1 is a dense flow, not a quasi-static RVE; more than 10^5 DEM
  // steps per increment is a mistake, not a setting.
  Fields<RveSpec> fields = {
      NumberField("max_inertial_number", &RveSpec::max_inertial_number, Need::kOptional,
                  Range{0.0, 0.1}),
      IntegerField("min_steps", &RveSpec::min_steps, 0, 100000),
      NumberField("max_stretch", &RveSpec::max_stretch, Need::kOptional, Range{0.0, 0.5}),
  };
  if (keys.real_time) fields.push_back(FlagField("real_time", &RveSpec::real_time));
  fields.push_back(FlagField("full_state_every_step", &RveSpec::full_state_every_step));
  if (keys.max_void_ratio) {
    fields.push_back(
        NumberField("max_void_ratio", &RveSpec::max_void_ratio, Need::kOptional, Range{0.0, 10.0}));
  }
  return fields;
}

}  // namespace

absl::Status ParseRve(const Json& j, const std::string& ptr, const RveKeys& keys, RveSpec* rve) {
  RETURN_IF_ERROR(ReadFields(j, ptr, RveFields(keys), rve).status());
  // Below the densest 2-D disc packings (e ≈ 0.1) it would be no cap but a
  // different material.
  if (rve->max_void_ratio > 0.0 && rve->max_void_ratio < 0.1) {
    return Bad(ptr + "/max_void_ratio", "must be 0 (no cap) or in [0.1, 10], got ",
               Num(rve->max_void_ratio));
  }
  // The RVE's own bound (dem::Controls): below 1e-6 a packing would take
  // without end to follow any increment, and the run would refuse it.
  if (rve->max_inertial_number > 0.0 && rve->max_inertial_number < dem::kMinInertialNumber) {
    return Bad(ptr + "/max_inertial_number", "must be 0 (the template's) or in [",
               Num(dem::kMinInertialNumber), ", 0.1], got ", Num(rve->max_inertial_number));
  }
  // A stretch of more than half in one step is a broken continuum, not an
  // increment; below 0.01 nearly every flow would stop.
  if (rve->max_stretch > 0.0 && rve->max_stretch < 0.01) {
    return Bad(ptr + "/max_stretch", "must be 0 (the template's) or in [0.01, 0.5], got ",
               Num(rve->max_stretch));
  }
  return absl::OkStatus();
}

OrderedJson WriteRve(const RveSpec& rve, const RveKeys& keys) {
  return WriteFields(RveFields(keys), rve);
}

}  // namespace rvehub::client_case
