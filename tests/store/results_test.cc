// MPM results (results.h5 + results.xdmf) and the whole-simulation
// checkpoint: bit-exact round trips, the XDMF text ParaView reads (every
// DataItem checked against the HDF5 file), resuming, refused input that
// leaves the files untouched, a writer killed mid-frame, and every way a
// checkpoint can be missing, malformed or corrupt.
#include "store/results.h"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"
#include "store/sim_checkpoint.h"
#include "tests/store/store_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::store {
namespace {

namespace fs = std::filesystem;
using ::rvehub::dem::testing_util::ExpectIdenticalPackings;
using ::rvehub::dem::testing_util::Prepared;
using ::rvehub::dem::testing_util::SameBits;
using ::rvehub::dem::testing_util::SquareLattice;
using testing_util::AwkwardValues;
using testing_util::ChunkLocation;
using testing_util::FilesStartingWith;
using testing_util::FlipByte;
using testing_util::FromBits;
using testing_util::MessageHas;
using testing_util::ReadBytes;
using testing_util::ReplaceDoubleDataset;
using testing_util::ReplaceInt64Dataset;
using testing_util::SetIntAttribute;
using testing_util::TestDirTest;
using testing_util::WriteBytes;

void DeleteObject(const std::string& path, const char* name) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  EXPECT_GE(H5Ldelete(file, name, H5P_DEFAULT), 0);
  H5Fclose(file);
}

class StoreFilesTest : public TestDirTest {
 protected:
  StoreFilesTest() : TestDirTest("rvehub_results_test_") {}
  void SetUp() override {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // the test's own HDF5 calls stay quiet
    TestDirTest::SetUp();
  }
};

// ============================================================================
// Results

// Frame `k` of 5 points: every component count, awkward values.
ResultFrame MakeFrame(std::int64_t step, double time, int k, std::size_t n = 5) {
  const std::vector<double>& awkward = AwkwardValues();
  ResultFrame f;
  f.step = step;
  f.time = time;
  ResultField velocity{"velocity", 2, {}}, stress{"stress", 9, {}}, p{"p", 1, {}},
      spin{"spin.axis-3", 3, {}}, id{"rve_id", 1, {}};
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(i) + 0.1 * k;
    f.position.insert(f.position.end(), {x, -x / 3.0});
    velocity.values.insert(velocity.values.end(), {awkward[(i + k) % awkward.size()], 1e-3 * x});
    for (int c = 0; c < 9; ++c) stress.values.push_back(-1e5 * (c + 1) + x);
    p.values.push_back(awkward[(i + 2 * k) % awkward.size()]);
    spin.values.insert(spin.values.end(), {x, -0.0, std::nextafter(x, 100.0)});
    id.values.push_back(static_cast<double>(i));
  }
  f.fields = {velocity, stress, p, spin, id};
  return f;
}

void ExpectSameFrames(const std::vector<ResultFrame>& a, const std::vector<ResultFrame>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    SCOPED_TRACE(absl::StrCat("frame ", k));
    EXPECT_EQ(a[k].step, b[k].step);
    EXPECT_TRUE(SameBits(a[k].time, b[k].time));
    EXPECT_TRUE(SameBits(a[k].position, b[k].position));
    ASSERT_EQ(a[k].fields.size(), b[k].fields.size());
    for (std::size_t f = 0; f < a[k].fields.size(); ++f) {
      EXPECT_EQ(a[k].fields[f].name, b[k].fields[f].name);
      EXPECT_EQ(a[k].fields[f].components, b[k].fields[f].components);
      EXPECT_TRUE(SameBits(a[k].fields[f].values, b[k].fields[f].values)) << a[k].fields[f].name;
    }
  }
}

// One <DataItem> of the XDMF text.
struct DataItem {
  std::string dimensions, type, file, dataset;
};

std::vector<DataItem> DataItems(const std::string& xml) {
  static const std::regex item(
      "<DataItem Dimensions=\"([0-9 ]+)\" DataType=\"(\\w+)\" Precision=\"8\" "
      "Format=\"HDF\">([^<:]+):([^<]+)</DataItem>");
  std::vector<DataItem> items;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), item); it != std::sregex_iterator();
       ++it) {
    items.push_back({(*it)[1], (*it)[2], (*it)[3], (*it)[4]});
  }
  return items;
}

// Every DataItem names an existing dataset of the referenced file with
// exactly the stated dimensions and element type.
void ExpectDataItemsMatchFile(const std::string& xml, const fs::path& xdmf_dir) {
  const std::vector<DataItem> items = DataItems(xml);
  ASSERT_FALSE(items.empty());
  for (const DataItem& d : items) {
    SCOPED_TRACE(d.file + ":" + d.dataset);
    const hid_t file = H5Fopen((xdmf_dir / d.file).c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t dset = H5Dopen2(file, d.dataset.c_str(), H5P_DEFAULT);
    ASSERT_GE(dset, 0);
    const hid_t space = H5Dget_space(dset);
    hsize_t dims[2] = {0, 0};
    const int rank = H5Sget_simple_extent_dims(space, dims, nullptr);
    std::string expected = absl::StrCat(dims[0]);
    if (rank == 2) absl::StrAppend(&expected, " ", dims[1]);
    EXPECT_EQ(d.dimensions, expected);
    const hid_t type = H5Dget_type(dset);
    EXPECT_GT(H5Tequal(type, d.type == "Float" ? H5T_IEEE_F64LE : H5T_STD_I64LE), 0) << d.type;
    H5Tclose(type);
    H5Sclose(space);
    H5Dclose(dset);
    H5Fclose(file);
  }
}

// The values of <Time Value="…"/>, in order.
std::vector<std::string> Times(const std::string& xml) {
  static const std::regex time("<Time Value=\"([^\"]+)\"/>");
  std::vector<std::string> values;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), time); it != std::sregex_iterator();
       ++it) {
    values.push_back((*it)[1]);
  }
  return values;
}

bool HaveXmllint() { return std::system("command -v xmllint >/dev/null 2>&1") == 0; }

// xmllint --noout: the XDMF text is well-formed XML (skipped without xmllint).
void ExpectWellFormed(const std::string& path) {
  if (!HaveXmllint()) return;
  EXPECT_EQ(std::system(absl::StrCat("xmllint --noout '", path, "'").c_str()), 0) << path;
}

TEST_F(StoreFilesTest, ResultsRoundTripBitExactly) {
  const std::vector<ResultFrame> frames = {MakeFrame(0, 0.0, 0), MakeFrame(10, 1e-3, 1),
                                           MakeFrame(25, std::nextafter(2.5e-3, 1.0), 2)};
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(Path("results.h5"), Path("results.xdmf"), "results_test 1.0");
  ASSERT_TRUE(writer.ok()) << writer.status();
  for (const ResultFrame& f : frames) ASSERT_TRUE((*writer)->Append(f).ok());
  EXPECT_EQ((*writer)->num_frames(), 3u);
  // Valid after every frame: readable while the writer is still alive.
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(Path("results.h5"));
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames(frames, *read);
  ASSERT_TRUE((*writer)->Close().ok());
  EXPECT_EQ((*writer)->Append(MakeFrame(30, 1.0, 3)).code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_TRUE(FilesStartingWith(dir_, "results.xdmf.tmp").empty());

  // The file's attributes, through the store's reader of root attributes.
  EXPECT_EQ(ReadRves(Path("results.h5")).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(MessageHas(ReadRves(Path("results.h5")).status(), "read it with ReadResults"));
}

TEST_F(StoreFilesTest, XdmfListsEveryFrameWithTimesPathsAndTypes) {
  const std::string xdmf = Path("results.xdmf");
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(Path("results.h5"), xdmf, "results_test");
  ASSERT_TRUE(writer.ok()) << writer.status();
  std::string xml = ReadBytes(xdmf);
  EXPECT_TRUE(absl::StrContains(xml, "CollectionType=\"Temporal\"")) << xml;
  EXPECT_TRUE(Times(xml).empty());
  ExpectWellFormed(xdmf);

  const double times[] = {0.0, 1e-3, 0.1 + 0.2};
  const std::int64_t steps[] = {0, 10, 20};
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE((*writer)->Append(MakeFrame(steps[k], times[k], k)).ok());
    xml = ReadBytes(xdmf);
    EXPECT_EQ(Times(xml).size(), static_cast<std::size_t>(k + 1)) << "after frame " << k;
  }
  ExpectWellFormed(xdmf);
  const std::vector<std::string> values = Times(xml);
  ASSERT_EQ(values.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(SameBits(std::strtod(values[k].c_str(), nullptr), times[k])) << values[k];
  }
  EXPECT_EQ(values[1], "0.001");
  EXPECT_EQ(values[2], "0.30000000000000004");

  for (const char* part : {
           "<Grid Name=\"step_0\" GridType=\"Uniform\">",
           "<Grid Name=\"step_20\" GridType=\"Uniform\">",
           "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"5\" NodesPerElement=\"1\">",
           "<Geometry GeometryType=\"XYZ\">",
           ">results.h5:/frames/10/position</DataItem>",
           "<Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n"
           "          <DataItem Dimensions=\"5 3\" DataType=\"Float\" Precision=\"8\" "
           "Format=\"HDF\">results.h5:/frames/20/velocity</DataItem>",
           "<Attribute Name=\"stress\" AttributeType=\"Tensor\" Center=\"Node\">\n"
           "          <DataItem Dimensions=\"5 9\" DataType=\"Float\" Precision=\"8\" "
           "Format=\"HDF\">results.h5:/frames/0/stress</DataItem>",
           "<Attribute Name=\"p\" AttributeType=\"Scalar\" Center=\"Node\">\n"
           "          <DataItem Dimensions=\"5\" DataType=\"Float\" Precision=\"8\" "
           "Format=\"HDF\">results.h5:/frames/10/p</DataItem>",
           "<Attribute Name=\"spin.axis-3\" AttributeType=\"Vector\"",
       }) {
    EXPECT_TRUE(absl::StrContains(xml, part)) << part << "\nnot in:\n" << xml;
  }
  // 3 frames × (topology, geometry, 5 fields).
  EXPECT_EQ(DataItems(xml).size(), 3u * 7u);
  ExpectDataItemsMatchFile(xml, dir_);
}

TEST_F(StoreFilesTest, XdmfRefersToTheHdf5FileRelatively) {
  fs::create_directories(dir_ / "data");
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(Path("data/run 1.h5"), Path("view.xdmf"), "results_test");
  ASSERT_TRUE(writer.ok()) << writer.status();
  ASSERT_TRUE((*writer)->Append(MakeFrame(1, 0.5, 0)).ok());
  const std::string xml = ReadBytes(Path("view.xdmf"));
  EXPECT_TRUE(absl::StrContains(xml, ">data/run 1.h5:/frames/1/stress<")) << xml;
  ExpectDataItemsMatchFile(xml, dir_);

  EXPECT_EQ(ResultsWriter::Create(Path("a.h5"), Path("a.h5"), "x").status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ResultsWriter::Create(Path("a:b.h5"), Path("a.xdmf"), "x").status().code(),
            absl::StatusCode::kInvalidArgument);
  absl::StatusOr<std::unique_ptr<ResultsWriter>> missing =
      ResultsWriter::Create(Path("no/such/dir/r.h5"), Path("r.xdmf"), "x");
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound) << missing.status();
}

TEST_F(StoreFilesTest, OpenKeepsFramesThroughStepAndContinues) {
  const std::string h5 = Path("results.h5"), xdmf = Path("results.xdmf");
  std::vector<ResultFrame> frames = {MakeFrame(0, 0.0, 0), MakeFrame(10, 0.1, 1),
                                     MakeFrame(20, 0.2, 2), MakeFrame(30, 0.3, 3)};
  {
    absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
        ResultsWriter::Create(h5, xdmf, "first run");
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (const ResultFrame& f : frames) ASSERT_TRUE((*writer)->Append(f).ok());
    // Dropped without Close, as a killed run would leave it.
  }
  // Resumed from a checkpoint at step 15: frames 20 and 30 are rewritten.
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Open(h5, xdmf, "resumed run", 15);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ((*writer)->num_frames(), 2u);
  std::string xml = ReadBytes(xdmf);
  EXPECT_EQ(Times(xml), (std::vector<std::string>{"0", "0.1"}));
  EXPECT_FALSE(absl::StrContains(xml, "/frames/20/"));
  ExpectDataItemsMatchFile(xml, dir_);
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames({frames[0], frames[1]}, *read);

  EXPECT_EQ((*writer)->Append(MakeFrame(10, 0.1, 9)).code(), absl::StatusCode::kInvalidArgument);
  frames[2] = MakeFrame(20, 0.2, 7);  // different values this time
  frames[3] = MakeFrame(25, 0.25, 8);
  ASSERT_TRUE((*writer)->Append(frames[2]).ok());
  ASSERT_TRUE((*writer)->Append(frames[3]).ok());
  ASSERT_TRUE((*writer)->Close().ok());
  read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames(frames, *read);
  xml = ReadBytes(xdmf);
  EXPECT_EQ(Times(xml), (std::vector<std::string>{"0", "0.1", "0.2", "0.25"}));
  ExpectDataItemsMatchFile(xml, dir_);
  ExpectWellFormed(xdmf);

  // Keeping nothing; keeping everything.
  writer = ResultsWriter::Open(h5, xdmf, "again", 1000);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ((*writer)->num_frames(), 4u);
  writer = ResultsWriter::Open(h5, xdmf, "again", -1);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_EQ((*writer)->num_frames(), 0u);
  EXPECT_TRUE(Times(ReadBytes(xdmf)).empty());
  read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_TRUE(read->empty());

  // Not a results file.
  EXPECT_EQ(ResultsWriter::Open(Path("none.h5"), xdmf, "x", 0).status().code(),
            absl::StatusCode::kNotFound);
  ASSERT_TRUE(WriteRves(Path("rves.h5"), {}, {}).ok());
  absl::StatusOr<std::unique_ptr<ResultsWriter>> wrong =
      ResultsWriter::Open(Path("rves.h5"), xdmf, "x", 0);
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kInvalidArgument) << wrong.status();
}

TEST_F(StoreFilesTest, BadFramesAreRefusedAndNothingIsWritten) {
  const std::string h5 = Path("results.h5"), xdmf = Path("results.xdmf");
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(h5, xdmf, "results_test");
  ASSERT_TRUE(writer.ok()) << writer.status();
  ASSERT_TRUE((*writer)->Append(MakeFrame(10, 1.0, 0)).ok());
  const std::string h5_before = ReadBytes(h5), xdmf_before = ReadBytes(xdmf);

  auto expect_refused = [&](const char* what, const ResultFrame& f, absl::string_view part) {
    const absl::Status s = (*writer)->Append(f);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << what << ": " << s;
    EXPECT_TRUE(MessageHas(s, part)) << what;
  };
  ResultFrame f = MakeFrame(20, 2.0, 1);
  f.position.pop_back();
  expect_refused("odd position", f, "position has 9 values");
  f = MakeFrame(20, 2.0, 1);
  f.fields[1].values.pop_back();
  expect_refused("short field", f, "field 'stress' has 44 values; need 5 points × 9");
  f = MakeFrame(20, 2.0, 1);
  f.fields[0].components = 4;
  f.fields[0].values.resize(20);
  expect_refused("4 components", f, "4 components");
  f = MakeFrame(20, 2.0, 1);
  f.fields[2].components = 0;
  f.fields[2].values.clear();
  expect_refused("0 components", f, "0 components");
  expect_refused("same step", MakeFrame(10, 2.0, 1), "the last frame is step 10");
  expect_refused("earlier step", MakeFrame(5, 2.0, 1), "steps must increase");
  expect_refused("NaN time", MakeFrame(20, std::nan(""), 1), "time is nan");
  for (const char* name : {"", "a/b", "a b", ".hidden", "position", "x<y"}) {
    f = MakeFrame(20, 2.0, 1);
    f.fields[2].name = name;
    expect_refused(name, f, "field name");
  }
  f = MakeFrame(20, 2.0, 1);
  f.fields[4].name = "p";
  expect_refused("duplicate", f, "field 'p' twice");

  EXPECT_TRUE(ReadBytes(h5) == h5_before) << "the HDF5 file changed";
  EXPECT_EQ(ReadBytes(xdmf), xdmf_before);
  EXPECT_EQ((*writer)->num_frames(), 1u);
  // And the writer goes on.
  ASSERT_TRUE((*writer)->Append(MakeFrame(20, 2.0, 1)).ok());
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames({MakeFrame(10, 1.0, 0), MakeFrame(20, 2.0, 1)}, *read);
}

TEST_F(StoreFilesTest, FramesWithoutFieldsOrPoints) {
  const std::string h5 = Path("results.h5");
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(h5, Path("results.xdmf"), "results_test");
  ASSERT_TRUE(writer.ok()) << writer.status();
  ResultFrame bare = MakeFrame(1, 0.0, 0);
  bare.fields.clear();
  ResultFrame empty = MakeFrame(2, 1.0, 0, 0);
  ResultFrame more = MakeFrame(3, 2.0, 0, 12);  // a different point count
  for (const ResultFrame* f : {&bare, &empty, &more}) ASSERT_TRUE((*writer)->Append(*f).ok());
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames({bare, empty, more}, *read);
  ExpectDataItemsMatchFile(ReadBytes(Path("results.xdmf")), dir_);
}

// A writer killed in the middle of a frame: the files stay readable (HDF5
// opens the file; the XDMF file lists the complete frames), ReadResults
// names the incomplete frame, and a resumed run drops it.
TEST_F(StoreFilesTest, WriterKilledMidFrame) {
  const std::string h5 = Path("results.h5"), xdmf = Path("results.xdmf");
  const std::vector<ResultFrame> frames = {MakeFrame(0, 0.0, 0), MakeFrame(10, 1.0, 1)};
  {
    absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
        ResultsWriter::Create(h5, xdmf, "results_test");
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (const ResultFrame& f : frames) ASSERT_TRUE((*writer)->Append(f).ok());
  }
  const std::string xdmf_before = ReadBytes(xdmf);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // As the writer does, up to half a frame, then killed (no close).
    const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
    H5Pset_libver_bounds(fapl, H5F_LIBVER_V18, H5F_LIBVER_V110);
    const hid_t file = H5Fopen(h5.c_str(), H5F_ACC_RDWR, fapl);
    if (file < 0) ::_exit(1);
    const hid_t group = H5Gcreate2(file, "/frames/20", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t dims[2] = {5, 3};
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t dset =
        H5Dcreate2(group, "position", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (group < 0 || dset < 0 || H5Fflush(file, H5F_SCOPE_GLOBAL) < 0) ::_exit(2);
    ::kill(::getpid(), SIGKILL);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "child exit status " << WEXITSTATUS(status);

  EXPECT_EQ(ReadBytes(xdmf), xdmf_before);
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "frame /frames/20 of " + h5 + " is incomplete"));

  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Open(h5, xdmf, "resumed", 10);
  ASSERT_TRUE(writer.ok()) << writer.status();
  ASSERT_TRUE((*writer)->Append(MakeFrame(20, 2.0, 2)).ok());
  read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameFrames({frames[0], frames[1], MakeFrame(20, 2.0, 2)}, *read);
}

// A reader holding HDF5's lock (flock) of results.h5 neither delays nor
// fails the writer (which replaces the file rather than writing it), and
// keeps reading what it opened.
TEST_F(StoreFilesTest, AppendDoesNotWaitForAReaderLock) {
  const std::string h5 = Path("results.h5");
  absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
      ResultsWriter::Create(h5, Path("results.xdmf"), "results_test");
  ASSERT_TRUE(writer.ok()) << writer.status();
  const int fd = ::open(h5.c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_SH | LOCK_NB), 0);
  const auto start = std::chrono::steady_clock::now();
  const absl::Status s = (*writer)->Append(MakeFrame(1, 0.0, 0));
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ::close(fd);
  ASSERT_TRUE(s.ok()) << s;
  EXPECT_LT(waited, 5.0) << "the append waited for the reader's lock";
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->size(), 1u);
}

TEST_F(StoreFilesTest, CorruptOrTruncatedResultsAreDataLoss) {
  const std::string h5 = Path("results.h5");
  {
    absl::StatusOr<std::unique_ptr<ResultsWriter>> writer =
        ResultsWriter::Create(h5, Path("results.xdmf"), "results_test");
    ASSERT_TRUE(writer.ok()) << writer.status();
    ASSERT_TRUE((*writer)->Append(MakeFrame(0, 0.0, 0, 3000)).ok());
    ASSERT_TRUE((*writer)->Append(MakeFrame(10, 1.0, 1, 3000)).ok());
  }
  // Each frame is a file of its own beside results.h5, which links it.
  const std::string frame = Path("results.frames/10.h5");
  const std::string good_frame = ReadBytes(frame);
  haddr_t addr = 0;
  hsize_t size = 0;
  ChunkLocation(frame, "/frames/10/stress", 0, &addr, &size);
  ASSERT_GT(size, 1000u);
  FlipByte(frame, addr + size / 2);
  absl::StatusOr<std::vector<ResultFrame>> read = ReadResults(h5);
  EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(read.status(),
                         "checksum mismatch (fletcher32) in dataset "
                         "/frames/10/stress of " +
                             h5));

  for (std::size_t keep : {good_frame.size() - 1, good_frame.size() / 2, std::size_t{0}}) {
    WriteBytes(frame, good_frame.substr(0, keep));
    read = ReadResults(h5);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << "kept " << keep << " bytes: " << read.status();
    EXPECT_TRUE(
        MessageHas(read.status(), "frame /frames/10 of " + h5 + " is unreadable: its file"));
  }
  fs::remove(frame);
  read = ReadResults(h5);
  EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "frame /frames/10 of " + h5 + " is missing: its file"));
  EXPECT_TRUE(MessageHas(read.status(), "10.h5 does not exist"));

  const std::string good = ReadBytes(h5);
  for (std::size_t keep : {good.size() - 1, good.size() / 2, std::size_t{100}, std::size_t{0}}) {
    WriteBytes(h5, good.substr(0, keep));
    read = ReadResults(h5);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << "kept " << keep << " bytes: " << read.status();
  }
  EXPECT_EQ(ReadResults(Path("none.h5")).status().code(), absl::StatusCode::kNotFound);
}

// ============================================================================
// Simulation checkpoint

RveRecord MakeRecord(std::int64_t id, dem::RveSnapshot packing) {
  RveRecord r;
  r.run_id = "run-sim";
  r.id = id;
  r.step = 40 + id;
  r.last_delta_f << 1.0 + 1e-4 * id, -0.0, 0.0, 2.5e-5, 1.0 - 3e-5, 0.0, 0.0, 0.0, 1.0;
  r.packing = std::move(packing);
  return r;
}

// A small packing with contact history (fast to build, unlike Prepared).
dem::RveSnapshot Lattice(double salt) {
  dem::RveSnapshot p = SquareLattice(3, 0.02, [&](int x, int y) { return 0.009 + 1e-4 * (x + y); });
  p.material.name = absl::StrCat("lattice ", salt);
  dem::ContactHistory c;
  c.i = 0;
  c.j = 1;
  c.tangential_force = -0.0;
  c.rolling_moment = FromBits(0x7ff8000000000777ull);
  c.bond_strength = salt;
  p.contacts.push_back(c);
  p.vx[2] = std::numeric_limits<double>::denorm_min();
  return p;
}

SimCheckpoint MakeCheckpoint() {
  SimCheckpoint c;
  c.case_json = "{\n  \"name\": \"footing \xc3\xa9\",\n  \"solver\": {\"dt\": 1e-05}\n}\n";
  c.run_id = "footing-20261122-1234";
  c.step = 123456;
  c.time = std::nextafter(1.23456, 2.0);
  c.doubles["x"] = AwkwardValues();
  c.doubles["solver/F with spaces"] = {1.0, -0.0, 0.0, 1.0};
  c.doubles["empty"] = {};
  std::vector<double>& big = c.doubles["big"];
  for (int i = 0; i < 20000; ++i) big.push_back(std::sin(i) * 1e-3);
  c.ints["ids"] = {std::numeric_limits<std::int64_t>::min(), -1, 0,
                   std::numeric_limits<std::int64_t>::max()};
  c.ints["none"] = {};
  c.rves.push_back(MakeRecord(3, Prepared("SET-dense")));
  c.rves.push_back(MakeRecord(7, Lattice(1.0)));
  c.rves.push_back(MakeRecord(1000, Lattice(2.0)));
  TemplateRecord t;
  t.name = "SET-dense";
  t.description = "PreparePacking(SET-dense, seed 1)";
  t.packing = Prepared("SET-dense");
  c.templates.push_back(std::move(t));
  return c;
}

void ExpectSameCheckpoints(const SimCheckpoint& a, const SimCheckpoint& b) {
  EXPECT_EQ(a.case_json, b.case_json);
  EXPECT_EQ(a.run_id, b.run_id);
  EXPECT_EQ(a.step, b.step);
  EXPECT_TRUE(SameBits(a.time, b.time));
  ASSERT_EQ(a.doubles.size(), b.doubles.size());
  for (const auto& [name, values] : a.doubles) {
    ASSERT_TRUE(b.doubles.count(name)) << name;
    EXPECT_TRUE(SameBits(values, b.doubles.at(name))) << name;
  }
  EXPECT_EQ(a.ints, b.ints);
  ASSERT_EQ(a.rves.size(), b.rves.size());
  for (std::size_t k = 0; k < a.rves.size(); ++k) {
    SCOPED_TRACE(absl::StrCat("rve ", k));
    EXPECT_EQ(a.rves[k].run_id, b.rves[k].run_id);
    EXPECT_EQ(a.rves[k].id, b.rves[k].id);
    EXPECT_EQ(a.rves[k].step, b.rves[k].step);
    EXPECT_TRUE(SameBits(a.rves[k].last_delta_f, b.rves[k].last_delta_f));
    ExpectIdenticalPackings(a.rves[k].packing, b.rves[k].packing);
  }
  ASSERT_EQ(a.templates.size(), b.templates.size());
  for (std::size_t k = 0; k < a.templates.size(); ++k) {
    EXPECT_EQ(a.templates[k].name, b.templates[k].name);
    EXPECT_EQ(a.templates[k].description, b.templates[k].description);
    ExpectIdenticalPackings(a.templates[k].packing, b.templates[k].packing, a.templates[k].name);
  }
}

const FileInfo kInfo{"results_test 1.0", "2026-11-22T10:00:00Z"};

TEST_F(StoreFilesTest, SimCheckpointRoundTripsBitExactly) {
  const SimCheckpoint c = MakeCheckpoint();
  const std::string path = Path("checkpoint.h5");
  ASSERT_TRUE(WriteSimCheckpoint(path, c, kInfo).ok());
  FileInfo info;
  absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path, &info);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameCheckpoints(c, *read);
  EXPECT_EQ(info.created_by, kInfo.created_by);
  EXPECT_EQ(info.created_at, kInfo.created_at);
  EXPECT_EQ(info.format_version, kFormatVersion);
  EXPECT_TRUE(FilesStartingWith(dir_, "checkpoint.h5.tmp").empty());

  // Overwritten atomically by the next checkpoint; an empty one round-trips.
  ASSERT_TRUE(WriteSimCheckpoint(path, SimCheckpoint{}, {}).ok());
  read = ReadSimCheckpoint(path, &info);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameCheckpoints(SimCheckpoint{}, *read);
  EXPECT_EQ(info.created_at.size(), 20u) << info.created_at;
}

TEST_F(StoreFilesTest, SimCheckpointKindsDoNotMix) {
  const std::string sim = Path("checkpoint.h5"), rves = Path("rves.h5");
  ASSERT_TRUE(WriteSimCheckpoint(sim, MakeCheckpoint(), kInfo).ok());
  ASSERT_TRUE(WriteRves(rves, MakeCheckpoint().rves, kInfo).ok());

  absl::StatusOr<std::vector<RveRecord>> as_rves = ReadRves(sim);
  EXPECT_EQ(as_rves.status().code(), absl::StatusCode::kInvalidArgument) << as_rves.status();
  EXPECT_TRUE(MessageHas(as_rves.status(),
                         "'simulation', not 'rves': read it with "
                         "ReadSimCheckpoint"));
  EXPECT_EQ(ReadTemplates(sim).status().code(), absl::StatusCode::kInvalidArgument);
  absl::StatusOr<SimCheckpoint> as_sim = ReadSimCheckpoint(rves);
  EXPECT_EQ(as_sim.status().code(), absl::StatusCode::kInvalidArgument) << as_sim.status();
  EXPECT_TRUE(MessageHas(as_sim.status(), "'rves', not 'simulation': read it with ReadRves"));
  EXPECT_EQ(ReadSimCheckpoint(Path("results.h5")).status().code(), absl::StatusCode::kNotFound);
  ASSERT_TRUE(ResultsWriter::Create(Path("results.h5"), Path("results.xdmf"), "x").ok());
  EXPECT_TRUE(MessageHas(ReadSimCheckpoint(Path("results.h5")).status(), "ReadResults"));
}

TEST_F(StoreFilesTest, SimCheckpointCorruptionIsDataLossNamingTheDataset) {
  const std::string path = Path("checkpoint.h5");
  ASSERT_TRUE(WriteSimCheckpoint(path, MakeCheckpoint(), kInfo).ok());
  const std::string good = ReadBytes(path);
  for (const char* dataset : {"/mpm/doubles/values", "/rves/particles/sx"}) {
    WriteBytes(path, good);
    haddr_t addr = 0;
    hsize_t size = 0;
    ChunkLocation(path, dataset, 0, &addr, &size);
    ASSERT_GT(size, 1000u) << dataset;
    FlipByte(path, addr + size / 2);
    absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
    EXPECT_TRUE(MessageHas(read.status(), absl::StrCat("checksum mismatch (fletcher32) in dataset ",
                                                       dataset, " of ", path)));
  }
  for (std::size_t keep : {good.size() - 1, good.size() / 2, std::size_t{100}, std::size_t{0}}) {
    WriteBytes(path, good.substr(0, keep));
    absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << "kept " << keep << " bytes: " << read.status();
  }
  EXPECT_EQ(ReadSimCheckpoint(Path("none.h5")).status().code(), absl::StatusCode::kNotFound);
}

TEST_F(StoreFilesTest, MalformedSimCheckpointsGiveSpecificErrors) {
  const SimCheckpoint c = MakeCheckpoint();
  const std::string path = Path("checkpoint.h5");
  ASSERT_TRUE(WriteSimCheckpoint(path, c, kInfo).ok());
  const std::string good = ReadBytes(path);
  auto expect = [&](const char* what, absl::StatusCode code, const std::string& part) {
    absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path);
    EXPECT_EQ(read.status().code(), code) << what << ": " << read.status();
    EXPECT_TRUE(MessageHas(read.status(), part)) << what;
    WriteBytes(path, good);
  };

  SetIntAttribute(path, "format_version", kFormatVersion + 1);
  expect("newer version", absl::StatusCode::kFailedPrecondition,
         absl::StrCat("format_version ", kFormatVersion + 1, ", newer than this build reads"));
  SetIntAttribute(path, "format_version", 0);
  expect("version 0", absl::StatusCode::kDataLoss, "invalid format_version 0");

  for (const char* dataset : {"/simulation/time", "/simulation/case_json", "/mpm/ints/values",
                              "/rves/particles/omega", "/templates/records/name"}) {
    DeleteObject(path, dataset);
    expect(dataset, absl::StatusCode::kDataLoss, absl::StrCat("missing dataset ", dataset));
  }
  ReplaceInt64Dataset(path, "/mpm/ints/offset", {0, 1});
  expect("wrong shape", absl::StatusCode::kDataLoss,
         "dataset /mpm/ints/offset of " + path + " has shape [2]; expected [3]");
  ReplaceInt64Dataset(path, "/mpm/ints/offset", {0, 4, 3});
  expect("decreasing offsets", absl::StatusCode::kDataLoss,
         "dataset /mpm/ints/offset of " + path + " decreases at entry 2");
  ReplaceInt64Dataset(path, "/simulation/time", {0});
  expect("wrong type", absl::StatusCode::kDataLoss, "unexpected element type");
  ReplaceInt64Dataset(path, "/rves/records/id", {3, 7, 7});
  expect("unsorted ids", absl::StatusCode::kDataLoss, "not strictly increasing at entry 2");
  SetIntAttribute(path, "num_rves", 2);
  expect("wrong count", absl::StatusCode::kDataLoss, "/rves/records/run_id");
  SetIntAttribute(path, "num_double_arrays", -1);
  expect("negative count", absl::StatusCode::kDataLoss, "invalid num_double_arrays -1");
}

// A step or time no run can have (tampered with, or corrupt) is refused on
// reading, naming the file, the dataset and the value.
TEST_F(StoreFilesTest, SimCheckpointStepAndTimeOutOfRangeAreDataLoss) {
  const std::string path = Path("checkpoint.h5");
  const std::string nan = absl::StrCat(std::numeric_limits<double>::quiet_NaN());
  struct Case {
    std::vector<std::int64_t> step;
    std::vector<double> time;
    std::string message;
  };
  for (const Case& c : {
           Case{{-1}, {}, "/simulation/step = -1 must lie in 0..9007199254740992"},
           Case{{std::int64_t{1} << 62}, {}, "/simulation/step = 4611686018427387904 must lie"},
           Case{{}, {std::numeric_limits<double>::quiet_NaN()}, "/simulation/time = " + nan},
           Case{{}, {std::numeric_limits<double>::infinity()}, "/simulation/time = inf s"},
           Case{{}, {-1.0}, "/simulation/time = -1 s must be finite and >= 0"},
       }) {
    ASSERT_TRUE(WriteSimCheckpoint(path, MakeCheckpoint(), kInfo).ok());
    if (!c.step.empty()) ReplaceInt64Dataset(path, "/simulation/step", c.step);
    if (!c.time.empty()) ReplaceDoubleDataset(path, "/simulation/time", c.time);
    const absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << c.message << ": " << read.status();
    EXPECT_TRUE(MessageHas(read.status(), c.message));
    EXPECT_TRUE(MessageHas(read.status(), path));
  }
  // The largest step and a zero time are a run's.
  SimCheckpoint edge = MakeCheckpoint();
  edge.step = kMaxStep;
  edge.time = 0.0;
  ASSERT_TRUE(WriteSimCheckpoint(path, edge, kInfo).ok());
  const absl::StatusOr<SimCheckpoint> read = ReadSimCheckpoint(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->step, kMaxStep);
}

TEST_F(StoreFilesTest, InvalidSimCheckpointsAreRefusedBeforeWriting) {
  const std::string path = Path("checkpoint.h5");
  ASSERT_TRUE(WriteSimCheckpoint(path, MakeCheckpoint(), kInfo).ok());
  const std::string before = ReadBytes(path);
  auto expect_refused = [&](const char* what, const SimCheckpoint& c, absl::string_view part) {
    const absl::Status s = WriteSimCheckpoint(path, c, kInfo);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << what << ": " << s;
    EXPECT_TRUE(MessageHas(s, part)) << what;
  };
  SimCheckpoint c = MakeCheckpoint();
  std::swap(c.rves[0], c.rves[1]);
  expect_refused("unsorted", c, "sorted by strictly increasing id; record 1 has id 3 after 7");
  c = MakeCheckpoint();
  c.rves[2].id = 7;
  expect_refused("duplicate id", c, "record 2 has id 7 after 7");
  c = MakeCheckpoint();
  c.case_json += std::string(1, '\0');
  expect_refused("NUL in case", c, "case_json contains a NUL byte");
  c = MakeCheckpoint();
  c.doubles[std::string("a\0b", 3)] = {1.0};
  expect_refused("NUL in name", c, "a name in doubles");
  c = MakeCheckpoint();
  c.rves[1].packing.vy.pop_back();
  expect_refused("bad packing", c, "record 1 (run 'run-sim', id 7)");
  c = MakeCheckpoint();
  c.templates[0].packing.material.friction = -1.0;
  expect_refused("bad template", c, "template 0 ('SET-dense')");
  c = MakeCheckpoint();
  c.step = kMaxStep + 1;
  expect_refused("step past 2^53", c, "/simulation/step = 9007199254740993 must lie");
  c = MakeCheckpoint();
  c.time = std::numeric_limits<double>::quiet_NaN();
  expect_refused("NaN time", c, "/simulation/time = nan s must be finite");

  EXPECT_TRUE(ReadBytes(path) == before) << "the existing file changed";
  EXPECT_TRUE(FilesStartingWith(dir_, "checkpoint.h5.tmp").empty());
  EXPECT_EQ(WriteSimCheckpoint(Path("no/such/dir/c.h5"), MakeCheckpoint(), kInfo).code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace rvehub::store
