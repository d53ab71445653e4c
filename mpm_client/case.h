// Case files: a 2-D MPM×DEM problem as JSON (cases/FORMAT.md), parsed and
// validated into a CaseSpec (model.h), and written back canonically.
#ifndef RVEHUB_MPM_CLIENT_CASE_H_
#define RVEHUB_MPM_CLIENT_CASE_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "mpm_client/model.h"

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

// Reads and parses the case file at `path` (NotFound naming the path when it
// cannot be read); base_dir is the file's directory and the case name
// defaults to the file's stem. Parse errors are prefixed with "<path>: ".
absl::StatusOr<CaseSpec> LoadCase(const std::string& path);

// Canonical JSON of a spec (every field that applies: e.g. no "seed" for a
// template read from a file, no "remove_time" for a permanent wall), for
// checkpoints and `mpm_client check`. ParseCase(ToJson(s)) gives
// back s for any spec ParseCase produced. Tractions are written as vectors.
std::string ToJson(const CaseSpec& spec);

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_CASE_H_
