// Case files (mpm_client/case.h): a full case parses into the expected
// CaseSpec (with the compression-positive → tension-positive conversion),
// ToJson round-trips, defaults match model.h, and each kind of bad input is
// an InvalidArgument naming the JSON pointer of the bad field.
#include "mpm_client/case.h"

#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"
#include "mpm_client/elastic.h"
#include "mpm_client/solver.h"
#include "tests/env_util.h"

namespace rvehub::mpm {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// gmock is not linked: plain predicates for status messages.
::testing::AssertionResult MessageStartsWith(const absl::Status& status, absl::string_view prefix) {
  if (absl::StartsWith(status.message(), prefix)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "message does not start with '" << prefix << "': " << status;
}
::testing::AssertionResult MessageHas(const absl::Status& status, absl::string_view part) {
  if (absl::StrContains(status.message(), part)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not in: " << status;
}

// Every section, with non-default values wherever a default exists. The grid
// is 2 m × 2 m (4 × 4 cells of 0.5 m); "soil" fills [0, 1]², "top" sits on it.
constexpr char kFullCase[] = R"json({
  "name": "full",
  "description": "every section",
  "expected_runtime_s": 12.5,
  "grid": {"origin": [0, 0], "cell_size": 0.5, "cells": [4, 4]},
  "solver": {"shape": "gimp", "pic_fraction": 0.05, "gravity": [0, -9.81], "time_step": 1e-4,
             "cfl": 0.4, "wave_modulus": 2.5e7, "end_time": 1.5, "thickness": 0.1,
             "shaking_amplitude": [0.05, 0], "shaking_frequency": 2, "f_bar": "nodal"},
  "templates": [
    {"name": "dense", "parameter_set": "SET-dense", "seed": 7, "pressure": 6600, "void_ratio": 0.19,
     "particles": 1600},
    {"name": "stored", "file": "packings/x.h5", "template_name": "loose-1"}
  ],
  "regions": [
    {"name": "soil", "lower": [0, 0], "upper": [1, 1], "points_per_cell_side": 3,
     "template": "dense", "density": 1800,
     "initial_stress": {"kind": "geostatic_k0", "k0": 0.45, "surface_y": 1.5,
                        "surcharge": 20e3, "minimum": 1000}},
    {"name": "top", "lower": [0, 1], "upper": [1, 1.5], "template": "stored",
     "initial_stress": {"kind": "geostatic_isotropic"}}
  ],
  "walls": [
    {"name": "base", "kind": "fixed", "line": "y", "position": 0, "unilateral": true},
    {"name": "left", "kind": "roller", "line": "x", "position": 0, "remove_time": 0.1},
    {"name": "right", "kind": "frictional", "line": "x", "position": 2, "friction": 0.4,
     "shaking_amplitude": [0.0785, 0], "shaking_frequency": 2.5}
  ],
  "bodies": [
    {"name": "footing", "shape": "rectangle", "center": [0.5, 1.75], "half_size": [0.25, 0.25],
     "velocity": [[0, 0, 0], [0.1, 0, -0.1]]},
    {"name": "ball", "shape": "circle", "center": [1.5, 1.5], "radius": 0.2,
     "contact": "frictional", "friction": 0.3}
  ],
  "tractions": [
    {"name": "confining", "region": "soil", "surface": "+x", "pressure": 100e3,
     "ramp_time": 0.01},
    {"name": "load", "region": "top", "surface": "+y", "traction": [0, -2e4], "from": 0,
     "to": 0.5},
    {"name": "side", "region": "top", "surface": "-x", "pressure": 5e3,
     "history": [[0, 0], [0.01, 1], [0.02, 0]]}
  ],
  "rve": {"max_inertial_number": 1e-3, "min_steps": 50, "max_stretch": 0.2, "real_time": true},
  "output": {"frame_every": 50, "timeseries_every": 5, "checkpoint_every": 1000,
             "progress_every": 10, "plot": "load-settlement", "plot_body": "footing",
             "plot_width": 0.5, "phi_deg": 30}
})json";

// The smallest valid case: everything else takes model.h's defaults.
// In a BadEdit: remove the key instead of setting it.
const Json kRemove(Json::value_t::discarded);

constexpr char kMinimalCase[] = R"json({
  "grid": {"cell_size": 0.5, "cells": [2, 2]},
  "solver": {"end_time": 1},
  "templates": [{"name": "t", "parameter_set": "SET-dense"}],
  "regions": [{"name": "r", "lower": [0, 0], "upper": [1, 0.5], "template": "t"}]
})json";

class CaseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / absl::StrCat("case_test_", getpid());
    fs::create_directories(dir_ / "packings");
    std::ofstream(dir_ / "packings" / "x.h5") << "not read by the parser";
  }
  void TearDown() override { fs::remove_all(dir_); }

  absl::StatusOr<CaseSpec> Parse(absl::string_view text) { return ParseCase(text, dir_.string()); }

  // The full case with the value at `pointer` replaced (or removed when
  // `value` is empty), parsed.
  absl::StatusOr<CaseSpec> ParseEdited(const std::string& pointer, const Json& value) {
    Json doc = Json::parse(kFullCase);
    const Json::json_pointer p(pointer);
    if (value.is_discarded()) {
      doc[p.parent_pointer()].erase(p.back());
    } else {
      doc[p] = value;
    }
    return Parse(doc.dump(2));
  }

  fs::path dir_;
};

TEST_F(CaseTest, FullCaseParsesIntoExpectedSpec) {
  absl::StatusOr<CaseSpec> spec = Parse(kFullCase);
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->name, "full");
  EXPECT_EQ(spec->description, "every section");
  EXPECT_EQ(spec->expected_runtime_s, 12.5);

  EXPECT_EQ(spec->grid.origin, Eigen::Vector2d(0, 0));
  EXPECT_EQ(spec->grid.cell_size, 0.5);
  EXPECT_EQ(spec->grid.nx, 4);
  EXPECT_EQ(spec->grid.ny, 4);

  const SolverSpec& s = spec->solver;
  EXPECT_EQ(s.shape, ShapeKind::kGimp);
  EXPECT_EQ(s.pic_fraction, 0.05);
  EXPECT_EQ(s.gravity, Eigen::Vector2d(0, -9.81));
  EXPECT_EQ(s.time_step, 1e-4);
  EXPECT_EQ(s.cfl, 0.4);
  EXPECT_EQ(s.wave_modulus, 2.5e7);
  EXPECT_EQ(s.end_time, 1.5);
  EXPECT_EQ(s.thickness, 0.1);

  ASSERT_EQ(spec->templates.size(), 2u);
  EXPECT_EQ(spec->templates[0].name, "dense");
  EXPECT_EQ(spec->templates[0].parameter_set, "SET-dense");
  EXPECT_EQ(spec->templates[0].seed, 7u);
  EXPECT_EQ(spec->templates[0].pressure, 6600);
  EXPECT_EQ(spec->templates[0].void_ratio, 0.19);
  EXPECT_EQ(spec->templates[0].particles, 1600);
  EXPECT_EQ(spec->templates[1].pressure, 0);
  EXPECT_EQ(spec->templates[1].particles, 0);
  EXPECT_EQ(spec->templates[0].file, "");
  EXPECT_EQ(spec->templates[1].name, "stored");
  EXPECT_EQ(spec->templates[1].parameter_set, "");
  // Resolved against base_dir, absolute.
  EXPECT_EQ(spec->templates[1].file, (fs::absolute(dir_) / "packings" / "x.h5").string());
  EXPECT_EQ(spec->templates[1].template_name, "loose-1");

  ASSERT_EQ(spec->regions.size(), 2u);
  const MaterialRegion& soil = spec->regions[0];
  EXPECT_EQ(soil.name, "soil");
  EXPECT_EQ(soil.lower, Eigen::Vector2d(0, 0));
  EXPECT_EQ(soil.upper, Eigen::Vector2d(1, 1));
  EXPECT_EQ(soil.points_per_cell_side, 3);
  EXPECT_EQ(soil.rve_template, "dense");
  EXPECT_EQ(soil.density, 1800);
  EXPECT_EQ(soil.initial_stress, InitialStressKind::kK0);
  EXPECT_EQ(soil.k0, 0.45);
  EXPECT_EQ(soil.surface_y, 1.5);
  EXPECT_EQ(soil.surcharge, 20e3);  // compression +, as model.h keeps it
  EXPECT_EQ(soil.minimum_stress, 1000);
  const MaterialRegion& top = spec->regions[1];
  EXPECT_EQ(top.points_per_cell_side, 2);
  EXPECT_EQ(top.density, 0.0);
  EXPECT_EQ(top.initial_stress, InitialStressKind::kIsotropic);
  EXPECT_EQ(top.surface_y, 1.5);  // defaults to the region's top

  ASSERT_EQ(spec->walls.size(), 3u);
  EXPECT_EQ(spec->walls[0].name, "base");
  EXPECT_EQ(spec->walls[0].axis, 1);
  EXPECT_EQ(spec->walls[0].position, 0.0);
  EXPECT_EQ(spec->walls[0].contact, ContactKind::kRough);
  EXPECT_EQ(spec->walls[0].remove_time, kNever);
  EXPECT_TRUE(spec->walls[0].unilateral);
  EXPECT_FALSE(spec->walls[1].unilateral);
  EXPECT_EQ(spec->walls[1].axis, 0);
  EXPECT_EQ(spec->walls[1].contact, ContactKind::kSmooth);
  EXPECT_EQ(spec->walls[1].remove_time, 0.1);
  EXPECT_EQ(spec->walls[2].position, 2.0);
  EXPECT_EQ(spec->walls[2].contact, ContactKind::kFrictional);
  EXPECT_EQ(spec->walls[2].friction, 0.4);
  EXPECT_EQ(spec->solver.shaking_amplitude, Eigen::Vector2d(0.05, 0.0));
  EXPECT_EQ(spec->solver.shaking_frequency, 2.0);
  EXPECT_EQ(spec->solver.f_bar, FBar::kNodal);
  EXPECT_EQ(spec->walls[2].shaking_amplitude, Eigen::Vector2d(0.0785, 0.0));
  EXPECT_EQ(spec->walls[2].shaking_frequency, 2.5);
  EXPECT_EQ(spec->walls[0].shaking_frequency, 0.0);

  ASSERT_EQ(spec->bodies.size(), 2u);
  const RigidBody& footing = spec->bodies[0];
  EXPECT_EQ(footing.shape, RigidBody::Shape::kRectangle);
  EXPECT_EQ(footing.center, Eigen::Vector2d(0.5, 1.75));
  EXPECT_EQ(footing.half_size, Eigen::Vector2d(0.25, 0.25));
  EXPECT_EQ(footing.contact, ContactKind::kRough);
  ASSERT_EQ(footing.velocity.size(), 2u);
  EXPECT_EQ(footing.velocity[1].time, 0.1);
  EXPECT_EQ(footing.velocity[1].velocity, Eigen::Vector2d(0, -0.1));
  const RigidBody& ball = spec->bodies[1];
  EXPECT_EQ(ball.shape, RigidBody::Shape::kCircle);
  EXPECT_EQ(ball.radius, 0.2);
  EXPECT_EQ(ball.contact, ContactKind::kFrictional);
  EXPECT_EQ(ball.friction, 0.3);
  EXPECT_TRUE(ball.velocity.empty());

  ASSERT_EQ(spec->tractions.size(), 3u);
  const SurfaceTraction& confining = spec->tractions[0];
  EXPECT_EQ(confining.region, "soil");
  EXPECT_EQ(confining.normal_axis, 0);
  EXPECT_EQ(confining.normal_sign, 1);
  // 100 kPa pressure on +x pushes along −x: tension-positive (−1e5, 0) Pa.
  EXPECT_EQ(confining.traction, Eigen::Vector2d(-1e5, 0));
  EXPECT_EQ(confining.ramp_time, 0.01);
  EXPECT_EQ(confining.from, -std::numeric_limits<double>::infinity());
  EXPECT_EQ(confining.to, std::numeric_limits<double>::infinity());
  const SurfaceTraction& load = spec->tractions[1];
  EXPECT_EQ(load.normal_axis, 1);
  EXPECT_EQ(load.normal_sign, 1);
  EXPECT_EQ(load.traction, Eigen::Vector2d(0, -2e4));
  EXPECT_EQ(load.from, 0.0);
  EXPECT_EQ(load.to, 0.5);
  // On −x the outward normal is (−1, 0): the pressure pushes along +x.
  EXPECT_EQ(spec->tractions[2].normal_sign, -1);
  EXPECT_EQ(spec->tractions[2].traction, Eigen::Vector2d(5e3, 0));
  EXPECT_TRUE(confining.history.empty());
  ASSERT_EQ(spec->tractions[2].history.size(), 3u);
  EXPECT_EQ(spec->tractions[2].history[1].time, 0.01);
  EXPECT_EQ(spec->tractions[2].history[1].factor, 1.0);

  EXPECT_EQ(spec->rve.max_inertial_number, 1e-3);
  EXPECT_EQ(spec->rve.min_steps, 50);
  EXPECT_EQ(spec->rve.max_stretch, 0.2);
  EXPECT_TRUE(spec->rve.real_time);

  EXPECT_EQ(spec->output.frame_every, 50);
  EXPECT_EQ(spec->output.timeseries_every, 5);
  EXPECT_EQ(spec->output.checkpoint_every, 1000);
  EXPECT_EQ(spec->output.progress_every, 10);
  EXPECT_EQ(spec->output.plot, "load-settlement");
  EXPECT_EQ(spec->output.plot_body, "footing");
  EXPECT_EQ(spec->output.phi_deg, 30.0);
  EXPECT_EQ(spec->output.summary, "");  // from the plot: a footing
  EXPECT_EQ(spec->output.plot_width, 0.5);
}

TEST_F(CaseTest, MinimalCaseTakesModelDefaults) {
  absl::StatusOr<CaseSpec> spec = Parse(kMinimalCase);
  ASSERT_TRUE(spec.ok()) << spec.status();
  const CaseSpec defaults;
  EXPECT_EQ(spec->name, "");
  EXPECT_EQ(spec->grid.origin, defaults.grid.origin);
  EXPECT_EQ(spec->solver.shape, defaults.solver.shape);
  EXPECT_EQ(spec->solver.pic_fraction, defaults.solver.pic_fraction);
  EXPECT_EQ(spec->solver.gravity, defaults.solver.gravity);
  EXPECT_EQ(spec->solver.time_step, defaults.solver.time_step);
  EXPECT_EQ(spec->solver.cfl, defaults.solver.cfl);
  EXPECT_EQ(spec->solver.time_step_update_every, 0);
  EXPECT_EQ(spec->solver.f_bar, FBar::kNone);
  EXPECT_EQ(spec->solver.nonlocal_radius, 0.0);
  EXPECT_EQ(spec->solver.nonlocal_fraction, 0.5);
  EXPECT_EQ(spec->solver.thickness, defaults.solver.thickness);
  EXPECT_EQ(spec->solver.shaking_amplitude, Eigen::Vector2d::Zero());
  EXPECT_EQ(spec->solver.shaking_frequency, 0.0);
  EXPECT_EQ(spec->templates[0].seed, 1u);
  EXPECT_EQ(spec->templates[0].pressure, 0);  // the set's p0
  const MaterialRegion region_defaults;
  EXPECT_EQ(spec->regions[0].points_per_cell_side, region_defaults.points_per_cell_side);
  EXPECT_EQ(spec->regions[0].initial_stress, InitialStressKind::kTemplate);
  EXPECT_EQ(spec->regions[0].surface_y, 0.5);
  EXPECT_TRUE(spec->walls.empty());
  EXPECT_TRUE(spec->bodies.empty());
  EXPECT_TRUE(spec->tractions.empty());
  EXPECT_EQ(spec->rve.min_steps, defaults.rve.min_steps);
  EXPECT_EQ(spec->rve.max_stretch, 0.0);
  EXPECT_EQ(spec->output.frame_every, defaults.output.frame_every);
  EXPECT_EQ(spec->output.checkpoint_every, defaults.output.checkpoint_every);
  EXPECT_EQ(spec->output.plot, "stress-strain");
}

// solver.time_step_update_every: a step count, written to the canonical form
// only when on (cases without it keep their canonical text).
TEST_F(CaseTest, TimeStepUpdateIsAStepCountWrittenOnlyWhenOn) {
  Json doc = Json::parse(kMinimalCase);
  absl::StatusOr<CaseSpec> off = Parse(doc.dump());
  ASSERT_TRUE(off.ok()) << off.status();
  EXPECT_FALSE(absl::StrContains(ToJson(*off), "time_step_update_every"));
  doc["solver"]["time_step_update_every"] = 100;
  absl::StatusOr<CaseSpec> on = Parse(doc.dump());
  ASSERT_TRUE(on.ok()) << on.status();
  EXPECT_EQ(on->solver.time_step_update_every, 100);
  EXPECT_TRUE(absl::StrContains(ToJson(*on), "\"time_step_update_every\": 100"));
  for (const Json& bad : {Json(-1), Json(2.5), Json(2e9)}) {
    doc["solver"]["time_step_update_every"] = bad;
    EXPECT_TRUE(
        MessageStartsWith(Parse(doc.dump()).status(),
                          "/solver/time_step_update_every: must be an integer in 0..1000000000"))
        << bad;
  }
}

// templates[].rolling_eta: another η for a set with rolling resistance,
// written to the canonical form only when given; refused, naming the field,
// outside [0, 1] or for a set without rolling resistance.
TEST_F(CaseTest, RollingEtaIsReadWrittenAndOnlyForSetsWithRollingResistance) {
  Json doc = Json::parse(kMinimalCase);
  doc["templates"][0]["parameter_set"] = "footing-dense";
  absl::StatusOr<CaseSpec> plain = Parse(doc.dump());
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_FALSE(plain->templates[0].rolling_eta.has_value());
  EXPECT_FALSE(absl::StrContains(ToJson(*plain), "rolling_eta"));
  doc["templates"][0]["rolling_eta"] = 0.02;
  absl::StatusOr<CaseSpec> spec = Parse(doc.dump());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->templates[0].rolling_eta, 0.02);
  absl::StatusOr<CaseSpec> again = Parse(ToJson(*spec));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->templates[0].rolling_eta, 0.02);
  doc["templates"][0]["rolling_eta"] = 0;  // no rolling resistance: a valid material
  spec = Parse(doc.dump());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->templates[0].rolling_eta, 0.0);
  for (const Json& bad : {Json(-0.01), Json(1.5), Json("0.02")}) {
    doc["templates"][0]["rolling_eta"] = bad;
    EXPECT_TRUE(MessageStartsWith(Parse(doc.dump()).status(), "/templates/0/rolling_eta: must be"))
        << bad;
  }
  doc["templates"][0]["parameter_set"] = "SET-dense";
  doc["templates"][0]["rolling_eta"] = 0.02;
  EXPECT_TRUE(MessageStartsWith(
      Parse(doc.dump()).status(),
      "/templates/0/rolling_eta: parameter set \"SET-dense\" has no rolling resistance (β = 0)"));
}

TEST_F(CaseTest, NonlocalRadiusAndFractionAreReadWrittenAndTheRadiusBoundedByTheCell) {
  Json doc = Json::parse(kMinimalCase);  // cells of 0.5 m
  doc["solver"]["nonlocal_radius"] = 1.25;
  doc["solver"]["nonlocal_fraction"] = 0.75;
  absl::StatusOr<CaseSpec> spec = Parse(doc.dump());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->solver.nonlocal_radius, 1.25);
  EXPECT_EQ(spec->solver.nonlocal_fraction, 0.75);
  absl::StatusOr<CaseSpec> again = Parse(ToJson(*spec));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->solver.nonlocal_radius, 1.25);
  EXPECT_EQ(again->solver.nonlocal_fraction, 0.75);
  for (double radius : {0.04, 4.5}) {
    doc["solver"]["nonlocal_radius"] = radius;
    spec = Parse(doc.dump());
    ASSERT_FALSE(spec.ok());
    EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(spec.status().message(),
              absl::StrCat("/solver/nonlocal_radius: ", radius,
                           " m must be 0 (off) or between 0.1 and 8 cells (0.05 to 4 m for "
                           "cells of 0.5 m)"));
  }
}

TEST_F(CaseTest, CoordinatesSnapOntoGridLines) {
  // 0.3 is not 3 × 0.1 in binary; the parser puts the corner on the line.
  Json doc = Json::parse(kMinimalCase);
  doc["grid"]["cell_size"] = 0.1;
  doc["grid"]["cells"] = {10, 10};
  doc["regions"][0]["lower"] = {0.3, 0.0};
  doc["regions"][0]["upper"] = {0.7, 0.6000000001};
  doc["walls"] = {{{"name", "w"}, {"kind", "smooth"}, {"line", "x"}, {"position", 0.3}}};
  absl::StatusOr<CaseSpec> spec = Parse(doc.dump());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->regions[0].lower.x(), 3 * 0.1);
  EXPECT_EQ(spec->regions[0].upper.x(), 7 * 0.1);
  EXPECT_EQ(spec->regions[0].upper.y(), 6 * 0.1);
  EXPECT_EQ(spec->walls[0].position, 3 * 0.1);
}

void ExpectSameSpec(const CaseSpec& a, const CaseSpec& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.description, b.description);
  EXPECT_EQ(a.expected_runtime_s, b.expected_runtime_s);
  EXPECT_EQ(a.grid.origin, b.grid.origin);
  EXPECT_EQ(a.grid.cell_size, b.grid.cell_size);
  EXPECT_EQ(a.grid.nx, b.grid.nx);
  EXPECT_EQ(a.grid.ny, b.grid.ny);
  EXPECT_EQ(a.solver.shape, b.solver.shape);
  EXPECT_EQ(a.solver.pic_fraction, b.solver.pic_fraction);
  EXPECT_EQ(a.solver.gravity, b.solver.gravity);
  EXPECT_EQ(a.solver.time_step, b.solver.time_step);
  EXPECT_EQ(a.solver.cfl, b.solver.cfl);
  EXPECT_EQ(a.solver.wave_modulus, b.solver.wave_modulus);
  EXPECT_EQ(a.solver.time_step_update_every, b.solver.time_step_update_every);
  EXPECT_EQ(a.solver.end_time, b.solver.end_time);
  EXPECT_EQ(a.solver.thickness, b.solver.thickness);
  EXPECT_EQ(a.solver.shaking_amplitude, b.solver.shaking_amplitude);
  EXPECT_EQ(a.solver.shaking_frequency, b.solver.shaking_frequency);
  EXPECT_EQ(a.solver.lost_points, b.solver.lost_points);
  EXPECT_EQ(a.solver.mass_scale, b.solver.mass_scale);
  EXPECT_EQ(a.solver.f_bar, b.solver.f_bar);
  EXPECT_EQ(a.solver.nonlocal_radius, b.solver.nonlocal_radius);
  EXPECT_EQ(a.solver.nonlocal_fraction, b.solver.nonlocal_fraction);
  ASSERT_EQ(a.templates.size(), b.templates.size());
  for (size_t i = 0; i < a.templates.size(); ++i) {
    SCOPED_TRACE(absl::StrCat("template ", i));
    EXPECT_EQ(a.templates[i].name, b.templates[i].name);
    EXPECT_EQ(a.templates[i].file, b.templates[i].file);
    EXPECT_EQ(a.templates[i].template_name, b.templates[i].template_name);
    EXPECT_EQ(a.templates[i].parameter_set, b.templates[i].parameter_set);
    EXPECT_EQ(a.templates[i].seed, b.templates[i].seed);
    EXPECT_EQ(a.templates[i].pressure, b.templates[i].pressure);
    EXPECT_EQ(a.templates[i].void_ratio, b.templates[i].void_ratio);
    EXPECT_EQ(a.templates[i].particles, b.templates[i].particles);
    EXPECT_EQ(a.templates[i].rolling_eta, b.templates[i].rolling_eta);
  }
  ASSERT_EQ(a.regions.size(), b.regions.size());
  for (size_t i = 0; i < a.regions.size(); ++i) {
    SCOPED_TRACE(absl::StrCat("region ", i));
    const MaterialRegion& p = a.regions[i];
    const MaterialRegion& q = b.regions[i];
    EXPECT_EQ(p.name, q.name);
    EXPECT_EQ(p.lower, q.lower);
    EXPECT_EQ(p.upper, q.upper);
    EXPECT_EQ(p.points_per_cell_side, q.points_per_cell_side);
    EXPECT_EQ(p.rve_template, q.rve_template);
    EXPECT_EQ(p.density, q.density);
    EXPECT_EQ(p.initial_stress, q.initial_stress);
    EXPECT_EQ(p.k0, q.k0);
    EXPECT_EQ(p.surface_y, q.surface_y);
    EXPECT_EQ(p.surcharge, q.surcharge);
    EXPECT_EQ(p.minimum_stress, q.minimum_stress);
  }
  ASSERT_EQ(a.walls.size(), b.walls.size());
  for (size_t i = 0; i < a.walls.size(); ++i) {
    SCOPED_TRACE(absl::StrCat("wall ", i));
    EXPECT_EQ(a.walls[i].name, b.walls[i].name);
    EXPECT_EQ(a.walls[i].axis, b.walls[i].axis);
    EXPECT_EQ(a.walls[i].position, b.walls[i].position);
    EXPECT_EQ(a.walls[i].contact, b.walls[i].contact);
    EXPECT_EQ(a.walls[i].friction, b.walls[i].friction);
    EXPECT_EQ(a.walls[i].remove_time, b.walls[i].remove_time);
    EXPECT_EQ(a.walls[i].unilateral, b.walls[i].unilateral);
    EXPECT_EQ(a.walls[i].shaking_amplitude, b.walls[i].shaking_amplitude);
    EXPECT_EQ(a.walls[i].shaking_frequency, b.walls[i].shaking_frequency);
  }
  ASSERT_EQ(a.bodies.size(), b.bodies.size());
  for (size_t i = 0; i < a.bodies.size(); ++i) {
    SCOPED_TRACE(absl::StrCat("body ", i));
    const RigidBody& p = a.bodies[i];
    const RigidBody& q = b.bodies[i];
    EXPECT_EQ(p.name, q.name);
    EXPECT_EQ(p.shape, q.shape);
    EXPECT_EQ(p.center, q.center);
    EXPECT_EQ(p.half_size, q.half_size);
    EXPECT_EQ(p.radius, q.radius);
    EXPECT_EQ(p.contact, q.contact);
    EXPECT_EQ(p.friction, q.friction);
    ASSERT_EQ(p.velocity.size(), q.velocity.size());
    for (size_t k = 0; k < p.velocity.size(); ++k) {
      EXPECT_EQ(p.velocity[k].time, q.velocity[k].time);
      EXPECT_EQ(p.velocity[k].velocity, q.velocity[k].velocity);
    }
  }
  ASSERT_EQ(a.tractions.size(), b.tractions.size());
  for (size_t i = 0; i < a.tractions.size(); ++i) {
    SCOPED_TRACE(absl::StrCat("traction ", i));
    const SurfaceTraction& p = a.tractions[i];
    const SurfaceTraction& q = b.tractions[i];
    EXPECT_EQ(p.name, q.name);
    EXPECT_EQ(p.region, q.region);
    EXPECT_EQ(p.normal_axis, q.normal_axis);
    EXPECT_EQ(p.normal_sign, q.normal_sign);
    EXPECT_EQ(p.traction, q.traction);
    EXPECT_EQ(p.ramp_time, q.ramp_time);
    ASSERT_EQ(p.history.size(), q.history.size());
    for (size_t k = 0; k < p.history.size(); ++k) {
      EXPECT_EQ(p.history[k].time, q.history[k].time);
      EXPECT_EQ(p.history[k].factor, q.history[k].factor);
    }
    EXPECT_EQ(p.from, q.from);
    EXPECT_EQ(p.to, q.to);
  }
  EXPECT_EQ(a.rve.max_inertial_number, b.rve.max_inertial_number);
  EXPECT_EQ(a.rve.min_steps, b.rve.min_steps);
  EXPECT_EQ(a.rve.max_stretch, b.rve.max_stretch);
  EXPECT_EQ(a.rve.real_time, b.rve.real_time);
  EXPECT_EQ(a.phases.saturated, b.phases.saturated);
  EXPECT_EQ(a.phases.fluid_density, b.phases.fluid_density);
  EXPECT_EQ(a.phases.permeability, b.phases.permeability);
  EXPECT_EQ(a.phases.porosity, b.phases.porosity);
  EXPECT_EQ(a.phases.water_table, b.phases.water_table);
  EXPECT_EQ(a.phases.drained_free_surface, b.phases.drained_free_surface);
  EXPECT_EQ(a.phases.excess_from, b.phases.excess_from);
  ASSERT_EQ(a.phases.drained.size(), b.phases.drained.size());
  for (std::size_t i = 0; i < a.phases.drained.size(); ++i) {
    EXPECT_EQ(a.phases.drained[i].name, b.phases.drained[i].name);
    EXPECT_EQ(a.phases.drained[i].axis, b.phases.drained[i].axis);
    EXPECT_EQ(a.phases.drained[i].position, b.phases.drained[i].position);
    EXPECT_EQ(a.phases.drained[i].pressure, b.phases.drained[i].pressure);
  }
  ASSERT_EQ(a.phases.monitors.size(), b.phases.monitors.size());
  for (std::size_t i = 0; i < a.phases.monitors.size(); ++i) {
    EXPECT_EQ(a.phases.monitors[i].name, b.phases.monitors[i].name);
    EXPECT_EQ(a.phases.monitors[i].position, b.phases.monitors[i].position);
  }
  EXPECT_EQ(a.output.frame_times, b.output.frame_times);
  EXPECT_EQ(a.output.reference_curve, b.output.reference_curve);
  EXPECT_EQ(a.output.frame_every, b.output.frame_every);
  EXPECT_EQ(a.output.timeseries_every, b.output.timeseries_every);
  EXPECT_EQ(a.output.checkpoint_every, b.output.checkpoint_every);
  EXPECT_EQ(a.output.progress_every, b.output.progress_every);
  EXPECT_EQ(a.output.plot, b.output.plot);
  EXPECT_EQ(a.output.plot_body, b.output.plot_body);
  EXPECT_EQ(a.output.plot_width, b.output.plot_width);
  EXPECT_EQ(a.output.summary, b.output.summary);
  EXPECT_EQ(a.output.phi_deg, b.output.phi_deg);
}

TEST_F(CaseTest, ToJsonRoundTrips) {
  for (const char* text : {kFullCase, kMinimalCase}) {
    absl::StatusOr<CaseSpec> spec = Parse(text);
    ASSERT_TRUE(spec.ok()) << spec.status();
    const std::string json = ToJson(*spec);
    // Template paths are absolute: any base_dir reads the same spec.
    absl::StatusOr<CaseSpec> again = ParseCase(json, "/nonexistent");
    ASSERT_TRUE(again.ok()) << again.status() << "\n" << json;
    ExpectSameSpec(*spec, *again);
    EXPECT_EQ(ToJson(*again), json);  // canonical: a fixed point
  }
}

TEST_F(CaseTest, ToJsonKeepsAwkwardDoubles) {
  Json doc = Json::parse(kFullCase);
  doc["solver"]["pic_fraction"] = 0.1 + 0.2;  // 0.30000000000000004
  doc["solver"]["time_step"] = 5e-324;        // smallest subnormal
  doc["bodies"][0]["velocity"][1] = {1.0 / 3.0, -0.0, -1e-17};
  absl::StatusOr<CaseSpec> spec = Parse(doc.dump());
  ASSERT_TRUE(spec.ok()) << spec.status();
  absl::StatusOr<CaseSpec> again = ParseCase(ToJson(*spec), "");
  ASSERT_TRUE(again.ok()) << again.status();
  ExpectSameSpec(*spec, *again);
}

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
       "/output/summary: unknown summary \"fancy\" (footing, pipe, collapse, biaxial, none)"},
      {"/output/plot_body", kRemove, "/output/plot_body: required key is missing"},
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

TEST_F(CaseTest, LoadCaseReadsTheFileRelativeToItsDirectory) {
  Json doc = Json::parse(kFullCase);
  doc.erase("name");
  const fs::path path = dir_ / "strip-footing.json";
  std::ofstream(path) << doc.dump(2);
  absl::StatusOr<CaseSpec> spec = LoadCase(path.string());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->name, "strip-footing");  // the file's stem
  EXPECT_EQ(spec->templates[1].file, (fs::absolute(dir_) / "packings" / "x.h5").string());

  doc["solver"]["cfl"] = 2;
  std::ofstream(path) << doc.dump(2);
  spec = LoadCase(path.string());
  ASSERT_FALSE(spec.ok());
  EXPECT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(MessageStartsWith(spec.status(), absl::StrCat(path.string(), ": /solver/cfl: ")));
}

// Every case shipped in cases/ parses and round-trips.
TEST(ShippedCases, ParseAndRoundTrip) {
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  int count = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    ++count;
    absl::StatusOr<CaseSpec> spec = LoadCase(entry.path().string());
    ASSERT_TRUE(spec.ok()) << spec.status();
    absl::StatusOr<CaseSpec> again = ParseCase(ToJson(*spec), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ExpectSameSpec(*spec, *again);
  }
  EXPECT_GT(count, 0);
}

// Every JSON pointer in `j` (containers and leaves; "" is the root).
void CollectPointers(const Json& j, const Json::json_pointer& at,
                     std::vector<Json::json_pointer>* out) {
  out->push_back(at);
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) CollectPointers(it.value(), at / it.key(), out);
  } else if (j.is_array()) {
    for (std::size_t k = 0; k < j.size(); ++k) CollectPointers(j[k], at / k, out);
  }
}

// The shipped case files in `dir` whose names end with `suffix`, by name.
std::vector<std::pair<std::string, Json>> ShippedCases(const fs::path& dir,
                                                       const std::string& suffix) {
  std::vector<std::pair<std::string, Json>> cases;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (!entry.path().filename().string().ends_with(suffix)) continue;
    std::ifstream in(entry.path());
    cases.emplace_back(entry.path().filename().string(), Json::parse(in));
  }
  std::sort(cases.begin(), cases.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return cases;
}

// One to three random edits of a case (CaseFuzz): delete a field or element,
// add an unknown key, scale a number, or put an absurd value anywhere.
// Returns what was done, for the failure message.
std::string MutateCase(Json& doc, std::mt19937_64& rng) {
  static const std::vector<Json> absurd = {0,
                                           -1,
                                           1,
                                           2147483648.0,
                                           -2147483649.0,
                                           9.3e18,
                                           -9.3e18,
                                           1e308,
                                           -1e308,
                                           1e-308,
                                           -0.0,
                                           std::numeric_limits<std::int64_t>::max(),
                                           std::numeric_limits<std::int64_t>::min(),
                                           "",
                                           "x",
                                           "NaN",
                                           "inf",
                                           true,
                                           nullptr,
                                           Json::array(),
                                           Json::object(),
                                           Json::array({1e308, -1e308}),
                                           Json::array({0, 0, 0}),
                                           Json::array({"a", "b"})};
  auto pick = [&rng](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  const int edits = 1 + static_cast<int>(pick(3));
  std::string what;
  for (int e = 0; e < edits; ++e) {
    std::vector<Json::json_pointer> pointers;
    CollectPointers(doc, Json::json_pointer(), &pointers);
    const Json::json_pointer ptr = pointers[pick(pointers.size())];
    const std::string at = ptr.to_string();
    const int kind = static_cast<int>(pick(8));
    if (kind == 0 && !at.empty()) {  // delete the field or element
      Json& parent = doc[ptr.parent_pointer()];
      if (parent.is_object()) parent.erase(ptr.back());
      if (parent.is_array()) parent.erase(static_cast<std::size_t>(std::stoul(ptr.back())));
      absl::StrAppend(&what, " delete ", at, ";");
    } else if (kind == 1 && doc[ptr].is_object()) {  // an unknown key
      doc[ptr]["unknown_key"] = 1;
      absl::StrAppend(&what, " unknown key in ", at, ";");
    } else if (kind == 2 && doc[ptr].is_number()) {  // a nearby or scaled number
      const double x = doc[ptr].get<double>();
      const double factors[] = {-1.0, 0.5, 2.0, 1e3, 1e-3, 1.0000001};
      doc[ptr] = x * factors[pick(6)];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    } else if (!at.empty()) {
      doc[ptr] = absurd[pick(absurd.size())];
      absl::StrAppend(&what, " ", at, " = ", doc[ptr].dump(), ";");
    }
  }
  return what;
}

// Hostile case files: the shipped cases with one to three fields replaced by
// absurd values (huge, tiny, negative, beyond int64, wrong types, empty
// containers), deleted, or joined by an unknown key. ParseCase must either
// accept the result, whose ToJson then parses back to the same spec, or refuse
// it with InvalidArgument naming a JSON pointer ("/..."), never crash; an
// accepted case's regions are then filled with material points, or refused.
// Seeded and sized from the environment like fuzz_test:
//   RVEHUB_CASE_FUZZ_ITERATIONS=100000 RVEHUB_CASE_FUZZ_SEED=7 build/tests/case_test
TEST(CaseFuzz, MutatedShippedCasesAreAcceptedOrRefusedByPointer) {
  const std::int64_t iterations = testing_env::EnvInt("RVEHUB_CASE_FUZZ_ITERATIONS", 3000);
  const std::uint64_t seed =
      static_cast<std::uint64_t>(testing_env::EnvInt("RVEHUB_CASE_FUZZ_SEED", 1));
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  const std::vector<std::pair<std::string, Json>> cases = ShippedCases(dir, ".json");
  ASSERT_FALSE(cases.empty());
  std::mt19937_64 rng(seed);
  auto pick = [&rng](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  std::int64_t accepted = 0, filled = 0;
  for (std::int64_t it = 0; it < iterations; ++it) {
    const auto& [name, base] = cases[pick(cases.size())];
    Json doc = base;
    const std::string what = MutateCase(doc, rng);
    SCOPED_TRACE(absl::StrCat("iteration ", it, ", ", name, ":", what));
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), dir.string());
    if (!spec.ok()) {
      ASSERT_EQ(spec.status().code(), absl::StatusCode::kInvalidArgument) << spec.status();
      ASSERT_TRUE(MessageStartsWith(spec.status(), "/")) << spec.status();
      continue;
    }
    ++accepted;
    absl::StatusOr<CaseSpec> again = ParseCase(ToJson(*spec), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ASSERT_EQ(ToJson(*again), ToJson(*spec));
    // The accepted case's material points, as a run places them (no RVEs): filled or
    // refused, never a crash. Cases past a million points are left out for memory.
    if (EstimateSize(*spec).points <= 1000000) {
      const absl::StatusOr<MaterialPoints> points =
          FillRegions(*spec, std::vector<double>(spec->regions.size(), 2000.0));
      if (points.ok()) {
        ++filled;
      } else {
        ASSERT_EQ(points.status().code(), absl::StatusCode::kInvalidArgument) << points.status();
      }
    }
  }
  std::printf("case fuzz: %lld mutated cases, %lld accepted, %lld filled with points, seed %llu\n",
              static_cast<long long>(iterations), static_cast<long long>(accepted),
              static_cast<long long>(filled), static_cast<unsigned long long>(seed));
  // Mutations of unused or equivalent fields are accepted; most are refused.
  EXPECT_GT(accepted, 0);
  EXPECT_LT(accepted, iterations);
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

// The run stage of CaseFuzz: mutated reduced cases (cases/*-ci.json) that
// are read and hold at most 5000 points run up to 20 steps with a linear
// elastic stand-in for their RVEs (E = 20 MPa, ν = 0.3, the time step from its
// P-wave modulus at the case's CFL; saturated points' n0 0.2 where the case
// leaves it to the RVEs). Each step ends OK or with an error, never a crash
// (deploy/sanitize.sh runs it under ASan and UBSan); after an OK step every
// point's position and stress are finite. deploy/fuzz_runs.py does the same
// with RVEs, out of CI. Seeded like CaseFuzz:
//   RVEHUB_RUN_FUZZ_ITERATIONS=20000 RVEHUB_RUN_FUZZ_SEED=7 build/tests/case_test
TEST(CaseFuzz, AcceptedMutatedCasesRunOrStopWithAnError) {
  const std::int64_t iterations = testing_env::EnvInt("RVEHUB_RUN_FUZZ_ITERATIONS", 3000);
  const std::uint64_t seed =
      static_cast<std::uint64_t>(testing_env::EnvInt("RVEHUB_RUN_FUZZ_SEED", 1));
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  const std::vector<std::pair<std::string, Json>> cases = ShippedCases(dir, "-ci.json");
  ASSERT_FALSE(cases.empty());
  constexpr double kYoungs = 20e6, kPoisson = 0.3;  // Pa, [-]
  std::mt19937_64 rng(seed);
  std::int64_t run = 0, stopped = 0, steps = 0;
  for (std::int64_t it = 0; it < iterations; ++it) {
    const auto& [name, base] = cases[rng() % cases.size()];
    Json doc = base;
    const std::string what = MutateCase(doc, rng);
    SCOPED_TRACE(absl::StrCat("iteration ", it, ", ", name, ":", what));
    absl::StatusOr<CaseSpec> spec = ParseCase(doc.dump(), dir.string());
    if (!spec.ok() || EstimateSize(*spec).points > 5000) continue;
    spec->solver.wave_modulus = PWaveModulus(kYoungs, kPoisson);
    absl::StatusOr<MaterialPoints> points =
        FillRegions(*spec, std::vector<double>(spec->regions.size(), 2000.0));
    if (!points.ok()) continue;
    for (double& n0 : points->porosity0) {
      if (!(n0 > 0.0 && n0 < 1.0)) n0 = 0.2;
    }
    const std::size_t n = points->size();
    LinearElasticModel model(kYoungs, kPoisson);
    model.SetStress(std::vector<Eigen::Matrix3d>(n, Eigen::Matrix3d::Zero()));
    absl::StatusOr<std::unique_ptr<Solver>> solver =
        Solver::Create(*spec, *std::move(points), &model);
    if (!solver.ok() || !((*solver)->dt() > 0.0)) continue;
    ++run;
    for (int k = 0; k < 20 && (*solver)->time() < spec->solver.end_time; ++k) {
      if (!(*solver)->Step().ok()) {
        ++stopped;
        break;
      }
      ++steps;
      const MaterialPoints& mp = (*solver)->points();
      for (std::size_t p = 0; p < mp.size(); ++p) {
        ASSERT_TRUE(mp.position[p].allFinite() && mp.stress[p].allFinite())
            << "point " << p << " after step " << (*solver)->step();
      }
    }
  }
  std::printf(
      "run fuzz: %lld mutated cases, %lld run, %lld stopped with an error, %lld steps, "
      "seed %llu\n",
      static_cast<long long>(iterations), static_cast<long long>(run),
      static_cast<long long>(stopped), static_cast<long long>(steps),
      static_cast<unsigned long long>(seed));
  EXPECT_GT(run, 0);
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

// A reference curve is resolved against the case file's directory and
// must exist; the shipped biaxial cases name one that does.
TEST(ReferenceCurve, ResolvedAgainstTheCaseAndChecked) {
  const fs::path path = fs::path(RVEHUB_SOURCE_DIR) / "cases" / "single-element-biaxial.json";
  absl::StatusOr<CaseSpec> spec = LoadCase(path.string());
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->output.reference_curve,
            (path.parent_path() / "reference" / "set-dense-drained-biaxial-100kPa.csv")
                .lexically_normal()
                .string());
  std::ifstream in(path);
  Json doc = Json::parse(in);
  doc["output"]["reference_curve"] = "reference/missing.csv";
  absl::StatusOr<CaseSpec> bad = ParseCase(doc.dump(), path.parent_path().string());
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(MessageStartsWith(bad.status(), "/output/reference_curve: no such file"))
      << bad.status();
}

TEST(CaseOverride, ParsesPointerAndDottedPaths) {
  absl::StatusOr<CaseOverride> pointer = ParseOverride("/rve/min_steps=4");
  ASSERT_TRUE(pointer.ok()) << pointer.status();
  EXPECT_EQ(pointer->pointer, "/rve/min_steps");
  EXPECT_EQ(pointer->value, "4");
  absl::StatusOr<CaseOverride> dotted = ParseOverride("regions.0.density=1.6e3");
  ASSERT_TRUE(dotted.ok()) << dotted.status();
  EXPECT_EQ(dotted->pointer, "/regions/0/density");
  EXPECT_EQ(dotted->value, "1.6e3");
  // Only the first "=" splits: values may hold more.
  absl::StatusOr<CaseOverride> equals = ParseOverride("description=a=b");
  ASSERT_TRUE(equals.ok()) << equals.status();
  EXPECT_EQ(equals->pointer, "/description");
  EXPECT_EQ(equals->value, "a=b");
  for (const char* bad : {"rve.min_steps", "=4", ""}) {
    absl::StatusOr<CaseOverride> o = ParseOverride(bad);
    EXPECT_FALSE(o.ok()) << bad;
    EXPECT_TRUE(MessageStartsWith(o.status(), "--set needs PATH=VALUE")) << o.status();
  }
}

TEST_F(CaseTest, OverridesApplyBeforeValidation) {
  const std::vector<CaseOverride> ok = {
      {"/solver/end_time", "2.5"}, {"/regions/0/points_per_cell_side", "3"}, {"/name", "sweep"}};
  absl::StatusOr<CaseSpec> spec = ParseCase(kMinimalCase, dir_.string(), ok);
  ASSERT_TRUE(spec.ok()) << spec.status();
  EXPECT_EQ(spec->solver.end_time, 2.5);
  EXPECT_EQ(spec->regions[0].points_per_cell_side, 3);
  EXPECT_EQ(spec->name, "sweep");
  const std::vector<CaseOverride> bad = {{"/solver/end_time", "-1"}};
  absl::StatusOr<CaseSpec> refused = ParseCase(kMinimalCase, dir_.string(), bad);
  EXPECT_TRUE(MessageStartsWith(refused.status(), "/solver/end_time: must be in (0, 1000000]"))
      << refused.status();
  // A new key is checked like one in the file.
  const std::vector<CaseOverride> typo = {{"/solver/end_tme", "1"}};
  EXPECT_TRUE(MessageStartsWith(ParseCase(kMinimalCase, dir_.string(), typo).status(),
                                "/solver/end_tme: unknown key"));
}

TEST_F(CaseTest, MemoryEstimateBoundsTheCase) {
  absl::StatusOr<CaseSpec> spec = Parse(kMinimalCase);
  ASSERT_TRUE(spec.ok()) << spec.status();
  const CaseSize size = EstimateSize(*spec);
  EXPECT_EQ(size.nodes, (spec->grid.nx + 1) * (spec->grid.ny + 1));
  EXPECT_EQ(size.points, 2 * 1 * 4);  // 2 × 1 cells of 0.5 m, 2 × 2 points each
  EXPECT_NEAR(size.bytes,
              kBytesPerNode * size.nodes + size.points * (kBytesPerPoint + 400 * kRveBytesPerDisc),
              1e-6);
  // A larger sample of the material is counted as such.
  Json larger = Json::parse(kMinimalCase);
  larger["templates"][0]["particles"] = 1600;
  absl::StatusOr<CaseSpec> spec1600 = Parse(larger.dump());
  ASSERT_TRUE(spec1600.ok()) << spec1600.status();
  EXPECT_NEAR(EstimateSize(*spec1600).bytes,
              kBytesPerNode * size.nodes + size.points * (kBytesPerPoint + 1600 * kRveBytesPerDisc),
              1e-6);
  // 10^4 × 10^4 cells filled with points: ~5e3 GiB, refused naming the grid.
  Json doc = Json::parse(kMinimalCase);
  doc["grid"]["cells"] = {10000, 10000};
  doc["regions"][0]["upper"] = {5000, 5000};
  absl::StatusOr<CaseSpec> huge = Parse(doc.dump());
  ASSERT_FALSE(huge.ok());
  EXPECT_TRUE(MessageStartsWith(huge.status(), "/grid: the case needs about ")) << huge.status();
  EXPECT_TRUE(MessageHas(huge.status(), "more than the limit of 32 GiB")) << huge.status();
}

TEST_F(CaseTest, LoadCaseOnAMissingFileIsNotFound) {
  const std::string path = (dir_ / "no-such-case.json").string();
  absl::StatusOr<CaseSpec> spec = LoadCase(path);
  ASSERT_FALSE(spec.ok());
  EXPECT_EQ(spec.status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(MessageHas(spec.status(), path));
}

}  // namespace
}  // namespace rvehub::mpm
