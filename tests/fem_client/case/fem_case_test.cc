// fem_client's case files (fem_client/case/case.h): a full case parses into
// the expected FemCase, a minimal one takes fem_case.h's defaults, ToJson
// round-trips, a strain per step becomes a step count, overrides apply
// before the checks, the memory estimate bounds a case and every shipped
// fem case reads back. Bad input: fem_case_errors_test.cc; mutated cases:
// fem_case_fuzz_test.cc.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "client_case/sections.h"
#include "fem_client/case/case.h"
#include "gtest/gtest.h"
#include "tests/fem_client/case/fem_case_test_util.h"

namespace rvehub::fem::case_test {
namespace {

TEST_F(FemCaseTest, FullCaseParsesIntoExpectedCase) {
  absl::StatusOr<FemCase> c = Parse(kFullCase);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->name, "full");
  EXPECT_EQ(c->description, "every section");
  EXPECT_EQ(c->expected_runtime_s, 12.5);

  EXPECT_EQ(c->mesh.origin, Eigen::Vector2d(1, 2));
  EXPECT_EQ(c->mesh.size, Eigen::Vector2d(0.05, 0.1));
  EXPECT_EQ(c->mesh.nx, 4);
  EXPECT_EQ(c->mesh.ny, 6);
  EXPECT_EQ(c->mesh.element, ElementKind::kQ8);
  EXPECT_EQ(GaussPointsPerElement(c->mesh.element), 9);
  EXPECT_EQ(GaussPointCount(c->mesh), 216);

  ASSERT_EQ(c->templates.size(), 2u);
  EXPECT_EQ(c->templates[0].name, "dense");
  EXPECT_EQ(c->templates[0].parameter_set, "SET-dense");
  EXPECT_EQ(c->templates[0].seed, 7u);
  EXPECT_EQ(c->templates[0].pressure, 6600);
  EXPECT_EQ(c->templates[0].void_ratio, 0.19);
  EXPECT_EQ(c->templates[0].particles, 1600);
  EXPECT_EQ(c->templates[1].file, (fs::absolute(dir_) / "packings" / "x.h5").string());
  EXPECT_EQ(c->templates[1].template_name, "loose-1");

  EXPECT_EQ(c->material.rve_template, "dense");
  EXPECT_EQ(c->material.initial_stress, InitialStressKind::kK0);
  EXPECT_EQ(c->material.vertical, 2e5);  // compression +, as in the file
  EXPECT_EQ(c->material.k0, 0.45);

  EXPECT_EQ(c->rve.max_inertial_number, 1e-3);
  EXPECT_EQ(c->rve.min_steps, 50);
  EXPECT_EQ(c->rve.max_stretch, 0.2);
  EXPECT_TRUE(c->rve.full_state_every_step);

  ASSERT_EQ(c->boundaries.size(), 4u);
  const BoundarySpec& base = c->boundaries[0];
  EXPECT_EQ(base.name, "base");
  EXPECT_EQ(base.face, Face::kBottom);
  EXPECT_EQ(base.kind, BoundaryKind::kRoller);
  EXPECT_EQ(base.pin, Pin::kStart);
  EXPECT_EQ(c->boundaries[1].face, Face::kLeft);
  EXPECT_EQ(c->boundaries[1].kind, BoundaryKind::kPressure);
  EXPECT_EQ(c->boundaries[1].pressure, 150e3);
  EXPECT_EQ(c->boundaries[2].pin, Pin::kNone);
  EXPECT_EQ(c->boundaries[3].kind, BoundaryKind::kPlaten);
  EXPECT_EQ(c->boundaries[3].contact, Contact::kRough);

  EXPECT_EQ(c->loading.kind, LoadingKind::kCompression);
  EXPECT_EQ(c->loading.end_strain, 0.15);
  EXPECT_EQ(c->loading.steps, 75);  // 0.15 / 2e-3

  EXPECT_EQ(c->solver.tangent, TangentKind::kPerturbation);
  EXPECT_EQ(c->solver.perturbation, 1e-4);
  EXPECT_EQ(c->solver.tolerance, 0.005);
  EXPECT_EQ(c->solver.max_iterations, 40);
  EXPECT_EQ(c->solver.max_cutbacks, 3);

  EXPECT_EQ(c->output.timeseries_every, 2);
  EXPECT_EQ(c->output.frame_every, 5);
  EXPECT_EQ(c->output.checkpoint_every, 25);
  EXPECT_EQ(c->output.progress_every, 3);
  EXPECT_EQ(c->output.monitor, (std::vector<std::int64_t>{0, 215}));
  EXPECT_EQ(c->output.packings, (std::vector<std::int64_t>{7}));
  EXPECT_EQ(c->output.plot, PlotKind::kStressStrain);
  EXPECT_EQ(c->output.reference_curve, (fs::absolute(dir_) / "reference.csv").string());
}

TEST_F(FemCaseTest, MinimalCaseTakesTheDefaults) {
  absl::StatusOr<FemCase> c = Parse(kMinimalCase);
  ASSERT_TRUE(c.ok()) << c.status();
  const FemCase defaults;
  EXPECT_EQ(c->name, "");
  EXPECT_EQ(c->expected_runtime_s, 0.0);
  EXPECT_EQ(c->mesh.origin, Eigen::Vector2d::Zero());
  EXPECT_EQ(c->mesh.element, ElementKind::kQ4);
  EXPECT_EQ(c->templates[0].seed, 1u);
  EXPECT_EQ(c->material.initial_stress, InitialStressKind::kTemplate);
  EXPECT_EQ(c->rve.max_inertial_number, defaults.rve.max_inertial_number);
  EXPECT_EQ(c->rve.min_steps, defaults.rve.min_steps);
  EXPECT_EQ(c->loading.steps, 10);
  // G&Z's: the contact tangent, ξ = 5e-5, E_d < 0.01.
  EXPECT_EQ(c->solver.tangent, TangentKind::kContact);
  EXPECT_EQ(c->solver.perturbation, 5e-5);
  EXPECT_EQ(c->solver.tolerance, 0.01);
  EXPECT_EQ(c->solver.max_iterations, 30);
  EXPECT_EQ(c->solver.max_cutbacks, 6);
  EXPECT_EQ(c->solver.force_tolerance, 0.0);  // E_f only reported, as in G&Z
  EXPECT_EQ(c->solver.second_gradient, 0.0);  // none
  EXPECT_EQ(c->output.timeseries_every, defaults.output.timeseries_every);
  EXPECT_EQ(c->output.frame_every, defaults.output.frame_every);
  EXPECT_EQ(c->output.checkpoint_every, 0);
  EXPECT_TRUE(c->output.monitor.empty());
  EXPECT_EQ(c->output.plot, PlotKind::kStressStrain);
  EXPECT_EQ(c->output.reference_curve, "");
}

TEST_F(FemCaseTest, ShearCaseParsesWithItsPlotByDefault) {
  absl::StatusOr<FemCase> c = Parse(kShearCase);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->material.initial_stress, InitialStressKind::kIsotropic);
  EXPECT_EQ(c->material.pressure, 8e4);
  EXPECT_EQ(c->boundaries[1].kind, BoundaryKind::kPeriodic);
  EXPECT_EQ(c->boundaries[3].kind, BoundaryKind::kShear);
  EXPECT_EQ(c->loading.kind, LoadingKind::kCyclicShear);
  EXPECT_EQ(c->loading.control, CyclicControl::kStress);
  EXPECT_EQ(c->loading.amplitude, 3e4);
  EXPECT_EQ(c->loading.cycles, 13);
  EXPECT_EQ(c->loading.steps_per_cycle, 80);
  EXPECT_EQ(c->loading.end_strain, 0.05);
  EXPECT_EQ(c->output.plot, PlotKind::kSimpleShear);

  // Strain control: no end strain (the cycles' γ stays within the amplitude).
  Json doc = Json::parse(kShearCase);
  doc["loading"] = {{"kind", "cyclic_shear"},
                    {"strain_amplitude", 0.01},
                    {"cycles", 12},
                    {"steps_per_cycle", 40}};
  absl::StatusOr<FemCase> strain = Parse(doc.dump());
  ASSERT_TRUE(strain.ok()) << strain.status();
  EXPECT_EQ(strain->loading.control, CyclicControl::kStrain);
  EXPECT_EQ(strain->loading.amplitude, 0.01);
  EXPECT_EQ(strain->loading.end_strain, std::numeric_limits<double>::infinity());

  // Monotonic shear to an end strain.
  doc["loading"] = {{"kind", "shear"}, {"end_shear_strain", 0.2}, {"shear_strain_step", 1e-3}};
  absl::StatusOr<FemCase> monotonic = Parse(doc.dump());
  ASSERT_TRUE(monotonic.ok()) << monotonic.status();
  EXPECT_EQ(monotonic->loading.kind, LoadingKind::kShear);
  EXPECT_EQ(monotonic->loading.end_strain, 0.2);
  EXPECT_EQ(monotonic->loading.steps, 200);
}

// A strain per step gives the step count, rounded up (no step larger than
// asked) but not past a quotient's rounding error (0.1/1e-3 is 100 steps).
TEST_F(FemCaseTest, AStrainPerStepBecomesAStepCount) {
  struct Row {
    double end;
    double step;
    std::int64_t steps;
  };
  for (const Row& r : {Row{0.1, 1e-3, 100}, Row{0.1, 3e-3, 34}, Row{0.01, 0.02, 1},
                       Row{0.15, 2e-3, 75}, Row{0.3, 1e-4, 3000}}) {
    SCOPED_TRACE(absl::StrCat(r.end, " / ", r.step));
    Json doc = Json::parse(kMinimalCase);
    doc["loading"] = {
        {"kind", "compression"}, {"end_axial_strain", r.end}, {"axial_strain_step", r.step}};
    absl::StatusOr<FemCase> c = Parse(doc.dump());
    ASSERT_TRUE(c.ok()) << c.status();
    EXPECT_EQ(c->loading.steps, r.steps);
    // The canonical form holds the count.
    const Json canonical = Json::parse(ToJson(*c));
    EXPECT_EQ(canonical["loading"]["steps"], r.steps);
    EXPECT_FALSE(canonical["loading"].contains("axial_strain_step"));
  }
}

// Everything ParseFemCase reads, ToJson writes and reads back the same.
void ExpectSameCase(const FemCase& a, const FemCase& b) {
  // The canonical form is the comparison: it holds every field that applies.
  EXPECT_EQ(ToJson(a), ToJson(b));
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.mesh.nx, b.mesh.nx);
  EXPECT_EQ(a.boundaries.size(), b.boundaries.size());
  EXPECT_EQ(a.loading.steps, b.loading.steps);
  EXPECT_EQ(a.output.monitor, b.output.monitor);
}

TEST_F(FemCaseTest, ToJsonRoundTrips) {
  for (const char* text : {kFullCase, kMinimalCase, kShearCase}) {
    absl::StatusOr<FemCase> c = Parse(text);
    ASSERT_TRUE(c.ok()) << c.status();
    const std::string json = ToJson(*c);
    absl::StatusOr<FemCase> again = Parse(json);
    ASSERT_TRUE(again.ok()) << again.status() << "\n" << json;
    ExpectSameCase(*c, *again);
    EXPECT_EQ(ToJson(*again), json);
  }
}

// The canonical form: every key, in the format's order, defaults filled in.
TEST_F(FemCaseTest, ToJsonWritesEveryKeyInOrder) {
  absl::StatusOr<FemCase> c = Parse(kMinimalCase);
  ASSERT_TRUE(c.ok()) << c.status();
  const nlohmann::ordered_json j = nlohmann::ordered_json::parse(ToJson(*c));
  std::vector<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{"name", "description", "expected_runtime_s", "mesh",
                                            "templates", "material", "rve", "boundaries", "loading",
                                            "solver", "output", "checks"}));
  EXPECT_EQ(j["checks"], Json::array());
  EXPECT_EQ(j["mesh"]["element"], "q4");
  EXPECT_EQ(j["material"]["initial_stress"], Json({{"kind", "template"}}));
  EXPECT_EQ(j["solver"]["tangent"], "contact");
  EXPECT_FALSE(j["solver"].contains("perturbation"));  // only for its tangent
  EXPECT_EQ(j["output"]["plot"], "stress-strain");
  // The shared rve section without mpm_client's keys.
  EXPECT_FALSE(j["rve"].contains("real_time"));
  EXPECT_FALSE(j["rve"].contains("max_void_ratio"));
  EXPECT_TRUE(j["rve"].contains("min_steps"));
}

// --set: pointers and dotted paths, applied before validation so a bad
// override gets the file's message.
TEST_F(FemCaseTest, OverridesApplyBeforeValidation) {
  std::vector<CaseOverride> ok;
  for (const char* text : {"rve.min_steps=4", "/mesh/elements=[2, 12]", "name=sweep-3",
                           "boundaries.1.pressure=2e5", "solver.tolerance=0.02"}) {
    absl::StatusOr<CaseOverride> o = ParseOverride(text);
    ASSERT_TRUE(o.ok()) << o.status();
    ok.push_back(*o);
  }
  absl::StatusOr<FemCase> c = Parse(kFullCase, ok);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->rve.min_steps, 4);
  EXPECT_EQ(c->mesh.nx, 2);
  EXPECT_EQ(c->mesh.ny, 12);
  EXPECT_EQ(c->name, "sweep-3");
  EXPECT_EQ(c->boundaries[1].pressure, 2e5);
  EXPECT_EQ(c->solver.tolerance, 0.02);

  const std::vector<CaseOverride> bad = {{"/mesh/elements/0", "0"}};
  absl::StatusOr<FemCase> refused = Parse(kFullCase, bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(
      MessageStartsWith(refused.status(), "/mesh/elements/0: must be an integer in 1..200, got 0"));
  const std::vector<CaseOverride> typo = {{"/solver/tolerence", "0.1"}};
  refused = Parse(kFullCase, typo);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(MessageStartsWith(refused.status(),
                                "/solver/tolerence: unknown key (did you mean \"tolerance\"?"));
  const std::vector<CaseOverride> missing = {{"/phases/permeability", "1"}};
  refused = Parse(kFullCase, missing);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(MessageStartsWith(refused.status(),
                                "--set /phases/permeability: /phases is not in the case"));
  const std::vector<CaseOverride> past = {{"/boundaries/4/name", "\"x\""}};
  refused = Parse(kFullCase, past);
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(
      MessageStartsWith(refused.status(), "--set /boundaries/4/name: /boundaries/4 is not in"));
  // Overrides apply in order: the last one stands.
  const std::vector<CaseOverride> twice = {{"/solver/max_iterations", "5"},
                                           {"/solver/max_iterations", "7"}};
  c = Parse(kFullCase, twice);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->solver.max_iterations, 7);
}

// The RVEs' memory: Gauss points × discs × 140 B; a case above 32 GiB is
// refused while it is read.
TEST_F(FemCaseTest, MemoryEstimateBoundsTheCase) {
  absl::StatusOr<FemCase> c = Parse(kFullCase);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_DOUBLE_EQ(EstimateRveBytes(*c), 216.0 * 1600 * client_case::kRveBytesPerDisc);
  Json doc = Json::parse(kFullCase);
  doc["mesh"]["elements"] = {200, 200};
  doc["templates"][0]["particles"] = 2000;
  absl::StatusOr<FemCase> big = Parse(doc.dump());
  ASSERT_FALSE(big.ok());
  EXPECT_TRUE(MessageStartsWith(big.status(),
                                "/mesh: the case's RVEs need about 93.9 GiB "
                                "(360000 Gauss points)"));
  // The same mesh of Q4 elements with 400-disc packings fits.
  doc["mesh"]["element"] = "q4";
  doc["templates"][0].erase("particles");
  doc["output"]["monitor"] = {0};
  EXPECT_TRUE(Parse(doc.dump()).ok());
}

TEST_F(FemCaseTest, LoadFemCaseReadsTheFileRelativeToItsDirectory) {
  const fs::path path = dir_ / "my-case.json";
  std::ofstream(path) << kMinimalCase;
  absl::StatusOr<FemCase> c = LoadFemCase(path.string());
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->name, "my-case");  // the file's stem
  std::ofstream(path) << kFullCase;
  c = LoadFemCase(path.string());
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->name, "full");
  EXPECT_EQ(c->templates[1].file, (fs::absolute(dir_) / "packings" / "x.h5").string());

  Json doc = Json::parse(kMinimalCase);
  doc["solver"] = {{"tolerance", 0}};
  std::ofstream(path) << doc.dump();
  c = LoadFemCase(path.string());
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(MessageStartsWith(c.status(), absl::StrCat(path.string(), ": /solver/tolerance: ")));

  absl::StatusOr<FemCase> missing = LoadFemCase((dir_ / "nope.json").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(absl::StrContains(missing.status().message(), "nope.json"));
}

// Every fem case shipped in cases/ parses and round-trips; the biaxial and
// single element ones name a reference curve that exists.
TEST(ShippedFemCases, ParseAndRoundTrip) {
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  std::vector<std::string> names;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with("fem-") || entry.path().extension() != ".json") continue;
    SCOPED_TRACE(name);
    names.push_back(name);
    absl::StatusOr<FemCase> c = LoadFemCase(entry.path().string());
    ASSERT_TRUE(c.ok()) << c.status();
    EXPECT_EQ(c->name, entry.path().stem().string());
    EXPECT_FALSE(c->description.empty());
    EXPECT_GT(c->expected_runtime_s, 0.0);
    absl::StatusOr<FemCase> again = ParseFemCase(ToJson(*c), dir.string());
    ASSERT_TRUE(again.ok()) << again.status();
    ExpectSameCase(*c, *again);
    if (c->loading.kind == LoadingKind::kCompression) {
      EXPECT_TRUE(fs::is_regular_file(c->output.reference_curve)) << c->output.reference_curve;
    }
  }
  // The names scripts look for.
  for (const char* expected :
       {"fem-single-element.json", "fem-single-element-ci.json", "fem-biaxial-coarse.json",
        "fem-biaxial-medium.json", "fem-biaxial-fine.json", "fem-biaxial-coarse-q8.json",
        "fem-biaxial-coarse-ci.json", "fem-biaxial-coarse-q8-ci.json",
        "fem-simple-shear-strain.json", "fem-simple-shear-strain-ci.json",
        "fem-simple-shear-stress.json", "fem-simple-shear-stress-ci.json",
        "fem-biaxial-second-gradient.json", "fem-biaxial-second-gradient-ci.json"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
  }
}

// The shipped cases hold G&Z's set-ups: the meshes, the element kinds and
// the loadings of §3.3, §4 and §5.
TEST(ShippedFemCases, HoldThePapersSetUps) {
  const fs::path dir = fs::path(RVEHUB_SOURCE_DIR) / "cases";
  const auto load = [&](const char* name) {
    absl::StatusOr<FemCase> c = LoadFemCase((dir / name).string());
    EXPECT_TRUE(c.ok()) << name << ": " << c.status();
    return c.ok() ? *c : FemCase{};
  };
  struct Mesh {
    const char* name;
    int nx, ny;
    ElementKind element;
  };
  for (const Mesh& m : {Mesh{"fem-biaxial-coarse.json", 6, 10, ElementKind::kQ4},
                        Mesh{"fem-biaxial-medium.json", 10, 15, ElementKind::kQ4},
                        Mesh{"fem-biaxial-fine.json", 12, 20, ElementKind::kQ4},
                        Mesh{"fem-biaxial-coarse-q8.json", 6, 10, ElementKind::kQ8},
                        Mesh{"fem-biaxial-second-gradient.json", 6, 10, ElementKind::kQ8R}}) {
    SCOPED_TRACE(m.name);
    const FemCase c = load(m.name);
    EXPECT_EQ(c.mesh.size, Eigen::Vector2d(0.05, 0.1));
    EXPECT_EQ(c.mesh.nx, m.nx);
    EXPECT_EQ(c.mesh.ny, m.ny);
    EXPECT_EQ(c.mesh.element, m.element);
    EXPECT_EQ(c.loading.end_strain, 0.1);
    EXPECT_EQ(c.loading.steps, 100);
    EXPECT_EQ(c.templates[0].parameter_set, "SET-dense");
  }
  const FemCase single = load("fem-single-element.json");
  EXPECT_EQ(GaussPointCount(single.mesh), 4);
  EXPECT_EQ(single.boundaries[2].pressure, 100e3);

  const FemCase strain = load("fem-simple-shear-strain.json");
  EXPECT_EQ(strain.mesh.size, Eigen::Vector2d(0.1, 0.05));
  EXPECT_EQ(GaussPointCount(strain.mesh), 600);
  EXPECT_EQ(strain.loading.control, CyclicControl::kStrain);
  EXPECT_EQ(strain.loading.amplitude, 0.01);
  EXPECT_EQ(strain.loading.cycles, 12);
  EXPECT_EQ(strain.templates[0].parameter_set, "cyclic-loose");
  const FemCase stress = load("fem-simple-shear-stress.json");
  EXPECT_EQ(stress.loading.control, CyclicControl::kStress);
  EXPECT_EQ(stress.loading.amplitude, 30e3);
  EXPECT_EQ(stress.loading.end_strain, 0.05);
  EXPECT_EQ(stress.templates[0].parameter_set, "cyclic-loose-stress");
}

}  // namespace
}  // namespace rvehub::fem::case_test
