// What the case file tests share (case_test, case_errors_test,
// case_fuzz_test): status predicates, a full and a minimal case, and a
// fixture that parses them against a temporary directory holding the full
// case's template file.
#ifndef RVEHUB_TESTS_MPM_CLIENT_CASE_CASE_TEST_UTIL_H_
#define RVEHUB_TESTS_MPM_CLIENT_CASE_CASE_TEST_UTIL_H_

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"
#include "mpm_client/case/case.h"

namespace rvehub::mpm::case_test {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// gmock is not linked: plain predicates for status messages.
inline ::testing::AssertionResult MessageStartsWith(const absl::Status& status,
                                                    absl::string_view prefix) {
  if (absl::StartsWith(status.message(), prefix)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "message does not start with '" << prefix << "': " << status;
}
inline ::testing::AssertionResult MessageHas(const absl::Status& status, absl::string_view part) {
  if (absl::StrContains(status.message(), part)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not in: " << status;
}

// Every section, with non-default values wherever a default exists. The grid
// is 2 m × 2 m (4 × 4 cells of 0.5 m); "soil" fills [0, 1]², "top" sits on it.
inline constexpr char kFullCase[] = R"json({
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
             "plot_width": 0.5, "phi_deg": 30},
  "checks": [
    {"quantity": "N_q", "reference": 14.4, "relative_tolerance": 0.1,
     "source": "liang-zhao-mpm-dem §3.3 Fig. 12"},
    {"quantity": "N_q", "reference": "N_q_reduced", "relative_tolerance": 0.25,
     "source": "Terzaghi's N'_q, liang-zhao-mpm-dem eq. 47"},
    {"quantity": "ultimate_is_peak", "reference": 1, "absolute_tolerance": 0,
     "source": "general shear: a peak"}
  ]
})json";

// The smallest valid case: everything else takes model.h's defaults.
// In a BadEdit: remove the key instead of setting it.
inline const Json kRemove(Json::value_t::discarded);

inline constexpr char kMinimalCase[] = R"json({
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

}  // namespace rvehub::mpm::case_test

#endif  // RVEHUB_TESTS_MPM_CLIENT_CASE_CASE_TEST_UTIL_H_
