// mpm_client's output directory under stress, the binary run as a child
// process: a second run into a directory in use is refused at its start; a
// file size limit or a full disk ends the run with run.json saying
// "failed" and the results written before it readable (and a resume
// continues once there is room).
#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "store/results.h"
#include "tests/mpm_client/mpm_cli_test_util.h"
#include "tests/support/process_util.h"

namespace rvehub::mpm::cli_test {
namespace {

// The small case with a frame every step (results.xdmf grows by about 3 kB a
// frame) and a checkpoint every `checkpoint_every` steps.
std::string FrameEveryStepCase(const std::string& name, int checkpoint_every) {
  Json c = SmallCase();
  c["output"]["frame_every"] = 1;
  c["output"]["checkpoint_every"] = checkpoint_every;
  return WriteCase(name, c);
}

// mpm_client with `args` after the shell command `before` (e.g. a ulimit).
Result RunClientAfter(const std::string& before, const std::string& args) {
  const std::string err_path = TempPath("stderr-after.txt");
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat(before, "; exec ", Quote(MPM_CLIENT_PATH), " ", args, " 2>", Quote(err_path)));
  Result r{run.exit_code, std::move(run.out), ReadFile(err_path)};
  std::remove(err_path.c_str());
  return r;
}

std::string Lower(const std::string& s) { return absl::AsciiStrToLower(s); }

// The frames of DIR/results.h5, which must read back, and those that
// DIR/results.xdmf lists: the same steps, 0, 1, 2, … (a frame every step).
std::vector<std::int64_t> ExpectReadableFrames(const std::string& dir) {
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(dir + "/results.h5");
  EXPECT_TRUE(frames.ok()) << frames.status();
  std::vector<std::int64_t> steps;
  if (!frames.ok()) return steps;
  for (const store::ResultFrame& f : *frames) {
    EXPECT_EQ(f.step, static_cast<std::int64_t>(steps.size()));
    steps.push_back(f.step);
  }
  const auto listed = XdmfFrames(ReadFile(dir + "/results.xdmf"));
  EXPECT_EQ(listed.size(), steps.size());
  for (std::size_t k = 0; k < listed.size() && k < steps.size(); ++k) {
    EXPECT_EQ(listed[k].first, absl::StrCat(steps[k]));
  }
  return steps;
}

// Waits (at most 60 s) until DIR/.lock names `pid`: that run holds the lock.
bool WaitForLockHolder(const std::string& dir, pid_t pid) {
  const std::string expected = absl::StrCat(pid, " ");
  for (int i = 0; i < 600; ++i) {
    if (ReadFile(dir + "/.lock").starts_with(expected)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

// While one run writes into a directory, a second run or a resume into it is
// refused at its start, naming the first run's pid, and changes nothing
// there; once the first has ended (killed, even), a run there goes ahead.
TEST(MpmCliOutputTest, ADirectoryInUseByAnotherRunIsRefused) {
  const std::string out = TempPath("in-use");
  Json long_case = SmallCase();
  long_case["solver"]["end_time"] = 60.0;  // 30000 steps: killed long before
  long_case["output"]["checkpoint_every"] = 10;
  testing_util::ChildProcess first(
      {MPM_CLIENT_PATH, "run", WriteCase("in-use-long", long_case), "--out=" + out, "--threads=2",
       "--template-cache=" + TemplateCache(), "--quiet"},
      TempPath("in-use-first.txt"));
  ASSERT_TRUE(WaitForLockHolder(out, first.pid())) << ReadFile(TempPath("in-use-first.txt"));
  const std::string expected =
      absl::StrCat(out, " is in use by another run (pid ", first.pid(), ")");
  const Result second = RunClient(absl::StrCat("run ", Quote(WriteCase("in-use", SmallCase())),
                                               " --out=", Quote(out), CommonFlags(), " --quiet"));
  EXPECT_EQ(second.exit_code, 1) << second;
  EXPECT_TRUE(absl::StrContains(second.err, expected)) << second;
  EXPECT_FALSE(absl::StrContains(second.err, "HDF5")) << second;
  // A checkpoint of the first run, resumed into its own directory.
  for (int i = 0; i < 600 && !fs::exists(out + "/checkpoint.h5"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(fs::exists(out + "/checkpoint.h5"));
  const Result resume =
      RunClient(absl::StrCat("resume ", Quote(out + "/checkpoint.h5"), CommonFlags(), " --quiet"));
  EXPECT_EQ(resume.exit_code, 1) << resume;
  EXPECT_TRUE(absl::StrContains(resume.err, expected)) << resume;
  ASSERT_TRUE(first.Running()) << "the first run ended: " << ReadFile(TempPath("in-use-first.txt"));
  EXPECT_EQ(Json::parse(ReadFile(out + "/run.json"), nullptr, false)["command"], "run");

  first.Kill();
  const Result after = RunClient(absl::StrCat("run ", Quote(TempPath("in-use.json")),
                                              " --out=", Quote(out), CommonFlags(), " --quiet"));
  EXPECT_EQ(after.exit_code, 0) << after;
}

// A file size limit (ulimit -f) reached by results.xdmf part way: the write
// fails (SIGXFSZ does not kill the client), the run ends with exit code 1
// and run.json "failed" with the error, and every frame before it reads back.
TEST(MpmCliOutputTest, AFileSizeLimitFailsTheRunAndKeepsTheFramesBefore) {
  const std::string out = TempPath("size-limit");
  // 60 blocks: 30 kB (dash's 512-byte blocks) or 60 kB (1 kB blocks), both
  // reached by results.xdmf between steps 8 and 25 of 35.
  const Result r = RunClientAfter("ulimit -f 60",
                                  absl::StrCat("run ", Quote(FrameEveryStepCase("size-limit", 0)),
                                               " --out=", Quote(out), CommonFlags(), " --quiet"));
  ASSERT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(r.err, "appending step")) << r;
  EXPECT_TRUE(absl::StrContains(Lower(r.err), "file too large")) << r;
  const Json record = Json::parse(ReadFile(out + "/run.json"), nullptr, false);
  ASSERT_TRUE(record.is_object()) << ReadFile(out + "/run.json");
  EXPECT_EQ(record["outcome"], "failed");
  EXPECT_TRUE(absl::StrContains(record.value("error", ""), "appending step")) << record.dump(2);
  const std::vector<std::int64_t> steps = ExpectReadableFrames(out);
  EXPECT_GE(steps.size(), 5u);
  EXPECT_LT(steps.size(), 36u);
}

// A tmpfs of `size` at `dir`, unmounted at destruction; mounted() false
// where this process may not mount one.
class SmallTmpfs {
 public:
  SmallTmpfs(const std::string& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, absl::StrCat("size=", size).c_str()) == 0;
    error_ = mounted_ ? "" : std::strerror(errno);
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }
  bool Resize(const std::string& size) {
    return ::mount("tmpfs", dir_.c_str(), "tmpfs", MS_REMOUNT,
                   absl::StrCat("size=", size).c_str()) == 0;
  }

 private:
  std::string dir_;
  bool mounted_ = false;
  std::string error_;
};

// A real full disk (ENOSPC) at step 20's checkpoint or a frame: the run
// fails with run.json saying so, the frames before read back, and once
// there is room a resume from the step-10 checkpoint finishes the run.
TEST(MpmCliOutputTest, AFullDiskFailsTheRunAndAResumeFinishesIt) {
  const std::string mount_point = TempPath("full-disk");
  // The step-10 checkpoint (~0.3 MB) and 10 frames fit; a second checkpoint
  // beside the first (written before the old one goes) does not.
  SmallTmpfs tmpfs(mount_point, "700k");
  if (!tmpfs.mounted()) {
    GTEST_SKIP() << "cannot mount a small tmpfs here (" << tmpfs.error()
                 << "); AFileSizeLimitFailsTheRunAndKeepsTheFramesBefore covers failed writes";
  }
  const std::string out = mount_point + "/out";
  const Result r = RunClient(absl::StrCat("run ", Quote(FrameEveryStepCase("full-disk", 10)),
                                          " --out=", Quote(out), CommonFlags(), " --quiet"));
  ASSERT_EQ(r.exit_code, 1) << r;
  EXPECT_TRUE(absl::StrContains(Lower(r.err), "no space left on device")) << r;
  const Json record = Json::parse(ReadFile(out + "/run.json"), nullptr, false);
  ASSERT_TRUE(record.is_object()) << ReadFile(out + "/run.json");
  EXPECT_EQ(record["outcome"], "failed");
  EXPECT_TRUE(absl::StrContains(Lower(record.value("error", "")), "no space left on device"))
      << record.dump(2);
  EXPECT_GE(ExpectReadableFrames(out).size(), 11u);
  ASSERT_TRUE(fs::exists(out + "/checkpoint.h5"));

  ASSERT_TRUE(tmpfs.Resize("16m"));
  const Result resumed =
      RunClient(absl::StrCat("resume ", Quote(out + "/checkpoint.h5"), CommonFlags(), " --quiet"));
  ASSERT_EQ(resumed.exit_code, 0) << resumed;
  EXPECT_EQ(ExpectReadableFrames(out).size(), 36u);
  const Json finished = Json::parse(ReadFile(out + "/run.json"), nullptr, false);
  ASSERT_TRUE(finished.is_object());
  EXPECT_EQ(finished["outcome"], "finished");
  EXPECT_EQ(finished["previous"][0]["outcome"], "failed");
}

}  // namespace
}  // namespace rvehub::mpm::cli_test
