// Helpers shared by the store tests (store_test, results_test): status
// message checks, doubles from bit patterns, awkward doubles, a fresh
// directory per test, byte-level corruption of written files, and HDF5 C API
// edits that forge malformed files or find the bytes to corrupt.
#ifndef RVEHUB_TESTS_STORE_STORE_TEST_UTIL_H_
#define RVEHUB_TESTS_STORE_STORE_TEST_UTIL_H_

#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"

namespace rvehub::store::testing_util {

// gmock is not linked: a plain substring predicate for status messages.
::testing::AssertionResult MessageHas(const absl::Status& status, absl::string_view part);

// A double with a chosen bit pattern (NaN payloads and the like).
double FromBits(std::uint64_t bits);

// Doubles a lossy path (text, float conversion, arithmetic) would alter:
// signed zero, subnormals, extremes, inexact decimals, NaNs with payloads
// and sign bits, infinity. Written and read back, each must keep its bits.
const std::vector<double>& AwkwardValues();

// A fresh directory per test, <tmp>/<prefix><pid>_<test name>, removed
// after the test.
class TestDirTest : public ::testing::Test {
 protected:
  explicit TestDirTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override;
  void TearDown() override;
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::filesystem::path dir_;

 private:
  std::string prefix_;
};

// Files of `dir` whose names start with `prefix`, e.g. leftover temporaries.
std::vector<std::string> FilesStartingWith(const std::filesystem::path& dir,
                                           const std::string& prefix);

std::string ReadBytes(const std::string& path);
void WriteBytes(const std::string& path, const std::string& bytes);
// XORs the byte at `offset` of the file (which must lie inside it) with 0x5a.
void FlipByte(const std::string& path, std::uint64_t offset);

// File offset and size of chunk `index` of `dataset`.
void ChunkLocation(const std::string& path, const char* dataset, hsize_t index, haddr_t* addr,
                   hsize_t* size);

// Rewrites one int32 attribute of the root group (forging files from elsewhere).
void SetIntAttribute(const std::string& path, const char* name, std::int32_t value);

// Replaces dataset `name` by a 1-D int64 (float64) dataset holding `values`.
void ReplaceInt64Dataset(const std::string& path, const char* name,
                         const std::vector<std::int64_t>& values);
void ReplaceDoubleDataset(const std::string& path, const char* name,
                          const std::vector<double>& values);

}  // namespace rvehub::store::testing_util

#endif  // RVEHUB_TESTS_STORE_STORE_TEST_UTIL_H_
