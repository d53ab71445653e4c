// The output directory of a continuum client's run, locked for the run's
// life: an exclusive flock on DIR/.lock (which holds the run's pid and
// host), so that a second run into the same directory is refused at its
// start rather than failing part way on the first run's files.
#ifndef RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_
#define RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_

#include <string>

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

  OutDirLock(OutDirLock&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  OutDirLock& operator=(OutDirLock&& other) noexcept;
  OutDirLock(const OutDirLock&) = delete;
  OutDirLock& operator=(const OutDirLock&) = delete;
  // Releases the lock (as the process's end does, however it ends). The
  // file stays: removing it would let a run waiting on the old file and one
  // creating a new file both hold "the" lock.
  ~OutDirLock();

 private:
  explicit OutDirLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

// Before a resume takes the lock, which makes its directory: NotFound
// "<path>: no such checkpoint file" when `checkpoint` is not a file, so that
// a mistyped path makes no directory.
absl::Status CheckCheckpointFile(const std::string& checkpoint);

}  // namespace rvehub::client_run

#endif  // RVEHUB_CLIENT_RUN_OUT_DIR_LOCK_H_
