// A whole-simulation checkpoint: the MPM state and every RVE state of a run
// in one HDF5 file (kind "simulation", store/FORMAT.md), from which
// `mpm_client resume <checkpoint>` continues bit-identically: every double
// round-trips bit for bit (−0.0 and NaN payloads included), and the RVEs and
// templates use the record layout of rves.h5 / templates.h5.
//
// Writes are atomic (temporary name, fsync, rename), like WriteRves. Reads
// check kind, format version, every dataset's presence, shape and type,
// offsets and checksums, as ReadRves does.
//
// Thread-safe: calls are serialised process-wide with the other store calls.
#ifndef RVEHUB_STORE_SIM_CHECKPOINT_H_
#define RVEHUB_STORE_SIM_CHECKPOINT_H_

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "rve_server/values/record.h"
#include "store/checkpoint.h"  // kFormatVersion

namespace rvehub::store {

struct SimCheckpoint {
  std::string case_json;  // the case file text as run (so resume needs nothing else)
  std::string run_id;
  std::int64_t step = 0;  // last completed MPM step, 0..kMaxStep
  double time = 0.0;      // s, finite, >= 0
  // Named flat arrays of the MPM state, bit-exact. Names are any strings
  // without NUL bytes (they are data, not HDF5 object names).
  std::map<std::string, std::vector<double>> doubles;
  std::map<std::string, std::vector<std::int64_t>> ints;
  std::vector<RveRecord> rves;            // every RVE, sorted by id (strictly increasing)
  std::vector<TemplateRecord> templates;  // templates the run used
};

// Writes `c` to `path` (kind "simulation"), replacing any file there
// atomically. An empty info.created_at is filled with the current UTC time.
// InvalidArgument, before anything is written, for strings with NUL bytes,
// a step or time ReadSimCheckpoint would refuse, RVEs not sorted by strictly
// increasing id, or a record WriteRves / WriteTemplates would refuse;
// otherwise the errors of WriteRves.
absl::Status WriteSimCheckpoint(const std::string& path, const SimCheckpoint& c,
                                const FileInfo& info);

// Reads a file written by WriteSimCheckpoint. NotFound when `path` does not
// exist; InvalidArgument when it is not an RVEHub store file or of another
// kind (rves, templates, results); FailedPrecondition when its
// format_version is newer than kFormatVersion; DataLoss when it is
// truncated, corrupt (checksum mismatch, naming the dataset) or
// inconsistent (a step outside 0..kMaxStep or a time that is not finite and
// >= 0 included). `info`, when given, receives created_by, created_at and
// format_version.
absl::StatusOr<SimCheckpoint> ReadSimCheckpoint(const std::string& path, FileInfo* info = nullptr);

}  // namespace rvehub::store

#endif  // RVEHUB_STORE_SIM_CHECKPOINT_H_
