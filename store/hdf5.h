// Thin RAII wrappers over the HDF5 C API, private to store/: only store .cc
// files include this header, so HDF5's headers never reach the rest of the
// project. The only code that calls HDF5 directly: files, groups and
// datasets as RAII handles sharing one attribute interface (Object); whole
// 1-D or [rows × width] datasets of a few numeric types and of fixed-length
// strings, and appendable ones (every one chunked and
// fletcher32-checksummed). Every failure becomes an absl::Status naming the
// file, the object and the operation, with HDF5's error stack.
#ifndef RVEHUB_STORE_HDF5_H_
#define RVEHUB_STORE_HDF5_H_

#include <hdf5.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::store::h5 {

// Stops HDF5 from printing its error stack to stderr on the calling thread
// (the stack goes into the returned Status instead). In a thread-safe HDF5
// build the setting is per thread, so every entry point calls this; it is
// cheap after the first call on a thread.
void SilenceErrorPrinting();

// HDF5's current error stack of the calling thread as one line
// ("func(): description (minor); ..."), then clears it.
std::string TakeErrorStack();

// What went wrong on the stack, for choosing a status code.
struct ErrorInfo {
  std::string text;                // as TakeErrorStack
  bool fletcher32 = false;         // a chunk failed its fletcher32 checksum
  bool metadata_checksum = false;  // metadata (superblock, headers, indices) failed its checksum
};
ErrorInfo TakeErrorInfo();

// Status `code` with message "<what>: <HDF5 error stack>"; clears the stack.
absl::Status Error(absl::StatusCode code, absl::string_view what);

// One HDF5 identifier and the function that releases it. Move-only; the
// destructor closes (ignoring errors: use Close() where they matter).
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& other) noexcept : id_(other.id_), closer_(other.closer_) { other.id_ = -1; }
  Handle& operator=(Handle&& other) noexcept;
  ~Handle() { Reset(); }

  hid_t id() const { return id_; }
  bool valid() const { return id_ >= 0; }
  // Closes now; false when HDF5 reported an error (the stack holds it).
  bool Close();

 private:
  void Reset();
  hid_t id_ = -1;
  Closer closer_ = nullptr;
};

// The dataspace and dataset creation properties of every store dataset:
// [rows] (width 0) or [rows × width], chunked in about kChunkBytes with the
// rows spread evenly over the chunks, fletcher32-checksummed and never
// filled. False when HDF5 refuses (its error stack says why).
bool ChunkedLayout(std::size_t rows, std::size_t width, std::size_t row_bytes, Handle* space,
                   Handle* dcpl);

// Maps a C++ element type to its HDF5 memory type and its little-endian
// file type (the same bits on x86-64 and aarch64: no conversion happens).
template <typename T>
struct TypeOf;
template <>
struct TypeOf<double> {
  static hid_t Memory() { return H5T_NATIVE_DOUBLE; }
  static hid_t File() { return H5T_IEEE_F64LE; }
};
template <>
struct TypeOf<std::int64_t> {
  static hid_t Memory() { return H5T_NATIVE_INT64; }
  static hid_t File() { return H5T_STD_I64LE; }
};
template <>
struct TypeOf<std::int32_t> {
  static hid_t Memory() { return H5T_NATIVE_INT32; }
  static hid_t File() { return H5T_STD_I32LE; }
};
template <>
struct TypeOf<std::uint32_t> {
  static hid_t Memory() { return H5T_NATIVE_UINT32; }
  static hid_t File() { return H5T_STD_U32LE; }
};
template <>
struct TypeOf<std::uint8_t> {
  static hid_t Memory() { return H5T_NATIVE_UINT8; }
  static hid_t File() { return H5T_STD_U8LE; }
};

// `v` as the span File::Write takes (a vector does not convert to
// std::span<const T> while T is being deduced).
template <typename T>
std::span<const T> Span(const std::vector<T>& v) {
  return std::span<const T>(v.data(), v.size());
}

// Bytes of data per chunk that the writer aims for: large enough that the
// per-chunk overhead (index entry, checksum, one write call) vanishes, small
// enough that a corrupt chunk is pinpointed and a partial read stays cheap.
inline constexpr std::size_t kChunkBytes = std::size_t{1} << 20;  // 1 MiB

// How long a writer waits for HDF5's advisory lock of a file that another
// process keeps open (a reader such as h5py or HDFView): `attempts` opens,
// `delay` apart. The default tries once.
struct LockRetry {
  int attempts = 1;
  std::chrono::milliseconds delay{0};
};

// The on-disk format bounds a file is created with.
enum class Format {
  // v1.10 at both ends: checksummed superblock (v3), object headers (v2) and
  // chunk indices, readable by any HDF5 >= 1.10. For files written once
  // under a temporary name (checkpoints).
  kV110,
  // v1.8 .. v1.10: superblock v2 (checksummed) rather than v3, whose "open
  // for writing" flag a killed writer leaves set, after which HDF5 refuses
  // to open the file (even read-only) until `h5clear -s` runs. For files
  // reopened and appended to in place (results).
  kAppendable,
};

// An open HDF5 object (a file's root group, a group or a dataset) and its
// attributes: the part File, Group and Dataset share. Attribute strings are
// fixed-length UTF-8 (stored inside the checksummed object header, unlike
// variable-length strings, which live in the unchecksummed global heap);
// numbers are scalars of the types TypeOf knows.
class Object {
 public:
  Object(Object&&) = default;
  Object& operator=(Object&&) = default;

  hid_t id() const { return handle_.id(); }
  // "group /frames/30 of out/results.h5" and the like, for messages.
  const std::string& where() const { return where_; }

  // Writes a scalar attribute, replacing one of the same name.
  template <typename T>
  absl::Status WriteAttribute(const char* name, T value) {
    return WriteAttributeRaw(name, TypeOf<T>::File(), TypeOf<T>::Memory(), &value);
  }
  // InvalidArgument when `value` contains NUL bytes.
  absl::Status WriteStringAttribute(const char* name, absl::string_view value);

  // DataLoss when the lookup itself fails (corrupt metadata).
  absl::StatusOr<bool> HasAttribute(const char* name) const;
  // One value of exactly T's file type. NotFound when absent; DataLoss when
  // of another type or shape.
  template <typename T>
  absl::StatusOr<T> ReadAttribute(const char* name) const {
    T value{};
    if (absl::Status s = ReadAttributeRaw(name, TypeOf<T>::File(), TypeOf<T>::Memory(), &value);
        !s.ok()) {
      return s;
    }
    return value;
  }
  // Any integer type, as int64; any string type (h5py writes variable-length
  // strings by default, so files annotated from Python stay readable).
  // NotFound when absent; DataLoss when of another class.
  absl::StatusOr<std::int64_t> ReadIntAttribute(const char* name) const;
  absl::StatusOr<std::string> ReadStringAttribute(const char* name) const;

  // Size in bytes of the file that holds the object: another file than the
  // one opened where an external link led to it.
  absl::StatusOr<std::uint64_t> FileSize() const;

 protected:
  Object() = default;
  Object(Handle handle, std::string where) : handle_(std::move(handle)), where_(std::move(where)) {}

  Handle handle_;
  std::string where_;

 private:
  absl::Status WriteAttributeRaw(const char* name, hid_t file_type, hid_t memory_type,
                                 const void* value);
  absl::Status ReadAttributeRaw(const char* name, hid_t file_type, hid_t memory_type,
                                void* value) const;
};

// An open group. Created by File::CreateGroup / OpenGroup.
class Group : public Object {
 public:
  // The names of the group's links, in creation order where the group
  // tracks it (File::CreateGroup's groups do), else by name.
  absl::StatusOr<std::vector<std::string>> LinkNames() const;

 private:
  friend class File;
  using Object::Object;
};

// An open dataset, for its attributes. Created by File::WriteDataset /
// OpenDataset.
class Dataset : public Object {
 private:
  friend class File;
  using Object::Object;
};

// An open HDF5 file; as an Object, its attributes are the root group's.
// Dataset and group names are absolute paths ("/particles/sx"); the groups
// along a dataset's path are created on demand.
class File : public Object {
 public:
  // Creates (truncating) `path`. A file another process holds locked is
  // retried as `retry` says, then Unavailable.
  static absl::StatusOr<File> Create(const std::string& path, Format format = Format::kV110,
                                     LockRetry retry = {});
  // Opens `path` read-only. The caller checks existence first (for a precise
  // NotFound); a file HDF5 cannot open is reported as DataLoss.
  static absl::StatusOr<File> Open(const std::string& path);
  // Opens `path` for reading and writing (appending), retrying a lock as
  // Create does. DataLoss when HDF5 cannot open it.
  static absl::StatusOr<File> OpenForAppend(const std::string& path, LockRetry retry = {});

  const std::string& path() const { return path_; }
  // Flushes and closes, reporting errors (a write is complete only after this).
  absl::Status Close();
  // Size of the file in bytes as HDF5 sees it.
  absl::StatusOr<std::uint64_t> Size() const;

  // A new group whose links are listed in creation order (members keep the
  // order they were written in).
  absl::StatusOr<Group> CreateGroup(const std::string& name);
  // DataLoss when missing or unreadable.
  absl::StatusOr<Group> OpenGroup(const std::string& name) const;
  absl::StatusOr<Dataset> OpenDataset(const std::string& name) const;
  // Unlinks `name` (HDF5 does not reclaim its space; h5repack does).
  absl::Status Delete(const std::string& name);

  // A link `name` to object `target_object` of the file `target_file`. HDF5
  // looks for a relative `target_file` in the directory of the file holding
  // the link, so the two can be moved together.
  absl::Status CreateExternalLink(const std::string& name, const std::string& target_file,
                                  const std::string& target_object);
  // The file an external link `name` points to, as stored; "" when `name`
  // is a link of another kind. DataLoss when the lookup fails.
  absl::StatusOr<std::string> ExternalLinkFile(const std::string& name) const;
  // Copies object `name` of `source` (a group with everything below it) to
  // the same name here, creating the groups along the way.
  absl::Status CopyFrom(const File& source, const std::string& name);

  // A [rows] dataset (width 0) or a [rows × width] dataset from `data`
  // (row-major, rows·max(width, 1) elements), chunked and checksummed.
  template <typename T>
  absl::Status Write(const std::string& name, std::span<const T> data, std::size_t width = 0) {
    return WriteRaw(name, data.data(), data.size(), width, sizeof(T), TypeOf<T>::File(),
                    TypeOf<T>::Memory(), nullptr);
  }
  // As Write, and returns the dataset still open (for its attributes).
  template <typename T>
  absl::StatusOr<Dataset> WriteDataset(const std::string& name, std::span<const T> data,
                                       std::size_t width = 0) {
    Handle dataset;
    if (absl::Status s = WriteRaw(name, data.data(), data.size(), width, sizeof(T),
                                  TypeOf<T>::File(), TypeOf<T>::Memory(), &dataset);
        !s.ok()) {
      return s;
    }
    return Dataset(std::move(dataset), Where("dataset", name));
  }
  // Reads a dataset that must have exactly `rows` rows (and `width` columns,
  // 0 for 1-D) and exactly the element type T; anything else is DataLoss.
  template <typename T>
  absl::Status Read(const std::string& name, std::size_t rows, std::size_t width,
                    std::vector<T>* out) const {
    // Checked before allocating: a corrupt row count must not make the
    // reader allocate more than the file could hold.
    if (absl::Status s = CheckFits(name, rows, width, sizeof(T)); !s.ok()) return s;
    out->resize(rows * (width == 0 ? 1 : width));
    return ReadRaw(name, out->data(), rows, width, TypeOf<T>::File(), TypeOf<T>::Memory());
  }
  // DataLoss unless dataset `name` exists with shape [rows] (width 0) or
  // [rows × width]; reads nothing.
  absl::Status CheckShape(const std::string& name, std::size_t rows, std::size_t width) const;

  // Appendable datasets: [0 × width] (width 0: [0]) with an unlimited first
  // dimension, chunked and checksummed like the rest; AppendRows adds rows
  // at the end (rows·max(width, 1) values); NumRows says how many it holds.
  template <typename T>
  absl::Status CreateAppendable(const std::string& name, std::size_t width = 0) {
    return CreateAppendableRaw(name, width, sizeof(T), TypeOf<T>::File());
  }
  template <typename T>
  absl::Status AppendRows(const std::string& name, std::span<const T> data) {
    return AppendRaw(name, data.data(), data.size(), TypeOf<T>::File(), TypeOf<T>::Memory());
  }
  absl::StatusOr<std::size_t> NumRows(const std::string& name) const;

  // A [rows] dataset of fixed-length, NUL-padded UTF-8 strings as wide as the
  // longest (at least 1 byte). Strings must not contain NUL bytes.
  absl::Status WriteStrings(const std::string& name, std::span<const std::string> values);
  absl::Status ReadStrings(const std::string& name, std::size_t rows,
                           std::vector<std::string>* out) const;

  // Whether every group along `name` and the object itself exist; DataLoss
  // when the lookup itself fails (corrupt metadata).
  absl::StatusOr<bool> Exists(const std::string& name) const;

 private:
  File(Handle handle, std::string path)
      : Object(std::move(handle), absl::StrCat("file ", path)), path_(std::move(path)) {}
  absl::Status WriteRaw(const std::string& name, const void* data, std::size_t count,
                        std::size_t width, std::size_t element_size, hid_t file_type,
                        hid_t memory_type, Handle* keep_open);
  absl::Status ReadRaw(const std::string& name, void* data, std::size_t rows, std::size_t width,
                       hid_t file_type, hid_t memory_type) const;
  absl::Status CreateAppendableRaw(const std::string& name, std::size_t width,
                                   std::size_t element_size, hid_t file_type);
  absl::Status AppendRaw(const std::string& name, const void* data, std::size_t count,
                         hid_t file_type, hid_t memory_type);
  // DataLoss unless rows × max(width, 1) elements of `element_size` bytes
  // fit in the file that holds dataset `name` (unfiltered data must).
  absl::Status CheckFits(const std::string& name, std::size_t rows, std::size_t width,
                         std::size_t element_size) const;
  absl::Status CreateDataset(const std::string& name, std::size_t rows, std::size_t width,
                             std::size_t row_bytes, hid_t file_type, Handle* dataset);
  // Opens `name` and checks its shape against rows × width (0: 1-D).
  absl::Status OpenShaped(const std::string& name, std::size_t rows, std::size_t width,
                          Handle* dataset) const;
  // "dataset /particles/sx of FILE" and the like, for messages.
  std::string Where(absl::string_view what, absl::string_view name) const;

  std::string path_;
};

}  // namespace rvehub::store::h5

#endif  // RVEHUB_STORE_HDF5_H_
