// Bad case files (mpm_client/case.h): each kind of bad field, document and
// hydraulic input is an InvalidArgument naming the JSON pointer of the bad
// value (or the line and column of a syntax error).
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "gtest/gtest.h"
#include "mpm_client/case/case.h"
#include "tests/mpm_client/case/case_test_util.h"

namespace rvehub::mpm::case_test {
namespace {

struct BadEdit {
  std::string pointer;  // where to edit the full case
  Json value;           // kRemove: remove the key
  std::string message;  // the expected start of the error message
};

TEST_F(CaseTest, BadFieldsNameTheirPointer) {
  const std::vector<BadEdit> edits = {
      // Unknown keys (typos), with a suggestion.
      {"/solver/pic_fracton", 0.1,
       "/solver/pic_fracton: unknown key (did you mean \"pic_fraction\"?"},
      {"/colour", "red", "/colour: unknown key (keys here: name, description"},
      // Wrong types.
      {"/grid/cell_size", "0.5", "/grid/cell_size: must be a number, got string \"0.5\""},
      {"/grid/origin", {1, 2, 3}, "/grid/origin: must be an array of 2 numbers [x, y]"},
      {"/grid/cells/1", 4.5, "/grid/cells/1: must be an integer in 1..100000, got 4.5"},
      {"/regions", Json::object(), "/regions: must be an array"},
      {"/walls/0", 3, "/walls/0: must be an object, got number 3"},
      {"/name", 3, "/name: must be a string, got number 3"},
      // Missing required keys.
      {"/solver/end_time", kRemove, "/solver/end_time: required key is missing"},
      {"/grid", kRemove, "/grid: required key is missing"},
      {"/templates", kRemove, "/templates: required key is missing"},
      {"/templates", Json::array(), "/templates: must not be empty"},
      {"/regions/0/template", kRemove, "/regions/0/template: required key is missing"},
      {"/walls/2/friction", kRemove, "/walls/2/friction: required key is missing"},
      // Out of range.
      {"/solver/pic_fraction", 1.5, "/solver/pic_fraction: must be in [0, 1], got 1.5"},
      {"/solver/cfl", 0, "/solver/cfl: must be in (0, 1], got 0"},
      // Unbounded DEM work per increment.
      {"/rve/min_steps", 1e15, "/rve/min_steps: must be an integer in 0..100000"},
      {"/rve/max_inertial_number", 0.5, "/rve/max_inertial_number: must be in [0, 0.1], got 0.5"},
      // What check took and run refused.
      {"/rve/max_inertial_number", 1e-300,
       "/rve/max_inertial_number: must be 0 (the template's) or in [1e-06, 0.1], got 1e-300"},
      {"/solver/end_time", 0, "/solver/end_time: must be in (0, 1000000], got 0"},
      {"/solver/gravity", Json::array({0, -1e13}),
       "/solver/gravity/1: must be at most 1e+12 in magnitude, got -1e+13"},
      {"/grid/cell_size", 1e13, "/grid/cell_size: must be at most 1e+12 in magnitude, got 1e+13"},
      {"/solver/time_step", -1e-3, "/solver/time_step: must be in [0, 1000000], got -0.001"},
      {"/solver/thickness", 0, "/solver/thickness: must be > 0, got 0"},
      // Positive numbers have a floor too (1e-308 overflowed mid-run to NaN).
      {"/solver/thickness", 1e-308,
       "/solver/thickness: must be at least 1e-12 (the smallest positive value a case takes), "
       "got 1e-308"},
      {"/solver/cfl", 1e-13, "/solver/cfl: must be at least 1e-12"},
      {"/grid/cell_size", -0.5, "/grid/cell_size: must be > 0, got -0.5"},
      {"/regions/0/points_per_cell_side", 0,
       "/regions/0/points_per_cell_side: must be an integer in 1..8, got 0"},
      {"/regions/0/initial_stress/k0", 0, "/regions/0/initial_stress/k0: must be > 0, got 0"},
      {"/walls/2/friction", 0, "/walls/2/friction: must be > 0, got 0"},
      {"/walls/0/unilateral", "yes",
       "/walls/0/unilateral: must be true or false, got string \"yes\""},
      {"/walls/2/shaking_frequency", 0, "/walls/2/shaking_frequency: must be in (0, 1000], got 0"},
      {"/walls/2/shaking_amplitude", Json::array({500, 0}),
       "/walls/2/shaking_amplitude/0: must be in [-100, 100], got 500"},
      {"/walls/0/shaking_frequency", 2,
       "/walls/0/shaking_frequency: only with a shaking_amplitude other than [0, 0]"},
      {"/solver/shaking_frequency", -1, "/solver/shaking_frequency: must be in (0, 1000], got -1"},
      {"/solver/shaking_amplitude", Json::array({0, 1e3}),
       "/solver/shaking_amplitude/1: must be in [-100, 100], got 1000"},
      {"/bodies/0/half_size/1", -1, "/bodies/0/half_size/1: must be > 0, got -1"},
      {"/output/frame_every", 0, "/output/frame_every: must be an integer >= 1, got 0"},
      {"/output/checkpoint_every", -1, "/output/checkpoint_every: must be an integer >= 0, got -1"},
      {"/templates/0/seed", -1, "/templates/0/seed: must be an integer in 0..18446744073709551615"},
      // Enumerations.
      {"/walls/2/kind", "sticky",
       "/walls/2/kind: unknown wall kind \"sticky\" (fixed, rough, roller, smooth, symmetry, "
       "frictional)"},
      {"/solver/shape", "cubic", "/solver/shape: unknown shape function \"cubic\" (linear, gimp)"},
      {"/solver/lost_points", "remove",
       "/solver/lost_points: unknown lost-point policy \"remove\" (stop, drop)"},
      {"/solver/f_bar", "cell", "/solver/f_bar: unknown F-bar kind \"cell\" (none, nodal)"},
      {"/solver/nonlocal_radius", -0.1, "/solver/nonlocal_radius: must be >= 0, got -0.1"},
      {"/solver/nonlocal_fraction", 0, "/solver/nonlocal_fraction: must be in (0, 1], got 0"},
      {"/solver/nonlocal_fraction", 1.5, "/solver/nonlocal_fraction: must be in (0, 1], got 1.5"},
      // The full case has F-bar.
      {"/solver/nonlocal_radius", 1.0, "/solver/nonlocal_radius: not together with solver.f_bar"},
      {"/solver/mass_scale", 0.5, "/solver/mass_scale: must be in [1, 1000000], got 0.5"},
      // The full case fixes its time step.
      {"/solver/time_step_update_every", 100,
       "/solver/time_step_update_every: only where the time step comes from the RVEs' tangent "
       "(solver.time_step and solver.wave_modulus 0)"},
      {"/rve/max_stretch", 0.6, "/rve/max_stretch: must be in [0, 0.5], got 0.6"},
      {"/rve/max_stretch", 0.001,
       "/rve/max_stretch: must be 0 (the template's) or in [0.01, 0.5], got 0.001"},
      {"/rve/max_void_ratio", 0.05,
       "/rve/max_void_ratio: must be 0 (no cap) or in [0.1, 10], got 0.05"},
      {"/tractions/0/surface", "x", "/tractions/0/surface: unknown surface \"x\" (+x, -x, +y, -y)"},
      // Dangling references.
      {"/regions/1/template", "dense2",
       "/regions/1/template: no template named \"dense2\" (templates: dense, stored)"},
      {"/tractions/0/region", "rock", "/tractions/0/region: no region named \"rock\""},
      {"/output/plot_body", "pile", "/output/plot_body: no body named \"pile\" (bodies: footing"},
      {"/output/phi_deg", 95, "/output/phi_deg: must be in (0, 90), got 95"},
      {"/output/reference_curve", "reference.csv",
       "/output/reference_curve: only for plot \"stress-strain\""},
      {"/output/summary", "fancy",
       "/output/summary: unknown summary \"fancy\" (footing, pipe, collapse, biaxial, shaking, "
       "consolidation, crs, wave, none)"},
      {"/output/plot_body", kRemove, "/output/plot_body: required key is missing"},
      // Checks.
      {"/checks", Json::object(), "/checks: must be an array of checks, got object"},
      {"/checks/0/quantity", kRemove, "/checks/0/quantity: required key is missing"},
      {"/checks/0/quantity", "N q",
       "/checks/0/quantity: keys of summary.json use letters, digits, '_', '-' and '.' only"},
      {"/checks/0/reference", Json::array({1}),
       "/checks/0/reference: must be a number or a key of summary.json, got array"},
      {"/checks/1/reference", "N_q", "/checks/1/reference: is the checked quantity itself"},
      {"/checks/0/reference", 1e13,
       "/checks/0/reference: must be at most 1e+12 in magnitude, got 1e+13"},
      {"/checks/0/relative_tolerance", kRemove,
       "/checks/0: give exactly one of \"relative_tolerance\" ([-], of the reference) or "
       "\"absolute_tolerance\""},
      {"/checks/0/absolute_tolerance", 1, "/checks/0: give exactly one of"},
      {"/checks/0/relative_tolerance", 0,
       "/checks/0/relative_tolerance: must be in (0, 10], got 0"},
      {"/checks/2/absolute_tolerance", -1, "/checks/2/absolute_tolerance: must be >= 0, got -1"},
      {"/checks/0/reference", 0,
       "/checks/0/relative_tolerance: a relative tolerance needs a non-zero reference"},
      {"/checks/0/source", kRemove, "/checks/0/source: required key is missing"},
      {"/checks/0/source", "", "/checks/0/source: must be a non-empty string"},
      {"/checks/0/bound", "below", "/checks/0/bound: unknown bound \"below\" (upper, lower)"},
      {"/checks/0/bound", 1, "/checks/0/bound: must be a string (upper, lower), got "},
      {"/checks/0/tolerance", 0.1,
       "/checks/0/tolerance: unknown key (keys here: quantity, reference, relative_tolerance, "
       "absolute_tolerance, bound, source)"},
      // Parameter sets and template files.
      {"/templates/0/parameter_set", "SET-foo",
       "/templates/0/parameter_set: unknown parameter set \"SET-foo\" (known: SET-dense, "
       "SPFEM-biaxial, "},
      {"/templates/0/file", "packings/x.h5", "/templates/0: give exactly one of \"file\""},
      {"/templates/1/file", "packings/missing.h5", "/templates/1/file: no such file \"/"},
      {"/templates/1/seed", 3, "/templates/1/seed: only for templates prepared"},
      {"/templates/1/pressure", 5000, "/templates/1/pressure: only for templates prepared"},
      {"/templates/0/pressure", 0, "/templates/0/pressure: must be in (0, 1000000000], got 0"},
      {"/templates/0/pressure", -1, "/templates/0/pressure: must be in (0, 1000000000], got -1"},
      {"/templates/1/void_ratio", 0.2, "/templates/1/void_ratio: only for templates prepared"},
      {"/templates/0/void_ratio", 0, "/templates/0/void_ratio: must be in (0, 1), got 0"},
      {"/templates/0/void_ratio", 1.2, "/templates/0/void_ratio: must be in (0, 1), got 1.2"},
      {"/templates/1/particles", 1600, "/templates/1/particles: only for templates prepared"},
      {"/templates/1/rolling_eta", 0.02, "/templates/1/rolling_eta: only for templates prepared"},
      {"/templates/0/particles", 1,
       "/templates/0/particles: must be an integer in 2..1000000, got 1"},
      {"/templates/0/particles", 1000001,
       "/templates/0/particles: must be an integer in 2..1000000, got 1000001"},
      {"/templates/0/particles", 16.5,
       "/templates/0/particles: must be an integer in 2..1000000, got 16.5"},
      // Geometry: off the grid, outside it, empty, overlapping.
      {"/regions/0/lower/0", 0.25,
       "/regions/0/lower/0: x = 0.25 m is not on a grid line (origin 0 m, cell size 0.5 m)"},
      {"/regions/1/upper/1", 2.5, "/regions/1/upper/1: y = 2.5 m is outside the grid, y in [0, 2]"},
      {"/regions/1/upper/1", 1, "/regions/1/upper/1: upper y = 1 m must be above lower y = 1 m"},
      {"/regions/1/lower/1", 0.5,
       "/regions/1: region \"top\" overlaps region \"soil\" (/regions/0)"},
      {"/walls/0/position", 0.3, "/walls/0/position: y = 0.3 m is not on a grid line"},
      {"/walls/1/position", -0.5, "/walls/1/position: x = -0.5 m is outside the grid"},
      // Duplicate names.
      {"/walls/1/name", "base", "/walls/1/name: duplicate wall name \"base\" (also /walls/0)"},
      {"/templates/1/name", "dense", "/templates/1/name: duplicate template name \"dense\""},
      {"/regions/1/name", "soil", "/regions/1/name: duplicate region name \"soil\""},
      {"/bodies/1/name", "footing", "/bodies/1/name: duplicate body name \"footing\""},
      {"/tractions/2/name", "load", "/tractions/2/name: duplicate traction name \"load\""},
      {"/regions/0/name", "my soil", "/regions/0/name: names use letters, digits"},
      {"/templates/0/name", std::string(33, 'a'),
       "/templates/0/name: names have at most 32 characters, got 33"},
      // Velocity histories.
      {"/bodies/0/velocity/1/0", 0,
       "/bodies/0/velocity/1/0: times must increase strictly, got 0 s after 0 s"},
      {"/bodies/0/velocity/1", {0.2, 0}, "/bodies/0/velocity/1: must be an array of 3 numbers"},
      // Keys that do not apply.
      {"/regions/1/initial_stress/k0", 0.5,
       "/regions/1/initial_stress/k0: only for kind \"geostatic_k0\""},
      {"/walls/0/friction", 0.4, "/walls/0/friction: only for kind \"frictional\""},
      {"/solver/gravity",
       {0, 0},
       "/regions/1/initial_stress/kind: a geostatic start without gravity needs a surcharge"},
      {"/bodies/0/radius", 0.4, "/bodies/0/radius: only for shape \"circle\""},
      {"/output/plot", "none", "/output/plot_body: only for plot \"load-settlement\""},
      // Tractions: one of pressure / traction, on a free part of a face.
      {"/tractions/0/traction", {1, 0}, "/tractions/0: give exactly one of \"pressure\""},
      {"/tractions/0/surface", "+y",
       "/tractions/0/surface: the +y face of region \"soil\" touches region \"top\" (/regions/1) "
       "for x in [0, 1] m"},
      {"/tractions/1/from", 2, "/tractions/1/to: must be > from = 2 m, got 0.5"},
      // Load histories: [t, factor] pairs, times increasing, not with a ramp.
      {"/tractions/2/history/1/0", 0,
       "/tractions/2/history/1/0: times must increase strictly, got 0 s after 0 s"},
      {"/tractions/2/history/1", {0.2}, "/tractions/2/history/1: must be an array of 2 numbers"},
      {"/tractions/2/history", Json::array(), "/tractions/2/history: must be a non-empty array"},
      {"/tractions/0/history",
       {{0, 1}},
       "/tractions/0/history: give either \"history\" or \"ramp_time\", not both"},
  };
  for (const BadEdit& edit : edits) {
    SCOPED_TRACE(edit.pointer);
    absl::StatusOr<CaseSpec> spec = ParseEdited(edit.pointer, edit.value);
    ASSERT_FALSE(spec.ok()) << "accepted: " << edit.pointer;
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument) << spec.status();
    EXPECT_TRUE(MessageStartsWith(spec.status(), edit.message));
  }
  EXPECT_GE(edits.size(), 15u);
}

TEST_F(CaseTest, TractionWindowMustMeetTheFace) {
  Json doc = Json::parse(kFullCase);
  doc["tractions"][1]["from"] = 1.5;
  doc["tractions"][1]["to"] = 2.0;
  absl::StatusOr<CaseSpec> spec = Parse(doc.dump());
  ASSERT_FALSE(spec.ok());
  EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(MessageStartsWith(spec.status(),
                                "/tractions/1/from: [from, to] = [1.5, 2] m misses the +y face of "
                                "region \"top\", x in [0, 1] m"));
}

// Errors found before the document is walked.
TEST_F(CaseTest, BadDocuments) {
  struct Bad {
    std::string text;
    std::string message;
  };
  const std::vector<Bad> bad = {
      {"{\n  \"grid\": tru\n}",
       "line 2, column 13: syntax error while parsing value - invalid literal"},
      {"{\"grid\": {}, }", "line 1, column 14: syntax error"},
      {"", "line 1, column 1: syntax error"},
      {"{\n\n  \"solver\": {\"end_time\": 1e400}}", "line 3, column 26: number overflow"},
      {"[1, 2]", "(document): must be an object, got array [1,2]"},
      {R"({"grid": {"cell_size": 0.5, "cells": [2, 2], "cell_size": 1}})",
       "/grid/cell_size: duplicate key"},
      {R"({"regions": [{"name": "a"}, {"name": "b", "name": "c"}]})",
       "/regions/1/name: duplicate key"},
  };
  for (const Bad& b : bad) {
    SCOPED_TRACE(b.text);
    absl::StatusOr<CaseSpec> spec = Parse(b.text);
    ASSERT_FALSE(spec.ok());
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument) << spec.status();
    EXPECT_TRUE(MessageStartsWith(spec.status(), b.message));
  }
}

// A water table above the soil's top is refused where the free surface
// drains (it holds p = 0: free water over the soil is not modelled); at the
// top, as the shipped cases set it, or below it, it is read.
TEST(SaturatedCase, AWaterTableAboveTheSoilIsRefused) {
  const fs::path path = fs::path(RVEHUB_SOURCE_DIR) / "cases" / "cyclic-shaking-medium-ci.json";
  std::ifstream in(path);
  Json doc = Json::parse(in);
  for (const double table : {1.0, 0.5}) {
    doc["phases"]["water_table"] = table;
    EXPECT_TRUE(ParseCase(doc.dump(), path.parent_path().string()).ok()) << table;
  }
  doc["phases"]["water_table"] = 11.0;
  const absl::StatusOr<CaseSpec> above = ParseCase(doc.dump(), path.parent_path().string());
  ASSERT_FALSE(above.ok());
  EXPECT_EQ(above.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(absl::StrContains(above.status().message(),
                                "/phases/water_table: y = 11 m lies above the soil's top, y = 1 m"))
      << above.status();
}

// The wave summary's monitors must be two of the case's; its keys belong to
// it alone (the shipped wave-propagation-ci).
TEST(SaturatedCase, TheWaveSummaryNamesTwoOfTheCasesMonitors) {
  const fs::path path = fs::path(RVEHUB_SOURCE_DIR) / "cases" / "wave-propagation-ci.json";
  std::ifstream in(path);
  const Json base = Json::parse(in);
  ASSERT_TRUE(ParseCase(base.dump(), path.parent_path().string()).ok());
  const std::vector<std::pair<std::pair<std::string, Json>, std::string>> edits = {
      {{"/output/wave_from", "R9"},
       "/output/wave_from: no monitor named \"R9\" (phases.monitors: A, B, C, R3, R5, R7)"},
      {{"/output/wave_to", "R3"}, "/output/wave_to: must name another monitor than wave_from"},
      {{"/output/wave_window", 0}, "/output/wave_window: must be > 0, got 0"},
      {{"/output/summary", "none"}, "/output/wave_from: only for a wave summary"},
  };
  for (const auto& [edit, message] : edits) {
    SCOPED_TRACE(edit.first);
    Json doc = base;
    doc[Json::json_pointer(edit.first)] = edit.second;
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), path.parent_path().string());
    ASSERT_FALSE(spec.ok());
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(MessageStartsWith(spec.status(), message)) << spec.status();
  }
  Json doc = base;
  doc["output"].erase("wave_window");
  absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), path.parent_path().string());
  ASSERT_FALSE(spec.ok());
  EXPECT_TRUE(MessageStartsWith(spec.status(), "/output/wave_window: required key is missing"))
      << spec.status();
}

// Bad hydraulic input in a saturated case (the shipped consolidation-1d-ci)
// names its pointer: k <= 0, porosity outside (0, 1), a drained line no soil
// reaches, no drained boundary at all, a monitor outside the soil, a free
// surface widened where none is drained.
TEST(SaturatedCase, BadHydraulicInputNamesItsPointer) {
  const fs::path path = fs::path(RVEHUB_SOURCE_DIR) / "cases" / "consolidation-1d-ci.json";
  std::ifstream in(path);
  const Json base = Json::parse(in);
  ASSERT_TRUE(ParseCase(base.dump(), path.parent_path().string()).ok());
  const std::vector<std::pair<std::string, Json>> edits = {
      {"/phases/permeability", 0},
      {"/phases/permeability", -1e-3},
      {"/phases/porosity", 1.0},
      {"/phases/porosity", -0.1},
      {"/phases/fluid_density", 0},
      {"/phases/drained/0/position", 2.0},
      {"/phases/drained/0/position", 0.55},
      {"/phases/drained", Json::array()},
      {"/phases/monitors/0/position", {0.5, 0.5}},
      {"/phases/drainage", true},
      {"/phases/projection", "implicit"},
      {"/phases/excess_pressure_from", "current_water_table"},
      {"/solver/lost_points", "drop"},
      {"/solver/mass_scale", 100},
      {"/rve/max_void_ratio", 0.3},
      {"/solver/time_step_update_every", 100},
      {"/solver/nonlocal_radius", 0.2},
      {"/phases/free_surface_beside_light_nodes", true},
  };
  const std::vector<std::string> messages = {
      "/phases/permeability: must be in (0, 10], got 0",
      "/phases/permeability: must be in (0, 10], got -0.001",
      "/phases/porosity: must be in [0, 1), got 1",
      "/phases/porosity: must be in [0, 1), got -0.1",
      "/phases/fluid_density: must be in (0, 20000], got 0",
      "/phases/drained/0/position: y = 2 m is outside the grid",
      "/phases/drained/0/position: y = 0.55 m is not on a grid line",
      "/phases/drained: a saturated case needs at least one drained boundary",
      "/phases/monitors/0/position: (0.5, 0.5) m is in no region",
      "/phases/drainage: unknown key",
      "/phases/projection: unknown projection \"implicit\"",
      "/phases/excess_pressure_from: unknown excess pressure datum \"current_water_table\"",
      "/solver/lost_points: \"drop\" is for dry cases only",
      "/solver/mass_scale: mass scaling is for dry cases only",
      "/rve/max_void_ratio: a void-ratio cap is for dry cases only",
      "/solver/time_step_update_every: an updated time step is for dry cases only",
      "/solver/nonlocal_radius: a nonlocal strain is for dry cases only",
      "/phases/free_surface_beside_light_nodes: needs drained_free_surface",
  };
  for (std::size_t i = 0; i < edits.size(); ++i) {
    SCOPED_TRACE(edits[i].first);
    Json doc = base;
    doc[Json::json_pointer(edits[i].first)] = edits[i].second;
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), path.parent_path().string());
    ASSERT_FALSE(spec.ok());
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(MessageStartsWith(spec.status(), messages[i])) << spec.status();
  }
  // Rigid bodies are read in a saturated case too (impermeable platens).
  Json with_body = base;
  with_body["bodies"] = Json::array({{{"name", "plate"},
                                      {"shape", "rectangle"},
                                      {"center", {0.01, 1.1}},
                                      {"half_size", {0.01, 0.05}}}});
  absl::StatusOr<CaseSpec> body = ParseCase(with_body.dump(), path.parent_path().string());
  ASSERT_TRUE(body.ok()) << body.status();
  ASSERT_EQ(body->bodies.size(), 1u);
  EXPECT_TRUE(body->phases.saturated);
  // So is F-bar: the effective stress's volume change shared over the nodes.
  Json with_f_bar = base;
  with_f_bar["solver"]["f_bar"] = "nodal";
  absl::StatusOr<CaseSpec> f_bar = ParseCase(with_f_bar.dump(), path.parent_path().string());
  ASSERT_TRUE(f_bar.ok()) << f_bar.status();
  EXPECT_EQ(f_bar->solver.f_bar, FBar::kNodal);
  EXPECT_TRUE(f_bar->phases.saturated);
  // Single shaken walls are refused: a saturated box is shaken whole, in its
  // frame (solver.shaking_amplitude).
  Json shaken = base;
  shaken["walls"][0]["shaking_amplitude"] = {0.05, 0};
  shaken["walls"][0]["shaking_frequency"] = 2;
  absl::StatusOr<CaseSpec> refused = ParseCase(shaken.dump(), path.parent_path().string());
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(MessageStartsWith(
      refused.status(), "/walls/0/shaking_amplitude: a saturated case shakes its whole box"))
      << refused.status();
  // A drained line on the grid but away from the soil: widen the grid.
  Json doc = base;
  doc["grid"]["cells"][0] = 3;
  doc["phases"]["drained"][0] = {{"name", "far"}, {"line", "x"}, {"position", 0.3}};
  absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), path.parent_path().string());
  ASSERT_FALSE(spec.ok());
  EXPECT_TRUE(MessageStartsWith(spec.status(),
                                "/phases/drained/0/position: no region reaches the line x = 0.3 m"))
      << spec.status();
}

}  // namespace
}  // namespace rvehub::mpm::case_test
