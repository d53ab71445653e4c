// bench_store: write and read speed of the HDF5 checkpoint store, and its
// size per RVE. 2000 RVE records of the SET-dense packing (400 discs, ~830
// contacts, prepared once at start-up), each with its own run/id, written
// with store::WriteRves and read back with store::ReadRves; best of 3.
// Prints one line per figure next to the project's goals (write ≥ 300 MB/s,
// ≤ 60 KB per 400-disc RVE). Plain main: nothing passes or fails.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/values/material.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kRecords = 2000;
constexpr int kRepetitions = 3;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// Bitwise equality of the particle and contact arrays (a cheap check that
// the timed read returned what was written).
bool SamePacking(const rvehub::dem::RveSnapshot& a, const rvehub::dem::RveSnapshot& b) {
  auto same = [](const std::vector<double>& x, const std::vector<double>& y) {
    return x.size() == y.size() &&
           (x.empty() || std::memcmp(x.data(), y.data(), 8 * x.size()) == 0);
  };
  if (!same(a.radius, b.radius) || !same(a.sx, b.sx) || !same(a.sy, b.sy) || !same(a.vx, b.vx) ||
      !same(a.vy, b.vy) || !same(a.omega, b.omega) || !same(a.theta, b.theta) ||
      a.contacts.size() != b.contacts.size()) {
    return false;
  }
  for (std::size_t k = 0; k < a.contacts.size(); ++k) {
    const auto &x = a.contacts[k], &y = b.contacts[k];
    if (x.i != y.i || x.j != y.j || std::memcmp(&x.tangential_force, &y.tangential_force, 8) != 0 ||
        std::memcmp(&x.rolling_moment, &y.rolling_moment, 8) != 0 ||
        std::memcmp(&x.bond_strength, &y.bond_strength, 8) != 0) {
      return false;
    }
  }
  return true;
}

int Run() {
  using rvehub::RveRecord;
  const auto t0 = Clock::now();
  absl::StatusOr<rvehub::dem::ParameterSet> set = rvehub::dem::FindParameterSet("SET-dense");
  if (!set.ok()) {
    std::fprintf(stderr, "%s\n", set.status().ToString().c_str());
    return 1;
  }
  absl::StatusOr<rvehub::dem::RveSnapshot> packing = rvehub::dem::PreparePacking(*set);
  if (!packing.ok()) {
    std::fprintf(stderr, "PreparePacking: %s\n", packing.status().ToString().c_str());
    return 1;
  }
  std::vector<RveRecord> rves(kRecords);
  for (int k = 0; k < kRecords; ++k) {
    RveRecord& r = rves[k];
    r.run_id = absl::StrCat("bench-run-", k / 500);  // four runs of 500 material points
    r.id = k;
    r.step = 10 + k;
    r.last_delta_f(0, 1) = 1e-4 * k;
    r.packing = *packing;
    // Distinct states, so that no record is a byte copy of another.
    for (double& theta : r.packing.theta) theta += 1e-3 * k;
  }
  std::size_t contacts = 0;
  for (const RveRecord& r : rves) contacts += r.packing.contacts.size();
  const double setup_s = Seconds(t0, Clock::now());

  const fs::path dir = fs::temp_directory_path() / absl::StrCat("rvehub_bench_store_", ::getpid());
  fs::create_directories(dir);
  const std::string path = (dir / "rves.h5").string();
  const rvehub::store::FileInfo info{"bench_store", ""};

  double best_write = 1e300, best_read = 1e300;
  bool ok = true;
  for (int rep = 0; rep < kRepetitions && ok; ++rep) {
    const auto a = Clock::now();
    const absl::Status written = rvehub::store::WriteRves(path, rves, info);
    const auto b = Clock::now();
    if (!written.ok()) {
      std::fprintf(stderr, "WriteRves: %s\n", written.ToString().c_str());
      ok = false;
      break;
    }
    best_write = std::min(best_write, Seconds(a, b));
    const auto c = Clock::now();
    absl::StatusOr<std::vector<RveRecord>> read = rvehub::store::ReadRves(path);
    const auto d = Clock::now();
    if (!read.ok()) {
      std::fprintf(stderr, "ReadRves: %s\n", read.status().ToString().c_str());
      ok = false;
      break;
    }
    best_read = std::min(best_read, Seconds(c, d));
    if (read->size() != rves.size() || !SamePacking(read->front().packing, rves.front().packing) ||
        !SamePacking(read->back().packing, rves.back().packing)) {
      std::fprintf(stderr, "ReadRves returned different data\n");
      ok = false;
    }
  }
  const std::uintmax_t file_bytes = ok ? fs::file_size(path) : 0;
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  if (!ok) return 1;

  const double mb = static_cast<double>(file_bytes) / 1e6;
  const double per_rve = static_cast<double>(file_bytes) / kRecords;
  std::printf(
      "bench_store: %d RVE records of %zu discs, %.0f contacts per RVE (SET-dense, "
      "set-up %.1f s)\n",
      kRecords, packing->radius.size(), static_cast<double>(contacts) / kRecords, setup_s);
  std::printf("file size           %.1f MB (%ju bytes)\n", mb, file_bytes);
  std::printf("bytes per RVE       %.1f KB (goal <= 60 KB)   %s\n", per_rve / 1e3,
              per_rve <= 60e3 ? "met" : "NOT met");
  std::printf("WriteRves           %.3f s, %.0f MB/s (goal >= 300 MB/s)   %s\n", best_write,
              mb / best_write, mb / best_write >= 300 ? "met" : "NOT met");
  std::printf("ReadRves            %.3f s, %.0f MB/s (page cache warm)\n", best_read,
              mb / best_read);
  std::printf(
      "(best of %d; MB = 1e6 bytes of file; the write includes fsync and rename; "
      "temp dir %s)\n",
      kRepetitions, fs::temp_directory_path().c_str());
  return 0;
}

}  // namespace

int main() { return Run(); }
