#include "client_run/run_record.h"

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
  const std::string tmp = Path() + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "w");
  const std::string text = json_.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
  const bool ok = f != nullptr && std::fwrite(text.data(), 1, text.size(), f) == text.size();
  const bool closed = f != nullptr && std::fclose(f) == 0;
  if (!ok || !closed || std::rename(tmp.c_str(), Path().c_str()) != 0) {
    std::remove(tmp.c_str());
    std::fprintf(stderr, "%s: cannot write %s\n", program_.c_str(), Path().c_str());
  }
}

}  // namespace rvehub::client_run
