// Bad fem case files (fem_client/case/case.h): each kind of bad field and
// document is an InvalidArgument naming the JSON pointer of the bad value
// (or the line and column of a syntax error), and boundaries that do not
// make a well-posed problem together are refused naming the one at fault.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "fem_client/case/case.h"
#include "gtest/gtest.h"
#include "tests/fem_client/case/fem_case_test_util.h"

namespace rvehub::fem::case_test {
namespace {

struct BadEdit {
  const char* base;     // the case edited: kFullCase, kMinimalCase or kShearCase
  std::string pointer;  // where to edit it
  Json value;           // kRemove: remove the key
  std::string message;  // the expected start of the error message
};

class FemCaseErrorsTest : public FemCaseTest {
 protected:
  // Each edit refused with InvalidArgument and its message.
  void ExpectRefused(const std::vector<BadEdit>& edits) {
    for (const BadEdit& edit : edits) {
      SCOPED_TRACE(edit.pointer + " = " +
                   (edit.value.is_discarded() ? "(removed)" : edit.value.dump()));
      absl::StatusOr<FemCase> c = ParseEdited(edit.base, edit.pointer, edit.value);
      ASSERT_FALSE(c.ok()) << "accepted";
      EXPECT_EQ(c.status().code(), absl::StatusCode::kInvalidArgument) << c.status();
      EXPECT_TRUE(MessageStartsWith(c.status(), edit.message));
    }
  }
};

TEST_F(FemCaseErrorsTest, BadFieldsNameTheirPointer) {
  const char* full = kFullCase;
  const char* shear = kShearCase;
  const std::vector<BadEdit> edits = {
      // Unknown keys (typos), with a suggestion; wrong types; missing keys.
      {full, "/colour", "red",
       "/colour: unknown key (keys here: name, description, expected_runtime_s, mesh, templates, "
       "material, rve, boundaries, loading, solver, output, checks)"},
      {full, "/mesh/elemnts", {1, 1}, "/mesh/elemnts: unknown key (did you mean \"elements\"?"},
      {full, "/name", 3, "/name: must be a string, got number 3"},
      {full, "/expected_runtime_s", -1, "/expected_runtime_s: must be >= 0, got -1"},
      {full, "/mesh", kRemove, "/mesh: required key is missing"},
      {full, "/material", kRemove, "/material: required key is missing"},
      {full, "/boundaries", kRemove, "/boundaries: required key is missing"},
      {full, "/boundaries", Json::array(), "/boundaries: must not be empty"},
      {full, "/loading", kRemove, "/loading: required key is missing"},
      {full, "/templates", Json::array(), "/templates: must not be empty"},
      // mesh
      {full, "/mesh/size", kRemove, "/mesh/size: required key is missing"},
      {full, "/mesh/size", {1}, "/mesh/size: must be an array of 2 numbers [x, y], got array [1]"},
      {full, "/mesh/size/0", 0, "/mesh/size/0: must be in (0, 10000], got 0"},
      {full, "/mesh/size/1", 2e4, "/mesh/size/1: must be in (0, 10000], got 20000"},
      {full, "/mesh/origin/1", "0", "/mesh/origin/1: must be a number, got string \"0\""},
      {full, "/mesh/origin/0", 1e13, "/mesh/origin/0: must be at most 1e+12 in magnitude"},
      {full, "/mesh/elements", 4,
       "/mesh/elements: must be an array of 2 integers [nx, ny], got "
       "number 4"},
      {full, "/mesh/elements/0", 0, "/mesh/elements/0: must be an integer in 1..200, got 0"},
      {full, "/mesh/elements/1", 201, "/mesh/elements/1: must be an integer in 1..200, got 201"},
      {full, "/mesh/elements/0", 2.5, "/mesh/elements/0: must be an integer in 1..200, got 2.5"},
      {full, "/mesh/element", "q9", "/mesh/element: unknown element \"q9\" (q4, q8, q8r)"},
      // templates (shared with mpm_client)
      {full, "/templates/0/parameter_set", "SET-foo",
       "/templates/0/parameter_set: unknown parameter set \"SET-foo\" (known: SET-dense"},
      {full, "/templates/1/seed", 3, "/templates/1/seed: only for templates prepared"},
      {full, "/templates/1/name", "dense",
       "/templates/1/name: duplicate template name \"dense\" (also /templates/0)"},
      {full, "/templates/0/particles", 1,
       "/templates/0/particles: must be an integer in 2..1000000"},
      // material
      {full, "/material/template", "dense2",
       "/material/template: no template named \"dense2\" (templates: dense, stored)"},
      {full, "/material/template", kRemove, "/material/template: required key is missing"},
      {full, "/material/density", 1800, "/material/density: unknown key"},
      {full, "/material/initial_stress/kind", "geostatic_k0",
       "/material/initial_stress/kind: unknown initial stress kind \"geostatic_k0\" (template, "
       "isotropic, k0)"},
      {full, "/material/initial_stress/vertical", kRemove,
       "/material/initial_stress/vertical: required key is missing"},
      {full, "/material/initial_stress/vertical", -1e5,
       "/material/initial_stress/vertical: must be in (0, 1000000000], got -100000"},
      {full, "/material/initial_stress/k0", 0,
       "/material/initial_stress/k0: must be in (0, 10], got 0"},
      {full, "/material/initial_stress/pressure", 1e5,
       "/material/initial_stress/pressure: only for kind \"isotropic\""},
      {shear, "/material/initial_stress/pressure", kRemove,
       "/material/initial_stress/pressure: required key is missing"},
      {shear, "/material/initial_stress/k0", 0.5,
       "/material/initial_stress/k0: only for kind \"k0\""},
      // rve: shared, without mpm_client's keys
      {full, "/rve/real_time", true,
       "/rve/real_time: unknown key (keys here: max_inertial_number, min_steps, max_stretch, "
       "full_state_every_step)"},
      {full, "/rve/max_void_ratio", 0.3, "/rve/max_void_ratio: unknown key"},
      {full, "/rve/min_steps", 1e6, "/rve/min_steps: must be an integer in 0..100000"},
      {full, "/rve/max_inertial_number", 0.5,
       "/rve/max_inertial_number: must be in [0, 0.1], got 0.5"},
      {full, "/rve/max_stretch", 0.001,
       "/rve/max_stretch: must be 0 (the template's) or in [0.01, 0.5], got 0.001"},
      // boundaries, one at a time
      {full, "/boundaries/0/face", "front",
       "/boundaries/0/face: unknown face \"front\" (left, right, bottom, top)"},
      {full, "/boundaries/0/face", kRemove, "/boundaries/0/face: required key is missing"},
      {full, "/boundaries/0/kind", "sticky",
       "/boundaries/0/kind: unknown boundary kind \"sticky\" (fixed, roller, platen, pressure, "
       "periodic, shear)"},
      {full, "/boundaries/0/name", "my base", "/boundaries/0/name: names use letters, digits"},
      {full, "/boundaries/2/name", "base",
       "/boundaries/2/name: duplicate boundary name \"base\" (also /boundaries/0)"},
      {full, "/boundaries/0/velocity", {0, -1}, "/boundaries/0/velocity: unknown key"},
      {full, "/boundaries/1/pressure", kRemove, "/boundaries/1/pressure: required key is missing"},
      {full, "/boundaries/1/pressure", 0,
       "/boundaries/1/pressure: must be in (0, 1000000000], got 0"},
      {full, "/boundaries/1/pressure", 2e9,
       "/boundaries/1/pressure: must be in (0, 1000000000], got 2000000000"},
      {full, "/boundaries/2/pressure", 1e5, "/boundaries/2/pressure: only for kind \"pressure\""},
      {full, "/boundaries/3/contact", kRemove, "/boundaries/3/contact: required key is missing"},
      {full, "/boundaries/3/contact", "frictional",
       "/boundaries/3/contact: unknown contact \"frictional\" (smooth, rough)"},
      {full, "/boundaries/0/contact", "rough", "/boundaries/0/contact: only for kind \"platen\""},
      {full, "/boundaries/1/pin", "start", "/boundaries/1/pin: only for kind \"roller\""},
      {full, "/boundaries/0/pin", "centre",
       "/boundaries/0/pin: unknown pin \"centre\" (start, middle, end)"},
      {full, "/boundaries/0/kind", "periodic",
       "/boundaries/0/kind: periodic boundaries pair the left and right faces, not the bottom"},
      {full, "/boundaries/0/kind", "shear",
       "/boundaries/0/kind: the shear platen is the top face, not the bottom"},
      // loading
      {full, "/loading/kind", "triaxial",
       "/loading/kind: unknown loading kind \"triaxial\" (compression, shear, cyclic_shear)"},
      {full, "/loading/kind", "shear", "/loading/end_axial_strain: only for kind \"compression\""},
      {full, "/loading/end_axial_strain", kRemove,
       "/loading/end_axial_strain: required key is missing"},
      {full, "/loading/end_axial_strain", 0.6,
       "/loading/end_axial_strain: must be in (0, 0.5], got 0.6"},
      {full, "/loading/end_axial_strain", 0,
       "/loading/end_axial_strain: must be in (0, 0.5], got 0"},
      {full, "/loading/steps", 10,
       "/loading: give exactly one of \"steps\" (load steps to the end) or \"axial_strain_step\" "
       "(strain per step)"},
      {full, "/loading/axial_strain_step", kRemove,
       "/loading: give exactly one of \"steps\" (load steps to the end) or \"axial_strain_step\""},
      {full, "/loading/axial_strain_step", 0.1,
       "/loading/axial_strain_step: must be in (0, 0.05], got 0.1"},
      {full, "/loading/axial_strain_step", 1e-8,
       "/loading/axial_strain_step: gives 15000000 steps to the end strain 0.15, more than "
       "1000000"},
      {full, "/loading/shear_strain_step", 1e-3,
       "/loading/shear_strain_step: only for kind \"shear\""},
      {full, "/loading/cycles", 3, "/loading/cycles: only for kind \"cyclic_shear\""},
      {full, "/loading/strain_amplitude", 0.01,
       "/loading/strain_amplitude: only for kind \"cyclic_shear\""},
      {full, "/loading/end_shear_strain", 0.1,
       "/loading/end_shear_strain: only for kinds \"shear\" and \"cyclic_shear\""},
      {full,
       "/loading",
       {{"kind", "shear"}, {"end_shear_strain", 0.1}, {"steps", 10}},
       "/loading/kind: \"shear\" drives the top's shear platen, and the case's driven boundary is "
       "platen boundary \"platen\" (/boundaries/3)"},
      {shear, "/loading/steps_per_cycle", 30,
       "/loading/steps_per_cycle: must be a multiple of 4 (a cycle's four equal quarters), got 30"},
      {shear, "/loading/steps_per_cycle", 2,
       "/loading/steps_per_cycle: must be an integer in 4..1000000, got 2"},
      {shear, "/loading/steps_per_cycle", 100000,
       "/loading/steps_per_cycle: cycles × steps_per_cycle must be at most 1000000, got 13 × "
       "100000"},
      {shear, "/loading/steps_per_cycle", kRemove,
       "/loading/steps_per_cycle: required key is missing"},
      {shear, "/loading/cycles", 0, "/loading/cycles: must be an integer in 1..1000, got 0"},
      {shear, "/loading/cycles", kRemove, "/loading/cycles: required key is missing"},
      {shear, "/loading/strain_amplitude", 0.01,
       "/loading: give exactly one of \"strain_amplitude\" (γ, strain control) or "
       "\"stress_amplitude\" (|τ| in Pa, stress control)"},
      {shear, "/loading/stress_amplitude", kRemove, "/loading: give exactly one of"},
      {shear, "/loading/stress_amplitude", -3e4,
       "/loading/stress_amplitude: must be in (0, 1000000000], got -30000"},
      {shear, "/loading/steps", 10,
       "/loading/steps: only for kinds \"compression\" and \"shear\" (a cyclic shear counts "
       "steps_per_cycle)"},
      {shear, "/loading/end_shear_strain", 2,
       "/loading/end_shear_strain: must be in (0, 1], got 2"},
      {shear, "/loading/kind", "compression",
       "/loading/stress_amplitude: only for kind \"cyclic_shear\""},
      {shear,
       "/loading",
       {{"kind", "cyclic_shear"},
        {"strain_amplitude", 0.01},
        {"cycles", 2},
        {"steps_per_cycle", 8},
        {"end_shear_strain", 0.05}},
       "/loading/end_shear_strain: only with a \"stress_amplitude\""},
      {shear,
       "/loading",
       {{"kind", "cyclic_shear"}, {"strain_amplitude", 0.3}, {"cycles", 2}, {"steps_per_cycle", 8}},
       "/loading/strain_amplitude: must be in (0, 0.2], got 0.3"},
      {shear,
       "/loading",
       {{"kind", "compression"}, {"end_axial_strain", 0.1}, {"steps", 10}},
       "/loading/kind: \"compression\" drives a platen, and the case's driven boundary is shear "
       "boundary \"top\" (/boundaries/3)"},
      // solver
      {full, "/solver/tangent", "secant",
       "/solver/tangent: unknown tangent \"secant\" (contact, perturbation, initial-elastic)"},
      {full, "/solver/perturbation", 0, "/solver/perturbation: must be in (0, 0.01], got 0"},
      {full, "/solver/tangent", "contact",
       "/solver/perturbation: only for tangent \"perturbation\""},
      {full, "/solver/tolerance", 1, "/solver/tolerance: must be in (0, 1), got 1"},
      {full, "/solver/tolerance", 1e-13, "/solver/tolerance: must be at least 1e-12"},
      {full, "/solver/max_iterations", 0,
       "/solver/max_iterations: must be an integer in 1..1000, got 0"},
      {full, "/solver/max_cutbacks", 21,
       "/solver/max_cutbacks: must be an integer in 0..20, got 21"},
      {full, "/solver/max_cutbacks", -1,
       "/solver/max_cutbacks: must be an integer in 0..20, got -1"},
      {full, "/solver/force_tolerance", 1, "/solver/force_tolerance: must be in [0, 1), got 1"},
      {full, "/solver/second_gradient_N", -2,
       "/solver/second_gradient_N: must be in [0, 1000000], got -2"},
      {full, "/solver/second_gradient_N", 30,
       "/solver/second_gradient_N: the second gradient needs the mesh's element \"q8r\""},
      // output
      {full, "/output/frame_every", 0, "/output/frame_every: must be an integer >= 1, got 0"},
      {full, "/output/timeseries_every", 0.5,
       "/output/timeseries_every: must be an integer >= 1, got 0.5"},
      {full, "/output/checkpoint_every", -1,
       "/output/checkpoint_every: must be an integer >= 0, got -1"},
      {full, "/output/monitor/1", 216, "/output/monitor/1: must be an integer in 0..215, got 216"},
      {full,
       "/output/monitor",
       {3, 3},
       "/output/monitor/1: Gauss point 3 is listed twice (also /output/monitor/0)"},
      {full, "/output/packings", 7, "/output/packings: must be an array, got number 7"},
      {full, "/output/packings/0", -1, "/output/packings/0: must be an integer in 0..215, got -1"},
      {shear, "/output/monitor/0", 24, "/output/monitor/0: must be an integer in 0..23, got 24"},
      {full, "/output/plot", "load-settlement",
       "/output/plot: unknown plot \"load-settlement\" (stress-strain, simple-shear, none)"},
      {full, "/output/plot", "simple-shear",
       "/output/plot: \"simple-shear\" is the plot of the shear loadings; this case's loading is "
       "\"compression\", whose plot is \"stress-strain\""},
      {shear, "/output/plot", "stress-strain",
       "/output/plot: \"stress-strain\" is the plot of loading \"compression\"; this case's "
       "loading is \"cyclic_shear\", whose plot is \"simple-shear\""},
      {full, "/output/reference_curve", "missing.csv", "/output/reference_curve: no such file \""},
      {full, "/output/plot", "none", "/output/reference_curve: only with a plot"},
  };
  ExpectRefused(edits);
  EXPECT_GE(edits.size(), 80u);
}

// Boundaries that cannot make a well-posed problem together: each refused
// naming the boundary (or the list) at fault.
TEST_F(FemCaseErrorsTest, ConflictingBoundariesAreRefused) {
  const char* full = kFullCase;
  const char* minimal = kMinimalCase;
  const char* shear = kShearCase;
  const Json left_platen = {
      {"name", "confining"}, {"face", "left"}, {"kind", "platen"}, {"contact", "smooth"}};
  const Json top_roller = {{"name", "platen"}, {"face", "top"}, {"kind", "roller"}};
  const Json base_pressure = {
      {"name", "base"}, {"face", "bottom"}, {"kind", "pressure"}, {"pressure", 1e5}};
  const Json side_roller = {{"name", "left"}, {"face", "left"}, {"kind", "roller"}};
  const std::vector<BadEdit> edits = {
      // Two conditions on one face.
      {full, "/boundaries/2/face", "left",
       "/boundaries/2/face: the left face already has boundary \"confining\" (/boundaries/1): one "
       "boundary per face"},
      {full, "/boundaries/3/face", "bottom",
       "/boundaries/3/face: the bottom face already has boundary \"base\" (/boundaries/0)"},
      // Periodic faces in pairs.
      {full, "/boundaries/2/kind", "periodic",
       "/boundaries/2/kind: a periodic right face needs the left face periodic too; the left face "
       "has pressure boundary \"confining\" (/boundaries/1)"},
      {shear, "/boundaries/2", kRemove,
       "/boundaries/1/kind: a periodic left face needs the right face periodic too; the right face "
       "is free"},
      // Exactly one driven face, pushing against a held one.
      {full, "/boundaries/1", left_platen,
       "/boundaries/3/kind: one boundary drives the specimen, and platen boundary \"confining\" "
       "(/boundaries/1) already does"},
      {full, "/boundaries/3", top_roller,
       "/boundaries: no boundary drives the specimen: give a \"platen\" (compression) or the top's "
       "\"shear\" platen (simple shear)"},
      {full, "/boundaries/0", base_pressure,
       "/boundaries/3/face: a platen on the top face needs the bottom face held normal to it "
       "(fixed or roller) to push against; the bottom face has pressure boundary \"base\" "
       "(/boundaries/0)"},
      {full, "/boundaries/0", kRemove,
       "/boundaries/2/face: a platen on the top face needs the bottom face held normal to it "
       "(fixed or roller) to push against; the bottom face is free"},
      // The shear platen over a fixed base, between periodic sides.
      {shear, "/boundaries/0/kind", "roller",
       "/boundaries/3/kind: the shear platen needs the bottom face fixed; the bottom face has "
       "roller boundary \"base\" (/boundaries/0)"},
      {shear, "/boundaries/1", side_roller,
       "/boundaries/2/kind: a periodic right face needs the left face periodic too; the left face "
       "has roller boundary \"left\" (/boundaries/1)"},
      // Rigid-body motion: nothing holds x without the pin or a rough platen.
      {minimal, "/boundaries/0/pin", kRemove,
       "/boundaries: nothing holds the specimen in x, so it can move as a rigid body: give a fixed "
       "face, a roller on the left or right face, a rough platen or a pin on a bottom or top "
       "roller"},
      // A pin at the middle of a face needs a node there.
      {minimal,
       "/mesh/elements",
       {3, 1},
       "/boundaries/0/pin: the bottom face has 4 nodes, none at its middle (3 q4 elements along "
       "it): pin \"start\" or \"end\", or use an even number of elements"},
  };
  // The minimal case pins the middle of its base for the last edit.
  std::vector<BadEdit> with_middle = edits;
  Json middle = Json::parse(kMinimalCase);
  middle["boundaries"][0]["pin"] = "middle";
  const std::string middle_text = middle.dump();
  with_middle.back().base = middle_text.c_str();
  ExpectRefused(with_middle);

  // The shear platen between sides that are not periodic.
  Json sides = Json::parse(kShearCase);
  sides["boundaries"][1] = side_roller;
  sides["boundaries"][2] = {{"name", "right"}, {"face", "right"}, {"kind", "roller"}};
  absl::StatusOr<FemCase> c = Parse(sides.dump());
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(
      MessageStartsWith(c.status(),
                        "/boundaries/3/kind: the shear platen needs periodic left and right "
                        "faces (simple shear); the left face has roller boundary \"left\" "
                        "(/boundaries/1)"));

  // Nothing holds y: a platen on the left pushing against a right roller.
  Json doc = Json::parse(kMinimalCase);
  doc["boundaries"] = {left_platen,
                       {{"name", "side"}, {"face", "right"}, {"kind", "roller"}},
                       {{"name", "p"}, {"face", "top"}, {"kind", "pressure"}, {"pressure", 1e5}}};
  c = Parse(doc.dump());
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(MessageStartsWith(c.status(), "/boundaries: nothing holds the specimen in y"));
  // Pinned, it is held; so is a specimen whose platen is rough, or Q8's
  // middle node.
  doc["boundaries"][1]["pin"] = "end";
  EXPECT_TRUE(Parse(doc.dump()).ok());
  doc = Json::parse(kMinimalCase);
  doc["boundaries"][0].erase("pin");
  doc["boundaries"][1]["contact"] = "rough";
  EXPECT_TRUE(Parse(doc.dump()).ok());
  middle["mesh"]["elements"] = {3, 1};
  middle["mesh"]["element"] = "q8";
  EXPECT_TRUE(Parse(middle.dump()).ok());
  middle["mesh"]["element"] = "q4";
  middle["mesh"]["elements"] = {4, 1};
  EXPECT_TRUE(Parse(middle.dump()).ok());
}

// Errors found before the document is walked.
TEST_F(FemCaseErrorsTest, BadDocuments) {
  struct Bad {
    std::string text;
    std::string message;
  };
  const std::vector<Bad> bad = {
      {"{\n  \"mesh\": tru\n}",
       "line 2, column 13: syntax error while parsing value - invalid literal"},
      {"", "line 1, column 1: syntax error"},
      {"[1, 2]", "(document): must be an object, got array [1,2]"},
      {R"({"mesh": {"size": [1, 1], "size": [2, 2]}})", "/mesh/size: duplicate key"},
      {R"({"boundaries": [{"name": "a"}, {"name": "b", "kind": "x", "kind": "y"}]})",
       "/boundaries/1/kind: duplicate key"},
  };
  for (const Bad& b : bad) {
    SCOPED_TRACE(b.text);
    absl::StatusOr<FemCase> c = Parse(b.text);
    ASSERT_FALSE(c.ok());
    EXPECT_EQ(c.status().code(), absl::StatusCode::kInvalidArgument) << c.status();
    EXPECT_TRUE(MessageStartsWith(c.status(), b.message));
  }
}

}  // namespace
}  // namespace rvehub::fem::case_test
