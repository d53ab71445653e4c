#include "fem_client/run/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <system_error>

#include "absl/algorithm/container.h"
#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "client_run/checks.h"
#include "client_run/endpoints.h"
#include "client_run/templates.h"
#include "client_run/timeseries.h"
#include "fem_client/case/case.h"
#include "fem_client/core/assembly.h"
#include "fem_client/run/checkpoint_state.h"
#include "fem_client/run/output.h"
#include "rve_server/common/elasticity.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/values/increment.h"
#include "rve_server/values/snapshot.h"
#include "rve_server/values/state.h"
#include "store/checkpoint.h"
#include "store/results.h"
#include "store/sim_checkpoint.h"
#include "toolkit/json_pointer.h"

namespace rvehub::fem {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A load step's Newton iterations and its sub-steps accepted unconverged,
// over all its sub-steps.
struct StepCounts {
  int iterations = 0;
  int unconverged = 0;
};

StepCounts Counts(const StepReport& report) {
  StepCounts c;
  for (const SubStepReport& sub : report.substeps) {
    c.iterations += static_cast<int>(sub.iterations.size());
    c.unconverged += sub.converged ? 0 : 1;
  }
  return c;
}

absl::Status MakeOutputDir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return absl::UnavailableError(
        absl::StrCat("cannot create the output directory ", dir, ": ", ec.message()));
  }
  return absl::OkStatus();
}

// A face's current length: from its first node to its last (the node sets
// run along the face), m.
double FaceLength(const Mesh& mesh, Face face) {
  const std::vector<int>& nodes = mesh.node_sets.at(FaceSetName(face));
  return (mesh.nodes[nodes.back()] - mesh.nodes[nodes.front()]).norm();
}

// The mean displacement of a face's nodes, m.
Eigen::Vector2d MeanTravel(const Mesh& mesh, const Eigen::VectorXd& u, Face face) {
  const std::vector<int>& nodes = mesh.node_sets.at(FaceSetName(face));
  Eigen::Vector2d travel = Eigen::Vector2d::Zero();
  for (int node : nodes) travel += u.segment<2>(2 * node);
  return travel / static_cast<double>(nodes.size());
}

// The driven face's nominal strains from the displacements u (m): its
// travel into the specimen, and along it relative to the face across (γ of
// a simple shear; 0 for a symmetric compression), over the length across.
struct Strains {
  double axial = 0.0;  // [-], compression +
  double shear = 0.0;  // [-]
};
Strains NominalStrains(const Mesh& mesh, const Eigen::VectorXd& u, const Problem& p) {
  const Face across = p.driven == Face::kTop      ? Face::kBottom
                      : p.driven == Face::kBottom ? Face::kTop
                      : p.driven == Face::kLeft   ? Face::kRight
                                                  : Face::kLeft;
  const Eigen::Vector2d travel = MeanTravel(mesh, u, p.driven);
  const Eigen::Vector2d slide = travel - MeanTravel(mesh, u, across);
  return {-travel.dot(OutwardNormal(p.driven)) / p.length_across,
          slide.dot(FaceTangent(p.driven)) / p.length_across};
}

// The in-plane part of a 3×3 stress.
Eigen::Matrix2d InPlane(const Eigen::Matrix3d& s) { return s.topLeftCorner<2, 2>(); }

}  // namespace

struct FemSimulation::Outputs {
  std::unique_ptr<store::ResultsWriter> results;
  std::unique_ptr<client_run::TimeseriesWriter> timeseries;
  // iterations.csv: every Newton iteration of every load step (G&Z Fig. 7).
  std::unique_ptr<client_run::TimeseriesWriter> iterations;
  std::int64_t last_frame_step = -1;
};

// What a row records of a load step beyond the state.
struct FemSimulation::StepFigures {
  std::int64_t step = 0;
  const StepReport* report = nullptr;  // none for row 0
  double dem_steps_per_trial = 0.0;
  double wall_step_s = 0.0;
};

FemSimulation::~FemSimulation() {
  if (pool_ != nullptr) {
    // Free the servers' memory; a failure here only leaks RVEs on a server
    // that is going away anyway.
    (void)pool_->DropAll();
  }
}

void FemSimulation::Log(const std::string& line) const {
  if (options_.log) {
    options_.log(line);
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
}

absl::StatusOr<std::unique_ptr<FemSimulation>> FemSimulation::Start(
    const FemCase& c, const FemSimulationOptions& options) {
  std::unique_ptr<FemSimulation> sim(new FemSimulation());
  sim->case_ = c;
  sim->case_json_ = ToJson(c);
  sim->options_ = options;
  // A case the run layer refuses fails before anything is written.
  ASSIGN_OR_RETURN(sim->problem_, BuildProblem(c));
  sim->run_id_ = client_run::MakeRunId(c.name);
  RETURN_IF_ERROR(MakeOutputDir(options.out_dir));
  for (const std::string& note : sim->problem_.notes) sim->Log(note);
  RETURN_IF_ERROR(sim->ResolveCaseTemplates());
  RETURN_IF_ERROR(sim->Connect());
  RETURN_IF_ERROR(sim->UploadTemplates());
  RETURN_IF_ERROR(sim->CreateRves());
  RETURN_IF_ERROR(sim->CreateSolver());
  RETURN_IF_ERROR(sim->OpenOutputs(/*resume=*/false));
  return sim;
}

absl::Status CheckResumableOverrides(std::span<const CaseOverride> overrides) {
  for (const CaseOverride& o : overrides) {
    if (absl::c_find(kResumableSettings, o.pointer) == kResumableSettings.end()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--set ", o.pointer, ": a resume may change only the Newton settings (",
          absl::StrJoin(kResumableSettings, ", "), "); the rest is the checkpoint's case"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<FemSimulation>> FemSimulation::Resume(
    const std::string& checkpoint_path, const FemSimulationOptions& options,
    std::span<const CaseOverride> solver_overrides) {
  RETURN_IF_ERROR(CheckResumableOverrides(solver_overrides));
  ASSIGN_OR_RETURN(store::SimCheckpoint c, store::ReadSimCheckpoint(checkpoint_path));
  auto bad = [&](absl::string_view what, const absl::Status& s) {
    return absl::DataLossError(absl::StrCat(checkpoint_path, ": ", what, s.message()));
  };
  absl::StatusOr<FemCase> spec = ParseFemCase(c.case_json, ".");
  if (!spec.ok())
    return bad("its case does not parse (is it an mpm_client checkpoint?): ", spec.status());
  std::string changed;  // for the log: what the overrides changed
  if (!solver_overrides.empty()) {
    // A new tangent drops the old one's ξ (the --set one or the default
    // applies): a contact tangent would refuse it.
    fields::Json doc = fields::Json::parse(c.case_json, nullptr, /*allow_exceptions=*/false);
    if (absl::c_any_of(solver_overrides,
                       [](const CaseOverride& o) { return o.pointer == "/solver/tangent"; })) {
      if (doc.contains("solver") && doc["solver"].is_object()) doc["solver"].erase("perturbation");
    }
    spec = ParseFemCase(doc.dump(), ".", solver_overrides);
    if (!spec.ok()) return spec.status();
    c.case_json = ToJson(*spec);
    for (const CaseOverride& o : solver_overrides) {
      absl::StrAppend(&changed, changed.empty() ? " with " : ", ", o.pointer, " = ", o.value);
    }
  }
  absl::StatusOr<RunState> state = GetRunState(c.doubles, c.ints);
  if (!state.ok()) return bad("", state.status());
  std::unique_ptr<FemSimulation> sim(new FemSimulation());
  sim->case_ = *std::move(spec);
  sim->case_json_ = std::move(c.case_json);
  sim->options_ = options;
  absl::StatusOr<Problem> problem = BuildProblem(sim->case_);
  if (!problem.ok()) return bad("its case cannot run: ", problem.status());
  sim->problem_ = *std::move(problem);
  if (c.rves.size() != static_cast<std::size_t>(CountGaussPoints(sim->problem_.mesh))) {
    return absl::DataLossError(absl::StrCat(checkpoint_path, ": it holds ", c.rves.size(),
                                            " RVEs for a mesh of ",
                                            CountGaussPoints(sim->problem_.mesh), " Gauss points"));
  }
  sim->run_id_ = client_run::MakeRunId(sim->case_.name);
  sim->templates_ = std::move(c.templates);
  RETURN_IF_ERROR(sim->Connect());
  RETURN_IF_ERROR(sim->UploadTemplates());
  std::vector<double> cost;
  for (RveRecord& r : c.rves) {
    r.run_id = sim->run_id_;
    cost.push_back(static_cast<double>(r.packing.radius.size()));
  }
  sim->pool_->Assign(cost);
  sim->pool_->SetPointSizes(cost);
  RETURN_IF_ERROR(sim->pool_->ImportAll(std::move(c.rves)));
  RETURN_IF_ERROR(sim->CreateSolver());
  if (absl::Status s = sim->solver_->Restore(std::move(state->solver)); !s.ok()) {
    return bad("", s);
  }
  sim->material_->Restore(state->committed_step, std::move(state->rves));
  sim->Log(absl::StrFormat("resumed %s at load step %d%s", checkpoint_path, sim->solver_->steps(),
                           changed));
  // Only a checkpoint that fits its case gets an output directory.
  RETURN_IF_ERROR(MakeOutputDir(options.out_dir));
  RETURN_IF_ERROR(sim->OpenOutputs(/*resume=*/true));
  return sim;
}

absl::Status FemSimulation::ResolveCaseTemplates() {
  // Only the material's template is used.
  std::vector<TemplateSpec> specs;
  for (const TemplateSpec& t : case_.templates) {
    if (t.name == case_.material.rve_template) specs.push_back(t);
  }
  const std::string cache =
      client_run::TemplateCacheDir(options_.template_cache_dir, options_.out_dir);
  ASSIGN_OR_RETURN(templates_,
                   client_run::ResolveTemplates(
                       specs, cache, [&](const std::string& l) { Log(l); }, "fem_client"));
  return absl::OkStatus();
}

absl::Status FemSimulation::Connect() {
  ASSIGN_OR_RETURN(std::vector<std::unique_ptr<client::RveEndpoint>> endpoints,
                   client_run::MakeEndpoints(options_.servers, options_.threads, options_.client));
  client::PoolOptions po;
  po.apply_deadline = absl::Seconds(options_.apply_timeout_s);
  pool_ = std::make_unique<client::RvePool>(std::move(endpoints), run_id_, po);
  return absl::OkStatus();
}

absl::Status FemSimulation::UploadTemplates() {
  // Under names of this run: an upload replaces a template of the same name,
  // so two runs sharing a server must not share names.
  std::vector<TemplateRecord> named = templates_;
  for (TemplateRecord& t : named) t.name = absl::StrCat(run_id_, ".", t.name);
  return pool_->UploadTemplates(named);
}

absl::Status FemSimulation::CreateRves() {
  const std::int64_t n = CountGaussPoints(problem_.mesh);
  const TemplateRecord& t = templates_.front();
  const std::string name = absl::StrCat(run_id_, ".", t.name);
  // The same RVE at every Gauss point (G&Z: a uniform specimen), so an equal
  // share per worker.
  const std::vector<double> cost(n, static_cast<double>(t.packing.radius.size()));
  pool_->Assign(cost);
  pool_->SetPointSizes(cost);
  InitialStress initial;  // compression +, Pa, as the case's
  switch (case_.material.initial_stress) {
    case InitialStressKind::kTemplate:
      break;
    case InitialStressKind::kIsotropic:
      initial.kind = InitialStress::Kind::kIsotropic;
      initial.pressure = case_.material.pressure;
      break;
    case InitialStressKind::kK0:
      initial.kind = InitialStress::Kind::kK0;
      initial.vertical_compression = case_.material.vertical;
      initial.k0 = case_.material.k0;
      break;
  }
  // The template's controls with the case's DEM steps per increment,
  // inertial-number bound and stretch bound, where the case sets them.
  std::map<std::string, dem::Controls> controls;
  const RveSpec& rve = case_.rve;
  if (rve.min_steps > 0 || rve.max_inertial_number > 0 || rve.max_stretch > 0) {
    dem::Controls c = t.packing.controls;
    if (rve.min_steps > 0) c.min_steps = rve.min_steps;
    if (rve.max_inertial_number > 0) c.max_inertial_number = rve.max_inertial_number;
    if (rve.max_stretch > 0) c.max_stretch = rve.max_stretch;
    controls[name] = c;
  }
  Log(absl::StrFormat("creating %d RVEs (one per Gauss point) on %d server(s)...", n,
                      pool_->num_endpoints()));
  const Clock::time_point t0 = Clock::now();
  const std::vector<std::string> names(n, name);
  ASSIGN_OR_RETURN(created_,
                   pool_->Create(names, std::span<const InitialStress>(&initial, 1), controls));
  Log(absl::StrFormat("created %d RVEs in %.1f s", n, Seconds(Clock::now() - t0)));
  return absl::OkStatus();
}

absl::Status FemSimulation::CreateSolver() {
  mesh0_ = problem_.mesh;
  ASSIGN_OR_RETURN(geometry0_, EvaluateGeometry(mesh0_, mesh0_.nodes));
  area0_ = 0.0;
  for (const PointGeometry& g : geometry0_) area0_ += g.volume;
  material_ = std::make_unique<RveMaterial>(pool_.get(), 0);
  ASSIGN_OR_RETURN(solver_, StaticSolver::Create(problem_.mesh, problem_.boundary, problem_.solver,
                                                 material_.get()));
  return absl::OkStatus();
}

const std::vector<dem::RveState>& FemSimulation::States() const {
  return material_->committed_step() > 0 ? material_->committed() : created_;
}

absl::Status FemSimulation::OpenOutputs(bool resume) {
  out_ = std::make_unique<Outputs>();
  const std::string dir = options_.out_dir;
  const std::string h5 = dir + "/results.h5", xdmf = dir + "/results.xdmf";
  const std::string csv = dir + "/timeseries.csv";
  const std::vector<std::string> columns = TimeseriesColumns(case_);
  // A resumed run goes on in the outputs it finds (a fresh directory gets
  // new ones); a timeseries it cannot continue is refused before the
  // results file is touched.
  bool csv_exists = false, h5_exists = false;
  if (resume) {
    std::error_code ec;
    csv_exists = std::filesystem::exists(csv, ec);
    h5_exists = std::filesystem::exists(h5, ec);
  }
  // What the uninterrupted run would have written by the checkpoint's step:
  // the row and frame a --stop-after added at its last step go.
  const std::int64_t step = solver_->steps();
  const std::int64_t rows_through = step - step % case_.output.timeseries_every;
  const std::int64_t frames_through = step - step % case_.output.frame_every;
  const std::string iterations_csv = dir + "/iterations.csv";
  const std::vector<std::string> iteration_columns = {"step",      "substep", "fraction",
                                                      "iteration", "error_d", "error_f"};
  bool iterations_exist = false;
  if (resume) {
    std::error_code ec;
    iterations_exist = std::filesystem::exists(iterations_csv, ec);
  }
  if (csv_exists) RETURN_IF_ERROR(client_run::TimeseriesWriter::CheckColumns(csv, columns));
  if (iterations_exist) {
    RETURN_IF_ERROR(client_run::TimeseriesWriter::CheckColumns(iterations_csv, iteration_columns));
  }
  ASSIGN_OR_RETURN(out_->results,
                   h5_exists ? store::ResultsWriter::Open(h5, xdmf, "fem_client", frames_through)
                             : store::ResultsWriter::Create(h5, xdmf, "fem_client"));
  ASSIGN_OR_RETURN(out_->timeseries,
                   csv_exists ? client_run::TimeseriesWriter::Resume(csv, columns, rows_through)
                              : client_run::TimeseriesWriter::Create(csv, columns));
  ASSIGN_OR_RETURN(out_->iterations, iterations_exist ? client_run::TimeseriesWriter::Resume(
                                                            iterations_csv, iteration_columns, step)
                                                      : client_run::TimeseriesWriter::Create(
                                                            iterations_csv, iteration_columns));
  if (resume) {
    out_->last_frame_step = frames_through;
    return absl::OkStatus();
  }
  RETURN_IF_ERROR(WriteFrame());
  return WriteRow(StepFigures{});
}

absl::Status FemSimulation::WriteIterations(std::int64_t step, const StepReport& report) {
  for (std::size_t k = 0; k < report.substeps.size(); ++k) {
    const SubStepReport& sub = report.substeps[k];
    for (std::size_t j = 0; j < sub.iterations.size(); ++j) {
      const IterationReport& it = sub.iterations[j];
      const double row[] = {static_cast<double>(step),  static_cast<double>(k + 1), sub.fraction,
                            static_cast<double>(j + 1), it.displacement_error,      it.force_error};
      RETURN_IF_ERROR(out_->iterations->Append(row));
    }
  }
  return absl::OkStatus();
}

absl::Status FemSimulation::WriteCheckpoint(const std::vector<RveRecord>* rves) {
  store::SimCheckpoint c;
  c.case_json = case_json_;
  c.run_id = run_id_;
  c.step = solver_->steps();
  c.time = static_cast<double>(c.step);  // no time: the load step
  RunState state{solver_->State(), material_->committed_step(), material_->committed()};
  PutRunState(state, c.doubles, c.ints);
  if (rves != nullptr) {
    c.rves = *rves;
  } else {
    ASSIGN_OR_RETURN(c.rves, pool_->ExportAll());
  }
  c.templates = templates_;
  store::FileInfo info;
  info.created_by = "fem_client";
  return store::WriteSimCheckpoint(options_.out_dir + "/checkpoint.h5", c, info);
}

struct FemSimulation::RecoveryPoint {
  std::int64_t step = 0;        // the load step it is after
  RunState state;               // the solver's and the material's
  std::vector<RveRecord> rves;  // every RVE's, by Gauss point
};

bool FemSimulation::RecoveryOn() const { return options_.recovery && !options_.servers.empty(); }

namespace {

double WallSeconds() { return Seconds(Clock::now().time_since_epoch()); }

// What an RVE costs to place: its particles (the same packing everywhere,
// unless a cell doubled).
std::vector<double> RecordSizes(std::span<const RveRecord> rves) {
  std::vector<double> sizes;
  for (const RveRecord& r : rves) sizes.push_back(static_cast<double>(r.packing.radius.size()));
  return sizes;
}

}  // namespace

absl::Status FemSimulation::TakeRecoveryPoint(FemRunSummary& sum) {
  const Clock::time_point t0 = Clock::now();
  auto point = std::make_unique<RecoveryPoint>();
  point->step = solver_->steps();
  point->state = RunState{solver_->State(), material_->committed_step(), material_->committed()};
  ASSIGN_OR_RETURN(point->rves, pool_->ExportAll());
  recovery_ = std::move(point);
  pool_->SetPointSizes(RecordSizes(recovery_->rves));
  // Servers back from a loss take their share again.
  if (ProbeLost(/*force=*/false, sum)) {
    pool_->Assign(RecordSizes(recovery_->rves));
    RETURN_IF_ERROR(pool_->Restore(recovery_->rves));
  }
  sum.recovery_s += Seconds(Clock::now() - t0);
  return absl::OkStatus();
}

bool FemSimulation::ProbeLost(bool force, FemRunSummary& sum) {
  last_probe_s_.resize(pool_->num_endpoints(), 0.0);
  bool rejoined = false;
  for (int k = 0; k < pool_->num_endpoints(); ++k) {
    if (!pool_->lost(k)) continue;
    const double now = WallSeconds();
    if (!force && now - last_probe_s_[k] < options_.probe_interval_s) continue;
    last_probe_s_[k] = now;
    client::RveEndpoint& e = pool_->endpoint(k);
    if (!e.Ping(absl::Seconds(1)).ok()) continue;
    // What it may still hold of this run is stale: it starts empty.
    if (absl::Status s = e.Drop(pool_->run_id()); !s.ok() && !absl::IsNotFound(s)) continue;
    pool_->MarkAlive(k);
    ++sum.servers_rejoined;
    rejoined = true;
    Log(absl::StrFormat("server %s answers again: it rejoins the run", e.name()));
  }
  return rejoined;
}

absl::Status FemSimulation::Recover(const absl::Status& cause, FemRunSummary& sum) {
  std::vector<int> failed = pool_->TakeFailed();
  if (failed.empty() || recovery_ == nullptr) return cause;
  const Clock::time_point t0 = Clock::now();
  const std::int64_t lost_at = solver_->steps() + 1;
  last_probe_s_.resize(pool_->num_endpoints(), 0.0);
  // A deadline missed by a server that was only slow must not be missed
  // again in the replay.
  if (absl::IsDeadlineExceeded(cause)) pool_->RelaxDeadline();
  for (int attempt = 0;; ++attempt) {
    for (int k : failed) {
      pool_->MarkLost(k);
      last_probe_s_[k] = WallSeconds();
      ++sum.servers_lost;
      // Its own error: `cause` is the first failing server's.
      const absl::Status& own = pool_->last_failure(k);
      Log(absl::StrFormat("server %s lost (load step %d): %s", pool_->endpoint(k).name(), lost_at,
                          own.ok() ? cause.message() : own.message()));
    }
    // One restarted at once (a supervisor) takes its share again.
    if (attempt > 0 || pool_->num_alive() == 0) ProbeLost(/*force=*/true, sum);
    const Clock::time_point wait_start = Clock::now();
    while (pool_->num_alive() == 0 && Seconds(Clock::now() - wait_start) < options_.server_wait_s) {
      absl::SleepFor(absl::Seconds(std::min(1.0, options_.server_wait_s)));
      ProbeLost(/*force=*/true, sum);
    }
    if (pool_->num_alive() == 0) {
      return absl::UnavailableError(absl::StrFormat(
          "every RVE server is lost (none answered within %.0f s); last error: %s. Resume from a "
          "checkpoint (fem_client resume) once servers run again",
          options_.server_wait_s, cause.message()));
    }
    pool_->Assign(RecordSizes(recovery_->rves));
    absl::Status restored = pool_->Restore(recovery_->rves);
    if (restored.ok()) break;
    failed = pool_->TakeFailed();
    if (failed.empty() || attempt >= pool_->num_endpoints()) {
      return absl::Status(restored.code(),
                          absl::StrCat("recovering from a lost server: ", restored.message(),
                                       " (after: ", cause.message(), ")"));
    }
  }
  // The steps done since the point (a step whose outputs failed) go again.
  sum.steps -= solver_->steps() - recovery_->step;
  RETURN_IF_ERROR(solver_->Restore(recovery_->state.solver));
  material_->Restore(recovery_->state.committed_step, recovery_->state.rves);
  RETURN_IF_ERROR(out_->results->Close());
  RETURN_IF_ERROR(OpenOutputs(/*resume=*/true));
  sum.recovery_s += Seconds(Clock::now() - t0);
  std::string hosts;
  for (int k = 0; k < pool_->num_endpoints(); ++k) {
    if (pool_->lost(k)) continue;
    absl::StrAppend(&hosts, hosts.empty() ? "" : ", ", pool_->endpoint(k).name(), " (",
                    pool_->points_of(k).size(), ")");
  }
  Log(absl::StrFormat("recovered in %.2f s: %d RVEs restored from load step %d onto %s",
                      Seconds(Clock::now() - t0), recovery_->rves.size(), recovery_->step, hosts));
  return absl::OkStatus();
}

absl::Status FemSimulation::WriteRow(const StepFigures& f) {
  const Mesh& mesh = solver_->mesh();
  const Eigen::VectorXd& u = solver_->displacement();  // m, since the start
  const Problem& p = problem_;
  const Strains strains = NominalStrains(mesh, u, p);
  const Eigen::Vector2d n = OutwardNormal(p.driven), t = FaceTangent(p.driven);
  const Eigen::Vector2d n_lateral = OutwardNormal(p.lateral);
  // The Gauss points on the current configuration: their volumes weigh the means.
  ASSIGN_OR_RETURN(const std::vector<PointGeometry> geometry, EvaluateGeometry(mesh, mesh.nodes));
  const std::vector<dem::RveState>& states = States();
  double area = 0.0, void_ratio = 0.0;
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();  // tension +, Pa
  for (std::size_t k = 0; k < geometry.size(); ++k) {
    const double v = geometry[k].volume;
    area += v;
    sigma += v * states[k].stress;
    void_ratio += v * states[k].void_ratio;
  }
  sigma /= area;
  void_ratio /= area;
  const Eigen::Matrix2d s = InPlane(sigma);
  double platen = 0.0, lateral = 0.0;  // Pa
  if (f.report != nullptr) {
    // The supports' force on the body at the driven face, and the body's
    // own force on the lateral face, over their current lengths.
    const SetForces& at_platen = f.report->forces.at(FaceSetName(p.driven));
    const SetForces& at_side = f.report->forces.at(FaceSetName(p.lateral));
    const double length = FaceLength(mesh, p.driven);
    // τ: the body's own force on the shear platen (with the platen under
    // force control, the load it balances; under displacement control, the
    // reaction, the top carrying no other load).
    platen = p.shear ? at_platen.internal.dot(t) / length : -at_platen.reaction.dot(n) / length;
    lateral = -at_side.internal.dot(n_lateral) / FaceLength(mesh, p.lateral);
  } else {
    // Before any step: the mean stress's tractions on those faces.
    platen = p.shear ? t.dot(s * n) : -n.dot(s * n);
    lateral = -n_lateral.dot(s * n_lateral);
  }
  std::vector<double> row = {static_cast<double>(f.step),
                             strains.axial,
                             1.0 - area / area0_,
                             strains.shear,
                             platen,
                             lateral,
                             dem::InPlaneMeanPressure(sigma),
                             dem::InPlaneDeviatorStress(sigma),
                             void_ratio};
  if (f.report != nullptr) {
    const StepCounts counts = Counts(*f.report);
    const IterationReport& last = f.report->substeps.back().iterations.back();
    row.insert(row.end(),
               {static_cast<double>(counts.iterations), last.displacement_error, last.force_error,
                static_cast<double>(f.report->cutbacks), static_cast<double>(counts.unconverged),
                static_cast<double>(f.report->trials), f.dem_steps_per_trial});
  } else {
    row.insert(row.end(), {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0});
  }
  row.push_back(f.wall_step_s);
  for (std::int64_t k : case_.output.monitor) {
    const Eigen::Matrix3d& sk = states[k].stress;
    row.insert(row.end(), {-sk(0, 0), -sk(1, 1), -sk(0, 1), states[k].void_ratio});
  }
  for (double& v : row) v += 0.0;  // −0 (a negated zero) reads as 0
  return out_->timeseries->Append(row);
}

absl::Status FemSimulation::WriteFrame() {
  const Mesh& mesh = solver_->mesh();
  const std::int64_t step = solver_->steps();
  const std::vector<dem::RveState>& states = States();
  const std::vector<Eigen::Vector2d> x = GaussPointPositions(mesh, mesh.nodes);
  const std::vector<Eigen::Vector2d> x0 = GaussPointPositions(mesh0_, mesh0_.nodes);
  // F since the start at every Gauss point, on the mesh as created.
  const std::vector<Eigen::Matrix3d> f =
      DeformationIncrements(mesh0_, geometry0_, solver_->displacement());
  store::ResultFrame frame;
  frame.step = step;
  frame.time = static_cast<double>(step);  // no time: the load step
  store::ResultField stress{"stress", 9, {}}, p{"p", 1, {}}, q{"q", 1, {}}, eq{"eps_q", 1, {}},
      ev{"eps_v", 1, {}}, e{"void_ratio", 1, {}}, z{"coordination", 1, {}},
      fa{"fabric_anisotropy", 1, {}}, rot{"rotation", 1, {}}, u{"displacement", 2, {}},
      id{"gauss_point", 1, {}};
  for (std::size_t k = 0; k < x.size(); ++k) {
    frame.position.push_back(x[k].x());
    frame.position.push_back(x[k].y());
    const Eigen::Matrix3d& s = states[k].stress;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) stress.values.push_back(s(r, c));
    }
    p.values.push_back(dem::InPlaneMeanPressure(s));
    q.values.push_back(dem::InPlaneDeviatorStress(s));
    // G&Z eqs. 10, 12, 13: the infinitesimal strain of the total ∇u,
    // compression +: εv = tr ε, εq = sqrt(2 e:e), e = ε − (εv/2) I.
    const Eigen::Matrix2d fk = f[k].topLeftCorner<2, 2>();
    const Eigen::Matrix2d strain = Eigen::Matrix2d::Identity() - 0.5 * (fk + fk.transpose());
    const double vol = strain.trace();
    const Eigen::Matrix2d dev = strain - 0.5 * vol * Eigen::Matrix2d::Identity();
    ev.values.push_back(vol);
    eq.values.push_back(std::sqrt(2.0 * dev.cwiseProduct(dev).sum()));
    e.values.push_back(states[k].void_ratio);
    z.values.push_back(states[k].coordination);
    fa.values.push_back(states[k].fabric_anisotropy);
    // The material's rigid rotation since the start (polar R of F), rad,
    // counter-clockwise positive.
    const Eigen::Matrix2d r = PolarRotation(fk);
    rot.values.push_back(std::atan2(r(1, 0), r(0, 0)));
    u.values.push_back(x[k].x() - x0[k].x());
    u.values.push_back(x[k].y() - x0[k].y());
    id.values.push_back(static_cast<double>(k));
  }
  frame.fields = {std::move(stress), std::move(p), std::move(q), std::move(eq),
                  std::move(ev),     std::move(e), std::move(z), std::move(fa),
                  std::move(rot),    std::move(u), std::move(id)};
  RETURN_IF_ERROR(out_->results->Append(frame));
  out_->last_frame_step = step;
  if (case_.output.packings.empty()) return absl::OkStatus();
  // The packings of the chosen Gauss points, as rves.h5 files.
  ASSIGN_OR_RETURN(std::vector<RveRecord> all, pool_->ExportAll());
  std::vector<RveRecord> chosen;
  for (std::int64_t k : case_.output.packings) chosen.push_back(std::move(all[k]));
  store::FileInfo info;
  info.created_by = "fem_client";
  return store::WriteRves(absl::StrCat(options_.out_dir, "/packings-", step, ".h5"), chosen, info);
}

absl::StatusOr<FemRunSummary> FemSimulation::StepToEnd() {
  FemRunSummary sum;
  const OutputSpec& o = case_.output;
  const std::vector<double>& factors = problem_.factors;
  const std::int64_t total = static_cast<std::int64_t>(factors.size());
  sum.total_steps = total;
  const Clock::time_point start = Clock::now();
  const double rve_start = pool_->total_apply_seconds();
  const client::ApplyStats commits_start = pool_->apply_stats();
  const client::ApplyStats trials_start = pool_->trial_stats();
  Clock::time_point row_clock = start, last_progress = start;
  std::int64_t row_step = solver_->steps();
  auto output_time = Clock::duration::zero();
  // Stress-controlled cycles end early once |γ| reaches the case's end
  // shear strain (G&Z §5.2: 5 % accumulated).
  bool reached_end_strain = false;
  auto last_of_case = [&](std::int64_t step) { return step == total || reached_end_strain; };
  if (RecoveryOn()) RETURN_IF_ERROR(TakeRecoveryPoint(sum));
  // One load step with its outputs (and recovery point); an error leaves
  // the outputs as they were at some step (a recovery rewrites them from
  // its point).
  auto step_once = [&]() -> absl::Status {
    reached_end_strain = false;
    const std::int64_t step = solver_->steps() + 1;
    const bool last = step == total ||
                      (options_.stop_after_steps > 0 && sum.steps + 1 >= options_.stop_after_steps);
    const bool frame = step % o.frame_every == 0 || last;
    // Between frames the RVEs measure the stress alone (and the void ratio):
    // the same states, bit for bit, faster; a frame's step is measured in full.
    pool_->set_stress_only(!case_.rve.full_state_every_step && !frame);
    const client::ApplyStats trials_before = pool_->trial_stats();
    absl::StatusOr<StepReport> report = solver_->Step(factors[step - 1]);
    if (!report.ok()) return report.status();  // "load step N ...: " already
    ++sum.steps;
    const StepCounts counts = Counts(*report);
    sum.iterations += counts.iterations;
    sum.unconverged += counts.unconverged;
    sum.cutbacks += report->cutbacks;
    sum.trials += report->trials;
    const client::ApplyStats tried = pool_->trial_stats().Since(trials_before);
    if (problem_.forced) {
      const Strains strains = NominalStrains(solver_->mesh(), solver_->displacement(), problem_);
      reached_end_strain = std::abs(strains.shear) >= case_.loading.end_strain;
    }
    const Clock::time_point t_out = Clock::now();
    RETURN_IF_ERROR(WriteIterations(step, *report));
    StepFigures figures;
    figures.step = step;
    figures.report = &*report;
    figures.dem_steps_per_trial = tried.increments > 0 ? static_cast<double>(tried.dem_steps) /
                                                             static_cast<double>(tried.increments)
                                                       : 0.0;
    if (step % o.timeseries_every == 0 || last || reached_end_strain) {
      figures.wall_step_s = Seconds(t_out - row_clock) / static_cast<double>(step - row_step);
      RETURN_IF_ERROR(WriteRow(figures));
      row_clock = t_out;
      row_step = step;
    }
    if (frame) RETURN_IF_ERROR(WriteFrame());
    // Where --stop-after stops there is always a checkpoint, checkpoints on
    // or not: stopping is for resuming later.
    const bool stopping = !last_of_case(step) && options_.stop_after_steps > 0 &&
                          sum.steps >= options_.stop_after_steps;
    if (RecoveryOn() && !last_of_case(step) && !stopping) RETURN_IF_ERROR(TakeRecoveryPoint(sum));
    if ((o.checkpoint_every > 0 && (step % o.checkpoint_every == 0 || last_of_case(step))) ||
        stopping) {
      const bool fresh = recovery_ != nullptr && recovery_->step == step;
      RETURN_IF_ERROR(WriteCheckpoint(fresh ? &recovery_->rves : nullptr));
      if (options_.on_checkpoint) options_.on_checkpoint(step, Seconds(Clock::now() - start));
    }
    output_time += Clock::now() - t_out;
    if (options_.progress &&
        (step % o.progress_every == 0 || last || reached_end_strain ||
         Seconds(Clock::now() - last_progress) >= options_.progress_interval_s)) {
      last_progress = Clock::now();
      const double wall = Seconds(Clock::now() - start);
      const double eta = wall / static_cast<double>(sum.steps) * static_cast<double>(total - step);
      const Strains strains = NominalStrains(solver_->mesh(), solver_->displacement(), problem_);
      const SetForces& at = report->forces.at(FaceSetName(problem_.driven));
      const double length = FaceLength(solver_->mesh(), problem_.driven);
      const Eigen::Vector2d n = OutwardNormal(problem_.driven), t = FaceTangent(problem_.driven);
      const std::string state =
          problem_.shear
              ? absl::StrFormat("gamma %.3f %%  tau %.2f kPa", 100 * strains.shear,
                                1e-3 * at.internal.dot(t) / length)
              : absl::StrFormat("axial strain %.3f %%  stress %.1f kPa", 100 * strains.axial,
                                -1e-3 * at.reaction.dot(n) / length);
      Log(absl::StrFormat(
          "load step %d/%d  %s  iterations %d%s%s  E_d %.2e  wall %.1f s  ETA %.0f s", step, total,
          state, counts.iterations,
          report->cutbacks > 0 ? absl::StrFormat(" (%d cut-backs)", report->cutbacks) : "",
          report->substeps.back().converged ? "" : " (not converged, accepted)",
          report->substeps.back().iterations.back().displacement_error, wall, eta));
    }
    return absl::OkStatus();
  };
  while (solver_->steps() < total && !reached_end_strain) {
    if (options_.stop_after_steps > 0 && sum.steps >= options_.stop_after_steps) break;
    const absl::Status s = step_once();
    if (s.ok()) continue;
    if (!RecoveryOn()) return s;
    RETURN_IF_ERROR(Recover(s, sum));
    row_clock = Clock::now();
    row_step = solver_->steps();
  }
  sum.final_step = solver_->steps();
  sum.finished = sum.final_step >= total || reached_end_strain;
  if (reached_end_strain) {
    Log(absl::StrFormat("shear strain reached %g (loading.end_shear_strain) at load step %d",
                        case_.loading.end_strain, sum.final_step));
  }
  client_run::TimeSplit& split = sum.split;
  split.wall_s = Seconds(Clock::now() - start);
  split.rve_s = pool_->total_apply_seconds() - rve_start;
  split.output_s = Seconds(output_time);
  split.rve_stats = pool_->apply_stats().Since(commits_start);
  split.rve_stats.Add(pool_->trial_stats().Since(trials_start));
  split.rve_workers = pool_->total_workers();
  if (RecoveryOn()) {
    Log(absl::StrFormat(
        "recovery: %d server(s) lost and survived, %d rejoined; recovery points and recoveries "
        "took %.1f s (%.1f %% of the wall time)",
        sum.servers_lost, sum.servers_rejoined, sum.recovery_s,
        split.wall_s > 0 ? 100.0 * sum.recovery_s / split.wall_s : 0.0));
  }
  RETURN_IF_ERROR(out_->results->Close());
  if (sum.finished) {
    ASSIGN_OR_RETURN(const Summary summary, WriteFemRunOutputs(case_, options_.out_dir));
    // The same lines as `fem_client summarise`; the verdict is summarise's
    // exit status, a finished run's is 0 either way.
    for (const std::string& line : client_run::SummaryAndCheckLines(summary, case_.checks)) {
      Log(line);
    }
  } else if (options_.stop_after_steps > 0) {
    const std::string path = options_.out_dir + "/checkpoint.h5";
    Log(absl::StrFormat(
        "stopped after load step %d (--stop-after=%d); checkpoint written to %s (continue "
        "with: fem_client resume %s --out=%s)",
        sum.final_step, options_.stop_after_steps, path, path, options_.out_dir));
  }
  return sum;
}

}  // namespace rvehub::fem
