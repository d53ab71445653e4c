#include "store/results.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "store/checkpoint.h"
#include "store/hdf5.h"
#include "store/record_io.h"

namespace rvehub::store {
namespace {

namespace fs = std::filesystem;
using h5::Handle;
using h5::Span;

constexpr char kFramesGroup[] = "/frames";
constexpr char kTopologyGroup[] = "/topology";
constexpr char kPosition[] = "position";

// A reader that keeps the HDF5 file open (h5py, HDFView) holds HDF5's
// advisory lock and makes the writer's open fail; readers that open per
// read (ParaView) let go within moments, so the writer retries for a while.
constexpr int kLockAttempts = 40;
constexpr std::chrono::milliseconds kLockRetryDelay(250);  // 40 × 0.25 s = 10 s

// ----------------------------------------------------------------------------
// HDF5 pieces the read-only h5::File does not offer: opening for appending,
// groups with ordered links, attributes on groups and datasets, deletion.

// File access list: HDF5's advisory lock as in the rest of the store, and
// format bounds V18..V110, which give superblock version 2 (checksummed)
// rather than 3: version 3 carries an "open for writing" flag that a killed
// writer leaves set, after which HDF5 refuses to open the file (even
// read-only) until `h5clear -s` is run on it.
Handle ResultsFileAccess() {
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (!fapl.valid() || H5Pset_file_locking(fapl.id(), 1, 1) < 0 ||
      H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_V18, H5F_LIBVER_V110) < 0) {
    return Handle();
  }
  return fapl;
}

bool IsLockFailure(const std::string& stack) {
  return absl::StrContains(absl::AsciiStrToLower(stack), "unable to lock file");
}

// Creates (truncating) or opens for appending, retrying while another
// process holds the file's lock.
absl::Status OpenForWriting(const std::string& path, bool create, Handle* file) {
  Handle fapl = ResultsFileAccess();
  if (!fapl.valid()) return h5::Error(absl::StatusCode::kInternal, "creating a file access list");
  for (int attempt = 1;; ++attempt) {
    *file = Handle(create ? H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id())
                          : H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl.id()),
                   H5Fclose);
    if (file->valid()) return absl::OkStatus();
    const h5::ErrorInfo info = h5::TakeErrorInfo();
    if (!IsLockFailure(info.text)) {
      return absl::Status(create ? absl::StatusCode::kInternal : absl::StatusCode::kDataLoss,
                          absl::StrCat("cannot ", create ? "create " : "open ", path,
                                       create ? "" : " for appending", ": ", info.text));
    }
    if (attempt == kLockAttempts) {
      return absl::UnavailableError(absl::StrCat(
          path, " stays locked by another process (a reader keeping it open, e.g. h5py or ",
          "HDFView, or another run writing it): ", info.text));
    }
    std::this_thread::sleep_for(kLockRetryDelay);
  }
}

// Closes, reporting errors (a frame is on disk only after this).
absl::Status CloseFile(Handle& file, const std::string& path) {
  if (H5Fflush(file.id(), H5F_SCOPE_LOCAL) < 0 || !file.Close()) {
    return h5::Error(absl::StatusCode::kInternal, absl::StrCat("cannot close ", path));
  }
  return absl::OkStatus();
}

// A group whose links are listed in creation order (fields keep their
// order; frames are listed as appended).
absl::Status CreateGroup(hid_t file, const std::string& name, const std::string& path) {
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  if (!gcpl.valid() ||
      H5Pset_link_creation_order(gcpl.id(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED) < 0) {
    return h5::Error(absl::StatusCode::kInternal, "creating a group creation list");
  }
  Handle group(H5Gcreate2(file, name.c_str(), H5P_DEFAULT, gcpl.id(), H5P_DEFAULT), H5Gclose);
  if (!group.valid() || !group.Close()) {
    return h5::Error(absl::StatusCode::kInternal,
                     absl::StrCat("cannot create group ", name, " of ", path));
  }
  return absl::OkStatus();
}

// Writes a scalar attribute of `object`, replacing one of that name.
absl::Status WriteAttribute(hid_t object, const char* name, hid_t file_type, hid_t memory_type,
                            const void* value, const std::string& where) {
  const htri_t exists = H5Aexists(object, name);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  if (exists < 0 || (exists > 0 && H5Adelete(object, name) < 0) || !space.valid()) {
    return h5::Error(absl::StatusCode::kInternal,
                     absl::StrCat("cannot write attribute ", name, " of ", where));
  }
  Handle attribute(H5Acreate2(object, name, file_type, space.id(), H5P_DEFAULT, H5P_DEFAULT),
                   H5Aclose);
  if (!attribute.valid() || H5Awrite(attribute.id(), memory_type, value) < 0 ||
      !attribute.Close()) {
    return h5::Error(absl::StatusCode::kInternal,
                     absl::StrCat("cannot write attribute ", name, " of ", where));
  }
  return absl::OkStatus();
}

template <typename T>
absl::Status WriteAttribute(hid_t object, const char* name, T value, const std::string& where) {
  return WriteAttribute(object, name, h5::TypeOf<T>::File(), h5::TypeOf<T>::Memory(), &value,
                        where);
}

// Fixed-length, NUL-padded UTF-8, as h5::File writes them.
absl::Status WriteStringAttribute(hid_t object, const char* name, const std::string& value,
                                  const std::string& where) {
  const std::string buffer = value.empty() ? std::string(1, '\0') : value;
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose);
  if (!type.valid() || H5Tset_size(type.id(), buffer.size()) < 0 ||
      H5Tset_strpad(type.id(), H5T_STR_NULLPAD) < 0 || H5Tset_cset(type.id(), H5T_CSET_UTF8) < 0) {
    return h5::Error(absl::StatusCode::kInternal, "creating a string type");
  }
  return WriteAttribute(object, name, type.id(), type.id(), buffer.data(), where);
}

// A [rows] (width 0) or [rows × width] dataset, chunked and
// fletcher32-checksummed like every store dataset (FORMAT.md).
template <typename T>
absl::Status WriteDataset(hid_t file, const std::string& name, std::span<const T> data,
                          std::size_t width, const std::string& path, Handle* dataset) {
  const std::string where = absl::StrCat("dataset ", name, " of ", path);
  const std::size_t per_row = width == 0 ? 1 : width;
  const std::size_t rows = data.size() / per_row;
  Handle space, dcpl;
  if (!h5::ChunkedLayout(rows, width, per_row * sizeof(T), &space, &dcpl)) {
    return h5::Error(absl::StatusCode::kInternal, absl::StrCat("cannot set up ", where));
  }
  *dataset = Handle(H5Dcreate2(file, name.c_str(), h5::TypeOf<T>::File(), space.id(), H5P_DEFAULT,
                               dcpl.id(), H5P_DEFAULT),
                    H5Dclose);
  if (!dataset->valid() || (rows > 0 && H5Dwrite(dataset->id(), h5::TypeOf<T>::Memory(), H5S_ALL,
                                                 H5S_ALL, H5P_DEFAULT, data.data()) < 0)) {
    return h5::Error(absl::StatusCode::kInternal, absl::StrCat("cannot write ", where));
  }
  return absl::OkStatus();
}

// Attribute `name` of `object` (described by `where`): one value of exactly
// the type T is written with; anything else is DataLoss.
template <typename T>
absl::Status ReadAttribute(hid_t object, const char* name, const std::string& where, T* value) {
  const htri_t exists = H5Aexists(object, name);
  if (exists < 0) return h5::Error(absl::StatusCode::kDataLoss, absl::StrCat("reading ", where));
  if (exists == 0) {
    return absl::DataLossError(absl::StrCat(where, " has no attribute '", name, "'"));
  }
  Handle attribute(H5Aopen(object, name, H5P_DEFAULT), H5Aclose);
  Handle space(attribute.valid() ? H5Aget_space(attribute.id()) : -1, H5Sclose);
  Handle type(attribute.valid() ? H5Aget_type(attribute.id()) : -1, H5Tclose);
  if (!space.valid() || !type.valid() || H5Sget_simple_extent_npoints(space.id()) != 1 ||
      H5Tequal(type.id(), h5::TypeOf<T>::File()) <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(
        absl::StrCat("attribute '", name, "' of ", where, " is not a single value of its type"));
  }
  if (H5Aread(attribute.id(), h5::TypeOf<T>::Memory(), value) < 0) {
    return h5::Error(absl::StatusCode::kDataLoss,
                     absl::StrCat("cannot read attribute '", name, "' of ", where));
  }
  return absl::OkStatus();
}

// The names of the links in `group`, in creation order where the group
// tracks it (every group this code creates), else by name.
absl::Status ListLinks(hid_t file, const std::string& group, const std::string& path,
                       std::vector<std::string>* names) {
  const std::string where = absl::StrCat("group ", group, " of ", path);
  const htri_t exists = H5Lexists(file, group.c_str(), H5P_DEFAULT);
  if (exists <= 0) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat("missing ", where, ": file is corrupt"));
  }
  Handle g(H5Gopen2(file, group.c_str(), H5P_DEFAULT), H5Gclose);
  H5G_info_t info;
  if (!g.valid() || H5Gget_info(g.id(), &info) < 0) {
    return h5::Error(absl::StatusCode::kDataLoss, absl::StrCat("cannot open ", where));
  }
  for (H5_index_t index : {H5_INDEX_CRT_ORDER, H5_INDEX_NAME}) {
    names->clear();
    for (hsize_t k = 0; k < info.nlinks; ++k) {
      const ssize_t size =
          H5Lget_name_by_idx(g.id(), ".", index, H5_ITER_INC, k, nullptr, 0, H5P_DEFAULT);
      if (size < 0) break;
      std::string name(static_cast<std::size_t>(size) + 1, '\0');
      if (H5Lget_name_by_idx(g.id(), ".", index, H5_ITER_INC, k, name.data(), name.size(),
                             H5P_DEFAULT) < 0) {
        break;
      }
      name.resize(static_cast<std::size_t>(size));
      names->push_back(std::move(name));
    }
    if (names->size() == info.nlinks) {
      H5Eclear2(H5E_DEFAULT);  // a failed creation-order attempt
      return absl::OkStatus();
    }
  }
  return h5::Error(absl::StatusCode::kDataLoss, absl::StrCat("cannot list ", where));
}

// DataLoss unless dataset `name` has shape [rows] (width 0) or [rows × width].
absl::Status CheckShape(hid_t file, const std::string& name, std::size_t rows, std::size_t width,
                        const std::string& path) {
  const std::string where = absl::StrCat("dataset ", name, " of ", path);
  Handle dataset(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  Handle space(dataset.valid() ? H5Dget_space(dataset.id()) : -1, H5Sclose);
  if (!space.valid())
    return h5::Error(absl::StatusCode::kDataLoss, absl::StrCat("opening ", where));
  hsize_t dims[2] = {0, 0};
  const int rank = H5Sget_simple_extent_ndims(space.id());
  if (rank != (width == 0 ? 1 : 2) ||
      H5Sget_simple_extent_dims(space.id(), dims, nullptr) != rank || dims[0] != rows ||
      (rank == 2 && dims[1] != width)) {
    H5Eclear2(H5E_DEFAULT);
    return absl::DataLossError(absl::StrCat(where, " does not have shape [", rows,
                                            width == 0 ? "" : absl::StrCat(", ", width),
                                            "]: file is corrupt"));
  }
  return absl::OkStatus();
}

// ----------------------------------------------------------------------------
// Frames.

std::string FramePath(std::int64_t step) { return absl::StrCat(kFramesGroup, "/", step); }

std::string TopologyPath(std::size_t num_points) {
  return absl::StrCat(kTopologyGroup, "/polyvertex_", num_points);
}

// Columns of a field's dataset: 0 (1-D) for scalars, 3 for 2- and
// 3-vectors, 9 for tensors.
std::size_t StoredWidth(int components) {
  return components == 1 ? 0 : components == 2 ? 3 : static_cast<std::size_t>(components);
}

bool ValidComponents(std::int64_t c) { return c == 1 || c == 2 || c == 3 || c == 9; }

bool ValidFieldName(const std::string& name) {
  if (name.empty() || name[0] == '.' || name == kPosition) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return absl::ascii_isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-';
  });
}

absl::Status CheckFrame(const ResultFrame& frame, const std::int64_t* last_step,
                        const std::string& path) {
  const auto invalid = [&](absl::string_view why) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot append step ", frame.step, " to ", path, ": ", why));
  };
  if (last_step != nullptr && frame.step <= *last_step) {
    return invalid(absl::StrCat("steps must increase; the last frame is step ", *last_step));
  }
  if (!std::isfinite(frame.time)) return invalid(absl::StrCat("time is ", frame.time));
  if (frame.position.size() % 2 != 0) {
    return invalid(
        absl::StrCat("position has ", frame.position.size(), " values; need num_points × 2"));
  }
  const std::size_t n = frame.position.size() / 2;
  std::set<std::string> names;
  for (const ResultField& f : frame.fields) {
    if (!ValidFieldName(f.name)) {
      return invalid(absl::StrCat("field name '", f.name,
                                  "' is not [A-Za-z0-9_.-]+ (no leading '.', not 'position')"));
    }
    if (!names.insert(f.name).second) return invalid(absl::StrCat("field '", f.name, "' twice"));
    if (!ValidComponents(f.components)) {
      return invalid(absl::StrCat("field '", f.name, "' has ", f.components,
                                  " components; need 1, 2, 3 or 9"));
    }
    if (f.values.size() != n * static_cast<std::size_t>(f.components)) {
      return invalid(absl::StrCat("field '", f.name, "' has ", f.values.size(), " values; need ", n,
                                  " points × ", f.components));
    }
  }
  return absl::OkStatus();
}

// Writes frame (already checked) into the open file; the group's
// attributes come last, so a frame with a `step` attribute is complete.
absl::Status WriteFrame(hid_t file, const ResultFrame& frame, const std::string& path) {
  const std::size_t n = frame.position.size() / 2;
  const std::string group = FramePath(frame.step);
  RETURN_IF_ERROR(CreateGroup(file, group, path));
  std::vector<double> values;
  values.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    values.insert(values.end(), {frame.position[2 * i], frame.position[2 * i + 1], 0.0});
  }
  Handle dataset;
  RETURN_IF_ERROR(
      WriteDataset(file, absl::StrCat(group, "/", kPosition), Span(values), 3, path, &dataset));
  for (const ResultField& f : frame.fields) {
    const std::string name = absl::StrCat(group, "/", f.name);
    if (f.components == 2) {
      values.clear();
      for (std::size_t i = 0; i < n; ++i) {
        values.insert(values.end(), {f.values[2 * i], f.values[2 * i + 1], 0.0});
      }
      RETURN_IF_ERROR(WriteDataset(file, name, Span(values), 3, path, &dataset));
    } else {
      RETURN_IF_ERROR(
          WriteDataset(file, name, Span(f.values), StoredWidth(f.components), path, &dataset));
    }
    RETURN_IF_ERROR(WriteAttribute<std::int32_t>(dataset.id(), "components", f.components,
                                                 absl::StrCat("dataset ", name, " of ", path)));
  }
  dataset = Handle();
  // Point ids 0 … n-1, the Polyvertex connectivity of every frame of n
  // points (ParaView builds no vertex cells without it).
  const std::string topology = TopologyPath(n);
  const htri_t exists = H5Lexists(file, topology.c_str(), H5P_DEFAULT);
  if (exists < 0) return h5::Error(absl::StatusCode::kInternal, "looking up " + topology);
  if (exists == 0) {
    std::vector<std::int64_t> ids(n);
    for (std::size_t i = 0; i < n; ++i) ids[i] = static_cast<std::int64_t>(i);
    RETURN_IF_ERROR(WriteDataset(file, topology, Span(ids), 0, path, &dataset));
  }
  Handle g(H5Gopen2(file, group.c_str(), H5P_DEFAULT), H5Gclose);
  const std::string where = absl::StrCat("group ", group, " of ", path);
  if (!g.valid()) return h5::Error(absl::StatusCode::kInternal, "opening " + where);
  RETURN_IF_ERROR(
      WriteAttribute<std::int64_t>(g.id(), "num_points", static_cast<std::int64_t>(n), where));
  RETURN_IF_ERROR(WriteAttribute<double>(g.id(), "time", frame.time, where));
  return WriteAttribute<std::int64_t>(g.id(), "step", frame.step, where);
}

// The frames of a results file, by step: group name and step.
absl::StatusOr<std::vector<std::pair<std::string, std::int64_t>>> ListFrames(
    hid_t file, const std::string& path) {
  std::vector<std::string> names;
  RETURN_IF_ERROR(ListLinks(file, kFramesGroup, path, &names));
  std::vector<std::pair<std::string, std::int64_t>> frames;
  for (std::string& name : names) {
    std::int64_t step = 0;
    if (!absl::SimpleAtoi(name, &step) || absl::StrCat(step) != name) {
      return absl::DataLossError(absl::StrCat("unexpected object ", kFramesGroup, "/", name, " in ",
                                              path, " (frames are named by step)"));
    }
    frames.emplace_back(std::move(name), step);
  }
  std::sort(frames.begin(), frames.end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
  return frames;
}

// Reads frame `step` into `frame`: its attributes and fields, and, with
// `data`, the values (else only the fields' names and component counts,
// their shapes checked). Sets *num_points.
absl::Status ReadFrame(const h5::File& file, std::int64_t step, bool data, ResultFrame* frame,
                       std::size_t* num_points) {
  const std::string& path = file.path();
  const std::string group = FramePath(step);
  const std::string where = absl::StrCat("frame ", group, " of ", path);
  Handle g(H5Gopen2(file.id(), group.c_str(), H5P_DEFAULT), H5Gclose);
  if (!g.valid()) return h5::Error(absl::StatusCode::kDataLoss, "opening " + where);
  // `step` is written last: without it the writer was interrupted.
  if (H5Aexists(g.id(), "step") == 0) {
    return absl::DataLossError(absl::StrCat(where, " is incomplete (its writer was interrupted)"));
  }
  std::int64_t stored_step = 0, n = 0;
  RETURN_IF_ERROR(ReadAttribute(g.id(), "step", where, &stored_step));
  RETURN_IF_ERROR(ReadAttribute(g.id(), "time", where, &frame->time));
  RETURN_IF_ERROR(ReadAttribute(g.id(), "num_points", where, &n));
  absl::StatusOr<std::uint64_t> size = file.Size();
  if (!size.ok()) return size.status();
  if (stored_step != step || n < 0 || static_cast<std::uint64_t>(n) > *size) {
    return absl::DataLossError(
        absl::StrCat(where, " has step ", stored_step, " and num_points ", n, ": file is corrupt"));
  }
  frame->step = step;
  *num_points = static_cast<std::size_t>(n);
  std::vector<std::string> names;
  RETURN_IF_ERROR(ListLinks(file.id(), group, path, &names));
  if (std::find(names.begin(), names.end(), kPosition) == names.end()) {
    return absl::DataLossError(
        absl::StrCat("missing dataset ", group, "/", kPosition, " of ", path));
  }
  std::vector<double> values;
  frame->fields.clear();
  for (const std::string& name : names) {
    const std::string dataset = absl::StrCat(group, "/", name);
    if (name == kPosition) {
      if (!data) {
        RETURN_IF_ERROR(CheckShape(file.id(), dataset, *num_points, 3, path));
        continue;
      }
      RETURN_IF_ERROR(file.Read(dataset, *num_points, 3, &values));
      frame->position.resize(2 * *num_points);
      for (std::size_t i = 0; i < *num_points; ++i) {
        frame->position[2 * i] = values[3 * i];
        frame->position[2 * i + 1] = values[3 * i + 1];
      }
      continue;
    }
    ResultField& f = frame->fields.emplace_back();
    f.name = name;
    const std::string dataset_where = absl::StrCat("dataset ", dataset, " of ", path);
    Handle d(H5Dopen2(file.id(), dataset.c_str(), H5P_DEFAULT), H5Dclose);
    if (!d.valid()) return h5::Error(absl::StatusCode::kDataLoss, "opening " + dataset_where);
    std::int32_t components = 0;
    RETURN_IF_ERROR(ReadAttribute(d.id(), "components", dataset_where, &components));
    if (!ValidComponents(components)) {
      return absl::DataLossError(
          absl::StrCat(dataset_where, " has components ", components, ": file is corrupt"));
    }
    f.components = components;
    const std::size_t width = StoredWidth(components);
    if (!data) {
      RETURN_IF_ERROR(CheckShape(file.id(), dataset, *num_points, width, path));
    } else if (components == 2) {
      RETURN_IF_ERROR(file.Read(dataset, *num_points, width, &values));
      f.values.resize(2 * *num_points);
      for (std::size_t i = 0; i < *num_points; ++i) {
        f.values[2 * i] = values[3 * i];
        f.values[2 * i + 1] = values[3 * i + 1];
      }
    } else {
      RETURN_IF_ERROR(file.Read(dataset, *num_points, width, &f.values));
    }
  }
  return absl::OkStatus();
}

// ----------------------------------------------------------------------------
// XDMF.

// Shortest text that reads back as the same double.
std::string Number(double v) {
  char buffer[32];
  const std::to_chars_result r = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, r.ptr);
}

std::string XmlEscape(absl::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// h5_path as the XDMF file refers to it: relative to the XDMF file's
// directory, so that the pair can be moved together.
absl::StatusOr<std::string> H5Reference(const std::string& h5_path, const std::string& xdmf_path) {
  std::error_code ec;
  const fs::path h5 = fs::absolute(h5_path, ec).lexically_normal();
  if (ec) return absl::InvalidArgumentError(absl::StrCat("bad path ", h5_path, ": ", ec.message()));
  const fs::path xdmf = fs::absolute(xdmf_path, ec).lexically_normal();
  if (ec) {
    return absl::InvalidArgumentError(absl::StrCat("bad path ", xdmf_path, ": ", ec.message()));
  }
  if (h5 == xdmf) {
    return absl::InvalidArgumentError(
        absl::StrCat("the HDF5 and XDMF files are the same file ", h5_path));
  }
  const fs::path relative = h5.lexically_relative(xdmf.parent_path());
  std::string reference = relative.empty() ? h5.generic_string() : relative.generic_string();
  // XDMF separates the file from the dataset path with ':'.
  if (reference.find(':') != std::string::npos) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot refer to ", h5_path, " from an XDMF file: its path contains ':'"));
  }
  return reference;
}

}  // namespace

ResultsWriter::~ResultsWriter() = default;

absl::StatusOr<std::unique_ptr<ResultsWriter>> ResultsWriter::Create(
    const std::string& h5_path, const std::string& xdmf_path, const std::string& created_by) {
  absl::StatusOr<std::string> reference = H5Reference(h5_path, xdmf_path);
  if (!reference.ok()) return reference.status();
  if (internal::HasNul(created_by)) {
    return absl::InvalidArgumentError("created_by must not contain NUL bytes");
  }
  // open(2) first: errno says precisely why a directory is unusable.
  const int fd = ::open(h5_path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return absl::ErrnoToStatus(errno, absl::StrCat("cannot create ", h5_path));
  ::close(fd);
  {
    std::lock_guard<std::mutex> lock(internal::StoreMutex());
    h5::SilenceErrorPrinting();
    Handle file;
    RETURN_IF_ERROR(OpenForWriting(h5_path, /*create=*/true, &file));
    const std::string where = absl::StrCat("file ", h5_path);
    RETURN_IF_ERROR(
        WriteAttribute<std::int32_t>(file.id(), "format_version", kFormatVersion, where));
    RETURN_IF_ERROR(WriteStringAttribute(file.id(), "kind", internal::kKindResults, where));
    RETURN_IF_ERROR(WriteStringAttribute(file.id(), "created_by", created_by, where));
    RETURN_IF_ERROR(WriteStringAttribute(file.id(), "created_at", internal::UtcNow(), where));
    RETURN_IF_ERROR(CreateGroup(file.id(), kFramesGroup, h5_path));
    RETURN_IF_ERROR(CreateGroup(file.id(), kTopologyGroup, h5_path));
    RETURN_IF_ERROR(CloseFile(file, h5_path));
    internal::SyncPath(h5_path, O_RDONLY);
  }
  std::unique_ptr<ResultsWriter> writer(
      new ResultsWriter(h5_path, xdmf_path, *std::move(reference)));
  RETURN_IF_ERROR(writer->WriteXdmf());
  return writer;
}

absl::StatusOr<std::unique_ptr<ResultsWriter>> ResultsWriter::Open(const std::string& h5_path,
                                                                   const std::string& xdmf_path,
                                                                   const std::string& created_by,
                                                                   std::int64_t keep_through_step) {
  absl::StatusOr<std::string> reference = H5Reference(h5_path, xdmf_path);
  if (!reference.ok()) return reference.status();
  if (internal::HasNul(created_by)) {
    return absl::InvalidArgumentError("created_by must not contain NUL bytes");
  }
  std::unique_ptr<ResultsWriter> writer(
      new ResultsWriter(h5_path, xdmf_path, *std::move(reference)));
  {
    std::lock_guard<std::mutex> lock(internal::StoreMutex());
    std::vector<std::int64_t> dropped;
    {
      // Read-only first, with the store's checks of kind and version; the
      // kept frames are checked (not read) so the XDMF file can list them.
      absl::StatusOr<h5::File> file = internal::OpenStore(h5_path, internal::kKindResults, nullptr);
      if (!file.ok()) return file.status();
      absl::StatusOr<std::vector<std::pair<std::string, std::int64_t>>> frames =
          ListFrames(file->id(), h5_path);
      if (!frames.ok()) return frames.status();
      for (const auto& [name, step] : *frames) {
        if (step > keep_through_step) {
          dropped.push_back(step);
          continue;
        }
        ResultFrame frame;
        FrameInfo info;
        RETURN_IF_ERROR(ReadFrame(*file, step, /*data=*/false, &frame, &info.num_points));
        info.step = step;
        info.time = frame.time;
        for (const ResultField& f : frame.fields) info.fields.emplace_back(f.name, f.components);
        writer->frames_.push_back(std::move(info));
      }
      // Closed before the read-write open: HDF5 refuses to open a file
      // read-write that the process has open read-only.
      RETURN_IF_ERROR(file->Close());
    }
    Handle file;
    RETURN_IF_ERROR(OpenForWriting(h5_path, /*create=*/false, &file));
    for (std::int64_t step : dropped) {
      if (H5Ldelete(file.id(), FramePath(step).c_str(), H5P_DEFAULT) < 0) {
        return h5::Error(absl::StatusCode::kInternal,
                         absl::StrCat("cannot delete frame ", FramePath(step), " of ", h5_path));
      }
    }
    RETURN_IF_ERROR(
        WriteStringAttribute(file.id(), "resumed_by", created_by, absl::StrCat("file ", h5_path)));
    RETURN_IF_ERROR(CloseFile(file, h5_path));
    internal::SyncPath(h5_path, O_RDONLY);
  }
  RETURN_IF_ERROR(writer->WriteXdmf());
  return writer;
}

absl::Status ResultsWriter::Append(const ResultFrame& frame) {
  if (closed_) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot append to ", h5_path_, ": the writer is closed"));
  }
  RETURN_IF_ERROR(CheckFrame(frame, frames_.empty() ? nullptr : &frames_.back().step, h5_path_));
  {
    std::lock_guard<std::mutex> lock(internal::StoreMutex());
    h5::SilenceErrorPrinting();
    Handle file;
    RETURN_IF_ERROR(OpenForWriting(h5_path_, /*create=*/false, &file));
    if (absl::Status s = WriteFrame(file.id(), frame, h5_path_); !s.ok()) {
      // Best effort: no partial frame left behind (a later Append of the
      // same step would collide with it).
      H5Ldelete(file.id(), FramePath(frame.step).c_str(), H5P_DEFAULT);
      H5Eclear2(H5E_DEFAULT);
      return absl::Status(s.code(), absl::StrCat("appending step ", frame.step, ": ", s.message()));
    }
    RETURN_IF_ERROR(CloseFile(file, h5_path_));
    // Data before name: the XDMF file never lists a frame not on disk.
    internal::SyncPath(h5_path_, O_RDONLY);
  }
  FrameInfo info;
  info.step = frame.step;
  info.time = frame.time;
  info.num_points = frame.position.size() / 2;
  for (const ResultField& f : frame.fields) info.fields.emplace_back(f.name, f.components);
  frames_.push_back(std::move(info));
  return WriteXdmf();
}

absl::Status ResultsWriter::Close() {
  closed_ = true;
  return absl::OkStatus();
}

absl::Status ResultsWriter::WriteXdmf() const {
  std::string xml =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
      "  <Domain>\n"
      "    <Grid Name=\"material_points\" GridType=\"Collection\" "
      "CollectionType=\"Temporal\">\n";
  const std::string file = XmlEscape(h5_reference_);
  const auto data_item = [&](absl::string_view dims, absl::string_view type,
                             absl::string_view dataset) {
    return absl::StrCat("          <DataItem Dimensions=\"", dims, "\" DataType=\"", type,
                        "\" Precision=\"8\" Format=\"HDF\">", file, ":", dataset, "</DataItem>\n");
  };
  for (const FrameInfo& f : frames_) {
    const std::string n = absl::StrCat(f.num_points);
    const std::string group = FramePath(f.step);
    absl::StrAppend(&xml, "      <Grid Name=\"step_", f.step, "\" GridType=\"Uniform\">\n",
                    "        <Time Value=\"", Number(f.time), "\"/>\n",
                    "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"", n,
                    "\" NodesPerElement=\"1\">\n", data_item(n, "Int", TopologyPath(f.num_points)),
                    "        </Topology>\n", "        <Geometry GeometryType=\"XYZ\">\n",
                    data_item(absl::StrCat(n, " 3"), "Float", absl::StrCat(group, "/", kPosition)),
                    "        </Geometry>\n");
    for (const auto& [name, components] : f.fields) {
      const char* type = components == 1 ? "Scalar" : components == 9 ? "Tensor" : "Vector";
      const std::size_t width = StoredWidth(components);
      absl::StrAppend(&xml, "        <Attribute Name=\"", name, "\" AttributeType=\"", type,
                      "\" Center=\"Node\">\n",
                      data_item(width == 0 ? n : absl::StrCat(n, " ", width), "Float",
                                absl::StrCat(group, "/", name)),
                      "        </Attribute>\n");
    }
    xml += "      </Grid>\n";
  }
  xml += "    </Grid>\n  </Domain>\n</Xdmf>\n";

  // Replaced atomically: a viewer never sees a half-written list.
  const std::string temp = absl::StrCat(xdmf_path_, ".tmp-", ::getpid());
  std::FILE* out = std::fopen(temp.c_str(), "wb");
  if (out == nullptr) {
    return absl::ErrnoToStatus(
        errno, absl::StrCat("cannot write ", xdmf_path_, ": cannot create temporary file ", temp));
  }
  bool ok = std::fwrite(xml.data(), 1, xml.size(), out) == xml.size() && std::fflush(out) == 0;
  int error = ok ? 0 : errno;
  if (ok && ::fsync(::fileno(out)) != 0 && errno != EINVAL) {
    ok = false;
    error = errno;
  }
  if (std::fclose(out) != 0 && ok) {
    ok = false;
    error = errno;
  }
  if (ok && std::rename(temp.c_str(), xdmf_path_.c_str()) != 0) {
    ok = false;
    error = errno;
  }
  if (!ok) {
    std::remove(temp.c_str());
    return absl::ErrnoToStatus(error != 0 ? error : EIO, absl::StrCat("cannot write ", xdmf_path_));
  }
  const fs::path dir = fs::path(xdmf_path_).parent_path();
  internal::SyncPath(dir.empty() ? "." : dir.string(), O_RDONLY | O_DIRECTORY);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<ResultFrame>> ReadResults(const std::string& h5_path) {
  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  absl::StatusOr<h5::File> file = internal::OpenStore(h5_path, internal::kKindResults, nullptr);
  if (!file.ok()) return file.status();
  absl::StatusOr<std::vector<std::pair<std::string, std::int64_t>>> frames =
      ListFrames(file->id(), h5_path);
  if (!frames.ok()) return frames.status();
  std::vector<ResultFrame> out(frames->size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    std::size_t num_points = 0;
    RETURN_IF_ERROR(ReadFrame(*file, (*frames)[k].second, /*data=*/true, &out[k], &num_points));
  }
  return out;
}

#undef RETURN_IF_ERROR

}  // namespace rvehub::store
