// ReadTextFile, ReadTokenFile and PathExists: paths given on a command line
// (token, certificate and case files, checkpoint and cache directories) are
// input; each misuse is an error naming the path, never an exception (a
// directory as a token file aborted mpm_client and rve_server) or a read
// without end (/dev/zero as a token file filled the memory).
#include "rve_server/common/text_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"

namespace rvehub {
namespace {

namespace fs = std::filesystem;

class TextFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("rvehub_text_file_test_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(TextFileTest, ReadsAFileWholeAndATokenWithoutItsWhitespace) {
  const std::string path = Path("token");
  std::ofstream(path, std::ios::binary) << "  s3cret\n";
  absl::StatusOr<std::string> text = ReadTextFile(path);
  ASSERT_TRUE(text.ok()) << text.status();
  EXPECT_EQ(*text, "  s3cret\n");
  absl::StatusOr<std::string> token = ReadTokenFile(path);
  ASSERT_TRUE(token.ok()) << token.status();
  EXPECT_EQ(*token, "s3cret");
}

TEST_F(TextFileTest, MisusedPathsAreErrorsNamingThem) {
  const absl::StatusOr<std::string> missing = ReadTextFile(Path("none"), "token file");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(absl::StrContains(missing.status().message(), "cannot read token file '"))
      << missing.status();

  const absl::StatusOr<std::string> directory = ReadTokenFile(dir_.string());
  EXPECT_EQ(directory.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(directory.status().message(), "token file '" + dir_.string() + "' is a directory");

  // Without a bound this reads until the memory is gone.
  const absl::StatusOr<std::string> endless = ReadTextFile("/dev/zero", "TLS CA file");
  EXPECT_EQ(endless.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(endless.status().message(), "TLS CA file '/dev/zero' is larger than 16 MiB");

  const std::string empty = Path("empty");
  std::ofstream(empty) << " \n";
  EXPECT_EQ(ReadTokenFile(empty).status().code(), absl::StatusCode::kInvalidArgument);
}

// A token goes into a gRPC header: a newline, a NUL or a non-ASCII byte
// inside it, or a megabyte of it, is refused where the file is read, naming
// the byte; a FIFO is refused instead of waiting for a writer forever.
TEST_F(TextFileTest, ATokenIsOneLineOfVisibleAscii) {
  const std::string path = Path("token");
  for (const auto& [content, says] : std::vector<std::pair<std::string, std::string>>{
           {"abc\ndef", "byte 4 of the token is 0x0a"},
           {std::string("ab\0cd", 5), "byte 3 of the token is 0x00"},
           {"caf\xc3\xa9", "byte 4 of the token is 0xc3"},
           {"two words", "byte 4 of the token is 0x20"},
           {std::string(1 << 20, 'a'), "holds 1048576 bytes; a token has at most 4096"}}) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << content;
    const absl::Status s = ReadTokenFile(path).status();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << says;
    EXPECT_TRUE(absl::StrContains(s.message(), says)) << s;
  }
  std::ofstream(path, std::ios::binary | std::ios::trunc) << std::string(4096, '~');
  EXPECT_TRUE(ReadTokenFile(path).ok());

  const std::string fifo = Path("fifo");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(ReadTokenFile(fifo).status().message(),
            "token file '" + fifo + "' is a FIFO, not a file");
}

// Others may read a token file only by mistake: taken, with a warning.
TEST_F(TextFileTest, AWorldReadableTokenFileIsTakenWithAWarning) {
  const std::string path = Path("token");
  std::ofstream(path) << "s3cret\n";
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  ::testing::internal::CaptureStderr();
  EXPECT_TRUE(ReadTokenFile(path).ok());
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  fs::permissions(path, fs::perms::others_read, fs::perm_options::add);
  ::testing::internal::CaptureStderr();
  EXPECT_TRUE(ReadTokenFile(path).ok());
  EXPECT_EQ(::testing::internal::GetCapturedStderr(),
            "warning: token file '" + path + "' is readable by every user; chmod 600 it\n");
}

TEST_F(TextFileTest, PathExistsSaysYesNoOrWhyItCannotTell) {
  const std::string file = Path("file");
  std::ofstream(file) << "x";
  EXPECT_EQ(PathExists(file).value_or(false), true);
  EXPECT_EQ(PathExists(dir_.string()).value_or(false), true);
  EXPECT_EQ(PathExists(Path("none")).value_or(true), false);
  // A name longer than the system's limit: std::filesystem::exists(path)
  // throws here, which aborted mpm_client given such a --template-cache.
  const std::string long_name = Path(std::string(5000, 'x'));
  const absl::StatusOr<bool> too_long = PathExists(long_name);
  EXPECT_EQ(too_long.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(
      absl::StartsWith(too_long.status().message(), "cannot look for '" + long_name + "': "))
      << too_long.status();
}

}  // namespace
}  // namespace rvehub
