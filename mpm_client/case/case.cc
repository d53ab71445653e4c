// The case reader's driver: the document (parse, overrides), the top level
// and the sections in order (sections.h), the checks across sections,
// the memory estimate; and the canonical writer.
#include "mpm_client/case/case.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "mpm_client/case/sections.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "toolkit/json_document.h"

namespace rvehub::mpm {
namespace case_internal {
namespace {

// The explicit step takes every key of the shared "rve" section.
constexpr client_case::RveKeys kRveKeys;

// The case in `doc`, a section at a time: each is read after those it
// refers to (regions after templates, tractions after regions, ...).
absl::StatusOr<CaseSpec> ReadCase(const Json& doc, const std::string& base_dir) {
  ASSIGN_OR_RETURN(Object root, Object::Open(doc, "",
                                             {"name", "description", "expected_runtime_s", "grid",
                                              "solver", "templates", "regions", "walls", "bodies",
                                              "tractions", "rve", "phases", "output", "checks"}));
  CaseSpec spec;
  RETURN_IF_ERROR(GetString(root, "name", Need::kOptional, false, &spec.name));
  RETURN_IF_ERROR(GetString(root, "description", Need::kOptional, false, &spec.description));
  RETURN_IF_ERROR(GetNumber(root, "expected_runtime_s", Need::kOptional, kNonNegative,
                            &spec.expected_runtime_s));

  const Json* grid = root.Get("grid");
  if (grid == nullptr) return root.Missing("grid");
  RETURN_IF_ERROR(ParseGrid(*grid, root.At("grid"), &spec.grid));
  const GridLines lines(spec.grid);

  const Json* solver = root.Get("solver");
  if (solver == nullptr) return root.Missing("solver");
  RETURN_IF_ERROR(ParseSolver(*solver, root.At("solver"), &spec.solver));

  RETURN_IF_ERROR(GetList(root, "templates", Need::kRequired, "template", &spec.templates,
                          [&](const Json& j, const std::string& ptr, size_t, TemplateSpec* t) {
                            return ParseTemplate(j, ptr, base_dir, t);
                          }));

  std::vector<CellBox> boxes;
  RETURN_IF_ERROR(GetList(root, "regions", Need::kRequired, "region", &spec.regions,
                          [&](const Json& j, const std::string& ptr, size_t, MaterialRegion* r) {
                            boxes.emplace_back();
                            return ParseRegion(j, ptr, lines, spec.solver, spec.templates, r,
                                               &boxes.back());
                          }));
  RETURN_IF_ERROR(CheckOverlaps(spec.regions, boxes, root.At("regions")));

  RETURN_IF_ERROR(GetList(root, "walls", Need::kOptional, "wall", &spec.walls,
                          [&](const Json& j, const std::string& ptr, size_t, Wall* w) {
                            return ParseWall(j, ptr, lines, w);
                          }));
  RETURN_IF_ERROR(GetList(root, "bodies", Need::kOptional, "body", &spec.bodies,
                          [&](const Json& j, const std::string& ptr, size_t, RigidBody* b) {
                            return ParseBody(j, ptr, b);
                          }));
  RETURN_IF_ERROR(GetList(root, "tractions", Need::kOptional, "traction", &spec.tractions,
                          [&](const Json& j, const std::string& ptr, size_t, SurfaceTraction* t) {
                            return ParseTraction(j, ptr, spec.regions, boxes, root.At("regions"),
                                                 t);
                          }));

  if (const Json* rve = root.Get("rve")) {
    RETURN_IF_ERROR(ParseRve(*rve, root.At("rve"), kRveKeys, &spec.rve));
  }
  if (const Json* phases = root.Get("phases")) {
    // A wall shaken on its fixed grid line draws the soil off the line by
    // the shake's displacement, which the free-surface test of the water
    // then takes for a drained face: refused for the box's frame.
    for (std::size_t w = 0; w < spec.walls.size(); ++w) {
      if (IsShaken(spec.walls[w])) {
        return Bad(absl::StrCat(root.At("walls"), "/", w, "/shaking_amplitude"),
                   "a saturated case shakes its whole box (solver.shaking_amplitude and "
                   "solver.shaking_frequency), not single walls");
      }
    }
    RETURN_IF_ERROR(ParsePhases(*phases, root.At("phases"), lines, spec.regions, &spec.phases));
    // The two-phase step's porosity, drag and pressure need every point on
    // the grid.
    if (spec.phases.saturated && spec.solver.lost_points == LostPointPolicy::kDrop) {
      return Bad(root.At("solver") + "/lost_points", "\"drop\" is for dry cases only");
    }
    // Scaled inertia would change the drag's and the pressure's time scales.
    if (spec.phases.saturated && spec.solver.mass_scale != 1.0) {
      return Bad(root.At("solver") + "/mass_scale", "mass scaling is for dry cases only");
    }
    // The water's mass balance takes its porosity from the RVE's void ratio.
    if (spec.phases.saturated && spec.rve.max_void_ratio > 0.0) {
      return Bad(root.At("rve") + "/max_void_ratio", "a void-ratio cap is for dry cases only");
    }
    // The water's mass balance follows each point's own strain.
    if (spec.phases.saturated && spec.solver.nonlocal_radius > 0.0) {
      return Bad(root.At("solver") + "/nonlocal_radius", "a nonlocal strain is for dry cases only");
    }
    // The two-phase step's pressure solve is set up for one Δt.
    if (spec.phases.saturated && spec.solver.time_step_update_every > 0) {
      return Bad(root.At("solver") + "/time_step_update_every",
                 "an updated time step is for dry cases only");
    }
    // A drained free surface holds p = 0, so water at rest fills the soil to
    // its top. A table above it (free water over the soil, not modelled)
    // started a pressure shock: 10 m over cyclic-shaking-medium-ci's 1 m
    // box gave 1.8 J of kinetic energy in the first step against 0.04 J.
    if (const double table = spec.phases.water_table; spec.phases.drained_free_surface &&
                                                      spec.solver.gravity.norm() > 0.0 &&
                                                      std::isfinite(table)) {
      double top = -kInf;  // m
      for (const MaterialRegion& r : spec.regions) top = std::max(top, r.upper.y());
      if (table > top + 1e-9 * std::max(1.0, std::abs(top))) {
        return Bad(root.At("phases") + "/water_table", "y = ", Num(table),
                   " m lies above the soil's top, y = ", Num(top),
                   " m: free water over the soil is not modelled (the drained free surface "
                   "holds p = 0); put the table at the top");
      }
    }
  }
  if (const double radius = spec.solver.nonlocal_radius; radius > 0.0) {
    const std::string at = root.At("solver") + "/nonlocal_radius";
    // Each averages the strain its own way; one at a time keeps either's
    // energy balance exact.
    if (spec.solver.f_bar != FBar::kNone) return Bad(at, "not together with solver.f_bar");
    // Below a tenth of a cell no point has a neighbour within it; beyond
    // 8 cells the averaging would span most small domains and cost O(n·64²).
    const double h = spec.grid.cell_size;
    if (radius < 0.1 * h || radius > 8.0 * h) {
      return Bad(at, absl::StrFormat("%.6g m must be 0 (off) or between 0.1 and 8 cells (%.6g to "
                                     "%.6g m for cells of %.6g m)",
                                     radius, 0.1 * h, 8.0 * h, h));
    }
  }
  if (const Json* output = root.Get("output")) {
    RETURN_IF_ERROR(ParseOutput(*output, root.At("output"), spec.bodies, base_dir, &spec.output));
    // The wave summary reads two monitors' traces, which saturated cases write.
    if (spec.output.summary == "wave") {
      std::vector<std::string> monitors;
      for (const PressureMonitor& m : spec.phases.monitors) monitors.push_back(m.name);
      for (const auto& [key, name] : {std::pair{"wave_from", spec.output.wave_from},
                                      std::pair{"wave_to", spec.output.wave_to}}) {
        if (std::find(monitors.begin(), monitors.end(), name) == monitors.end()) {
          return Bad(root.At("output") + "/" + key, "no monitor named ", Quote(name),
                     " (phases.monitors: ", absl::StrJoin(monitors, ", "), ")");
        }
      }
      if (spec.output.wave_from == spec.output.wave_to) {
        return Bad(root.At("output") + "/wave_to", "must name another monitor than wave_from");
      }
    }
  }
  if (const Json* checks = root.Get("checks")) {
    RETURN_IF_ERROR(client_case::ParseChecks(*checks, root.At("checks"), &spec.checks));
  }
  // Refused here rather than as std::bad_alloc an hour into setting up.
  if (const CaseSize size = EstimateSize(spec); size.bytes > kMaxCaseBytes) {
    return Bad("/grid",
               absl::StrFormat(
                   "the case needs about %.1f GiB (%d grid nodes, %d material points "
                   "with their RVEs), more than the limit of %.0f GiB: use a coarser grid "
                   "or smaller regions",
                   size.bytes / (1 << 30), size.nodes, size.points, kMaxCaseBytes / (1 << 30)));
  }
  return spec;
}

OrderedJson WriteCase(const CaseSpec& spec) {
  OrderedJson doc;
  doc["name"] = spec.name;
  doc["description"] = spec.description;
  doc["expected_runtime_s"] = spec.expected_runtime_s;

  doc["grid"] = WriteGrid(spec.grid);
  doc["solver"] = WriteSolver(spec.solver);

  OrderedJson& templates = doc["templates"] = OrderedJson::array();
  for (const TemplateSpec& t : spec.templates) {
    templates.push_back(WriteTemplate(t));
  }

  OrderedJson& regions = doc["regions"] = OrderedJson::array();
  for (const MaterialRegion& r : spec.regions) regions.push_back(WriteRegion(r));

  OrderedJson& walls = doc["walls"] = OrderedJson::array();
  for (const Wall& w : spec.walls) walls.push_back(WriteWall(w));

  OrderedJson& bodies = doc["bodies"] = OrderedJson::array();
  for (const RigidBody& b : spec.bodies) bodies.push_back(WriteBody(b));

  OrderedJson& tractions = doc["tractions"] = OrderedJson::array();
  for (const SurfaceTraction& t : spec.tractions) {
    tractions.push_back(WriteTraction(t));
  }

  doc["rve"] = WriteRve(spec.rve, kRveKeys);
  if (spec.phases.saturated) doc["phases"] = WritePhases(spec.phases);
  doc["output"] = WriteOutput(spec.output);
  doc["checks"] = client_case::WriteChecks(spec.checks);
  return doc;
}

}  // namespace
}  // namespace case_internal

CaseSize EstimateSize(const CaseSpec& spec) {
  CaseSize size;
  size.nodes = (static_cast<std::int64_t>(spec.grid.nx) + 1) * (spec.grid.ny + 1);
  std::map<std::string, double> rve_bytes;
  for (const TemplateSpec& t : spec.templates) {
    rve_bytes[t.name] = kRveBytesPerDisc * case_internal::EstimatedDiscs(t);
  }
  double bytes = kBytesPerNode * static_cast<double>(size.nodes);
  for (const MaterialRegion& r : spec.regions) {
    double points = static_cast<double>(r.points_per_cell_side) * r.points_per_cell_side;
    for (int d = 0; d < 2; ++d) {
      points *= std::max(0.0, std::round((r.upper[d] - r.lower[d]) / spec.grid.cell_size));
    }
    size.points += static_cast<std::int64_t>(points);
    bytes += points * (kBytesPerPoint + rve_bytes[r.rve_template]);
  }
  size.bytes = bytes;
  return size;
}

absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir) {
  return ParseCase(json_text, base_dir, {});
}

absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir,
                                   std::span<const CaseOverride> overrides) {
  ASSIGN_OR_RETURN(fields::Json doc, fields::ParseJson(json_text));
  RETURN_IF_ERROR(client_case::ApplyOverrides(overrides, doc));
  return case_internal::ReadCase(doc, base_dir);
}

absl::StatusOr<CaseSpec> LoadCase(const std::string& path,
                                  std::span<const CaseOverride> overrides) {
  ASSIGN_OR_RETURN(std::string text, ReadTextFile(path, "case file"));
  const std::filesystem::path file(path);
  const std::string dir = file.has_parent_path() ? file.parent_path().string() : ".";
  absl::StatusOr<CaseSpec> spec = ParseCase(text, dir, overrides);
  if (!spec.ok()) {
    return absl::Status(spec.status().code(), absl::StrCat(path, ": ", spec.status().message()));
  }
  if (spec->name.empty()) spec->name = file.stem().string();
  return spec;
}

std::string ToJson(const CaseSpec& spec) {
  return fields::FormatJson(case_internal::WriteCase(spec));
}

}  // namespace rvehub::mpm
