#include "rve_server/engine/element_test.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/prepare.h"

namespace rvehub::dem {
namespace {

// Lateral-stress servo while shearing: gain and integral time (DEM steps),
// tuned on SPFEM-biaxial to hold σxx within ±2 % through peak and dilation.
constexpr double kServoIntegralSteps = 300;
constexpr double kServoGain = 0.2;

ElementTestRow MakeRow(const RveState& s, const Eigen::Matrix2d& f, int axis, std::int64_t step) {
  ElementTestRow r;
  r.step = step;
  r.axial_strain_comp = 1.0 - f(axis, axis);
  r.vol_strain_comp = 1.0 - f.determinant();
  r.shear_strain = f(0, 1);
  r.sxx_comp = -s.stress(0, 0);
  r.syy_comp = -s.stress(1, 1);
  r.sxy_comp = -s.stress(0, 1);
  r.p_comp = s.MeanPressure();
  r.q = s.DeviatorStress();
  r.void_ratio = s.void_ratio;
  r.coordination = s.coordination;
  r.fabric_xx = s.fabric(0, 0);
  r.fabric_yy = s.fabric(1, 1);
  r.fabric_xy = s.fabric(0, 1);
  r.fabric_anisotropy = s.fabric_anisotropy;
  r.permeability = s.permeability;
  return r;
}

absl::Status CheckSpec(const ElementTestSpec& spec) {
  auto bad = [](absl::string_view field, double v, absl::string_view rule) {
    return absl::InvalidArgumentError(absl::StrCat(field, " = ", v, " is invalid: ", rule));
  };
  if (!(spec.confining > 0 && spec.confining <= kMaxPressure))
    return bad("confining", spec.confining, "must lie in (0, 1e9] Pa");
  const bool shear = spec.kind == ElementTestKind::kUndrainedSimpleShear ||
                     spec.kind == ElementTestKind::kCyclicSimpleShear;
  // Compression beyond 50 % would crush the cell; shear is unlimited thanks
  // to cell flips (shear bands reach γ ≈ 2.6), capped at 10 for run time.
  const double strain_limit = shear ? 10.0 : 0.5;
  if (!(spec.max_strain > 0 && spec.max_strain < strain_limit))
    return bad("max_strain", spec.max_strain, absl::StrCat("must lie in (0, ", strain_limit, ")"));
  if (!(spec.inertial_number >= kMinInertialNumber && spec.inertial_number <= 0.1))
    return bad("inertial_number", spec.inertial_number, "must lie in [1e-6, 0.1]");
  if (spec.rows < 2 || spec.rows > 1000000) return bad("rows", spec.rows, "must lie in [2, 1e6]");
  if (spec.axis != 0 && spec.axis != 1) return bad("axis", spec.axis, "must be 0 (x) or 1 (y)");
  if (!HasLoadingAxis(spec.kind) && spec.axis != 1) {
    return bad("axis", spec.axis, "only the biaxial and oedometer tests have a loading axis");
  }
  if (spec.kind == ElementTestKind::kCyclicSimpleShear) {
    if (!(spec.amplitude > 0) || !std::isfinite(spec.amplitude) ||
        (spec.cyclic_control == CyclicControl::kStress && spec.amplitude > kMaxPressure))
      return bad("amplitude", spec.amplitude, "must be > 0 (a stress at most 1e9 Pa)");
    if (spec.cyclic_control == CyclicControl::kStrain && spec.amplitude >= spec.max_strain)
      return bad("amplitude", spec.amplitude, "a strain amplitude must be below max_strain");
    if (spec.cycles < 1 || spec.cycles > 10000)
      return bad("cycles", spec.cycles, "must lie in [1, 1e4]");
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::vector<ElementTestRow>> RunElementTest(
    Rve& rve, const ElementTestSpec& spec, const std::function<void(double)>& progress,
    const Interrupt& interrupt) {
  RETURN_IF_ERROR(CheckSpec(spec));
  // The rate and the DEM step are the packing's, whatever its state: a test
  // they cannot run is refused before the consolidation changes the RVE.
  const double rate = rve.QuasiStaticStrainRate(spec.inertial_number, spec.confining);  // 1/s
  const double step_strain = rate * rve.time_step();  // strain of one DEM step, [-]
  if (!(spec.max_strain >= step_strain)) {
    // It would end after its first step, strained far past max_strain
    // (--strain=1e-308 wrote a biaxial test of one step, to 1.3e-05).
    return absl::InvalidArgumentError(absl::StrCat(
        "max_strain = ", spec.max_strain, " is invalid: one DEM step at the test's strain rate ",
        "is a strain of ", step_strain, " (inertial_number ", spec.inertial_number, ", confining ",
        spec.confining, " Pa), and max_strain must be at least that"));
  }
  const bool cyclic = spec.kind == ElementTestKind::kCyclicSimpleShear;
  // Strain between recorded rows, and the steps that take.
  const double row_strain = cyclic ? (spec.cyclic_control == CyclicControl::kStrain
                                          ? 4.0 * spec.amplitude * spec.cycles / spec.rows
                                          : spec.max_strain / spec.rows)
                                   : spec.max_strain / spec.rows;
  // Sized before the first step (llround needs it in range, too).
  const double row_steps = row_strain / step_strain;
  if (!(row_steps * spec.rows <= static_cast<double>(kMaxElementTestSteps))) {
    return absl::ResourceExhaustedError(
        absl::StrCat("the test would take about ", row_steps * spec.rows, " DEM steps; at most ",
                     kMaxElementTestSteps, " (raise inertial_number or lower max_strain)"));
  }
  ASSIGN_OR_RETURN(RveState start,
                   ConsolidateIsotropic(rve, spec.confining, 1e-4, nullptr, interrupt));
  // Strains count from the consolidated state.
  const Eigen::Matrix2d f0_inv = rve.DeformationGradient().inverse();
  auto strain_f = [&] { return Eigen::Matrix2d(rve.DeformationGradient() * f0_inv); };

  CellControl control;
  control.max_strain_rate = 4.0 * rate;
  control.servo_integral_steps = kServoIntegralSteps;
  control.servo_gain = kServoGain;
  control.xy = {ControlMode::kStrainRate, 0.0};
  // The loading axis's and the lateral component (biaxial, oedometer).
  ComponentControl& along = spec.axis == 0 ? control.xx : control.yy;
  ComponentControl& across = spec.axis == 0 ? control.yy : control.xx;
  switch (spec.kind) {
    case ElementTestKind::kDrainedBiaxial:
      across = {ControlMode::kStress, -spec.confining};
      along = {ControlMode::kStrainRate, -rate};
      break;
    case ElementTestKind::kIsotropic:
      control.xx = control.yy = {ControlMode::kStrainRate, -rate / std::sqrt(2.0)};
      break;
    case ElementTestKind::kOedometer:
      along = {ControlMode::kStrainRate, -rate};
      break;
    case ElementTestKind::kUndrainedSimpleShear:
    case ElementTestKind::kCyclicSimpleShear:
      control.xy = {ControlMode::kStrainRate, rate};
      break;
  }
  const std::int64_t steps_per_row = std::max<std::int64_t>(1, std::llround(row_steps));
  // Cyclic tests end on the response; this bounds them whatever it does.
  const std::int64_t max_rows = std::min<std::int64_t>(
      kMaxElementTestRows, std::max<std::int64_t>(1, kMaxElementTestSteps / steps_per_row));
  // Progress measure and stop rule per test: the row's strain of its kind.
  auto measure = [&](const ElementTestRow& r) {
    switch (spec.kind) {
      case ElementTestKind::kDrainedBiaxial:
      case ElementTestKind::kOedometer:
        return r.axial_strain_comp;
      case ElementTestKind::kIsotropic:
        return r.vol_strain_comp;
      default:
        return std::abs(r.shear_strain);
    }
  };

  std::vector<ElementTestRow> rows;
  std::int64_t step = 0;
  rows.push_back(MakeRow(start, strain_f(), spec.axis, step));
  int half_cycles = 0;  // reversals done (cyclic)
  // Only a cyclic test's cycles are validated (and used); another test's field may hold
  // anything, so it must not enter arithmetic (2 × 2e9 overflows an int).
  const int target_half_cycles = cyclic ? 2 * spec.cycles : 0;
  double direction = 1.0;
  for (;;) {
    if (static_cast<std::int64_t>(rows.size()) > max_rows) {
      return absl::ResourceExhaustedError(
          absl::StrCat("the test did not end within ", max_rows, " rows of ", steps_per_row,
                       " DEM steps (lower rows, cycles or max_strain)"));
    }
    RveState s;
    if (interrupt) {
      RETURN_IF_ERROR(interrupt());
      ASSIGN_OR_RETURN(RveState run, rve.Run(control, steps_per_row, interrupt));
      s = run;
    } else {
      s = rve.Run(control, steps_per_row);
    }
    step += steps_per_row;
    rows.push_back(MakeRow(s, strain_f(), spec.axis, step));
    const ElementTestRow& r = rows.back();
    if (!cyclic) {
      if (progress) progress(std::min(1.0, measure(r) / spec.max_strain));
      if (measure(r) >= spec.max_strain) break;
      continue;
    }
    // Cyclic: reverse at the amplitude (γ or τ); a cycle is two reversals,
    // and the test ends back at γ = 0 heading in the first direction.
    const double level =
        spec.cyclic_control == CyclicControl::kStrain ? r.shear_strain : -r.sxy_comp;
    if (half_cycles < target_half_cycles && direction * level >= spec.amplitude) {
      direction = -direction;
      ++half_cycles;
      control.xy.value = direction * rate;
      if (progress) progress(static_cast<double>(half_cycles) / (target_half_cycles + 1));
    }
    if (half_cycles == target_half_cycles && direction > 0 && r.shear_strain >= 0) break;
    if (std::abs(r.shear_strain) >= spec.max_strain) break;  // liquefied: strain runs away
  }
  if (progress) progress(1.0);
  return rows;
}

}  // namespace rvehub::dem
