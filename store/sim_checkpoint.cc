#include "store/sim_checkpoint.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "store/checkpoint.h"
#include "store/hdf5.h"
#include "store/record_io.h"

namespace rvehub::store {
namespace {

using h5::Span;
using internal::HasNul;

// Where the record sets live (the rves.h5 / templates.h5 layout below them).
constexpr char kRvesGroup[] = "/rves";
constexpr char kTemplatesGroup[] = "/templates";

// Named arrays as three datasets under `group`: name [a], offset [a+1]
// (CSR into values) and values [total], in the map's (sorted) order.
template <typename T>
absl::Status WriteNamedArrays(h5::File& file, const std::string& group,
                              const std::map<std::string, std::vector<T>>& arrays) {
  std::vector<std::string> names;
  std::vector<std::int64_t> offsets{0};
  std::vector<T> values;
  std::size_t total = 0;
  for (const auto& [name, array] : arrays) total += array.size();
  values.reserve(total);
  for (const auto& [name, array] : arrays) {
    names.push_back(name);
    values.insert(values.end(), array.begin(), array.end());
    offsets.push_back(static_cast<std::int64_t>(values.size()));
  }
  RETURN_IF_ERROR(file.WriteStrings(absl::StrCat(group, "/name"), names));
  RETURN_IF_ERROR(file.Write(absl::StrCat(group, "/offset"), Span(offsets)));
  return file.Write(absl::StrCat(group, "/values"), Span(values));
}

template <typename T>
absl::Status ReadNamedArrays(const h5::File& file, const std::string& group, std::size_t count,
                             std::map<std::string, std::vector<T>>* arrays) {
  std::vector<std::string> names;
  std::vector<std::int64_t> offsets;
  std::vector<T> values;
  const std::string offset_name = absl::StrCat(group, "/offset");
  RETURN_IF_ERROR(file.ReadStrings(absl::StrCat(group, "/name"), count, &names));
  RETURN_IF_ERROR(file.Read(offset_name, count + 1, 0, &offsets));
  RETURN_IF_ERROR(internal::CheckOffsets(offsets, offset_name, file.path()));
  // Read checks the shape against the last offset (and that it fits).
  RETURN_IF_ERROR(file.Read(absl::StrCat(group, "/values"),
                            static_cast<std::size_t>(offsets.back()), 0, &values));
  arrays->clear();
  for (std::size_t k = 0; k < count; ++k) {
    std::vector<T> array(values.begin() + offsets[k], values.begin() + offsets[k + 1]);
    if (!arrays->emplace(names[k], std::move(array)).second) {
      return absl::DataLossError(absl::StrCat("dataset ", group, "/name of ", file.path(),
                                              " names '", names[k], "' twice: file is corrupt"));
    }
  }
  return absl::OkStatus();
}

// One-element datasets for the scalars: checksummed like everything else,
// and doubles stay bit-exact (an attribute would be too, but unchecksummed
// data is what the store avoids).
template <typename T>
absl::Status WriteScalar(h5::File& file, const char* name, T value) {
  return file.Write(name, std::span<const T>(&value, 1));
}

template <typename T>
absl::Status ReadScalar(const h5::File& file, const char* name, T* value) {
  std::vector<T> v;
  RETURN_IF_ERROR(file.Read(name, 1, 0, &v));
  *value = v[0];
  return absl::OkStatus();
}

absl::Status ReadString(const h5::File& file, const char* name, std::string* value) {
  std::vector<std::string> v;
  RETURN_IF_ERROR(file.ReadStrings(name, 1, &v));
  *value = std::move(v[0]);
  return absl::OkStatus();
}

// Index of the first RVE whose id is not greater than its predecessor's,
// or rves.size().
std::size_t FirstUnsorted(const std::vector<RveRecord>& rves) {
  for (std::size_t k = 1; k < rves.size(); ++k) {
    if (rves[k].id <= rves[k - 1].id) return k;
  }
  return rves.size();
}

// Why the MPM step or time cannot be a run's ("" when they can): a step in
// 0..kMaxStep, a finite time >= 0.
std::string BadStepOrTime(std::int64_t step, double time) {
  if (step < 0 || step > kMaxStep) {
    return absl::StrCat("/simulation/step = ", step, " must lie in 0..", kMaxStep, " (2^53)");
  }
  if (!std::isfinite(time) || time < 0) {
    return absl::StrCat("/simulation/time = ", time, " s must be finite and >= 0");
  }
  return "";
}

absl::Status CheckCheckpoint(const std::string& path, const SimCheckpoint& c) {
  const auto invalid = [&path](absl::string_view why) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write ", path, ": ", why));
  };
  if (HasNul(c.case_json)) return invalid("case_json contains a NUL byte");
  if (HasNul(c.run_id)) return invalid("run_id contains a NUL byte");
  if (const std::string why = BadStepOrTime(c.step, c.time); !why.empty()) return invalid(why);
  for (const auto& [name, array] : c.doubles) {
    if (HasNul(name)) return invalid("a name in doubles contains a NUL byte");
  }
  for (const auto& [name, array] : c.ints) {
    if (HasNul(name)) return invalid("a name in ints contains a NUL byte");
  }
  if (const std::size_t k = FirstUnsorted(c.rves); k < c.rves.size()) {
    return invalid(absl::StrCat("rves must be sorted by strictly increasing id; record ", k,
                                " has id ", c.rves[k].id, " after ", c.rves[k - 1].id));
  }
  RETURN_IF_ERROR(internal::CheckRveRecords(path, c.rves));
  return internal::CheckTemplateRecords(path, c.templates);
}

}  // namespace

absl::Status WriteSimCheckpoint(const std::string& path, const SimCheckpoint& c,
                                const FileInfo& info) {
  RETURN_IF_ERROR(CheckCheckpoint(path, c));
  const std::pair<const char*, std::int64_t> counts[] = {
      {"num_rves", static_cast<std::int64_t>(c.rves.size())},
      {"num_templates", static_cast<std::int64_t>(c.templates.size())},
      {"num_double_arrays", static_cast<std::int64_t>(c.doubles.size())},
      {"num_int_arrays", static_cast<std::int64_t>(c.ints.size())},
  };
  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  return internal::WriteAtomically(
      path, internal::kKindSimulation, counts, info, [&](h5::File& file) -> absl::Status {
        const std::string strings[] = {c.case_json, c.run_id};
        RETURN_IF_ERROR(file.WriteStrings("/simulation/case_json",
                                          std::span<const std::string>(&strings[0], 1)));
        RETURN_IF_ERROR(
            file.WriteStrings("/simulation/run_id", std::span<const std::string>(&strings[1], 1)));
        RETURN_IF_ERROR(WriteScalar<std::int64_t>(file, "/simulation/step", c.step));
        RETURN_IF_ERROR(WriteScalar<double>(file, "/simulation/time", c.time));
        RETURN_IF_ERROR(WriteNamedArrays(file, "/mpm/doubles", c.doubles));
        RETURN_IF_ERROR(WriteNamedArrays(file, "/mpm/ints", c.ints));
        RETURN_IF_ERROR(internal::WriteRveRecords(file, kRvesGroup, c.rves));
        return internal::WriteTemplateRecords(file, kTemplatesGroup, c.templates);
      });
}

absl::StatusOr<SimCheckpoint> ReadSimCheckpoint(const std::string& path, FileInfo* info) {
  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  ASSIGN_OR_RETURN(h5::File file, internal::OpenStore(path, internal::kKindSimulation, info));
  std::size_t counts[4] = {};
  const char* const count_names[4] = {"num_rves", "num_templates", "num_double_arrays",
                                      "num_int_arrays"};
  for (int k = 0; k < 4; ++k) {
    ASSIGN_OR_RETURN(std::size_t n, internal::ReadCount(file, count_names[k]));
    counts[k] = n;
  }
  SimCheckpoint c;
  RETURN_IF_ERROR(ReadString(file, "/simulation/case_json", &c.case_json));
  RETURN_IF_ERROR(ReadString(file, "/simulation/run_id", &c.run_id));
  RETURN_IF_ERROR(ReadScalar(file, "/simulation/step", &c.step));
  RETURN_IF_ERROR(ReadScalar(file, "/simulation/time", &c.time));
  if (const std::string why = BadStepOrTime(c.step, c.time); !why.empty()) {
    return absl::DataLossError(absl::StrCat(path, ": ", why, ": file is corrupt"));
  }
  RETURN_IF_ERROR(ReadNamedArrays(file, "/mpm/doubles", counts[2], &c.doubles));
  RETURN_IF_ERROR(ReadNamedArrays(file, "/mpm/ints", counts[3], &c.ints));
  ASSIGN_OR_RETURN(std::vector<RveRecord> rves,
                   internal::ReadRveRecords(file, kRvesGroup, counts[0]));
  c.rves = std::move(rves);
  if (const std::size_t k = FirstUnsorted(c.rves); k < c.rves.size()) {
    return absl::DataLossError(absl::StrCat(
        "dataset ", kRvesGroup, "/records/id of ", path, " is not strictly increasing at entry ", k,
        " (", c.rves[k - 1].id, ", ", c.rves[k].id, "): file is corrupt"));
  }
  ASSIGN_OR_RETURN(std::vector<TemplateRecord> templates,
                   internal::ReadTemplateRecords(file, kTemplatesGroup, counts[1]));
  c.templates = std::move(templates);
  return c;
}

}  // namespace rvehub::store
