#include "tests/store/store_test_util.h"

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <system_error>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace rvehub::store::testing_util {

namespace fs = std::filesystem;

::testing::AssertionResult MessageHas(const absl::Status& status, absl::string_view part) {
  if (absl::StrContains(status.message(), part)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not in: " << status;
}

double FromBits(std::uint64_t bits) {
  double d;
  std::memcpy(&d, &bits, sizeof d);
  return d;
}

const std::vector<double>& AwkwardValues() {
  static const auto* values = new std::vector<double>{
      -0.0,
      std::numeric_limits<double>::denorm_min(),
      -std::numeric_limits<double>::denorm_min(),
      std::numeric_limits<double>::min(),
      std::numeric_limits<double>::max(),
      std::numeric_limits<double>::lowest(),
      std::numeric_limits<double>::epsilon(),
      0.1,
      1.0 / 3.0,
      std::nextafter(1.0, 2.0),
      FromBits(0x7ff8000000000123ull),  // quiet NaN with a payload
      FromBits(0xfff4000000000001ull),  // signalling NaN, sign bit set
      -std::numeric_limits<double>::infinity(),
  };
  return *values;
}

void TestDirTest::SetUp() {
  const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
  dir_ = fs::temp_directory_path() / absl::StrCat(prefix_, ::getpid(), "_", test->name());
  fs::remove_all(dir_);
  fs::create_directories(dir_);
}

void TestDirTest::TearDown() {
  std::error_code ignored;
  fs::remove_all(dir_, ignored);
}

std::vector<std::string> FilesStartingWith(const fs::path& dir, const std::string& prefix) {
  std::vector<std::string> names;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) == 0) names.push_back(name);
  }
  return names;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

void FlipByte(const std::string& path, std::uint64_t offset) {
  std::string bytes = ReadBytes(path);
  ASSERT_LT(offset, bytes.size());
  bytes[offset] = static_cast<char>(bytes[offset] ^ 0x5a);
  WriteBytes(path, bytes);
}

void ChunkLocation(const std::string& path, const char* dataset, hsize_t index, haddr_t* addr,
                   hsize_t* size) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t dset = H5Dopen2(file, dataset, H5P_DEFAULT);
  ASSERT_GE(dset, 0);
  const hid_t space = H5Dget_space(dset);
  hsize_t offset[2] = {0, 0};
  unsigned filter_mask = 0;
  EXPECT_GE(H5Dget_chunk_info(dset, space, index, offset, &filter_mask, addr, size), 0);
  H5Sclose(space);
  H5Dclose(dset);
  H5Fclose(file);
}

void SetIntAttribute(const std::string& path, const char* name, std::int32_t value) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t attr = H5Aopen(file, name, H5P_DEFAULT);
  ASSERT_GE(attr, 0);
  EXPECT_GE(H5Awrite(attr, H5T_NATIVE_INT32, &value), 0);
  H5Aclose(attr);
  H5Fclose(file);
}

namespace {

void ReplaceDataset(const std::string& path, const char* name, hid_t file_type, hid_t memory_type,
                    std::size_t size, const void* values) {
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  ASSERT_GE(H5Ldelete(file, name, H5P_DEFAULT), 0);
  const hsize_t dims[1] = {size};
  const hid_t space = H5Screate_simple(1, dims, nullptr);
  const hid_t dset =
      H5Dcreate2(file, name, file_type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(dset, 0);
  EXPECT_GE(H5Dwrite(dset, memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
  H5Dclose(dset);
  H5Sclose(space);
  H5Fclose(file);
}

}  // namespace

void ReplaceInt64Dataset(const std::string& path, const char* name,
                         const std::vector<std::int64_t>& values) {
  ReplaceDataset(path, name, H5T_STD_I64LE, H5T_NATIVE_INT64, values.size(), values.data());
}

void ReplaceDoubleDataset(const std::string& path, const char* name,
                          const std::vector<double>& values) {
  ReplaceDataset(path, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, values.size(), values.data());
}

}  // namespace rvehub::store::testing_util
