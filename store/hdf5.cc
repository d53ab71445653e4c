#include "store/hdf5.h"

#include <algorithm>
#include <cstring>
#include <string>
#include <thread>
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

// HDF5 1.10 closes every file still registered at process exit
// (H5_term_library). A file whose close failed (a full disk: ENOSPC, EFBIG)
// stays registered half-closed, and closing it again there crashes
// (H5F__close_cb). Every file here is closed by its owner before the call
// that opened it returns, so the exit hook has nothing left to do but crash:
// it is turned off before the library starts (at static initialisation).
[[maybe_unused]] const bool kNoExitHook = [] {
  H5dont_atexit();
  return true;
}();

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
  const std::string stack = TakeErrorStack();
  // A write that failed for want of space says so first: the stack buries
  // the errno HDF5's file driver saw in a long line.
  for (const auto& [marker, why] : {std::pair{"errno = 28,", "no space left on device"},
                                    std::pair{"errno = 27,", "file too large"}}) {
    if (absl::StrContains(stack, marker)) {
      return absl::ResourceExhaustedError(absl::StrCat(what, ": ", why, " (HDF5: ", stack, ")"));
    }
  }
  return absl::Status(code, absl::StrCat(what, ": ", stack));
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

namespace {

bool IsLockFailure(const std::string& stack) {
  return absl::StrContains(absl::AsciiStrToLower(stack), "unable to lock file");
}

// Opens (create: creates, truncating) `path` with `fapl`, retrying while
// another process holds the file's lock.
absl::StatusOr<Handle> OpenRetrying(const std::string& path, bool create, unsigned flags,
                                    hid_t fapl, LockRetry retry) {
  for (int attempt = 1;; ++attempt) {
    Handle file(create ? H5Fcreate(path.c_str(), flags, H5P_DEFAULT, fapl)
                       : H5Fopen(path.c_str(), flags, fapl),
                H5Fclose);
    if (file.valid()) return file;
    const ErrorInfo info = TakeErrorInfo();
    if (IsLockFailure(info.text) && attempt >= std::max(retry.attempts, 1)) {
      return absl::UnavailableError(absl::StrCat(
          path, " stays locked by another process (a reader keeping it open, e.g. h5py or ",
          "HDFView, or another run writing it): ", info.text));
    }
    if (!IsLockFailure(info.text)) {
      if (create) {
        return absl::InternalError(absl::StrCat("cannot create HDF5 file ", path, ": ", info.text));
      }
      return absl::DataLossError(
          absl::StrCat("cannot open ", path, (flags & H5F_ACC_RDWR) ? " for appending" : "",
                       info.metadata_checksum ? " (metadata checksum mismatch)" : "",
                       ": file is truncated, corrupt or not HDF5: ", info.text));
    }
    std::this_thread::sleep_for(retry.delay);
  }
}

}  // namespace

absl::StatusOr<File> File::Create(const std::string& path, Format format, LockRetry retry) {
  SilenceErrorPrinting();
  Handle fapl = FileAccess();
  if (!fapl.valid()) return Error(absl::StatusCode::kInternal, "creating a file access list");
  const H5F_libver_t low = format == Format::kV110 ? H5F_LIBVER_V110 : H5F_LIBVER_V18;
  if (Failed(H5Pset_libver_bounds(fapl.id(), low, H5F_LIBVER_V110))) {
    return Error(absl::StatusCode::kInternal, "setting the file format bounds");
  }
  ASSIGN_OR_RETURN(Handle file,
                   OpenRetrying(path, /*create=*/true, H5F_ACC_TRUNC, fapl.id(), retry));
  return File(std::move(file), path);
}

absl::StatusOr<File> File::Open(const std::string& path) {
  SilenceErrorPrinting();
  Handle fapl = FileAccess();
  if (!fapl.valid()) return Error(absl::StatusCode::kInternal, "creating a file access list");
  ASSIGN_OR_RETURN(Handle file,
                   OpenRetrying(path, /*create=*/false, H5F_ACC_RDONLY, fapl.id(), LockRetry{}));
  return File(std::move(file), path);
}

absl::StatusOr<File> File::OpenForAppend(const std::string& path, LockRetry retry) {
  SilenceErrorPrinting();
  Handle fapl = FileAccess();
  // The bounds of Format::kAppendable: objects added keep the file's format.
  if (!fapl.valid() || Failed(H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_V18, H5F_LIBVER_V110))) {
    return Error(absl::StatusCode::kInternal, "creating a file access list");
  }
  ASSIGN_OR_RETURN(Handle file,
                   OpenRetrying(path, /*create=*/false, H5F_ACC_RDWR, fapl.id(), retry));
  return File(std::move(file), path);
}

absl::Status File::Close() {
  if (!handle_.valid()) return absl::OkStatus();
  if (Failed(H5Fflush(handle_.id(), H5F_SCOPE_LOCAL))) {
    absl::Status error = Error(absl::StatusCode::kInternal, absl::StrCat("cannot flush ", path_));
    handle_.Close();
    H5Eclear2(H5E_DEFAULT);
    return error;
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

absl::Status Object::WriteAttributeRaw(const char* name, hid_t file_type, hid_t memory_type,
                                       const void* value) {
  const std::string what = absl::StrCat("cannot write attribute ", name, " of ", where_);
  const htri_t exists = H5Aexists(handle_.id(), name);
  if (exists < 0 || (exists > 0 && Failed(H5Adelete(handle_.id(), name)))) {
    return Error(absl::StatusCode::kInternal, what);
  }
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  if (!space.valid()) return Error(absl::StatusCode::kInternal, "creating a scalar dataspace");
  Handle attribute(H5Acreate2(handle_.id(), name, file_type, space.id(), H5P_DEFAULT, H5P_DEFAULT),
                   H5Aclose);
  if (!attribute.valid() || Failed(H5Awrite(attribute.id(), memory_type, value)) ||
      !attribute.Close()) {
    return Error(absl::StatusCode::kInternal, what);
  }
  return absl::OkStatus();
}

absl::Status Object::WriteStringAttribute(const char* name, absl::string_view value) {
  if (value.find('\0') != absl::string_view::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("attribute ", name, " of ", where_, " must not contain NUL bytes"));
  }
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  // HDF5 has no zero-length fixed strings: an empty value is one NUL byte.
  const std::string buffer = value.empty() ? std::string(1, '\0') : std::string(value);
  if (!type.valid() || Failed(H5Tset_size(type.id(), buffer.size())) ||
      Failed(H5Tset_strpad(type.id(), H5T_STR_NULLPAD)) ||
      Failed(H5Tset_cset(type.id(), H5T_CSET_UTF8))) {
    return Error(absl::StatusCode::kInternal,
                 absl::StrCat("cannot make the type of attribute ", name, " of ", where_));
  }
  return WriteAttributeRaw(name, type.id(), type.id(), buffer.data());
}

absl::StatusOr<bool> Object::HasAttribute(const char* name) const {
  const htri_t exists = H5Aexists(handle_.id(), name);
  if (exists < 0) return CorruptError("look up", absl::StrCat("attribute ", name, " of ", where_));
  return exists > 0;
}

namespace {

// Opens attribute `name` of `object`, which must hold one element.
absl::Status OpenScalarAttribute(hid_t object, const char* name, const std::string& where,
                                 Handle* attribute) {
  const htri_t exists = H5Aexists(object, name);
  if (exists < 0) return CorruptError("read", where);
  if (exists == 0) return absl::NotFoundError(absl::StrCat("missing ", where));
  *attribute = Handle(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
  if (!attribute->valid()) return CorruptError("open", where);
  Handle space(H5Aget_space(attribute->id()), H5Sclose);
  if (!space.valid() || H5Sget_simple_extent_npoints(space.id()) != 1) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " must hold exactly one value"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status Object::ReadAttributeRaw(const char* name, hid_t file_type, hid_t memory_type,
                                      void* value) const {
  const std::string where = absl::StrCat("attribute ", name, " of ", where_);
  Handle attribute;
  RETURN_IF_ERROR(OpenScalarAttribute(handle_.id(), name, where, &attribute));
  Handle type(H5Aget_type(attribute.id()), H5Tclose);
  if (!type.valid() || H5Tequal(type.id(), file_type) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " has an unexpected type"));
  }
  if (Failed(H5Aread(attribute.id(), memory_type, value))) return CorruptError("read", where);
  return absl::OkStatus();
}

absl::StatusOr<std::string> Object::ReadStringAttribute(const char* name) const {
  const std::string where = absl::StrCat("attribute ", name, " of ", where_);
  Handle attribute;
  RETURN_IF_ERROR(OpenScalarAttribute(handle_.id(), name, where, &attribute));
  Handle type(H5Aget_type(attribute.id()), H5Tclose);
  if (!type.valid() || H5Tget_class(type.id()) != H5T_STRING) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " is not a string"));
  }
  if (H5Tis_variable_str(type.id()) > 0) {
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

absl::StatusOr<std::int64_t> Object::ReadIntAttribute(const char* name) const {
  const std::string where = absl::StrCat("attribute ", name, " of ", where_);
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

absl::StatusOr<std::vector<std::string>> Group::LinkNames() const {
  H5G_info_t info;
  if (Failed(H5Gget_info(handle_.id(), &info))) {
    return Error(absl::StatusCode::kDataLoss, absl::StrCat("cannot open ", where_));
  }
  std::vector<std::string> names;
  for (H5_index_t index : {H5_INDEX_CRT_ORDER, H5_INDEX_NAME}) {
    names.clear();
    for (hsize_t k = 0; k < info.nlinks; ++k) {
      const ssize_t size =
          H5Lget_name_by_idx(handle_.id(), ".", index, H5_ITER_INC, k, nullptr, 0, H5P_DEFAULT);
      if (size < 0) break;
      std::string name(static_cast<std::size_t>(size) + 1, '\0');
      if (H5Lget_name_by_idx(handle_.id(), ".", index, H5_ITER_INC, k, name.data(), name.size(),
                             H5P_DEFAULT) < 0) {
        break;
      }
      name.resize(static_cast<std::size_t>(size));
      names.push_back(std::move(name));
    }
    if (names.size() == info.nlinks) {
      H5Eclear2(H5E_DEFAULT);  // a failed creation-order attempt
      return names;
    }
  }
  return Error(absl::StatusCode::kDataLoss, absl::StrCat("cannot list ", where_));
}

absl::StatusOr<Group> File::CreateGroup(const std::string& name) {
  const std::string where = Where("group", name);
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  if (!gcpl.valid() || Failed(H5Pset_link_creation_order(
                           gcpl.id(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED))) {
    return Error(absl::StatusCode::kInternal, "creating a group creation list");
  }
  Handle group(H5Gcreate2(handle_.id(), name.c_str(), H5P_DEFAULT, gcpl.id(), H5P_DEFAULT),
               H5Gclose);
  if (!group.valid()) return Error(absl::StatusCode::kInternal, "cannot create " + where);
  return Group(std::move(group), where);
}

absl::StatusOr<Group> File::OpenGroup(const std::string& name) const {
  const std::string where = Where("group", name);
  ASSIGN_OR_RETURN(bool exists, Exists(name));
  if (!exists) return absl::DataLossError(absl::StrCat("missing ", where, ": file is corrupt"));
  Handle group(H5Gopen2(handle_.id(), name.c_str(), H5P_DEFAULT), H5Gclose);
  if (!group.valid()) return CorruptError("open", where);
  return Group(std::move(group), where);
}

absl::StatusOr<Dataset> File::OpenDataset(const std::string& name) const {
  const std::string where = Where("dataset", name);
  ASSIGN_OR_RETURN(bool exists, Exists(name));
  if (!exists) return absl::DataLossError(absl::StrCat("missing ", where, ": file is corrupt"));
  Handle dataset(H5Dopen2(handle_.id(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!dataset.valid()) return CorruptError("open", where);
  return Dataset(std::move(dataset), where);
}

absl::Status File::Delete(const std::string& name) {
  if (Failed(H5Ldelete(handle_.id(), name.c_str(), H5P_DEFAULT))) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot delete ", name, " of ", path_));
  }
  return absl::OkStatus();
}

absl::Status File::CreateExternalLink(const std::string& name, const std::string& target_file,
                                      const std::string& target_object) {
  if (Failed(H5Lcreate_external(target_file.c_str(), target_object.c_str(), handle_.id(),
                                name.c_str(), H5P_DEFAULT, H5P_DEFAULT))) {
    return Error(
        absl::StatusCode::kInternal,
        absl::StrCat("cannot link ", name, " of ", path_, " to ", target_file, ":", target_object));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> File::ExternalLinkFile(const std::string& name) const {
  H5L_info_t info;
  if (Failed(H5Lget_info(handle_.id(), name.c_str(), &info, H5P_DEFAULT))) {
    return CorruptError("look up", Where("link", name));
  }
  if (info.type != H5L_TYPE_EXTERNAL) return std::string();
  std::string value(info.u.val_size, '\0');
  const char* file = nullptr;
  const char* object = nullptr;
  if (value.empty() ||
      Failed(H5Lget_val(handle_.id(), name.c_str(), value.data(), value.size(), H5P_DEFAULT)) ||
      Failed(H5Lunpack_elink_val(value.data(), value.size(), nullptr, &file, &object)) ||
      file == nullptr) {
    return CorruptError("read", Where("link", name));
  }
  return std::string(file);
}

absl::Status File::CopyFrom(const File& source, const std::string& name) {
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  if (!lcpl.valid() || Failed(H5Pset_create_intermediate_group(lcpl.id(), 1))) {
    return Error(absl::StatusCode::kInternal, "creating a link creation list");
  }
  if (Failed(
          H5Ocopy(source.id(), name.c_str(), handle_.id(), name.c_str(), H5P_DEFAULT, lcpl.id()))) {
    return Error(absl::StatusCode::kInternal,
                 absl::StrCat("cannot copy ", name, " of ", source.path(), " to ", path_));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::uint64_t> Object::FileSize() const {
  Handle file(H5Iget_file_id(handle_.id()), H5Fclose);
  hsize_t size = 0;
  if (!file.valid() || Failed(H5Fget_filesize(file.id(), &size))) {
    return Error(absl::StatusCode::kDataLoss,
                 absl::StrCat("cannot get the size of the file holding ", where_));
  }
  return static_cast<std::uint64_t>(size);
}

absl::Status File::CheckShape(const std::string& name, std::size_t rows, std::size_t width) const {
  Handle dataset;
  return OpenShaped(name, rows, width, &dataset);
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
                            hid_t memory_type, Handle* keep_open) {
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
  if (keep_open != nullptr) {
    *keep_open = std::move(dataset);
    return absl::OkStatus();
  }
  if (!dataset.Close()) {
    return Error(absl::StatusCode::kInternal, Where("cannot close dataset", name));
  }
  return absl::OkStatus();
}

namespace {

// The extent of an open dataset: its rank, and for rank 1 or 2 the current
// and maximum dimensions (an unreadable dataspace gives rank -1; the error
// stack is cleared). Callers accept only ranks 1 and 2.
struct Extent {
  int rank = -1;
  hsize_t dims[2] = {0, 0};
  hsize_t max_dims[2] = {0, 0};
};
Extent ExtentOf(hid_t dataset) {
  Extent e;
  Handle space(H5Dget_space(dataset), H5Sclose);
  const int rank = space.valid() ? H5Sget_simple_extent_ndims(space.id()) : -1;
  if (rank >= 1 && rank <= 2 && H5Sget_simple_extent_dims(space.id(), e.dims, e.max_dims) == rank) {
    e.rank = rank;
  } else {
    e.rank = rank >= 1 && rank <= 2 ? -1 : rank;
    H5Eclear2(H5E_DEFAULT);
  }
  return e;
}

}  // namespace

absl::Status File::OpenShaped(const std::string& name, std::size_t rows, std::size_t width,
                              Handle* dataset) const {
  const std::string where = Where("dataset", name);
  ASSIGN_OR_RETURN(bool exists, Exists(name));
  if (!exists) return absl::DataLossError(absl::StrCat("missing ", where));
  const Handle dapl = UncachedAccess();
  *dataset = Handle(H5Dopen2(handle_.id(), name.c_str(), dapl.valid() ? dapl.id() : H5P_DEFAULT),
                    H5Dclose);
  if (!dataset->valid()) return CorruptError("open", where);
  const Extent e = ExtentOf(dataset->id());
  const int rank = e.rank;
  const hsize_t* dims = e.dims;
  const int expected_rank = width == 0 ? 1 : 2;
  if (rank != expected_rank || dims[0] != rows || (rank == 2 && dims[1] != width)) {
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
  // A missing dataset is for the caller's open to report.
  ASSIGN_OR_RETURN(bool exists, Exists(name));
  if (!exists) return absl::OkStatus();
  // The dataset's own file: an external link may lead to another.
  Handle object(H5Oopen(handle_.id(), name.c_str(), H5P_DEFAULT), H5Oclose);
  if (!object.valid()) return CorruptError("open", Where("dataset", name));
  ASSIGN_OR_RETURN(std::uint64_t file_size,
                   Dataset(std::move(object), Where("dataset", name)).FileSize());
  const std::uint64_t row_bytes = std::uint64_t{element_size} * (width == 0 ? 1 : width);
  // Division, not multiplication: a corrupt count must not overflow.
  if (row_bytes == 0 || rows > file_size / row_bytes) {
    return absl::DataLossError(absl::StrCat(Where("dataset", name), " would hold ", rows,
                                            " rows of ", row_bytes, " bytes, more than the file's ",
                                            file_size, " bytes: file is corrupt"));
  }
  return absl::OkStatus();
}

absl::Status File::ReadRaw(const std::string& name, void* data, std::size_t rows, std::size_t width,
                           hid_t file_type, hid_t memory_type) const {
  const std::string where = Where("dataset", name);
  Handle dataset;
  RETURN_IF_ERROR(OpenShaped(name, rows, width, &dataset));
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

absl::Status File::CreateAppendableRaw(const std::string& name, std::size_t width,
                                       std::size_t element_size, hid_t file_type) {
  // ChunkedLayout gives a dataset of 0 rows an unlimited first dimension.
  Handle dataset;
  RETURN_IF_ERROR(
      CreateDataset(name, 0, width, (width == 0 ? 1 : width) * element_size, file_type, &dataset));
  if (!dataset.Close()) {
    return Error(absl::StatusCode::kInternal, Where("cannot close dataset", name));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::size_t> File::NumRows(const std::string& name) const {
  ASSIGN_OR_RETURN(Dataset dataset, OpenDataset(name));
  const Extent e = ExtentOf(dataset.id());
  if (e.rank != 1 && e.rank != 2) {
    return absl::DataLossError(absl::StrCat(Where("dataset", name), " is not 1-D or 2-D"));
  }
  return static_cast<std::size_t>(e.dims[0]);
}

absl::Status File::AppendRaw(const std::string& name, const void* data, std::size_t count,
                             hid_t file_type, hid_t memory_type) {
  const std::string where = Where("dataset", name);
  ASSIGN_OR_RETURN(Dataset dataset, OpenDataset(name));
  Handle type(H5Dget_type(dataset.id()), H5Tclose);
  const Extent e = ExtentOf(dataset.id());
  const int rank = e.rank;
  const hsize_t* dims = e.dims;
  if ((rank != 1 && rank != 2) || e.max_dims[0] != H5S_UNLIMITED || !type.valid() ||
      H5Tequal(type.id(), file_type) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::InvalidArgumentError(
        absl::StrCat(where, " is not an appendable dataset of this element type"));
  }
  const std::size_t width = rank == 2 ? dims[1] : 1;
  if (count % width != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(where, ": ", count, " values are not rows of ", width));
  }
  const hsize_t rows = count / width;
  if (rows == 0) return absl::OkStatus();
  const hsize_t new_dims[2] = {dims[0] + rows, dims[1]};
  const hsize_t start[2] = {dims[0], 0};
  const hsize_t block[2] = {rows, dims[1]};
  if (Failed(H5Dset_extent(dataset.id(), new_dims))) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot extend ", where));
  }
  Handle file_space(H5Dget_space(dataset.id()), H5Sclose);
  Handle memory_space(H5Screate_simple(rank, block, nullptr), H5Sclose);
  if (!file_space.valid() || !memory_space.valid() ||
      Failed(
          H5Sselect_hyperslab(file_space.id(), H5S_SELECT_SET, start, nullptr, block, nullptr)) ||
      Failed(H5Dwrite(dataset.id(), memory_type, memory_space.id(), file_space.id(), H5P_DEFAULT,
                      data))) {
    return Error(absl::StatusCode::kInternal, absl::StrCat("cannot append to ", where));
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
  RETURN_IF_ERROR(OpenShaped(name, rows, 0, &dataset));
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

}  // namespace rvehub::store::h5
