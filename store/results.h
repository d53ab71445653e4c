// MPM results for ParaView: per output frame, the material points' positions
// and fields in DIR/results.h5 (HDF5, kind "results", store/FORMAT.md), and
// DIR/results.xdmf, an XDMF file listing the frames as a temporal collection
// of Polyvertex grids whose DataItems point into results.h5 by relative file
// name. Open results.xdmf in ParaView (either XDMF reader).
//
// Each frame is a file of its own in DIR/results.frames/, which results.h5
// links (HDF5 external links, followed by every HDF5 reader). Both files
// are valid after every Append, even if the run is killed or the disk fills
// up: nothing written is ever written again (frames are written under a
// temporary name; results.h5 and the XDMF file are replaced atomically), so
// a failed Append leaves the frames before it readable.
//
// Calls are serialised with the other store calls; one writer per file.
#ifndef RVEHUB_STORE_RESULTS_H_
#define RVEHUB_STORE_RESULTS_H_

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::store {

namespace h5 {
class File;
}  // namespace h5

struct ResultField {
  // [A-Za-z0-9_.-]+, not starting with '.', not "position", unique in a frame.
  std::string name;  // e.g. "velocity", "stress", "p", "rve_id"
  // 1 (scalar), 2 or 3 (vector; 2 is written padded to 3 with z = 0),
  // 9 (3×3 tensor, row-major).
  int components = 1;
  std::vector<double> values;  // num_points × components, row-major
};

struct ResultFrame {
  std::int64_t step = 0;         // MPM step; strictly increasing from frame to frame
  double time = 0.0;             // s; finite
  std::vector<double> position;  // num_points × 2, m (written as × 3 with z = 0)
  std::vector<ResultField> fields;
};

class ResultsWriter {
 public:
  // Creates (truncates) h5_path and xdmf_path (an XDMF file without frames).
  // created_by (program and version) becomes an attribute of the HDF5 file.
  static absl::StatusOr<std::unique_ptr<ResultsWriter>> Create(const std::string& h5_path,
                                                               const std::string& xdmf_path,
                                                               const std::string& created_by);
  // Continues an existing results file (a resumed run): drops its frames
  // with step > keep_through_step (the run writes them again; their files
  // are removed), rewrites xdmf_path to list exactly the frames kept, and
  // records created_by as the file's resumed_by attribute. Frames kept
  // inside results.h5 itself (files written before frame files) move into
  // frame files. NotFound when h5_path does not exist; InvalidArgument when
  // it is no results file; DataLoss when a kept frame is missing, incomplete
  // or inconsistent.
  static absl::StatusOr<std::unique_ptr<ResultsWriter>> Open(const std::string& h5_path,
                                                             const std::string& xdmf_path,
                                                             const std::string& created_by,
                                                             std::int64_t keep_through_step);

  ResultsWriter(const ResultsWriter&) = delete;
  ResultsWriter& operator=(const ResultsWriter&) = delete;
  ~ResultsWriter();

  // Appends one frame as /frames/<step>: writes and fsyncs its frame file,
  // then replaces results.h5 and the XDMF file. InvalidArgument, with
  // nothing written, for inconsistent sizes, an unsupported component count
  // or field name, a non-finite time, or a step not greater than the last.
  // A failed write ("appending step N to PATH: …"; ResourceExhausted for a
  // full disk or a file size limit) leaves both files as they were.
  // FailedPrecondition after Close.
  absl::Status Append(const ResultFrame& frame);
  // Ends the writer (both files are already complete); later Appends fail.
  absl::Status Close();

  // Frames written so far (including those kept by Open).
  std::size_t num_frames() const { return frames_.size(); }

 private:
  // What the XDMF file needs to know of a frame.
  struct FrameInfo {
    std::int64_t step = 0;
    double time = 0.0;
    std::size_t num_points = 0;
    std::vector<std::pair<std::string, int>> fields;  // name, components as given
  };

  ResultsWriter(std::string h5_path, std::string xdmf_path, std::string h5_reference,
                std::string created_by);
  absl::Status AppendFiles(const ResultFrame& frame);
  absl::Status MakeFramesDir() const;
  // Builds the next index under a temporary name and returns that name: a
  // copy of *base with `edit` applied, or (base null) a new index with the
  // root attributes and `edit` (if any) applied.
  absl::StatusOr<std::string> StageIndex(const std::string* base,
                                         const std::function<absl::Status(h5::File&)>& edit) const;
  // The XDMF text of `frames` under a temporary name; returns that name.
  absl::StatusOr<std::string> StageXdmf(const std::vector<FrameInfo>& frames) const;
  absl::Status WriteXdmf() const;

  std::string h5_path_;
  std::string xdmf_path_;
  std::string h5_reference_;  // h5_path relative to the XDMF file's directory
  std::string created_by_;
  std::string frames_dir_name_;  // "results.frames" for results.h5, as the links name it
  std::string frames_dir_;       // its path
  std::vector<FrameInfo> frames_;
  std::set<std::size_t> topologies_;  // the point counts whose topology is linked
  bool closed_ = false;
};

// Reads a results file back (for tests and tools): the frames in step
// order, each field with the component count it was written with (a
// 2-component field loses its z padding again; position is × 2).
// NotFound / InvalidArgument / FailedPrecondition / DataLoss as ReadRves.
absl::StatusOr<std::vector<ResultFrame>> ReadResults(const std::string& h5_path);

}  // namespace rvehub::store

#endif  // RVEHUB_STORE_RESULTS_H_
