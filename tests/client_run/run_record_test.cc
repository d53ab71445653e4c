// run.json: a run killed after a checkpoint still says how far it got, and a
// resume keeps that; on a disk that fills up during the run the final record
// still says "failed" (with the error), in the room its earlier writes
// reserved.
#include "client_run/run_record.h"

#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"

namespace rvehub::client_run {
namespace {

namespace fs = std::filesystem;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

RunRecord MakeRecord(const std::string& command) {
  std::vector<std::string> args = {"mpm_client", command, "x"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return RunRecord("mpm_client", "1.0", static_cast<int>(argv.size()), argv.data(), command);
}

// A run killed (no end written) after its checkpoint at step 20: its record
// has the checkpoint's step and wall time, and the resumed run keeps it.
TEST(RunRecordTest, AKilledRunKeepsItsLastCheckpoint) {
  const fs::path dir = fs::temp_directory_path() / absl::StrCat("run_record_kill_", ::getpid());
  fs::create_directories(dir);
  {
    RunRecord killed = MakeRecord("run");
    killed.Started(dir.string(), R"({"name": "killed"})", /*resumed=*/false);
    killed.Checkpointed(10, 1.25);
    killed.Checkpointed(20, 2.5);
  }
  const nlohmann::json r = nlohmann::json::parse(ReadFile((dir / "run.json").string()));
  EXPECT_EQ(r["outcome"], "running");
  EXPECT_TRUE(r["end"].is_null());
  ASSERT_TRUE(r.contains("last_checkpoint")) << r.dump(2);
  EXPECT_EQ(r["last_checkpoint"]["step"], 20);
  EXPECT_EQ(r["last_checkpoint"]["wall_s"], 2.5);
  EXPECT_EQ(r["last_checkpoint"]["at"].get<std::string>().size(), 24u);

  RunRecord resumed = MakeRecord("resume");
  resumed.Started(dir.string(), R"({"name": "killed"})", /*resumed=*/true);
  resumed.Finished("finished", {{"final_step", 30}, {"wall_s", 1.0}});
  const nlohmann::json after = nlohmann::json::parse(ReadFile((dir / "run.json").string()));
  EXPECT_EQ(after["outcome"], "finished");
  EXPECT_FALSE(after.contains("last_checkpoint"));
  ASSERT_TRUE(after.contains("previous")) << after.dump(2);
  ASSERT_EQ(after["previous"].size(), 1u);
  ASSERT_TRUE(after["previous"][0].contains("last_checkpoint")) << after.dump(2);
  EXPECT_EQ(after["previous"][0]["command"], "run");
  EXPECT_EQ(after["previous"][0]["last_checkpoint"], r["last_checkpoint"]);
  fs::remove_all(dir);
}

TEST(RunRecordTest, AFullDiskStillRecordsTheFailure) {
  const fs::path dir = fs::temp_directory_path() / absl::StrCat("run_record_test_", ::getpid());
  fs::create_directories(dir);
  if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=256k") != 0) {
    const std::string why = std::strerror(errno);
    fs::remove_all(dir);
    GTEST_SKIP() << "cannot mount a small tmpfs here (" << why << ")";
  }
  std::vector<std::string> args = {"mpm_client", "run", "case.json"};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  RunRecord record("mpm_client", "1.0", static_cast<int>(argv.size()), argv.data(), "run");
  record.Started(dir.string(), R"({"name": "full disk"})", /*resumed=*/false);
  ASSERT_EQ(nlohmann::json::parse(ReadFile((dir / "run.json").string()))["outcome"], "running");

  // Filled to the last byte.
  {
    std::FILE* filler = std::fopen((dir / "filler").c_str(), "wb");
    ASSERT_NE(filler, nullptr);
    const std::string block(4096, 'x');
    while (std::fwrite(block.data(), 1, block.size(), filler) == block.size() &&
           std::fflush(filler) == 0) {
    }
    std::fclose(filler);
    std::FILE* probe = std::fopen((dir / "probe").c_str(), "wb");
    ASSERT_NE(probe, nullptr);
    EXPECT_NE(std::fwrite(block.data(), 1, block.size(), probe) == block.size() &&
                  std::fflush(probe) == 0,
              true)
        << "the disk is not full";
    std::fclose(probe);
  }
  const std::string error =
      absl::StrCat("appending step 20 to out/results.h5: no space left on device (HDF5: ",
                   std::string(3000, 'e'), ")");
  record.Failed(error);
  const nlohmann::json r =
      nlohmann::json::parse(ReadFile((dir / "run.json").string()), nullptr, false);
  ASSERT_TRUE(r.is_object()) << ReadFile((dir / "run.json").string());
  EXPECT_EQ(r["outcome"], "failed");
  EXPECT_EQ(r["error"], error);
  EXPECT_EQ(r["case"]["name"], "full disk");
  EXPECT_FALSE(fs::exists(dir / "run.json.tmp"));

  ::umount2(dir.c_str(), MNT_DETACH);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rvehub::client_run
