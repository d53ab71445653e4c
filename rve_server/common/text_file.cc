#include "rve_server/common/text_file.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"

namespace rvehub {

absl::StatusOr<std::string> ReadTextFile(const std::string& path, absl::string_view what) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(status)) {
    return absl::InvalidArgumentError(absl::StrCat(what, " '", path, "' is a directory"));
  }
  // Opening a FIFO waits for a writer, reading a socket for a peer: forever.
  if (std::filesystem::is_fifo(status) || std::filesystem::is_socket(status)) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, " '", path, "' is a ",
                     std::filesystem::is_fifo(status) ? "FIFO" : "socket", ", not a file"));
  }
  errno = 0;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    const int err = errno;
    const std::string why =
        absl::StrCat("cannot read ", what, " '", path, "': ", std::strerror(err));
    if (err == EACCES) return absl::PermissionDeniedError(why);
    return absl::NotFoundError(why);
  }
  std::string text;
  char buffer[1 << 16];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), f)) > 0) {
    if (text.size() + n > kMaxTextFileBytes) {
      std::fclose(f);
      return absl::InvalidArgumentError(
          absl::StrCat(what, " '", path, "' is larger than ", kMaxTextFileBytes >> 20, " MiB"));
    }
    text.append(buffer, n);
  }
  const int err = errno;
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) {
    return absl::DataLossError(
        absl::StrCat("error while reading ", what, " '", path, "': ", std::strerror(err)));
  }
  return text;
}

absl::StatusOr<bool> PathExists(const std::string& path) {
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  if (ec) {
    const std::string why = absl::StrCat("cannot look for '", path, "': ", ec.message());
    if (ec == std::errc::permission_denied) return absl::PermissionDeniedError(why);
    return absl::InvalidArgumentError(why);
  }
  return exists;
}

absl::StatusOr<std::string> ReadTokenFile(const std::string& path) {
  ASSIGN_OR_RETURN(std::string text, ReadTextFile(path, "token file"));
  std::string token(absl::StripAsciiWhitespace(text));
  if (token.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("token file '", path, "' is empty"));
  }
  if (token.size() > kMaxTokenBytes) {
    return absl::InvalidArgumentError(absl::StrCat("token file '", path, "' holds ", token.size(),
                                                   " bytes; a token has at most ", kMaxTokenBytes));
  }
  // gRPC sends it in a header: visible ASCII only (a newline or a NUL
  // aborted the clients, and a server started with one could never be
  // reached).
  for (std::size_t i = 0; i < token.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(token[i]);
    if (c < 0x21 || c > 0x7e) {
      return absl::InvalidArgumentError(
          absl::StrFormat("token file '%s': byte %d of the token is 0x%02x; a token is one line "
                          "of visible ASCII characters",
                          path, i + 1, c));
    }
  }
  std::error_code ec;
  const std::filesystem::perms perms = std::filesystem::status(path, ec).permissions();
  if (!ec && (perms & (std::filesystem::perms::others_read |
                       std::filesystem::perms::others_write)) != std::filesystem::perms::none) {
    std::fprintf(stderr, "warning: token file '%s' is %s by every user; chmod 600 it\n",
                 path.c_str(),
                 (perms & std::filesystem::perms::others_write) != std::filesystem::perms::none
                     ? "writable"
                     : "readable");
  }
  return token;
}

}  // namespace rvehub
