// Reading small text files the server and clients are pointed at (bearer
// tokens, PEM certificates and keys, case files), and looking for files,
// with errors that name the file: a path given on a command line is input,
// and nothing here throws.
#ifndef RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_
#define RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_

#include <cstddef>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub {

// The most ReadTextFile reads, bytes: tokens, certificates (a system's CA
// bundle is about 200 kB) and case files are far smaller; /dev/zero or a
// data file named by mistake must not fill the memory.
inline constexpr std::size_t kMaxTextFileBytes = std::size_t{16} << 20;

// The whole file. NotFound / PermissionDenied naming `what` and the path
// when it cannot be opened; InvalidArgument for a directory, a FIFO or a
// socket (which would block) or a file of more than kMaxTextFileBytes;
// DataLoss when reading fails midway.
absl::StatusOr<std::string> ReadTextFile(const std::string& path, absl::string_view what = "file");

// Whether `path` exists. Any other failure to find out (a name too long, a
// directory on the way that may not be searched) is an error naming it:
// PermissionDenied or InvalidArgument.
absl::StatusOr<bool> PathExists(const std::string& path);

// The longest token ReadTokenFile takes, bytes (a bearer token is a few
// dozen; each call sends it).
inline constexpr std::size_t kMaxTokenBytes = 4096;

// A bearer token: the file without surrounding whitespace, 1 to
// kMaxTokenBytes visible ASCII characters (0x21–0x7e), else InvalidArgument
// naming the file (and the first bad byte). A file other users may read or
// write is taken with a warning on stderr.
absl::StatusOr<std::string> ReadTokenFile(const std::string& path);

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_TEXT_FILE_H_
