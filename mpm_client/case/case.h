// Case files: a 2-D MPM×DEM problem as JSON (cases/FORMAT.md), parsed and
// validated into a CaseSpec (model.h), and written back canonically.
#ifndef RVEHUB_MPM_CLIENT_CASE_CASE_H_
#define RVEHUB_MPM_CLIENT_CASE_CASE_H_

#include <cstdint>
#include <span>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "client_case/overrides.h"
#include "client_case/sections.h"
#include "mpm_client/core/model.h"

namespace rvehub::mpm {

// Parses and validates a case (JSON text). `base_dir` resolves relative
// template file paths; the spec holds them absolute (so a checkpointed spec
// does not depend on the working directory). Region corners and wall
// positions are snapped onto their grid lines. Errors are InvalidArgument
// "<JSON pointer of the bad field>: <what is wrong>", e.g.
// "/solver/pic_fraction: must be in [0, 1], got 1.5", or for a JSON syntax
// error "line L, column C: <parser message>". Unknown and duplicate keys are
// errors naming their path (they are usually typos).
absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir);

// One field of a case set from outside the file (mpm_client --set), so that a
// parameter sweep needs no copied case files; ParseOverride reads
// "PATH=VALUE" (client_case/overrides.h).
using client_case::CaseOverride;
using client_case::ParseOverride;

// solver.f_bar's names ("none", "nodal"), for mpm_client resume --f-bar.
// FBarFromName is InvalidArgument "must be one of none, nodal, got \"x\"" for
// any other name.
absl::string_view FBarName(FBar f);
absl::StatusOr<FBar> FBarFromName(absl::string_view name);

// ParseCase with `overrides` applied in order to the parsed JSON before it is
// validated, so an override is checked exactly like the file. An override
// whose parent is not in the case (or not an object or array, or an array
// index past its end) is InvalidArgument "--set <pointer>: ...".
absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir,
                                   std::span<const CaseOverride> overrides);

// What a case's run holds in memory, roughly: grid nodes (4 vectors each),
// material points (state, shape functions, buffers: ~1 KB each) and their
// RVEs (~140 bytes per disc, bench/README.md: 55.5 KB per 400-disc RVE; a
// template file's RVEs are counted at 400 discs). ParseCase refuses a case
// above kMaxCaseBytes (cases/FORMAT.md).
struct CaseSize {
  std::int64_t nodes = 0;
  std::int64_t points = 0;
  double bytes = 0.0;
};
inline constexpr double kBytesPerNode = 56.0;
inline constexpr double kBytesPerPoint = 1024.0;
inline constexpr double kRveBytesPerDisc = client_case::kRveBytesPerDisc;
inline constexpr double kMaxCaseBytes = 32.0 * (1 << 30);  // 32 GiB
CaseSize EstimateSize(const CaseSpec& spec);

// Reads and parses the case file at `path` (NotFound naming the path when it
// cannot be read); base_dir is the file's directory and the case name
// defaults to the file's stem. Parse errors are prefixed with "<path>: ".
absl::StatusOr<CaseSpec> LoadCase(const std::string& path,
                                  std::span<const CaseOverride> overrides = {});

// Canonical JSON of a spec (every field that applies: e.g. no "seed" for a
// template read from a file, no "remove_time" for a permanent wall), for
// checkpoints and `mpm_client check`. ParseCase(ToJson(s)) gives
// back s for any spec ParseCase produced. Tractions are written as vectors.
std::string ToJson(const CaseSpec& spec);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CASE_CASE_H_
