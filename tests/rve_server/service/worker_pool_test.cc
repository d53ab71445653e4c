// WorkerPool: every index runs exactly once, concurrent callers share the
// workers, and a call returns only when its items are done.
#include "rve_server/service/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <limits>
#include <thread>
#include <vector>

namespace rvehub::service {
namespace {

TEST(WorkerPoolTest, EveryIndexRunsExactlyOnce) {
  WorkerPool pool(3);
  EXPECT_EQ(pool.threads(), 3);
  std::vector<std::atomic<int>> hits(1000);
  pool.ParallelFor(hits.size(), [&](std::size_t k) { ++hits[k]; });
  for (std::size_t k = 0; k < hits.size(); ++k) ASSERT_EQ(hits[k].load(), 1) << k;
  pool.ParallelFor(0, [&](std::size_t) { FAIL() << "no item expected"; });
}

TEST(WorkerPoolTest, ConcurrentCallersEachGetTheirOwnItemsDone) {
  WorkerPool pool(2);
  constexpr int kCallers = 4;
  constexpr std::size_t kItems = 200;
  std::vector<std::vector<int>> results(kCallers, std::vector<int>(kItems, 0));
  std::vector<std::thread> callers;
  for (int c = 0; c < kCallers; ++c) {
    callers.emplace_back([&, c] {
      for (int round = 0; round < 20; ++round) {
        pool.ParallelFor(kItems, [&](std::size_t k) { results[c][k] += 1; });
        // All items of this call are finished when ParallelFor returns.
        for (std::size_t k = 0; k < kItems; ++k) ASSERT_EQ(results[c][k], round + 1);
      }
    });
  }
  for (std::thread& t : callers) t.join();
}

// Workers out of work watch for the next job for a while, then sleep: calls
// that follow each other at once, within the watch and after it all get
// every item done exactly once.
TEST(WorkerPoolTest, CallsAfterShortAndLongPausesAreAllDone) {
  WorkerPool pool(2);
  for (int pause_us : {0, 0, 100, 500, 3000, 0, 2000, 50}) {
    std::this_thread::sleep_for(std::chrono::microseconds(pause_us));
    std::vector<std::atomic<int>> hits(64);
    pool.ParallelFor(hits.size(), [&](std::size_t k) { ++hits[k]; });
    for (std::size_t k = 0; k < hits.size(); ++k) ASSERT_EQ(hits[k].load(), 1) << pause_us;
  }
}

TEST(WorkerPoolTest, RunsOnWorkerThreadsOnly) {
  WorkerPool pool(1);
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> on_caller{0};
  pool.ParallelFor(50, [&](std::size_t) { on_caller += std::this_thread::get_id() == caller; });
  EXPECT_EQ(on_caller.load(), 0);
}

// With costs, workers take runs of indices: still every index exactly once,
// whatever the costs (zero, negative, not finite, unsorted).
TEST(WorkerPoolTest, CostsGroupIndicesButEachRunsExactlyOnce) {
  WorkerPool pool(3);
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::vector<double>> cases = {
      {5, 4, 3, 2, 1}, {0, 0, 0, 0, 0, 0, 0},   {1},          {1e6, 1, 1, 1, 1, 1, 1, 1, 1},
      {1, 2, 3, 4, 5}, {inf, 1, nan, -3, 2, 0}, {0, 0, 0, 7}, std::vector<double>(5000, 800.0)};
  for (const std::vector<double>& costs : cases) {
    std::vector<std::atomic<int>> hits(costs.size());
    pool.ParallelFor(
        hits.size(), [&](std::size_t k) { ++hits[k]; }, costs);
    for (std::size_t k = 0; k < hits.size(); ++k) ASSERT_EQ(hits[k].load(), 1) << k;
  }
  // Costs of the wrong length are ignored: one index at a time.
  std::vector<std::atomic<int>> hits(10);
  const std::vector<double> short_costs = {1, 2};
  pool.ParallelFor(
      hits.size(), [&](std::size_t k) { ++hits[k]; }, short_costs);
  for (std::size_t k = 0; k < hits.size(); ++k) ASSERT_EQ(hits[k].load(), 1) << k;
}

// A run reaches a share of the rest's cost: equal costs give runs of a
// quarter of what is left on two workers, an expensive index a run of its own.
TEST(WorkerPoolTest, GuidedRunsReachTheirShareOfTheRest) {
  auto before = [](const std::vector<double>& costs) {
    std::vector<double> b(costs.size() + 1, 0.0);
    for (std::size_t k = 0; k < costs.size(); ++k) b[k + 1] = b[k] + costs[k];
    return b;
  };
  const std::vector<double> equal = before(std::vector<double>(1000, 1.0));
  EXPECT_EQ(GuidedRunEnd(equal, 0, 4.0), 250u);
  EXPECT_EQ(GuidedRunEnd(equal, 250, 4.0), 250u + 188u);  // ⌈750/4⌉
  EXPECT_EQ(GuidedRunEnd(equal, 996, 4.0), 997u);         // the tail: one at a time
  EXPECT_EQ(GuidedRunEnd(equal, 999, 4.0), 1000u);
  std::vector<double> costs(1000, 1.0);
  costs[0] = 600.0;
  const std::vector<double> heavy_first = before(costs);
  EXPECT_EQ(GuidedRunEnd(heavy_first, 0, 4.0), 1u);
  EXPECT_EQ(GuidedRunEnd(heavy_first, 1, 4.0), 1u + 250u);
  const std::vector<double> free_rest = before({3.0, 0.0, 0.0, 0.0});
  EXPECT_EQ(GuidedRunEnd(free_rest, 1, 4.0), 2u);  // nothing left to share: one index
}

}  // namespace
}  // namespace rvehub::service
