// Particle and contact parameters of a DEM material, and the named parameter
// sets of ../shared/reference/README.md. Pure data plus validation.
#ifndef RVEHUB_RVE_SERVER_VALUES_MATERIAL_H_
#define RVEHUB_RVE_SERVER_VALUES_MATERIAL_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace rvehub::dem {

enum class ContactModel {
  kLinear,        // kn = E·r*, kt = (kt/kn)·kn, r* = 2 r1 r2 / (r1 + r2)
  kHertzMindlin,  // fn = (4/3) E* sqrt(R* δ) δ, kt = 8 G* sqrt(R* δ)
};

struct Material {
  std::string name = "custom";
  double density = 2650.0;       // ρ_p, kg/m³
  double young_modulus = 600e6;  // E_c, Pa (linear: kn = E·r*)
  double stiffness_ratio = 0.8;  // kt/kn, linear model only, [-]
  double poisson_ratio = 0.25;   // ν, Hertz–Mindlin only, [-]
  double friction = 0.5452;      // μ = tan φ, [-]
  double rolling_beta = 0.0;     // β in kr = kt·r1·r2·β; 0 disables rolling resistance
  double rolling_eta = 0.0;      // η in |M_r| ≤ η·r_min·fn, [-]
  double bond_cohesion = 0.0;    // c, Pa; bond strength c·min(r1,r2)² (N); 0: no bonds
  double damping = 0.1;          // local non-viscous damping α, [-]
  double thickness = 0.1;        // out-of-plane disc thickness t, m (see shared/reference)
  ContactModel model = ContactModel::kLinear;
};

// Whether contacts of `m` carry rolling moments: without a rolling stiffness
// (β = 0) there are none, and η changes nothing.
inline bool HasRollingResistance(const Material& m) { return m.rolling_beta > 0; }

// Largest rolling-resistance η a template variant takes (PrepareTemplate): a
// moment limit of the smaller radius times fn is already a lever arm as long
// as the disc's radius.
inline constexpr double kMaxRollingEta = 1.0;

// How an RVE of a material is generated and prepared.
struct PreparationSpec {
  int num_particles = 400;
  double radius_min = 3e-3;            // m
  double radius_max = 7e-3;            // m (radii uniform in [min, max])
  double pressure = 100e3;             // p0, Pa, compression positive
  double target_void_ratio = 0.177;    // e0 sought by the compaction friction; <= 0: frictionless
  double initial_permeability = 1e-3;  // k0 at e0, m/s (hydraulic conductivity)
  std::uint64_t seed = 1;
};

struct ParameterSet {
  Material material;
  PreparationSpec preparation;
};

// Checks every field; the message names the field and the value.
absl::Status Validate(const Material& m);
absl::Status Validate(const PreparationSpec& p);

// The sets of shared/reference/README.md: SET-dense, SPFEM-biaxial,
// footing-dense, footing-medium, footing-soft, consolidation,
// saturated-dense/-medium/-loose, wave-isotropic, cyclic-loose,
// cyclic-loose-stress, collapse. NotFound lists the known names.
absl::StatusOr<ParameterSet> FindParameterSet(absl::string_view name);
std::vector<std::string> ParameterSetNames();

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_VALUES_MATERIAL_H_
