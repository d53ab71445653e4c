// The case's "phases" section: the water of a saturated case, its drained
// boundaries and pressure monitors.
#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

Fields<DrainedBoundary> DrainedFields(const GridLines* lines) {
  return {
      NameField<DrainedBoundary>(),
      EnumField("line", &DrainedBoundary::axis, Need::kRequired, "drained line", kAxes, &AxisName),
      GridLinePositionField<DrainedBoundary>(lines),
      NumberField("pressure", &DrainedBoundary::pressure, Need::kOptional, kAny),
      OptionalFiniteField("from", &DrainedBoundary::from, kAny),
      OptionalFiniteField("to", &DrainedBoundary::to, kAny),
  };
}

Fields<PressureMonitor> MonitorFields() {
  return {
      NameField<PressureMonitor>(),
      Vec2Field("position", &PressureMonitor::position, Need::kRequired, kAny),
  };
}

// Fluid density up to that of mercury; k up to that of clean gravel (×10).
constexpr Range kFluidDensity{0.0, 2e4, true, false};
constexpr Range kPermeability{0.0, 10.0, true, false};
constexpr Range kPorosity{0.0, 1.0, false, true};

constexpr Table<Projection> kProjections = {{"incremental", Projection::kIncremental},
                                            {"stabilised", Projection::kStabilised}};

absl::string_view ProjectionName(Projection p) {
  return p == Projection::kStabilised ? "stabilised" : "incremental";
}

constexpr Table<ExcessDatum> kExcessData = {{"water_table", ExcessDatum::kWaterTable},
                                            {"surface", ExcessDatum::kSurface}};

absl::string_view ExcessDatumName(ExcessDatum d) {
  return d == ExcessDatum::kSurface ? "surface" : "water_table";
}

Fields<PhasesSpec> PhasesFields() {
  return {
      EnumField("projection", &PhasesSpec::projection, Need::kOptional, "projection", kProjections,
                &ProjectionName),
      NumberField("fluid_density", &PhasesSpec::fluid_density, Need::kOptional, kFluidDensity),
      NumberField("permeability", &PhasesSpec::permeability, Need::kRequired, kPermeability),
      NumberField("porosity", &PhasesSpec::porosity, Need::kOptional, kPorosity),
      OptionalFiniteField("water_table", &PhasesSpec::water_table, kAny),
      FlagField("drained_free_surface", &PhasesSpec::drained_free_surface),
      FlagField("free_surface_beside_light_nodes", &PhasesSpec::free_surface_beside_light_nodes),
      EnumField("excess_pressure_from", &PhasesSpec::excess_from, Need::kOptional,
                "excess pressure datum", kExcessData, &ExcessDatumName),
      // Read by ParsePhases (lists); written here.
      {"drained", [](const Object&, PhasesSpec*) { return absl::OkStatus(); },
       [](const PhasesSpec& s, OrderedJson& j) {
         OrderedJson& list = j["drained"] = OrderedJson::array();
         for (const DrainedBoundary& d : s.drained)
           list.push_back(WriteFields(DrainedFields(nullptr), d));
       }},
      {"monitors", [](const Object&, PhasesSpec*) { return absl::OkStatus(); },
       [](const PhasesSpec& s, OrderedJson& j) {
         OrderedJson& list = j["monitors"] = OrderedJson::array();
         for (const PressureMonitor& m : s.monitors)
           list.push_back(WriteFields(MonitorFields(), m));
       }},
  };
}

}  // namespace

// The phases section: its fields, the drained boundaries (each on a grid
// line that a region reaches) and the pressure monitors (inside a region).
absl::Status ParsePhases(const Json& j, const std::string& ptr, const GridLines& lines,
                         const std::vector<MaterialRegion>& regions, PhasesSpec* phases) {
  phases->saturated = true;
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, PhasesFields(), phases));
  RETURN_IF_ERROR(GetList(
      o, "drained", Need::kOptional, "drained boundary", &phases->drained,
      [&](const Json& e, const std::string& at, size_t, DrainedBoundary* d) {
        RETURN_IF_ERROR(ReadFields(e, at, DrainedFields(&lines), d).status());
        if (!(d->from < d->to)) {
          return Bad(Child(at, "to"), "must be > from = ", Num(d->from), " m, got ", Num(d->to));
        }
        const int along = 1 - d->axis;
        for (const MaterialRegion& r : regions) {
          if (d->position >= r.lower[d->axis] && d->position <= r.upper[d->axis] &&
              std::max(d->from, r.lower[along]) <= std::min(d->to, r.upper[along])) {
            return absl::OkStatus();
          }
        }
        return Bad(Child(at, "position"), "no region reaches the line ", kAxisName[d->axis], " = ",
                   Num(d->position), " m: a drained boundary must touch the soil");
      }));
  if (phases->free_surface_beside_light_nodes && !phases->drained_free_surface) {
    return Bad(o.At("free_surface_beside_light_nodes"),
               "needs drained_free_surface: it widens the free surface that one drains");
  }
  if (phases->drained.empty() && !phases->drained_free_surface) {
    return Bad(o.At("drained"),
               "a saturated case needs at least one drained boundary (or drained_free_surface): "
               "the pore pressure is otherwise undetermined");
  }
  return GetList(o, "monitors", Need::kOptional, "monitor", &phases->monitors,
                 [&](const Json& e, const std::string& at, size_t, PressureMonitor* m) {
                   RETURN_IF_ERROR(ReadFields(e, at, MonitorFields(), m).status());
                   for (const MaterialRegion& r : regions) {
                     if ((m->position.array() >= r.lower.array()).all() &&
                         (m->position.array() <= r.upper.array()).all()) {
                       return absl::OkStatus();
                     }
                   }
                   return Bad(Child(at, "position"), "(", Num(m->position.x()), ", ",
                              Num(m->position.y()), ") m is in no region");
                 });
}

OrderedJson WritePhases(const PhasesSpec& phases) { return WriteFields(PhasesFields(), phases); }

}  // namespace rvehub::mpm::case_internal
