#include "store/checkpoint.h"

#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "store/hdf5.h"
#include "store/record_io.h"

namespace rvehub::store {

using internal::kKindRves;
using internal::kKindTemplates;
using internal::StoreMutex;

absl::Status WriteRves(const std::string& path, std::span<const RveRecord> rves,
                       const FileInfo& info) {
  RETURN_IF_ERROR(internal::CheckRveRecords(path, rves));
  const std::pair<const char*, std::int64_t> counts[] = {
      {"num_records", static_cast<std::int64_t>(rves.size())}};
  std::lock_guard<std::mutex> lock(StoreMutex());
  return internal::WriteAtomically(path, kKindRves, counts, info, [&](h5::File& file) {
    return internal::WriteRveRecords(file, "", rves);
  });
}

absl::StatusOr<std::vector<RveRecord>> ReadRves(const std::string& path, FileInfo* info) {
  std::lock_guard<std::mutex> lock(StoreMutex());
  ASSIGN_OR_RETURN(h5::File file, internal::OpenStore(path, kKindRves, info));
  ASSIGN_OR_RETURN(std::size_t n, internal::ReadCount(file, "num_records"));
  return internal::ReadRveRecords(file, "", n);
}

absl::Status WriteTemplates(const std::string& path, std::span<const TemplateRecord> templates,
                            const FileInfo& info) {
  RETURN_IF_ERROR(internal::CheckTemplateRecords(path, templates));
  const std::pair<const char*, std::int64_t> counts[] = {
      {"num_records", static_cast<std::int64_t>(templates.size())}};
  std::lock_guard<std::mutex> lock(StoreMutex());
  return internal::WriteAtomically(path, kKindTemplates, counts, info, [&](h5::File& file) {
    return internal::WriteTemplateRecords(file, "", templates);
  });
}

absl::StatusOr<std::vector<TemplateRecord>> ReadTemplates(const std::string& path, FileInfo* info) {
  std::lock_guard<std::mutex> lock(StoreMutex());
  ASSIGN_OR_RETURN(h5::File file, internal::OpenStore(path, kKindTemplates, info));
  ASSIGN_OR_RETURN(std::size_t n, internal::ReadCount(file, "num_records"));
  return internal::ReadTemplateRecords(file, "", n);
}

}  // namespace rvehub::store
