// The case's "solver" section, and solver.f_bar's names (case.h).
#include <string>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "mpm_client/case/case.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

constexpr double kMaxEndTime = 1e6;  // s

constexpr Table<ShapeKind> kShapes = {{"linear", ShapeKind::kLinear}, {"gimp", ShapeKind::kGimp}};

absl::string_view ShapeName(ShapeKind kind) { return kind == ShapeKind::kGimp ? "gimp" : "linear"; }

constexpr Table<LostPointPolicy> kLostPointPolicies = {{"stop", LostPointPolicy::kStop},
                                                       {"drop", LostPointPolicy::kDrop}};

absl::string_view LostPointPolicyName(LostPointPolicy p) {
  return p == LostPointPolicy::kDrop ? "drop" : "stop";
}

constexpr Table<FBar> kFBars = {{"none", FBar::kNone}, {"nodal", FBar::kNodal}};

bool IsShakenBox(const SolverSpec& s) { return !s.shaking_amplitude.isZero(0.0); }

// Read only where the time step comes from the RVEs' tangent (time_step and
// wave_modulus read before it are 0); written only when on.
Field<SolverSpec> TimeStepUpdateField() {
  constexpr absl::string_view kKey = "time_step_update_every";
  return {kKey,
          [=](const Object& o, SolverSpec* s) -> absl::Status {
            if (s->time_step > 0 || s->wave_modulus > 0) {
              return Forbid(o, kKey,
                            "only where the time step comes from the RVEs' tangent "
                            "(solver.time_step and solver.wave_modulus 0)");
            }
            return GetInteger(o, kKey, 0, 1'000'000'000, &s->time_step_update_every);
          },
          [=](const SolverSpec& s, OrderedJson& j) {
            if (s.time_step_update_every > 0) j[std::string(kKey)] = s.time_step_update_every;
          }};
}

Fields<SolverSpec> SolverFields() {
  return {
      EnumField("shape", &SolverSpec::shape, Need::kOptional, "shape function", kShapes,
                &ShapeName),
      NumberField("pic_fraction", &SolverSpec::pic_fraction, Need::kOptional, kUnit),
      Vec2Field("gravity", &SolverSpec::gravity, Need::kOptional, kAny),
      NumberField("time_step", &SolverSpec::time_step, Need::kOptional, Range{0.0, kMaxEndTime}),
      NumberField("cfl", &SolverSpec::cfl, Need::kOptional, Range{0.0, 1.0, true, false}),
      NumberField("wave_modulus", &SolverSpec::wave_modulus, Need::kOptional, kNonNegative),
      TimeStepUpdateField(),
      // A bound that keeps end_time / Δt a step count (1e308 s overflowed it
      // and ended the run at step 0); the step count itself is bounded at the
      // start.
      NumberField("end_time", &SolverSpec::end_time, Need::kRequired,
                  Range{0.0, kMaxEndTime, true, false}),
      NumberField("thickness", &SolverSpec::thickness, Need::kOptional, kPositive),
      ShakingAmplitudeField(&SolverSpec::shaking_amplitude, &IsShakenBox),
      ShakingFrequencyField(&SolverSpec::shaking_frequency, &IsShakenBox),
      EnumField("lost_points", &SolverSpec::lost_points, Need::kOptional, "lost-point policy",
                kLostPointPolicies, &LostPointPolicyName),
      NumberField("mass_scale", &SolverSpec::mass_scale, Need::kOptional,
                  Range{1.0, 1e6, false, false}),
      EnumField("f_bar", &SolverSpec::f_bar, Need::kOptional, "F-bar kind", kFBars, &FBarName),
      NumberField("nonlocal_radius", &SolverSpec::nonlocal_radius, Need::kOptional, kNonNegative),
      NumberField("nonlocal_fraction", &SolverSpec::nonlocal_fraction, Need::kOptional,
                  Range{0.0, 1.0, true, false}),
  };
}

}  // namespace

absl::Status ParseSolver(const Json& j, const std::string& ptr, SolverSpec* solver) {
  return ReadFields(j, ptr, SolverFields(), solver).status();
}

OrderedJson WriteSolver(const SolverSpec& solver) { return WriteFields(SolverFields(), solver); }

}  // namespace rvehub::mpm::case_internal

namespace rvehub::mpm {

absl::string_view FBarName(FBar f) { return f == FBar::kNodal ? "nodal" : "none"; }

absl::StatusOr<FBar> FBarFromName(absl::string_view name) {
  for (const auto& [n, value] : case_internal::kFBars) {
    if (n == name) return value;
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "must be one of ", fields::Choices(case_internal::kFBars), ", got ", fields::Quote(name)));
}

}  // namespace rvehub::mpm
