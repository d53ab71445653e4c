// The case's "walls" section: rigid walls on grid lines; and the contact
// kinds walls and bodies share.
#include <string>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

constexpr Table<ContactKind> kWallKinds = {
    {"fixed", ContactKind::kRough},     {"rough", ContactKind::kRough},
    {"roller", ContactKind::kSmooth},   {"smooth", ContactKind::kSmooth},
    {"symmetry", ContactKind::kSmooth}, {"frictional", ContactKind::kFrictional}};

// `lines`: the grid's, for snapping the position (null when only writing).
Fields<Wall> WallFields(const GridLines* lines) {
  return {
      NameField<Wall>(),
      EnumField("kind", &Wall::contact, Need::kRequired, "wall kind", kWallKinds, &ContactKindName),
      EnumField("line", &Wall::axis, Need::kRequired, "wall line", kAxes, &AxisName),
      GridLinePositionField<Wall>(lines),
      FrictionField<Wall>("kind"),
      OptionalFiniteField("remove_time", &Wall::remove_time, kNonNegative),
      FlagField("unilateral", &Wall::unilateral),
      ShakingAmplitudeField(&Wall::shaking_amplitude, &IsShaken),
      ShakingFrequencyField(&Wall::shaking_frequency, &IsShaken),
  };
}

}  // namespace

absl::string_view ContactKindName(ContactKind kind) {
  switch (kind) {
    case ContactKind::kRough:
      return "rough";
    case ContactKind::kSmooth:
      return "smooth";
    case ContactKind::kFrictional:
      return "frictional";
  }
  return "rough";
}

absl::Status GetFriction(const Object& o, ContactKind kind, absl::string_view kind_key,
                         double* friction) {
  if (kind != ContactKind::kFrictional) {
    return Forbid(o, "friction", absl::StrCat("only for ", kind_key, " \"frictional\""));
  }
  return GetNumber(o, "friction", Need::kRequired, kPositive, friction);
}

absl::Status ParseWall(const Json& j, const std::string& ptr, const GridLines& lines, Wall* w) {
  return ReadFields(j, ptr, WallFields(&lines), w).status();
}

OrderedJson WriteWall(const Wall& w) { return WriteFields(WallFields(nullptr), w); }

}  // namespace rvehub::mpm::case_internal
