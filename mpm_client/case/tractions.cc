// The case's "tractions" section: loads on a free face of a region.
#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

absl::Status ParseLoadHistory(const Json& j, const std::string& ptr,
                              std::vector<LoadFactorPoint>* history) {
  std::vector<std::array<double, 3>> rows;
  RETURN_IF_ERROR(ReadTimeRows(j, ptr, 2, "[t, factor] (s, -)", true, &rows));
  for (const auto& row : rows) history->push_back({row[0], row[1]});
  return absl::OkStatus();
}

struct Surface {
  int axis;
  int sign;
};
constexpr Table<Surface> kSurfaces = {
    {"+x", {0, 1}}, {"-x", {0, -1}}, {"+y", {1, 1}}, {"-y", {1, -1}}};

std::string SurfaceName(int axis, int sign) {
  return absl::StrCat(sign > 0 ? "+" : "-", kAxisName[axis]);
}

// `regions`: the case's, for the region's check (null when only writing).
Fields<SurfaceTraction> TractionFields(const std::vector<MaterialRegion>* regions) {
  return {
      NameField<SurfaceTraction>(),
      {"region",
       [regions](const Object& o, SurfaceTraction* t) -> absl::Status {
         RETURN_IF_ERROR(GetString(o, "region", Need::kRequired, true, &t->region));
         if (std::none_of(regions->begin(), regions->end(),
                          [&](const MaterialRegion& r) { return r.name == t->region; })) {
           return Bad(o.At("region"), "no region named ", Quote(t->region),
                      " (regions: ", absl::StrJoin(NamesOf(*regions), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) { j["region"] = t.region; }},
      {"surface",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         Surface surface{0, 1};
         RETURN_IF_ERROR(GetEnum(o, "surface", Need::kRequired, "surface", kSurfaces, &surface));
         t->normal_axis = surface.axis;
         t->normal_sign = surface.sign;
         return absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) {
         j["surface"] = SurfaceName(t.normal_axis == 0 ? 0 : 1, t.normal_sign);
       }},
      // Read as the traction it makes; the writer writes that traction.
      {"pressure",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         if (o.Has("pressure") == o.Has("traction")) {
           return Bad(o.ptr(), "give exactly one of \"pressure\" (Pa, compression +) or ",
                      "\"traction\" ([tx, ty], Pa, tension +)");
         }
         if (!o.Has("pressure")) return absl::OkStatus();
         double pressure = 0.0;
         RETURN_IF_ERROR(GetNumber(o, "pressure", Need::kRequired, kAny, &pressure));
         // A pressure pushes against the outward normal n: t = −p·n.
         t->traction = Eigen::Vector2d::Zero();
         t->traction[t->normal_axis] = -pressure * t->normal_sign;
         return absl::OkStatus();
       },
       [](const SurfaceTraction&, OrderedJson&) {}},
      {"traction",
       [](const Object& o, SurfaceTraction* t) {
         return o.Has("traction") ? GetVec2(o, "traction", Need::kRequired, kAny, &t->traction)
                                  : absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) { j["traction"] = Vec2Json(t.traction); }},
      NumberField("ramp_time", &SurfaceTraction::ramp_time, Need::kOptional, kNonNegative),
      {"history",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         const Json* h = o.Get("history");
         if (h == nullptr) return absl::OkStatus();
         if (t->ramp_time > 0.0) {
           return Bad(o.At("history"), "give either \"history\" or \"ramp_time\", not both");
         }
         return ParseLoadHistory(*h, o.At("history"), &t->history);
       },
       [](const SurfaceTraction& t, OrderedJson& j) {
         if (t.history.empty()) return;
         OrderedJson& history = j["history"] = OrderedJson::array();
         for (const LoadFactorPoint& p : t.history) {
           history.push_back(OrderedJson::array({p.time, p.factor}));
         }
       }},
      OptionalFiniteField("from", &SurfaceTraction::from, kAny),
      OptionalFiniteField("to", &SurfaceTraction::to, kAny),
  };
}

}  // namespace

absl::Status ParseTraction(const Json& j, const std::string& ptr,
                           const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, const std::string& regions_ptr,
                           SurfaceTraction* t) {
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, TractionFields(&regions), t));
  if (!(t->from < t->to)) {
    return Bad(o.At("to"), "must be > from = ", Num(t->from), " m, got ", Num(t->to));
  }
  auto region = std::find_if(regions.begin(), regions.end(),
                             [&](const MaterialRegion& r) { return r.name == t->region; });
  const Surface surface{t->normal_axis, t->normal_sign};

  // The loaded part of the face, [lo, hi] along the other axis, must exist
  // and be free: not shared with a neighbouring region.
  const size_t index = region - regions.begin();
  const int along = 1 - surface.axis;
  const double face_lo = std::max(region->lower[along], t->from);
  const double face_hi = std::min(region->upper[along], t->to);
  const std::string face = absl::StrCat("the ", SurfaceName(surface.axis, surface.sign),
                                        " face of region ", Quote(region->name));
  if (!(face_lo < face_hi)) {
    return Bad(o.At(o.Has("from") ? "from" : "to"), "[from, to] = [", Num(t->from), ", ",
               Num(t->to), "] m misses ", face, ", ", kAxisName[along], " in [",
               Num(region->lower[along]), ", ", Num(region->upper[along]), "] m");
  }
  const CellBox& box = boxes[index];
  const int line = surface.sign > 0 ? box.hi[surface.axis] : box.lo[surface.axis];
  for (size_t k = 0; k < regions.size(); ++k) {
    const CellBox& other = boxes[k];
    const int other_line = surface.sign > 0 ? other.lo[surface.axis] : other.hi[surface.axis];
    if (k == index || other_line != line) continue;
    const double lo = std::max(face_lo, regions[k].lower[along]);
    const double hi = std::min(face_hi, regions[k].upper[along]);
    if (lo < hi) {
      return Bad(o.At("surface"), face, " touches region ", Quote(regions[k].name), " (",
                 Child(regions_ptr, k), ") for ", kAxisName[along], " in [", Num(lo), ", ", Num(hi),
                 "] m: not a free surface (narrow the load with from/to)");
    }
  }
  return absl::OkStatus();
}

OrderedJson WriteTraction(const SurfaceTraction& t) {
  return WriteFields(TractionFields(nullptr), t);
}

}  // namespace rvehub::mpm::case_internal
