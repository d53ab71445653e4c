#include "mpm_client/run/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <system_error>
#include <thread>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/synchronization/mutex.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "client_run/checks.h"
#include "client_run/endpoints.h"
#include "client_run/templates.h"
#include "client_run/time_split.h"
#include "mpm_client/case/case.h"
#include "mpm_client/core/body_contact.h"
#include "mpm_client/core/shape.h"
#include "mpm_client/core/solver_checkpoint.h"
#include "mpm_client/core/two_phase.h"
#include "mpm_client/run/output.h"
#include "mpm_client/run/summary.h"
#include "rve_server/client/endpoint.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/state.h"
#include "store/results.h"

namespace rvehub::mpm {

using client_run::BulkDensity;

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// The StressModel the solver sees: one batched COMMIT per server per step.
class RveStressModel : public StressModel {
 public:
  RveStressModel(client::RvePool* pool, double* seconds) : pool_(pool), seconds_(seconds) {}
  absl::Status Update(std::int64_t step, std::span<const Eigen::Matrix3d> delta_f,
                      std::span<PointResponse> out) override {
    const Clock::time_point t0 = Clock::now();
    absl::StatusOr<std::vector<dem::RveState>> states = pool_->Apply(step, delta_f);
    *seconds_ += Seconds(Clock::now() - t0);
    if (!states.ok()) return states.status();
    for (std::size_t p = 0; p < out.size(); ++p) out[p] = ToResponse((*states)[p]);
    return absl::OkStatus();
  }
  void SetStressOnly(bool stress_only) override { pool_->set_stress_only(stress_only); }

  static PointResponse ToResponse(const dem::RveState& s) {
    PointResponse r;
    r.stress = s.stress;
    r.void_ratio = s.void_ratio;
    r.fabric_anisotropy = s.fabric_anisotropy;
    r.mean_rotation = s.mean_rotation;
    r.coordination = s.coordination;
    r.permeability = s.permeability;
    return r;
  }

 private:
  client::RvePool* pool_;
  double* seconds_;
};

// Nominal in-plane strain of a total F, compression +: ε = I − sym(F), so
// εyy = 1 − F_yy is the element tests' axial strain (timeseries.csv). Not
// rotation-free: the frames use LogStrain.
Eigen::Matrix2d Strain(const Eigen::Matrix2d& f) {
  return Eigen::Matrix2d::Identity() - 0.5 * (f + f.transpose());
}

// Logarithmic (Hencky) strain of a total F, compression +: −½ ln(F·Fᵀ),
// rotation-free at any deformation.
Eigen::Matrix2d LogStrain(const Eigen::Matrix2d& f) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(f * f.transpose());
  const Eigen::Vector2d ln = eig.eigenvalues().array().log();
  return -0.5 * eig.eigenvectors() * ln.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

struct Simulation::Outputs {
  std::unique_ptr<store::ResultsWriter> results;
  std::unique_ptr<TimeseriesWriter> timeseries;
  std::int64_t last_frame_step = -1;
  std::int64_t last_row_step = -1;
  // Saturated cases: the points of the surface settlement and of each
  // monitor, chosen by their starting positions (the same after a resume).
  std::vector<std::size_t> top_row, monitor_points;
};

Simulation::~Simulation() {
  if (pool_ != nullptr) {
    // Free the servers' memory; a failure here only leaks RVEs on a server
    // that is going away anyway.
    (void)pool_->DropAll();
    // A server lost during the run that answers again (one stopped and
    // continued since the last probe) still holds this run's RVEs as they
    // were when it was lost: dropped too, or they stay until it stops.
    for (int k = 0; k < pool_->num_endpoints(); ++k) {
      if (!pool_->lost(k)) continue;
      client::RveEndpoint& e = pool_->endpoint(k);
      if (e.Ping(absl::Seconds(1)).ok()) (void)e.Drop(pool_->run_id());
    }
  }
}

void Simulation::SetApplyOptions() {
  dem::ApplyOptions apply;
  if (spec_.rve.real_time) apply.duration = solver_->dt();
  pool_->set_apply_options(apply);
}

void Simulation::LogCornerOverhangs() const {
  const MaterialPoints& mp = solver_->points();
  for (const RigidBody& body : spec_.bodies) {
    const double overhang = CornerOverhang(body, body.center, mp.position, mp.half_size0,
                                           spec_.grid.origin, spec_.grid.cell_size);
    if (overhang <= 0) continue;
    Log(absl::StrFormat(
        "note: body %s has a corner inside a grid cell, %.4g m from the node line beyond it: "
        "the contact pushes the soil of that cell with the body, over a strip up to that much "
        "wider than the body (edges on node lines avoid it)",
        body.name, overhang));
  }
}

void Simulation::Log(const std::string& line) const {
  if (options_.log) {
    options_.log(line);
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
}

std::string Simulation::ServerTemplateName(const std::string& name) const {
  return absl::StrCat(run_id_, ".", name);
}

absl::Status Simulation::UploadTemplates() {
  // Under names of this run: an upload replaces a template of the same name,
  // so two runs sharing a server must not share names.
  std::vector<TemplateRecord> named = templates_;
  for (TemplateRecord& t : named) t.name = ServerTemplateName(t.name);
  return pool_->UploadTemplates(named);
}

absl::Status Simulation::Connect() {
  ASSIGN_OR_RETURN(std::vector<std::unique_ptr<client::RveEndpoint>> endpoints,
                   client_run::MakeEndpoints(options_.servers, options_.threads, options_.client));
  client::PoolOptions po;
  po.apply_deadline = absl::Seconds(options_.apply_timeout_s);
  if (RecoveryOn()) {
    // A failed server is recovered from, not waited for: one retry for a
    // lost reply, and a deadline that follows the measured batch times.
    po.max_attempts = 2;
    po.deadline_factor = options_.deadline_factor;
    po.min_apply_deadline = absl::Seconds(options_.min_apply_timeout_s);
  }
  pool_ = std::make_unique<client::RvePool>(std::move(endpoints), run_id_, po);
  last_probe_s_.assign(pool_->num_endpoints(), 0.0);
  probe_wait_s_.assign(pool_->num_endpoints(), options_.probe_interval_s);
  return absl::OkStatus();
}

std::vector<std::string> Simulation::Columns() const {
  std::vector<std::string> c = {"time", "step"};
  for (const Wall& w : spec_.walls) {
    c.push_back(w.name + "_fx");
    c.push_back(w.name + "_fy");
  }
  for (const RigidBody& b : spec_.bodies) {
    c.push_back(b.name + "_fx");
    c.push_back(b.name + "_fy");
    c.push_back(b.name + "_dx");
    c.push_back(b.name + "_dy");
  }
  for (const char* name : {"mean_sxx", "mean_syy", "mean_sxy", "mean_exx", "mean_eyy", "mean_exy",
                           "mean_p", "mean_q", "mean_void_ratio", "kinetic_energy",
                           "potential_energy", "front_x", "top_y", "wall_per_step_s"}) {
    c.push_back(name);
  }
  if (spec_.solver.lost_points == LostPointPolicy::kDrop) c.push_back("lost_points");
  if (spec_.solver.time_step_update_every > 0) c.push_back("time_step");
  if (WritesDepositFront()) {
    c.push_back("deposit_front_x");
    for (const int percent : kMassFrontPercents) c.push_back(MassFrontColumn(percent));
  }
  if (spec_.phases.saturated) {
    c.push_back("surface_settlement");
    for (const PressureMonitor& m : spec_.phases.monitors) {
      c.push_back(m.name + "_p");
      c.push_back(m.name + "_excess_ratio");
      c.push_back(m.name + "_sxy");
      c.push_back(m.name + "_ux");
      c.push_back(m.name + "_uy");
    }
  }
  return c;
}

bool Simulation::WritesDepositFront() const {
  return SummaryKind(spec_.output) == "collapse" && !spec_.regions.empty();
}

namespace {

// The material points that started in the top row (largest y0).
std::vector<std::size_t> TopRow(const MaterialPoints& mp) {
  double top0 = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < mp.size(); ++i) top0 = std::max(top0, mp.position0[i].y());
  std::vector<std::size_t> row;
  for (std::size_t i = 0; i < mp.size(); ++i) {
    if (mp.position0[i].y() >= top0 - 1e-9) row.push_back(i);
  }
  return row;
}

// The material point that started nearest to `x` (the first of equals).
std::size_t NearestPoint(const MaterialPoints& mp, const Eigen::Vector2d& x) {
  std::size_t best = 0;
  for (std::size_t p = 1; p < mp.size(); ++p) {
    if ((mp.position0[p] - x).squaredNorm() < (mp.position0[best] - x).squaredNorm()) best = p;
  }
  return best;
}

// Each point's excess pore pressure p − p_rest, Pa, the water at rest
// counted from the case's datum (PhasesSpec::excess_from).
std::vector<double> ExcessPorePressures(const CaseSpec& spec, const MaterialPoints& mp) {
  const double rho = spec.phases.fluid_density, g = spec.solver.gravity.norm();
  SurfaceProfile surface(spec.grid.origin.x(), spec.grid.cell_size, spec.grid.nx);
  const bool from_surface = spec.phases.excess_from == ExcessDatum::kSurface;
  if (from_surface) {
    for (std::size_t i = 0; i < mp.size(); ++i) {
      surface.Add(mp.position[i].x(),
                  mp.position[i].y() + CurrentHalfSize(mp.F[i], mp.half_size0[i]).y());
    }
  }
  std::vector<double> excess(mp.size());
  for (std::size_t i = 0; i < mp.size(); ++i) {
    const double table =
        from_surface ? surface.HeightAt(mp.position[i].x()) : spec.phases.water_table;  // m
    excess[i] = mp.pore_pressure[i] - HydrostaticPressure(rho, g, table, mp.position[i].y());
  }
  return excess;
}

}  // namespace

// Made before any expensive setup, so an unusable --out fails at once.
static absl::Status MakeOutputDir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    return absl::UnavailableError(
        absl::StrCat("cannot create the output directory ", dir, ": ", ec.message()));
  }
  return absl::OkStatus();
}

absl::Status Simulation::OpenOutputs(bool resume) {
  out_ = std::make_unique<Outputs>();
  if (spec_.phases.saturated) {
    const MaterialPoints& mp = solver_->points();
    out_->top_row = TopRow(mp);
    for (const PressureMonitor& m : spec_.phases.monitors) {
      out_->monitor_points.push_back(NearestPoint(mp, m.position));
    }
  }
  const std::string dir = options_.out_dir;
  const std::string h5 = dir + "/results.h5", xdmf = dir + "/results.xdmf";
  const std::string csv = dir + "/timeseries.csv";
  // A timeseries this run cannot continue is refused before the results
  // file is touched.
  bool csv_exists = false, h5_exists = false;
  if (resume) {
    ASSIGN_OR_RETURN(csv_exists, PathExists(csv));
    ASSIGN_OR_RETURN(h5_exists, PathExists(h5));
  }
  if (csv_exists) RETURN_IF_ERROR(TimeseriesWriter::CheckColumns(csv, Columns()));
  ASSIGN_OR_RETURN(std::unique_ptr<store::ResultsWriter> results,
                   h5_exists ? store::ResultsWriter::Open(h5, xdmf, "mpm_client", solver_->step())
                             : store::ResultsWriter::Create(h5, xdmf, "mpm_client"));
  out_->results = std::move(results);
  ASSIGN_OR_RETURN(std::unique_ptr<TimeseriesWriter> ts,
                   csv_exists ? TimeseriesWriter::Resume(csv, Columns(), solver_->step())
                              : TimeseriesWriter::Create(csv, Columns()));
  out_->timeseries = std::move(ts);
  if (resume) {
    out_->last_frame_step = out_->last_row_step = solver_->step();
    return absl::OkStatus();
  }
  RETURN_IF_ERROR(WriteFrame());
  return WriteRow(0.0);
}

absl::Status Simulation::WriteFrame() {
  const MaterialPoints& mp = solver_->points();
  const std::size_t n = mp.size();
  store::ResultFrame f;
  f.step = solver_->step();
  f.time = solver_->time();
  f.position.reserve(2 * n);
  store::ResultField velocity{"velocity", 2, {}}, stress{"stress", 9, {}}, p{"p", 1, {}},
      q{"q", 1, {}}, eq{"eps_q", 1, {}}, ev{"eps_v", 1, {}}, e{"void_ratio", 1, {}},
      fa{"fabric_anisotropy", 1, {}}, rot{"rotation", 1, {}}, z{"coordination", 1, {}},
      id{"rve_id", 1, {}};
  for (std::size_t i = 0; i < n; ++i) {
    f.position.push_back(mp.position[i].x());
    f.position.push_back(mp.position[i].y());
    velocity.values.push_back(mp.velocity[i].x());
    velocity.values.push_back(mp.velocity[i].y());
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) stress.values.push_back(mp.stress[i](r, c));
    }
    const Eigen::Matrix3d& s = mp.stress[i];
    p.values.push_back(dem::InPlaneMeanPressure(s));
    q.values.push_back(dem::InPlaneDeviatorStress(s));
    // εv = tr ε, εq = sqrt(2 e:e) with e = ε − (εv/2) I (2-D, shared/reference),
    // of the logarithmic strain: large rotations (flows) are not strain.
    const Eigen::Matrix2d strain = LogStrain(mp.F[i]);
    const double vol = strain.trace();
    const Eigen::Matrix2d dev = strain - 0.5 * vol * Eigen::Matrix2d::Identity();
    ev.values.push_back(vol);
    eq.values.push_back(std::sqrt(2.0 * dev.cwiseProduct(dev).sum()));
    e.values.push_back(mp.response[i].void_ratio);
    fa.values.push_back(mp.response[i].fabric_anisotropy);
    rot.values.push_back(mp.response[i].mean_rotation);
    z.values.push_back(mp.response[i].coordination);
    id.values.push_back(static_cast<double>(i));
  }
  f.fields = {std::move(velocity), std::move(stress), std::move(p), std::move(q),
              std::move(eq),       std::move(ev),     std::move(e), std::move(fa),
              std::move(rot),      std::move(z),      std::move(id)};
  if (spec_.phases.saturated) {
    store::ResultField pore{"pore_pressure", 1, {}}, excess{"excess_pore_pressure", 1, {}},
        fluid{"fluid_velocity", 2, {}}, k{"permeability", 1, {}}, porosity{"porosity", 1, {}};
    excess.values = ExcessPorePressures(spec_, mp);
    for (std::size_t i = 0; i < n; ++i) {
      pore.values.push_back(mp.pore_pressure[i]);
      fluid.values.push_back(mp.fluid_velocity[i].x());
      fluid.values.push_back(mp.fluid_velocity[i].y());
      k.values.push_back(solver_->Permeability(i));
      porosity.values.push_back(solver_->Porosity(i));
    }
    for (auto* field : {&pore, &excess, &fluid, &k, &porosity})
      f.fields.push_back(std::move(*field));
  }
  RETURN_IF_ERROR(out_->results->Append(f));
  out_->last_frame_step = solver_->step();
  return absl::OkStatus();
}

absl::Status Simulation::WriteRow(double wall_per_step) {
  const MaterialPoints& mp = solver_->points();
  std::vector<double> row = {solver_->time(), static_cast<double>(solver_->step())};
  const std::vector<Eigen::Vector2d> reactions = solver_->Reactions();
  for (std::size_t i = 0; i < spec_.walls.size(); ++i) {
    row.push_back(reactions[i].x());
    row.push_back(reactions[i].y());
  }
  for (std::size_t b = 0; b < spec_.bodies.size(); ++b) {
    const Eigen::Vector2d& r = reactions[spec_.walls.size() + b];
    const Eigen::Vector2d d = solver_->BodyDisplacement(static_cast<int>(b));
    row.insert(row.end(), {r.x(), r.y(), d.x(), d.y()});
  }
  // Volume averages (current volumes), compression +.
  double volume = 0, e = 0;
  // Extent of the material (points' positions), m: a flow's front and height.
  double front_x = -std::numeric_limits<double>::infinity(), top_y = front_x;
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  Eigen::Matrix2d strain = Eigen::Matrix2d::Zero();
  const std::vector<std::uint8_t>& lost = solver_->lost();
  double lost_points = 0.0;
  for (std::size_t i = 0; i < mp.size(); ++i) {
    if (lost[i]) {  // parked off the grid (kDrop)
      lost_points += 1.0;
      continue;
    }
    const double v = mp.volume[i];
    volume += v;
    sigma += v * mp.stress[i];
    strain += v * Strain(mp.F[i]);
    e += v * mp.response[i].void_ratio;
    front_x = std::max(front_x, mp.position[i].x());
    top_y = std::max(top_y, mp.position[i].y());
  }
  if (volume > 0) {
    sigma /= volume;
    strain /= volume;
    e /= volume;
  }
  row.insert(row.end(),
             {-sigma(0, 0), -sigma(1, 1), -sigma(0, 1), strain(0, 0), strain(1, 1), strain(0, 1),
              dem::InPlaneMeanPressure(sigma), dem::InPlaneDeviatorStress(sigma), e,
              solver_->KineticEnergy(), solver_->PotentialEnergy(), front_x, top_y, wall_per_step});
  if (spec_.solver.lost_points == LostPointPolicy::kDrop) row.push_back(lost_points);
  if (spec_.solver.time_step_update_every > 0) row.push_back(solver_->dt());
  if (WritesDepositFront()) {
    // The main deposit's front (m): points within two initial spacings of
    // each other are in contact; those thrown clear are scatter.
    row.push_back(
        MainDepositFront(mp.position, lost, kDepositLinkSpacings * InitialPointSpacing(spec_)));
    // And read by mass (m): where 98 and 99 % of the points' mass lie behind.
    for (const int percent : kMassFrontPercents) {
      row.push_back(MassFront(mp.position, mp.mass, lost, percent / 100.0));
    }
  }
  if (spec_.phases.saturated) {
    // The surface's settlement: the mean of (y0 − y) over the points that
    // started in the top row, m (down +).
    double settlement = 0.0;
    for (std::size_t i : out_->top_row) settlement += mp.position0[i].y() - mp.position[i].y();
    row.push_back(out_->top_row.empty() ? 0.0 : settlement / out_->top_row.size());
    // Each monitor's pore pressure (Pa) and excess ratio Δp/σ'yy,0 [-],
    const Eigen::Vector2d box = FrameDisplacement(spec_.solver, solver_->time());  // m
    const std::vector<double> excess = ExcessPorePressures(spec_, mp);
    for (std::size_t i : out_->monitor_points) {
      row.push_back(mp.pore_pressure[i]);
      row.push_back(mp.vertical_stress0[i] > 0 ? excess[i] / mp.vertical_stress0[i] : 0.0);
      // Its effective shear stress (Pa) and displacement (m, relative to
      // the ground: a shaken box's own added): the σxy–u_x loops of cyclic
      // loading, a surface point's orbit in a wave.
      row.push_back(mp.stress[i](0, 1));
      row.push_back(mp.position[i].x() - mp.position0[i].x() + box.x());
      row.push_back(mp.position[i].y() - mp.position0[i].y() + box.y());
    }
  }
  for (double& v : row) v += 0.0;  // −0 (a negated zero) reads as 0
  RETURN_IF_ERROR(out_->timeseries->Append(row));
  out_->last_row_step = solver_->step();
  return absl::OkStatus();
}

void Simulation::LogLostPoints() {
  const std::vector<std::uint8_t>& lost = solver_->lost();
  if (spec_.solver.lost_points != LostPointPolicy::kDrop) return;
  lost_logged_.resize(lost.size(), 0);
  for (std::size_t p = 0; p < lost.size(); ++p) {
    if (!lost[p] || lost_logged_[p]) continue;
    lost_logged_[p] = 1;
    const Eigen::Vector2d& x = solver_->points().position[p];
    Log(absl::StrFormat(
        "step %d: material point %d at (%.6g, %.6g) m is off the grid: parked (solver.lost_points "
        "\"drop\"; %d parked)",
        solver_->step(), p, x.x(), x.y(), std::count(lost.begin(), lost.end(), 1)));
  }
}

absl::StatusOr<store::SimCheckpoint> Simulation::Snapshot() {
  store::SimCheckpoint c;
  c.case_json = case_json_;
  c.run_id = run_id_;
  c.step = solver_->step();
  c.time = solver_->time();
  ExportSolverState(*solver_, c.doubles, c.ints);
  ASSIGN_OR_RETURN(std::vector<RveRecord> rves, pool_->ExportAll());
  c.rves = std::move(rves);
  c.templates = templates_;
  return c;
}

absl::Status Simulation::WriteCheckpoint() {
  ASSIGN_OR_RETURN(store::SimCheckpoint c, Snapshot());
  store::FileInfo info;
  info.created_by = "mpm_client";
  return store::WriteSimCheckpoint(options_.out_dir + "/checkpoint.h5", c, info);
}

std::string FormatTimeSplit(const SimulationSummary& s) {
  return client_run::FormatTimeSplit({s.wall_s, s.rve_s, s.output_s, s.rve_stats, s.rve_workers},
                                     "grid");
}

absl::StatusOr<std::unique_ptr<Simulation>> Simulation::Start(const CaseSpec& spec,
                                                              const SimulationOptions& options) {
  std::unique_ptr<Simulation> sim(new Simulation());
  sim->spec_ = spec;
  sim->case_json_ = ToJson(spec);
  sim->options_ = options;
  sim->run_id_ = client_run::MakeRunId(spec.name);
  RETURN_IF_ERROR(MakeOutputDir(options.out_dir));
  RETURN_IF_ERROR(sim->ResolveCaseTemplates());
  RETURN_IF_ERROR(sim->Connect());
  RETURN_IF_ERROR(sim->UploadTemplates());
  const std::vector<double> density = sim->RegionDensities();
  ASSIGN_OR_RETURN(MaterialPoints points, FillRegions(spec, density));
  const RveStarts starts = sim->PlanRveStarts(points, density);
  RETURN_IF_ERROR(sim->CreateRves(starts, points));
  ASSIGN_OR_RETURN(const double dt, sim->InitialTimeStep(density));
  sim->model_ = std::make_unique<RveStressModel>(sim->pool_.get(), &sim->rve_seconds_);
  ASSIGN_OR_RETURN(std::unique_ptr<Solver> solver,
                   Solver::Create(spec, std::move(points), sim->model_.get(), dt));
  sim->solver_ = std::move(solver);
  sim->LogCornerOverhangs();
  sim->SetApplyOptions();
  RETURN_IF_ERROR(sim->OpenOutputs(/*resume=*/false));
  return sim;
}

absl::Status Simulation::ResolveCaseTemplates() {
  const std::string cache =
      client_run::TemplateCacheDir(options_.template_cache_dir, options_.out_dir);
  ASSIGN_OR_RETURN(
      templates_, client_run::ResolveTemplates(
                      spec_.templates, cache, [&](const std::string& l) { Log(l); }, "mpm_client"));
  return absl::OkStatus();
}

const TemplateRecord& Simulation::CaseTemplate(const std::string& name) const {
  return *std::find_if(templates_.begin(), templates_.end(),
                       [&](const TemplateRecord& t) { return t.name == name; });
}

std::vector<double> Simulation::RegionDensities() const {
  std::vector<double> density;
  for (const MaterialRegion& r : spec_.regions) {
    density.push_back(r.density > 0 ? r.density
                                    : BulkDensity(CaseTemplate(r.rve_template).packing));
  }
  return density;
}

Simulation::RveStarts Simulation::PlanRveStarts(const MaterialPoints& points,
                                                const std::vector<double>& density) const {
  const CaseSpec& spec = spec_;
  const std::size_t n = points.size();
  // RVEs: one per point, consolidated to the geostatic stress of its depth
  // when the region asks for it (σv = ρ·|g|·depth + surcharge). Saturated:
  // the effective stress, with the buoyant density ρ − (1 − n0)·ρ_f (the
  // water table at or above the surface; mixed dry and saturated soil is
  // out of scope), the pore pressure hydrostatic (FillRegions).
  const double g = spec.solver.gravity.norm();
  std::vector<double> stress_density = density;  // kg/m³
  if (spec.phases.saturated) {
    for (std::size_t r = 0; r < spec.regions.size(); ++r) {
      const dem::RveSnapshot& t = CaseTemplate(spec.regions[r].rve_template).packing;
      const double n0 = spec.phases.porosity > 0 ? spec.phases.porosity
                                                 : 1.0 - BulkDensity(t) / t.material.density;
      stress_density[r] -= (1.0 - n0) * spec.phases.fluid_density;
    }
  }
  RveStarts out;
  out.template_of.resize(n);
  out.initial.resize(n);
  out.cost.resize(n);
  out.vertical_stress0.assign(n, std::numeric_limits<double>::quiet_NaN());
  std::vector<std::string>& template_of = out.template_of;
  std::vector<InitialStress>& initial = out.initial;
  std::vector<double>& cost = out.cost;
  // Per region, for the notes below (Pa, compression +): its points with an
  // initial stress of their own; those starting below
  // dem::kLowConsolidationStress and the least principal stress among them;
  // those the floor (initial_stress.minimum) lifts and the largest geostatic
  // stress among them.
  struct RegionStart {
    std::int64_t points = 0, low = 0, lifted = 0;
    double least = dem::kLowConsolidationStress, largest_lifted = 0.0;
  };
  std::vector<RegionStart> starts(spec.regions.size());
  for (std::size_t p = 0; p < n; ++p) {
    const MaterialRegion& r = spec.regions[points.region[p]];
    template_of[p] = ServerTemplateName(r.rve_template);
    cost[p] = static_cast<double>(CaseTemplate(r.rve_template).packing.radius.size());
    const double depth = std::max(0.0, r.surface_y - points.position[p].y());
    const double geostatic = stress_density[points.region[p]] * g * depth + r.surcharge;
    const double sv = std::max(r.minimum_stress, geostatic);
    InitialStress& s = initial[p];
    switch (r.initial_stress) {
      case InitialStressKind::kTemplate:
        s.kind = InitialStress::Kind::kTemplate;
        break;
      case InitialStressKind::kIsotropic:
        s.kind = InitialStress::Kind::kIsotropic;
        s.pressure = sv;
        break;
      case InitialStressKind::kK0:
        s.kind = InitialStress::Kind::kK0;
        s.vertical_compression = sv;
        s.k0 = r.k0;
        break;
    }
    if (r.initial_stress != InitialStressKind::kTemplate) {
      out.vertical_stress0[p] = geostatic;
      RegionStart& start = starts[points.region[p]];
      ++start.points;
      if (r.minimum_stress > geostatic) {
        ++start.lifted;
        start.largest_lifted = std::max(start.largest_lifted, geostatic);
      }
      const double least =
          r.initial_stress == InitialStressKind::kK0 ? std::min(sv, r.k0 * sv) : sv;
      if (least < dem::kLowConsolidationStress) {
        ++start.low;
        start.least = std::min(start.least, least);
      }
    }
  }
  for (std::size_t r = 0; r < spec.regions.size(); ++r) {
    const RegionStart& start = starts[r];
    if (start.low > 0) {
      Log(absl::StrFormat(
          "note: region %s starts %d of its points below %.0f Pa (the least stress %.4g Pa): "
          "RVEs may not consolidate that low, and the run then stops while creating them; "
          "initial_stress.minimum raises the floor (cases/FORMAT.md)",
          spec.regions[r].name, start.low, dem::kLowConsolidationStress, start.least));
    }
    // A floor meant for the few points near a free surface (2 kPa in the
    // shipped cases) that lifts most of a soil under gravity starts it at a
    // stress its weight does not balance: at the surface it pushes itself
    // apart. (pipe-ci at a 1 MPa floor: kinetic energy 37 kJ by step 20,
    // then 2.5 s a step.) Without gravity the floor is the stress meant.
    if (g > 0 && 2 * start.lifted > start.points) {
      Log(absl::StrFormat(
          "note: region %s's initial_stress.minimum (%.4g Pa) lifts %d of its %d points above "
          "their geostatic stress (the largest of those %.4g Pa): the soil's weight does not "
          "hold such a stress, and at a free surface the soil pushes itself apart (a run may "
          "slow to seconds a step)",
          spec.regions[r].name, spec.regions[r].minimum_stress, start.lifted, start.points,
          start.largest_lifted));
    }
  }
  return out;
}

absl::Status Simulation::CreateRves(const RveStarts& starts, MaterialPoints& points) {
  const CaseSpec& spec = spec_;
  const SimulationOptions& options = options_;
  const std::size_t n = points.size();
  const std::vector<std::string>& template_of = starts.template_of;
  const std::vector<InitialStress>& initial = starts.initial;
  pool_->Assign(starts.cost);
  pool_->SetPointSizes(starts.cost);
  // Each template's own controls with the case's DEM steps per increment,
  // inertial-number bound and stretch bound, where the case sets them.
  std::map<std::string, dem::Controls> controls;
  if (spec.rve.min_steps > 0 || spec.rve.max_inertial_number > 0 || spec.rve.max_stretch > 0) {
    for (const TemplateRecord& t : templates_) {
      dem::Controls c = t.packing.controls;
      if (spec.rve.min_steps > 0) c.min_steps = spec.rve.min_steps;
      if (spec.rve.max_inertial_number > 0) c.max_inertial_number = spec.rve.max_inertial_number;
      if (spec.rve.max_stretch > 0) c.max_stretch = spec.rve.max_stretch;
      controls[ServerTemplateName(t.name)] = c;
    }
  }
  Log(absl::StrFormat("creating %d RVEs on %d server(s)...", n, pool_->num_endpoints()));
  const Clock::time_point create_start = Clock::now();
  // A line every ~2 s while the RVEs are consolidated (minutes for large
  // cases), in the style of the stepping's progress lines, from a ticker
  // thread: a call to the servers can take longer than that.
  struct Consolidation {
    absl::Mutex mu;
    std::int64_t done ABSL_GUARDED_BY(mu) = 0;
    std::int64_t total ABSL_GUARDED_BY(mu) = 0;
    bool finished ABSL_GUARDED_BY(mu) = false;
  } consolidation;
  std::thread ticker;
  if (options.progress) {
    ticker = std::thread([&] {
      absl::MutexLock lock(&consolidation.mu);
      while (!consolidation.mu.AwaitWithTimeout(absl::Condition(&consolidation.finished),
                                                absl::Seconds(2))) {
        const std::int64_t done = consolidation.done, total = consolidation.total;
        if (total == 0) continue;
        const double wall = Seconds(Clock::now() - create_start);
        const std::string eta =
            done > 0 ? absl::StrFormat("%.0f s", wall / static_cast<double>(done) *
                                                     static_cast<double>(total - done))
                     : std::string("?");
        Log(
            absl::StrFormat("consolidating RVEs: %d/%d initial stresses done  wall %.1f s  "
                            "ETA %s",
                            done, total, wall, eta));
      }
    });
  }
  absl::StatusOr<std::vector<dem::RveState>> states =
      pool_->Create(template_of, initial, controls, [&](std::int64_t done, std::int64_t total) {
        absl::MutexLock lock(&consolidation.mu);
        consolidation.done = done;
        consolidation.total = total;
      });
  {
    absl::MutexLock lock(&consolidation.mu);
    consolidation.finished = true;
  }
  if (ticker.joinable()) ticker.join();
  if (!states.ok()) return states.status();
  Log(absl::StrFormat("created %d RVEs in %.1f s", n, Seconds(Clock::now() - create_start)));
  for (std::size_t p = 0; p < n; ++p) {
    points.stress[p] = (*states)[p].stress;
    points.response[p] = RveStressModel::ToResponse((*states)[p]);
    if (spec.phases.saturated) {
      // n0 = e0/(1 + e0) of the point's own RVE unless the case gives it.
      const double e0 = (*states)[p].void_ratio;
      if (spec.phases.porosity == 0) points.porosity0[p] = e0 / (1.0 + e0);
      const double geostatic = starts.vertical_stress0[p];
      points.vertical_stress0[p] = std::isnan(geostatic) ? -(*states)[p].stress(1, 1) : geostatic;
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<double> Simulation::InitialTimeStep(const std::vector<double>& density) {
  const CaseSpec& spec = spec_;
  // Fixed, or Δt = cfl·h/c with c = sqrt(M/ρ) from the stiffest
  // RVE's contact tangent (an upper bound of its P-wave modulus).
  double dt = spec.solver.time_step;
  if (dt <= 0) {
    double modulus = spec.solver.wave_modulus;
    if (modulus <= 0) {
      ASSIGN_OR_RETURN(std::vector<dem::RveState> tangent, pool_->Get(/*want_tangent=*/true));
      for (const dem::RveState& s : tangent) {
        if (s.tangent) modulus = std::max(modulus, TangentWaveModulus(*s.tangent));
      }
    }
    double rho = *std::min_element(density.begin(), density.end());
    if (!(modulus > 0) || !(rho > 0)) {
      return absl::FailedPreconditionError(
          "cannot derive the time step: the RVEs have no stiffness (set solver.time_step)");
    }
    dt = CflTimeStep(spec.solver.cfl, spec.grid.cell_size, modulus, spec.solver.mass_scale * rho);
    Log(absl::StrFormat("time step %.4g s (CFL %.2f, M = %.4g MPa, rho = %.1f kg/m3%s)", dt,
                        spec.solver.cfl, modulus * 1e-6, rho,
                        spec.solver.mass_scale != 1.0
                            ? absl::StrFormat(", mass scaled %g times", spec.solver.mass_scale)
                            : ""));
  }
  return dt;
}

absl::StatusOr<std::unique_ptr<Simulation>> Simulation::Resume(const std::string& checkpoint_path,
                                                               const SimulationOptions& options) {
  RETURN_IF_ERROR(MakeOutputDir(options.out_dir));
  ASSIGN_OR_RETURN(store::SimCheckpoint c, store::ReadSimCheckpoint(checkpoint_path));
  absl::StatusOr<CaseSpec> spec = ParseCase(c.case_json, ".");
  if (!spec.ok()) {
    return absl::DataLossError(
        absl::StrCat(checkpoint_path, ": its case does not parse: ", spec.status().message()));
  }
  std::string case_json = c.case_json;
  // Checked before any server is asked to hold the RVEs.
  std::vector<CaseOverride> overrides;
  if (options.end_time > 0) {
    if (!(options.end_time > c.time)) {
      return absl::InvalidArgumentError(absl::StrFormat(
          "--end-time %.6g s is not after the checkpoint's time %.6g s", options.end_time, c.time));
    }
    overrides.push_back({"/solver/end_time", absl::StrFormat("%.17g", options.end_time)});
  }
  // The CFL step scales with the CFL number alone (the modulus and density
  // were fixed at the start), so the new step is the old one times the ratio.
  double dt_ratio = 1.0;
  if (options.cfl > 0) {
    if (spec->solver.time_step > 0) {
      return absl::InvalidArgumentError(absl::StrFormat(
          "--cfl: this run's case fixes solver.time_step = %.6g s; it has no CFL step to change",
          spec->solver.time_step));
    }
    dt_ratio = options.cfl / spec->solver.cfl;
    overrides.push_back({"/solver/cfl", absl::StrFormat("%.17g", options.cfl)});
  }
  if (options.f_bar) {
    overrides.push_back({"/solver/f_bar", absl::StrCat("\"", FBarName(*options.f_bar), "\"")});
  }
  if (options.nonlocal_radius) {
    overrides.push_back(
        {"/solver/nonlocal_radius", absl::StrFormat("%.17g", *options.nonlocal_radius)});
  }
  if (options.nonlocal_fraction) {
    overrides.push_back(
        {"/solver/nonlocal_fraction", absl::StrFormat("%.17g", *options.nonlocal_fraction)});
  }
  if (!overrides.empty()) {
    spec = ParseCase(c.case_json, ".", overrides);
    if (!spec.ok()) return spec.status();
    case_json = ToJson(*spec);
  }
  std::unique_ptr<Simulation> sim(new Simulation());
  sim->spec_ = *std::move(spec);
  sim->case_json_ = std::move(case_json);
  sim->options_ = options;
  sim->run_id_ = client_run::MakeRunId(sim->spec_.name);
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
  sim->model_ = std::make_unique<RveStressModel>(sim->pool_.get(), &sim->rve_seconds_);
  ASSIGN_OR_RETURN(std::unique_ptr<Solver> solver,
                   SolverFromState(sim->spec_, c.doubles, c.ints, sim->model_.get()));
  sim->solver_ = std::move(solver);
  if (dt_ratio != 1.0) {
    const double dt = sim->solver_->dt();
    sim->solver_->set_dt(dt * dt_ratio);
    sim->Log(absl::StrFormat("time step %.4g s -> %.4g s (CFL %.2f)", dt, sim->solver_->dt(),
                             options.cfl));
  }
  if (options.f_bar) sim->Log(absl::StrCat("F-bar: ", FBarName(*options.f_bar)));
  if (options.nonlocal_radius) {
    sim->Log(absl::StrFormat("nonlocal strain radius: %.4g m", *options.nonlocal_radius));
  }
  if (options.nonlocal_fraction) {
    sim->Log(absl::StrFormat("nonlocal fraction: %.4g", *options.nonlocal_fraction));
  }
  sim->SetApplyOptions();
  sim->Log(absl::StrFormat("resumed %s at step %d, t = %.6g s", checkpoint_path,
                           sim->solver_->step(), sim->solver_->time()));
  RETURN_IF_ERROR(sim->OpenOutputs(/*resume=*/true));
  return sim;
}

struct Simulation::RecoveryPoint {
  std::int64_t step = -1;
  std::map<std::string, std::vector<double>> doubles;
  std::map<std::string, std::vector<std::int64_t>> ints;
  std::vector<RveRecord> rves;  // every point's, by id
};

bool Simulation::RecoveryOn() const { return options_.recovery && !options_.servers.empty(); }

namespace {

double WallSeconds() { return Seconds(Clock::now().time_since_epoch()); }

// What a point costs per step for placing it: its measured work in
// `measured` (RvePool::point_work) where there is any, else its RVE's
// particle count (before the first step). Only the ratios matter.
std::vector<double> PlacementCost(std::span<const double> measured,
                                  std::span<const RveRecord> rves) {
  const bool any = std::any_of(measured.begin(), measured.end(), [](double c) { return c > 0; });
  std::vector<double> cost(rves.size());
  for (std::size_t p = 0; p < rves.size(); ++p) {
    cost[p] = any && p < measured.size() ? measured[p]
                                         : static_cast<double>(rves[p].packing.radius.size());
  }
  return cost;
}

}  // namespace

absl::Status Simulation::TakeRecoveryPoint(SimulationSummary& sum) {
  const Clock::time_point t0 = Clock::now();
  auto point = std::make_unique<RecoveryPoint>();
  point->step = solver_->step();
  ExportSolverState(*solver_, point->doubles, point->ints);
  ASSIGN_OR_RETURN(point->rves, pool_->ExportAll());
  recovery_ = std::move(point);
  // Sizes change where an RVE's cell doubled.
  std::vector<double> sizes;
  for (const RveRecord& r : recovery_->rves) {
    sizes.push_back(static_cast<double>(r.packing.radius.size()));
  }
  pool_->SetPointSizes(std::move(sizes));
  ++sum.recovery_points;
  // Servers back from a loss take RVEs again; otherwise balance by cost.
  const bool rejoined = ProbeLost(/*force=*/false, sum);
  RETURN_IF_ERROR(Rebalance(/*force=*/rejoined, sum));
  sum.recovery_s += Seconds(Clock::now() - t0);
  return absl::OkStatus();
}

bool Simulation::ProbeLost(bool force, SimulationSummary& sum) {
  bool rejoined = false;
  for (int k = 0; k < pool_->num_endpoints(); ++k) {
    if (!pool_->lost(k)) continue;
    const double now = WallSeconds();
    if (!force && now - last_probe_s_[k] < probe_wait_s_[k]) continue;
    last_probe_s_[k] = now;
    client::RveEndpoint& e = pool_->endpoint(k);
    if (!e.Ping(absl::Seconds(1)).ok()) {
      probe_wait_s_[k] = std::min(2 * probe_wait_s_[k], 12 * options_.probe_interval_s);
      continue;
    }
    probe_wait_s_[k] = options_.probe_interval_s;
    // What it may still hold of this run is stale: it starts empty.
    if (absl::Status s = e.Drop(pool_->run_id()); !s.ok() && !absl::IsNotFound(s)) continue;
    pool_->MarkAlive(k);
    ++sum.servers_rejoined;
    rejoined = true;
    Log(absl::StrFormat("server %s answers again: it rejoins the run", e.name()));
  }
  return rejoined;
}

absl::Status Simulation::Rebalance(bool force, SimulationSummary& sum) {
  if (recovery_ == nullptr || pool_->num_alive() < 2) return absl::OkStatus();
  if (!force && options_.rebalance_threshold <= 0) return absl::OkStatus();
  const std::vector<double>& total = pool_->point_work();
  std::vector<double> cost(total.size(), 0.0);
  for (std::size_t p = 0; p < total.size(); ++p) {
    cost[p] = total[p] - (p < cost_checked_.size() ? cost_checked_[p] : 0.0);
  }
  cost_checked_ = total;
  cost = PlacementCost(cost, recovery_->rves);
  std::vector<int> plan = pool_->PlanAssignment(cost);
  const double now = pool_->Makespan(pool_->assignment(), cost);
  const double planned = pool_->Makespan(plan, cost);
  imbalance_streak_ =
      planned < (1.0 - options_.rebalance_threshold) * now ? imbalance_streak_ + 1 : 0;
  if (!force && imbalance_streak_ < 2) return absl::OkStatus();
  imbalance_streak_ = 0;
  std::int64_t moved = 0;
  for (std::size_t p = 0; p < plan.size(); ++p) moved += plan[p] != pool_->assignment()[p];
  if (moved == 0) return absl::OkStatus();
  RETURN_IF_ERROR(pool_->Migrate(std::move(plan), recovery_->rves));
  sum.rves_moved += moved;
  Log(
      absl::StrFormat("balanced at step %d: %d RVEs moved; makespan %.4g -> %.4g particle-steps "
                      "per worker since the last check",
                      solver_->step(), moved, now, planned));
  return absl::OkStatus();
}

absl::Status Simulation::Recover(const absl::Status& cause, SimulationSummary& sum) {
  std::vector<int> failed = pool_->TakeFailed();
  if (failed.empty() || recovery_ == nullptr) return cause;
  const Clock::time_point t0 = Clock::now();
  const std::int64_t lost_at = solver_->step();
  const bool deadline = absl::IsDeadlineExceeded(cause) ||
                        absl::StrContains(cause.message(), "Deadline Exceeded") ||
                        absl::StrContains(cause.message(), "deadline");
  // A deadline missed by a server that was only slow must not be missed
  // again in the replay.
  if (deadline) pool_->RelaxDeadline();
  for (int attempt = 0;; ++attempt) {
    for (int k : failed) {
      pool_->MarkLost(k);
      last_probe_s_[k] = WallSeconds();
      ++sum.servers_lost;
      // Its own error: `cause` is the first failing server's.
      const absl::Status& own = pool_->last_failure(k);
      Log(absl::StrFormat("server %s lost (run at step %d): %s", pool_->endpoint(k).name(), lost_at,
                          own.ok() ? cause.message() : own.message()));
    }
    // One restarted at once (a supervisor) takes its share again.
    if (attempt > 0 || pool_->num_alive() == 0) ProbeLost(/*force=*/true, sum);
    const Clock::time_point wait_start = Clock::now();
    while (pool_->num_alive() == 0 && Seconds(Clock::now() - wait_start) < options_.server_wait_s) {
      absl::SleepFor(absl::Seconds(1));
      ProbeLost(/*force=*/true, sum);
    }
    if (pool_->num_alive() == 0) {
      return absl::UnavailableError(absl::StrFormat(
          "every RVE server is lost (none answered within %.0f s); last error: %s. Resume from a "
          "checkpoint (mpm_client resume) once servers run again",
          options_.server_wait_s, cause.message()));
    }
    pool_->Assign(PlacementCost(pool_->point_work(), recovery_->rves));
    absl::Status restored = pool_->Restore(recovery_->rves);
    if (restored.ok()) break;
    failed = pool_->TakeFailed();
    if (failed.empty() || attempt >= pool_->num_endpoints()) {
      return absl::Status(restored.code(),
                          absl::StrCat("recovering from a lost server: ", restored.message(),
                                       " (after: ", cause.message(), ")"));
    }
  }
  ASSIGN_OR_RETURN(std::unique_ptr<Solver> solver,
                   SolverFromState(spec_, recovery_->doubles, recovery_->ints, model_.get()));
  solver_ = std::move(solver);
  SetApplyOptions();
  RETURN_IF_ERROR(out_->results->Close());
  RETURN_IF_ERROR(OpenOutputs(/*resume=*/true));
  const std::int64_t replay = lost_at - recovery_->step;
  sum.steps -= replay;
  sum.steps_replayed += replay;
  cost_checked_ = pool_->point_work();
  sum.recovery_s += Seconds(Clock::now() - t0);
  std::string hosts;
  for (int k = 0; k < pool_->num_endpoints(); ++k) {
    if (pool_->lost(k)) continue;
    absl::StrAppend(&hosts, hosts.empty() ? "" : ", ", pool_->endpoint(k).name(), " (",
                    pool_->points_of(k).size(), ")");
  }
  Log(
      absl::StrFormat("recovered in %.2f s: %d RVEs restored from step %d onto %s; replaying "
                      "steps %d..%d",
                      Seconds(Clock::now() - t0), recovery_->rves.size(), recovery_->step, hosts,
                      recovery_->step + 1, lost_at));
  return absl::OkStatus();
}

std::string Simulation::ServerLoadLine() {
  const int n = pool_->num_endpoints();
  if (n < 2) return "";
  const std::vector<double>& busy = pool_->endpoint_busy_seconds();
  const std::vector<double>& engine = pool_->endpoint_engine_seconds();
  busy_shown_.resize(n, 0.0);
  engine_shown_.resize(n, 0.0);
  const double apply = pool_->total_apply_seconds() - apply_shown_;
  double engine_total = 0.0;
  for (int k = 0; k < n; ++k) engine_total += engine[k] - engine_shown_[k];
  std::string line = "  servers:";
  for (int k = 0; k < n; ++k) {
    if (pool_->lost(k)) {
      absl::StrAppend(&line, " ", pool_->endpoint(k).name(), " lost;");
    } else {
      const double load = engine_total > 0 ? (engine[k] - engine_shown_[k]) / engine_total : 0.0;
      const double idle = apply > 0 ? 1.0 - (busy[k] - busy_shown_[k]) / apply : 0.0;
      absl::StrAppendFormat(&line, " %s load %.0f %% idle %.0f %%;", pool_->endpoint(k).name(),
                            100 * load, 100 * std::max(0.0, idle));
    }
    busy_shown_[k] = busy[k];
    engine_shown_[k] = engine[k];
  }
  apply_shown_ = pool_->total_apply_seconds();
  line.pop_back();
  return line;
}

absl::Status Simulation::UpdateTimeStep() {
  const Clock::time_point t0 = Clock::now();
  absl::StatusOr<std::vector<dem::RveState>> got = pool_->Get(/*want_tangent=*/true);
  rve_seconds_ += Seconds(Clock::now() - t0);  // an RVE call: in the split's service share
  if (!got.ok()) return got.status();
  const std::vector<dem::RveState>& states = *got;
  const MaterialPoints& mp = solver_->points();
  const std::vector<std::uint8_t>& lost = solver_->lost();
  double speed = 0.0;  // m/s
  for (std::size_t p = 0; p < mp.size() && p < states.size(); ++p) {
    if ((p < lost.size() && lost[p]) || !states[p].tangent) continue;
    const double modulus = TangentWaveModulus(*states[p].tangent);  // Pa
    const double density = spec_.solver.mass_scale * mp.mass[p] / mp.volume[p];
    if (!(modulus > 0) || !(density > 0)) continue;
    speed = std::max(speed, WaveSpeed(modulus, density) + mp.velocity[p].norm());
  }
  // Not one point with contacts: nothing to take a speed from; keep the step.
  if (!(speed > 0) || !std::isfinite(speed)) return absl::OkStatus();
  solver_->set_dt(spec_.solver.cfl * spec_.grid.cell_size / speed);
  SetApplyOptions();
  return absl::OkStatus();
}

absl::StatusOr<SimulationSummary> Simulation::StepToEnd() {
  SimulationSummary sum;
  const OutputSpec& o = spec_.output;
  const double end = spec_.solver.end_time;
  const std::int64_t update_every = spec_.solver.time_step_update_every;
  // The run ends at the step count end/Δt; with an updated Δt, at the steps
  // the time left takes at the current Δt, counted again at each update.
  std::int64_t total_steps = 0;
  auto count_steps = [&]() -> absl::Status {
    const double dt = solver_->dt();
    const double steps_needed =
        update_every > 0
            ? static_cast<double>(solver_->step()) + std::ceil((end - solver_->time()) / dt - 1e-9)
            : std::ceil(end / dt - 1e-9);
    // Bounded before the cast: a step count beyond int64 was undefined (and
    // ended runs at step 0); beyond kMaxSteps a run would not end in a lifetime.
    if (!(steps_needed <= static_cast<double>(kMaxSteps))) {
      return absl::FailedPreconditionError(absl::StrFormat(
          "solver.end_time %.6g s at a time step of %.4g s is %.4g MPM steps, more than the limit "
          "of %d (cases/FORMAT.md): shorten end_time or raise the time step",
          end, dt, steps_needed, kMaxSteps));
    }
    total_steps = std::max(solver_->step(), static_cast<std::int64_t>(steps_needed));
    return absl::OkStatus();
  };
  RETURN_IF_ERROR(count_steps());
  const Clock::time_point start = Clock::now();
  const double rve_start = rve_seconds_;
  const std::int64_t evals_start = pool_->evaluations();
  const client::ApplyStats stats_start = pool_->apply_stats();
  Clock::time_point row_clock = start;
  std::int64_t row_step = solver_->step();
  Clock::time_point last_progress = start;
  auto output_time = Clock::duration::zero();
  // Recovery points: one now, then every recovery_interval_ steps, chosen
  // from what taking one costs against a step.
  Clock::time_point point_clock = start;
  if (RecoveryOn()) RETURN_IF_ERROR(TakeRecoveryPoint(sum));
  // One step with its outputs; an error leaves the outputs and checkpoint
  // as they were at some step (a recovery rewrites them from its point).
  auto step_once = [&]() -> absl::Status {
    if (update_every > 0 && solver_->step() % update_every == 0) {
      RETURN_IF_ERROR(UpdateTimeStep());
      RETURN_IF_ERROR(count_steps());
    }
    // Between outputs the RVEs measure the stress alone; a step whose frame,
    // checkpoint or stop writes the points' fabric, rotation and
    // coordination has them measured in full (decided from the step number
    // and time alone, so a resumed or recovered run decides alike).
    {
      const std::int64_t next = solver_->step() + 1;
      const double t_next = solver_->time() + solver_->dt(), half = 0.5 * solver_->dt();
      const bool frame = next % o.frame_every == 0 || next >= total_steps ||
                         std::any_of(o.frame_times.begin(), o.frame_times.end(), [&](double t) {
                           return t_next >= t - half && t_next - 2 * half < t - half;
                         });
      const bool checkpoint = o.checkpoint_every > 0 && next % o.checkpoint_every == 0;
      const bool stopping =
          options_.stop_after_steps > 0 && sum.steps + 1 >= options_.stop_after_steps;
      solver_->set_stress_only(!spec_.rve.full_state_every_step &&
                               !(frame || checkpoint || stopping));
    }
    if (absl::Status s = solver_->Step(); !s.ok()) {
      // The RVE pool's errors name the step already.
      const std::string step = absl::StrCat("step ", solver_->step() + 1, ": ");
      if (absl::StartsWith(s.message(), step)) return s;
      return absl::Status(s.code(), absl::StrCat(step, s.message()));
    }
    ++sum.steps;
    const std::int64_t step = solver_->step();
    LogLostPoints();
    const bool last = step >= total_steps;
    const Clock::time_point t_out = Clock::now();
    if (step % o.timeseries_every == 0 || last) {
      const double per_step = Seconds(t_out - row_clock) / static_cast<double>(step - row_step);
      RETURN_IF_ERROR(WriteRow(per_step));
      row_clock = t_out;
      row_step = step;
    }
    // A frame time t is due at the step nearest to it: t_n ≥ t − Δt/2 > t_{n−1}.
    const double t_now = solver_->time(), half = 0.5 * solver_->dt();
    const bool due = std::any_of(o.frame_times.begin(), o.frame_times.end(), [&](double t) {
      return t_now >= t - half && t_now - 2 * half < t - half;
    });
    if (step % o.frame_every == 0 || last || due) {
      RETURN_IF_ERROR(WriteFrame());
    }
    // Where --stop-after stops there is always a checkpoint, checkpoints on
    // or not: stopping is for resuming later.
    const bool stopping =
        !last && options_.stop_after_steps > 0 && sum.steps >= options_.stop_after_steps;
    if ((o.checkpoint_every > 0 && (step % o.checkpoint_every == 0 || last)) || stopping) {
      RETURN_IF_ERROR(WriteCheckpoint());
      if (options_.on_checkpoint) options_.on_checkpoint(step, Seconds(Clock::now() - start));
    }
    if (stopping) {
      const std::string path = options_.out_dir + "/checkpoint.h5";
      Log(
          absl::StrFormat("stopped at step %d (--stop-after=%d); checkpoint written to %s "
                          "(continue with: mpm_client resume %s)",
                          step, options_.stop_after_steps, path, path));
    }
    output_time += Clock::now() - t_out;
    if (RecoveryOn() && !last && !stopping && step - recovery_->step >= recovery_interval_) {
      const double per_step =
          Seconds(Clock::now() - point_clock) / static_cast<double>(step - recovery_->step);
      const Clock::time_point t0 = Clock::now();
      RETURN_IF_ERROR(TakeRecoveryPoint(sum));
      const double taking = Seconds(Clock::now() - t0);
      recovery_interval_ = static_cast<std::int64_t>(std::clamp(
          std::ceil(taking / (options_.recovery_share * std::max(per_step, 1e-9))), 1.0, 1e5));
      point_clock = Clock::now();
    }
    if (options_.progress &&
        (step % o.progress_every == 0 || last ||
         Seconds(Clock::now() - last_progress) >= options_.progress_interval_s)) {
      last_progress = Clock::now();
      const double wall = Seconds(Clock::now() - start);
      const double rate = wall > 0 ? (pool_->evaluations() - evals_start) / wall : 0.0;
      const double eta = wall / static_cast<double>(std::max<std::int64_t>(1, sum.steps)) *
                         static_cast<double>(total_steps - step);
      const std::string dt =
          update_every > 0 ? absl::StrFormat("  dt %.4g s", solver_->dt()) : std::string();
      Log(absl::StrFormat("step %d/%d  t = %.4g s%s  wall %.1f s  ETA %.0f s  %.0f RVE evals/s%s",
                          step, total_steps, solver_->time(), dt, wall, eta, rate,
                          ServerLoadLine()));
    }
    return absl::OkStatus();
  };
  while (solver_->step() < total_steps) {
    if (options_.stop_after_steps > 0 && sum.steps >= options_.stop_after_steps) break;
    const absl::Status s = step_once();
    if (s.ok()) continue;
    if (!RecoveryOn()) return s;
    RETURN_IF_ERROR(Recover(s, sum));
    row_clock = point_clock = Clock::now();
    row_step = solver_->step();
  }
  sum.wall_s = Seconds(Clock::now() - start);
  sum.rve_s = rve_seconds_ - rve_start;
  sum.output_s = Seconds(output_time);
  sum.rve_evaluations = pool_->evaluations() - evals_start;
  sum.rve_stats = pool_->apply_stats().Since(stats_start);
  sum.rve_workers = pool_->total_workers();
  sum.final_step = solver_->step();
  sum.final_time = solver_->time();
  sum.finished = solver_->step() >= total_steps;
  RETURN_IF_ERROR(out_->results->Close());
  if (sum.finished) {
    ASSIGN_OR_RETURN(const Summary summary, WriteRunOutputs(spec_, options_.out_dir));
    // The same lines as `mpm_client summarise`; the verdict is summarise's
    // exit status, a finished run's is 0 either way.
    for (const std::string& line : client_run::SummaryAndCheckLines(summary, spec_.checks)) {
      Log(line);
    }
  }
  return sum;
}

}  // namespace rvehub::mpm
