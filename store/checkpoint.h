// Checkpoint files: many RVE states (or packing templates) in one HDF5 file,
// laid out as a few large chunked, fletcher32-checksummed datasets indexed by
// record (store/FORMAT.md). Every RveSnapshot field round-trips bit for bit, so a
// restored RVE continues exactly as the saved one would have.
//
// Writes are atomic: the file is built under a temporary name next to `path`
// and renamed over it only when complete, so `path` always holds either the
// previous file or the new one. Reads check the file's kind and format
// version, every dataset's presence, shape and type, the offsets, every
// checksum (a mismatch is DataLoss naming the dataset) and every restored
// RveSnapshot (material, controls, array lengths, contact indices).
//
// Thread-safe: calls are serialised process-wide (HDF5 itself has one lock).
#ifndef RVEHUB_STORE_CHECKPOINT_H_
#define RVEHUB_STORE_CHECKPOINT_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "rve_server/values/record.h"

namespace rvehub::store {

// File-level facts written into every store file.
struct FileInfo {
  std::string created_by;           // program and version, e.g. "rve_server 0.3.0"
  std::string created_at;           // ISO 8601 UTC
  std::int32_t format_version = 0;  // filled in by the reader
};

// The format version this code writes, and the newest it reads.
inline constexpr std::int32_t kFormatVersion = 1;

// Writes `rves` to `path` (kind "rves"), replacing any file there atomically.
// An empty info.created_at is filled with the current UTC time.
// InvalidArgument for a record that could not be read back (invalid material
// or controls, inconsistent array lengths, contact indices out of range,
// strings with NUL bytes), before anything is written; NotFound /
// PermissionDenied / … when the directory is not writable; on any failure an
// existing `path` is left untouched and no temporary file remains.
absl::Status WriteRves(const std::string& path, std::span<const RveRecord> rves,
                       const FileInfo& info);

// Reads a file written by WriteRves, in the order written. NotFound when
// `path` does not exist; InvalidArgument when it is not an RVEHub store file
// or holds templates; FailedPrecondition when its format_version is newer
// than kFormatVersion; DataLoss when it is truncated, corrupt (checksum
// mismatch, naming the dataset) or inconsistent. `info`, when given, receives
// created_by, created_at and format_version.
absl::StatusOr<std::vector<RveRecord>> ReadRves(const std::string& path, FileInfo* info = nullptr);

// The same for packing templates (kind "templates").
absl::Status WriteTemplates(const std::string& path, std::span<const TemplateRecord> templates,
                            const FileInfo& info);
absl::StatusOr<std::vector<TemplateRecord>> ReadTemplates(const std::string& path,
                                                          FileInfo* info = nullptr);

// Removes the temporaries PATH.tmp-PID next to `path` that writers killed
// mid-write (kill -9, power loss) left behind: those whose PID names no
// live process, and, with `own_too`, this process's own (a process that
// starts after a crash may have the crashed one's PID, as in a container:
// before it writes anything itself, a temporary under its PID is stale).
// Others (a writer in another live process) are left alone.
void RemoveStaleTemporaries(const std::string& path, bool own_too = false);

}  // namespace rvehub::store

#endif  // RVEHUB_STORE_CHECKPOINT_H_
