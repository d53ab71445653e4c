#include "rve_server/values/material.h"

#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace rvehub::dem {
namespace {

absl::Status Check(bool ok, absl::string_view field, double value, absl::string_view rule) {
  if (ok && std::isfinite(value)) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(field, " = ", value, " is invalid: ", rule));
}

double TanDeg(double degrees) { return std::tan(degrees * std::numbers::pi / 180.0); }

ParameterSet Make(std::string name, double young, double kt_kn, double friction, double e0) {
  ParameterSet s;
  s.material.name = std::move(name);
  s.material.young_modulus = young;
  s.material.stiffness_ratio = kt_kn;
  s.material.friction = friction;
  s.preparation.target_void_ratio = e0;
  return s;
}

std::vector<ParameterSet> AllSets() {
  std::vector<ParameterSet> sets;
  // liang-zhao-mpm-dem Table 1.
  sets.push_back(Make("SET-dense", 600e6, 0.8, TanDeg(28.6), 0.177));
  // guo-et-al-spfem-dem Table 1: φ = 0.5 rad.
  sets.push_back(Make("SPFEM-biaxial", 800e6, 0.8, std::tan(0.5), 0.178));
  // liang-zhao-mpm-dem Table 2, with rolling resistance.
  for (auto [name, young, phi, eta, e0] : {std::tuple{"footing-dense", 800e6, 23.0, 0.05, 0.1874},
                                           std::tuple{"footing-medium", 800e6, 23.0, 0.05, 0.2314},
                                           std::tuple{"footing-soft", 80e6, 20.0, 0.02, 0.2299}}) {
    ParameterSet s = Make(name, young, 0.5, TanDeg(phi), e0);
    s.material.rolling_beta = 1.0;
    s.material.rolling_eta = eta;
    sets.push_back(s);
  }
  // The soft packing's e0 = 0.2299 is taken at the footing's confining
  // stress, 20 kPa: at 100 kPa its ten times softer contacts overlap by
  // ~2.5 % of a radius, and even compacted at its full friction it reaches
  // only e = 0.174 there. At 20 kPa the full friction gives e0 = 0.2318.
  // (The dense and medium packings, ten times stiffer, differ by < 0.005
  // between the two pressures; they keep the usual 100 kPa.)
  sets.back().preparation.pressure = 20e3;
  // liang-zhao-wu-soga Table 1: μ = 0.545, porosity n = 0.161 at 100 kPa.
  sets.push_back(Make("consolidation", 600e6, 0.8, 0.545, 0.161 / (1.0 - 0.161)));
  // liang-zhao-wu-soga §4.2–4.3: Table 1's material, packed to the dense,
  // medium and loose void ratios of the cyclic shaking and the saturated
  // collapse (at 100 kPa).
  for (auto [name, e0] : {std::tuple{"saturated-dense", 0.21}, std::tuple{"saturated-medium", 0.23},
                          std::tuple{"saturated-loose", 0.24}}) {
    sets.push_back(Make(name, 600e6, 0.8, 0.545, e0));
  }
  // liang-zhao-wu-soga Table 2 (wave propagation) with discs for its
  // elliptic grains: kn = kt = 6e6 N/m (E·r* at r* = 5 mm, the ellipses'
  // semi-major axis), μ = 0.6, radii 4–6 mm around 5 mm; the isotropic
  // packing compacted without friction (the paper: "randomly compressed").
  ParameterSet wave = Make("wave-isotropic", 1.2e9, 1.0, 0.6, 0.0);
  wave.preparation.radius_min = 4e-3;
  wave.preparation.radius_max = 6e-3;
  wave.preparation.initial_permeability = 1e-2;
  sets.push_back(wave);
  // guo-zhao-2014 §5: loose RVEs for cyclic shear (strain / stress control).
  sets.push_back(Make("cyclic-loose", 600e6, 0.8, TanDeg(28.6), 0.223));
  sets.push_back(Make("cyclic-loose-stress", 600e6, 0.8, TanDeg(28.6), 0.209));
  // liang-zhao-mpm-dem Table 3: 1000 discs, e0 = 0.197–0.226 (midpoint).
  ParameterSet collapse = Make("collapse", 600e6, 0.8, TanDeg(28.6), 0.21);
  collapse.preparation.num_particles = 1000;
  sets.push_back(collapse);
  return sets;
}

}  // namespace

absl::Status Validate(const Material& m) {
  for (const absl::Status& s : {
           Check(m.density > 0, "density", m.density, "must be > 0 kg/m³"),
           Check(m.young_modulus > 0, "young_modulus", m.young_modulus, "must be > 0 Pa"),
           Check(m.stiffness_ratio >= 0, "stiffness_ratio", m.stiffness_ratio,
                 "kt/kn must be >= 0"),
           Check(m.poisson_ratio > -1 && m.poisson_ratio < 0.5, "poisson_ratio", m.poisson_ratio,
                 "must lie in (-1, 0.5)"),
           Check(m.friction >= 0, "friction", m.friction, "μ = tan φ must be >= 0"),
           Check(m.rolling_beta >= 0, "rolling_beta", m.rolling_beta, "must be >= 0"),
           Check(m.rolling_eta >= 0, "rolling_eta", m.rolling_eta, "must be >= 0"),
           Check(m.bond_cohesion >= 0, "bond_cohesion", m.bond_cohesion, "must be >= 0 Pa"),
           Check(m.damping >= 0 && m.damping < 1, "damping", m.damping, "α must lie in [0, 1)"),
           Check(m.thickness > 0, "thickness", m.thickness, "must be > 0 m"),
       }) {
    if (!s.ok()) return s;
  }
  return absl::OkStatus();
}

absl::Status Validate(const PreparationSpec& p) {
  for (const absl::Status& s : {
           Check(p.num_particles >= 2 && p.num_particles <= 1000000, "num_particles",
                 p.num_particles, "must lie in [2, 1e6]"),
           Check(p.radius_min > 0, "radius_min", p.radius_min, "must be > 0 m"),
           Check(p.radius_max >= p.radius_min, "radius_max", p.radius_max, "must be >= radius_min"),
           Check(p.pressure > 0, "pressure", p.pressure, "must be > 0 Pa"),
           Check(p.target_void_ratio < 10, "target_void_ratio", p.target_void_ratio,
                 "must be < 10 (<= 0 means frictionless compaction)"),
           Check(p.initial_permeability > 0, "initial_permeability", p.initial_permeability,
                 "must be > 0 m/s"),
       }) {
    if (!s.ok()) return s;
  }
  return absl::OkStatus();
}

absl::StatusOr<ParameterSet> FindParameterSet(absl::string_view name) {
  for (ParameterSet& s : AllSets()) {
    if (s.material.name == name) return s;
  }
  return absl::NotFoundError(absl::StrCat("unknown parameter set '", name,
                                          "'; known: ", absl::StrJoin(ParameterSetNames(), ", ")));
}

std::vector<std::string> ParameterSetNames() {
  std::vector<std::string> names;
  for (const ParameterSet& s : AllSets()) names.push_back(s.material.name);
  return names;
}

}  // namespace rvehub::dem
