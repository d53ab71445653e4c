// Driving the DEM: an increment of deformation at a bounded inertial
// number (Apply), stress- or strain-controlled runs (Run) and relaxation.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/rve.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

using internal::CellHeights;
using internal::GridCells;
using internal::MaxGridCells;
using internal::Rotation;
using internal::Sign;

double Rve::QuasiStaticStrainRate(double inertial_number, double pressure) const {
  const double p = std::max(pressure, p_.controls.pressure_floor);
  const double rho = p_.material.density * p_.controls.mass_scale;
  return inertial_number / (2.0 * radius_mean_ * std::sqrt(rho / p));  // I = γ̇ d sqrt(ρ/p)
}

Eigen::Matrix2d Rve::PlanDoublings(const Eigen::Matrix2d& f, int (&axes)[2]) const {
  Eigen::Matrix2d target = f * p_.cell;
  axes[0] = axes[1] = -1;
  for (int& axis : axes) {
    const Eigen::Vector2d heights = CellHeights(target);
    if (heights.minCoeff() > 2.0 * Cutoff()) break;
    axis = heights.x() <= heights.y() ? 0 : 1;
    target.col(axis) *= 2.0;
  }
  return target;
}

std::int64_t Rve::ParticlesAfterApply(const Eigen::Matrix3d& delta_f) const {
  std::int64_t particles = num_particles();
  if (!delta_f.allFinite()) return particles;
  int axes[2];
  PlanDoublings(delta_f.topLeftCorner<2, 2>(), axes);
  for (int axis : axes) particles *= axis >= 0 ? 2 : 1;
  return particles;
}

absl::StatusOr<RveState> Rve::Apply(const Eigen::Matrix3d& delta_f, const ApplyOptions& options,
                                    const Interrupt& interrupt) {
  RETURN_IF_ERROR(ValidateDeltaF(delta_f));
  RETURN_IF_ERROR(Validate(options));
  const Eigen::Matrix2d f = delta_f.topLeftCorner<2, 2>();
  // Polar split ΔF = V·R: rotate rigidly (exact, objective), then stretch.
  const double angle = std::atan2(f(1, 0) - f(0, 1), f(0, 0) + f(1, 1));
  const Eigen::Matrix2d v = f * Rotation(angle).transpose();
  const double stretch = (v - Eigen::Matrix2d::Identity()).norm();
  if (std::abs(angle) > p_.controls.max_rotation) {
    return absl::InvalidArgumentError(absl::StrCat("rotation of ΔF ", angle,
                                                   " rad exceeds the per-call limit ",
                                                   p_.controls.max_rotation, " rad"));
  }
  if (stretch > p_.controls.max_stretch) {
    return absl::InvalidArgumentError(absl::StrCat("stretch |V − I| = ", stretch,
                                                   " of ΔF exceeds the per-call limit ",
                                                   p_.controls.max_stretch));
  }
  // A cell that ΔF would squeeze thinner than the minimum image allows is
  // first doubled along the thin direction (at most twice: ΔF's stretch is
  // bounded by max_stretch); the checks below see the doubled cell.
  int doublings[2] = {-1, -1};
  const Eigen::Matrix2d target = PlanDoublings(f, doublings);
  std::size_t particles = p_.radius.size();
  for (int axis : doublings) particles *= axis >= 0 ? 2 : 1;
  if (CellHeights(target).minCoeff() <= 2.0 * Cutoff()) {
    return absl::FailedPreconditionError(
        "ΔF would make the periodic cell thinner than twice the pair cutoff");
  }
  if (particles > kMaxParticles) {
    return absl::FailedPreconditionError(
        absl::StrCat("ΔF would make the periodic cell thinner than twice the pair cutoff, and "
                     "doubling it would give ",
                     particles, " particles; at most ", kMaxParticles));
  }
  if (!(GridCells(CellHeights(target), Cutoff()) <= MaxGridCells(particles))) {
    return absl::FailedPreconditionError(
        "ΔF would make the periodic cell too large for its particles (neighbour-grid limit)");
  }

  // e after ΔF is geometry alone (the area det ΔF·A): at or below 0 the
  // discs' overlaps exceed the voids, no packing at all.
  if (const double e = VoidRatioOfArea(f.determinant() * p_.cell.determinant()); !(e > 0)) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "ΔF (det %.6g) would squeeze the cell below the discs' own area: e = %.4g ≤ 0 is no "
        "packing",
        f.determinant(), e));
  }
  // p before the rotation (which leaves it unchanged): after an increment
  // it is known from that increment's last step.
  const double pressure = MeanPressure();
  const double inertial_number =
      options.max_inertial_number > 0
          ? std::min(options.max_inertial_number, p_.controls.max_inertial_number)
          : p_.controls.max_inertial_number;
  const double rate = QuasiStaticStrainRate(inertial_number, pressure);
  double steps_needed = std::ceil(stretch / (rate * dt_));
  // Never slower than real time, where the caller says how long the
  // increment lasts (the quasi-static bound is then kept where it can be).
  if (options.duration > 0)
    steps_needed = std::min(steps_needed, std::ceil(options.duration / dt_));
  // Sized before anything changes (the cast below needs it in range, too).
  if (!(steps_needed <= static_cast<double>(kMaxStepsPerApply))) {
    return absl::InvalidArgumentError(absl::StrCat("the increment would take ", steps_needed,
                                                   " DEM steps at inertial number ",
                                                   inertial_number, "; at most ", kMaxStepsPerApply,
                                                   " per call: split ΔF into smaller increments"));
  }
  // Only a long call can be interrupted, and only a long call pays for the
  // copy that undoes it (a short one ends soon anyway).
  std::optional<Rve> before;
  const std::int64_t planned =
      std::max<std::int64_t>(p_.controls.min_steps, static_cast<std::int64_t>(steps_needed));
  if (interrupt && (planned > kInterruptCheckSteps || options.relax)) before.emplace(*this);
  // The doublings sized above (recomputed: a doubling may change the basis).
  for (int axis : doublings) {
    if (axis < 0) break;
    const Eigen::Vector2d heights = CellHeights(f * p_.cell);
    if (heights.minCoeff() > 2.0 * Cutoff()) break;
    RETURN_IF_ERROR(DoubleCell(heights.x() <= heights.y() ? 0 : 1));  // sized: cannot fail
  }
  ApplyRigidRotation(angle);
  Eigen::Matrix2d start = p_.cell;
  const Eigen::Matrix2d identity = Eigen::Matrix2d::Identity();
  const Measure last = options.stress_only ? Measure::kStress : Measure::kSums;
  const std::int64_t steps = planned;
  for (std::int64_t k = 0; k < steps; ++k) {
    if (before && k > 0 && k % kInterruptCheckSteps == 0) {
      if (absl::Status stop = interrupt(); !stop.ok()) {
        *this = *std::move(before);
        return stop;
      }
    }
    const double tau = static_cast<double>(k + 1) / static_cast<double>(steps);
    const Eigen::Matrix2d next = (identity + (v - identity) * tau) * start;
    const Eigen::Matrix2d l = (next - p_.cell) * p_.cell.inverse() / dt_;
    StepForcesLast(l, next, k + 1 == steps ? last : Measure::kNone);  // the last homogenises
    // A flip in Step changed the lattice basis: follow it (h' = h·U, U integer).
    if (p_.cell != next) start = start * (next.inverse() * p_.cell).array().round().matrix();
  }
  std::int64_t used = steps;
  if (options.relax) {
    absl::Status stopped;
    used += RelaxSteps(options.relax_tolerance, options.relax_max_steps,
                       before ? &interrupt : nullptr, stopped)
                .steps;
    if (!stopped.ok()) {
      *this = *std::move(before);
      return stopped;
    }
  }
  RveState s =
      options.stress_only ? ObserveStress(options.want_tangent) : Observe(options.want_tangent);
  s.steps = used;
  return s;
}

RveState Rve::Run(CellControl& control, std::int64_t steps) {
  absl::Status stopped;
  return RunSteps(control, steps, nullptr, stopped);
}

absl::StatusOr<RveState> Rve::Run(CellControl& control, std::int64_t steps,
                                  const Interrupt& interrupt) {
  absl::Status stopped;
  RveState s = RunSteps(control, steps, interrupt ? &interrupt : nullptr, stopped);
  if (!stopped.ok()) return stopped;
  return s;
}

RveState Rve::RunSteps(CellControl& control, std::int64_t steps, const Interrupt* interrupt,
                       absl::Status& stopped) {
  Eigen::Matrix2d stress = DefinitionStress();
  Eigen::Vector2d stiffness = Eigen::Vector2d::Zero();
  const double cap = control.max_strain_rate;
  // PI servo on the strain rate: Δσ ≈ K·L·Δt, so gain·gap/(K·Δt) closes a
  // fraction `gain` of the stress gap per step; the integral removes the
  // steady-state error while the stress keeps being pushed (e.g. dilation).
  auto servo = [&](const ComponentControl& c, double sigma, double k, double& integral) {
    if (c.mode == ControlMode::kStrainRate) return c.value;
    const double gap = c.value - sigma;
    double p_term = k > 0 ? control.servo_gain * gap / (k * dt_) : Sign(gap) * cap;
    p_term = std::clamp(p_term, -cap, cap);
    if (control.servo_integral_steps <= 0) return p_term;
    integral = std::clamp(integral + p_term / control.servo_integral_steps, -cap, cap);
    return std::clamp(p_term + integral, -cap, cap);
  };
  Eigen::Vector3d& integral = control.servo_integral;
  // The step measures stress and stiffness only when a servo needs them.
  const bool servo_on = control.xx.mode == ControlMode::kStress ||
                        control.yy.mode == ControlMode::kStress ||
                        control.xy.mode == ControlMode::kStress;
  for (std::int64_t k = 0; k < steps; ++k) {
    if (interrupt != nullptr && k > 0 && k % kInterruptCheckSteps == 0) {
      stopped = (*interrupt)();
      if (!stopped.ok()) return RveState{};
    }
    Eigen::Matrix2d l = Eigen::Matrix2d::Zero();
    l(0, 0) = servo(control.xx, stress(0, 0), stiffness.x(), integral[0]);
    l(1, 1) = servo(control.yy, stress(1, 1), stiffness.y(), integral[1]);
    l(0, 1) =
        servo(control.xy, 0.5 * (stress(0, 1) + stress(1, 0)), 0.25 * stiffness.sum(), integral[2]);
    const Eigen::Matrix2d next = p_.cell + dt_ * l * p_.cell;
    const StepResult r = Step(l, next, servo_on);
    stress = r.stress;
    stiffness = r.stiffness;
  }
  RveState s = Observe();
  s.steps = steps;
  return s;
}

RveState Rve::Relax(double tolerance, std::int64_t max_steps) {
  absl::Status stopped;
  return RelaxSteps(tolerance, max_steps, nullptr, stopped);
}

absl::StatusOr<RveState> Rve::Relax(double tolerance, std::int64_t max_steps,
                                    const Interrupt& interrupt) {
  absl::Status stopped;
  RveState s = RelaxSteps(tolerance, max_steps, interrupt ? &interrupt : nullptr, stopped);
  if (!stopped.ok()) return stopped;
  return s;
}

RveState Rve::RelaxSteps(double tolerance, std::int64_t max_steps, const Interrupt* interrupt,
                         absl::Status& stopped) {
  constexpr std::int64_t kCheckEvery = 50;
  std::int64_t done = 0;
  std::int64_t since_asked = 0;  // steps since `interrupt` was last asked
  RveState s = Observe();
  while (done < max_steps && !(s.unbalanced_force_ratio < tolerance && s.num_contacts > 0)) {
    if (interrupt != nullptr && since_asked >= kInterruptCheckSteps) {
      since_asked = 0;
      stopped = (*interrupt)();
      if (!stopped.ok()) return s;
    }
    const std::int64_t chunk = std::min(kCheckEvery, max_steps - done);
    since_asked += chunk;
    for (std::int64_t k = 0; k < chunk; ++k)
      Step(Eigen::Matrix2d::Zero(), p_.cell, /*measure=*/false);
    done += chunk;
    s = Observe();
  }
  s.steps = done;
  return s;
}

}  // namespace rvehub::dem
