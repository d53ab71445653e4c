// Case files (mpm_client/case.h): a full case parses into the expected
// CaseSpec (with the compression-positive → tension-positive conversion),
// ToJson round-trips, defaults match model.h, overrides apply before the
// checks, the memory estimate bounds a case and every shipped case reads
// back. Bad input: case_errors_test.cc; mutated cases: case_fuzz_test.cc.
#include "mpm_client/case/case.h"

#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "tests/mpm_client/case/case_test_util.h"

namespace rvehub::mpm::case_test {
namespace {

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

// The checks are read in order, a number or a summary key as the reference,
// and the tolerance's kind kept.
TEST_F(CaseTest, ChecksAreReadInOrder) {
  absl::StatusOr<CaseSpec> spec = Parse(kFullCase);
  ASSERT_TRUE(spec.ok()) << spec.status();
  ASSERT_EQ(spec->checks.size(), 3u);
  EXPECT_EQ(spec->checks[0].quantity, "N_q");
  EXPECT_EQ(spec->checks[0].reference, 14.4);
  EXPECT_TRUE(spec->checks[0].reference_quantity.empty());
  EXPECT_TRUE(spec->checks[0].relative);
  EXPECT_EQ(spec->checks[0].tolerance, 0.1);
  EXPECT_EQ(spec->checks[0].source, "liang-zhao-mpm-dem §3.3 Fig. 12");
  EXPECT_EQ(spec->checks[1].reference_quantity, "N_q_reduced");
  EXPECT_FALSE(spec->checks[2].relative);
  EXPECT_EQ(spec->checks[2].tolerance, 0.0);
  absl::StatusOr<CaseSpec> minimal = Parse(kMinimalCase);
  ASSERT_TRUE(minimal.ok()) << minimal.status();
  EXPECT_TRUE(minimal->checks.empty());
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
  EXPECT_EQ(a.output.wave_from, b.output.wave_from);
  EXPECT_EQ(a.output.wave_to, b.output.wave_to);
  EXPECT_EQ(a.output.wave_window, b.output.wave_window);
  ASSERT_EQ(a.checks.size(), b.checks.size());
  for (std::size_t c = 0; c < a.checks.size(); ++c) {
    EXPECT_EQ(a.checks[c].quantity, b.checks[c].quantity);
    EXPECT_EQ(a.checks[c].reference, b.checks[c].reference);
    EXPECT_EQ(a.checks[c].reference_quantity, b.checks[c].reference_quantity);
    EXPECT_EQ(a.checks[c].relative, b.checks[c].relative);
    EXPECT_EQ(a.checks[c].tolerance, b.checks[c].tolerance);
    EXPECT_EQ(a.checks[c].source, b.checks[c].source);
  }
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

// Every MPM case shipped in cases/ parses and round-trips (fem-*.json are
// fem_client's: tests/fem_client/case).
TEST(ShippedCases, ParseAndRoundTrip) {
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  int count = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".json") continue;
    if (entry.path().filename().string().starts_with("fem-")) continue;
    SCOPED_TRACE(entry.path().string());
    ++count;
    absl::StatusOr<CaseSpec> spec = LoadCase(entry.path().string());
    ASSERT_TRUE(spec.ok()) << spec.status();
    absl::StatusOr<CaseSpec> again = ParseCase(ToJson(*spec), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ExpectSameSpec(*spec, *again);
    // Its checks come last, away from the description at the top; a case
    // that CI runs and whose summary has figures checks at least one.
    std::ifstream in(entry.path());
    const nlohmann::ordered_json doc = nlohmann::ordered_json::parse(in);
    ASSERT_TRUE(doc.contains("checks"));
    EXPECT_EQ(std::prev(doc.end()).key(), "checks");
    const std::string file = entry.path().filename().string();
    const bool in_ci = file.ends_with("-ci.json") || file == "single-element-biaxial.json";
    // The summary's kind as mpm_client/run/summary.h reads it ("collapse"
    // names its plot "collapse" too).
    const std::string kind = !spec->output.summary.empty() ? spec->output.summary
                             : spec->output.plot == "none" ? "none"
                                                           : spec->output.plot;
    if (in_ci && kind != "none") {
      EXPECT_FALSE(spec->checks.empty());
    }
  }
  EXPECT_GT(count, 0);
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
}  // namespace rvehub::mpm::case_test
