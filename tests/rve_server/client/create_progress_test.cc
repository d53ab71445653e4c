// RvePool::Create sends the RVEs' consolidations in calls of whole groups of
// equal initial stress (mpm_client's progress lines count them): progress is
// reported after each call, and the RVEs are bit for bit those of one call.
#include <gtest/gtest.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rve_server/client/endpoint.h"
#include "rve_server/client/rve_pool.h"
#include "rve_server/embedded/endpoint.h"
#include "tests/support/test_util.h"

namespace rvehub::client {
namespace {

using dem::testing_util::SameBits;

TEST(CreateProgressTest, ReportsEachCallAndMatchesOneCall) {
  dem::RveSnapshot packing = dem::testing_util::Prepared("SET-dense");
  const TemplateRecord record{"t", "SET-dense seed 1", packing};
  // 9 distinct stresses over 12 points (points 9..11 repeat 0..2); one
  // worker: calls of 2, 2, 2, 2 and 1 consolidations.
  constexpr int kPoints = 12;
  std::vector<InitialStress> initial(kPoints);
  std::vector<std::int64_t> ids;
  for (int p = 0; p < kPoints; ++p) {
    initial[p].kind = InitialStress::Kind::kIsotropic;
    initial[p].pressure = 100e3 * (1 + 0.01 * (p % 9));
    ids.push_back(p);
  }
  embedded::EmbeddedOptions options;
  options.threads = 1;
  std::vector<std::unique_ptr<RveEndpoint>> endpoints;
  endpoints.push_back(embedded::MakeEndpoint(options));
  RvePool pool(std::move(endpoints), "run");
  ASSERT_TRUE(pool.UploadTemplates(std::vector<TemplateRecord>{record}).ok());
  std::vector<std::pair<std::int64_t, std::int64_t>> reports;
  absl::StatusOr<std::vector<dem::RveState>> states = pool.Create(
      std::vector<std::string>(kPoints, "t"), initial, {},
      [&](std::int64_t done, std::int64_t total) { reports.emplace_back(done, total); });
  ASSERT_TRUE(states.ok()) << states.status();
  EXPECT_EQ(reports, (std::vector<std::pair<std::int64_t, std::int64_t>>{
                         {0, 9}, {2, 9}, {4, 9}, {6, 9}, {8, 9}, {9, 9}}));

  // The same RVEs created in one call.
  std::unique_ptr<RveEndpoint> single = embedded::MakeEndpoint(options);
  ASSERT_TRUE(single->PutTemplate(record).ok());
  absl::StatusOr<std::vector<RveOutcome>> one =
      single->Create("run", "t", ids, initial, std::nullopt);
  ASSERT_TRUE(one.ok()) << one.status();
  ASSERT_EQ(one->size(), static_cast<std::size_t>(kPoints));
  for (int p = 0; p < kPoints; ++p) {
    ASSERT_TRUE((*one)[p].status.ok()) << (*one)[p].status;
    EXPECT_TRUE(SameBits((*states)[p].stress, (*one)[p].state.stress)) << "point " << p;
    EXPECT_EQ((*states)[p].void_ratio, (*one)[p].state.void_ratio) << "point " << p;
  }
  // Equal stresses still share one consolidation.
  EXPECT_TRUE(SameBits((*states)[9].stress, (*states)[0].stress));
}

}  // namespace
}  // namespace rvehub::client
