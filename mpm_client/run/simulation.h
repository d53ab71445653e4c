// A multiscale simulation: the MPM solver of a case with its material points'
// RVEs hosted by RVE servers (embedded in this process by default, or remote),
// plus the outputs (results.h5/.xdmf, timeseries.csv, plot.png), the progress
// line and whole-simulation checkpoints.
#ifndef RVEHUB_MPM_CLIENT_RUN_SIMULATION_H_
#define RVEHUB_MPM_CLIENT_RUN_SIMULATION_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/solver.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/rve_pool.h"
#include "store/sim_checkpoint.h"

namespace rvehub::mpm {

struct SimulationOptions {
  std::string out_dir = "out";
  std::vector<std::string> servers;  // HOST:PORT each; empty: one embedded server
  int threads = 0;                   // embedded server's workers; 0: all cores
  client::ClientOptions client;      // token, TLS, message size for remote servers
  double apply_timeout_s = 600;      // deadline of one batched Apply call at most, s
  // Remote servers only. The client keeps a recovery point in memory (the
  // MPM state and every RVE's full state), refreshed so that taking it costs
  // about `recovery_share` of the stepping time. A server that fails for
  // good (refused, reset, or a missed deadline after the retries) is
  // dropped: its RVEs and everyone else's go back to the recovery point on
  // the servers left, the MPM state rolls back and the steps are replayed,
  // bit-identical to a run without the failure. A lost server that answers
  // again (probed every few seconds at recovery points) rejoins and takes
  // RVEs. false: a lost server ends the run (resume from a checkpoint).
  bool recovery = true;
  double recovery_share = 0.02;
  // The deadline of an Apply attempt adapts: `deadline_factor` × the slowest
  // server batch of the last steps, at least min_apply_timeout_s, at most
  // apply_timeout_s (a hung server is found in seconds).
  double deadline_factor = 20;
  double min_apply_timeout_s = 10;
  // Balancing by measured cost: at a recovery point, points move between
  // servers (longest first by the work the servers reported since the last
  // point, DEM steps × particles) when that plan's makespan beats the
  // current one by more than this share at two points in a row. 0: never.
  double rebalance_threshold = 0.1;
  // With every server lost, how long to wait for one to answer again, s.
  double server_wait_s = 60;
  // A lost server is asked whether it is back at most this often, s (the
  // wait doubles while it does not answer, up to 12 × this).
  double probe_interval_s = 5;
  // Prepared templates are cached here; empty: <out_dir>/templates.
  std::string template_cache_dir;
  // Stop after this many MPM steps of this invocation (0: run to the end),
  // writing a checkpoint there (checkpoints on or not) to resume from.
  std::int64_t stop_after_steps = 0;
  // Resume only: the run's new end time, s (0: the case's). Lets a run that
  // ended, or was planned too short, go on; later checkpoints carry it.
  double end_time = 0;
  // Resume only: a new CFL number (0: the case's) for a run whose case takes
  // its time step from one; Δt changes by the ratio of the two and later
  // checkpoints carry the new number.
  double cfl = 0;
  // Resume only: the run's F-bar from the checkpoint on (unset: the case's
  // solver.f_bar); later checkpoints carry it.
  std::optional<FBar> f_bar;
  // Resume only: the run's nonlocal strain radius from the checkpoint on, m
  // (0 turns it off; unset: the case's solver.nonlocal_radius).
  std::optional<double> nonlocal_radius;
  // Resume only: its solver.nonlocal_fraction from the checkpoint on, (0, 1].
  std::optional<double> nonlocal_fraction;
  bool progress = true;  // progress lines on stderr
  // A progress line also comes when this much wall time has passed since the
  // last one, s: a run whose steps have slowed to seconds each (a soil blown
  // apart) would otherwise look hung for output.progress_every steps.
  double progress_interval_s = 60.0;
  std::function<void(const std::string&)> log;  // default: stderr
  // Called after each checkpoint is written, with its MPM step and the wall
  // time of this invocation's stepping so far, s (the run record keeps it).
  std::function<void(std::int64_t step, double wall_s)> on_checkpoint;
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
  client::ApplyStats rve_stats;
  int rve_workers = 1;
  // Faults and balancing in this invocation.
  int servers_lost = 0;
  int servers_rejoined = 0;
  std::int64_t steps_replayed = 0;
  std::int64_t rves_moved = 0;  // by rebalancing and rejoining
  int recovery_points = 0;
  double recovery_s = 0.0;  // s, of wall_s taking recovery points and recovering
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
  client::RvePool& pool() { return *pool_; }
  // The whole state as a checkpoint would hold it.
  absl::StatusOr<store::SimCheckpoint> Snapshot();

 private:
  Simulation() = default;

  // Start's stages, in order.
  // The case's templates, prepared (and cached) or read from their files.
  absl::Status ResolveCaseTemplates();
  const TemplateRecord& CaseTemplate(const std::string& name) const;
  absl::Status Connect();  // endpoints and pool
  absl::Status UploadTemplates();
  // Each region's bulk density, kg/m³: the case's, else its template's.
  std::vector<double> RegionDensities() const;
  // What each point's RVE starts from: its template on the servers, its
  // initial stress (geostatic where the region asks for it) and its cost
  // (discs) for the assignment to servers; logs notes on regions that start
  // below what a packing consolidates to, or that a floor lifts.
  struct RveStarts {
    std::vector<std::string> template_of;
    std::vector<InitialStress> initial;
    std::vector<double> cost;
    // −σ'yy,0 the excess pore pressure ratio is taken against, Pa
    // (compression +): the geostatic effective stress of the point's depth,
    // without the floor (initial_stress.minimum) that only lets its RVE
    // consolidate; NaN where the region starts from the template (the
    // RVE's own σyy then).
    std::vector<double> vertical_stress0;
  };
  RveStarts PlanRveStarts(const MaterialPoints& points, const std::vector<double>& density) const;
  // Creates (and consolidates) the RVEs on the servers, with a progress line
  // every ~2 s, and gives the points their RVEs' stresses and responses.
  absl::Status CreateRves(const RveStarts& starts, MaterialPoints& points);
  // The case's Δt, or the CFL step from the stiffest RVE's tangent, s.
  absl::StatusOr<double> InitialTimeStep(const std::vector<double>& density);

  // The name of a case template on the servers: unique to this run.
  std::string ServerTemplateName(const std::string& name) const;
  absl::Status OpenOutputs(bool resume);
  absl::Status WriteFrame();
  absl::Status WriteRow(double wall_per_step);
  absl::Status WriteCheckpoint();

  // Surviving lost servers (SimulationOptions::recovery).
  struct RecoveryPoint;
  bool RecoveryOn() const;
  // Takes the MPM state and every RVE's state at the current step; probes
  // lost servers and rebalances. An error from a server is left for Recover.
  absl::Status TakeRecoveryPoint(SimulationSummary& sum);
  // After `cause`: drops the servers that failed, restores every RVE from
  // the recovery point onto the servers left and rolls the MPM state and the
  // outputs back to it. `cause` itself when no server failed (not a loss).
  absl::Status Recover(const absl::Status& cause, SimulationSummary& sum);
  // Lost servers that answer again rejoin (empty, RVE-less); `force`:
  // probe now, else at most every few seconds each. Whether one rejoined.
  bool ProbeLost(bool force, SimulationSummary& sum);
  // Moves points between servers by the measured cost since the last
  // check (see SimulationOptions::rebalance_threshold); `force`: now.
  absl::Status Rebalance(bool force, SimulationSummary& sum);
  // Per-server load and idle share since the last progress line.
  std::string ServerLoadLine();
  std::vector<std::string> Columns() const;
  // Whether the timeseries carries deposit_front_x (collapse summaries).
  bool WritesDepositFront() const;
  // The options sent with every Apply, from the case and the solver's Δt.
  void SetApplyOptions();
  // Δt from the points' current wave speeds (SolverSpec::time_step_update_every).
  absl::Status UpdateTimeStep();
  void Log(const std::string& line) const;
  // Says, at set-up, where a rectangle body's corner lies inside a grid cell
  // over soil (CornerOverhang): the load then acts on a wider strip than the body.
  void LogCornerOverhangs() const;
  // Logs each point the solver parked off the grid since the last call.
  void LogLostPoints();

  CaseSpec spec_;
  std::string case_json_;
  SimulationOptions options_;
  std::string run_id_;
  std::vector<TemplateRecord> templates_;
  std::unique_ptr<client::RvePool> pool_;
  std::unique_ptr<StressModel> model_;
  std::unique_ptr<Solver> solver_;
  struct Outputs;
  std::unique_ptr<Outputs> out_;
  double rve_seconds_ = 0.0;  // total wall time inside RVE calls (Apply, tangents)
  std::unique_ptr<RecoveryPoint> recovery_;
  std::int64_t recovery_interval_ = 10;  // MPM steps between recovery points
  std::vector<double> cost_checked_;     // RvePool::point_work at the last balance check
  int imbalance_streak_ = 0;
  std::vector<double> last_probe_s_;  // per server, wall clock of its last probe, s
  // Per server, the wait before its next probe, s: probe_interval_s, doubled
  // after each unanswered probe up to 12 × that (a hung server costs its
  // probe's deadline each time).
  std::vector<double> probe_wait_s_;
  // At the last progress line: per server busy and engine seconds, and the
  // pool's Apply wall time.
  std::vector<double> busy_shown_, engine_shown_;
  double apply_shown_ = 0.0;
  // Per point, whether its drop off the grid was logged (kDrop).
  std::vector<std::uint8_t> lost_logged_;
};

}  // namespace rvehub::mpm

#endif  // RVEHUB_MPM_CLIENT_RUN_SIMULATION_H_
