// The output directory's lock: a second holder is refused, and a run that
// fails before writing anything leaves no directory it made behind.
#include "client_run/out_dir_lock.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"

namespace rvehub::client_run {
namespace {

namespace fs = std::filesystem;

class OutDirLockTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / absl::StrCat("out_dir_lock_test_", ::getpid());
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

TEST_F(OutDirLockTest, ASecondHolderIsRefusedUntilTheFirstReleases) {
  const std::string dir = (root_ / "run").string();
  absl::StatusOr<OutDirLock> first = OutDirLock::Acquire(dir);
  ASSERT_TRUE(first.ok()) << first.status();
  absl::StatusOr<OutDirLock> second = OutDirLock::Acquire(dir);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(second.status().message(),
            absl::StrCat(dir, " is in use by another run (pid ", ::getpid(),
                         "); choose another --out, or wait for that run to end"));
  first->ReleaseAndRemoveIfUnused();
  EXPECT_TRUE(OutDirLock::Acquire(dir).ok());
}

TEST_F(OutDirLockTest, AnUnusedDirectoryItMadeIsRemoved) {
  const fs::path dir = root_ / "a" / "b";
  absl::StatusOr<OutDirLock> lock = OutDirLock::Acquire(dir.string());
  ASSERT_TRUE(lock.ok()) << lock.status();
  ASSERT_TRUE(fs::exists(dir / ".lock"));
  lock->ReleaseAndRemoveIfUnused();
  EXPECT_FALSE(fs::exists(dir));
  EXPECT_TRUE(fs::exists(root_ / "a")) << "only the run's own directory goes";
}

TEST_F(OutDirLockTest, ADirectoryWithFilesOrMadeBeforeIsKept) {
  const fs::path written = root_ / "written";
  absl::StatusOr<OutDirLock> lock = OutDirLock::Acquire(written.string());
  ASSERT_TRUE(lock.ok()) << lock.status();
  std::ofstream(written / "results.h5") << "x";
  lock->ReleaseAndRemoveIfUnused();
  EXPECT_TRUE(fs::exists(written / "results.h5"));
  EXPECT_TRUE(fs::exists(written / ".lock"));
  EXPECT_TRUE(OutDirLock::Acquire(written.string()).ok()) << "released";

  const fs::path before = root_ / "before";
  fs::create_directories(before);
  lock = OutDirLock::Acquire(before.string());
  ASSERT_TRUE(lock.ok()) << lock.status();
  lock->ReleaseAndRemoveIfUnused();
  EXPECT_TRUE(fs::exists(before / ".lock"));
}

}  // namespace
}  // namespace rvehub::client_run
