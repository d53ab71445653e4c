// Plain data every continuum client's case holds alike (cases/FORMAT.md,
// cases/FEM_FORMAT.md): the RVE packing templates its RVEs are created from
// and the controls set on every RVE it creates. Standard library only, so a
// client's RVE-free core can hold them in its own spec.
#ifndef RVEHUB_CLIENT_CASE_SPEC_RVE_SPEC_H_
#define RVEHUB_CLIENT_CASE_SPEC_RVE_SPEC_H_

#include <cstdint>
#include <optional>
#include <string>

namespace rvehub::client_case {

// A packing template the case's RVEs are created from: either a template
// file (store format, kind "templates") or prepared in code from a named
// parameter set and a seed (then cached next to the outputs).
struct TemplateSpec {
  std::string name;
  std::string file;           // path, relative to the case file; empty: prepare
  std::string template_name;  // name inside the file (empty: the only one)
  std::string parameter_set;  // e.g. "SET-dense" (rve_cli materials)
  std::uint64_t seed = 1;
  // Pa, compression +: compact at this pressure instead of the set's p0
  // (0: the set's), so that e0 is the state where the RVEs are used.
  double pressure = 0;
  // Target void ratio of the preparation, [-] (0: the set's e0): the same
  // material packed denser or looser.
  double void_ratio = 0;
  // Discs in the packing (0: the set's count): a larger sample of the same
  // material, whose peak strength carries less sampling noise.
  int particles = 0;
  // η of the rolling-resistance limit instead of the set's, [-] (unset: the
  // set's): another material, for sets with rolling resistance.
  std::optional<double> rolling_eta = std::nullopt;
};

struct RveSpec {
  // Set in the controls of every RVE the case creates (0: the template's own).
  double max_inertial_number = 0.0;  // bound on I = γ̇·d·sqrt(ρ/p) per increment, [-]
  std::int64_t min_steps = 0;        // DEM steps per increment at least
  // Per-increment bound on the stretch |V − I| (Frobenius) of ΔF = V·R, [-].
  // The RVE deforms its cell along a straight path over the increment's DEM
  // steps, so a looser bound changes nothing for increments within the
  // template's (0.05): it lets a rare larger one through instead of stopping
  // the run. It does not cure a point that blows up (its increments only
  // grow): with 0.5 the saturated scatter point of docs/f-bar-and-nonlocal-strain.md left the
  // grid one step after its 0.19 increment.
  double max_stretch = 0.0;
  // Cap every increment's DEM steps at the MPM step's own duration
  // (ApplyOptions::duration = Δt): an RVE never deforms slower than the
  // continuum, so a flowing or nearly stress-free RVE follows its inertial
  // response at the real strain rate instead of the quasi-static bound.
  // mpm_client only (a quasi-static load step has no duration).
  bool real_time = false;
  // Measure every RVE's full homogenised state at every step. Off (the
  // default), the RVEs measure the stress alone between outputs
  // (ApplyOptions::stress_only): the same results, bit for bit, faster.
  bool full_state_every_step = false;
  // e_max, [-]; 0: none. A point's RVE that carries no stress and is at or
  // above it is not opened further: a dilating increment reaches it without
  // its volume change (RveIncrement). Near zero pressure a granular material
  // comes apart in clumps at about its loosest state; the extra volume is
  // void between them, which the point's own volume carries and the packing
  // does not, so that it meets its neighbours again as soon as it is
  // squeezed. Dry MPM cases only (mpm_client: a material point's volume of
  // its own).
  double max_void_ratio = 0.0;
};

}  // namespace rvehub::client_case

#endif  // RVEHUB_CLIENT_CASE_SPEC_RVE_SPEC_H_
