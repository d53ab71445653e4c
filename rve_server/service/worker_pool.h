// A fixed set of worker threads shared by all calls of a server. ParallelFor
// blocks its caller until every index is done; a worker out of work watches
// for the next job for a millisecond before it sleeps; concurrent callers share the
// workers (first come, first served). Work items of one call run in any order on any thread, so
// callers keep results per index (determinism comes from each item being independent).
#ifndef RVEHUB_RVE_SERVER_SERVICE_WORKER_POOL_H_
#define RVEHUB_RVE_SERVER_SERVICE_WORKER_POOL_H_

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <thread>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"

namespace rvehub::service {

class WorkerPool {
 public:
  explicit WorkerPool(int threads);  // threads ≥ 1
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()); }

  // Runs fn(0) … fn(n − 1) on the workers and returns when all are done.
  void ParallelFor(std::size_t n, const std::function<void(std::size_t)>& fn);

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
