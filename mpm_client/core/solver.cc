#include "mpm_client/core/solver.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "mpm_client/core/body_contact.h"
#include "mpm_client/core/explicit_solver.h"
#include "mpm_client/core/two_phase.h"
#include "mpm_client/core/two_phase_solver.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

using Eigen::Matrix2d;
using Eigen::Matrix3d;
using Eigen::Vector2d;

// Tolerance, in cells, for "on a grid line".
constexpr double kGridTolerance = 1e-9;
// Faces within this many cells of a body are contact candidates.
constexpr double kContactMargin = 0.5;

std::string Format(const Vector2d& x) { return absl::StrCat("(", x.x(), ", ", x.y(), ")"); }

// The index k of the grid line origin + k·h that `value` lies on, or −1.
int GridLineIndex(double value, double origin, double h, int n) {
  const double t = (value - origin) / h;
  if (!(t >= -kGridTolerance && t <= n + kGridTolerance)) return -1;
  const double k = std::round(t);
  return std::abs(t - k) <= kGridTolerance ? static_cast<int>(k) : -1;
}

// A wall node's new velocity relative to the wall (m/s), from its relative
// velocity `rel` and the unit normal n pointing from the obstacle into the
// soil. Rough: no relative motion. Smooth: no normal relative motion.
// Frictional: also, while the soil presses on the obstacle (rel·n < 0), the
// tangential speed reduced by μ·|Δv_n| (Coulomb: tangential impulse ≤ μ ×
// compressive normal impulse). Unilateral contacts let separating nodes go;
// bilateral ones also hold them, without friction (the normal impulse is
// then tensile).
Vector2d ContactVelocity(const Vector2d& rel, const Vector2d& n, ContactKind kind, double mu,
                         bool bilateral) {
  const double vn = rel.dot(n);
  if (!bilateral && vn >= 0.0) return rel;
  if (kind == ContactKind::kRough) return Vector2d::Zero();
  Vector2d vt = rel - vn * n;
  if (kind == ContactKind::kFrictional && vn < 0.0) {
    const double speed = vt.norm();
    const double slip = speed + mu * vn;
    vt = slip > 0.0 ? Vector2d(vt * (slip / speed)) : Vector2d::Zero();
  }
  return vt;
}

Vector2d BodyExtent(const RigidBody& body) {
  return body.shape == RigidBody::Shape::kCircle ? Vector2d(body.radius, body.radius)
                                                 : body.half_size;
}

absl::Status Invalid(absl::string_view what, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat(what, ": ", why));
}

absl::Status ValidateGrid(const GridSpec& grid) {
  if (grid.nx < 1 || grid.ny < 1) {
    return Invalid("grid", absl::StrCat("nx = ", grid.nx, ", ny = ", grid.ny, " must be >= 1"));
  }
  if (!(grid.cell_size > 0.0) || !std::isfinite(grid.cell_size)) {
    return Invalid("grid", absl::StrCat("cell_size = ", grid.cell_size, " must be > 0"));
  }
  if (!grid.origin.allFinite()) return Invalid("grid", "origin must be finite");
  return absl::OkStatus();
}

absl::Status ValidateHistory(absl::string_view name, const std::vector<VelocityPoint>& history) {
  double last = 0.0;
  for (const VelocityPoint& v : history) {
    if (!(v.time >= last) || !std::isfinite(v.time) || !v.velocity.allFinite()) {
      return Invalid(name, "velocity history times must be finite, >= 0 and non-decreasing");
    }
    last = v.time;
  }
  return absl::OkStatus();
}

}  // namespace

void MaterialPoints::Resize(std::size_t n) {
  position.resize(n, Vector2d::Zero());
  velocity.resize(n, Vector2d::Zero());
  mass.resize(n, 0.0);
  volume.resize(n, 0.0);
  volume0.resize(n, 0.0);
  F.resize(n, Matrix2d::Identity());
  stress.resize(n, Matrix3d::Zero());
  half_size0.resize(n, Vector2d::Zero());
  region.resize(n, 0);
  response.resize(n);
  fluid_velocity.resize(n, Vector2d::Zero());
  pore_pressure.resize(n, 0.0);
  porosity0.resize(n, 0.0);
  position0.resize(n, Vector2d::Zero());
  vertical_stress0.resize(n, 0.0);
}

double WaveSpeed(double wave_modulus, double density) { return std::sqrt(wave_modulus / density); }

double TangentWaveModulus(const Eigen::Matrix<double, 9, 9>& tangent) {
  return std::max(tangent(0, 0), tangent(4, 4));
}

double CflTimeStep(double cfl, double cell_size, double wave_modulus, double density) {
  return cfl * cell_size / WaveSpeed(wave_modulus, density);
}

namespace {

// value(point) of a piecewise-linear history at time t: interpolated between
// its points (times increasing), held at the first before the first time and
// at the last after the last. `history` is not empty.
template <typename Point, typename Value>
auto Interpolate(const std::vector<Point>& history, double t, Value value) {
  if (t <= history.front().time) return value(history.front());
  for (std::size_t k = 0; k + 1 < history.size(); ++k) {
    const Point &a = history[k], &b = history[k + 1];
    if (t >= a.time && t < b.time) {
      const decltype(value(a)) va = value(a), vb = value(b);
      return decltype(va)(va + (vb - va) * ((t - a.time) / (b.time - a.time)));
    }
  }
  return value(history.back());
}

}  // namespace

Eigen::Vector2d VelocityAt(const std::vector<VelocityPoint>& history, double t) {
  if (history.empty()) return Vector2d::Zero();
  return Interpolate(history, t, [](const VelocityPoint& p) -> Vector2d { return p.velocity; });
}

double LoadFactorAt(const std::vector<LoadFactorPoint>& history, double ramp_time, double t) {
  if (history.empty()) return ramp_time > 0.0 ? std::min(1.0, t / ramp_time) : 1.0;
  return Interpolate(history, t, [](const LoadFactorPoint& p) { return p.factor; });
}

Eigen::Vector2d DisplacementAt(const std::vector<VelocityPoint>& history, double t) {
  Vector2d d = Vector2d::Zero();
  if (history.empty() || t <= 0.0) return d;
  // Constant before the first point, trapezoids between points, constant after.
  d += std::min(t, history.front().time) * history.front().velocity;
  for (std::size_t k = 0; k + 1 < history.size(); ++k) {
    const VelocityPoint &a = history[k], &b = history[k + 1];
    if (t <= a.time) break;
    if (b.time <= a.time) continue;  // a jump: no time passes
    const double hi = std::min(t, b.time);
    const Vector2d v_hi =
        a.velocity + (b.velocity - a.velocity) * ((hi - a.time) / (b.time - a.time));
    d += (hi - a.time) * 0.5 * (a.velocity + v_hi);
  }
  if (t > history.back().time) d += (t - history.back().time) * history.back().velocity;
  return d;
}

absl::StatusOr<MaterialPoints> FillRegions(const CaseSpec& spec, const RegionDensity& density) {
  const GridSpec& grid = spec.grid;
  RETURN_IF_ERROR(ValidateGrid(grid));
  const double thickness = spec.solver.thickness;
  if (!(thickness > 0.0)) {
    return Invalid("solver", absl::StrCat("thickness = ", thickness, " must be > 0"));
  }
  const double h = grid.cell_size;
  const int n[2] = {grid.nx, grid.ny};
  MaterialPoints points;
  std::vector<std::size_t> first(spec.regions.size() + 1, 0);
  for (std::size_t r = 0; r < spec.regions.size(); ++r) {
    const MaterialRegion& region = spec.regions[r];
    const std::string what = absl::StrCat("region ", region.name);
    int cells[2];
    for (int d = 0; d < 2; ++d) {
      const int lo = GridLineIndex(region.lower[d], grid.origin[d], h, n[d]);
      const int hi = GridLineIndex(region.upper[d], grid.origin[d], h, n[d]);
      if (lo < 0 || hi < 0) {
        return Invalid(what, absl::StrCat("corners ", Format(region.lower), " and ",
                                          Format(region.upper), " must lie on grid lines"));
      }
      if (hi <= lo) return Invalid(what, "upper must exceed lower along both axes");
      cells[d] = hi - lo;
    }
    if (region.points_per_cell_side < 1) {
      return Invalid(what, absl::StrCat("points_per_cell_side = ", region.points_per_cell_side,
                                        " must be >= 1"));
    }
    double rho = region.density;
    if (rho == 0.0) {
      if (!density) return Invalid(what, "density 0 needs the template's density");
      ASSIGN_OR_RETURN(double d, density(static_cast<int>(r)));
      rho = d;
    }
    if (!(rho > 0.0) || !std::isfinite(rho)) {
      return Invalid(what, absl::StrCat("density = ", rho, " must be > 0"));
    }
    const int ppc = region.points_per_cell_side;
    const double s = h / ppc;  // point spacing, m
    const double volume = s * s * thickness;
    const std::size_t start = points.size();
    const std::size_t count = static_cast<std::size_t>(cells[0]) * ppc * cells[1] * ppc;
    points.Resize(start + count);
    std::size_t p = start;
    for (int j = 0; j < cells[1] * ppc; ++j) {
      for (int i = 0; i < cells[0] * ppc; ++i, ++p) {
        points.position[p] = region.lower + s * Vector2d(i + 0.5, j + 0.5);
        points.mass[p] = rho * volume;
        points.volume[p] = volume;
        points.volume0[p] = volume;
        points.half_size0[p] = Vector2d(0.5 * s, 0.5 * s);
        points.region[p] = static_cast<std::int32_t>(r);
        if (spec.phases.saturated) {
          // n0 from the case (else the driver sets it from the RVEs), and a
          // hydrostatic start below the water table.
          points.porosity0[p] = spec.phases.porosity;
          points.position0[p] = points.position[p];
          points.pore_pressure[p] =
              HydrostaticPressure(spec.phases.fluid_density, spec.solver.gravity.norm(),
                                  spec.phases.water_table, points.position[p].y());
        }
      }
    }
    first[r + 1] = points.size();
  }
  for (std::size_t source = 0; source < spec.tractions.size(); ++source) {
    const SurfaceTraction& traction = spec.tractions[source];
    const std::string what = absl::StrCat("traction ", traction.name);
    std::size_t r = 0;
    while (r < spec.regions.size() && spec.regions[r].name != traction.region) ++r;
    if (r == spec.regions.size()) return Invalid(what, absl::StrCat("no region ", traction.region));
    const int a = traction.normal_axis;
    if (a != 0 && a != 1) return Invalid(what, "normal_axis must be 0 or 1");
    if (traction.normal_sign != 1 && traction.normal_sign != -1) {
      return Invalid(what, "normal_sign must be +1 or -1");
    }
    if (!(traction.ramp_time >= 0.0) || !traction.traction.allFinite()) {
      return Invalid(what, "ramp_time must be >= 0 and the traction finite");
    }
    const MaterialRegion& region = spec.regions[r];
    const double s = h / region.points_per_cell_side;
    const double surface = traction.normal_sign > 0 ? region.upper[a] : region.lower[a];
    bool any = false;
    for (std::size_t p = first[r]; p < first[r + 1]; ++p) {
      const Vector2d& x = points.position[p];
      if (std::abs(x[a] - surface) >= s || x[1 - a] < traction.from || x[1 - a] > traction.to) {
        continue;
      }
      points.loads.push_back({static_cast<std::int32_t>(p), traction.traction, s, a,
                              traction.normal_sign, traction.ramp_time,
                              static_cast<std::int32_t>(source)});
      any = true;
    }
    if (!any) return Invalid(what, "selects no material points");
  }
  return points;
}

absl::StatusOr<MaterialPoints> FillRegions(const CaseSpec& spec,
                                           const std::vector<double>& density) {
  if (density.size() != spec.regions.size()) {
    return Invalid("FillRegions", absl::StrCat(density.size(), " densities for ",
                                               spec.regions.size(), " regions"));
  }
  return FillRegions(spec, [&](int r) -> absl::StatusOr<double> { return density[r]; });
}

namespace {

// The first field of point p that is not finite, as "velocity (nan, 0) m/s",
// or "" when every one is. A state with a NaN or an infinity in it cannot be
// stepped: a NaN position even reads as off the grid, which kDrop would park
// without a word.
std::string NonFiniteField(const MaterialPoints& mp, std::size_t p) {
  // Checked every step: the message is built only for a field that fails.
  const auto vector = [](const char* name, const Vector2d& v, const char* unit) {
    return absl::StrCat(name, " ", Format(v), " ", unit);
  };
  const auto scalar = [](const char* name, double x, const char* unit) {
    return absl::StrCat(name, " ", x, unit[0] == '\0' ? "" : " ", unit);
  };
  const PointResponse& r = mp.response[p];
  if (!mp.position[p].allFinite()) return vector("position", mp.position[p], "m");
  if (!mp.velocity[p].allFinite()) return vector("velocity", mp.velocity[p], "m/s");
  if (!std::isfinite(mp.mass[p])) return scalar("mass", mp.mass[p], "kg");
  if (!std::isfinite(mp.volume[p])) return scalar("volume", mp.volume[p], "m³");
  if (!std::isfinite(mp.volume0[p])) return scalar("initial volume", mp.volume0[p], "m³");
  if (!mp.half_size0[p].allFinite()) return vector("GIMP half size", mp.half_size0[p], "m");
  if (!mp.F[p].allFinite()) return "deformation gradient";
  if (!mp.stress[p].allFinite()) return "stress";
  if (!r.stress.allFinite()) return "RVE stress";
  if (!std::isfinite(r.void_ratio)) return scalar("void ratio", r.void_ratio, "");
  if (!std::isfinite(r.permeability)) return scalar("permeability", r.permeability, "m/s");
  if (!mp.fluid_velocity[p].allFinite()) {
    return vector("fluid velocity", mp.fluid_velocity[p], "m/s");
  }
  if (!std::isfinite(mp.pore_pressure[p])) {
    return scalar("pore pressure", mp.pore_pressure[p], "Pa");
  }
  if (!mp.position0[p].allFinite()) return vector("initial position", mp.position0[p], "m");
  if (!std::isfinite(mp.vertical_stress0[p])) {
    return scalar("initial vertical stress", mp.vertical_stress0[p], "Pa");
  }
  return "";
}

// num_sources: the case's tractions, which a load's source indexes.
absl::Status ValidatePoints(const MaterialPoints& points, ShapeKind shape,
                            std::size_t num_sources) {
  const std::size_t n = points.size();
  for (std::size_t size :
       {points.velocity.size(), points.mass.size(), points.volume.size(), points.volume0.size(),
        points.F.size(), points.stress.size(), points.half_size0.size(), points.region.size(),
        points.response.size(), points.fluid_velocity.size(), points.pore_pressure.size(),
        points.porosity0.size(), points.position0.size(), points.vertical_stress0.size()}) {
    if (size != n) return Invalid("material points", "arrays differ in length");
  }
  for (std::size_t p = 0; p < n; ++p) {
    if (const std::string field = NonFiniteField(points, p); !field.empty()) {
      return Invalid(absl::StrCat("material point ", p), absl::StrCat(field, " is not finite"));
    }
    if (!(points.mass[p] > 0.0) || !(points.volume[p] > 0.0) || !(points.volume0[p] > 0.0)) {
      return Invalid(absl::StrCat("material point ", p), "mass and volumes must be > 0");
    }
    if (shape == ShapeKind::kGimp &&
        !(points.half_size0[p].x() > 0.0 && points.half_size0[p].y() > 0.0)) {
      return Invalid(absl::StrCat("material point ", p), "GIMP half sizes must be > 0");
    }
  }
  for (const SurfaceLoad& load : points.loads) {
    if (load.point < 0 || static_cast<std::size_t>(load.point) >= n ||
        (load.normal_axis != 0 && load.normal_axis != 1) ||
        (load.normal_sign != 1 && load.normal_sign != -1) || !(load.length0 >= 0.0) ||
        !(load.ramp_time >= 0.0) || load.source < -1 ||
        load.source >= static_cast<std::int64_t>(num_sources)) {
      return Invalid(absl::StrCat("surface load of point ", load.point), "invalid");
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::unique_ptr<Solver>> Solver::ForCase(const CaseSpec& spec, StressModel* model) {
  std::unique_ptr<Solver> solver;
  if (spec.phases.saturated) {
    solver.reset(new TwoPhaseSolver());
  } else {
    solver.reset(new ExplicitSolver());
  }
  RETURN_IF_ERROR(solver->SetUp(spec, model));
  return solver;
}

absl::Status Solver::SetUp(const CaseSpec& spec, StressModel* model) {
  if (model == nullptr) return absl::InvalidArgumentError("Solver needs a stress model");
  RETURN_IF_ERROR(ValidateGrid(spec.grid));
  const SolverSpec& sv = spec.solver;
  if (!(sv.pic_fraction >= 0.0 && sv.pic_fraction <= 1.0)) {
    return Invalid("solver",
                   absl::StrCat("pic_fraction = ", sv.pic_fraction, " must be in [0, 1]"));
  }
  if (!(sv.thickness > 0.0)) {
    return Invalid("solver", absl::StrCat("thickness = ", sv.thickness, " must be > 0"));
  }
  if (!(sv.time_step >= 0.0) || !sv.gravity.allFinite()) {
    return Invalid("solver", "time_step must be >= 0 and gravity finite");
  }
  if (!sv.shaking_amplitude.allFinite() || !(sv.shaking_frequency >= 0.0) ||
      !std::isfinite(sv.shaking_frequency)) {
    return Invalid("solver", "shaking_amplitude must be finite and shaking_frequency >= 0");
  }
  // The bins of NonlocalMap are ℓ wide: a radius far below the cell would
  // make their count overflow (the case file bounds it to 0.1–8 cells).
  if (!(sv.nonlocal_radius == 0.0 || (sv.nonlocal_radius >= 1e-3 * spec.grid.cell_size &&
                                      sv.nonlocal_radius <= 1e3 * spec.grid.cell_size))) {
    return Invalid("solver", absl::StrCat("nonlocal_radius = ", sv.nonlocal_radius,
                                          " m must be 0 or within 1e-3 to 1e3 cells"));
  }
  if (!(sv.nonlocal_fraction > 0.0 && sv.nonlocal_fraction <= 1.0)) {
    return Invalid(
        "solver", absl::StrCat("nonlocal_fraction = ", sv.nonlocal_fraction, " must be in (0, 1]"));
  }
  grid_ = spec.grid;
  solver_ = sv;
  walls_ = spec.walls;
  bodies_ = spec.bodies;
  for (const SurfaceTraction& traction : spec.tractions) {
    const std::vector<LoadFactorPoint>& history = traction.history;
    for (std::size_t k = 0; k < history.size(); ++k) {
      if (!(history[k].time >= 0.0) || !std::isfinite(history[k].factor) ||
          (k > 0 && !(history[k].time > history[k - 1].time))) {
        return Invalid(absl::StrCat("traction ", traction.name),
                       "history times must be >= 0 and increase strictly, factors finite");
      }
    }
    load_histories_.push_back(history);
  }
  model_ = model;
  for (const Wall& wall : spec.walls) {
    const std::string what = absl::StrCat("wall ", wall.name);
    if (wall.axis != 0 && wall.axis != 1) return Invalid(what, "axis must be 0 or 1");
    const int line = GridLine(wall.axis, wall.position);
    if (line < 0) {
      return Invalid(what, absl::StrCat("position ", wall.position, " is not on a grid line"));
    }
    if (!(wall.friction >= 0.0)) return Invalid(what, "friction must be >= 0");
    wall_nodes_.push_back(NodesOnLine(wall.axis, line));
    wall_lines_.push_back(line);
  }
  for (const RigidBody& body : spec.bodies) {
    const std::string what = absl::StrCat("body ", body.name);
    const bool circle = body.shape == RigidBody::Shape::kCircle;
    if (circle ? !(body.radius > 0.0) : !(body.half_size.x() > 0.0 && body.half_size.y() > 0.0)) {
      return Invalid(what, "radius or half sizes must be > 0");
    }
    if (!(body.friction >= 0.0) || !body.center.allFinite()) {
      return Invalid(what, "friction must be >= 0 and the centre finite");
    }
    RETURN_IF_ERROR(ValidateHistory(what, body.velocity));
  }
  reactions_.assign(spec.walls.size() + spec.bodies.size(), Vector2d::Zero());
  phases_ = spec.phases;
  max_void_ratio_ = spec.rve.max_void_ratio;
  return SetUpScheme(spec);
}

int Solver::GridLine(int axis, double position) const {
  return GridLineIndex(position, grid_.origin[axis], grid_.cell_size,
                       axis == 0 ? grid_.nx : grid_.ny);
}

std::vector<std::int32_t> Solver::NodesOnLine(int axis, int line, double from, double to) const {
  const double h = grid_.cell_size;
  std::vector<std::int32_t> nodes;
  const int along = axis == 0 ? grid_.ny : grid_.nx;
  for (int k = 0; k <= along; ++k) {
    const double s = grid_.origin[1 - axis] + k * h;  // m, along the line
    if (s < from - kGridTolerance * h || s > to + kGridTolerance * h) continue;
    nodes.push_back(axis == 0 ? line + (grid_.nx + 1) * k : k + (grid_.nx + 1) * line);
  }
  return nodes;
}

absl::StatusOr<std::unique_ptr<Solver>> Solver::Create(const CaseSpec& spec, MaterialPoints initial,
                                                       StressModel* model, double dt) {
  ASSIGN_OR_RETURN(std::unique_ptr<Solver> solver, ForCase(spec, model));
  RETURN_IF_ERROR(ValidatePoints(initial, spec.solver.shape, spec.tractions.size()));
  RETURN_IF_ERROR(solver->ValidateInitialPoints(initial));
  Solver& sv = *solver;
  sv.points_ = std::move(initial);
  sv.Prepare();
  const std::size_t n = sv.points_.size();
  if (dt > 0.0) {
    sv.dt_ = dt;
  } else if (spec.solver.time_step > 0.0) {
    sv.dt_ = spec.solver.time_step;
  } else if (spec.solver.wave_modulus > 0.0 && n > 0) {
    double rho = 0.0;  // the densest point gives the smallest step
    for (std::size_t p = 0; p < n; ++p)
      rho = std::max(rho, sv.points_.mass[p] / sv.points_.volume[p]);
    sv.dt_ = CflTimeStep(spec.solver.cfl, spec.grid.cell_size, spec.solver.wave_modulus,
                         spec.solver.mass_scale * rho);
  }
  return solver;
}

absl::Status Solver::Restore(MaterialPoints points, double time, double dt, std::int64_t step,
                             std::vector<Eigen::Vector2d> reactions) {
  RETURN_IF_ERROR(ValidatePoints(points, solver_.shape, load_histories_.size()));
  if (reactions.size() != reactions_.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat(reactions.size(), " reactions for ", reactions_.size(), " walls and bodies"));
  }
  points_ = std::move(points);
  reactions_ = std::move(reactions);
  time_ = time;
  dt_ = dt;
  step_ = step;
  Prepare();
  return absl::OkStatus();
}

Eigen::Vector2d Solver::BodyAcceleration() const {
  const Vector2d gravity = solver_.gravity / solver_.mass_scale;  // exact for s = 1
  if (!(solver_.shaking_frequency > 0.0)) return gravity;
  return gravity - (FrameVelocity(solver_, time_ + dt_) - FrameVelocity(solver_, time_)) / dt_;
}

void Solver::Prepare() {
  const std::size_t n = points_.size();
  double min_mass = std::numeric_limits<double>::infinity();
  for (double m : points_.mass) min_mass = std::min(min_mass, m);
  min_node_mass_ = n > 0 ? inactive_mass_fraction_ * solver_.mass_scale * min_mass : 0.0;
  shape_.resize(n);
  lost_.assign(n, 0);
  load_shape_.resize(points_.loads.size());
  load_force_.resize(points_.loads.size());
  const int nodes = NodeCount(grid_);
  node_mass_.resize(nodes);
  node_velocity_.resize(nodes);
  node_force_.resize(nodes);
  node_velocity_new_.resize(nodes);
  node_fixed_.resize(nodes);
  impulse_.resize(walls_.size() + bodies_.size());
  body_velocity_.resize(bodies_.size());
  in_plane_df_.resize(n);
  f_bar_apart_.assign(n, 0);
  delta_f_.resize(n);
  rve_delta_f_.resize(n);
  response_.resize(n);
}

absl::Status Solver::EvaluateShapes() {
  const MaterialPoints& mp = points_;
  const bool drop = solver_.lost_points == LostPointPolicy::kDrop;
  // Tractions act at the points' surface positions x_p + n·l with the current
  // half-size l along n, over the current surface length, linear weights
  // there (the GIMP limit lp → 0).
  const auto surface = [&](const SurfaceLoad& load) {
    const Vector2d lp = CurrentHalfSize(mp.F[load.point], mp.half_size0[load.point]);
    Vector2d x = mp.position[load.point];
    x[load.normal_axis] += load.normal_sign * lp[load.normal_axis];
    return x;
  };
  // Under kDrop a point is lost with its centre or a loaded surface off the
  // grid; once parked it does not move, so it stays lost. Under kStop none
  // is: the shape evaluations below fail instead.
  if (drop) {
    for (std::size_t p = 0; p < mp.size(); ++p) lost_[p] = !InsideGrid(grid_, mp.position[p]);
    for (const SurfaceLoad& load : mp.loads) {
      if (!InsideGrid(grid_, surface(load))) lost_[load.point] = 1;
    }
  }
  for (std::size_t p = 0; p < mp.size(); ++p) {
    if (lost_[p]) {
      shape_[p].count = 0;
      continue;
    }
    const Vector2d lp = solver_.shape == ShapeKind::kGimp
                            ? CurrentHalfSize(mp.F[p], mp.half_size0[p])
                            : Vector2d::Zero();
    if (!EvaluateShape(grid_, solver_.shape, mp.position[p], lp, shape_[p])) {
      return absl::OutOfRangeError(
          absl::StrCat("material point ", p, " at ", Format(mp.position[p]), " m left the grid"));
    }
  }
  for (std::size_t k = 0; k < mp.loads.size(); ++k) {
    const SurfaceLoad& load = mp.loads[k];
    const int a = load.normal_axis;
    const Matrix2d& f = mp.F[load.point];
    if (lost_[load.point]) {
      load_shape_[k].count = 0;
      load_force_[k].setZero();
      continue;
    }
    const Vector2d x = surface(load);
    if (!EvaluateShape(grid_, ShapeKind::kLinear, x, Vector2d::Zero(), load_shape_[k])) {
      return absl::OutOfRangeError(absl::StrCat("surface of material point ", load.point, " at ",
                                                Format(x), " m left the grid"));
    }
    const double length = load.length0 * f.col(1 - a).norm();
    const double factor = load.source >= 0
                              ? LoadFactorAt(load_histories_[load.source], load.ramp_time, time_)
                              : LoadFactorAt({}, load.ramp_time, time_);
    load_force_[k] = load.traction * (factor * length * solver_.thickness);
  }
  FindContacts();
  return absl::OkStatus();
}

void Solver::FindContacts() {
  contacts_.clear();
  const MaterialPoints& mp = points_;
  const double h = grid_.cell_size;
  // Faces farther than this stay out: to close it within one step a face
  // would move half a cell per step, far beyond any stable Δt.
  const double margin = kContactMargin * h;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const RigidBody& body = bodies_[b];
    const Vector2d center = body.center + DisplacementAt(body.velocity, time_);
    const Vector2d reach = BodyExtent(body) + Vector2d::Constant(margin);
    for (std::size_t p = 0; p < mp.size(); ++p) {
      if (lost_[p]) continue;
      const Vector2d d =
          (mp.position[p] - center).cwiseAbs() - DomainBound(mp.F[p], mp.half_size0[p]);
      if (d.x() > reach.x() || d.y() > reach.y()) continue;
      const BodyGap where = GapToBody(body, center, mp.position[p], mp.F[p], mp.half_size0[p]);
      if (where.gap > margin) continue;
      const ShapeValues& shape = shape_[p];
      const Vector2d arm = where.face - mp.position[p];  // m
      SurfaceContact& contact = contacts_.emplace_back();
      contact.body = static_cast<std::int32_t>(b);
      contact.point = static_cast<std::int32_t>(p);
      contact.where = where;
      contact.count = shape.count;
      contact.mass_floor = kContactMassFloor * solver_.mass_scale * mp.mass[p];
      for (int k = 0; k < shape.count; ++k) {
        contact.node[k] = shape.node[k];
        contact.weight[k] = shape.weight[k] + shape.gradient[k].dot(arm);
      }
    }
  }
}

void Solver::Constrain(std::vector<Eigen::Vector2d>& velocity, double body_time, double weight) {
  std::fill(node_fixed_.begin(), node_fixed_.end(), std::uint8_t{0});
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    const Wall& wall = walls_[w];
    if (wall.remove_time <= time_) continue;
    const Vector2d axis = wall.axis == 0 ? Vector2d(1.0, 0.0) : Vector2d(0.0, 1.0);
    // The neighbour nodes across the wall line tell on which side the soil
    // lies; with soil on both sides, any approach presses on the wall.
    const int stride = wall.axis == 0 ? 1 : grid_.nx + 1;
    const int last_line = wall.axis == 0 ? grid_.nx : grid_.ny;
    // What a wall holds, the body contacts below leave alone: the normal
    // velocity, and the tangential one of a rough wall.
    const std::uint8_t held = wall.contact == ContactKind::kRough ? 3 : (wall.axis == 0 ? 1 : 2);
    // A shaken wall: the contact acts on the velocity relative to it.
    const Vector2d moving = WallVelocity(wall, body_time);
    for (std::int32_t node : wall_nodes_[w]) {
      if (node_mass_[node] <= min_node_mass_) continue;
      const Vector2d relative = velocity[node] - moving;
      const double m_plus = wall_lines_[w] < last_line ? node_mass_[node + stride] : 0.0;
      const double m_minus = wall_lines_[w] > 0 ? node_mass_[node - stride] : 0.0;
      const double side = m_plus > m_minus   ? 1.0
                          : m_plus < m_minus ? -1.0
                                             : (relative.dot(axis) <= 0.0 ? 1.0 : -1.0);
      if (wall.unilateral && relative.dot(side * axis) >= 0.0) continue;  // separating
      const Vector2d v = moving + ContactVelocity(relative, side * axis, wall.contact,
                                                  wall.friction, !wall.unilateral);
      impulse_[w] += (weight * node_mass_[node]) * (v - velocity[node]);
      velocity[node] = v;
      node_fixed_[node] |= held;
    }
  }
  ResolveBodies(contacts_, bodies_, {node_mass_, velocity, node_fixed_, min_node_mass_}, body_time,
                weight);
}

void Solver::ResolveBodies(std::span<const SurfaceContact> contacts,
                           std::span<const RigidBody> bodies, ContactGrid grid, double body_time,
                           double weight) {
  if (contacts.empty()) return;
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    body_velocity_[b] = VelocityAt(bodies[b].velocity, body_time);
  }
  ResolveContacts(contacts, bodies, body_velocity_, dt_, weight, grid,
                  std::span<Vector2d>(impulse_).subspan(walls_.size()));
}

Eigen::Vector2d Solver::KeepOffWalls(const Eigen::Vector2d& from, Eigen::Vector2d to) const {
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    const Wall& wall = walls_[w];
    if (wall.remove_time <= time_) continue;
    const int a = wall.axis;
    const double before = from[a] - wall.position, after = to[a] - wall.position;
    const int last_line = a == 0 ? grid_.nx : grid_.ny;
    const bool crosses = (before > 0.0 && after < 0.0) || (before < 0.0 && after > 0.0);
    const bool off_grid =
        (wall_lines_[w] == 0 && after < 0.0) || (wall_lines_[w] == last_line && after > 0.0);
    if (crosses || off_grid) to[a] = wall.position;
  }
  return to;
}

absl::Status Solver::UpdateStress() {
  MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  for (std::size_t p = 0; p < n; ++p) {
    const ShapeValues& s = shape_[p];
    Matrix2d l = Matrix2d::Zero();
    for (int k = 0; k < s.count; ++k) l += node_velocity_[s.node[k]] * s.gradient[k].transpose();
    const Matrix2d df = Matrix2d::Identity() + dt_ * l;
    if (!(df.determinant() > 0.0)) {
      return absl::FailedPreconditionError(absl::StrCat(
          "material point ", p, " at ", Format(mp.position[p]), " m would invert: det ",
          "ΔF = ", df.determinant(), " (time step too large?)"));
    }
    in_plane_df_[p] = df;
  }
  if (solver_.f_bar == FBar::kNodal) {
    for (std::size_t p = 0; p < n; ++p) f_bar_apart_[p] = HasComeApart(mp.response[p]);
    AverageVolumeChange(shape_, FBarWeights(), NodeCount(grid_), in_plane_df_);
  }
  if (solver_.nonlocal_radius > 0.0) {
    std::vector<std::uint8_t> active(n);
    for (std::size_t p = 0; p < n; ++p) active[p] = !lost_[p] && shape_[p].count > 0;
    nonlocal_ = NonlocalMap::Build(mp.position, mp.volume, active, solver_.nonlocal_radius,
                                   solver_.thickness, solver_.nonlocal_fraction);
    AverageStrainIncrement(nonlocal_, in_plane_df_);
    for (std::size_t p = 0; p < n; ++p) {
      if (!(in_plane_df_[p].determinant() > 0.0)) {
        return absl::FailedPreconditionError(absl::StrCat(
            "material point ", p, " at ", Format(mp.position[p]),
            " m would invert with its averaged strain: det ΔF = ", in_plane_df_[p].determinant(),
            " (time step too large?)"));
      }
    }
  }
  for (std::size_t p = 0; p < n; ++p) {
    const Matrix2d& df = in_plane_df_[p];
    delta_f_[p].setIdentity();
    delta_f_[p].topLeftCorner<2, 2>() = df;
    rve_delta_f_[p].setIdentity();
    rve_delta_f_[p].topLeftCorner<2, 2>() = RveIncrement(df, mp.response[p], max_void_ratio_);
  }
  model_->SetStressOnly(stress_only_);
  RETURN_IF_ERROR(model_->Update(step_ + 1, rve_delta_f_, response_));
  for (std::size_t p = 0; p < n; ++p) {
    const PointResponse& r = response_[p];
    if (!r.stress.allFinite() || !std::isfinite(r.void_ratio) || !std::isfinite(r.permeability)) {
      return absl::InternalError(absl::StrCat(
          "the stress model answered material point ", p, " at ", Format(mp.position[p]),
          " m with a stress, void ratio or permeability that is not finite"));
    }
  }
  for (std::size_t p = 0; p < n; ++p) {
    Matrix2d& f = mp.F[p];
    f = (delta_f_[p].topLeftCorner<2, 2>() * f).eval();
    mp.volume[p] = mp.volume0[p] * f.determinant();
    if (stress_only_) {  // the point keeps its other fields from its last full response
      mp.response[p].stress = response_[p].stress;
      mp.response[p].void_ratio = response_[p].void_ratio;
      mp.response[p].permeability = response_[p].permeability;
    } else {
      mp.response[p] = response_[p];
    }
    mp.stress[p] = response_[p].stress;
  }
  return absl::OkStatus();
}

std::vector<double> Solver::FBarWeights() const {
  std::vector<double> w(points_.volume.begin(), points_.volume.end());
  for (std::size_t p = 0; p < w.size(); ++p) {
    if (f_bar_apart_[p]) w[p] = 0.0;
  }
  return w;
}

std::vector<Matrix2d> Solver::ForceStresses() const {
  const MaterialPoints& mp = points_;
  const std::size_t n = mp.size();
  std::vector<Matrix2d> sigma;
  if (solver_.nonlocal_radius > 0.0) {
    sigma = AverageInPlaneStress(nonlocal_, mp.stress);  // the strain's map
  } else {
    sigma.resize(n);
    for (std::size_t p = 0; p < n; ++p) sigma[p] = mp.stress[p].topLeftCorner<2, 2>();
  }
  if (solver_.f_bar == FBar::kNodal) {
    std::vector<double> own(n);
    for (std::size_t p = 0; p < n; ++p) own[p] = 0.5 * sigma[p].trace();
    const std::vector<double> mean = NodalAverage(shape_, FBarWeights(), own, NodeCount(grid_));
    for (std::size_t p = 0; p < n; ++p) sigma[p].diagonal().array() += mean[p] - own[p];
  }
  return sigma;
}

absl::Status Solver::AddLoadForces() {
  // A traction goes to the nodes around the surface position that carry
  // mass, weights renormalised over them: once the surface has moved into a
  // cell the soil's points do not reach, the share of its empty nodes would
  // otherwise be lost (a confined element that dilates would lose σxx).
  const auto active_weight = [&](const ShapeValues& s) {
    double active = 0.0;
    for (int q = 0; q < s.count; ++q) {
      if (node_mass_[s.node[q]] > min_node_mass_) active += s.weight[q];
    }
    return active;
  };
  for (std::size_t k = 0; k < points_.loads.size(); ++k) {
    const std::int32_t point = points_.loads[k].point;
    if (lost_[point]) continue;  // parked (kDrop)
    const ShapeValues* shape = &load_shape_[k];
    double active = active_weight(*shape);
    if (!(active > 0.0)) {
      // No node with mass around the surface position: a point stretched
      // over cells its support does not reach (1 point per cell in a shear
      // band or a heave). Its own nodes take the load, a force on the point.
      shape = &shape_[point];
      active = active_weight(*shape);
    }
    const ShapeValues& s = *shape;
    if (!(active > 0.0)) {
      return absl::FailedPreconditionError(
          absl::StrCat("surface load of material point ", points_.loads[k].point,
                       " has no node with mass around its surface position (points too sparse?)"));
    }
    for (int q = 0; q < s.count; ++q) {
      if (node_mass_[s.node[q]] > min_node_mass_) {
        node_force_[s.node[q]] += (s.weight[q] / active) * load_force_[k];
      }
    }
  }
  return absl::OkStatus();
}

absl::Status Solver::CheckReady() const {
  if (!(dt_ > 0.0) || !std::isfinite(dt_)) {
    return absl::FailedPreconditionError(absl::StrCat("time step dt = ", dt_, " must be > 0"));
  }
  if (shape_.size() != points_.size() || load_shape_.size() != points_.loads.size()) {
    return absl::FailedPreconditionError("the number of material points or loads changed");
  }
  return absl::OkStatus();
}

void Solver::ConstrainStart() {
  std::fill(impulse_.begin(), impulse_.end(), Vector2d::Zero());
  Constrain(node_velocity_, time_, solver_.pic_fraction);
}

absl::Status Solver::FinishStep() {
  RETURN_IF_ERROR(CheckPointsFinite());
  for (std::size_t k = 0; k < reactions_.size(); ++k) reactions_[k] = impulse_[k] / -dt_;
  time_ += dt_;
  ++step_;
  return absl::OkStatus();
}

absl::Status Solver::CheckPointsFinite() const {
  const MaterialPoints& mp = points_;
  for (std::size_t p = 0; p < mp.size(); ++p) {
    // The fields a step changes (UpdateStress has checked the stresses);
    // the full list only to name the one that failed.
    if (mp.position[p].allFinite() && mp.velocity[p].allFinite() && mp.F[p].allFinite() &&
        std::isfinite(mp.volume[p]) && mp.fluid_velocity[p].allFinite() &&
        std::isfinite(mp.pore_pressure[p])) {
      continue;
    }
    if (const std::string field = NonFiniteField(mp, p); !field.empty()) {
      return absl::FailedPreconditionError(
          absl::StrCat("after the step, material point ", p, "'s ", field,
                       " is not finite: the solution became unstable (time step too large?)"));
    }
  }
  return absl::OkStatus();
}

Eigen::Vector2d Solver::BodyDisplacement(int body) const {
  if (body < 0 || static_cast<std::size_t>(body) >= bodies_.size()) return Vector2d::Zero();
  return DisplacementAt(bodies_[body].velocity, time_);
}

double Solver::KineticEnergy() const {
  double e = 0.0;
  for (std::size_t p = 0; p < points_.size(); ++p) {
    if (lost_[p]) continue;  // parked off the grid
    e += 0.5 * points_.mass[p] * points_.velocity[p].squaredNorm();
  }
  return e;
}

std::vector<double> NodalAverage(std::span<const ShapeValues> shapes,
                                 std::span<const double> weight, std::span<const double> value,
                                 int node_count) {
  std::vector<double> node_weight(node_count, 0.0), node_value(node_count, 0.0);
  for (std::size_t p = 0; p < value.size(); ++p) {
    const ShapeValues& s = shapes[p];
    for (int k = 0; k < s.count; ++k) {
      node_weight[s.node[k]] += s.weight[k] * weight[p];
      node_value[s.node[k]] += s.weight[k] * weight[p] * value[p];
    }
  }
  for (int i = 0; i < node_count; ++i) {
    if (node_weight[i] > 0.0) node_value[i] /= node_weight[i];
  }
  std::vector<double> out(value.begin(), value.end());
  for (std::size_t p = 0; p < value.size(); ++p) {
    const ShapeValues& s = shapes[p];
    if (s.count == 0 || !(weight[p] > 0.0)) continue;
    double sum = 0.0, total = 0.0;
    for (int k = 0; k < s.count; ++k) {
      if (!(node_weight[s.node[k]] > 0.0)) continue;  // only points left out reach it
      sum += s.weight[k] * node_value[s.node[k]];
      total += s.weight[k];
    }
    if (total > 0.0) out[p] = sum / total;
  }
  return out;
}

void AverageVolumeChange(std::span<const ShapeValues> shapes, std::span<const double> volume,
                         int node_count, std::span<Matrix2d> df) {
  std::vector<double> j(df.size());
  for (std::size_t p = 0; p < df.size(); ++p) j[p] = df[p].determinant();
  const std::vector<double> j_bar = NodalAverage(shapes, volume, j, node_count);
  // Plane strain: the in-plane factor sqrt scales the determinant by J̄/J.
  for (std::size_t p = 0; p < df.size(); ++p) df[p] *= std::sqrt(j_bar[p] / j[p]);
}

bool HasComeApart(const PointResponse& last) {
  return last.void_ratio >= kApartVoidRatio && last.stress == Matrix3d::Zero();
}

Matrix2d RveIncrement(const Matrix2d& df, const PointResponse& last, double max_void_ratio) {
  const double det = df.determinant();
  if (!(max_void_ratio > 0.0) || last.void_ratio < max_void_ratio || !(det > 1.0) ||
      last.stress != Matrix3d::Zero()) {
    return df;
  }
  return df / std::sqrt(det);
}

double Solver::PotentialEnergy() const {
  double e = 0.0;
  for (std::size_t p = 0; p < points_.size(); ++p) {
    if (lost_[p]) continue;  // parked off the grid
    e -= points_.mass[p] * solver_.gravity.dot(points_.position[p]);
  }
  return e;
}

double Solver::Porosity(std::size_t p) const {
  const MaterialPoints& mp = points_;
  return PorosityAt(mp.porosity0[p], mp.volume[p] / mp.volume0[p]);
}

double Solver::Permeability(std::size_t p) const {
  const double e0 = VoidRatio(points_.porosity0[p]);
  return KozenyCarmanPermeability(KozenyCarmanCoefficient(e0, phases_.permeability),
                                  VoidRatio(Porosity(p)));
}

double Solver::MixtureMass() const {
  double m = 0.0;
  for (std::size_t p = 0; p < points_.size(); ++p) m += points_.mass[p];
  return m;
}

}  // namespace rvehub::mpm
