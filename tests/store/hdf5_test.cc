// store/hdf5.h, the project's one HDF5 layer: groups keep their members'
// order, attributes work alike on files, groups and datasets, appendable
// datasets grow row by row and read back bit for bit, and misuse is a
// specific error rather than a crash.
#include "store/hdf5.h"

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "gtest/gtest.h"
#include "tests/store/store_test_util.h"

namespace rvehub::store::h5 {
namespace {

using testing_util::MessageHas;
using testing_util::TestDirTest;

class Hdf5Test : public TestDirTest {
 protected:
  Hdf5Test() : TestDirTest("hdf5_test") {}
};

TEST_F(Hdf5Test, GroupsListMembersInCreationOrder) {
  absl::StatusOr<File> file = File::Create(Path("a.h5"), Format::kAppendable);
  ASSERT_TRUE(file.ok()) << file.status();
  ASSERT_TRUE(file->CreateGroup("/g").ok());
  const std::vector<double> one = {1.0};
  // Not alphabetical: the order must come from the creation index.
  for (const char* name : {"/g/zeta", "/g/alpha", "/g/mid"}) {
    ASSERT_TRUE(file->Write(name, Span(one)).ok());
  }
  absl::StatusOr<Group> group = file->OpenGroup("/g");
  ASSERT_TRUE(group.ok()) << group.status();
  absl::StatusOr<std::vector<std::string>> names = group->LinkNames();
  ASSERT_TRUE(names.ok()) << names.status();
  EXPECT_EQ(*names, (std::vector<std::string>{"zeta", "alpha", "mid"}));
  ASSERT_TRUE(file->Delete("/g/alpha").ok());
  names = group->LinkNames();
  ASSERT_TRUE(names.ok());
  EXPECT_EQ(*names, (std::vector<std::string>{"zeta", "mid"}));
  EXPECT_EQ(file->OpenGroup("/missing").status().code(), absl::StatusCode::kDataLoss);
}

TEST_F(Hdf5Test, AttributesOnFilesGroupsAndDatasets) {
  {
    absl::StatusOr<File> file = File::Create(Path("b.h5"));
    ASSERT_TRUE(file.ok()) << file.status();
    ASSERT_TRUE(file->WriteStringAttribute("kind", "test").ok());
    absl::StatusOr<Group> group = file->CreateGroup("/g");
    ASSERT_TRUE(group.ok());
    ASSERT_TRUE(group->WriteAttribute<double>("time", -0.0).ok());
    ASSERT_TRUE(group->WriteAttribute<double>("time", 0.25).ok()) << "replacing failed";
    const std::vector<std::int64_t> ids = {3, 4};
    absl::StatusOr<Dataset> dataset = file->WriteDataset("/g/ids", Span(ids));
    ASSERT_TRUE(dataset.ok()) << dataset.status();
    ASSERT_TRUE(dataset->WriteAttribute<std::int32_t>("components", 9).ok());
    EXPECT_EQ(file->WriteStringAttribute("bad", std::string("a\0b", 3)).code(),
              absl::StatusCode::kInvalidArgument);
    ASSERT_TRUE(file->Close().ok());
  }
  absl::StatusOr<File> file = File::Open(Path("b.h5"));
  ASSERT_TRUE(file.ok()) << file.status();
  EXPECT_EQ(*file->ReadStringAttribute("kind"), "test");
  absl::StatusOr<Group> group = file->OpenGroup("/g");
  ASSERT_TRUE(group.ok());
  EXPECT_EQ(*group->ReadAttribute<double>("time"), 0.25);
  EXPECT_TRUE(*group->HasAttribute("time"));
  EXPECT_FALSE(*group->HasAttribute("step"));
  EXPECT_EQ(group->ReadAttribute<double>("step").status().code(), absl::StatusCode::kNotFound);
  absl::StatusOr<Dataset> dataset = file->OpenDataset("/g/ids");
  ASSERT_TRUE(dataset.ok());
  EXPECT_EQ(*dataset->ReadAttribute<std::int32_t>("components"), 9);
  EXPECT_EQ(*dataset->ReadIntAttribute("components"), 9);
  // Exactly the written type, or DataLoss naming the object.
  absl::StatusOr<double> wrong = dataset->ReadAttribute<double>("components");
  EXPECT_EQ(wrong.status().code(), absl::StatusCode::kDataLoss);
  EXPECT_TRUE(MessageHas(wrong.status(), "/g/ids"));
}

TEST_F(Hdf5Test, AppendableDatasetsGrowAndReadBackExactly) {
  const std::string path = Path("c.h5");
  {
    absl::StatusOr<File> file = File::Create(path, Format::kAppendable);
    ASSERT_TRUE(file.ok()) << file.status();
    ASSERT_TRUE(file->CreateAppendable<double>("/series/rows", 3).ok());
    ASSERT_TRUE(file->CreateAppendable<std::int64_t>("/series/step").ok());
    EXPECT_EQ(*file->NumRows("/series/rows"), 0u);
    ASSERT_TRUE(file->Close().ok());
  }
  // Appended across reopenings, as a run that outputs as it goes would.
  std::vector<double> all;
  std::vector<std::int64_t> steps;
  for (int k = 0; k < 3; ++k) {
    absl::StatusOr<File> file = File::OpenForAppend(path);
    ASSERT_TRUE(file.ok()) << file.status();
    const std::vector<double> rows = {k + 0.1, -0.0, 1e-310, k + 0.2, 5.0, -7.0};
    const std::vector<std::int64_t> step = {10 * k, 10 * k + 5};
    ASSERT_TRUE(file->AppendRows("/series/rows", Span(rows)).ok());
    ASSERT_TRUE(file->AppendRows("/series/step", Span(step)).ok());
    all.insert(all.end(), rows.begin(), rows.end());
    steps.insert(steps.end(), step.begin(), step.end());
    // Not whole rows, the wrong type, a fixed-size dataset: refused.
    const std::vector<double> partial = {1.0, 2.0};
    EXPECT_EQ(file->AppendRows("/series/rows", Span(partial)).code(),
              absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(file->AppendRows("/series/step", Span(partial)).code(),
              absl::StatusCode::kInvalidArgument);
    ASSERT_TRUE(file->Close().ok());
  }
  absl::StatusOr<File> file = File::Open(path);
  ASSERT_TRUE(file.ok()) << file.status();
  ASSERT_EQ(*file->NumRows("/series/rows"), 6u);
  std::vector<double> read;
  ASSERT_TRUE(file->Read("/series/rows", 6, 3, &read).ok());
  ASSERT_EQ(read.size(), all.size());
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(std::signbit(read[i]), std::signbit(all[i]));
    EXPECT_EQ(read[i], all[i]) << i;
  }
  std::vector<std::int64_t> read_steps;
  ASSERT_TRUE(file->Read("/series/step", 6, 0, &read_steps).ok());
  EXPECT_EQ(read_steps, steps);
}

TEST_F(Hdf5Test, AppendingToAFixedDatasetIsRefused) {
  absl::StatusOr<File> file = File::Create(Path("d.h5"));
  ASSERT_TRUE(file.ok());
  const std::vector<double> fixed = {1.0, 2.0};
  ASSERT_TRUE(file->Write("/fixed", Span(fixed)).ok());
  absl::Status s = file->AppendRows("/fixed", Span(fixed));
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << s;
  EXPECT_TRUE(MessageHas(s, "not an appendable dataset"));
  EXPECT_EQ(file->AppendRows("/nothing", Span(fixed)).code(), absl::StatusCode::kDataLoss);
}

}  // namespace
}  // namespace rvehub::store::h5
