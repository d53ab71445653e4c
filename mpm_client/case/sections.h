// The sections of a case file (cases/FORMAT.md), one file each
// (<section>.cc), for case.cc's ParseCase and ToJson: each section's
// Parse (JSON at a pointer -> its part of the CaseSpec, checked against the
// sections read before it) and Write (its canonical JSON), both from one
// field table (toolkit/field_table.h). Internal to the case reader.
#ifndef RVEHUB_MPM_CLIENT_CASE_SECTIONS_H_
#define RVEHUB_MPM_CLIENT_CASE_SECTIONS_H_

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "client_case/sections.h"
#include "mpm_client/core/model.h"
#include "rve_server/common/status_macros.h"
#include "toolkit/field_table.h"
#include "toolkit/json_pointer.h"

namespace rvehub::mpm::case_internal {

// The toolkit's readers, by their short names in the section files.
using fields::Bad;
using fields::CheckUnique;
using fields::Child;
using fields::EnumField;
using fields::Field;
using fields::Fields;
using fields::FlagField;
using fields::Forbid;
using fields::GetArray;
using fields::GetEnum;
using fields::GetFile;
using fields::GetInteger;
using fields::GetList;
using fields::GetNumber;
using fields::GetString;
using fields::GetVec2;
using fields::Got;
using fields::IntegerField;
using fields::Json;
using fields::kAny;
using fields::kInf;
using fields::kNonNegative;
using fields::kPositive;
using fields::kUnit;
using fields::NameField;
using fields::NamesOf;
using fields::Need;
using fields::Num;
using fields::NumberField;
using fields::Object;
using fields::Only;
using fields::OptionalFiniteField;
using fields::OrderedJson;
using fields::Quote;
using fields::Range;
using fields::ReadEnum;
using fields::ReadFields;
using fields::ReadInt;
using fields::ReadNumber;
using fields::ReadSeed;
using fields::ReadTimeRows;
using fields::Table;
using fields::TextField;
using fields::Vec2Field;
using fields::Vec2Json;
using fields::WriteFields;

// ---------------------------------------------------------------- shared

inline constexpr absl::string_view kAxisName[2] = {"x", "y"};
// A line's axis by name ("x", "y"; walls, drained boundaries) and back.
extern const Table<int> kAxes;
absl::string_view AxisName(int axis);

// Grid lines along each axis: x_i = origin + i·h, i in 0..n (grid.cc).
class GridLines {
 public:
  explicit GridLines(const GridSpec& grid) : grid_(grid) {}

  // The index of the grid line at coordinate `x` along `axis`; the snapped
  // coordinate goes to `snapped`.
  absl::Status Snap(double x, int axis, absl::string_view ptr, int* index, double* snapped) const;

 private:
  GridSpec grid_;
};

// "position": a coordinate along the line of axis S::axis (read before it),
// snapped onto a grid line of `lines` (null when only writing).
template <typename S>
Field<S> GridLinePositionField(const GridLines* lines) {
  return {"position",
          [lines](const Object& o, S* s) -> absl::Status {
            RETURN_IF_ERROR(GetNumber(o, "position", Need::kRequired, kAny, &s->position));
            int index = 0;
            return lines->Snap(s->position, s->axis, o.At("position"), &index, &s->position);
          },
          [](const S& s, OrderedJson& j) { j["position"] = s.position; }};
}

// A region's extent in grid cells, for the overlap and free-surface checks.
struct CellBox {
  int lo[2] = {0, 0};
  int hi[2] = {0, 0};
};

// A shaking table's speeds are of cm/s to m/s; its frequencies of Hz.
inline constexpr Range kShakingSpeed{-100.0, 100.0, false, false};   // m/s
inline constexpr Range kShakingFrequency{0.0, 1000.0, true, false};  // Hz

inline bool IsShaken(const Wall& w) { return !w.shaking_amplitude.isZero(0.0); }

// A shake's two keys (a wall's or the whole box's): shaking_amplitude, m/s,
// written only when shaken; shaking_frequency, Hz, required then and
// refused otherwise.
template <typename S>
Field<S> ShakingAmplitudeField(Eigen::Vector2d S::*m, bool (*shaken)(const S&)) {
  return {"shaking_amplitude",
          [m](const Object& o, S* s) {
            return GetVec2(o, "shaking_amplitude", Need::kOptional, kShakingSpeed, &(s->*m));
          },
          [m, shaken](const S& s, OrderedJson& j) {
            if (shaken(s)) j["shaking_amplitude"] = Vec2Json(s.*m);
          }};
}
template <typename S>
Field<S> ShakingFrequencyField(double S::*m, bool (*shaken)(const S&)) {
  return Only(shaken, "only with a shaking_amplitude other than [0, 0]",
              NumberField("shaking_frequency", m, Need::kRequired, kShakingFrequency));
}

// Contact kinds of walls and bodies (walls.cc).
absl::string_view ContactKindName(ContactKind kind);

// μ: required and > 0 for frictional contact, absent otherwise.
absl::Status GetFriction(const Object& o, ContactKind kind, absl::string_view kind_key,
                         double* friction);

// μ of a contact `kind_key` ("kind" or "contact"): required and > 0 for
// frictional contact, refused otherwise; written only where it applies.
template <typename S>
Field<S> FrictionField(absl::string_view kind_key) {
  return {"friction",
          [=](const Object& o, S* s) { return GetFriction(o, s->contact, kind_key, &s->friction); },
          [](const S& s, OrderedJson& j) {
            if (s.contact == ContactKind::kFrictional) j["friction"] = s.friction;
          }};
}

// ---------------------------------------------------------------- sections
// Each Parse reads the section's JSON `j` at pointer `ptr`; each Write gives
// the section's canonical JSON (ParseX(WriteX(x)) reads back x).
// "templates" and "rve" are every continuum client's (client_case/).
using client_case::EstimatedDiscs;
using client_case::ParseRve;
using client_case::ParseTemplate;
using client_case::WriteRve;
using client_case::WriteTemplate;

absl::Status ParseGrid(const Json& j, const std::string& ptr, GridSpec* grid);
OrderedJson WriteGrid(const GridSpec& grid);

absl::Status ParseSolver(const Json& j, const std::string& ptr, SolverSpec* solver);
OrderedJson WriteSolver(const SolverSpec& solver);

// Corners snapped onto `lines` (their cells into `box`), the template one
// of `templates`, the initial stress checked against the solver's gravity.
absl::Status ParseRegion(const Json& j, const std::string& ptr, const GridLines& lines,
                         const SolverSpec& solver, const std::vector<TemplateSpec>& templates,
                         MaterialRegion* r, CellBox* box);
OrderedJson WriteRegion(const MaterialRegion& r);
// No two regions share a cell; `ptr` is the regions' list.
absl::Status CheckOverlaps(const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, absl::string_view ptr);

absl::Status ParseWall(const Json& j, const std::string& ptr, const GridLines& lines, Wall* w);
OrderedJson WriteWall(const Wall& w);

absl::Status ParseBody(const Json& j, const std::string& ptr, RigidBody* b);
OrderedJson WriteBody(const RigidBody& b);

// On a free face of one of `regions` (their cells `boxes`, their list at
// `regions_ptr`).
absl::Status ParseTraction(const Json& j, const std::string& ptr,
                           const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, const std::string& regions_ptr,
                           SurfaceTraction* t);
OrderedJson WriteTraction(const SurfaceTraction& t);

// Sets phases->saturated; drained boundaries on `lines` where a region
// reaches, monitors inside a region.
absl::Status ParsePhases(const Json& j, const std::string& ptr, const GridLines& lines,
                         const std::vector<MaterialRegion>& regions, PhasesSpec* phases);
OrderedJson WritePhases(const PhasesSpec& phases);

// `bodies`: the case's, for the plot body; `base_dir` for a relative
// reference curve.
absl::Status ParseOutput(const Json& j, const std::string& ptr,
                         const std::vector<RigidBody>& bodies, const std::string& base_dir,
                         OutputSpec* out);
OrderedJson WriteOutput(const OutputSpec& out);

}  // namespace rvehub::mpm::case_internal

#endif  // RVEHUB_MPM_CLIENT_CASE_SECTIONS_H_
