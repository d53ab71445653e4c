// The output directory of a continuum client's run, locked for the run's
// life: an exclusive flock on DIR/.lock (which holds the run's pid and
// host), so that a second run into the same directory is refused at its
// start rather than failing part way on the first run's files.
#ifndef RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_
#define RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_

#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace rvehub::client_run {

class OutDirLock {
 public:
  // Creates `dir` (and its parents) when missing and locks it.
  // FailedPrecondition "DIR is in use by another run (pid N)" when another
  // process holds the lock; Unavailable when the directory or the lock file
  // cannot be made. On a file system without flock (some network mounts)
  // the run goes on unlocked.
  static absl::StatusOr<OutDirLock> Acquire(const std::string& dir);

  // For a run that failed before writing anything (a case the servers
  // refuse, a checkpoint that does not read): when Acquire made the directory
  // and it holds nothing but the lock file, removes both and releases the
  // lock, so that the failure leaves no directory behind. Otherwise only
  // releases the lock.
  void ReleaseAndRemoveIfUnused();

  OutDirLock(OutDirLock&& other) noexcept : fd_(other.fd_), made_dir_(std::move(other.made_dir_)) {
    other.fd_ = -1;
    other.made_dir_.clear();
  }
  OutDirLock& operator=(OutDirLock&& other) noexcept;
  OutDirLock(const OutDirLock&) = delete;
  OutDirLock& operator=(const OutDirLock&) = delete;
  // Releases the lock (as the process's end does, however it ends). The
  // file stays: removing it would let a run waiting on the old file and one
  // creating a new file both hold "the" lock.
  ~OutDirLock();

 private:
  OutDirLock(int fd, std::string made_dir) : fd_(fd), made_dir_(std::move(made_dir)) {}
  int fd_ = -1;
  std::string made_dir_;  // the directory when Acquire made it, else ""
};

// Before a resume takes the lock: NotFound "<path>: no such checkpoint file"
// when `checkpoint` is not a file, so that a mistyped path gets that plain
// message (not the HDF5 library's, nor "in use" from a run holding its
// directory) and touches no lock. A checkpoint that exists but does not read
// is left to the resume, whose failure ReleaseAndRemoveIfUnused cleans up.
absl::Status CheckCheckpointFile(const std::string& checkpoint);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_
