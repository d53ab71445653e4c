#include "store/results.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "absl/strings/strip.h"
#include "store/checkpoint.h"
#include "store/hdf5.h"
#include "store/record_io.h"

namespace rvehub::store {
namespace {

namespace fs = std::filesystem;
using h5::Span;

constexpr char kFramesGroup[] = "/frames";
constexpr char kTopologyGroup[] = "/topology";
constexpr char kPosition[] = "position";

// A required attribute: absent is DataLoss here (the writer always writes it).
template <typename T>
absl::Status ReadRequired(const h5::Object& object, const char* name, T* value) {
  absl::StatusOr<T> read = object.ReadAttribute<T>(name);
  if (absl::IsNotFound(read.status())) {
    return absl::DataLossError(absl::StrCat(object.where(), " has no attribute '", name, "'"));
  }
  if (!read.ok()) return read.status();
  *value = *read;
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

// Writes frame (already checked) into a frame file as group
// /frames/<step>; the group's attributes come last, so a frame with a `step`
// attribute is complete.
absl::Status WriteFrame(h5::File& file, const ResultFrame& frame) {
  const std::size_t n = frame.position.size() / 2;
  const std::string group = FramePath(frame.step);
  ASSIGN_OR_RETURN(h5::Group frames, file.CreateGroup(kFramesGroup));
  ASSIGN_OR_RETURN(h5::Group g, file.CreateGroup(group));
  std::vector<double> values;
  values.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    values.insert(values.end(), {frame.position[2 * i], frame.position[2 * i + 1], 0.0});
  }
  RETURN_IF_ERROR(file.Write(absl::StrCat(group, "/", kPosition), Span(values), 3));
  for (const ResultField& f : frame.fields) {
    const std::string name = absl::StrCat(group, "/", f.name);
    absl::StatusOr<h5::Dataset> dataset;
    if (f.components == 2) {
      values.clear();
      for (std::size_t i = 0; i < n; ++i) {
        values.insert(values.end(), {f.values[2 * i], f.values[2 * i + 1], 0.0});
      }
      dataset = file.WriteDataset(name, Span(values), 3);
    } else {
      dataset = file.WriteDataset(name, Span(f.values), StoredWidth(f.components));
    }
    if (!dataset.ok()) return dataset.status();
    RETURN_IF_ERROR(dataset->WriteAttribute<std::int32_t>("components", f.components));
  }
  RETURN_IF_ERROR(g.WriteAttribute<std::int64_t>("num_points", static_cast<std::int64_t>(n)));
  RETURN_IF_ERROR(g.WriteAttribute<double>("time", frame.time));
  return g.WriteAttribute<std::int64_t>("step", frame.step);
}

// Point ids 0 … n-1, the Polyvertex connectivity of every frame of n points
// (ParaView builds no vertex cells without it), into a topology file.
absl::Status WriteTopology(h5::File& file, std::size_t n) {
  ASSIGN_OR_RETURN(h5::Group topology, file.CreateGroup(kTopologyGroup));
  std::vector<std::int64_t> ids(n);
  for (std::size_t i = 0; i < n; ++i) ids[i] = static_cast<std::int64_t>(i);
  return file.Write(TopologyPath(n), Span(ids), 0);
}

// ----------------------------------------------------------------------------
// Files beside results.h5.

// The directory of the frame and topology files: results.h5 → results.frames.
std::string FramesDirName(const std::string& h5_path) {
  std::string name = fs::path(h5_path).filename().string();
  if (absl::EndsWith(name, ".h5")) name.resize(name.size() - 3);
  return absl::StrCat(name, ".frames");
}
std::string FrameFileName(std::int64_t step) { return absl::StrCat(step, ".h5"); }
std::string TopologyFileName(std::size_t n) { return absl::StrCat("topology_", n, ".h5"); }

// Whether `name` is a file the writer makes in the frames directory (a
// frame, a topology or a temporary of either): the only files it removes.
bool IsWriterFile(absl::string_view name) {
  if (const std::size_t tmp = name.find(".tmp-"); tmp != absl::string_view::npos) {
    int pid = 0;
    if (!absl::SimpleAtoi(name.substr(tmp + 5), &pid)) return false;
    name = name.substr(0, tmp);
  }
  if (!absl::ConsumeSuffix(&name, ".h5")) return false;
  absl::ConsumePrefix(&name, "topology_");
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return absl::ascii_isdigit(static_cast<unsigned char>(c));
  });
}

// Removes the writer's files of `dir` but those `keep` names (best effort:
// a file left behind only takes space).
void RemoveWriterFiles(const std::string& dir, const std::set<std::string>& keep) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code type_ec;
    if (IsWriterFile(name) && !keep.contains(name) && it->is_regular_file(type_ec)) {
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
  }
}

// Renames `from` over `to`; the directory is synced by the caller.
absl::Status Rename(const std::string& from, const std::string& to) {
  if (std::rename(from.c_str(), to.c_str()) != 0) {
    return absl::ErrnoToStatus(errno, absl::StrCat("cannot rename ", from, " to ", to));
  }
  return absl::OkStatus();
}

void SyncDirOf(const std::string& path) {
  const fs::path dir = fs::path(path).parent_path();
  internal::SyncPath(dir.empty() ? "." : dir.string(), O_RDONLY | O_DIRECTORY);
}

// After renames into both files' directories: each synced once.
void SyncDirsOf(const std::string& a, const std::string& b) {
  SyncDirOf(a);
  if (fs::path(a).parent_path() != fs::path(b).parent_path()) SyncDirOf(b);
}

void RemoveQuietly(const std::string& path) {
  std::error_code ignored;
  fs::remove(path, ignored);
}

// The frames of a results file, by step: group name and step.
absl::StatusOr<std::vector<std::pair<std::string, std::int64_t>>> ListFrames(const h5::File& file) {
  const std::string& path = file.path();
  ASSIGN_OR_RETURN(h5::Group group, file.OpenGroup(kFramesGroup));
  ASSIGN_OR_RETURN(std::vector<std::string> names, group.LinkNames());
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
  absl::StatusOr<h5::Group> opened = file.OpenGroup(group);
  if (!opened.ok()) {
    // A frame in a file of its own: say which file is missing or unreadable.
    absl::StatusOr<std::string> target = file.ExternalLinkFile(group);
    if (!target.ok() || target->empty()) return opened.status();
    const fs::path frame_file = fs::path(path).parent_path() / *target;
    std::error_code ec;
    if (!fs::exists(frame_file, ec)) {
      return absl::DataLossError(
          absl::StrCat(where, " is missing: its file ", frame_file.string(), " does not exist"));
    }
    return absl::DataLossError(absl::StrCat(where, " is unreadable: its file ", frame_file.string(),
                                            ": ", opened.status().message()));
  }
  h5::Group& g = *opened;
  // `step` is written last: without it the writer was interrupted.
  ASSIGN_OR_RETURN(bool complete, g.HasAttribute("step"));
  if (!complete) {
    return absl::DataLossError(absl::StrCat(where, " is incomplete (its writer was interrupted)"));
  }
  std::int64_t stored_step = 0, n = 0;
  RETURN_IF_ERROR(ReadRequired(g, "step", &stored_step));
  RETURN_IF_ERROR(ReadRequired(g, "time", &frame->time));
  RETURN_IF_ERROR(ReadRequired(g, "num_points", &n));
  ASSIGN_OR_RETURN(std::uint64_t size, g.FileSize());
  if (stored_step != step || n < 0 || static_cast<std::uint64_t>(n) > size) {
    return absl::DataLossError(
        absl::StrCat(where, " has step ", stored_step, " and num_points ", n, ": file is corrupt"));
  }
  frame->step = step;
  *num_points = static_cast<std::size_t>(n);
  ASSIGN_OR_RETURN(std::vector<std::string> listed, g.LinkNames());
  const std::vector<std::string>& names = listed;
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
        RETURN_IF_ERROR(file.CheckShape(dataset, *num_points, 3));
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
    ASSIGN_OR_RETURN(h5::Dataset d, file.OpenDataset(dataset));
    std::int32_t components = 0;
    RETURN_IF_ERROR(ReadRequired(d, "components", &components));
    if (!ValidComponents(components)) {
      return absl::DataLossError(
          absl::StrCat(d.where(), " has components ", components, ": file is corrupt"));
    }
    f.components = components;
    const std::size_t width = StoredWidth(components);
    if (!data) {
      RETURN_IF_ERROR(file.CheckShape(dataset, *num_points, width));
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

// The XDMF text listing `frames`, whose DataItems name `h5_reference`.
template <typename Frames>
std::string XdmfText(const std::string& h5_reference, const Frames& frames) {
  std::string xml =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n"
      "  <Domain>\n"
      "    <Grid Name=\"material_points\" GridType=\"Collection\" "
      "CollectionType=\"Temporal\">\n";
  const std::string file = XmlEscape(h5_reference);
  const auto data_item = [&](absl::string_view dims, absl::string_view type,
                             absl::string_view dataset) {
    return absl::StrCat("          <DataItem Dimensions=\"", dims, "\" DataType=\"", type,
                        "\" Precision=\"8\" Format=\"HDF\">", file, ":", dataset, "</DataItem>\n");
  };
  for (const auto& f : frames) {
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

  return xml;
}

}  // namespace

ResultsWriter::ResultsWriter(std::string h5_path, std::string xdmf_path, std::string h5_reference,
                             std::string created_by)
    : h5_path_(std::move(h5_path)),
      xdmf_path_(std::move(xdmf_path)),
      h5_reference_(std::move(h5_reference)),
      created_by_(std::move(created_by)),
      frames_dir_name_(FramesDirName(h5_path_)),
      frames_dir_((fs::path(h5_path_).parent_path() / frames_dir_name_).string()) {}

ResultsWriter::~ResultsWriter() = default;

absl::StatusOr<std::unique_ptr<ResultsWriter>> ResultsWriter::Create(
    const std::string& h5_path, const std::string& xdmf_path, const std::string& created_by) {
  ASSIGN_OR_RETURN(std::string reference, H5Reference(h5_path, xdmf_path));
  if (internal::HasNul(created_by)) {
    return absl::InvalidArgumentError("created_by must not contain NUL bytes");
  }
  // open(2) first: errno says precisely why a directory is unusable.
  const int fd = ::open(h5_path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return absl::ErrnoToStatus(errno, absl::StrCat("cannot create ", h5_path));
  ::close(fd);
  std::unique_ptr<ResultsWriter> writer(
      new ResultsWriter(h5_path, xdmf_path, std::move(reference), created_by));
  {
    std::lock_guard<std::mutex> lock(internal::StoreMutex());
    ASSIGN_OR_RETURN(std::string index, writer->StageIndex(nullptr, {}));
    if (absl::Status s = Rename(index, h5_path); !s.ok()) {
      RemoveQuietly(index);
      return s;
    }
    SyncDirOf(h5_path);
    // The frames of a run written here before are gone with its index.
    RemoveWriterFiles(writer->frames_dir_, {});
  }
  RETURN_IF_ERROR(writer->WriteXdmf());
  return writer;
}

absl::StatusOr<std::unique_ptr<ResultsWriter>> ResultsWriter::Open(const std::string& h5_path,
                                                                   const std::string& xdmf_path,
                                                                   const std::string& created_by,
                                                                   std::int64_t keep_through_step) {
  ASSIGN_OR_RETURN(std::string reference, H5Reference(h5_path, xdmf_path));
  if (internal::HasNul(created_by)) {
    return absl::InvalidArgumentError("created_by must not contain NUL bytes");
  }
  std::unique_ptr<ResultsWriter> writer(
      new ResultsWriter(h5_path, xdmf_path, std::move(reference), created_by));
  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  // The kept frames are checked (not read) so the XDMF file can list them;
  // a new index links them (and only them) again.
  FileInfo info;
  ASSIGN_OR_RETURN(h5::File old, internal::OpenStore(h5_path, internal::kKindResults, &info));
  ASSIGN_OR_RETURN(auto frames, ListFrames(old));
  // Frames that a writer from before frame files kept inside results.h5 are
  // moved into frame files (once), so that every frame is one.
  std::vector<std::pair<std::int64_t, std::string>> links;  // step, frame file as linked
  std::set<std::string> keep;
  for (const auto& [name, step] : frames) {
    if (step > keep_through_step) continue;
    ResultFrame frame;
    FrameInfo frame_info;
    RETURN_IF_ERROR(ReadFrame(old, step, /*data=*/false, &frame, &frame_info.num_points));
    frame_info.step = step;
    frame_info.time = frame.time;
    for (const ResultField& f : frame.fields) frame_info.fields.emplace_back(f.name, f.components);
    ASSIGN_OR_RETURN(std::string target, old.ExternalLinkFile(FramePath(step)));
    if (target.empty()) {
      RETURN_IF_ERROR(writer->MakeFramesDir());
      const std::string file = (fs::path(writer->frames_dir_) / FrameFileName(step)).string();
      RETURN_IF_ERROR(internal::WriteAtomically(
          file, internal::kKindResultsFrame, {}, FileInfo{created_by, ""},
          [&](h5::File& out) { return out.CopyFrom(old, FramePath(step)); }));
      target = absl::StrCat(writer->frames_dir_name_, "/", FrameFileName(step));
    }
    keep.insert(fs::path(target).filename().string());
    links.emplace_back(step, std::move(target));
    writer->frames_.push_back(std::move(frame_info));
  }
  RETURN_IF_ERROR(old.Close());
  std::set<std::size_t> sizes;
  for (const FrameInfo& f : writer->frames_) sizes.insert(f.num_points);
  for (std::size_t n : sizes) {
    RETURN_IF_ERROR(writer->MakeFramesDir());
    RETURN_IF_ERROR(
        internal::WriteAtomically((fs::path(writer->frames_dir_) / TopologyFileName(n)).string(),
                                  internal::kKindResultsTopology, {}, FileInfo{created_by, ""},
                                  [&](h5::File& out) { return WriteTopology(out, n); }));
    keep.insert(TopologyFileName(n));
  }
  writer->topologies_ = sizes;
  const auto link_all = [&](h5::File& index) -> absl::Status {
    RETURN_IF_ERROR(index.WriteStringAttribute("created_by", info.created_by));
    RETURN_IF_ERROR(index.WriteStringAttribute("created_at", info.created_at));
    RETURN_IF_ERROR(index.WriteStringAttribute("resumed_by", created_by));
    for (const auto& [step, target] : links) {
      RETURN_IF_ERROR(index.CreateExternalLink(FramePath(step), target, FramePath(step)));
    }
    for (std::size_t n : sizes) {
      RETURN_IF_ERROR(index.CreateExternalLink(
          TopologyPath(n), absl::StrCat(writer->frames_dir_name_, "/", TopologyFileName(n)),
          TopologyPath(n)));
    }
    return absl::OkStatus();
  };
  ASSIGN_OR_RETURN(std::string index, writer->StageIndex(nullptr, link_all));
  absl::StatusOr<std::string> xdmf = writer->StageXdmf(writer->frames_);
  absl::Status s = xdmf.status();
  if (s.ok()) s = Rename(index, h5_path);
  if (!s.ok()) {
    RemoveQuietly(index);
    if (xdmf.ok()) RemoveQuietly(*xdmf);
    return s;
  }
  s = Rename(*xdmf, xdmf_path);
  if (!s.ok()) RemoveQuietly(*xdmf);
  SyncDirsOf(h5_path, xdmf_path);
  // The dropped frames' files, and what killed writers left.
  RemoveWriterFiles(writer->frames_dir_, keep);
  RETURN_IF_ERROR(s);
  return writer;
}

absl::Status ResultsWriter::MakeFramesDir() const {
  std::error_code ec;
  if (fs::create_directory(frames_dir_, ec)) {
    SyncDirOf(frames_dir_);
  } else if (ec) {
    return absl::ErrnoToStatus(ec.value(), absl::StrCat("cannot create directory ", frames_dir_));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> ResultsWriter::StageIndex(
    const std::string* base, const std::function<absl::Status(h5::File&)>& edit) const {
  RemoveStaleTemporaries(h5_path_);
  const std::string temp = absl::StrCat(h5_path_, ".tmp-", ::getpid());
  absl::Status s = [&]() -> absl::Status {
    if (base != nullptr) {
      // A copy of the index: results.h5 itself is never written in place.
      std::error_code ec;
      fs::copy_file(*base, temp, fs::copy_options::overwrite_existing, ec);
      if (ec) {
        return absl::ErrnoToStatus(ec.value(), absl::StrCat("cannot copy ", *base, " to ", temp));
      }
      ASSIGN_OR_RETURN(h5::File file, h5::File::OpenForAppend(temp));
      RETURN_IF_ERROR(edit(file));
      return file.Close();
    }
    ASSIGN_OR_RETURN(h5::File file, h5::File::Create(temp, h5::Format::kAppendable));
    RETURN_IF_ERROR(file.WriteAttribute<std::int32_t>("format_version", kFormatVersion));
    RETURN_IF_ERROR(file.WriteStringAttribute("kind", internal::kKindResults));
    RETURN_IF_ERROR(file.WriteStringAttribute("created_by", created_by_));
    RETURN_IF_ERROR(file.WriteStringAttribute("created_at", internal::UtcNow()));
    for (const char* group : {kFramesGroup, kTopologyGroup}) {
      ASSIGN_OR_RETURN(h5::Group g, file.CreateGroup(group));
    }
    if (edit) RETURN_IF_ERROR(edit(file));
    return file.Close();
  }();
  if (!s.ok()) {
    RemoveQuietly(temp);
    return s;
  }
  // Data before name: the index never links a frame not on disk.
  internal::SyncPath(temp, O_RDONLY);
  return temp;
}

absl::Status ResultsWriter::Append(const ResultFrame& frame) {
  if (closed_) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot append to ", h5_path_, ": the writer is closed"));
  }
  RETURN_IF_ERROR(CheckFrame(frame, frames_.empty() ? nullptr : &frames_.back().step, h5_path_));
  if (absl::Status s = AppendFiles(frame); !s.ok()) {
    return absl::Status(
        s.code(), absl::StrCat("appending step ", frame.step, " to ", h5_path_, ": ", s.message()));
  }
  return absl::OkStatus();
}

// Why a frame goes into a file of its own: HDF5 updates a file's metadata
// (superblock, group indices, free space) in place, so a write that fails
// part way (a full disk) can leave results.h5 unreadable, every frame lost
// with it. Instead nothing already written is ever written again: the frame
// (and, for a new point count, its topology) is written under a temporary
// name and renamed into results.frames/ once complete; the new index is a
// copy of results.h5 plus an external link to it, and the new XDMF text is
// written; only when all of them are on disk are the two renamed over the
// old ones. A failure before leaves the old pair as it was (and removes
// what it wrote); a failure between the renames leaves an index with one
// frame more than the XDMF file lists.
absl::Status ResultsWriter::AppendFiles(const ResultFrame& frame) {
  FrameInfo info;
  info.step = frame.step;
  info.time = frame.time;
  info.num_points = frame.position.size() / 2;
  for (const ResultField& f : frame.fields) info.fields.emplace_back(f.name, f.components);
  const std::size_t n = info.num_points;
  const bool new_topology = !topologies_.contains(n);
  const std::string frame_link = absl::StrCat(frames_dir_name_, "/", FrameFileName(frame.step));
  const std::string topology_link = absl::StrCat(frames_dir_name_, "/", TopologyFileName(n));
  const std::string frame_file = (fs::path(frames_dir_) / FrameFileName(frame.step)).string();
  const std::string topology_file = (fs::path(frames_dir_) / TopologyFileName(n)).string();

  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  std::vector<std::string> written;  // removed again on failure
  absl::Status s = [&]() -> absl::Status {
    RETURN_IF_ERROR(MakeFramesDir());
    const FileInfo file_info{created_by_, ""};
    if (new_topology) {
      RETURN_IF_ERROR(
          internal::WriteAtomically(topology_file, internal::kKindResultsTopology, {}, file_info,
                                    [&](h5::File& out) { return WriteTopology(out, n); }));
      written.push_back(topology_file);
    }
    RETURN_IF_ERROR(
        internal::WriteAtomically(frame_file, internal::kKindResultsFrame, {}, file_info,
                                  [&](h5::File& out) { return WriteFrame(out, frame); }));
    written.push_back(frame_file);
    ASSIGN_OR_RETURN(
        std::string index, StageIndex(&h5_path_, [&](h5::File& file) -> absl::Status {
          RETURN_IF_ERROR(
              file.CreateExternalLink(FramePath(frame.step), frame_link, FramePath(frame.step)));
          if (!new_topology) return absl::OkStatus();
          return file.CreateExternalLink(TopologyPath(n), topology_link, TopologyPath(n));
        }));
    written.push_back(index);
    std::vector<FrameInfo> frames = frames_;
    frames.push_back(info);
    ASSIGN_OR_RETURN(std::string xdmf, StageXdmf(frames));
    written.push_back(xdmf);
    RETURN_IF_ERROR(Rename(index, h5_path_));
    written.clear();  // linked: kept whatever follows
    frames_.push_back(std::move(info));
    if (new_topology) topologies_.insert(n);
    absl::Status renamed = Rename(xdmf, xdmf_path_);
    if (!renamed.ok()) RemoveQuietly(xdmf);
    SyncDirsOf(h5_path_, xdmf_path_);
    return renamed;
  }();
  for (const std::string& path : written) RemoveQuietly(path);
  return s;
}

absl::Status ResultsWriter::Close() {
  closed_ = true;
  return absl::OkStatus();
}

absl::StatusOr<std::string> ResultsWriter::StageXdmf(const std::vector<FrameInfo>& frames) const {
  const std::string xml = XdmfText(h5_reference_, frames);
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
  if (!ok) {
    std::remove(temp.c_str());
    return absl::ErrnoToStatus(error != 0 ? error : EIO, absl::StrCat("cannot write ", xdmf_path_));
  }
  return temp;
}

absl::Status ResultsWriter::WriteXdmf() const {
  ASSIGN_OR_RETURN(std::string temp, StageXdmf(frames_));
  if (absl::Status s = Rename(temp, xdmf_path_); !s.ok()) {
    RemoveQuietly(temp);
    return absl::Status(s.code(), absl::StrCat("cannot write ", xdmf_path_, ": ", s.message()));
  }
  SyncDirOf(xdmf_path_);
  return absl::OkStatus();
}

absl::StatusOr<std::vector<ResultFrame>> ReadResults(const std::string& h5_path) {
  std::lock_guard<std::mutex> lock(internal::StoreMutex());
  ASSIGN_OR_RETURN(h5::File file, internal::OpenStore(h5_path, internal::kKindResults, nullptr));
  ASSIGN_OR_RETURN(auto frames, ListFrames(file));
  std::vector<ResultFrame> out(frames.size());
  for (std::size_t k = 0; k < out.size(); ++k) {
    std::size_t num_points = 0;
    RETURN_IF_ERROR(ReadFrame(file, (frames)[k].second, /*data=*/true, &out[k], &num_points));
  }
  return out;
}

}  // namespace rvehub::store
