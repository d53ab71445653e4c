#include "rve_server/service/worker_pool.h"

#include <algorithm>
#include <atomic>

namespace rvehub::service {

struct WorkerPool::Job {
  std::size_t n = 0;
  const std::function<void(std::size_t)>* fn = nullptr;
  std::atomic<std::size_t> next{0};
  int active = 0;  // workers inside RunItems; guarded by the pool's mu_
};

WorkerPool::WorkerPool(int threads) {
  const int n = std::max(threads, 1);
  workers_.reserve(n);
  for (int t = 0; t < n; ++t) workers_.emplace_back([this] { WorkerLoop(); });
}

WorkerPool::~WorkerPool() {
  {
    absl::MutexLock lock(&mu_);
    stop_ = true;
  }
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::RunItems(Job& job) {
  for (std::size_t k = job.next++; k < job.n; k = job.next++) (*job.fn)(k);
}

void WorkerPool::WorkerLoop() {
  for (;;) {
    Job* job = nullptr;
    {
      absl::MutexLock lock(&mu_);
      mu_.Await(absl::Condition(
          +[](WorkerPool* p)
               ABSL_EXCLUSIVE_LOCKS_REQUIRED(p->mu_) { return p->stop_ || !p->queue_.empty(); },
          this));
      if (queue_.empty()) return;  // stopping, nothing left
      job = queue_.front();
      if (job->next.load() >= job->n) {  // all handed out: nothing to take
        queue_.pop_front();
        continue;
      }
      ++job->active;  // the owner waits for this before the job goes away
    }
    RunItems(*job);
    absl::MutexLock lock(&mu_);
    --job->active;
  }
}

void WorkerPool::ParallelFor(std::size_t n, const std::function<void(std::size_t)>& fn) {
  if (n == 0) return;
  // The caller only waits, so that the server computes on exactly threads()
  // threads however many calls are in flight.
  Job job;
  job.n = n;
  job.fn = &fn;
  absl::MutexLock lock(&mu_);
  queue_.push_back(&job);
  // Done when every index was taken and no worker is inside the job (a
  // worker raises `active` under mu_ before taking indices).
  mu_.Await(absl::Condition(
      +[](Job* j) { return j->active == 0 && j->next.load() >= j->n; }, &job));
  queue_.erase(std::remove(queue_.begin(), queue_.end(), &job), queue_.end());
}

}  // namespace rvehub::service
