// MPM results (results.h5 + results.xdmf), each frame a file of its own
// that results.h5 links: a results.h5 holding its frames itself (as written
// before frame files) is continued; and when the disk fills while a frame
// is written: the frames written before stay readable, the XDMF file lists
// only readable frames, and a resumed run continues the file. A full disk is
// simulated without privileges by RLIMIT_FSIZE in a forked child (write()
// then fails with EFBIG once a file would grow past the limit, SIGXFSZ
// ignored), at every point of a frame's write; and for real (ENOSPC) on a
// small tmpfs where this process may mount one.
#include <hdf5.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <system_error>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "store/results.h"
#include "tests/store/store_test_util.h"

namespace rvehub::store {
namespace {

namespace fs = std::filesystem;
using testing_util::MessageHas;
using testing_util::ReadBytes;
using testing_util::TestDirTest;

class ResultsFramesTest : public TestDirTest {
 protected:
  ResultsFramesTest() : TestDirTest("rvehub_results_frames_test_") {}
  void SetUp() override {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // the test's own HDF5 calls stay quiet
    TestDirTest::SetUp();
  }
};

// A frame of n points with a vector, a tensor and a scalar field (about
// 120·n bytes of data).
ResultFrame MakeFrame(std::int64_t step, std::size_t n) {
  ResultFrame f;
  f.step = step;
  f.time = 0.001 * static_cast<double>(step);
  ResultField velocity{"velocity", 2, {}}, stress{"stress", 9, {}}, p{"p", 1, {}};
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(i) + 0.01 * static_cast<double>(step);
    f.position.insert(f.position.end(), {x, -x / 3.0});
    velocity.values.insert(velocity.values.end(), {x, 1e-3 * x});
    for (int c = 0; c < 9; ++c) stress.values.push_back(-1e5 * (c + 1) + x);
    p.values.push_back(x * x);
  }
  f.fields = {velocity, stress, p};
  return f;
}

std::vector<std::int64_t> Steps(const std::vector<ResultFrame>& frames) {
  std::vector<std::int64_t> steps;
  for (const ResultFrame& f : frames) steps.push_back(f.step);
  return steps;
}

// The steps the XDMF file lists, in order.
std::vector<std::int64_t> XdmfSteps(const std::string& xml) {
  static const std::regex grid("<Grid Name=\"step_([0-9]+)\"");
  std::vector<std::int64_t> steps;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), grid); it != std::sregex_iterator();
       ++it) {
    steps.push_back(std::stoll((*it)[1]));
  }
  return steps;
}

// Every dataset the XDMF file names opens and reads through the HDF5 file
// it names (as ParaView reads it).
void ExpectXdmfReadable(const std::string& xdmf) {
  static const std::regex item("Format=\"HDF\">([^<:]+):([^<]+)</DataItem>");
  const std::string xml = ReadBytes(xdmf);
  const fs::path dir = fs::path(xdmf).parent_path();
  int items = 0;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), item); it != std::sregex_iterator();
       ++it, ++items) {
    const std::string file = (dir / (*it)[1].str()).string(), dataset = (*it)[2];
    SCOPED_TRACE(file + ":" + dataset);
    const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
    EXPECT_GE(d, 0);
    if (d >= 0) {
      const hid_t type = H5Dget_type(d);
      const hid_t space = H5Dget_space(d);
      std::vector<char> buffer(static_cast<std::size_t>(H5Sget_select_npoints(space)) *
                               H5Tget_size(type));
      EXPECT_GE(H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data()), 0);
      H5Sclose(space);
      H5Tclose(type);
      H5Dclose(d);
    }
    H5Fclose(f);
  }
  EXPECT_GT(items, 0);
}

// Appends `frame` in a forked child whose files may not grow past `limit`
// bytes; the child's exit code: 0 appended, 1 refused with a status.
int AppendInLimitedChild(ResultsWriter& writer, const ResultFrame& frame, rlim_t limit) {
  const pid_t child = ::fork();
  if (child == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    const rlimit rl{limit, limit};
    if (::setrlimit(RLIMIT_FSIZE, &rl) != 0) ::_exit(3);
    const absl::Status s = writer.Append(frame);
    ::_exit(s.ok() ? 0 : 1);
  }
  int status = 0;
  if (child < 0 || ::waitpid(child, &status, 0) != child) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::uint64_t TotalBytes(const fs::path& dir) {
  std::uint64_t total = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) total += e.file_size();
  }
  return total;
}

// Whatever byte a frame's write fails at, the frames before it survive: the
// failed Append reports it, ReadResults returns the earlier frames, the XDMF
// file lists just them, and a resumed writer appends again.
TEST_F(ResultsFramesTest, AFailedWriteAtAnyByteKeepsTheEarlierFrames) {
  constexpr std::size_t kPoints = 400;
  const ResultFrame next = MakeFrame(20, kPoints);
  // How many bytes a third frame adds, to spread the failure points over.
  std::uint64_t frame_bytes = 0;
  {
    const fs::path probe = dir_ / "probe";
    fs::create_directories(probe);
    auto writer = ResultsWriter::Create((probe / "results.h5").string(),
                                        (probe / "results.xdmf").string(), "test");
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (std::int64_t step : {0, 10}) ASSERT_TRUE((*writer)->Append(MakeFrame(step, kPoints)).ok());
    const std::uint64_t before = TotalBytes(probe);
    ASSERT_TRUE((*writer)->Append(next).ok());
    frame_bytes = TotalBytes(probe) - before;
    ASSERT_GT(frame_bytes, 0u);
  }
  const std::uint64_t two_frames = fs::file_size(dir_ / "probe" / "results.h5");
  int refused = 0;
  constexpr int kPointsTried = 48;
  for (int k = 0; k <= kPointsTried; ++k) {
    // From a tiny file through the size two frames and most of a third take.
    const rlim_t limit = 512 + (two_frames + frame_bytes) * k / kPointsTried;
    SCOPED_TRACE(absl::StrCat("file size limit ", limit, " bytes"));
    const fs::path run = dir_ / absl::StrCat("run", k);
    fs::create_directories(run);
    const std::string h5 = (run / "results.h5").string(), xdmf = (run / "results.xdmf").string();
    {
      auto writer = ResultsWriter::Create(h5, xdmf, "test");
      ASSERT_TRUE(writer.ok()) << writer.status();
      for (std::int64_t step : {0, 10}) {
        ASSERT_TRUE((*writer)->Append(MakeFrame(step, kPoints)).ok());
      }
      const int code = AppendInLimitedChild(**writer, next, limit);
      ASSERT_TRUE(code == 0 || code == 1) << "the writer's child ended with " << code;
      refused += code;
      absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
      ASSERT_TRUE(read.ok()) << read.status();
      const std::vector<std::int64_t> kept =
          code == 0 ? std::vector<std::int64_t>{0, 10, 20} : std::vector<std::int64_t>{0, 10};
      EXPECT_EQ(Steps(*read), kept);
      EXPECT_EQ(XdmfSteps(ReadBytes(xdmf)), kept);
      ExpectXdmfReadable(xdmf);
    }
    auto resumed = ResultsWriter::Open(h5, xdmf, "resumed", 10);
    ASSERT_TRUE(resumed.ok()) << resumed.status();
    EXPECT_EQ((*resumed)->num_frames(), 2u);
    ASSERT_TRUE((*resumed)->Append(next).ok());
    absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
    ASSERT_TRUE(read.ok()) << read.status();
    EXPECT_EQ(Steps(*read), (std::vector<std::int64_t>{0, 10, 20}));
    ExpectXdmfReadable(xdmf);
  }
  // Most limits fall inside the third frame.
  EXPECT_GT(refused, kPointsTried / 2);
}

// A mounted tmpfs of `size` bytes at `dir`, unmounted at destruction;
// mounted() false where this process may not mount.
class SmallTmpfs {
 public:
  SmallTmpfs(const fs::path& dir, std::size_t size) : dir_(dir) {
    fs::create_directories(dir_);
    const std::string options = absl::StrCat("size=", size);
    mounted_ = ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, options.c_str()) == 0;
    error_ = mounted_ ? 0 : errno;
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  std::string error() const { return std::strerror(error_); }

 private:
  fs::path dir_;
  bool mounted_ = false;
  int error_ = 0;
};

// A real full disk (ENOSPC): frames are appended until one fails; those
// before it read back, the XDMF file lists them, and once space is freed a
// resumed writer continues.
TEST_F(ResultsFramesTest, ARealFullDiskKeepsTheEarlierFrames) {
  SmallTmpfs tmpfs(dir_ / "small", 1 << 20);
  if (!tmpfs.mounted()) {
    GTEST_SKIP() << "cannot mount a 1 MiB tmpfs here (" << tmpfs.error()
                 << "); the RLIMIT_FSIZE test covers failed writes";
  }
  const std::string h5 = (dir_ / "small" / "results.h5").string();
  const std::string xdmf = (dir_ / "small" / "results.xdmf").string();
  std::vector<std::int64_t> written;
  absl::Status failed;
  {
    auto writer = ResultsWriter::Create(h5, xdmf, "test");
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (std::int64_t step = 0; step < 1000 && failed.ok(); step += 10) {
      failed = (*writer)->Append(MakeFrame(step, 300));
      if (failed.ok()) written.push_back(step);
    }
  }
  ASSERT_FALSE(failed.ok()) << "1 MiB did not fill up";
  EXPECT_TRUE(MessageHas(failed, "appending step")) << failed;
  EXPECT_EQ(failed.code(), absl::StatusCode::kResourceExhausted) << failed;
  EXPECT_TRUE(absl::StrContains(absl::AsciiStrToLower(failed.message()), "no space left on device"))
      << failed;
  ASSERT_GE(written.size(), 3u);
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(Steps(*read), written);
  EXPECT_EQ(XdmfSteps(ReadBytes(xdmf)), written);
  ExpectXdmfReadable(xdmf);

  // A resume from an earlier checkpoint drops the frames after it.
  written.resize(written.size() - 2);
  auto resumed = ResultsWriter::Open(h5, xdmf, "resumed", written.back());
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_EQ((*resumed)->num_frames(), written.size());
  read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(Steps(*read), written);
}

// A results.h5 that holds its frames itself (no frame files) is read, and a
// resumed writer moves the kept frames into frame files and continues.
TEST_F(ResultsFramesTest, FramesInsideResultsH5AreReadAndMovedOut) {
  const std::string h5 = Path("results.h5"), xdmf = Path("results.xdmf");
  std::vector<ResultFrame> frames = {MakeFrame(0, 7), MakeFrame(10, 7), MakeFrame(20, 7)};
  {
    auto writer = ResultsWriter::Create(h5, xdmf, "test");
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (const ResultFrame& f : frames) ASSERT_TRUE((*writer)->Append(f).ok());
  }
  // Every link replaced by the object it leads to; the frame files gone.
  {
    const hid_t file = H5Fopen(h5.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    std::vector<std::string> objects = {"/topology/polyvertex_7"};
    for (const ResultFrame& f : frames) objects.push_back(absl::StrCat("/frames/", f.step));
    for (const std::string& name : objects) {
      const hid_t target = H5Oopen(file, name.c_str(), H5P_DEFAULT);
      ASSERT_GE(target, 0) << name;
      const hid_t target_file = H5Iget_file_id(target);
      ASSERT_GE(H5Ldelete(file, name.c_str(), H5P_DEFAULT), 0);
      ASSERT_GE(H5Ocopy(target_file, name.c_str(), file, name.c_str(), H5P_DEFAULT, H5P_DEFAULT), 0)
          << name;
      H5Fclose(target_file);
      H5Oclose(target);
    }
    H5Fclose(file);
    fs::remove_all(dir_ / "results.frames");
  }
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(Steps(*read), (std::vector<std::int64_t>{0, 10, 20}));

  auto resumed = ResultsWriter::Open(h5, xdmf, "resumed", 10);
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_TRUE(fs::exists(dir_ / "results.frames" / "0.h5"));
  EXPECT_TRUE(fs::exists(dir_ / "results.frames" / "10.h5"));
  EXPECT_FALSE(fs::exists(dir_ / "results.frames" / "20.h5"));
  ASSERT_TRUE((*resumed)->Append(MakeFrame(30, 7)).ok());
  read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(Steps(*read), (std::vector<std::int64_t>{0, 10, 30}));
  EXPECT_EQ(read->at(1).position, frames[1].position);
  EXPECT_EQ(XdmfSteps(ReadBytes(xdmf)), (std::vector<std::int64_t>{0, 10, 30}));
  ExpectXdmfReadable(xdmf);
}

}  // namespace
}  // namespace rvehub::store
