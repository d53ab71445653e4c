#include "rve_server/values/snapshot.h"

#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"

namespace rvehub::dem {

constexpr double kPi = std::numbers::pi;

double SolidArea(const std::vector<double>& radius) {
  double a = 0.0;
  for (double r : radius) a += kPi * r * r;
  return a;
}

absl::Status Validate(const Controls& c) {
  auto check = [](bool ok, absl::string_view field, double v, absl::string_view rule) {
    return ok && std::isfinite(v)
               ? absl::OkStatus()
               : absl::InvalidArgumentError(absl::StrCat(field, " = ", v, " is invalid: ", rule));
  };
  for (const absl::Status& s : {
           check(c.time_step_factor > 0 && c.time_step_factor <= 1, "time_step_factor",
                 c.time_step_factor, "must lie in (0, 1]"),
           check(c.max_inertial_number >= kMinInertialNumber &&
                     c.max_inertial_number <= kMaxInertialNumber,
                 "max_inertial_number", c.max_inertial_number, "must lie in [1e-6, 1]"),
           check(c.pressure_floor >= kMinPressureFloor && c.pressure_floor <= kMaxPressure,
                 "pressure_floor", c.pressure_floor, "must lie in [1, 1e9] Pa"),
           check(c.min_steps >= 0 && c.min_steps <= kMaxMinSteps, "min_steps",
                 static_cast<double>(c.min_steps), "must lie in [0, 1e6]"),
           check(c.max_stretch > 0 && c.max_stretch <= 10, "max_stretch", c.max_stretch,
                 "must lie in (0, 10]"),
           check(c.max_rotation > 0 && c.max_rotation <= kPi / 2, "max_rotation", c.max_rotation,
                 "must lie in (0, π/2] rad"),
           check(c.mass_scale >= 1, "mass_scale", c.mass_scale, "must be >= 1"),
           check(c.skin > 0 && c.skin <= 2, "skin", c.skin, "must lie in (0, 2] (× r_min)"),
       }) {
    if (!s.ok()) return s;
  }
  return absl::OkStatus();
}

}  // namespace rvehub::dem
