// A run's log lines, written by the run's thread and read by a test's
// (the fault tests strike when a line appears).
#ifndef RVEHUB_TESTS_SUPPORT_LOG_LINES_H_
#define RVEHUB_TESTS_SUPPORT_LOG_LINES_H_

#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_join.h"
#include "absl/synchronization/mutex.h"

namespace rvehub::testing_util {

class LogLines {
 public:
  void Add(const std::string& line) {
    absl::MutexLock lock(&mu_);
    lines_.push_back(line);
  }
  // Whether a line contains `words`.
  bool Has(const std::string& words) const {
    absl::MutexLock lock(&mu_);
    for (const std::string& l : lines_) {
      if (absl::StrContains(l, words)) return true;
    }
    return false;
  }
  std::string All() const {
    absl::MutexLock lock(&mu_);
    return absl::StrJoin(lines_, "\n");
  }

 private:
  mutable absl::Mutex mu_;
  std::vector<std::string> lines_;
};

}  // namespace rvehub::testing_util

#endif  // RVEHUB_TESTS_SUPPORT_LOG_LINES_H_
