// Reading small text files the server and clients are pointed at (bearer
// tokens, PEM certificates and keys), with errors that name the file.
#ifndef RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_
#define RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub {

// The whole file. NotFound / PermissionDenied naming `what` and the path
// when it cannot be opened, DataLoss when reading fails midway.
absl::StatusOr<std::string> ReadTextFile(const std::string& path, absl::string_view what = "file");

// A bearer token: the file without surrounding whitespace; an empty token is
// InvalidArgument.
absl::StatusOr<std::string> ReadTokenFile(const std::string& path);

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_
