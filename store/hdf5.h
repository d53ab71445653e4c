// Thin RAII wrappers over the HDF5 C API, private to store/: only store .cc
// files include this header, so HDF5's headers never reach the rest of the
// project. Only what the checkpoint code needs: create/open a file, whole
// 1-D or [rows × width] datasets of a few numeric types and of fixed-length
// strings (every one chunked and fletcher32-checksummed), and string and
// integer attributes on the root group. Every failure becomes an absl::Status
// naming the file, the object and the operation, with HDF5's error stack.
#ifndef RVEHUB_STORE_HDF5_H_
#define RVEHUB_STORE_HDF5_H_

#include <hdf5.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

// Returns the status of `expr` from the enclosing function when it is not OK
// (store/ .cc files only: this header is private to store/).
#define RETURN_IF_ERROR(expr)                          \
  do {                                                 \
    if (absl::Status s_ = (expr); !s_.ok()) return s_; \
  } while (false)

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

// An open HDF5 file. Dataset and attribute names are absolute paths
// ("/particles/sx"); groups along the path are created on demand.
class File {
 public:
  // Creates (truncating) `path` with the v1.10 file format, whose superblock,
  // object headers and chunk indices carry metadata checksums.
  static absl::StatusOr<File> Create(const std::string& path);
  // Opens `path` read-only. The caller checks existence first (for a precise
  // NotFound); a file HDF5 cannot open is reported as DataLoss.
  static absl::StatusOr<File> Open(const std::string& path);

  const std::string& path() const { return path_; }
  // Flushes and closes, reporting errors (a write is complete only after this).
  absl::Status Close();
  // Size of the file in bytes as HDF5 sees it.
  absl::StatusOr<std::uint64_t> Size() const;

  // Root-group attributes. Strings are fixed-length (stored inside the
  // checksummed object header, unlike variable-length strings, which live
  // in the unchecksummed global heap); integers are scalars.
  absl::Status WriteStringAttribute(const char* name, absl::string_view value);
  absl::Status WriteInt32Attribute(const char* name, std::int32_t value);
  absl::Status WriteInt64Attribute(const char* name, std::int64_t value);
  // NotFound when absent; DataLoss when of another type.
  absl::StatusOr<std::string> ReadStringAttribute(const char* name) const;
  absl::StatusOr<std::int64_t> ReadIntAttribute(const char* name) const;

  // A [rows] dataset (width 0) or a [rows × width] dataset from `data`
  // (row-major, rows·max(width, 1) elements), chunked and checksummed.
  template <typename T>
  absl::Status Write(const std::string& name, std::span<const T> data, std::size_t width = 0) {
    return WriteRaw(name, data.data(), data.size(), width, sizeof(T), TypeOf<T>::File(),
                    TypeOf<T>::Memory());
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

  // A [rows] dataset of fixed-length, NUL-padded UTF-8 strings as wide as the
  // longest (at least 1 byte). Strings must not contain NUL bytes.
  absl::Status WriteStrings(const std::string& name, std::span<const std::string> values);
  absl::Status ReadStrings(const std::string& name, std::size_t rows,
                           std::vector<std::string>* out) const;

  // Whether every group along `name` and the object itself exist; DataLoss
  // when the lookup itself fails (corrupt metadata).
  absl::StatusOr<bool> Exists(const std::string& name) const;
  hid_t id() const { return handle_.id(); }

 private:
  File(Handle handle, std::string path) : handle_(std::move(handle)), path_(std::move(path)) {}
  absl::Status WriteRaw(const std::string& name, const void* data, std::size_t count,
                        std::size_t width, std::size_t element_size, hid_t file_type,
                        hid_t memory_type);
  absl::Status ReadRaw(const std::string& name, void* data, std::size_t rows, std::size_t width,
                       hid_t file_type, hid_t memory_type) const;
  // DataLoss unless rows × max(width, 1) elements of `element_size` bytes
  // fit in the file (unfiltered data must).
  absl::Status CheckFits(const std::string& name, std::size_t rows, std::size_t width,
                         std::size_t element_size) const;
  absl::Status CreateDataset(const std::string& name, std::size_t rows, std::size_t width,
                             std::size_t row_bytes, hid_t file_type, Handle* dataset);
  // Opens `name` and checks its shape against rows × width (0: 1-D).
  absl::Status OpenDataset(const std::string& name, std::size_t rows, std::size_t width,
                           Handle* dataset) const;
  absl::Status WriteAttribute(const char* name, hid_t file_type, hid_t memory_type,
                              const void* value);
  // "dataset /particles/sx of FILE" and the like, for messages.
  std::string Where(absl::string_view what, absl::string_view name) const;

  Handle handle_;
  std::string path_;
};

}  // namespace rvehub::store::h5

#endif  // RVEHUB_STORE_HDF5_H_
