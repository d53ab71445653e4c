// How a template is prepared, as values: the variant of a named parameter
// set a client asks for, the report of a preparation, and the name and
// description a prepared template carries (rve_cli prepare, mpm_client's
// template cache). The engine prepares (engine/prepare.h).
#ifndef RVEHUB_RVE_SERVER_VALUES_PREPARATION_H_
#define RVEHUB_RVE_SERVER_VALUES_PREPARATION_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "absl/strings/string_view.h"

namespace rvehub::dem {

// Pa, compression +: below this a packing's few contacts may not hold a
// consolidation stress within 1 % (engine/prepare.h, ConsolidateIsotropic);
// mpm_client notes the points it would start below it.
inline constexpr double kLowConsolidationStress = 1e3;

struct PreparationReport {
  double compaction_friction = 0.0;  // μ used while compacting, [-]
  int trials = 0;                    // compactions run to steer e toward the target
  double void_ratio = 0.0;           // e0 reached, [-]
  double pressure = 0.0;             // p0 reached, Pa (compression +)
  double coordination = 0.0;         // [-]
  std::int64_t steps = 0;            // DEM steps over all trials
  // The steering's reach at p0, [-]: e of the frictionless compaction (the
  // densest it packs) and of the one at the material's friction (the
  // loosest; 0 when not run, the target lying at or below the densest).
  double densest_void_ratio = 0.0;
  double loosest_void_ratio = 0.0;
};

// How a template departs from its parameter set's packing; each field left
// at its default keeps the set's.
struct TemplateVariant {
  // Pa, compression +: compact at this pressure instead of the set's p0 (0:
  // the set's). A packing compacted at the stress it will be used at reaches
  // the set's e0 there, where one compacted at 100 kPa and unloaded swells
  // and loses contacts.
  double pressure = 0;
  // Target e0 instead of the set's (0: the set's): the same material packed
  // denser or looser. The compaction friction, between 0 and the material's,
  // bounds what can be reached: a target beyond it is refused (below); the
  // report gives the e0 reached.
  double void_ratio = 0;
  // Discs instead of the set's count (0: the set's): a larger (or smaller)
  // sample of the same material, e.g. to see how much of an element test's
  // result is the sample's size.
  int num_particles = 0;
  // η of the rolling-resistance limit |M_r| ≤ η·r_min·fn instead of the
  // set's, [-] (unset: the set's): another material, for sets with rolling
  // resistance (β > 0). footing-dense's peak φ' rises from 24.5° at η = 0
  // to 30.7° at the set's 0.05 (means over seeds 1–9).
  std::optional<double> rolling_eta = std::nullopt;
};

// The name of a packing prepared by PrepareTemplate when nobody names it
// (rve_cli prepare --out, mpm_client's template cache files):
// "<set>-seed<S>", then "-p<P>Pa", "-e<E>", "-<N>discs" and "-eta<η>" for
// whichever field of `variant` is set, since each makes another packing.
// Values as %.6g without '+' (2e06 for 2 MPa), so the name is a valid
// template name.
std::string TemplateName(absl::string_view parameter_set, std::uint64_t seed,
                         const TemplateVariant& variant);

// The description a template prepared by PrepareTemplate carries in its file
// (rve_cli prepare --out, mpm_client's template cache): "material M, seed S,
// N discs, e0 = E, p0 = P Pa", from the report of its preparation, with
// ", rolling eta H" where `variant` replaces the set's η.
std::string TemplateDescription(absl::string_view parameter_set, std::uint64_t seed,
                                std::size_t num_particles, const PreparationReport& report,
                                const TemplateVariant& variant = {});

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_VALUES_PREPARATION_H_
