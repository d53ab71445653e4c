#include "rve_server/service/worker_pool.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

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

std::size_t GuidedRunEnd(const std::vector<double>& cost_before, std::size_t start, double shares) {
  const std::size_t n = cost_before.size() - 1;
  const double share = (cost_before[n] - cost_before[start]) / shares;
  if (!(share > 0)) return start + 1;  // the rest costs nothing: one at a time
  const auto end = std::lower_bound(cost_before.begin() + start + 1, cost_before.end() - 1,
                                    cost_before[start] + share);
  return static_cast<std::size_t>(end - cost_before.begin());
}

struct WorkerPool::Job {
  std::size_t n = 0;
  const std::function<void(std::size_t)>* fn = nullptr;
  // Σ costs of the indices before k, k = 0 … n; empty: one index at a time.
  std::vector<double> cost_before;
  double shares = 0;  // the rest's cost is split in this many runs
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
  if (job.cost_before.empty()) {
    for (std::size_t k = job.next++; k < job.n; k = job.next++) (*job.fn)(k);
    return;
  }
  std::size_t start = job.next.load();
  for (;;) {
    std::size_t end;
    do {
      if (start >= job.n) return;
      end = GuidedRunEnd(job.cost_before, start, job.shares);
    } while (!job.next.compare_exchange_weak(start, end));
    for (std::size_t k = start; k < end; ++k) (*job.fn)(k);
    start = job.next.load();
  }
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

void WorkerPool::ParallelFor(std::size_t n, const std::function<void(std::size_t)>& fn,
                             std::span<const double> costs) {
  if (n == 0) return;
  // The caller only waits, so that the server computes on exactly threads()
  // threads however many calls are in flight.
  Job job;
  job.n = n;
  job.fn = &fn;
  if (costs.size() == n) {
    job.cost_before.resize(n + 1, 0.0);
    for (std::size_t k = 0; k < n; ++k) {
      const double c = std::isfinite(costs[k]) && costs[k] > 0 ? costs[k] : 0.0;
      job.cost_before[k + 1] = job.cost_before[k] + c;
    }
    job.shares = 2.0 * static_cast<double>(threads());
  }
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
