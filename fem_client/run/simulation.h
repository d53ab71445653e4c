// A FEM×DEM run (G&Z §2.3): the implicit solver of a FemCase (core/) with
// an RVE at every Gauss point, hosted by RVE servers (embedded in this
// process by default, or remote), plus the outputs in one directory:
// timeseries.csv, summary.json and plot.png (output.h), iterations.csv
// (step, substep, fraction of the step, iteration, E_d, E_f: every Newton
// iteration of the converged sub-steps, G&Z Fig. 7), results.h5 +
// results.xdmf (every Gauss point as a point of its own every
// output.frame_every steps and at the last: its Cauchy stress, tension + as
// the RVE gives it; p and q, compression +; ε_q and ε_v of G&Z eqs. 12–13
// from the total displacement, compression +; void ratio, coordination,
// fabric anisotropy and its id; a frame's time is its load step) and
// packings-<step>.h5 (the RVEs of output.packings at those frames).
#ifndef RVEHUB_FEM_CLIENT_RUN_SIMULATION_H_
#define RVEHUB_FEM_CLIENT_RUN_SIMULATION_H_

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "client_case/overrides.h"
#include "client_run/time_split.h"
#include "fem_client/case/fem_case.h"
#include "fem_client/core/static_solver.h"
#include "fem_client/run/problem.h"
#include "fem_client/run/rve_material.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/rve_pool.h"
#include "rve_server/values/record.h"

namespace rvehub::fem {

using client_case::CaseOverride;

// The case fields a resume may change (fem_client resume --set): how the
// Newton iterations of the next steps run, none of what the checkpoint's
// state depends on.
inline constexpr std::array<absl::string_view, 8> kResumableSettings = {
    "/solver/tangent",      "/solver/perturbation",    "/solver/predictor",
    "/solver/tolerance",    "/solver/force_tolerance", "/solver/max_iterations",
    "/solver/max_cutbacks", "/solver/unconverged"};

// InvalidArgument "--set <pointer>: a resume may change only the Newton
// settings (...)" for the first override outside kResumableSettings.
absl::Status CheckResumableOverrides(std::span<const CaseOverride> overrides);

struct FemSimulationOptions {
  std::string out_dir = "out";
  std::vector<std::string> servers;  // HOST:PORT each; empty: one embedded server
  int threads = 0;                   // embedded server's workers; 0: all cores
  client::ClientOptions client;      // token, TLS, message size for remote servers
  double apply_timeout_s = 600;      // deadline of one batched TRIAL or COMMIT at most, s
  // Prepared templates are cached here; empty: <out_dir>/templates.
  std::string template_cache_dir;
  // Stop after this many load steps (0: run to the end), with a checkpoint
  // there (<out_dir>/checkpoint.h5) to resume from.
  std::int64_t stop_after_steps = 0;
  // With remote servers: a lost server (unreachable, crashed, its calls
  // past their deadline) is survived. After every load step the run keeps
  // a recovery point (every RVE's state and the solver's); a step that
  // loses a server goes back to it, its RVEs restored onto the servers
  // left, and runs again, giving what the run would have given without
  // the failure, bit for bit. A lost server that answers again rejoins at
  // the next recovery point (what it held of the run dropped first).
  // false: a lost server ends the run (resume from a checkpoint).
  bool recovery = true;
  // With every server lost, how long to wait for one to answer again, s.
  double server_wait_s = 60.0;
  // A lost server is asked whether it is back at most this often, s.
  double probe_interval_s = 5.0;
  bool progress = true;  // progress lines
  // A progress line also comes when this much wall time has passed since the
  // last one, s (a late load step may take minutes).
  double progress_interval_s = 60.0;
  std::function<void(const std::string&)> log;  // default: stderr
  // Called after each checkpoint is written, with its load step and the wall
  // time of this invocation's stepping so far, s (the run record keeps it).
  std::function<void(std::int64_t step, double wall_s)> on_checkpoint;
};

struct FemRunSummary {
  std::int64_t steps = 0;        // load steps taken in this run
  std::int64_t final_step = 0;   // the last load step done
  std::int64_t total_steps = 0;  // the case's
  bool finished = false;         // all the case's load steps done
  std::int64_t iterations = 0;   // Newton iterations over the steps
  std::int64_t cutbacks = 0;
  std::int64_t unconverged = 0;       // sub-steps accepted unconverged (solver.unconverged)
  std::int64_t trials = 0;            // TRIAL calls over every RVE
  std::int64_t servers_lost = 0;      // lost servers survived
  std::int64_t servers_rejoined = 0;  // lost servers that answered again and took RVEs
  double recovery_s = 0.0;            // s of wall_s taking recovery points and recovering
  // Where the wall time went: the stepping loop, the RVE calls (TRIALs and
  // COMMITs), the outputs; the increments' DEM steps and engine time.
  client_run::TimeSplit split;
};

class FemSimulation {
 public:
  // Sets the case up, in stages: the problem (mesh, boundaries, load steps:
  // a case the run layer cannot run fails here, before anything is
  // written), the output directory, the templates (prepared and cached, or
  // read), the endpoints, the templates uploaded, one RVE per Gauss point
  // (id = the Gauss point's, consolidated to material.initial_stress), the
  // solver, and the outputs with row and frame 0.
  static absl::StatusOr<std::unique_ptr<FemSimulation>> Start(const FemCase& c,
                                                              const FemSimulationOptions& options);
  // Continues a run from its checkpoint (written every
  // output.checkpoint_every load steps, at the last and at --stop-after): the
  // case it holds, its templates and RVEs (imported into the servers of
  // `options`, which may differ from the first run's), the solver's state.
  // The outputs in options.out_dir go on after the checkpoint's step (rows
  // and frames after it dropped), so that a run stopped and resumed gives
  // the uninterrupted run's outputs bit for bit, wall times aside.
  // `solver_overrides` change the Newton settings from here on (a tangent
  // or tolerance that suits the post-peak steps better than the pre-peak
  // ones); the checkpoints written after carry the changed case. Only the
  // pointers of kResumableSettings may change: the rest of the case is what
  // the state was computed with.
  // DataLoss for a checkpoint that is not one (ReadSimCheckpoint's errors,
  // a case that does not parse, a state that does not fit the case);
  // InvalidArgument naming the pointer for an override that is not one of
  // those settings or whose value the case reader refuses.
  static absl::StatusOr<std::unique_ptr<FemSimulation>> Resume(
      const std::string& checkpoint_path, const FemSimulationOptions& options,
      std::span<const CaseOverride> solver_overrides = {});
  ~FemSimulation();

  // Steps to the case's last load step (or FemSimulationOptions::
  // stop_after_steps). A step that fails for good (no convergence after
  // the cut-backs, a lost server) ends the run with the solver's error,
  // the outputs kept up to the step before; summary.json and plot.png are
  // written when the run finishes.
  absl::StatusOr<FemRunSummary> StepToEnd();

  const FemCase& spec() const { return case_; }
  const StaticSolver& solver() const { return *solver_; }
  const Problem& problem() const { return problem_; }
  client::RvePool& pool() { return *pool_; }

 private:
  FemSimulation() = default;

  // Start's stages after the problem, in order.
  absl::Status ResolveCaseTemplates();
  absl::Status Connect();
  absl::Status UploadTemplates();
  absl::Status CreateRves();
  absl::Status CreateSolver();
  absl::Status OpenOutputs(bool resume);
  // The rows of iterations.csv of a load step: each converged sub-step's
  // Newton iterations (1-based), with E_d and E_f.
  absl::Status WriteIterations(std::int64_t step, const StepReport& report);
  // <out_dir>/checkpoint.h5 of the current state (atomically replaced);
  // `rves`: every RVE's record now (a recovery point's), or none to export them.
  absl::Status WriteCheckpoint(const std::vector<RveRecord>* rves = nullptr);

  // Surviving lost servers (FemSimulationOptions::recovery).
  struct RecoveryPoint;
  bool RecoveryOn() const;
  // The state after the last load step, as a recovery point; servers back
  // from a loss rejoin here.
  absl::Status TakeRecoveryPoint(FemRunSummary& sum);
  // Lost servers that answer again, their stale RVEs of the run dropped,
  // marked alive (force: ask each now). Whether any rejoined.
  bool ProbeLost(bool force, FemRunSummary& sum);
  // After a step failed with `cause`: the servers it lost marked lost, the
  // recovery point restored onto those left (waiting for one when none
  // is), the solver and outputs back at the point. `cause` again when no
  // server was lost (the error is the run's) or there is no point.
  absl::Status Recover(const absl::Status& cause, FemRunSummary& sum);

  // The row of the current state (after load step `step`; its report when
  // there was one) and the frame of every Gauss point.
  struct StepFigures;
  absl::Status WriteRow(const StepFigures& figures);
  absl::Status WriteFrame();
  // The RVE states of the current state: those of the last COMMIT, or the
  // created ones before the first step.
  const std::vector<dem::RveState>& States() const;
  void Log(const std::string& line) const;

  FemCase case_;
  std::string case_json_;  // ToJson(case_): what a checkpoint carries
  FemSimulationOptions options_;
  Problem problem_;
  std::string run_id_;
  std::vector<TemplateRecord> templates_;
  std::unique_ptr<client::RvePool> pool_;
  std::vector<dem::RveState> created_;  // the RVEs' states after creation
  std::unique_ptr<RveMaterial> material_;
  std::unique_ptr<StaticSolver> solver_;
  Mesh mesh0_;  // the mesh as created: the reference of the total strains
  std::vector<PointGeometry> geometry0_;
  double area0_ = 0.0;  // m², the mesh's initial area (per m of thickness)
  struct Outputs;
  std::unique_ptr<Outputs> out_;
  std::unique_ptr<RecoveryPoint> recovery_;
  std::vector<double> last_probe_s_;  // per endpoint: when it was last asked, s
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_RUN_SIMULATION_H_
