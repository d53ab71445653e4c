// A fixed set of worker threads shared by all calls of a server. ParallelFor
// blocks its caller until every index is done; a worker out of work watches
// for the next job for a millisecond before it sleeps; concurrent callers share the
// workers (first come, first served). Work items of one call run in any order on any thread, so
// callers keep results per index (determinism comes from each item being independent).
// Given each item's expected cost, workers take runs of items at a time (see ParallelFor).
#ifndef RVEHUB_RVE_SERVER_SERVICE_WORKER_POOL_H_
#define RVEHUB_RVE_SERVER_SERVICE_WORKER_POOL_H_

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <span>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"

namespace rvehub::service {

// End of the run that starts at index `start` (exclusive): the first index
// where the run's cost reaches the rest's over `shares`, at least start + 1.
// cost_before[k] is the cost of the indices before k (k = 0 … n).
std::size_t GuidedRunEnd(const std::vector<double>& cost_before, std::size_t start, double shares);

class WorkerPool {
 public:
  explicit WorkerPool(int threads);  // threads ≥ 1
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()); }

  // Runs fn(0) … fn(n − 1) on the workers and returns when all are done.
  // Without costs a worker takes one index at a time. With `costs` (one per
  // index, in any unit; not positive or not finite counts as free; best
  // sorted longest first) it takes the next run of indices whose cost
  // reaches the rest's over 2·threads(), at least one (guided scheduling,
  // GuidedRunEnd): on two cores, taking each small increment's index by
  // itself cost as much as a fifth of the increment, the counter's cache line
  // passing between the workers every time. Costs of another length than n
  // are ignored.
  void ParallelFor(std::size_t n, const std::function<void(std::size_t)>& fn,
                   std::span<const double> costs = {});

 private:
  struct Job;
  void WorkerLoop();
  static void RunItems(Job& job);

  absl::Mutex mu_;
  std::deque<Job*> queue_ ABSL_GUARDED_BY(mu_);
  // Jobs ever queued: a worker out of work watches it for a while before it
  // sleeps (see WorkerLoop).
  std::atomic<std::uint64_t> queued_{0};
  bool stop_ ABSL_GUARDED_BY(mu_) = false;
  std::vector<std::thread> workers_;
};

}  // namespace rvehub::service

#endif  // RVEHUB_RVE_SERVER_SERVICE_WORKER_POOL_H_
