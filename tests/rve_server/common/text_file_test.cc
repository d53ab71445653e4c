// ReadTextFile, ReadTokenFile and PathExists: paths given on a command line
// (token, certificate and case files, checkpoint and cache directories) are
// input; each misuse is an error naming the path, never an exception (a
// directory as a token file aborted mpm_client and rve_server) or a read
// without end (/dev/zero as a token file filled the memory).
#include "rve_server/common/text_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

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
