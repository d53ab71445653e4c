#include "rve_server/values/increment.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "rve_server/values/snapshot.h"

namespace rvehub {
namespace {

constexpr double kMaxK0 = 10.0;  // σh/σv of a K0 state at most, [-]

}  // namespace

namespace dem {

absl::Status ValidateDeltaF(const Eigen::Matrix3d& delta_f) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(delta_f(r, c))) {
        return absl::InvalidArgumentError(
            absl::StrCat("ΔF(", r, ",", c, ") = ", delta_f(r, c), " is not finite"));
      }
    }
  }
  constexpr double kPlaneTol = 1e-12;
  if (std::abs(delta_f(2, 2) - 1.0) > kPlaneTol || std::abs(delta_f(0, 2)) > kPlaneTol ||
      std::abs(delta_f(1, 2)) > kPlaneTol || std::abs(delta_f(2, 0)) > kPlaneTol ||
      std::abs(delta_f(2, 1)) > kPlaneTol) {
    return absl::InvalidArgumentError(
        "ΔF must be plane strain for a 2-D RVE: ΔF_zz = 1 and no out-of-plane coupling");
  }
  const double det = delta_f.topLeftCorner<2, 2>().determinant();
  if (!(det > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("det ΔF = ", det, " must be > 0"));
  }
  return absl::OkStatus();
}

absl::Status Validate(const ApplyOptions& o) {
  if (!(o.relax_tolerance >= kMinRelaxTolerance && o.relax_tolerance <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("relax_tolerance = ", o.relax_tolerance,
                                                   " is invalid: must lie in [", kMinRelaxTolerance,
                                                   ", 1]"));
  }
  if (o.relax_max_steps < 0 || o.relax_max_steps > kMaxRelaxSteps) {
    return absl::InvalidArgumentError(absl::StrCat("relax_max_steps = ", o.relax_max_steps,
                                                   " is invalid: must lie in [0, ", kMaxRelaxSteps,
                                                   "]"));
  }
  if (!(o.max_inertial_number == 0 || (o.max_inertial_number >= kMinInertialNumber &&
                                       o.max_inertial_number <= kMaxInertialNumber))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_inertial_number = ", o.max_inertial_number, " is invalid: must be 0 or lie in [",
        kMinInertialNumber, ", ", kMaxInertialNumber, "]"));
  }
  if (!(o.duration >= 0 && o.duration <= kMaxDuration)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "duration = ", o.duration, " s is invalid: must lie in [0, ", kMaxDuration, "] s"));
  }
  return absl::OkStatus();
}

}  // namespace dem

absl::Status Validate(const InitialStress& initial) {
  switch (initial.kind) {
    case InitialStress::Kind::kTemplate:
      return absl::OkStatus();
    case InitialStress::Kind::kIsotropic:
      if (!(initial.pressure > 0 && initial.pressure <= dem::kMaxPressure)) {
        return absl::InvalidArgumentError(absl::StrCat("initial pressure ", initial.pressure,
                                                       " Pa must lie in (0, ", dem::kMaxPressure,
                                                       "] Pa (compression +)"));
      }
      return absl::OkStatus();
    case InitialStress::Kind::kK0:
      if (!(initial.vertical_compression > 0 && initial.vertical_compression <= dem::kMaxPressure &&
            initial.k0 > 0 && initial.k0 <= kMaxK0 &&
            initial.k0 * initial.vertical_compression <= dem::kMaxPressure)) {
        return absl::InvalidArgumentError(
            absl::StrCat("K0 state needs a vertical stress in (0, ", dem::kMaxPressure,
                         "] Pa (compression +) and K0 in (0, ", kMaxK0,
                         "], got σv = ", initial.vertical_compression, " Pa, K0 = ", initial.k0));
      }
      return absl::OkStatus();
  }
  return absl::InvalidArgumentError("unknown kind of initial stress");
}

}  // namespace rvehub
