#include "rve_server/engine/prepare.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/rve.h"

namespace rvehub::dem {
namespace {

// Uniform in [0, 1) from the top 53 bits: the same on every platform
// (std::uniform_real_distribution is implementation-defined).
double Uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

constexpr double kInitialSolidFraction = 0.35;  // loose enough to place discs quickly
constexpr double kPressureTolerance = 0.01;     // |p − p0|/p0 and q/p0 at the end
constexpr double kServoBalance = 3e-3;          // unbalanced-force ratio to stop the servo
constexpr double kCompactionBalance = 1e-3;     // ... to end a compaction trial
constexpr double kFinalBalance = 1e-4;          // ... after friction is restored
constexpr std::int64_t kChunk = 200;            // steps between convergence checks
constexpr std::int64_t kMaxSteps = 600000;      // per consolidation
constexpr int kMaxRounds = 6;                   // servo-then-relax rounds
constexpr double kVoidRatioTolerance = 0.002;   // steering stops this close to the target
constexpr int kMaxTrials = 7;

}  // namespace

absl::StatusOr<RveState> ConsolidateIsotropic(Rve& rve, double p, double balance,
                                              std::int64_t* steps, const Interrupt& interrupt,
                                              std::int64_t settle_steps) {
  return ConsolidateToStress(rve, p, p, balance, steps, interrupt, settle_steps);
}

absl::StatusOr<RveState> ConsolidateToStress(Rve& rve, double sxx, double syy, double balance,
                                             std::int64_t* steps, const Interrupt& interrupt,
                                             std::int64_t settle_steps) {
  if (!(sxx > 0 && syy > 0 && sxx <= kMaxPressure && syy <= kMaxPressure)) {
    return absl::InvalidArgumentError(
        absl::StrCat("consolidation stresses σxx = ", sxx, " Pa, σyy = ", syy,
                     " Pa (compression +) must lie in (0, ", kMaxPressure, "] Pa"));
  }
  const double p = 0.5 * (sxx + syy);
  CellControl control;
  control.xx = {ControlMode::kStress, -sxx};
  control.yy = {ControlMode::kStress, -syy};
  control.xy = {ControlMode::kStress, 0.0};          // principal axes x, y: no shear stress
  control.max_strain_rate = 2e-5 / rve.time_step();  // ≤ 2e-5 strain per step
  // Within 1 % of p in mean stress and in the deviator error (for an
  // isotropic target the latter is q itself).
  auto close = [&](const RveState& s) {
    const double d = (s.stress(1, 1) - s.stress(0, 0)) - (sxx - syy);  // Pa
    const double deviator_error = std::sqrt(0.25 * d * d + s.stress(0, 1) * s.stress(0, 1));
    return s.num_contacts > 0 && std::abs(s.MeanPressure() - p) < kPressureTolerance * p &&
           deviator_error < kPressureTolerance * p;
  };
  // e ≤ 0 is no packing: the stress is beyond what the soft contacts model.
  auto squeezed = [&](const RveState& s) {
    return absl::InvalidArgumentError(absl::StrFormat(
        "consolidation to σxx = %.4g Pa, σyy = %.4g Pa squeezes the discs into each other past "
        "any packing (e = %.4g ≤ 0: their overlaps exceed the voids): the stress is beyond what "
        "this material's contacts (E = %.4g MPa) model",
        sxx, syy, s.void_ratio, rve.material().young_modulus * 1e-6));
  };
  std::int64_t done = 0;
  for (int round = 0; round < kMaxRounds; ++round) {
    RveState s = rve.Observe();
    std::int64_t close_for = 0;  // steps the stress has stayed close
    while (done < kMaxSteps) {
      if (close(s)) {
        if (s.unbalanced_force_ratio < kServoBalance) break;
        if (settle_steps > 0 && close_for >= settle_steps) break;
        close_for += kChunk;
      } else {
        close_for = 0;
      }
      if (interrupt) {
        RETURN_IF_ERROR(interrupt());
      }
      s = rve.Run(control, kChunk);
      done += kChunk;
    }
    if (interrupt) {
      ASSIGN_OR_RETURN(RveState relaxed, rve.Relax(balance, kMaxSteps / 4, interrupt));
      s = relaxed;
    } else {
      s = rve.Relax(balance, kMaxSteps / 4);
    }
    done += s.steps;
    if (close(s) && s.unbalanced_force_ratio < balance) {
      if (steps != nullptr) *steps += done;
      if (!(s.void_ratio > 0)) return squeezed(s);
      return s;
    }
  }
  if (steps != nullptr) *steps += done;
  const RveState s = rve.Observe();
  if (!(s.void_ratio > 0)) return squeezed(s);
  // Say what was asked and what the packing holds: below
  // kLowConsolidationStress the shear stress may be what misses.
  const std::string held =
      s.num_contacts == 0
          ? std::string("the packing lost every contact (no stress: a gas at this pressure)")
          : absl::StrFormat(
                "the packing holds σxx = %.4g Pa, σyy = %.4g Pa, σxy = %.3g Pa on %d contacts "
                "(coordination %.3g), unbalanced %.3g",
                -s.stress(0, 0), -s.stress(1, 1), -s.stress(0, 1), s.num_contacts, s.coordination,
                s.unbalanced_force_ratio);
  // Not DeadlineExceeded: no deadline passed, and a client would take that
  // for a hung server and retry what fails the same way every time.
  return absl::FailedPreconditionError(absl::StrFormat(
      "consolidation to σxx = %.4g Pa, σyy = %.4g Pa did not converge: the mean stress and the "
      "deviator must come within %.3g Pa (1 %%), and after %d rounds of servo and relaxation "
      "%s%s",
      sxx, syy, kPressureTolerance * p, kMaxRounds, held,
      p < kLowConsolidationStress
          ? "; below about 1 kPa a packing's few contacts may not hold a stress that closely"
          : ""));
}

namespace {

struct Trial {
  double friction;
  double void_ratio;
  RveSnapshot packing;
};

}  // namespace

RveSnapshot GenerateLoosePacking(const ParameterSet& set, const Controls& controls) {
  const PreparationSpec& spec = set.preparation;
  std::mt19937_64 rng(spec.seed);
  RveSnapshot p;
  p.material = set.material;
  p.controls = controls;
  const int n = spec.num_particles;
  p.radius.resize(n);
  for (double& r : p.radius)
    r = spec.radius_min + (spec.radius_max - spec.radius_min) * Uniform(rng);
  // Largest first places quickly and is still a fixed function of the seed.
  std::sort(p.radius.begin(), p.radius.end(), std::greater<>());
  const double side = std::sqrt(SolidArea(p.radius) / kInitialSolidFraction);
  p.cell = Eigen::Matrix2d::Identity() * side;
  p.reference_cell = p.cell;
  p.sx.reserve(n);
  p.sy.reserve(n);
  for (int i = 0; i < n; ++i) {
    for (;;) {  // at this solid fraction a free spot is found in a few tries
      const double x = Uniform(rng), y = Uniform(rng);
      bool free = true;
      for (int j = 0; j < i && free; ++j) {
        double dx = x - p.sx[j], dy = y - p.sy[j];
        dx = (dx - std::round(dx)) * side;
        dy = (dy - std::round(dy)) * side;
        const double reach = p.radius[i] + p.radius[j];
        free = dx * dx + dy * dy >= reach * reach;
      }
      if (free) {
        p.sx.push_back(x);
        p.sy.push_back(y);
        break;
      }
    }
  }
  p.vx.assign(n, 0.0);
  p.vy.assign(n, 0.0);
  p.omega.assign(n, 0.0);
  p.theta.assign(n, 0.0);
  return p;
}

absl::StatusOr<RveSnapshot> PreparePacking(
    const ParameterSet& set, const Controls& controls, PreparationReport* report,
    const std::function<void(const std::string&)>& progress) {
  RETURN_IF_ERROR(Validate(set.material));
  RETURN_IF_ERROR(Validate(set.preparation));
  RETURN_IF_ERROR(Validate(controls));
  const double p0 = set.preparation.pressure;
  const double target = set.preparation.target_void_ratio;
  const RveSnapshot loose = GenerateLoosePacking(set, controls);
  std::int64_t steps = 0;
  int trials = 0;

  auto compact = [&](double friction) -> absl::StatusOr<Trial> {
    RveSnapshot start = loose;
    start.material.friction = friction;
    ASSIGN_OR_RETURN(Rve rve, Rve::Create(std::move(start)));
    ASSIGN_OR_RETURN(RveState s, ConsolidateIsotropic(rve, p0, kCompactionBalance, &steps));
    ++trials;
    if (progress) {
      progress(
          absl::StrFormat("compaction trial %d: friction %.4f -> e = %.4f (target %.4f), %d steps",
                          trials, friction, s.void_ratio, target, steps));
    }
    return Trial{friction, s.void_ratio, rve.ToSnapshot()};
  };

  // Steer e by the compaction friction: e grows with friction. Regula falsi
  // between μ = 0 (densest) and the material friction (loosest).
  ASSIGN_OR_RETURN(Trial lo, compact(0.0));
  Trial best = lo;
  double loosest = 0.0;
  if (target > 0 && lo.void_ratio < target - kVoidRatioTolerance) {
    ASSIGN_OR_RETURN(Trial hi, compact(set.material.friction));
    loosest = hi.void_ratio;
    if (std::abs(hi.void_ratio - target) < std::abs(best.void_ratio - target)) best = hi;
    Trial a = lo, b = hi;
    while (b.void_ratio > target + kVoidRatioTolerance && trials < kMaxTrials &&
           std::abs(best.void_ratio - target) > kVoidRatioTolerance) {
      double w = (target - a.void_ratio) / (b.void_ratio - a.void_ratio);
      w = std::clamp(w, 0.1, 0.9);  // keep away from the ends: e(μ) is noisy
      ASSIGN_OR_RETURN(Trial mid, compact(a.friction + w * (b.friction - a.friction)));
      if (std::abs(mid.void_ratio - target) < std::abs(best.void_ratio - target)) best = mid;
      (mid.void_ratio < target ? a : b) = mid;
    }
  }

  // Restore the material friction and stabilise at p0.
  best.packing.material.friction = set.material.friction;
  ASSIGN_OR_RETURN(Rve rve, Rve::Create(std::move(best.packing)));
  rve.BondContacts();
  ASSIGN_OR_RETURN(RveState final_state, ConsolidateIsotropic(rve, p0, kFinalBalance, &steps));

  RveSnapshot out = rve.ToSnapshot();
  const double e0 = final_state.void_ratio;
  out.initial_void_ratio = e0;
  out.permeability_coefficient = set.preparation.initial_permeability * (1.0 + e0) / (e0 * e0 * e0);
  std::fill(out.theta.begin(), out.theta.end(), 0.0);  // rotations count from the prepared state
  out.total_steps = 0;
  out.reference_cell = out.cell;  // strains count from the prepared state
  if (report != nullptr) {
    *report = {.compaction_friction = best.friction,
               .trials = trials,
               .void_ratio = e0,
               .pressure = final_state.MeanPressure(),
               .coordination = final_state.coordination,
               .steps = steps,
               .densest_void_ratio = lo.void_ratio,
               .loosest_void_ratio = loosest};
  }
  return out;
}

absl::StatusOr<RveSnapshot> PrepareTemplate(
    absl::string_view parameter_set, std::uint64_t seed, const TemplateVariant& variant,
    PreparationReport* report, const std::function<void(const std::string&)>& progress) {
  ASSIGN_OR_RETURN(ParameterSet set, FindParameterSet(parameter_set));
  set.preparation.seed = seed;
  if (const double p = variant.pressure; p != 0) {
    if (!(p > 0 && p <= kMaxPressure)) {
      return absl::InvalidArgumentError(absl::StrCat("preparation pressure ", p,
                                                     " Pa must lie in (0, ", kMaxPressure,
                                                     "] Pa (compression +)"));
    }
    set.preparation.pressure = p;
  }
  if (const double e = variant.void_ratio; e != 0) {
    if (!(e > 0 && e < 1)) {
      return absl::InvalidArgumentError(
          absl::StrCat("target void ratio ", e, " must lie in (0, 1)"));
    }
    set.preparation.target_void_ratio = e;
  }
  if (const int n = variant.num_particles; n != 0) {
    if (!(n >= 2 && static_cast<std::size_t>(n) <= kMaxParticles)) {
      return absl::InvalidArgumentError(
          absl::StrCat("particle count ", n, " must lie in [2, ", kMaxParticles, "]"));
    }
    set.preparation.num_particles = n;
  }
  if (variant.rolling_eta.has_value()) {
    const double eta = *variant.rolling_eta;
    if (!(eta >= 0 && eta <= kMaxRollingEta)) {
      return absl::InvalidArgumentError(
          absl::StrCat("rolling-resistance η ", eta, " must lie in [0, ", kMaxRollingEta, "]"));
    }
    if (!HasRollingResistance(set.material)) {
      return absl::InvalidArgumentError(
          absl::StrCat("rolling-resistance η given for parameter set ", parameter_set,
                       ", which has no rolling resistance (β = 0)"));
    }
    set.material.rolling_eta = eta;
  }
  if (progress) {
    progress(absl::StrFormat("%d discs, seed %d", set.preparation.num_particles, seed));
  }
  PreparationReport r;
  ASSIGN_OR_RETURN(RveSnapshot packing, PreparePacking(set, {}, &r, progress));
  // A target out of the steering's reach would give a packing that is not
  // the one asked for (and named for): refused, with the bound it met.
  if (const double e = variant.void_ratio; e != 0) {
    const std::string at =
        absl::StrFormat("%s packs at %.6g Pa (seed %d, %d discs)", parameter_set,
                        set.preparation.pressure, seed, set.preparation.num_particles);
    if (e < r.densest_void_ratio - kVoidRatioTolerance) {
      return absl::InvalidArgumentError(absl::StrFormat(
          "target void ratio %g is out of reach: the densest %s, compacted without friction, "
          "is e = %.4f",
          e, at, r.densest_void_ratio));
    }
    if (r.loosest_void_ratio > 0 && e > r.loosest_void_ratio + kVoidRatioTolerance) {
      return absl::InvalidArgumentError(absl::StrFormat(
          "target void ratio %g is out of reach: the loosest %s, compacted at its material "
          "friction %g, is e = %.4f",
          e, at, set.material.friction, r.loosest_void_ratio));
    }
  }
  if (report != nullptr) *report = r;
  return packing;
}

}  // namespace rvehub::dem
