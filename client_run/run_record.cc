#include "client_run/run_record.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <system_error>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "rve_server/common/text_file.h"
#include "rve_server/common/version.h"

namespace rvehub::client_run {
namespace {

std::string Now() {
  return absl::FormatTime("%Y-%m-%dT%H:%M:%E3SZ", absl::Now(), absl::UTCTimeZone());
}

std::string HostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "";
  return name;
}

// Room kept for run.json beyond its end: the final record (with an error
// message, a few kB) must fit when the disk has filled up during the run.
constexpr off_t kReserveBytes = 64 << 10;

// Written under a temporary name and renamed over `path`: readers see the
// old record or the new one.
bool WriteReplacing(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "w");
  const bool ok = f != nullptr && std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const bool closed = f != nullptr && std::fclose(f) == 0;
  if (!ok || !closed || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return false;
  }
  return true;
}

// Allocates kReserveBytes beyond the end of `path` without changing its size
// (best effort: a file system without fallocate keeps no reserve).
void Reserve(const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) return;
  (void)::fallocate(fd, FALLOC_FL_KEEP_SIZE, 0, kReserveBytes);
  ::close(fd);
}

// Overwrites `path` from its start, in its own (reserved) blocks.
bool WriteInPlace(const std::string& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n =
        ::pwrite(fd, text.data() + done, text.size() - done, static_cast<off_t>(done));
    if (n <= 0) break;
    done += static_cast<std::size_t>(n);
  }
  const bool ok = done == text.size() && ::ftruncate(fd, static_cast<off_t>(done)) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

RunRecord::RunRecord(const std::string& program, const std::string& version, int argc, char** argv,
                     const std::string& command)
    : program_(program) {
  json_["program"] = program;
  json_["version"] = version;
  json_["api_version"] = kVersion;
  json_["command_line"] = std::vector<std::string>(argv, argv + argc);
  json_["command"] = command;
  json_["host"] = HostName();
  std::error_code ec;
  json_["working_directory"] = std::filesystem::current_path(ec).string();
  json_["start"] = Now();
  json_["end"] = nullptr;
  json_["outcome"] = "running";
}

void RunRecord::Started(const std::string& dir, const std::string& case_json, bool resumed) {
  dir_ = dir;
  json_["case"] = Json::parse(case_json);
  if (resumed) {
    // The run this one continues, and any it continued.
    if (absl::StatusOr<std::string> old = ReadTextFile(Path(), "run record"); old.ok()) {
      Json previous = Json::parse(*old, nullptr, /*allow_exceptions=*/false);
      if (!previous.is_discarded()) {
        Json chain = previous.contains("previous") ? previous["previous"] : Json::array();
        previous.erase("previous");
        chain.push_back(std::move(previous));
        json_["previous"] = std::move(chain);
      }
    }
  }
  Write();
}

void RunRecord::Checkpointed(std::int64_t step, double wall_s) {
  json_["last_checkpoint"] = {{"step", step}, {"wall_s", wall_s}, {"at", Now()}};
  Write();
}

void RunRecord::Failed(const std::string& error) {
  json_["end"] = Now();
  json_["outcome"] = "failed";
  json_["error"] = error;
  Write();
}

void RunRecord::Finished(const std::string& outcome, const Json& fields) {
  json_["end"] = Now();
  json_["outcome"] = outcome;
  for (const auto& [key, value] : fields.items()) json_[key] = value;
  Write();
}

void RunRecord::Write() const {
  if (dir_.empty()) return;
  const std::string text = json_.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
  if (WriteReplacing(Path(), text)) {
    Reserve(Path());
    return;
  }
  // A full disk has no room for a second copy; the reserved blocks of the
  // one there take the record (so that it says "failed", not "running").
  if (WriteInPlace(Path(), text)) return;
  std::fprintf(stderr, "%s: cannot write %s\n", program_.c_str(), Path().c_str());
}

}  // namespace rvehub::client_run
