// fem_client's run (fem_client/run/simulation.h) on an embedded server, end
// to end on the reduced shipped cases: G&Z §3.3's single element follows the
// DEM element test on the same RVE within 2 % (it stops at 1 %, before the
// peak), the coarse biaxial specimen and a strain-controlled cycle of simple
// shear run to the end, every output is there and reads back, --stop-after
// stops, and a case the run cannot do is refused before anything is written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "client_run/templates.h"
#include "client_run/timeseries.h"
#include "fem_client/case/case.h"
#include "fem_client/run/output.h"
#include "fem_client/run/simulation.h"
#include "nlohmann/json.hpp"
#include "rve_server/embedded/packings.h"
#include "store/results.h"
#include "tests/fem_client/run/fem_run_test_util.h"
#include "tests/support/case_checks.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;
using run_test::Columns;
using run_test::Interpolate;
using run_test::ReadColumns;

std::string Scratch(const std::string& name) {
  return run_test::ScratchPath("fem_simulation_test", name);
}

// Prepared templates, shared with the other fem tests.
std::string TemplateCache() {
  return (fs::path(testing::TempDir()) / "fem_test_templates").string();
}

FemCase Load(const std::string& name, std::vector<CaseOverride> overrides = {}) {
  absl::StatusOr<FemCase> c =
      LoadFemCase(std::string(RVEHUB_SOURCE_DIR "/cases/") + name + ".json", overrides);
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? *c : FemCase{};
}

struct Outcome {
  absl::StatusOr<FemRunSummary> summary = absl::UnknownError("not run");
  std::vector<std::string> log;
};

Outcome RunCase(const FemCase& c, const std::string& out, std::int64_t stop_after = 0) {
  Outcome run;
  FemSimulationOptions o;
  o.out_dir = out;
  o.threads = 2;
  o.template_cache_dir = TemplateCache();
  o.stop_after_steps = stop_after;
  o.log = [&run](const std::string& line) { run.log.push_back(line); };
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(c, o);
  if (!sim.ok()) {
    run.summary = sim.status();
    return run;
  }
  run.summary = (*sim)->StepToEnd();
  return run;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
}

// The DEM element test on a case's template (SET-dense, seed 1), in process:
// drained biaxial at 100 kPa to 1.2 %, compression +.
struct Curve {
  std::vector<double> strain, syy, ev;
};
Curve ElementTest(const FemCase& c) {
  Curve curve;
  absl::StatusOr<std::vector<TemplateRecord>> templates =
      client_run::ResolveTemplates(c.templates, TemplateCache());
  EXPECT_TRUE(templates.ok()) << templates.status();
  if (!templates.ok()) return curve;
  dem::ElementTestSpec spec;
  spec.kind = dem::ElementTestKind::kDrainedBiaxial;
  spec.confining = 1e5;
  spec.max_strain = 0.012;
  spec.rows = 120;
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows =
      embedded::RunElementTest(templates->front().packing, spec);
  EXPECT_TRUE(rows.ok()) << rows.status();
  if (!rows.ok()) return curve;
  for (const dem::ElementTestRow& row : *rows) {
    curve.strain.push_back(row.axial_strain_comp);
    curve.syy.push_back(row.syy_comp);
    curve.ev.push_back(row.vol_strain_comp);
  }
  return curve;
}

// Every load step converged with at least two iterations (the first has
// E_d = 1) and below the tolerance, without cut-backs.
void ExpectConvergedSteps(const Columns& ts, double tolerance) {
  for (std::size_t r = 1; r < ts.at("step").size(); ++r) {
    SCOPED_TRACE(absl::StrCat("row ", r));
    EXPECT_GE(ts.at("iterations")[r], 2);
    EXPECT_LT(ts.at("error_d")[r], tolerance);
    EXPECT_EQ(ts.at("cutbacks")[r], 0);
    EXPECT_GE(ts.at("trials")[r], ts.at("iterations")[r]);
    EXPECT_GT(ts.at("dem_steps_per_trial")[r], 0);
  }
}

// G&Z §3.3: four identical RVEs in one element under the single element
// test's boundaries deform as one RVE does in the drained biaxial element
// test (σxx held at 100 kPa, εyy driven): the element's nominal σyy (the
// platen's force over its current width) against the platen's travel over
// the height is the element test's σyy against its axial strain. Both start
// from the same template (SET-dense, seed 1); the element test consolidates
// to 100 kPa first, the element starts at the template's state.
TEST(FemSimulationTest, SingleElementFollowsTheDemElementTest) {
  const FemCase c = Load("fem-single-element-ci");
  const std::string out = Scratch("single-element");
  const Outcome run = RunCase(c, out);
  ASSERT_TRUE(run.summary.ok()) << run.summary.status();
  EXPECT_TRUE(run.summary->finished);
  EXPECT_EQ(run.summary->final_step, 5);
  EXPECT_EQ(run.summary->total_steps, 5);
  EXPECT_GE(run.summary->iterations, 10);
  for (const char* file :
       {"timeseries.csv", "summary.json", "plot.png", "results.h5", "results.xdmf"}) {
    EXPECT_TRUE(fs::exists(fs::path(out) / file)) << file;
  }
  const Columns ts = ReadColumns(out + "/timeseries.csv");
  ASSERT_EQ(ts.at("step").size(), 6u);  // row 0 and five steps
  for (const std::string& column : TimeseriesColumns(c)) EXPECT_TRUE(ts.contains(column)) << column;
  EXPECT_TRUE(ts.contains("gp0_syy_Pa"));
  ExpectConvergedSteps(ts, 0.01);
  for (std::size_t r = 0; r < 6; ++r) {
    EXPECT_DOUBLE_EQ(ts.at("axial_strain")[r], 0.002 * r);  // nominal: the platen's travel
    // Nearly uniform: the four RVEs' responses part in the last bits and
    // the packings amplify it (measured: 2.4e-4 at 1 %).
    EXPECT_NEAR(ts.at("shear_strain")[r], 0.0, 1e-3);
    // The right face carries the confining pressure, up to the residual
    // Newton leaves (E_d < 0.01).
    EXPECT_NEAR(ts.at("lateral_stress_Pa")[r], 1e5, 1e3);
  }
  EXPECT_GT(ts.at("vol_strain").back(), 0.0);  // contracting before the peak

  const Curve dem_test = ElementTest(c);
  ASSERT_FALSE(dem_test.strain.empty());
  for (std::size_t r = 0; r < 6; ++r) {
    SCOPED_TRACE(absl::StrCat("row ", r));
    const double e = ts.at("axial_strain")[r];
    const double dem = Interpolate(dem_test.strain, dem_test.syy, e);
    EXPECT_NEAR(ts.at("platen_force_per_width_Pa")[r], dem, 0.02 * dem);
    std::printf("axial strain %.4f: element %.1f Pa, element test %.1f Pa (%+.2f %%)\n", e,
                ts.at("platen_force_per_width_Pa")[r], dem,
                100 * (ts.at("platen_force_per_width_Pa")[r] / dem - 1));
    EXPECT_NEAR(ts.at("vol_strain")[r], Interpolate(dem_test.strain, dem_test.ev, e), 5e-4);
  }

  // summary.json: the nominal peak as mpm_client reads it, then the solver's figures.
  const nlohmann::json summary = ReadJson(out + "/summary.json");
  ASSERT_TRUE(summary.is_object());
  EXPECT_EQ(summary["case"], "fem-single-element-ci");
  const auto peak = std::max_element(ts.at("platen_force_per_width_Pa").begin(),
                                     ts.at("platen_force_per_width_Pa").end());
  EXPECT_EQ(summary["peak_stress_Pa"].get<double>(), *peak);
  EXPECT_EQ(summary["peak_strain"].get<double>(),
            ts.at("axial_strain")[peak - ts.at("platen_force_per_width_Pa").begin()]);
  EXPECT_EQ(summary["load_steps"].get<double>(), 5);
  EXPECT_EQ(summary["iterations_total"].get<double>(),
            static_cast<double>(run.summary->iterations));
  for (const char* key : {"final_stress_Pa", "final_strain", "iterations_mean", "iterations_max",
                          "cutbacks_total", "trials_total", "dem_steps_per_trial", "wall_s"}) {
    EXPECT_TRUE(summary.contains(key)) << key;
  }

  // Frames 0 and 5 (frame_every 5): every Gauss point with its fields.
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  ASSERT_EQ(frames->size(), 2u);
  EXPECT_EQ((*frames)[0].step, 0);
  EXPECT_EQ((*frames)[1].step, 5);
  for (const store::ResultFrame& f : *frames) {
    EXPECT_EQ(f.position.size(), 8u);
    std::map<std::string, const store::ResultField*> fields;
    for (const store::ResultField& field : f.fields) fields[field.name] = &field;
    for (const char* name : {"stress", "p", "q", "eps_q", "eps_v", "void_ratio", "coordination",
                             "fabric_anisotropy", "rotation", "displacement", "gauss_point"}) {
      ASSERT_TRUE(fields.contains(name)) << name;
    }
    EXPECT_EQ(fields["stress"]->values.size(), 36u);
    ASSERT_EQ(fields["displacement"]->values.size(), 8u);
    // Nearly uniform compression: the packing's slight anisotropy skews the
    // element a little (measured: |θ| = 1.9e-4 rad at 1 %).
    for (double r : fields["rotation"]->values) EXPECT_LT(std::abs(r), 1e-3);
    if (f.step == 0) {
      for (double u : fields["displacement"]->values) EXPECT_EQ(u, 0.0);
      for (double r : fields["rotation"]->values) EXPECT_EQ(r, 0.0);
    }
    for (double z : fields["coordination"]->values) EXPECT_GT(z, 3.0);  // measured in full
    if (f.step == 5) {
      // The element's strain, nearly uniform: each point's εv near the
      // specimen's (measured: within 2.1e-4 at 1 %).
      for (double v : fields["eps_v"]->values) {
        EXPECT_NEAR(v, ts.at("vol_strain").back(), 5e-4);
      }
      for (double q : fields["eps_q"]->values) EXPECT_GT(q, 0.01);
      // Each point moves down by the axial strain times its height.
      for (int k = 0; k < 4; ++k) {
        EXPECT_NEAR(fields["displacement"]->values[2 * k + 1],
                    -ts.at("axial_strain").back() * f.position[2 * k + 1] /
                        (1.0 - ts.at("axial_strain").back()),
                    1e-4 * f.position[2 * k + 1]);
      }
    }
  }
  // Gauss point 0's row, as monitored, is its frame's stress.
  EXPECT_EQ(ts.at("gp0_syy_Pa").back(), -(*frames)[1].fields[0].values[4]);
}

// G&Z §4 reduced: 32 RVEs in a uniform specimen between smooth platens
// deform uniformly, so the specimen too follows the element test.
TEST(FemSimulationTest, BiaxialCoarseRunsToTheEnd) {
  const FemCase c = Load("fem-biaxial-coarse-ci");
  const std::string out = Scratch("biaxial");
  const Outcome run = RunCase(c, out);
  ASSERT_TRUE(run.summary.ok()) << run.summary.status();
  EXPECT_TRUE(run.summary->finished);
  const Columns ts = ReadColumns(out + "/timeseries.csv");
  ASSERT_EQ(ts.at("step").size(), 6u);
  ExpectConvergedSteps(ts, 0.01);
  const Curve dem_test = ElementTest(c);
  ASSERT_FALSE(dem_test.strain.empty());
  for (std::size_t r = 1; r < 6; ++r) {
    SCOPED_TRACE(absl::StrCat("row ", r));
    const double e = ts.at("axial_strain")[r];
    EXPECT_DOUBLE_EQ(e, 0.002 * r);
    EXPECT_NEAR(ts.at("shear_strain")[r], 0.0, 1e-3);
    EXPECT_NEAR(ts.at("lateral_stress_Pa")[r], 1e5, 2e3);
    const double dem = Interpolate(dem_test.strain, dem_test.syy, e);
    EXPECT_NEAR(ts.at("platen_force_per_width_Pa")[r], dem, 0.03 * dem);
  }
  EXPECT_TRUE(fs::exists(out + "/plot.png"));
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  ASSERT_EQ(frames->size(), 2u);
  EXPECT_EQ(frames->back().position.size(), 64u);  // 32 Gauss points
}

// G&Z §5.1 reduced: one cycle of ±1 % shear strain in eight steps at
// constant volume; the top's γ reaches the amplitude at the quarters and
// the platen's τ follows its sign.
TEST(FemSimulationTest, StrainControlledCyclicShearReversesAtTheQuarters) {
  const FemCase c = Load("fem-simple-shear-strain-ci");
  const std::string out = Scratch("shear");
  const Outcome run = RunCase(c, out);
  ASSERT_TRUE(run.summary.ok()) << run.summary.status();
  EXPECT_TRUE(run.summary->finished);
  const Columns ts = ReadColumns(out + "/timeseries.csv");
  ASSERT_EQ(ts.at("step").size(), 9u);
  const std::vector<double> gamma = {0, 0.005, 0.01, 0.005, 0, -0.005, -0.01, -0.005, 0};
  for (std::size_t r = 0; r < 9; ++r) {
    SCOPED_TRACE(absl::StrCat("row ", r));
    EXPECT_NEAR(ts.at("shear_strain")[r], gamma[r], 1e-15);
    EXPECT_NEAR(ts.at("axial_strain")[r], 0.0, 1e-15);  // the height held
    EXPECT_NEAR(ts.at("vol_strain")[r], 0.0, 1e-12);    // constant volume
  }
  EXPECT_GT(ts.at("platen_force_per_width_Pa")[2], 1e3);   // τ > 0 at +γ_a
  EXPECT_LT(ts.at("platen_force_per_width_Pa")[6], -1e3);  // τ < 0 at −γ_a
  // The specimen is uniform: at +γ_a its τ and p are those of the DEM cyclic
  // simple shear element test on the same template (measured: +1.0 %, −0.1 %).
  absl::StatusOr<std::vector<TemplateRecord>> templates =
      client_run::ResolveTemplates(c.templates, TemplateCache());
  ASSERT_TRUE(templates.ok()) << templates.status();
  dem::ElementTestSpec spec;
  spec.kind = dem::ElementTestKind::kCyclicSimpleShear;
  spec.cyclic_control = dem::CyclicControl::kStrain;
  spec.amplitude = 0.01;
  spec.cycles = 1;
  spec.max_strain = 0.1;
  spec.confining = 1e5;
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows =
      embedded::RunElementTest(templates->front().packing, spec);
  ASSERT_TRUE(rows.ok()) << rows.status();
  const dem::ElementTestRow& at_amplitude = *std::max_element(
      rows->begin(), rows->end(),
      [](const auto& a, const auto& b) { return a.shear_strain < b.shear_strain; });
  EXPECT_NEAR(at_amplitude.shear_strain, 0.01, 5e-4);
  const double tau = -at_amplitude.sxy_comp;  // σxy, Pa
  EXPECT_NEAR(ts.at("platen_force_per_width_Pa")[2], tau, 0.03 * tau);
  EXPECT_NEAR(ts.at("mean_p_Pa")[2], at_amplitude.p_comp, 0.02 * at_amplitude.p_comp);
  const nlohmann::json summary = ReadJson(out + "/summary.json");
  ASSERT_TRUE(summary.is_object());
  EXPECT_EQ(summary["peak_shear_stress_Pa"].get<double>(), ts.at("platen_force_per_width_Pa")[2]);
  EXPECT_TRUE(summary.contains("final_mean_p_Pa"));
  EXPECT_NEAR(summary["max_abs_shear_strain"].get<double>(), 0.01, 1e-15);
  EXPECT_EQ(summary["cycles"].get<double>(), 1.0);
  EXPECT_TRUE(fs::exists(out + "/plot.png"));
  testing_util::ExpectCaseChecksPass(c.checks, out);
}

TEST(FemSimulationTest, StopAfterEndsTheRunThereWithoutASummary) {
  const FemCase c = Load("fem-single-element-ci");
  const std::string out = Scratch("stopped");
  const Outcome run = RunCase(c, out, /*stop_after=*/2);
  ASSERT_TRUE(run.summary.ok()) << run.summary.status();
  EXPECT_FALSE(run.summary->finished);
  EXPECT_EQ(run.summary->final_step, 2);
  const Columns ts = ReadColumns(out + "/timeseries.csv");
  EXPECT_EQ(ts.at("step"), (std::vector<double>{0, 1, 2}));
  EXPECT_FALSE(fs::exists(out + "/summary.json"));
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  EXPECT_EQ(frames->back().step, 2);  // the last step done has its frame
  // fem_client summarise's outputs from the partial timeseries.
  absl::StatusOr<Summary> summary = WriteFemRunOutputs(c, out);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->front().first, "peak_stress_Pa");
}

// A stress-controlled cycle (G&Z §5.2, fem-simple-shear-stress-ci: 16 RVEs,
// |τ| = 30 kPa in eight steps): τ follows the prescribed force within the
// Newton tolerance's share (E_d < 0.01; measured within 2.4 %), the volume
// stays constant (height held, periodic sides), and the cycle ends near τ =
// 0 with the loop's residual shear strain.
TEST(FemSimulationTest, AStressControlledCycleFollowsThePlatensForce) {
  const std::string out = Scratch("stress-cycle");
  const FemCase c = Load("fem-simple-shear-stress-ci");
  const Outcome run = RunCase(c, out);
  ASSERT_TRUE(run.summary.ok()) << run.summary.status();
  const std::vector<double> tau_kpa = {15, 30, 15, 0, -15, -30, -15, 0};
  const Columns ts = ReadColumns(out + "/timeseries.csv");
  ASSERT_EQ(ts.at("step").size(), tau_kpa.size() + 1);  // step 0, then the eight
  for (std::size_t k = 0; k < tau_kpa.size(); ++k) {
    SCOPED_TRACE(absl::StrCat("step ", k + 1));
    EXPECT_NEAR(ts.at("platen_force_per_width_Pa")[k + 1], 1e3 * tau_kpa[k], 1.0e3);
    EXPECT_NEAR(ts.at("vol_strain")[k + 1], 0.0, 1e-12);
  }
  // The summary's largest |γ| is the timeseries' and the one cycle is counted.
  double largest = 0.0;
  for (double g : ts.at("shear_strain")) largest = std::max(largest, std::abs(g));
  EXPECT_GT(largest, 1e-3);
  const nlohmann::json summary = ReadJson(out + "/summary.json");
  ASSERT_TRUE(summary.is_object());
  EXPECT_EQ(summary["max_abs_shear_strain"].get<double>(), largest);
  EXPECT_EQ(summary["cycles"].get<double>(), 1.0);
  testing_util::ExpectCaseChecksPass(c.checks, out);
}

}  // namespace
}  // namespace rvehub::fem
