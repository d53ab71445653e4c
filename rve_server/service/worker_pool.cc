#include "rve_server/service/worker_pool.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

namespace rvehub::service {
namespace {

// How long a worker out of work watches for the next job before it sleeps.
// Waking a sleeping thread on an idle virtual CPU costs ~70 µs per round trip
// here (7 µs on a busy one), twice per batch: an MPM step's batch of small
// one-DEM-step increments (consolidation-1d: 200 RVEs, ~2 ms) left the
// workers idle 15–23 % of the run; watching for 1 ms, 8–9 %. Watching yields
// the CPU on every look, so the caller's grid work between batches runs.
constexpr auto kWatchBeforeSleep = std::chrono::microseconds(1000);

}  // namespace

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
  std::uint64_t seen = queued_.load(std::memory_order_acquire);
  bool idle = true;
  for (;;) {
    if (idle) {
      const auto until = std::chrono::steady_clock::now() + kWatchBeforeSleep;
      while (queued_.load(std::memory_order_acquire) == seen &&
             std::chrono::steady_clock::now() < until) {
        std::this_thread::yield();
      }
    }
    idle = true;
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
        idle = false;  // a job behind it may have work
        continue;
      }
      ++job->active;  // the owner waits for this before the job goes away
    }
    RunItems(*job);
    absl::MutexLock lock(&mu_);
    --job->active;
    // Watch only when no queued job has items left; a job queued from now
    // on changes `queued_`.
    idle = std::none_of(queue_.begin(), queue_.end(),
                        [](const Job* j) { return j->next.load() < j->n; });
    seen = queued_.load(std::memory_order_relaxed);
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
  queued_.fetch_add(1, std::memory_order_release);
  // Done when every index was taken and no worker is inside the job (a
  // worker raises `active` under mu_ before taking indices).
  mu_.Await(absl::Condition(
      +[](Job* j) { return j->active == 0 && j->next.load() >= j->n; }, &job));
  queue_.erase(std::remove(queue_.begin(), queue_.end(), &job), queue_.end());
}

}  // namespace rvehub::service
