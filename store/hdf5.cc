#include "store/hdf5.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace rvehub::store::h5 {
namespace {

// HDF5 stores a chunk's size in 32 bits.
constexpr std::size_t kMaxChunkBytes = (std::size_t{1} << 32) - 1;

herr_t CollectError(unsigned /*n*/, const H5E_error2_t* err, void* client) {
  auto* info = static_cast<ErrorInfo*>(client);
  char minor[160] = "";
  if (H5Eget_msg(err->min_num, nullptr, minor, sizeof minor) < 0) minor[0] = '\0';
  const absl::string_view desc = err->desc != nullptr ? err->desc : "";
  // HDF5 reports checksum failures only as text: the fletcher32 filter says
  // "data error detected by Fletcher32 checksum", the metadata cache
  // "incorrect metadata checksum ...".
  const std::string lower = absl::AsciiStrToLower(absl::StrCat(desc, " ", minor));
  if (absl::StrContains(lower, "fletcher32")) {
    info->fletcher32 = true;
  } else if (absl::StrContains(lower, "checksum")) {
    info->metadata_checksum = true;
  }
  if (!info->text.empty()) info->text += "; ";
  absl::StrAppend(&info->text, err->func_name != nullptr ? err->func_name : "?", "(): ", desc);
  if (minor[0] != '\0') absl::StrAppend(&info->text, " (", minor, ")");
  return 0;
}

// DataLoss for a failed read of `what`, naming a checksum failure when the
// stack shows one; takes the stack.
absl::Status CorruptError(absl::string_view verb, absl::string_view what) {
  const ErrorInfo info = TakeErrorInfo();
  return absl::DataLossError(absl::StrCat(
      "cannot ", verb, " ", what, info.metadata_checksum ? ": checksum mismatch (metadata)" : "",
      ": file is corrupt (HDF5: ", info.text, ")"));
}

// File access list shared by Create and Open: HDF5's advisory file lock
// stays on, but a file system without locks (NFS, Lustre) is no error;
// writers never share a file anyway (each builds its own temporary).
Handle FileAccess() {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (fapl.valid() && H5Pset_file_locking(fapl.id(), 1, 1) < 0) return Handle();
  return fapl;
}

// Dataset access list without a chunk cache: every dataset is written and
// read whole, once, so caching chunks only adds a copy per chunk.
Handle UncachedAccess() {
  Handle dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  if (dapl.valid() && H5Pset_chunk_cache(dapl.id(), 0, 0, H5D_CHUNK_CACHE_W0_DEFAULT) < 0) {
    H5Eclear2(H5E_DEFAULT);
    return Handle();
  }
  return dapl;
}

// True when an HDF5 call returning herr_t (or htri_t/hid_t) failed.
bool Failed(herr_t result) { return result < 0; }

}  // namespace

void SilenceErrorPrinting() {
  thread_local bool silenced = false;
  if (!silenced) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    silenced = true;
  }
}

ErrorInfo TakeErrorInfo() {
  ErrorInfo info;
  // Upward: the innermost frame (the root cause) comes first.
  if (H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, CollectError, &info) < 0) {
    info.text = "(HDF5 error stack unavailable)";
  }
  H5Eclear2(H5E_DEFAULT);
  if (info.text.empty()) info.text = "(no HDF5 error recorded)";
  return info;
}

std::string TakeErrorStack() { return TakeErrorInfo().text; }

absl::Status Error(absl::StatusCode code, absl::string_view what) {
  return absl::Status(code, absl::StrCat(what, ": ", TakeErrorStack()));
}

Handle& Handle::operator=(Handle&& other) noexcept {
  if (this != &other) {
    Reset();
    id_ = other.id_;
    closer_ = other.closer_;
    other.id_ = -1;
  }
  return *this;
}

void Handle::Reset() {
  if (id_ >= 0 && closer_ != nullptr) closer_(id_);
  id_ = -1;
}

bool Handle::Close() {
  if (id_ < 0 || closer_ == nullptr) return true;
  const herr_t result = closer_(id_);
  id_ = -1;
  return result >= 0;
}

std::string File::Where(absl::string_view what, absl::string_view name) const {
  return absl::StrCat(what, " ", name, " of ", path_);
}

absl::StatusOr<File> File::Create(const std::string& path) {
  SilenceErrorPrinting();
  Handle fapl = FileAccess();
  if (!fapl.valid()) return Error(absl::StatusCode::kInternal, "creating a file access list");
  // v1.10 format at both ends: checksummed superblock (v3), object headers
  // (v2) and chunk indices, and a format any HDF5 >= 1.10 reads.
  if (Failed(H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_V110, H5F_LIBVER_V110))) {
    return Error(absl::StatusCode::kInternal, "setting the v1.10 file format");
  }
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id()), H5Fclose);
  if (!file.valid()) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot create HDF5 file ", path));
  }
  return File(std::move(file), path);
}

absl::StatusOr<File> File::Open(const std::string& path) {
  SilenceErrorPrinting();
  Handle fapl = FileAccess();
  if (!fapl.valid()) return Error(absl::StatusCode::kInternal, "creating a file access list");
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl.id()), H5Fclose);
  if (!file.valid()) {
    const ErrorInfo info = TakeErrorInfo();
    return absl::DataLossError(
        absl::StrCat("cannot open ", path, " as an HDF5 file",
                     info.metadata_checksum ? " (metadata checksum mismatch)" : "",
                     ": file is truncated, corrupt or not HDF5: ", info.text));
  }
  return File(std::move(file), path);
}

absl::Status File::Close() {
  if (!handle_.valid()) return absl::OkStatus();
  if (Failed(H5Fflush(handle_.id(), H5F_SCOPE_LOCAL))) {
    const std::string stack = TakeErrorStack();
    handle_.Close();
    H5Eclear2(H5E_DEFAULT);
    return absl::InternalError(absl::StrCat("cannot flush ", path_, ": ", stack));
  }
  if (!handle_.Close()) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot close ", path_));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::uint64_t> File::Size() const {
  hsize_t size = 0;
  if (Failed(H5Fget_filesize(handle_.id(), &size))) {
    return Error(absl::StatusCode::kDataLoss, absl::StrCat("cannot get the size of ", path_));
  }
  return static_cast<std::uint64_t>(size);
}

absl::StatusOr<bool> File::Exists(const std::string& name) const {
  // H5Lexists fails (rather than answering false) when an intermediate group
  // is missing, so walk the path one component at a time.
  std::size_t pos = 0;
  while (pos != std::string::npos) {
    pos = name.find('/', pos + 1);
    const std::string prefix = name.substr(0, pos);
    if (prefix.empty() || prefix == "/") continue;
    const htri_t exists = H5Lexists(handle_.id(), prefix.c_str(), H5P_DEFAULT);
    if (exists < 0) return CorruptError("look up", absl::StrCat(prefix, " in ", path_));
    if (exists == 0) return false;
  }
  return true;
}

absl::Status File::WriteAttribute(const char* name, hid_t file_type, hid_t memory_type,
                                  const void* value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  if (!space.valid()) return Error(absl::StatusCode::kInternal, "creating a scalar dataspace");
  Handle attribute(H5Acreate2(handle_.id(), name, file_type, space.id(), H5P_DEFAULT, H5P_DEFAULT),
                   H5Aclose);
  if (!attribute.valid() || Failed(H5Awrite(attribute.id(), memory_type, value)) ||
      !attribute.Close()) {
    return Error(absl::StatusCode::kInternal, Where("cannot write attribute", name));
  }
  return absl::OkStatus();
}

absl::Status File::WriteStringAttribute(const char* name, absl::string_view value) {
  if (value.find('\0') != absl::string_view::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("attribute ", name, " must not contain NUL bytes"));
  }
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  // HDF5 has no zero-length fixed strings: an empty value is one NUL byte.
  const std::string buffer = value.empty() ? std::string(1, '\0') : std::string(value);
  if (!type.valid() || Failed(H5Tset_size(type.id(), buffer.size())) ||
      Failed(H5Tset_strpad(type.id(), H5T_STR_NULLPAD)) ||
      Failed(H5Tset_cset(type.id(), H5T_CSET_UTF8))) {
    return Error(absl::StatusCode::kInternal, Where("cannot make the type of attribute", name));
  }
  return WriteAttribute(name, type.id(), type.id(), buffer.data());
}

absl::Status File::WriteInt32Attribute(const char* name, std::int32_t value) {
  return WriteAttribute(name, H5T_STD_I32LE, H5T_NATIVE_INT32, &value);
}

absl::Status File::WriteInt64Attribute(const char* name, std::int64_t value) {
  return WriteAttribute(name, H5T_STD_I64LE, H5T_NATIVE_INT64, &value);
}

namespace {

// Opens attribute `name` of `file`, which must hold one element.
absl::Status OpenScalarAttribute(hid_t file, const char* name, const std::string& where,
                                 Handle* attribute) {
  const htri_t exists = H5Aexists(file, name);
  if (exists < 0) return CorruptError("read", where);
  if (exists == 0) return absl::NotFoundError(absl::StrCat("missing ", where));
  *attribute = Handle(H5Aopen(file, name, H5P_DEFAULT), H5Aclose);
  if (!attribute->valid()) return CorruptError("open", where);
  Handle space(H5Aget_space(attribute->id()), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space.id()) != 1) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " must hold exactly one value"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::string> File::ReadStringAttribute(const char* name) const {
  const std::string where = Where("attribute", name);
  Handle attribute;
  RETURN_IF_ERROR(OpenScalarAttribute(handle_.id(), name, where, &attribute));
  Handle type(H5Aget_type(attribute.id()), H5Tclose);
  if (!type.valid() || H5Tget_class(type.id()) != H5T_STRING) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " is not a string"));
  }
  if (H5Tis_variable_str(type.id()) > 0) {
    // Not what this code writes, but what h5py writes by default: accepted
    // so that files annotated from Python stay readable.
    Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
    char* text = nullptr;
    if (!memory.valid() || Failed(H5Tset_size(memory.id(), H5T_VARIABLE)) ||
        Failed(H5Tset_cset(memory.id(), H5Tget_cset(type.id()))) ||
        Failed(H5Aread(attribute.id(), memory.id(), &text))) {
      return CorruptError("read", where);
    }
    std::string value = text != nullptr ? text : "";
    H5free_memory(text);
    return value;
  }
  const std::size_t size = H5Tget_size(type.id());
  std::string buffer(size, '\0');
  if (size == 0 || Failed(H5Aread(attribute.id(), type.id(), buffer.data()))) {
    return CorruptError("read", where);
  }
  buffer.resize(std::strlen(buffer.c_str()));  // drop the NUL padding
  return buffer;
}

absl::StatusOr<std::int64_t> File::ReadIntAttribute(const char* name) const {
  const std::string where = Where("attribute", name);
  Handle attribute;
  RETURN_IF_ERROR(OpenScalarAttribute(handle_.id(), name, where, &attribute));
  Handle type(H5Aget_type(attribute.id()), H5Tclose);
  if (!type.valid() || H5Tget_class(type.id()) != H5T_INTEGER) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " is not an integer"));
  }
  std::int64_t value = 0;
  if (Failed(H5Aread(attribute.id(), H5T_NATIVE_INT64, &value))) {
    return CorruptError("read", where);
  }
  return value;
}

bool ChunkedLayout(std::size_t rows, std::size_t width, std::size_t row_bytes, Handle* space,
                   Handle* dcpl) {
  const int rank = width == 0 ? 1 : 2;
  const hsize_t dims[2] = {rows, width};
  // HDF5 cannot chunk a dimension fixed at size 0, so an empty dataset gets
  // an unlimited first dimension (and stays chunked and checksummed).
  const hsize_t max_dims[2] = {rows == 0 ? H5S_UNLIMITED : rows, width};
  // About kChunkBytes per chunk, the rows spread evenly over the chunks:
  // HDF5 stores a partial last chunk at full size, so 800 000 rows in chunks
  // of 131 072 would waste 0.9 MB; in chunks of 114 286 they waste 2 rows.
  hsize_t chunk_rows = std::max<std::size_t>(1, kChunkBytes / row_bytes);
  if (rows > 0) {
    const hsize_t num_chunks = (rows + chunk_rows - 1) / chunk_rows;
    chunk_rows = (rows + num_chunks - 1) / num_chunks;
  }
  const hsize_t chunk[2] = {chunk_rows, width};
  *space = Handle(H5Screate_simple(rank, dims, max_dims), H5Sclose);
  *dcpl = Handle(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  return space->valid() && dcpl->valid() && !Failed(H5Pset_chunk(dcpl->id(), rank, chunk)) &&
         !Failed(H5Pset_fletcher32(dcpl->id())) &&
         // Every element is written at once: filling chunks first is wasted work.
         !Failed(H5Pset_fill_time(dcpl->id(), H5D_FILL_TIME_NEVER));
}

absl::Status File::CreateDataset(const std::string& name, std::size_t rows, std::size_t width,
                                 std::size_t row_bytes, hid_t file_type, Handle* dataset) {
  const std::string where = Where("dataset", name);
  if (row_bytes == 0 || row_bytes > kMaxChunkBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat(where, ": a row of ", row_bytes, " bytes does not fit an HDF5 chunk"));
  }
  Handle space, dcpl;
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  if (!ChunkedLayout(rows, width, row_bytes, &space, &dcpl) || !lcpl.valid() ||
      Failed(H5Pset_create_intermediate_group(lcpl.id(), 1))) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot set up ", where));
  }
  const Handle dapl = UncachedAccess();
  *dataset = Handle(H5Dcreate2(handle_.id(), name.c_str(), file_type, space.id(), lcpl.id(),
                               dcpl.id(), dapl.valid() ? dapl.id() : H5P_DEFAULT),
                    H5Dclose);
  if (!dataset->valid()) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot create ", where));
  }
  return absl::OkStatus();
}

absl::Status File::WriteRaw(const std::string& name, const void* data, std::size_t count,
                            std::size_t width, std::size_t element_size, hid_t file_type,
                            hid_t memory_type) {
  const std::size_t per_row = width == 0 ? 1 : width;
  if (count % per_row != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(Where("dataset", name), ": ", count, " values are not rows of ", per_row));
  }
  const std::size_t rows = count / per_row;
  Handle dataset;
  RETURN_IF_ERROR(CreateDataset(name, rows, width, per_row * element_size, file_type, &dataset));
  if (rows > 0 &&
      Failed(H5Dwrite(dataset.id(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data))) {
    return Error(absl::StatusCode::kInternal, Where("cannot write dataset", name));
  }
  if (!dataset.Close()) {
    return Error(absl::StatusCode::kInternal, Where("cannot close dataset", name));
  }
  return absl::OkStatus();
}

absl::Status File::OpenDataset(const std::string& name, std::size_t rows, std::size_t width,
                               Handle* dataset) const {
  const std::string where = Where("dataset", name);
  absl::StatusOr<bool> exists = Exists(name);
  if (!exists.ok()) return exists.status();
  if (!*exists) return absl::DataLossError(absl::StrCat("missing ", where));
  const Handle dapl = UncachedAccess();
  *dataset = Handle(H5Dopen2(handle_.id(), name.c_str(), dapl.valid() ? dapl.id() : H5P_DEFAULT),
                    H5Dclose);
  if (!dataset->valid()) return CorruptError("open", where);
  Handle space(H5Dget_space(dataset->id()), H5Sclose);
  const int rank = space.valid() ? H5Sget_simple_extent_ndims(space.id()) : -1;
  hsize_t dims[2] = {0, 0};
  const int expected_rank = width == 0 ? 1 : 2;
  if (rank != expected_rank || H5Sget_simple_extent_dims(space.id(), dims, nullptr) != rank ||
      dims[0] != rows || (rank == 2 && dims[1] != width)) {
    H5Eclear2(H5E_DEFAULT);
    const std::string expected =
        width == 0 ? absl::StrCat("[", rows, "]") : absl::StrCat("[", rows, ", ", width, "]");
    const std::string found = rank == 1   ? absl::StrCat("[", dims[0], "]")
                              : rank == 2 ? absl::StrCat("[", dims[0], ", ", dims[1], "]")
                                          : absl::StrCat("rank ", rank);
    return absl::DataLossError(
        absl::StrCat(where, " has shape ", found, "; expected ", expected, ": file is corrupt"));
  }
  return absl::OkStatus();
}

namespace {

// The status of a failed H5Dread of `where`.
absl::Status ReadFailure(const std::string& where) {
  const ErrorInfo info = TakeErrorInfo();
  if (info.fletcher32) {
    return absl::DataLossError(absl::StrCat("checksum mismatch (fletcher32) in ", where,
                                            ": file is corrupt (HDF5: ", info.text, ")"));
  }
  if (info.metadata_checksum) {
    return absl::DataLossError(absl::StrCat("checksum mismatch (metadata) reading ", where,
                                            ": file is corrupt (HDF5: ", info.text, ")"));
  }
  return absl::DataLossError(
      absl::StrCat("cannot read ", where, ": file is corrupt (HDF5: ", info.text, ")"));
}

}  // namespace

absl::Status File::CheckFits(const std::string& name, std::size_t rows, std::size_t width,
                             std::size_t element_size) const {
  if (rows == 0) return absl::OkStatus();
  absl::StatusOr<std::uint64_t> file_size = Size();
  if (!file_size.ok()) return file_size.status();
  const std::uint64_t row_bytes = std::uint64_t{element_size} * (width == 0 ? 1 : width);
  // Division, not multiplication: a corrupt count must not overflow.
  if (row_bytes == 0 || rows > *file_size / row_bytes) {
    return absl::DataLossError(absl::StrCat(Where("dataset", name), " would hold ", rows,
                                            " rows of ", row_bytes, " bytes, more than the file's ",
                                            *file_size, " bytes: file is corrupt"));
  }
  return absl::OkStatus();
}

absl::Status File::ReadRaw(const std::string& name, void* data, std::size_t rows, std::size_t width,
                           hid_t file_type, hid_t memory_type) const {
  const std::string where = Where("dataset", name);
  Handle dataset;
  RETURN_IF_ERROR(OpenDataset(name, rows, width, &dataset));
  Handle type(H5Dget_type(dataset.id()), H5Tclose);
  // Exactly the stored type, so the read converts nothing and the bits
  // come back as written.
  if (!type.valid() || H5Tequal(type.id(), file_type) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " has an unexpected element type"));
  }
  if (rows == 0) return absl::OkStatus();
  if (Failed(H5Dread(dataset.id(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data))) {
    return ReadFailure(where);
  }
  return absl::OkStatus();
}

absl::Status File::WriteStrings(const std::string& name, std::span<const std::string> values) {
  std::size_t width = 1;  // HDF5 has no zero-length fixed strings
  for (const std::string& v : values) {
    if (v.find('\0') != std::string::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat(Where("dataset", name), ": strings must not contain NUL bytes"));
    }
    width = std::max(width, v.size());
  }
  std::string buffer(values.size() * width, '\0');
  for (std::size_t k = 0; k < values.size(); ++k) {
    std::memcpy(buffer.data() + k * width, values[k].data(), values[k].size());
  }
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!type.valid() || Failed(H5Tset_size(type.id(), width)) ||
      Failed(H5Tset_strpad(type.id(), H5T_STR_NULLPAD)) ||
      Failed(H5Tset_cset(type.id(), H5T_CSET_UTF8))) {
    return Error(absl::StatusCode::kInternal, Where("cannot make the string type of", name));
  }
  Handle dataset;
  RETURN_IF_ERROR(CreateDataset(name, values.size(), 0, width, type.id(), &dataset));
  if (!values.empty() &&
      Failed(H5Dwrite(dataset.id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()))) {
    return Error(absl::StatusCode::kInternal, Where("cannot write dataset", name));
  }
  if (!dataset.Close()) {
    return Error(absl::StatusCode::kInternal, Where("cannot close dataset", name));
  }
  return absl::OkStatus();
}

absl::Status File::ReadStrings(const std::string& name, std::size_t rows,
                               std::vector<std::string>* out) const {
  const std::string where = Where("dataset", name);
  Handle dataset;
  RETURN_IF_ERROR(OpenDataset(name, rows, 0, &dataset));
  Handle type(H5Dget_type(dataset.id()), H5Tclose);
  if (!type.valid() || H5Tget_class(type.id()) != H5T_STRING ||
      H5Tis_variable_str(type.id()) != 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " is not a fixed-length string dataset"));
  }
  const std::size_t width = H5Tget_size(type.id());
  if (width == 0) return absl::DataLossError(absl::StrCat(where, " has 0-byte strings"));
  RETURN_IF_ERROR(CheckFits(name, rows, width, 1));
  std::string buffer(rows * width, '\0');
  if (rows > 0 &&
      Failed(H5Dread(dataset.id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()))) {
    return ReadFailure(where);
  }
  out->clear();
  out->reserve(rows);
  for (std::size_t k = 0; k < rows; ++k) {
    const char* begin = buffer.data() + k * width;
    out->emplace_back(begin, std::find(begin, begin + width, '\0'));
  }
  return absl::OkStatus();
}

#undef RETURN_IF_ERROR

}  // namespace rvehub::store::h5
