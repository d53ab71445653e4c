// MPM results for ParaView: per output frame, the material points' positions
// and fields in DIR/results.h5 (HDF5, kind "results", store/FORMAT.md), and
// DIR/results.xdmf, an XDMF file listing the frames as a temporal collection
// of Polyvertex grids whose DataItems point into results.h5 by relative file
// name. Open results.xdmf in ParaView (either XDMF reader).
//
// Both files are valid after every Append, even if the run is killed: the
// HDF5 file is open only while a frame is appended (a killed writer leaves no
// "file is open" flag behind; the superblock has none), and the XDMF file is
// replaced atomically and lists only complete frames.
//
// Calls are serialised with the other store calls; one writer per file.
#ifndef RVEHUB_STORE_RESULTS_H_
#define RVEHUB_STORE_RESULTS_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::store {

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
  // Continues an existing results file (a resumed run): deletes its frames
  // with step > keep_through_step (the run writes them again), rewrites
  // xdmf_path to list exactly the frames kept, and records created_by as the
  // file's resumed_by attribute. NotFound when h5_path does not exist;
  // InvalidArgument when it is no results file; DataLoss when a kept frame is
  // incomplete or inconsistent. (HDF5 does not reclaim the space of deleted
  // frames; h5repack does.)
  static absl::StatusOr<std::unique_ptr<ResultsWriter>> Open(const std::string& h5_path,
                                                             const std::string& xdmf_path,
                                                             const std::string& created_by,
                                                             std::int64_t keep_through_step);

  ResultsWriter(const ResultsWriter&) = delete;
  ResultsWriter& operator=(const ResultsWriter&) = delete;
  ~ResultsWriter();

  // Appends one frame as /frames/<step>, closes (flushes) and fsyncs the
  // HDF5 file, then replaces the XDMF file. InvalidArgument, with nothing
  // written, for inconsistent sizes, an unsupported component count or
  // field name, a non-finite time, or a step not greater than the last.
  // Unavailable when another process keeps the HDF5 file locked (open) for
  // more than ~10 s. FailedPrecondition after Close.
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

  ResultsWriter(std::string h5_path, std::string xdmf_path, std::string h5_reference)
      : h5_path_(std::move(h5_path)),
        xdmf_path_(std::move(xdmf_path)),
        h5_reference_(std::move(h5_reference)) {}
  absl::Status WriteXdmf() const;

  std::string h5_path_;
  std::string xdmf_path_;
  std::string h5_reference_;  // h5_path relative to the XDMF file's directory
  std::vector<FrameInfo> frames_;
  bool closed_ = false;
};

// Reads a results file back (for tests and tools): the frames in step
// order, each field with the component count it was written with (a
// 2-component field loses its z padding again; position is × 2).
// NotFound / InvalidArgument / FailedPrecondition / DataLoss as ReadRves.
absl::StatusOr<std::vector<ResultFrame>> ReadResults(const std::string& h5_path);

}  // namespace rvehub::store

#endif  // RVEHUB_STORE_RESULTS_H_
