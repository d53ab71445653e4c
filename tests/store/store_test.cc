// The HDF5 checkpoint store: bit-exact round trips (hand-built packings with
// awkward values, a prepared packing, an RVE that must continue exactly),
// empty files, kinds, and every way a file can be missing, malformed or
// corrupt, which must end in a clear error rather than a crash or wrong data.
// The test opens the written files with the HDF5 C API to find the bytes to
// corrupt (chunk and object-header addresses) and to forge malformed files.
#include <hdf5.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"
#include "tests/store/store_test_util.h"
#include "tests/support/test_util.h"

namespace rvehub::store {
namespace {

namespace fs = std::filesystem;
using ::rvehub::dem::testing_util::CreateOrDie;
using ::rvehub::dem::testing_util::ExpectIdenticalPackings;
using ::rvehub::dem::testing_util::ExpectIdenticalStates;
using ::rvehub::dem::testing_util::Prepared;
using ::rvehub::dem::testing_util::SameBits;
using ::rvehub::dem::testing_util::SquareLattice;
using testing_util::AwkwardValues;
using testing_util::ChunkLocation;
using testing_util::FilesStartingWith;
using testing_util::FlipByte;
using testing_util::MessageHas;
using testing_util::ReadBytes;
using testing_util::ReplaceInt64Dataset;
using testing_util::SetIntAttribute;
using testing_util::TestDirTest;
using testing_util::WriteBytes;

// A packing built by hand with `side`² discs, `contacts_per_disc` contacts
// per disc with tangential force, rolling moment and bond history, and
// awkward values in every particle array.
dem::RveSnapshot HandBuilt(int side, int contacts_per_disc, double salt) {
  dem::RveSnapshot p = SquareLattice(side, 0.02, [&](int x, int y) {
    return 0.008 + 1e-4 * ((x * 7 + y * 3) % 11) + 1e-9 * salt;
  });
  p.material.name = absl::StrCat("hand-built ", salt);
  p.material.rolling_beta = 0.7 + salt;
  p.material.rolling_eta = 0.05;
  p.material.bond_cohesion = 2e5;
  p.material.friction = std::nextafter(0.5, 1.0);
  p.controls.min_steps = 17 + static_cast<int>(salt);
  p.controls.skin = 0.3;
  p.cell(0, 1) = 1e-3 * salt;
  p.reference_cell(1, 0) = -0.0;
  const double angle = 0.1 + salt;
  p.frame << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  const std::size_t n = p.radius.size();
  const std::vector<double>& awkward = AwkwardValues();
  for (std::size_t i = 0; i < n; ++i) {
    p.sx[i] += 1e-17 * static_cast<double>(i);
    p.vx[i] = awkward[i % awkward.size()];
    p.vy[i] = -1e-3 * static_cast<double>(i) - salt;
    p.omega[i] = awkward[(i + 3) % awkward.size()];
    p.theta[i] = std::sin(static_cast<double>(i) + salt);
  }
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 1; c <= contacts_per_disc && i + c < n; ++c) {
      dem::ContactHistory h;
      h.i = static_cast<std::uint32_t>(i);
      h.j = static_cast<std::uint32_t>(i + c);
      h.tangential_force = (c % 2 == 0 ? -1.0 : 1.0) * (0.1 + static_cast<double>(i));
      h.rolling_moment = awkward[(i + c) % awkward.size()];
      h.bond_strength = c == 1 ? 1.8 + 1e-3 * static_cast<double>(i) : 0.0;
      p.contacts.push_back(h);
    }
  }
  p.initial_void_ratio = 0.177 + salt;
  p.permeability_coefficient = 1e-3 / 3.0;
  p.total_steps = 123456789 + static_cast<std::int64_t>(salt);
  return p;
}

RveRecord MakeRecord(std::string run_id, std::int64_t id, dem::RveSnapshot packing) {
  RveRecord r;
  r.run_id = std::move(run_id);
  r.id = id;
  r.step = 1000 + id;
  r.last_delta_f << 1.0 + 1e-4 * id, -0.0, 0.0, 2.5e-5, 1.0 - 3e-5, 0.0, 0.0, 0.0, 1.0;
  r.packing = std::move(packing);
  return r;
}

void ExpectIdenticalRecords(const std::vector<RveRecord>& a, const std::vector<RveRecord>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    SCOPED_TRACE(absl::StrCat("record ", k));
    EXPECT_EQ(a[k].run_id, b[k].run_id);
    EXPECT_EQ(a[k].id, b[k].id);
    EXPECT_EQ(a[k].step, b[k].step);
    EXPECT_TRUE(SameBits(a[k].last_delta_f, b[k].last_delta_f));
    ExpectIdenticalPackings(a[k].packing, b[k].packing);
  }
}

class StoreTest : public TestDirTest {
 protected:
  StoreTest() : TestDirTest("rvehub_store_test_") {}

  // Three records of different sizes, one without contacts.
  std::vector<RveRecord> SomeRecords() const {
    std::vector<RveRecord> rves;
    rves.push_back(MakeRecord("run-a", 0, HandBuilt(4, 2, 0.0)));
    rves.push_back(MakeRecord("run-a", 7, HandBuilt(7, 3, 1.0)));
    rves.push_back(MakeRecord("", -3, HandBuilt(3, 0, 2.0)));  // no contacts, empty run id
    rves.push_back(MakeRecord("run-b \xc3\xa9", 1LL << 40, HandBuilt(5, 1, 3.0)));
    return rves;
  }

  const FileInfo info_{"store_test 1.0", "2026-11-22T10:00:00Z"};
};

TEST_F(StoreTest, HandBuiltRecordsRoundTripBitExactly) {
  const std::vector<RveRecord> rves = SomeRecords();
  ASSERT_TRUE(rves[2].packing.contacts.empty());
  const std::string path = Path("rves.h5");
  ASSERT_TRUE(WriteRves(path, rves, info_).ok());
  FileInfo info;
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path, &info);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdenticalRecords(rves, *read);
  EXPECT_EQ(info.created_by, "store_test 1.0");
  EXPECT_EQ(info.created_at, "2026-11-22T10:00:00Z");
  EXPECT_EQ(info.format_version, kFormatVersion);
  EXPECT_TRUE(FilesStartingWith(dir_, "rves.h5.tmp").empty());
}

TEST_F(StoreTest, PreparedPackingsRoundTripBitExactly) {
  std::vector<RveRecord> rves;
  rves.push_back(MakeRecord("prepared", 1, Prepared("SET-dense")));
  rves.push_back(MakeRecord("prepared", 2, Prepared("footing-dense")));  // rolling resistance
  ASSERT_FALSE(rves[0].packing.contacts.empty());
  const std::string path = Path("prepared.h5");
  ASSERT_TRUE(WriteRves(path, rves, info_).ok());
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdenticalRecords(rves, *read);
}

TEST_F(StoreTest, RestoredRveContinuesBitIdentically) {
  dem::RveSnapshot packing = Prepared("SET-dense");
  packing.material.rolling_beta = 1.0;
  packing.material.rolling_eta = 0.05;
  packing.material.bond_cohesion = 1e6;  // Pa: bonds of ~10–50 N, some of which break
  dem::Rve original = CreateOrDie(packing);
  original.BondContacts();
  Eigen::Matrix3d delta_f = Eigen::Matrix3d::Identity();
  delta_f(0, 1) = 2e-4;
  delta_f(1, 1) = 1.0 - 5e-5;
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(original.Apply(delta_f).ok());

  RveRecord record = MakeRecord("continue", 42, original.ToSnapshot());
  record.step = 5;
  record.last_delta_f = delta_f;
  bool bonded = false, rolling = false;
  for (const dem::ContactHistory& c : record.packing.contacts) {
    bonded |= c.bond_strength > 0;
    rolling |= c.rolling_moment != 0;
  }
  ASSERT_TRUE(bonded && rolling) << "the saved state should carry bond and rolling history";
  const std::string path = Path("continue.h5");
  ASSERT_TRUE(WriteRves(path, std::span<const RveRecord>(&record, 1), info_).ok());
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 1u);
  ExpectIdenticalPackings(record.packing, (*read)[0].packing, "restored packing");

  dem::Rve restored = CreateOrDie((*read)[0].packing);
  for (int k = 0; k < 50; ++k) {
    absl::StatusOr<dem::RveState> a = original.Apply(delta_f);
    absl::StatusOr<dem::RveState> b = restored.Apply(delta_f);
    ASSERT_TRUE(a.ok() && b.ok()) << a.status() << " / " << b.status();
    ExpectIdenticalStates(*a, *b, absl::StrCat("increment ", k));
    if (::testing::Test::HasFailure()) return;
  }
  ExpectIdenticalPackings(original.ToSnapshot(), restored.ToSnapshot(), "after 50 increments");
}

TEST_F(StoreTest, ZeroRecords) {
  const std::string path = Path("empty.h5");
  ASSERT_TRUE(WriteRves(path, {}, info_).ok());
  FileInfo info;
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path, &info);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_TRUE(read->empty());
  EXPECT_EQ(info.format_version, kFormatVersion);

  ASSERT_TRUE(WriteTemplates(Path("empty_templates.h5"), {}, {}).ok());
  absl::StatusOr<std::vector<TemplateRecord>> templates =
      ReadTemplates(Path("empty_templates.h5"), &info);
  ASSERT_TRUE(templates.ok()) << templates.status();
  EXPECT_TRUE(templates->empty());
  EXPECT_EQ(info.created_by, "");
  EXPECT_EQ(info.created_at.size(), 20u) << "filled with the current time: " << info.created_at;
}

TEST_F(StoreTest, RecordsWithoutContactsOrParticles) {
  std::vector<RveRecord> rves;
  rves.push_back(MakeRecord("r", 0, HandBuilt(2, 0, 0.0)));
  rves.push_back(MakeRecord("r", 1, dem::RveSnapshot{}));  // nothing at all
  rves.push_back(MakeRecord("r", 2, HandBuilt(3, 0, 1.0)));
  const std::string path = Path("no_contacts.h5");
  ASSERT_TRUE(WriteRves(path, rves, info_).ok());
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdenticalRecords(rves, *read);
}

TEST_F(StoreTest, TemplatesRoundTrip) {
  std::vector<TemplateRecord> templates(3);
  templates[0].name = "SET-dense";
  templates[0].description = "PreparePacking(SET-dense, seed 1): e0 = 0.181, p0 = 100 kPa";
  templates[0].packing = Prepared("SET-dense");
  templates[1].name = "hand-built";
  templates[1].description = std::string(5000, 'x');  // long free text
  templates[1].packing = HandBuilt(6, 2, 4.0);
  templates[2].name = "";
  templates[2].description = "";
  templates[2].packing = HandBuilt(2, 1, 5.0);
  const std::string path = Path("templates.h5");
  ASSERT_TRUE(WriteTemplates(path, templates, info_).ok());
  FileInfo info;
  absl::StatusOr<std::vector<TemplateRecord>> read = ReadTemplates(path, &info);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), templates.size());
  for (std::size_t k = 0; k < templates.size(); ++k) {
    EXPECT_EQ((*read)[k].name, templates[k].name);
    EXPECT_EQ((*read)[k].description, templates[k].description);
    ExpectIdenticalPackings(templates[k].packing, (*read)[k].packing, templates[k].name);
  }
  EXPECT_EQ(info.created_by, info_.created_by);
}

TEST_F(StoreTest, WrongKindIsInvalidArgument) {
  ASSERT_TRUE(WriteRves(Path("rves.h5"), SomeRecords(), info_).ok());
  absl::StatusOr<std::vector<TemplateRecord>> templates = ReadTemplates(Path("rves.h5"));
  EXPECT_EQ(templates.status().code(), absl::StatusCode::kInvalidArgument) << templates.status();
  EXPECT_TRUE(MessageHas(templates.status(), "'rves', not 'templates'"));

  std::vector<TemplateRecord> t(1);
  t[0].packing = HandBuilt(2, 0, 0.0);
  ASSERT_TRUE(WriteTemplates(Path("templates.h5"), t, info_).ok());
  absl::StatusOr<std::vector<RveRecord>> rves = ReadRves(Path("templates.h5"));
  EXPECT_EQ(rves.status().code(), absl::StatusCode::kInvalidArgument) << rves.status();
  EXPECT_TRUE(MessageHas(rves.status(), "ReadTemplates"));
}

TEST_F(StoreTest, MissingFileIsNotFound) {
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(Path("nothing_here.h5"));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kNotFound) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "nothing_here.h5"));
  EXPECT_EQ(ReadTemplates(Path("nothing_here.h5")).status().code(), absl::StatusCode::kNotFound);
}

TEST_F(StoreTest, NotAStoreFile) {
  WriteBytes(Path("text.h5"), "this is not HDF5\n");
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(Path("text.h5"));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  // An HDF5 file without the store's attributes.
  const hid_t file = H5Fcreate(Path("plain.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  H5Fclose(file);
  read = ReadRves(Path("plain.h5"));
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "not an RVEHub store file"));
  read = ReadRves(dir_.string());  // a directory
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument) << read.status();
}

TEST_F(StoreTest, TruncatedFileIsDataLoss) {
  const std::string path = Path("truncated.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  const std::string bytes = ReadBytes(path);
  for (std::size_t keep : {bytes.size() - 1, bytes.size() / 2, std::size_t{100}, std::size_t{0}}) {
    WriteBytes(path, bytes.substr(0, keep));
    absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << "kept " << keep << " bytes: " << read.status();
  }
}

TEST_F(StoreTest, FlippedByteInParticleChunkIsDataLossNamingTheDataset) {
  // 9000 particles: a chunk of /particles/sx large enough that the flipped
  // byte lies well inside it.
  std::vector<RveRecord> rves;
  for (int k = 0; k < 10; ++k) rves.push_back(MakeRecord("big", k, HandBuilt(30, 1, k)));
  const std::string path = Path("corrupt.h5");
  ASSERT_TRUE(WriteRves(path, rves, info_).ok());
  haddr_t addr = 0;
  hsize_t size = 0;
  ChunkLocation(path, "/particles/sx", 0, &addr, &size);
  ASSERT_GT(size, 1000u);
  FlipByte(path, addr + size / 2);
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(
      read.status(),
      "checksum mismatch (fletcher32) in dataset /particles/sx of " + path + ": file is corrupt"));
}

TEST_F(StoreTest, FlippedByteInContactChunkIsDataLoss) {
  const std::string path = Path("corrupt_contacts.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  haddr_t addr = 0;
  hsize_t size = 0;
  ChunkLocation(path, "/contacts/j", 0, &addr, &size);
  FlipByte(path, addr + size / 3);
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "/contacts/j"));
}

TEST_F(StoreTest, FlippedByteInMetadataIsAClearError) {
  const std::string path = Path("metadata.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  const std::string good = ReadBytes(path);

  // The superblock (v3, checksummed): bytes 8..47.
  for (std::uint64_t offset : {9, 20, 30, 40, 45}) {
    WriteBytes(path, good);
    FlipByte(path, offset);
    absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
    EXPECT_EQ(read.status().code(), absl::StatusCode::kDataLoss)
        << "superblock byte " << offset << ": " << read.status();
  }

  // The object header of a dataset (v2, checksummed).
  WriteBytes(path, good);
  haddr_t header = 0;
  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    H5O_info_t info;
    ASSERT_GE(H5Oget_info_by_name2(file, "/particles/vy", &info, H5O_INFO_BASIC, H5P_DEFAULT), 0);
    header = info.addr;
    H5Fclose(file);
  }
  FlipByte(path, header + 12);
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_EQ(read.status().code(), absl::StatusCode::kDataLoss) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), "checksum"));

  // Every single byte of the first 4 KiB (superblock, root group, heaps):
  // whatever it hits, the read fails cleanly or succeeds with intact data
  // (a few bytes are padding or unused).
  const std::vector<RveRecord> rves = SomeRecords();
  for (std::uint64_t offset = 0; offset < std::min<std::uint64_t>(4096, good.size()); offset += 7) {
    WriteBytes(path, good);
    FlipByte(path, offset);
    absl::StatusOr<std::vector<RveRecord>> r = ReadRves(path);
    if (r.ok()) {
      SCOPED_TRACE(absl::StrCat("flipped byte ", offset, " went unnoticed"));
      ExpectIdenticalRecords(rves, *r);
      if (::testing::Test::HasFailure()) return;
    }
  }
}

TEST_F(StoreTest, NewerFormatVersionNamesBothVersions) {
  const std::string path = Path("future.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  SetIntAttribute(path, "format_version", kFormatVersion + 1);
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_EQ(read.status().code(), absl::StatusCode::kFailedPrecondition) << read.status();
  EXPECT_TRUE(MessageHas(read.status(), absl::StrCat("format_version ", kFormatVersion + 1)));
  EXPECT_TRUE(MessageHas(read.status(), absl::StrCat("format_version ", kFormatVersion, ")")));
  SetIntAttribute(path, "format_version", 0);
  EXPECT_EQ(ReadRves(path).status().code(), absl::StatusCode::kDataLoss);
}

TEST_F(StoreTest, MalformedFilesGiveSpecificErrors) {
  const std::vector<RveRecord> rves = SomeRecords();
  const std::string good_path = Path("good.h5");
  ASSERT_TRUE(WriteRves(good_path, rves, info_).ok());
  const std::string good = ReadBytes(good_path);
  const std::string path = Path("malformed.h5");
  std::vector<std::int64_t> offsets{0};
  std::int64_t total = 0;
  std::size_t num_particles = 0;
  for (const RveRecord& r : rves) {
    total += static_cast<std::int64_t>(r.packing.contacts.size());
    offsets.push_back(total);
    num_particles += r.packing.radius.size();
  }

  auto expect = [&](const char* what, absl::StatusCode code, const std::string& substring) {
    absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
    EXPECT_EQ(read.status().code(), code) << what << ": " << read.status();
    EXPECT_TRUE(MessageHas(read.status(), substring)) << what;
    WriteBytes(path, good);
  };
  WriteBytes(path, good);

  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    ASSERT_GE(H5Ldelete(file, "/particles/omega", H5P_DEFAULT), 0);
    H5Fclose(file);
  }
  expect("missing dataset", absl::StatusCode::kDataLoss, "missing dataset /particles/omega");

  std::vector<std::int64_t> decreasing = offsets;
  std::swap(decreasing[1], decreasing[2]);
  ReplaceInt64Dataset(path, "/packing/contact_offset", decreasing);
  expect("decreasing offsets", absl::StatusCode::kDataLoss,
         "dataset /packing/contact_offset of " + path + " decreases at entry 2");

  std::vector<std::int64_t> longer = offsets;
  longer.back() += 1;
  ReplaceInt64Dataset(path, "/packing/contact_offset", longer);
  expect("last offset past the data", absl::StatusCode::kDataLoss, "/contacts/i");

  std::vector<std::int64_t> huge = offsets;
  huge.back() = std::int64_t{1} << 60;
  ReplaceInt64Dataset(path, "/packing/contact_offset", huge);
  expect("absurd offset", absl::StatusCode::kDataLoss, "more than the file's");

  ReplaceInt64Dataset(path, "/packing/contact_offset", {0, 1});
  expect("wrong shape", absl::StatusCode::kDataLoss, "has shape [2]; expected [5]");

  ReplaceInt64Dataset(path, "/particles/sx", std::vector<std::int64_t>(num_particles, 0));
  expect("wrong type", absl::StatusCode::kDataLoss, "unexpected element type");

  SetIntAttribute(path, "num_records", 3);
  expect("wrong record count", absl::StatusCode::kDataLoss, "expected [3]");

  // A contact index beyond its record's particles (written by forging the
  // j column of the first contact).
  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t dset = H5Dopen2(file, "/contacts/j", H5P_DEFAULT);
    std::vector<std::uint32_t> j(static_cast<std::size_t>(total));
    ASSERT_GE(H5Dread(dset, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, j.data()), 0);
    j[0] = 1000;
    ASSERT_GE(H5Dwrite(dset, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, j.data()), 0);
    H5Dclose(dset);
    H5Fclose(file);
  }
  expect(
      "contact index out of range", absl::StatusCode::kDataLoss,
      "record 0 (run 'run-a', id 0) of " + path + " is invalid: contact 0 has indices (0, 1000)");

  // An invalid material (negative density).
  {
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hid_t dset = H5Dopen2(file, "/material/density", H5P_DEFAULT);
    std::vector<double> density(rves.size());
    ASSERT_GE(H5Dread(dset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, density.data()), 0);
    density[1] = -1.0;
    ASSERT_GE(H5Dwrite(dset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, density.data()), 0);
    H5Dclose(dset);
    H5Fclose(file);
  }
  expect("invalid material", absl::StatusCode::kDataLoss, "record 1 (run 'run-a', id 7)");
}

TEST_F(StoreTest, InvalidRecordsAreRefusedBeforeWriting) {
  const std::string path = Path("existing.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  const std::string before = ReadBytes(path);

  std::vector<RveRecord> bad = SomeRecords();
  bad[1].packing.vy.pop_back();
  absl::Status s = WriteRves(path, bad, info_);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
  EXPECT_TRUE(MessageHas(s, "record 1 (run 'run-a', id 7)"));
  EXPECT_TRUE(MessageHas(s, "/particles/vy"));

  bad = SomeRecords();
  bad[0].packing.contacts[0].j = 10000;
  EXPECT_EQ(WriteRves(path, bad, info_).code(), absl::StatusCode::kInvalidArgument);
  bad = SomeRecords();
  bad[0].packing.material.friction = -1.0;
  EXPECT_EQ(WriteRves(path, bad, info_).code(), absl::StatusCode::kInvalidArgument);
  bad = SomeRecords();
  bad[0].packing.controls.mass_scale = 0.5;
  EXPECT_EQ(WriteRves(path, bad, info_).code(), absl::StatusCode::kInvalidArgument);
  bad = SomeRecords();
  bad[3].run_id = std::string("a\0b", 3);
  EXPECT_EQ(WriteRves(path, bad, info_).code(), absl::StatusCode::kInvalidArgument);

  EXPECT_TRUE(ReadBytes(path) == before) << "the existing file changed";
  EXPECT_EQ(FilesStartingWith(dir_, "existing.h5.tmp").size(), 0u);
}

TEST_F(StoreTest, FailedWriteLeavesNoTemporaryAndTheOldFileUntouched) {
  // A directory that does not exist.
  absl::Status s = WriteRves(Path("no/such/dir/rves.h5"), SomeRecords(), info_);
  EXPECT_EQ(s.code(), absl::StatusCode::kNotFound) << s;
  EXPECT_TRUE(MessageHas(s, "no/such/dir/rves.h5"));

  // The temporary name is taken by a directory: the write fails before
  // touching anything, and the directory is not removed.
  const std::string path = Path("existing.h5");
  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  const std::string before = ReadBytes(path);
  const std::string temp = absl::StrCat(path, ".tmp-", ::getpid());
  fs::create_directory(temp);
  s = WriteRves(path, SomeRecords(), info_);
  EXPECT_FALSE(s.ok());
  EXPECT_TRUE(fs::is_directory(temp));
  EXPECT_TRUE(ReadBytes(path) == before) << "the existing file changed";
  fs::remove(temp);

  // A name taken by something other than a regular file (a directory, a
  // FIFO standing in for a device, a link) is refused before anything is
  // written: the rename would have replaced it (as root, /dev/full became a
  // regular file).
  const std::string blocked = Path("blocked.h5");
  fs::create_directories(fs::path(blocked) / "inside");
  const std::string fifo = Path("fifo.h5");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  const std::string link = Path("link.h5");
  fs::create_symlink(path, link);
  for (const std::string& taken : {blocked, fifo, link}) {
    s = WriteRves(taken, SomeRecords(), info_);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
    EXPECT_TRUE(MessageHas(s, "it exists and is not a regular file")) << s;
    EXPECT_EQ(FilesStartingWith(dir_, fs::path(taken).filename().string() + ".tmp").size(), 0u);
  }
  EXPECT_TRUE(fs::is_directory(blocked));
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_TRUE(ReadBytes(path) == before) << "the link's target changed";

  // A read-only directory (meaningless for root, who may write anyway).
  if (::geteuid() != 0) {
    const fs::path locked = dir_ / "locked";
    fs::create_directory(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    s = WriteRves((locked / "rves.h5").string(), SomeRecords(), info_);
    EXPECT_EQ(s.code(), absl::StatusCode::kPermissionDenied) << s;
    fs::permissions(locked, fs::perms::owner_all);
  }

  // Overwriting replaces the file as a whole.
  std::vector<RveRecord> one = SomeRecords();
  one.resize(1);
  ASSERT_TRUE(WriteRves(path, one, info_).ok());
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdenticalRecords(one, *read);
  EXPECT_TRUE(FilesStartingWith(dir_, "existing.h5.tmp").empty());
}

TEST_F(StoreTest, NextWriteRemovesTemporariesOfKilledWriters) {
  // A pid that names no process: a child that has exited and been reaped.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) ::_exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string path = Path("rves.h5");
  const std::string stale = absl::StrCat(path, ".tmp-", child);
  // A live writer in another process (our parent, the test runner).
  const std::string live = absl::StrCat(path, ".tmp-", ::getppid());
  const std::string other = Path("other.h5.tmp-") + std::to_string(child);
  for (const std::string& name : {stale, live, other}) WriteBytes(name, std::string(4096, 'x'));

  ASSERT_TRUE(WriteRves(path, SomeRecords(), info_).ok());
  EXPECT_FALSE(fs::exists(stale)) << "a killed writer's temporary survived the next write";
  EXPECT_TRUE(fs::exists(live)) << "a live writer's temporary was removed";
  EXPECT_TRUE(fs::exists(other)) << "another file's temporary was removed";
  absl::StatusOr<std::vector<RveRecord>> read = ReadRves(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectIdenticalRecords(SomeRecords(), *read);
}

}  // namespace
}  // namespace rvehub::store
