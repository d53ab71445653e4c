// A multiscale simulation: the MPM solver of a case with its material points'
// RVEs hosted by RVE servers (embedded in this process by default, or remote),
// plus the outputs (results.h5/.xdmf, timeseries.csv, plot.png), the progress
// line and whole-simulation checkpoints.
#ifndef RVEHUB_MPM_CLIENT_SIMULATION_H_
#define RVEHUB_MPM_CLIENT_SIMULATION_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/model.h"
#include "mpm_client/rve_pool.h"
#include "mpm_client/solver.h"
#include "rve_server/client/channel.h"
#include "store/sim_checkpoint.h"

namespace rvehub::mpm {

struct SimulationOptions {
  std::string out_dir = "out";
  std::vector<std::string> servers;  // HOST:PORT each; empty: one embedded server
  int threads = 0;                   // embedded server's workers; 0: all cores
  client::ClientOptions client;      // token, TLS, message size for remote servers
  double apply_timeout_s = 600;      // deadline of one batched Apply call, s
  // Prepared templates are cached here; empty: <out_dir>/templates.
  std::string template_cache_dir;
  // Stop after this many MPM steps of this invocation (0: run to the end),
  // writing a checkpoint there (checkpoints on or not) to resume from.
  std::int64_t stop_after_steps = 0;
  bool progress = true;                         // progress lines on stderr
  std::function<void(const std::string&)> log;  // default: stderr
};

// MPM steps a run may take at most (end_time / Δt).
inline constexpr std::int64_t kMaxSteps = 1'000'000'000;

struct SimulationSummary {
  std::int64_t steps = 0;  // MPM steps taken in this invocation
  std::int64_t final_step = 0;
  double final_time = 0.0;  // s, simulated
  double wall_s = 0.0;      // s, this invocation's stepping loop
  double rve_s = 0.0;       // s, of wall_s spent in RVE calls (Apply)
  double output_s = 0.0;    // s, of wall_s spent writing outputs/checkpoints
  std::int64_t rve_evaluations = 0;
  bool finished = false;  // reached the case's end time
  // What the RVE calls cost in this invocation: DEM steps per increment and
  // the engine's time summed over the workers (rve_workers of them).
  ApplyStats rve_stats;
  int rve_workers = 1;
};

// Where the wall time went, two lines for people: DEM engine (the engine's
// time over the workers), service/transport/idle workers (the rest of the
// RVE calls), grid (the MPM step itself) and output; then DEM steps per
// increment, mean and histogram.
std::string FormatTimeSplit(const SimulationSummary& summary);

class Simulation {
 public:
  // Sets the case up: templates (prepared or read), servers, material points,
  // RVEs created (and consolidated to their geostatic stresses) on the
  // servers, the time step, and the output files with frame 0.
  static absl::StatusOr<std::unique_ptr<Simulation>> Start(const CaseSpec& spec,
                                                           const SimulationOptions& options);
  // Continues from a checkpoint written by a run (its case, MPM state and
  // RVEs), rewriting outputs after the checkpoint's step.
  static absl::StatusOr<std::unique_ptr<Simulation>> Resume(const std::string& checkpoint_path,
                                                            const SimulationOptions& options);
  ~Simulation();

  // Steps to the end time (or SimulationOptions::stop_after_steps).
  absl::StatusOr<SimulationSummary> StepToEnd();

  const CaseSpec& spec() const { return spec_; }
  const Solver& solver() const { return *solver_; }
  RvePool& pool() { return *pool_; }
  // The whole state as a checkpoint would hold it.
  absl::StatusOr<store::SimCheckpoint> Snapshot();

 private:
  Simulation() = default;
  absl::Status Connect();  // endpoints and pool
  absl::Status UploadTemplates();
  // The name of a case template on the servers: unique to this run.
  std::string ServerTemplateName(const std::string& name) const;
  absl::Status OpenOutputs(bool resume);
  absl::Status WriteFrame();
  absl::Status WriteRow(double wall_per_step);
  absl::Status WriteCheckpoint();
  std::vector<std::string> Columns() const;
  // The options sent with every Apply, from the case and the solver's Δt.
  void SetApplyOptions();
  void Log(const std::string& line) const;

  CaseSpec spec_;
  std::string case_json_;
  SimulationOptions options_;
  std::string run_id_;
  std::vector<store::TemplateRecord> templates_;
  std::unique_ptr<RvePool> pool_;
  std::unique_ptr<StressModel> model_;
  std::unique_ptr<Solver> solver_;
  struct Outputs;
  std::unique_ptr<Outputs> out_;
  double rve_seconds_ = 0.0;  // total wall time inside RVE Apply calls
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_SIMULATION_H_
