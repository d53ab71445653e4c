// Generation and isotropic preparation of an RVE packing.
#ifndef RVEHUB_RVE_SERVER_ENGINE_PREPARE_H_
#define RVEHUB_RVE_SERVER_ENGINE_PREPARE_H_

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/snapshot.h"

namespace rvehub::dem {

// Consolidates isotropically to p (Pa, compression +) by a cell servo, then
// relaxes at fixed cell (a moving servo keeps stirring the packing) until the
// unbalanced-force ratio < balance, repeating while relaxing moved p or the
// deviator q = sqrt(¼(σxx − σyy)² + σxy²) out of 1 % of p.
// Stresses lie in (0, 1e9] Pa (kMaxPressure). `interrupt` (optional) is
// asked between DEM steps; its status stops the consolidation (the RVE is
// left part-way). The servo stops once the stress is close and the
// unbalanced-force ratio < 3e-3, or, where `settle_steps` > 0, once the
// stress has stayed close that many steps: at a few kPa the moving servo
// keeps the ratio above 3e-3 and ran to its 600 000-step cap (3–4 s per
// RVE); the relaxation that follows balances the packing either way.
// FailedPrecondition "... did not converge" when 6 servo-and-relax rounds
// leave it out of reach, saying what the packing holds. Below about
// kLowConsolidationStress (values/preparation.h) a packing's few contacts may not hold a stress
// within 1 %: 40 loose discs compacted straight to 100 Pa end at σxx 88,
// σyy 86, σxy 3.7 Pa, and at 1 Pa unjam into a gas (no contacts); SET-dense's
// 400 discs unloaded from 100 kPa reach 300 Pa, but not 210 Pa (the
// deviator at 1.0–1.9 % of p after each round) nor 100 Pa.
// InvalidArgument when the stress, reached or not, leaves e ≤ 0: the discs'
// overlaps then exceed the voids, no packing at all. The soft contacts set
// where that starts, far below kMaxPressure (SET-dense, E = 600 MPa, 100
// discs: prepared e0 0.18 at 100 kPa, 0.14 at 1 MPa; at 3 MPa its
// frictionless compaction reaches e < 0).
//
// kSettleSteps is the settle_steps material points are created with (the
// registry): from a template at 100 or 20 kPa to 2–14 kPa it took 1 200 to
// 24 000 steps where the servo alone took 600 000, e within 0.0015 of that.
inline constexpr std::int64_t kSettleSteps = 4000;
absl::StatusOr<RveState> ConsolidateIsotropic(Rve& rve, double p, double balance = 1e-4,
                                              std::int64_t* steps = nullptr,
                                              const Interrupt& interrupt = {},
                                              std::int64_t settle_steps = 0);

// Same for an anisotropic state with principal axes x, y (e.g. K0 with y
// vertical): σxx, σyy in Pa, compression +; p and the deviator error
// sqrt(¼((σxx − σyy) − (target difference))² + σxy²) within 1 % of p.
absl::StatusOr<RveState> ConsolidateToStress(Rve& rve, double sxx, double syy,
                                             double balance = 1e-4, std::int64_t* steps = nullptr,
                                             const Interrupt& interrupt = {},
                                             std::int64_t settle_steps = 0);

// Random discs, placed without overlap in a loose square cell (seeded,
// platform-independent random numbers).
RveSnapshot GenerateLoosePacking(const ParameterSet& set, const Controls& controls = {});

// Generates N discs, compacts them isotropically by a cell servo to p0 with a
// compaction friction steered (a few trials) so that e lands near the target,
// restores the material friction and stabilises (p within 1 %, unbalanced
// force ratio < 1e-4). `progress`, when set, receives one line per trial.
absl::StatusOr<RveSnapshot> PreparePacking(
    const ParameterSet& set, const Controls& controls = {}, PreparationReport* report = nullptr,
    const std::function<void(const std::string&)>& progress = {});

// The one way to make a template from a named parameter set and a seed
// (rve_cli prepare, mpm_client's case templates): the set's preparation with
// its seed replaced and `variant` applied. NotFound naming the known sets
// for an unknown name; InvalidArgument for a pressure outside
// (0, kMaxPressure], a void ratio outside (0, 1), a count outside
// [2, kMaxParticles], an η outside [0, kMaxRollingEta] or an η for a set
// without rolling resistance. InvalidArgument, after the compactions that
// find it, for a void ratio the set does not pack to at that pressure and
// seed: denser than its frictionless compaction or looser than the one at
// its material friction, by more than the steering's tolerance (0.002); the
// message gives that bound. (A set's own e0 is steered toward the same way
// but never refused: it is the set's, not the caller's.) `progress`, when
// set, first receives "N discs, seed S", then PreparePacking's lines.
absl::StatusOr<RveSnapshot> PrepareTemplate(
    absl::string_view parameter_set, std::uint64_t seed, const TemplateVariant& variant = {},
    PreparationReport* report = nullptr,
    const std::function<void(const std::string&)>& progress = {});

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_PREPARE_H_
