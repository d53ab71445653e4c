#include "rve_server/service/log.h"

#include <atomic>
#include <cstdio>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"

namespace rvehub::service {
namespace {

std::atomic<bool> enabled{true};
absl::Mutex log_mu;

std::string Quote(absl::string_view v) {
  const bool plain = !v.empty() && v.find_first_of(" \"=\n\t") == absl::string_view::npos;
  if (plain) return std::string(v);
  return absl::StrCat("\"", absl::StrReplaceAll(v, {{"\\", "\\\\"}, {"\"", "\\\""}, {"\n", "\\n"}}),
                      "\"");
}

}  // namespace

void SetLogEnabled(bool on) { enabled = on; }

void Log(absl::string_view level, absl::string_view msg, const LogFields& fields) {
  if (!enabled) return;
  std::string line = absl::StrCat(
      "time=", absl::FormatTime("%Y-%m-%dT%H:%M:%E3SZ", absl::Now(), absl::UTCTimeZone()),
      " level=", level, " msg=", Quote(msg));
  for (const auto& [k, v] : fields) absl::StrAppend(&line, " ", k, "=", Quote(v));
  line += '\n';
  absl::MutexLock lock(&log_mu);
  std::fputs(line.c_str(), stderr);
}

}  // namespace rvehub::service
