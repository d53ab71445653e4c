// WorkerPool: every index runs exactly once, concurrent callers share the
// workers, and a call returns only when its items are done.
#include "rve_server/service/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
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

}  // namespace
}  // namespace rvehub::service
