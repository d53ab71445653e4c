#include "fem_client/core/static_solver.h"

#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace rvehub::fem {

struct StaticSolver::Failure {
  absl::Status status;  // what went wrong, without the step
  bool retry = true;    // whether a smaller step may cure it
};

namespace {

// Whether a smaller load step may cure a material's failure: a packing that
// cannot follow an increment (its limits, a point's own error) may follow a
// smaller one; a lost or refusing server, a missing RVE or a broken call
// fails the same way at any step size.
bool SmallerStepMayCure(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDeadlineExceeded:
    case absl::StatusCode::kCancelled:
    case absl::StatusCode::kUnauthenticated:
    case absl::StatusCode::kPermissionDenied:
    case absl::StatusCode::kNotFound:
    case absl::StatusCode::kUnimplemented:
    case absl::StatusCode::kInternal:
    case absl::StatusCode::kDataLoss:
      return false;
    default:
      return true;
  }
}

// `status` with `message` in front, its code and payloads (the failed point) kept.
absl::Status Prefixed(const absl::Status& status, absl::string_view message) {
  absl::Status out(status.code(), absl::StrCat(message, status.message()));
  status.ForEachPayload(
      [&out](absl::string_view url, const absl::Cord& payload) { out.SetPayload(url, payload); });
  return out;
}

const char* AxisName(int dof) { return dof == 0 ? "x" : "y"; }

// k with `extra` empty rows and columns appended.
Eigen::SparseMatrix<double> Padded(const Eigen::SparseMatrix<double>& k, int extra) {
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(k.nonZeros()));
  for (int c = 0; c < k.outerSize(); ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(k, c); it; ++it) {
      t.emplace_back(static_cast<int>(it.row()), static_cast<int>(it.col()), it.value());
    }
  }
  Eigen::SparseMatrix<double> out(k.rows() + extra, k.cols() + extra);
  out.setFromTriplets(t.begin(), t.end());
  return out;
}

// diag(t, I_extra): the extra unknowns are free.
Eigen::SparseMatrix<double> Expanded(const Eigen::SparseMatrix<double>& t, int extra) {
  Eigen::SparseMatrix<double> out = Padded(t, extra);
  for (int i = 0; i < extra; ++i) {
    out.coeffRef(t.rows() + i, t.cols() + i) = 1.0;
  }
  out.makeCompressed();
  return out;
}

}  // namespace

absl::StatusOr<std::unique_ptr<StaticSolver>> StaticSolver::Create(Mesh mesh, Boundary boundary,
                                                                   SolverOptions options,
                                                                   GaussPointMaterial* material) {
  if (material == nullptr) return absl::InvalidArgumentError("the solver needs a material");
  const SolverOptions& o = options;
  if (!(o.displacement_tolerance > 0.0 && std::isfinite(o.displacement_tolerance)) ||
      !(o.force_tolerance >= 0.0 && std::isfinite(o.force_tolerance)) || o.max_iterations < 1 ||
      o.max_iterations > 1000 || o.max_cutbacks < 0 || o.max_cutbacks > 30 ||
      !(o.perturbation > 0.0 && o.perturbation < 0.1) ||
      !(o.second_gradient >= 0.0 && std::isfinite(o.second_gradient))) {
    return absl::InvalidArgumentError(
        absl::StrCat("solver options: displacement tolerance ", o.displacement_tolerance,
                     " must be positive, force tolerance ", o.force_tolerance,
                     " non-negative, iterations ", o.max_iterations, " in [1, 1000], cut-backs ",
                     o.max_cutbacks, " in [0, 30], perturbation ", o.perturbation,
                     " in (0, 0.1), second-gradient modulus ", o.second_gradient, " non-negative"));
  }
  if (absl::Status s = ValidateMesh(mesh); !s.ok()) return s;
  absl::StatusOr<DofMap> dofs = DofMap::Create(static_cast<int>(mesh.nodes.size()), boundary);
  if (!dofs.ok()) return dofs.status();
  if (absl::Status s = CheckSupports(mesh, *dofs); !s.ok()) return s;
  absl::StatusOr<std::vector<PointGeometry>> reference = EvaluateGeometry(mesh, mesh.nodes);
  if (!reference.ok()) return reference.status();
  std::optional<SecondGradient> second_gradient;
  if (o.second_gradient > 0.0) {
    absl::StatusOr<SecondGradient> sg = SecondGradient::Create(mesh, o.second_gradient);
    if (!sg.ok()) return sg.status();
    second_gradient = *std::move(sg);
  }
  return std::unique_ptr<StaticSolver>(
      new StaticSolver(std::move(mesh), std::move(boundary), options, material, *std::move(dofs),
                       *std::move(reference), std::move(second_gradient)));
}

StaticSolver::StaticSolver(Mesh mesh, Boundary boundary, SolverOptions options,
                           GaussPointMaterial* material, DofMap dofs,
                           std::vector<PointGeometry> reference,
                           std::optional<SecondGradient> second_gradient)
    : mesh_(std::move(mesh)),
      boundary_(std::move(boundary)),
      options_(options),
      material_(material),
      dofs_(std::move(dofs)),
      reference_(std::move(reference)),
      displacement_(Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(mesh_.nodes.size()))),
      second_gradient_(std::move(second_gradient)),
      platens_(boundary_.forced.size()) {
  if (second_gradient_) {
    sg_committed_ = second_gradient_->Initial();
    expand_full_ = Expanded(dofs_.expand(), second_gradient_->unknowns());
  }
}

absl::StatusOr<StepReport> StaticSolver::Step(double factor) {
  if (!std::isfinite(factor)) return absl::InvalidArgumentError("the step factor is not finite");
  StepReport report;
  report.step = steps_ + 1;
  trials_ = 0;
  // (1) The RVEs' initial state: their stresses and tangents at ΔF = I.
  if (committed_.responses.empty()) {
    Failure failure;
    const std::vector<double> unloaded(boundary_.forced.size(), 0.0);
    const Eigen::VectorXd ds =
        Eigen::VectorXd::Zero(second_gradient_ ? second_gradient_->unknowns() : 0);
    if (!Evaluate(Eigen::VectorXd::Zero(displacement_.size()), ds, 0, unloaded, committed_,
                  failure)) {
      committed_.responses.clear();
      return Prefixed(failure.status, absl::StrCat("load step ", report.step, ", "));
    }
    forces_ = NodeSetForces(committed_);
    platens_ = PlatenStates(committed_);
  }
  // (3) March on: the load step in parts, halved on failure.
  double done = 0.0, size = 1.0;  // powers of 2: their sums are exact
  while (done < 1.0) {
    const double part = std::min(size, 1.0 - done);
    SubStepReport sub{part, {}};
    Failure failure;
    if (TrySubStep(factor * part, sub, failure)) {
      report.substeps.push_back(std::move(sub));
      done += part;
      continue;
    }
    if (!failure.retry || report.cutbacks == options_.max_cutbacks) {
      report.trials = trials_;
      return Prefixed(failure.status,
                      absl::StrFormat("load step %d (a part of %g of it, after %d cut-backs), ",
                                      report.step, part, report.cutbacks));
    }
    size = part / 2.0;
    ++report.cutbacks;
  }
  ++steps_;
  report.trials = trials_;
  report.forces = forces_;
  report.platens = platens_;
  return report;
}

bool StaticSolver::TrySubStep(double factor, SubStepReport& report, Failure& failure) {
  const Eigen::SparseMatrix<double>& t = dofs_.expand();
  // (2) Apply the loading step on ∂Ω: the prescribed increments g enter
  // the first solve, linearised on the committed state (the step starts
  // from Δu⁰ = 0, so the first E_d is 1).
  const Eigen::VectorXd g = dofs_.Prescribed(factor);
  // The forced platens' loads at the end of this part, and their change
  // (dead loads: a change of f_ext alone, the tangent as it was).
  std::vector<double> force_increment, platen_force;
  for (std::size_t k = 0; k < boundary_.forced.size(); ++k) {
    force_increment.push_back(factor * boundary_.forced[k].force_increment);
    platen_force.push_back(committed_.platen_force[k] + force_increment.back());
  }
  const int extra = second_gradient_ ? second_gradient_->unknowns() : 0;
  Eigen::VectorXd du = Eigen::VectorXd::Zero(g.size());
  Eigen::VectorXd q = Eigen::VectorXd::Zero(dofs_.unknowns());  // Δu's unknowns
  Eigen::VectorXd ds = Eigen::VectorXd::Zero(extra);            // the second gradient's
  const Evaluation* at = &committed_;
  Evaluation ev;
  // kPrevious: start from the last increment, scaled, with g imposed
  // exactly; then every solve is a correction (no g in it).
  bool predicted = false;
  if (options_.predictor == Predictor::kPrevious && last_rate_.size() == q.size() + extra) {
    const Eigen::VectorXd q0 = factor * last_rate_.head(q.size());
    const Eigen::VectorXd ds0 = factor * last_rate_.tail(extra);
    const Eigen::VectorXd du0 = g + t * q0;
    Failure predictor_failure;
    if (Evaluate(du0, ds0, 0, platen_force, ev, predictor_failure)) {
      du = du0;
      q = q0;
      ds = ds0;
      at = &ev;
      predicted = true;
    } else if (!predictor_failure.retry) {
      failure = std::move(predictor_failure);
      return false;
    }
  }
  // With a second gradient the system grows by its unknowns, all free:
  // T becomes diag(T, I), K gains the second gradient's blocks (constant
  // over the step: they live on the committed configuration).
  Eigen::SparseMatrix<double> k_sg;
  if (extra > 0) k_sg = second_gradient_->Stiffness(mesh_, mesh_.nodes);
  for (int j = 1; j <= options_.max_iterations; ++j) {
    const bool imposes = j == 1 && !predicted;  // the first solve of a zero start
    // (2a) The tangent operator of every Gauss point.
    std::vector<Tangent> d;
    if (!Tangents(*at, j, d, failure)) return false;
    // (2b) Assemble K_t (eq. 3, with the geometric terms) and solve
    // Tᵀ K T δq = −Tᵀ (R + K g − Δf) (g and the platens' Δf only in the
    // first) for the correction.
    Eigen::VectorXd delta = imposes ? g : Eigen::VectorXd::Zero(g.size());
    if (dofs_.unknowns() + extra > 0) {
      Eigen::SparseMatrix<double> k = TangentStiffness(
          mesh_, reference_, at->current, at->responses, d, boundary_.pressures, at->x);
      Eigen::VectorXd rhs = at->residual, gk = g;  // gk: g over all the system's unknowns
      if (extra > 0) {
        k = Padded(k, extra) + k_sg;
        rhs.conservativeResize(rhs.size() + extra);
        rhs.tail(extra) = at->sg_residual;
        gk.conservativeResize(gk.size() + extra);
        gk.tail(extra).setZero();
      }
      if (imposes) {
        rhs += k * gk;
        rhs.head(g.size()) -= PlatenLoads(force_increment);
      }
      const Eigen::SparseMatrix<double>& tt = extra > 0 ? expand_full_ : t;
      const Eigen::SparseMatrix<double> kr = tt.transpose() * k * tt;
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
      lu.compute(kr);
      Eigen::VectorXd dq;
      if (lu.info() == Eigen::Success) dq = lu.solve(-(tt.transpose() * rhs));
      if (lu.info() != Eigen::Success || !dq.allFinite()) {
        failure.status = absl::AbortedError(absl::StrCat(
            "iteration ", j, ": the tangent stiffness (", OperatorName(options_.tangent),
            " operator) is singular: ", lu.lastErrorMessage()));
        return false;
      }
      delta += t * dq.head(q.size());
      q += dq.head(q.size());
      ds += dq.tail(extra);
    }
    du += delta;
    IterationReport it;
    it.displacement_error = delta.norm() == 0.0 ? 0.0 : delta.norm() / du.norm();
    // (2c–d) Deform the RVEs by the new Δu and take the residual (eq. 4).
    if (!Evaluate(du, ds, j, platen_force, ev, failure)) return false;
    at = &ev;
    const Eigen::VectorXd reduced = t.transpose() * ev.residual;
    it.force_error = ForceError(ev, reduced);
    report.iterations.push_back(it);
    // (2e) Converged (eq. 21): commit the RVEs and the configuration.
    if (it.displacement_error < options_.displacement_tolerance &&
        (options_.force_tolerance == 0.0 || it.force_error < options_.force_tolerance)) {
      return CommitIterate(factor, du, q, ds, ev, failure);
    }
    if (j == options_.max_iterations && options_.accept_unconverged) {
      report.converged = false;
      return CommitIterate(factor, du, q, ds, ev, failure);
    }
    if (j == options_.max_iterations) {
      Eigen::Index worst = 0;
      const double largest = reduced.size() > 0 ? reduced.cwiseAbs().maxCoeff(&worst) : 0.0;
      const int dof = reduced.size() > 0 ? dofs_.DofOf(static_cast<int>(worst)) : 0;
      failure.status = absl::AbortedError(absl::StrFormat(
          "iteration %d: Newton did not converge (E_d = %.3g, tolerance %.3g; E_f = %.3g); the "
          "largest residual, %.4g N/m, is at node %d (%.6g, %.6g) m along %s",
          j, it.displacement_error, options_.displacement_tolerance, it.force_error, largest,
          dof / 2, ev.x[dof / 2].x(), ev.x[dof / 2].y(), AxisName(dof % 2)));
    }
  }
  return false;
}

bool StaticSolver::CommitIterate(double factor, const Eigen::VectorXd& du, const Eigen::VectorXd& q,
                                 const Eigen::VectorXd& ds, Evaluation& ev, Failure& failure) {
  if (absl::Status s = material_->Commit(ev.delta_f); !s.ok()) {
    failure = {Prefixed(s, "the material's Commit failed: "), false};
    return false;
  }
  forces_ = NodeSetForces(ev);
  mesh_.nodes = ev.x;
  displacement_ += du;
  platens_ = PlatenStates(ev);
  reference_ = ev.current;
  if (second_gradient_) {
    sg_committed_ = second_gradient_->Advance(sg_committed_, ds, std::move(ev.double_stress));
  }
  committed_ = std::move(ev);
  if (factor != 0.0) {
    last_rate_.resize(q.size() + ds.size());
    last_rate_ << q / factor, ds / factor;
  }
  // The next step starts here: its ΔF are measured from this state.
  std::fill(committed_.delta_f.begin(), committed_.delta_f.end(), Eigen::Matrix3d::Identity());
  RestartSecondGradient(/*move_forces=*/true);
  return true;
}

bool StaticSolver::Evaluate(const Eigen::VectorXd& du, const Eigen::VectorXd& ds, int iteration,
                            std::span<const double> platen_force, Evaluation& ev,
                            Failure& failure) {
  const std::string where = absl::StrCat("iteration ", iteration, ": ");
  ev.x = Moved(mesh_.nodes, du);
  absl::StatusOr<std::vector<PointGeometry>> current = EvaluateGeometry(mesh_, ev.x);
  if (!current.ok()) {
    failure.status = absl::AbortedError(
        absl::StrCat(where, current.status().message(), " (the iterate deforms it too far)"));
    return false;
  }
  ev.current = *std::move(current);
  // (2c) The deformation of each Gauss point, stretch and rotation (eqs. 10–11).
  ev.delta_f = DeformationIncrements(mesh_, reference_, du);
  const bool want_tangent =
      options_.tangent == TangentOperator::kContact ||
      (options_.tangent == TangentOperator::kInitialElastic && initial_tangents_.empty());
  ++trials_;
  absl::StatusOr<std::vector<PointResponse>> responses = material_->Trial(ev.delta_f, want_tangent);
  if (!responses.ok()) {
    const std::optional<int> point = FailedPoint(responses.status());
    failure.status = Prefixed(
        responses.status(),
        absl::StrCat(where, "the material failed",
                     point ? absl::StrCat(" at ", DescribeGaussPoint(mesh_, *point)) : "", ": "));
    failure.retry = SmallerStepMayCure(responses.status());
    return false;
  }
  if (responses->size() != ev.delta_f.size()) {
    failure = {
        absl::InternalError(absl::StrCat(where, "the material returned ", responses->size(),
                                         " responses for ", ev.delta_f.size(), " Gauss points")),
        false};
    return false;
  }
  for (std::size_t p = 0; p < responses->size(); ++p) {
    if (!(*responses)[p].stress.allFinite()) {
      failure.status = PointFailure(
          absl::AbortedError(absl::StrCat(where, "the material returned a stress not finite at ",
                                          DescribeGaussPoint(mesh_, static_cast<int>(p)))),
          static_cast<int>(p));
      return false;
    }
  }
  ev.responses = *std::move(responses);
  if (want_tangent && options_.tangent == TangentOperator::kInitialElastic) {
    for (std::size_t p = 0; p < ev.responses.size(); ++p) {
      if (!ev.responses[p].tangent.has_value() || !ev.responses[p].tangent->allFinite()) break;
      initial_tangents_.push_back(*ev.responses[p].tangent);
    }
  }
  // (2d) The residual (eq. 4) on the current configuration.
  ev.f_int = InternalForces(mesh_, ev.current, ev.responses);
  if (second_gradient_) {
    SecondGradient::Terms terms =
        second_gradient_->Evaluate(mesh_, mesh_.nodes, sg_committed_, du, ds);
    ev.f_int += terms.internal;
    ev.multiplier_forces = std::move(terms.internal);
    ev.sg_residual = std::move(terms.residual);
    ev.double_stress = std::move(terms.double_stress);
  }
  ev.f_ext = PressureForces(static_cast<int>(du.size()), boundary_.pressures, ev.x) +
             PlatenLoads(platen_force);
  ev.platen_force.assign(platen_force.begin(), platen_force.end());
  ev.residual = ev.f_int - ev.f_ext;
  return true;
}

void StaticSolver::RestartSecondGradient(bool move_forces) {
  if (!second_gradient_) return;
  SecondGradient::Terms terms = second_gradient_->Evaluate(
      mesh_, mesh_.nodes, sg_committed_, Eigen::VectorXd::Zero(displacement_.size()),
      Eigen::VectorXd::Zero(second_gradient_->unknowns()));
  // σ's share stays as the last Trial left it.
  if (move_forces) {
    const Eigen::VectorXd change = terms.internal - committed_.multiplier_forces;
    committed_.f_int += change;
    committed_.residual += change;
  }
  committed_.multiplier_forces = std::move(terms.internal);
  committed_.sg_residual = std::move(terms.residual);
  committed_.double_stress = std::move(terms.double_stress);
}

bool StaticSolver::Tangents(const Evaluation& ev, int iteration, std::vector<Tangent>& d,
                            Failure& failure) {
  const std::string where = absl::StrCat("iteration ", iteration, ": ");
  switch (options_.tangent) {
    case TangentOperator::kPerturbation: {
      trials_ += 4;
      absl::StatusOr<std::vector<Tangent>> dp =
          PerturbationTangents(*material_, ev.delta_f, ev.responses, options_.perturbation);
      if (!dp.ok()) {
        const std::optional<int> point = FailedPoint(dp.status());
        failure.status = Prefixed(
            dp.status(),
            absl::StrCat(where, "the material failed in a perturbation",
                         point ? absl::StrCat(" at ", DescribeGaussPoint(mesh_, *point)) : "",
                         ": "));
        failure.retry = SmallerStepMayCure(dp.status());
        return false;
      }
      d = *std::move(dp);
      return true;
    }
    case TangentOperator::kInitialElastic:
      if (initial_tangents_.size() == ev.responses.size()) {
        d = initial_tangents_;
        return true;
      }
      initial_tangents_.clear();  // the first Trial lacked one: ask again next time
      break;
    case TangentOperator::kContact:
      break;
  }
  d.resize(ev.responses.size());
  for (std::size_t p = 0; p < ev.responses.size(); ++p) {
    const std::optional<Tangent>& tangent = ev.responses[p].tangent;
    if (!tangent.has_value() || !tangent->allFinite()) {
      failure = {absl::FailedPreconditionError(
                     absl::StrCat(where, "the material gave no finite tangent at ",
                                  DescribeGaussPoint(mesh_, static_cast<int>(p)), ", which the ",
                                  OperatorName(options_.tangent), " operator needs")),
                 false};
      return false;
    }
    d[p] = *tangent;
  }
  return true;
}

double StaticSolver::ForceError(const Evaluation& ev, const Eigen::VectorXd& reduced) const {
  // f: the external forces where the dofs are free, the forces that hold the
  // prescribed dofs (f_int = f_ext + reaction) where they are prescribed.
  double f2 = 0.0;
  for (int dof = 0; dof < dofs_.dofs(); ++dof) {
    const double f = dofs_.IsPrescribed(dof) ? ev.f_int[dof] : ev.f_ext[dof];
    f2 += f * f;
  }
  const double r = reduced.norm();
  if (r == 0.0) return 0.0;
  return f2 > 0.0 ? r / std::sqrt(f2) : std::numeric_limits<double>::infinity();
}

Eigen::VectorXd StaticSolver::PlatenLoads(std::span<const double> force) const {
  // On the master's dof alone: Tᵀ gathers it into the platen's unknown,
  // which is all a rigid platen's load acts on.
  Eigen::VectorXd f = Eigen::VectorXd::Zero(dofs_.dofs());
  for (std::size_t k = 0; k < boundary_.forced.size(); ++k) {
    const ForcedPlaten& p = boundary_.forced[k];
    f[2 * p.nodes[0] + p.dof] += force[k];
  }
  return f;
}

std::vector<PlatenState> StaticSolver::PlatenStates(const Evaluation& ev) const {
  std::vector<PlatenState> out;
  for (std::size_t k = 0; k < boundary_.forced.size(); ++k) {
    const ForcedPlaten& p = boundary_.forced[k];
    const int master = 2 * p.nodes[0] + p.dof;
    // The residual of the platen's unknown is the load's imbalance.
    PlatenState state{ev.platen_force[k], ev.platen_force[k], displacement_[master]};
    for (int d = 0; d < dofs_.dofs(); ++d) {
      if (dofs_.UnknownOf(d) == dofs_.UnknownOf(master)) state.resistance += ev.residual[d];
    }
    out.push_back(state);
  }
  return out;
}

std::map<std::string, SetForces> StaticSolver::NodeSetForces(const Evaluation& ev) const {
  std::map<std::string, SetForces> out;
  for (const auto& [name, nodes] : mesh_.node_sets) {
    SetForces& f = out[name];
    for (int a : nodes) {
      f.reaction += ev.residual.segment<2>(2 * a);
      f.internal += ev.f_int.segment<2>(2 * a);
    }
  }
  return out;
}

SolverState StaticSolver::State() const {
  SolverState s;
  s.steps = steps_;
  s.nodes = mesh_.nodes;
  s.displacement = displacement_;
  s.responses = committed_.responses;
  s.f_int = committed_.f_int;
  s.f_ext = committed_.f_ext;
  s.residual = committed_.residual;
  s.platen_force = committed_.platen_force;
  s.initial_tangents = initial_tangents_;
  s.last_rate = last_rate_;
  if (second_gradient_) s.second_gradient = sg_committed_;
  return s;
}

namespace {

bool AllFinite(std::span<const Eigen::Vector2d> v) {
  return std::all_of(v.begin(), v.end(), [](const Eigen::Vector2d& x) { return x.allFinite(); });
}

// InvalidArgument "solver state: <field> <what>" for a state Restore refuses.
absl::Status BadState(absl::string_view field, absl::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat("solver state: ", field, " ", what));
}

absl::Status CheckVector(absl::string_view field, const Eigen::VectorXd& v, Eigen::Index size) {
  if (v.size() != size) {
    return BadState(field, absl::StrCat("has ", v.size(), " values, not ", size));
  }
  if (!v.allFinite()) return BadState(field, "has a value that is not finite");
  return absl::OkStatus();
}

}  // namespace

absl::Status StaticSolver::Restore(SolverState state) {
  const std::size_t nodes = mesh_.nodes.size();
  const Eigen::Index dofs = 2 * static_cast<Eigen::Index>(nodes);
  const std::size_t points = reference_.size();
  if (state.steps < 0) return BadState("steps", absl::StrCat("is negative: ", state.steps));
  if (state.nodes.size() != nodes) {
    return BadState("nodes", absl::StrCat("has ", state.nodes.size(), " nodes, not ", nodes));
  }
  if (!AllFinite(state.nodes)) return BadState("nodes", "has a position that is not finite");
  if (absl::Status s = CheckVector("displacement", state.displacement, dofs); !s.ok()) return s;
  // Before the first step there is no committed Trial yet.
  const bool started = !state.responses.empty();
  if (state.steps > 0 && !started) {
    return BadState("responses", absl::StrCat("are missing after ", state.steps, " steps"));
  }
  if (started) {
    if (state.responses.size() != points) {
      return BadState("responses",
                      absl::StrCat("has ", state.responses.size(), " Gauss points, not ", points));
    }
    for (const PointResponse& r : state.responses) {
      if (!r.stress.allFinite() || (r.tangent.has_value() && !r.tangent->allFinite())) {
        return BadState("responses", "has a stress or tangent that is not finite");
      }
    }
    if (absl::Status s = CheckVector("f_int", state.f_int, dofs); !s.ok()) return s;
    if (absl::Status s = CheckVector("f_ext", state.f_ext, dofs); !s.ok()) return s;
    if (absl::Status s = CheckVector("residual", state.residual, dofs); !s.ok()) return s;
    if (state.platen_force.size() != boundary_.forced.size()) {
      return BadState("platen_force", absl::StrCat("has ", state.platen_force.size(),
                                                   " values, not ", boundary_.forced.size()));
    }
    for (double f : state.platen_force) {
      if (!std::isfinite(f)) return BadState("platen_force", "has a value that is not finite");
    }
  }
  if (!state.initial_tangents.empty() && state.initial_tangents.size() != points) {
    return BadState("initial_tangents", absl::StrCat("has ", state.initial_tangents.size(),
                                                     " Gauss points, not 0 or ", points));
  }
  for (const Tangent& d : state.initial_tangents) {
    if (!d.allFinite()) return BadState("initial_tangents", "has a value that is not finite");
  }
  const int extra = second_gradient_ ? second_gradient_->unknowns() : 0;
  if (state.last_rate.size() > 0) {
    if (absl::Status s = CheckVector("last_rate", state.last_rate, dofs_.unknowns() + extra);
        !s.ok()) {
      return s;
    }
  }
  if (second_gradient_) {
    const SecondGradientState& sg = state.second_gradient;
    if (sg.double_stress.size() != points) {
      return BadState("second_gradient.double_stress",
                      absl::StrCat("has ", sg.double_stress.size(), " Gauss points, not ", points));
    }
    for (const DoubleStress& v : sg.double_stress) {
      if (!v.allFinite()) {
        return BadState("second_gradient.double_stress", "has a value that is not finite");
      }
    }
    if (absl::Status s = CheckVector("second_gradient.multiplier", sg.multiplier,
                                     4 * static_cast<Eigen::Index>(mesh_.elements.size()));
        !s.ok()) {
      return s;
    }
    if (absl::Status s =
            CheckVector("second_gradient.micro", sg.micro,
                        4 * static_cast<Eigen::Index>(second_gradient_->corner_nodes()));
        !s.ok()) {
      return s;
    }
  } else if (!state.second_gradient.double_stress.empty() ||
             state.second_gradient.multiplier.size() > 0 ||
             state.second_gradient.micro.size() > 0) {
    return BadState("second_gradient", "is given to a solver without a second gradient");
  }
  absl::StatusOr<std::vector<PointGeometry>> reference = EvaluateGeometry(mesh_, state.nodes);
  if (!reference.ok()) {
    return BadState("nodes",
                    absl::StrCat("give a mesh the solver refuses: ", reference.status().message()));
  }
  // Accepted: from here on nothing fails.
  steps_ = state.steps;
  mesh_.nodes = std::move(state.nodes);
  displacement_ = std::move(state.displacement);
  reference_ = *std::move(reference);
  initial_tangents_ = std::move(state.initial_tangents);
  last_rate_ = std::move(state.last_rate);
  if (second_gradient_) sg_committed_ = std::move(state.second_gradient);
  committed_ = Evaluation{};
  platens_.assign(boundary_.forced.size(), PlatenState{});
  forces_.clear();
  if (!started) return absl::OkStatus();
  // As TrySubStep leaves them after a commit.
  committed_.x = mesh_.nodes;
  committed_.current = reference_;
  committed_.delta_f.assign(points, Eigen::Matrix3d::Identity());
  committed_.responses = std::move(state.responses);
  committed_.f_int = std::move(state.f_int);
  committed_.f_ext = std::move(state.f_ext);
  committed_.residual = std::move(state.residual);
  committed_.platen_force = std::move(state.platen_force);
  forces_ = NodeSetForces(committed_);
  platens_ = PlatenStates(committed_);
  // As the commit left them: the saved f_int already holds λ's share on
  // this configuration.
  RestartSecondGradient(/*move_forces=*/false);
  return absl::OkStatus();
}

}  // namespace rvehub::fem
