// What the fem case file tests share (fem_case_test, fem_case_errors_test,
// fem_case_fuzz_test): status predicates, a full, a minimal and a simple
// shear case, and a fixture that parses them against a temporary directory
// holding the full case's template file and reference curve.
#ifndef RVEHUB_TESTS_FEM_CLIENT_CASE_FEM_CASE_TEST_UTIL_H_
#define RVEHUB_TESTS_FEM_CLIENT_CASE_FEM_CASE_TEST_UTIL_H_

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "fem_client/case/case.h"
#include "gtest/gtest.h"

namespace rvehub::fem::case_test {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// gmock is not linked: plain predicates for status messages.
inline ::testing::AssertionResult MessageStartsWith(const absl::Status& status,
                                                    absl::string_view prefix) {
  if (absl::StartsWith(status.message(), prefix)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "message does not start with '" << prefix << "': " << status;
}

// Every section, with non-default values wherever a default exists: a
// 4 × 6 Q8 mesh (216 Gauss points) compressed by a rough platen on top.
inline constexpr char kFullCase[] = R"json({
  "name": "full",
  "description": "every section",
  "expected_runtime_s": 12.5,
  "mesh": {"origin": [1, 2], "size": [0.05, 0.1], "elements": [4, 6], "element": "q8"},
  "templates": [
    {"name": "dense", "parameter_set": "SET-dense", "seed": 7, "pressure": 6600, "void_ratio": 0.19,
     "particles": 1600},
    {"name": "stored", "file": "packings/x.h5", "template_name": "loose-1"}
  ],
  "material": {"template": "dense", "initial_stress": {"kind": "k0", "vertical": 2e5, "k0": 0.45}},
  "rve": {"max_inertial_number": 1e-3, "min_steps": 50, "max_stretch": 0.2,
          "full_state_every_step": true},
  "boundaries": [
    {"name": "base", "face": "bottom", "kind": "roller", "pin": "start"},
    {"name": "confining", "face": "left", "kind": "pressure", "pressure": 150e3},
    {"name": "side", "face": "right", "kind": "roller"},
    {"name": "platen", "face": "top", "kind": "platen", "contact": "rough"}
  ],
  "loading": {"kind": "compression", "end_axial_strain": 0.15, "axial_strain_step": 2e-3},
  "solver": {"tangent": "perturbation", "perturbation": 1e-4, "tolerance": 0.005,
             "max_iterations": 40, "max_cutbacks": 3},
  "output": {"timeseries_every": 2, "frame_every": 5, "checkpoint_every": 25, "progress_every": 3,
             "monitor": [0, 215], "packings": [7], "plot": "stress-strain",
             "reference_curve": "reference.csv"}
})json";

// The smallest valid case: everything else takes fem_case.h's defaults.
inline constexpr char kMinimalCase[] = R"json({
  "mesh": {"size": [1, 1], "elements": [1, 1]},
  "templates": [{"name": "t", "parameter_set": "SET-dense"}],
  "material": {"template": "t"},
  "boundaries": [
    {"name": "base", "face": "bottom", "kind": "roller", "pin": "start"},
    {"name": "platen", "face": "top", "kind": "platen", "contact": "smooth"}
  ],
  "loading": {"kind": "compression", "end_axial_strain": 0.1, "steps": 10}
})json";

// Stress-controlled cyclic simple shear (G&Z §5) on a 3 × 2 Q4 mesh.
inline constexpr char kShearCase[] = R"json({
  "mesh": {"size": [0.1, 0.05], "elements": [3, 2]},
  "templates": [{"name": "loose", "parameter_set": "cyclic-loose-stress"}],
  "material": {"template": "loose", "initial_stress": {"kind": "isotropic", "pressure": 8e4}},
  "boundaries": [
    {"name": "base", "face": "bottom", "kind": "fixed"},
    {"name": "left", "face": "left", "kind": "periodic"},
    {"name": "right", "face": "right", "kind": "periodic"},
    {"name": "top", "face": "top", "kind": "shear"}
  ],
  "loading": {"kind": "cyclic_shear", "stress_amplitude": 3e4, "cycles": 13, "steps_per_cycle": 80,
              "end_shear_strain": 0.05},
  "output": {"monitor": [23]}
})json";

// In an edit: remove the key instead of setting it.
inline const Json kRemove(Json::value_t::discarded);

class FemCaseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / absl::StrCat("fem_case_test_", getpid());
    fs::create_directories(dir_ / "packings");
    std::ofstream(dir_ / "packings" / "x.h5") << "not read by the parser";
    std::ofstream(dir_ / "reference.csv") << "step,axial_strain,syy\n";
  }
  void TearDown() override { fs::remove_all(dir_); }

  absl::StatusOr<FemCase> Parse(absl::string_view text,
                                std::span<const CaseOverride> overrides = {}) {
    return ParseFemCase(text, dir_.string(), overrides);
  }

  // `base` with the value at `pointer` replaced (or the key or element
  // removed for kRemove), parsed.
  absl::StatusOr<FemCase> ParseEdited(absl::string_view base, const std::string& pointer,
                                      const Json& value) {
    Json doc = Json::parse(base);
    const Json::json_pointer p(pointer);
    if (value.is_discarded()) {
      Json& parent = doc[p.parent_pointer()];
      if (parent.is_array()) {
        parent.erase(static_cast<std::size_t>(std::stoul(p.back())));
      } else {
        parent.erase(p.back());
      }
    } else {
      doc[p] = value;
    }
    return Parse(doc.dump(2));
  }

  fs::path dir_;
};

}  // namespace rvehub::fem::case_test

#endif  // RVEHUB_TESTS_FEM_CLIENT_CASE_FEM_CASE_TEST_UTIL_H_
