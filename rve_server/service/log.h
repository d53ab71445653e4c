// Structured log lines (logfmt) on stderr: one line per event,
// `time=2026-11-22T10:00:00.123Z level=info msg="created" run=a count=4`.
#ifndef RVEHUB_RVE_SERVER_SERVICE_LOG_H_
#define RVEHUB_RVE_SERVER_SERVICE_LOG_H_

#include <string>
#include <utility>
#include <vector>

#include "absl/strings/string_view.h"

namespace rvehub::service {

using LogFields = std::vector<std::pair<std::string, std::string>>;

// level: "info", "warn" or "error". Thread-safe; values with spaces or quotes
// are quoted.
void Log(absl::string_view level, absl::string_view msg, const LogFields& fields = {});

// Silences Log (tests that start many servers).
void SetLogEnabled(bool on);

}  // namespace rvehub::service

#endif  // RVEHUB_RVE_SERVER_SERVICE_LOG_H_
