// CSV and PNG output of element-test results (file I/O lives here, not in
// the engine).
#ifndef RVEHUB_RVE_SERVER_CLI_ELEMENT_TEST_IO_H_
#define RVEHUB_RVE_SERVER_CLI_ELEMENT_TEST_IO_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "rve_server/values/element_test.h"

namespace rvehub::cli {

// Writes `text` to `path` (replacing it): Unavailable naming the path when
// it cannot be opened or written.
absl::Status WriteTextFile(const std::string& path, absl::string_view text);

// The CSV header, in column order.
extern const char kElementTestCsvHeader[];

absl::Status WriteElementTestCsv(const std::string& path,
                                 const std::vector<dem::ElementTestRow>& rows);

// The usual curves for the test kind (stress–strain, volume change, stress
// path, void ratio, coordination and fabric).
absl::Status WriteElementTestPlot(const std::string& path, dem::ElementTestKind kind,
                                  const std::string& title,
                                  const std::vector<dem::ElementTestRow>& rows);

}  // namespace rvehub::cli

#endif  // RVEHUB_RVE_SERVER_CLI_ELEMENT_TEST_IO_H_
