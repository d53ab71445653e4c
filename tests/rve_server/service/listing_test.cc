// ListTemplates and ListRuns in pages: a server with the smallest message
// limit (1 MiB) and more templates or runs than one reply can hold answers
// in pages that each fit, the RemoteServer client follows them to the end,
// and a bad page_size or page_token is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/client/remote_server.h"
#include "tests/rve_server/service/service_harness.h"

namespace rvehub::service::testing {
namespace {

constexpr std::int64_t kMessageBytes = 1 << 20;  // the smallest limit a server takes

ServerConfig SmallMessages() {
  ServerConfig c;
  c.max_message_bytes = kMessageBytes;
  c.registry.threads = 2;
  return c;
}

// A 3×3 lattice of 1 mm discs: the smallest packing a server takes, so that
// thousands of RVEs cost little.
const dem::RveSnapshot& TinyPacking() {
  static const dem::RveSnapshot p =
      dem::testing_util::SquareLattice(3, 2e-3, [](int, int) { return 1e-3; });
  return p;
}

// Names long enough (128 bytes, the most a name may have) that a few
// thousand overflow a 1 MiB reply; sorted as the index is.
std::string LongName(const char* prefix, int k) {
  std::string name = absl::StrFormat("%s-%05d-", prefix, k);
  name.resize(128, 'x');
  return name;
}

// `n` templates with 4 KiB descriptions (the most a description may have).
void PutTemplates(Registry& registry, int n) {
  for (int k = 0; k < n; ++k) {
    TemplateRecord t;
    t.name = LongName("template", k);
    t.description = std::string(4096, 'd');
    t.packing = TinyPacking();
    ASSERT_TRUE(registry.PutTemplate(std::move(t), false).ok());
  }
}

// `n` runs of one RVE each.
void PutRuns(Registry& registry, int n) {
  std::vector<RveRecord> records(n);
  for (int k = 0; k < n; ++k) {
    records[k].run_id = LongName("run", k);
    records[k].id = k;
    records[k].step = k % 7;
    records[k].packing = TinyPacking();
  }
  absl::StatusOr<std::int64_t> imported = registry.Import(std::move(records));
  ASSERT_TRUE(imported.ok()) << imported.status();
  ASSERT_EQ(*imported, n);
}

TEST(ListingTest, TemplatesComeInPagesThatFitTheMessageLimit) {
  Harness h(SmallMessages());
  constexpr int kTemplates = 300;  // ~1.3 MB of descriptions alone
  PutTemplates(h.server().registry(), kTemplates);
  std::vector<std::string> names;
  v1::ListTemplatesRequest req;
  int pages = 0;
  do {
    v1::ListTemplatesResponse resp;
    const grpc::Status s = h.stub().ListTemplates(h.Context().get(), req, &resp);
    ASSERT_TRUE(s.ok()) << s.error_message();
    EXPECT_LE(static_cast<std::int64_t>(resp.ByteSizeLong()), kMessageBytes);
    EXPECT_GT(resp.templates_size(), 0);
    for (const v1::TemplateInfo& t : resp.templates()) {
      names.push_back(t.name());
      EXPECT_EQ(t.description().size(), 4096u);
    }
    req.set_page_token(resp.next_page_token());
    ASSERT_LT(++pages, 100);
  } while (!req.page_token().empty());
  EXPECT_GE(pages, 2);
  ASSERT_EQ(names.size(), static_cast<std::size_t>(kTemplates));
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
}

TEST(ListingTest, RunsComeInPagesThatFitTheMessageLimit) {
  Harness h(SmallMessages());
  constexpr int kRuns = 8000;  // ~1.2 MB of run ids alone
  PutRuns(h.server().registry(), kRuns);
  std::vector<v1::RunInfo> runs;
  v1::ListRunsRequest req;
  int pages = 0;
  do {
    v1::ListRunsResponse resp;
    const grpc::Status s = h.stub().ListRuns(h.Context().get(), req, &resp);
    ASSERT_TRUE(s.ok()) << s.error_message();
    EXPECT_LE(static_cast<std::int64_t>(resp.ByteSizeLong()), kMessageBytes);
    runs.insert(runs.end(), resp.runs().begin(), resp.runs().end());
    req.set_page_token(resp.next_page_token());
    ASSERT_LT(++pages, 100);
  } while (!req.page_token().empty());
  EXPECT_GE(pages, 2);
  ASSERT_EQ(runs.size(), static_cast<std::size_t>(kRuns));
  for (int k = 0; k < kRuns; ++k) {
    EXPECT_EQ(runs[k].run_id(), LongName("run", k));
    EXPECT_EQ(runs[k].num_rves(), 1);
    EXPECT_EQ(runs[k].max_step(), k % 7);
  }
}

TEST(ListingTest, PageSizeBoundsEachPage) {
  Harness h;
  PutRuns(h.server().registry(), 10);
  std::vector<std::string> ids;
  v1::ListRunsRequest req;
  req.set_page_size(3);
  std::vector<int> sizes;
  do {
    v1::ListRunsResponse resp;
    ASSERT_TRUE(h.stub().ListRuns(h.Context().get(), req, &resp).ok());
    sizes.push_back(resp.runs_size());
    for (const v1::RunInfo& r : resp.runs()) ids.push_back(r.run_id());
    req.set_page_token(resp.next_page_token());
    ASSERT_LT(sizes.size(), 20u);
  } while (!req.page_token().empty());
  // Exactly 3 + 3 + 3 + 1: a page that ends the list says so (no empty last page).
  EXPECT_EQ(sizes, (std::vector<int>{3, 3, 3, 1}));
  ASSERT_EQ(ids.size(), 10u);
  for (int k = 0; k < 10; ++k) EXPECT_EQ(ids[k], LongName("run", k));

  // A page size of exactly the count: one page, no token.
  req.Clear();
  req.set_page_size(10);
  v1::ListRunsResponse all;
  ASSERT_TRUE(h.stub().ListRuns(h.Context().get(), req, &all).ok());
  EXPECT_EQ(all.runs_size(), 10);
  EXPECT_TRUE(all.next_page_token().empty());

  // A token past the last entry: an empty last page.
  req.Clear();
  req.set_page_token("zzz");
  v1::ListRunsResponse none;
  ASSERT_TRUE(h.stub().ListRuns(h.Context().get(), req, &none).ok());
  EXPECT_EQ(none.runs_size(), 0);
  EXPECT_TRUE(none.next_page_token().empty());
}

TEST(ListingTest, NegativePageSizeIsInvalidArgument) {
  Harness h;
  v1::ListRunsRequest runs;
  runs.set_page_size(-1);
  v1::ListRunsResponse runs_resp;
  ExpectError(h.stub().ListRuns(h.Context().get(), runs, &runs_resp),
              grpc::StatusCode::INVALID_ARGUMENT, "page_size = -1 must be >= 0");
  v1::ListTemplatesRequest templates;
  templates.set_page_size(-5);
  v1::ListTemplatesResponse templates_resp;
  ExpectError(h.stub().ListTemplates(h.Context().get(), templates, &templates_resp),
              grpc::StatusCode::INVALID_ARGUMENT, "page_size = -5 must be >= 0");
}

TEST(ListingTest, BadPageTokenIsInvalidArgument) {
  Harness h;
  for (const std::string& token :
       {std::string("../etc"), std::string(129, 'a'), std::string("a b"), std::string("run\n")}) {
    v1::ListRunsRequest runs;
    runs.set_page_token(token);
    v1::ListRunsResponse runs_resp;
    ExpectError(h.stub().ListRuns(h.Context().get(), runs, &runs_resp),
                grpc::StatusCode::INVALID_ARGUMENT, "page_token");
    v1::ListTemplatesRequest templates;
    templates.set_page_token(token);
    v1::ListTemplatesResponse templates_resp;
    ExpectError(h.stub().ListTemplates(h.Context().get(), templates, &templates_resp),
                grpc::StatusCode::INVALID_ARGUMENT, "page_token");
  }
}

TEST(ListingTest, RemoteServerReadsEveryPage) {
  Harness h(SmallMessages());
  constexpr int kTemplates = 300, kRuns = 8000;
  PutTemplates(h.server().registry(), kTemplates);
  PutRuns(h.server().registry(), kRuns);
  absl::StatusOr<std::unique_ptr<client::RemoteServer>> remote =
      client::RemoteServer::Connect(h.server().address(), {});
  ASSERT_TRUE(remote.ok()) << remote.status();
  absl::StatusOr<std::vector<TemplateInfo>> templates = (*remote)->ListTemplates();
  ASSERT_TRUE(templates.ok()) << templates.status();
  ASSERT_EQ(templates->size(), static_cast<std::size_t>(kTemplates));
  for (int k = 0; k < kTemplates; ++k) EXPECT_EQ((*templates)[k].name, LongName("template", k));
  absl::StatusOr<std::vector<RunInfo>> runs = (*remote)->ListRuns();
  ASSERT_TRUE(runs.ok()) << runs.status();
  ASSERT_EQ(runs->size(), static_cast<std::size_t>(kRuns));
  for (int k = 0; k < kRuns; ++k) EXPECT_EQ((*runs)[k].run_id, LongName("run", k));
}

}  // namespace
}  // namespace rvehub::service::testing
