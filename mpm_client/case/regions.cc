// The case's "regions" section: material regions on the grid, each filled
// from a template, with its initial stress.
#include <algorithm>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_join.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

constexpr Table<InitialStressKind> kInitialStresses = {
    {"template", InitialStressKind::kTemplate},
    {"geostatic_isotropic", InitialStressKind::kIsotropic},
    {"geostatic_k0", InitialStressKind::kK0}};

absl::string_view InitialStressName(InitialStressKind kind) {
  switch (kind) {
    case InitialStressKind::kTemplate:
      break;
    case InitialStressKind::kIsotropic:
      return "geostatic_isotropic";
    case InitialStressKind::kK0:
      return "geostatic_k0";
  }
  return "template";
}

bool K0(const MaterialRegion& r) { return r.initial_stress == InitialStressKind::kK0; }
bool Geostatic(const MaterialRegion& r) { return r.initial_stress != InitialStressKind::kTemplate; }

// The keys of a region's "initial_stress" object.
Fields<MaterialRegion> InitialStressFields() {
  constexpr absl::string_view kOnlyGeostatic = "only for the geostatic kinds";
  return {
      EnumField("kind", &MaterialRegion::initial_stress, Need::kRequired, "initial stress kind",
                kInitialStresses, &InitialStressName),
      Only(&K0, "only for kind \"geostatic_k0\"",
           NumberField("k0", &MaterialRegion::k0, Need::kOptional, kPositive)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("surface_y", &MaterialRegion::surface_y, Need::kOptional, kAny)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("surcharge", &MaterialRegion::surcharge, Need::kOptional, kNonNegative)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("minimum", &MaterialRegion::minimum_stress, Need::kOptional, kNonNegative)),
  };
}

absl::Status ParseInitialStress(const Json& j, const std::string& ptr, const SolverSpec& solver,
                                MaterialRegion* r) {
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, InitialStressFields(), r));
  // RVEs need p > 0: without gravity σv is the surcharge (or the minimum).
  if (r->initial_stress != InitialStressKind::kTemplate && solver.gravity.isZero(0.0) &&
      r->surcharge == 0.0 && r->minimum_stress == 0.0) {
    return Bad(o.At("kind"), "a geostatic start without gravity needs a surcharge or a minimum ",
               "> 0 (RVEs need p > 0)");
  }
  return absl::OkStatus();
}

// What reading a region needs besides its JSON (null members: only writing).
struct RegionContext {
  const GridLines* lines = nullptr;
  const SolverSpec* solver = nullptr;
  const std::vector<TemplateSpec>* templates = nullptr;
  CellBox* box = nullptr;
};

Fields<MaterialRegion> RegionFields(const RegionContext& c) {
  return {
      NameField<MaterialRegion>(),
      Vec2Field("lower", &MaterialRegion::lower, Need::kRequired, kAny),
      {"upper",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         RETURN_IF_ERROR(GetVec2(o, "upper", Need::kRequired, kAny, &r->upper));
         // Both corners on grid lines, upper above lower: at least one cell.
         for (int axis = 0; axis < 2; ++axis) {
           RETURN_IF_ERROR(c.lines->Snap(r->lower[axis], axis, Child(o.At("lower"), axis),
                                         &c.box->lo[axis], &r->lower[axis]));
           RETURN_IF_ERROR(c.lines->Snap(r->upper[axis], axis, Child(o.At("upper"), axis),
                                         &c.box->hi[axis], &r->upper[axis]));
           if (c.box->hi[axis] <= c.box->lo[axis]) {
             return Bad(Child(o.At("upper"), axis), "upper ", kAxisName[axis], " = ",
                        Num(r->upper[axis]), " m must be above lower ", kAxisName[axis], " = ",
                        Num(r->lower[axis]), " m (a region spans at least one cell)");
           }
         }
         return absl::OkStatus();
       },
       [](const MaterialRegion& r, OrderedJson& j) { j["upper"] = Vec2Json(r.upper); }},
      {"points_per_cell_side",
       [](const Object& o, MaterialRegion* r) -> absl::Status {
         const Json* v = o.Get("points_per_cell_side");
         return v == nullptr
                    ? absl::OkStatus()
                    : ReadInt(*v, o.At("points_per_cell_side"), 1, 8, &r->points_per_cell_side);
       },
       [](const MaterialRegion& r, OrderedJson& j) {
         j["points_per_cell_side"] = r.points_per_cell_side;
       }},
      {"template",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         RETURN_IF_ERROR(GetString(o, "template", Need::kRequired, true, &r->rve_template));
         if (std::none_of(c.templates->begin(), c.templates->end(),
                          [&](const TemplateSpec& t) { return t.name == r->rve_template; })) {
           return Bad(o.At("template"), "no template named ", Quote(r->rve_template),
                      " (templates: ", absl::StrJoin(NamesOf(*c.templates), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const MaterialRegion& r, OrderedJson& j) { j["template"] = r.rve_template; }},
      NumberField("density", &MaterialRegion::density, Need::kOptional, kNonNegative),
      {"initial_stress",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         r->surface_y = r->upper.y();  // the region's top unless stated
         const Json* v = o.Get("initial_stress");
         return v == nullptr ? absl::OkStatus()
                             : ParseInitialStress(*v, o.At("initial_stress"), *c.solver, r);
       },
       [](const MaterialRegion& r, OrderedJson& j) {
         j["initial_stress"] = WriteFields(InitialStressFields(), r);
       }},
  };
}

}  // namespace

absl::Status ParseRegion(const Json& j, const std::string& ptr, const GridLines& lines,
                         const SolverSpec& solver, const std::vector<TemplateSpec>& templates,
                         MaterialRegion* r, CellBox* box) {
  return ReadFields(j, ptr, RegionFields({&lines, &solver, &templates, box}), r).status();
}

absl::Status CheckOverlaps(const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, absl::string_view ptr) {
  for (size_t b = 0; b < boxes.size(); ++b) {
    for (size_t a = 0; a < b; ++a) {
      const CellBox& p = boxes[a];
      const CellBox& q = boxes[b];
      if (p.lo[0] < q.hi[0] && q.lo[0] < p.hi[0] && p.lo[1] < q.hi[1] && q.lo[1] < p.hi[1]) {
        return Bad(Child(ptr, b), "region ", Quote(regions[b].name), " overlaps region ",
                   Quote(regions[a].name), " (", Child(ptr, a), ")");
      }
    }
  }
  return absl::OkStatus();
}

OrderedJson WriteRegion(const MaterialRegion& r) { return WriteFields(RegionFields({}), r); }

}  // namespace rvehub::mpm::case_internal
