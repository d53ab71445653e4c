#include "client_run/out_dir_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "absl/strings/strip.h"

namespace rvehub::client_run {
namespace {

std::string HostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "";
  return name;
}

// "pid N" (and "on HOST" when another host holds it) from the lock file's
// "N HOST" line; "" when it holds none yet (the holder writes it just after
// locking).
std::string Holder(int fd) {
  char buffer[320] = {};
  const ssize_t n = ::pread(fd, buffer, sizeof(buffer) - 1, 0);
  if (n <= 0) return "";
  const std::pair<std::string, std::string> fields = absl::StrSplit(
      absl::StripAsciiWhitespace(absl::string_view(buffer, n)), absl::MaxSplits(' ', 1));
  long pid = 0;
  if (!absl::SimpleAtoi(fields.first, &pid) || pid <= 0) return "";
  std::string holder = absl::StrCat("pid ", pid);
  if (!fields.second.empty() && fields.second != HostName()) {
    absl::StrAppend(&holder, " on ", fields.second);
  }
  return holder;
}

}  // namespace

absl::StatusOr<OutDirLock> OutDirLock::Acquire(const std::string& dir) {
  std::error_code ec;
  const bool existed = std::filesystem::exists(dir, ec);
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return absl::UnavailableError(
        absl::StrCat("cannot create the output directory ", dir, ": ", ec.message()));
  }
  const std::string path = (std::filesystem::path(dir) / ".lock").string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    return absl::UnavailableError(absl::StrCat("cannot lock the output directory ", dir,
                                               ": cannot open ", path, ": ", std::strerror(errno)));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    if (error == EWOULDBLOCK) {
      const std::string holder = Holder(fd);
      ::close(fd);
      return absl::FailedPreconditionError(
          absl::StrCat(dir, " is in use by another run (", holder.empty() ? "pid unknown" : holder,
                       "); choose another --out, or wait for that run to end"));
    }
    // No flock here (ENOLCK, EOPNOTSUPP): nothing to guard with.
    ::close(fd);
    return OutDirLock(-1, "");
  }
  const std::string line = absl::StrCat(::getpid(), " ", HostName(), "\n");
  // Best effort: the pid only makes the refusal's message more helpful.
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, line.data(), line.size(), 0);
  return OutDirLock(fd, existed ? "" : dir);
}

void OutDirLock::ReleaseAndRemoveIfUnused() {
  if (fd_ < 0) return;
  if (!made_dir_.empty()) {
    const std::filesystem::path lock = std::filesystem::path(made_dir_) / ".lock";
    std::error_code ec;
    bool only_lock = true;
    for (const auto& entry : std::filesystem::directory_iterator(made_dir_, ec)) {
      if (entry.path().filename() != ".lock") only_lock = false;
    }
    // Unlinked while still held, so no other run can lock this file after;
    // rmdir fails harmlessly if a run made a new one meanwhile.
    if (!ec && only_lock && std::filesystem::remove(lock, ec)) {
      std::filesystem::remove(made_dir_, ec);
    }
  }
  ::close(fd_);
  fd_ = -1;
  made_dir_.clear();
}

OutDirLock& OutDirLock::operator=(OutDirLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    made_dir_ = std::move(other.made_dir_);
    other.fd_ = -1;
    other.made_dir_.clear();
  }
  return *this;
}

OutDirLock::~OutDirLock() {
  if (fd_ >= 0) ::close(fd_);
}

absl::Status CheckCheckpointFile(const std::string& checkpoint) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(checkpoint, ec)) return absl::OkStatus();
  return absl::NotFoundError(absl::StrCat(checkpoint, ": no such checkpoint file"));
}

}  // namespace rvehub::client_run
