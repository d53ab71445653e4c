// The record layout of store files, as building blocks shared by the files
// that hold records: rves.h5 / templates.h5 (checkpoint.cc) and the
// simulation checkpoint (sim_checkpoint.cc), which stores the same layout
// under /rves and /templates. Private to store/ (it exposes store/hdf5.h).
#ifndef RVEHUB_STORE_RECORD_IO_H_
#define RVEHUB_STORE_RECORD_IO_H_

#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "rve_server/values/record.h"
#include "store/checkpoint.h"
#include "store/hdf5.h"

namespace rvehub::store::internal {

// Values of the root attribute `kind`.
inline constexpr char kKindRves[] = "rves";
inline constexpr char kKindTemplates[] = "templates";
inline constexpr char kKindSimulation[] = "simulation";
inline constexpr char kKindResults[] = "results";
// The files beside results.h5 that it links: one frame, one topology.
inline constexpr char kKindResultsFrame[] = "results_frame";
inline constexpr char kKindResultsTopology[] = "results_topology";

// One lock for every store call: HDF5 serialises its API anyway, and the
// lock also keeps two writers in one process off the same temporary file.
std::mutex& StoreMutex();

bool HasNul(const std::string& s);

// Current UTC time in ISO 8601 ("2026-11-22T10:15:00Z"); "" if unavailable.
std::string UtcNow();

// Best-effort fsync of a file (flags O_RDONLY) or directory (O_RDONLY |
// O_DIRECTORY): durability, not correctness, is at stake.
void SyncPath(const std::string& path, int flags);

// InvalidArgument ("cannot write PATH: record k (run …, id …): why") for the
// first record the reader would refuse; checked before anything is written.
absl::Status CheckRveRecords(const std::string& path, std::span<const RveRecord> rves);
absl::Status CheckTemplateRecords(const std::string& path,
                                  std::span<const TemplateRecord> templates);

// The record datasets (/records, /material, /controls, /packing,
// /particles, /contacts) under `group` ("" for the root, else e.g. "/rves").
absl::Status WriteRveRecords(h5::File& file, const std::string& group,
                             std::span<const RveRecord> rves);
absl::StatusOr<std::vector<RveRecord>> ReadRveRecords(const h5::File& file,
                                                      const std::string& group, std::size_t n);
absl::Status WriteTemplateRecords(h5::File& file, const std::string& group,
                                  std::span<const TemplateRecord> templates);
absl::StatusOr<std::vector<TemplateRecord>> ReadTemplateRecords(const h5::File& file,
                                                                const std::string& group,
                                                                std::size_t n);

// Builds a store file under a temporary name next to `path` with the root
// attributes format_version, kind, created_by, created_at, the integer
// attributes `counts` (e.g. {"num_records", n}) and engine, then whatever
// `body` writes; renames it over `path` only when complete (see FORMAT.md,
// "Atomic write"); first removes stale temporaries of `path`. A `path` that
// exists and is not a regular file (a directory, a device, a symbolic link)
// is InvalidArgument, and nothing is created. The caller holds StoreMutex().
absl::Status WriteAtomically(const std::string& path, const char* kind,
                             std::span<const std::pair<const char*, std::int64_t>> counts,
                             const FileInfo& info,
                             const std::function<absl::Status(h5::File&)>& body);

// Opens a store file of `kind`: checks that it is a regular file, its kind
// and its format_version, and fills `info` when given. The caller holds
// StoreMutex().
absl::StatusOr<h5::File> OpenStore(const std::string& path, const char* kind, FileInfo* info);

// A non-negative integer root attribute used as a row count, bounded by the
// file size so that a corrupt count cannot make a reader allocate absurdly.
absl::StatusOr<std::size_t> ReadCount(const h5::File& file, const char* attribute);

// DataLoss unless CSR `offsets` (read from `dataset`) start at 0 and never
// decrease.
absl::Status CheckOffsets(const std::vector<std::int64_t>& offsets, const std::string& dataset,
                          const std::string& path);

}  // namespace rvehub::store::internal

#endif  // RVEHUB_STORE_RECORD_IO_H_
