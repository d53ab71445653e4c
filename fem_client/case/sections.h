// The sections of a fem_client case file (cases/FEM_FORMAT.md), one file
// each (mesh.cc, material.cc, boundaries.cc, loading.cc, solver.cc,
// output.cc; templates and rve are client_case/'s), for case.cc's
// ParseFemCase and ToJson: each section's Parse (JSON at a pointer -> its
// part of the FemCase, checked against the sections read before it) and
// Write (its canonical JSON), both from one field table
// (toolkit/field_table.h). Internal to the case reader.
#ifndef RVEHUB_FEM_CLIENT_CASE_SECTIONS_H_
#define RVEHUB_FEM_CLIENT_CASE_SECTIONS_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "fem_client/case/fem_case.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/values/snapshot.h"
#include "toolkit/field_table.h"
#include "toolkit/json_pointer.h"

namespace rvehub::fem::case_internal {

// The toolkit's readers, by their short names in the section files.
using fields::Bad;
using fields::Child;
using fields::EnumField;
using fields::Field;
using fields::Fields;
using fields::Forbid;
using fields::GetArray;
using fields::GetEnum;
using fields::GetFile;
using fields::GetInteger;
using fields::GetNumber;
using fields::GetString;
using fields::GetVec2;
using fields::Got;
using fields::IntegerField;
using fields::Json;
using fields::kAny;
using fields::kNonNegative;
using fields::kPositive;
using fields::NameField;
using fields::NamesOf;
using fields::Need;
using fields::Num;
using fields::NumberField;
using fields::Object;
using fields::Only;
using fields::OrderedJson;
using fields::Quote;
using fields::Range;
using fields::ReadFields;
using fields::ReadInt;
using fields::ReadInteger;
using fields::Table;
using fields::Vec2Field;
using fields::Vec2Json;
using fields::WriteFields;

// A pressure or stress a packing may be given, Pa: positive (packings carry
// no tension) and at most the RVEs' own limit on any stress target.
inline constexpr Range kPackingStress{0.0, dem::kMaxPressure, true, false};

// An optional int in [lo, hi] (the default stands when absent), always
// written: "must be an integer in lo..hi, got <x>".
template <typename S>
Field<S> IntField(absl::string_view key, int S::*m, int lo, int hi) {
  return {key,
          [=](const Object& o, S* s) -> absl::Status {
            const Json* v = o.Get(key);
            return v == nullptr ? absl::OkStatus() : ReadInt(*v, o.At(key), lo, hi, &(s->*m));
          },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

// The names of the enumerations, as the file writes them.
absl::string_view ElementName(ElementKind kind);
absl::string_view FaceName(Face face);
absl::string_view BoundaryKindName(BoundaryKind kind);
absl::string_view LoadingKindName(LoadingKind kind);

// Nodes along a face: the face's elements (nx for bottom and top, ny for
// left and right) plus one, with the mid-side nodes of Q8 elements.
int NodesAlongFace(const MeshSpec& mesh, Face face);

// ---------------------------------------------------------------- sections
// Each Parse reads the section's JSON `j` at pointer `ptr`; each Write gives
// the section's canonical JSON (ParseX(WriteX(x)) reads back x).

absl::Status ParseMesh(const Json& j, const std::string& ptr, MeshSpec* mesh);
OrderedJson WriteMesh(const MeshSpec& mesh);

// The template one of `templates`.
absl::Status ParseMaterial(const Json& j, const std::string& ptr,
                           const std::vector<TemplateSpec>& templates, MaterialSpec* material);
OrderedJson WriteMaterial(const MaterialSpec& material);

// One boundary, checked alone against the mesh (its face for the kind, a
// pin's node).
absl::Status ParseBoundary(const Json& j, const std::string& ptr, const MeshSpec& mesh,
                           BoundarySpec* b);
OrderedJson WriteBoundary(const BoundarySpec& b);
// The boundaries together (their list at `ptr`): one per face, periodic
// faces in pairs, exactly one driven face (a platen or the shear platen)
// with the face across it held, and the specimen held in x and in y.
absl::Status CheckBoundaries(const std::vector<BoundarySpec>& boundaries, const std::string& ptr);

// Checked against the driven boundary of `boundaries` (their list at
// `boundaries_ptr`): compression for a platen, shear or cyclic shear for the
// shear platen.
absl::Status ParseLoading(const Json& j, const std::string& ptr,
                          const std::vector<BoundarySpec>& boundaries,
                          const std::string& boundaries_ptr, LoadingSpec* loading);
OrderedJson WriteLoading(const LoadingSpec& loading);

absl::Status ParseSolver(const Json& j, const std::string& ptr, SolverSpec* solver);
OrderedJson WriteSolver(const SolverSpec& solver);

// Gauss point ids within `mesh`, the plot for `loading` (its default too),
// a reference curve relative to `base_dir`.
absl::Status ParseOutput(const Json& j, const std::string& ptr, const MeshSpec& mesh,
                         const LoadingSpec& loading, const std::string& base_dir, OutputSpec* out);
OrderedJson WriteOutput(const OutputSpec& out);
// The plot a loading draws unless the output says otherwise.
PlotKind DefaultPlot(const LoadingSpec& loading);

}  // namespace rvehub::fem::case_internal

#endif  // RVEHUB_FEM_CLIENT_CASE_SECTIONS_H_
