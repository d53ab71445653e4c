#include "tests/support/test_util.h"

#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "gtest/gtest.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/values/material.h"

namespace rvehub::dem::testing_util {

const RveSnapshot& Prepared(const std::string& name) {
  static auto* cache = new std::map<std::string, RveSnapshot>();
  auto it = cache->find(name);
  if (it == cache->end()) {
    absl::StatusOr<ParameterSet> set = FindParameterSet(name);
    EXPECT_TRUE(set.ok()) << set.status();
    EXPECT_EQ(set->preparation.seed, 1u);
    absl::StatusOr<RveSnapshot> packing = PreparePacking(*set);
    EXPECT_TRUE(packing.ok()) << name << ": " << packing.status();
    it = cache->emplace(name, packing.ok() ? *std::move(packing) : RveSnapshot{}).first;
  }
  return it->second;
}

Rve CreateOrDie(RveSnapshot packing) {
  absl::StatusOr<Rve> rve = Rve::Create(std::move(packing));
  EXPECT_TRUE(rve.ok()) << rve.status();
  return *std::move(rve);
}

RveSnapshot SquareLattice(int side, double spacing, const std::function<double(int, int)>& radius) {
  RveSnapshot p;
  p.cell = Eigen::Matrix2d::Identity() * (side * spacing);
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      p.radius.push_back(radius(x, y));
      p.sx.push_back((x + 0.5) / side);
      p.sy.push_back((y + 0.5) / side);
    }
  }
  const std::size_t n = p.radius.size();
  p.vx.assign(n, 0.0);
  p.vy.assign(n, 0.0);
  p.omega.assign(n, 0.0);
  p.theta.assign(n, 0.0);
  return p;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  // memcmp must not see the null data() of an empty vector, even for 0 bytes.
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0);
}

void ExpectSameBits(const std::vector<double>& a, const std::vector<double>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (!SameBits(a[k], b[k])) {
      ADD_FAILURE() << what << "[" << k << "]: " << a[k] << " vs " << b[k];
      return;
    }
  }
}

void ExpectSameBits(const Eigen::Matrix2d& a, const Eigen::Matrix2d& b, const char* what) {
  EXPECT_TRUE(SameBits(a, b)) << what << "\n" << a << "\nvs\n" << b;
}

void ExpectSameMaterialAndControls(const RveSnapshot& a, const RveSnapshot& b) {
  const Material &ma = a.material, &mb = b.material;
  const Controls &ca = a.controls, &cb = b.controls;
  EXPECT_EQ(ma.name, mb.name);
  EXPECT_EQ(ma.model, mb.model);
  EXPECT_EQ(ca.min_steps, cb.min_steps);
  for (auto [x, y, field] :
       {std::tuple{ma.density, mb.density, "density"},
        {ma.young_modulus, mb.young_modulus, "young_modulus"},
        {ma.stiffness_ratio, mb.stiffness_ratio, "stiffness_ratio"},
        {ma.poisson_ratio, mb.poisson_ratio, "poisson_ratio"},
        {ma.friction, mb.friction, "friction"},
        {ma.rolling_beta, mb.rolling_beta, "rolling_beta"},
        {ma.rolling_eta, mb.rolling_eta, "rolling_eta"},
        {ma.bond_cohesion, mb.bond_cohesion, "bond_cohesion"},
        {ma.damping, mb.damping, "damping"},
        {ma.thickness, mb.thickness, "thickness"},
        {ca.time_step_factor, cb.time_step_factor, "time_step_factor"},
        {ca.max_inertial_number, cb.max_inertial_number, "max_inertial_number"},
        {ca.pressure_floor, cb.pressure_floor, "pressure_floor"},
        {ca.max_stretch, cb.max_stretch, "max_stretch"},
        {ca.max_rotation, cb.max_rotation, "max_rotation"},
        {ca.mass_scale, cb.mass_scale, "mass_scale"},
        {ca.skin, cb.skin, "skin"}}) {
    EXPECT_TRUE(SameBits(x, y)) << field << ": " << x << " vs " << y;
  }
}

void ExpectIdenticalPackings(const RveSnapshot& a, const RveSnapshot& b) {
  ExpectSameMaterialAndControls(a, b);
  ExpectSameBits(a.cell, b.cell, "cell");
  ExpectSameBits(a.frame, b.frame, "frame");
  ExpectSameBits(a.reference_cell, b.reference_cell, "reference_cell");
  ExpectSameBits(a.radius, b.radius, "radius");
  ExpectSameBits(a.sx, b.sx, "sx");
  ExpectSameBits(a.sy, b.sy, "sy");
  ExpectSameBits(a.vx, b.vx, "vx");
  ExpectSameBits(a.vy, b.vy, "vy");
  ExpectSameBits(a.omega, b.omega, "omega");
  ExpectSameBits(a.theta, b.theta, "theta");
  EXPECT_TRUE(SameBits(a.initial_void_ratio, b.initial_void_ratio))
      << "initial_void_ratio: " << a.initial_void_ratio << " vs " << b.initial_void_ratio;
  EXPECT_TRUE(SameBits(a.permeability_coefficient, b.permeability_coefficient))
      << "permeability_coefficient: " << a.permeability_coefficient << " vs "
      << b.permeability_coefficient;
  EXPECT_EQ(a.total_steps, b.total_steps);
  ASSERT_EQ(a.contacts.size(), b.contacts.size());
  // The first contact that differs only: the ones after it mostly follow.
  for (std::size_t k = 0; k < a.contacts.size(); ++k) {
    const ContactHistory &x = a.contacts[k], &y = b.contacts[k];
    if (x.i == y.i && x.j == y.j && SameBits(x.tangential_force, y.tangential_force) &&
        SameBits(x.rolling_moment, y.rolling_moment) &&
        SameBits(x.bond_strength, y.bond_strength)) {
      continue;
    }
    ADD_FAILURE() << "contact " << k << ": (" << x.i << ", " << x.j << ") ft " << x.tangential_force
                  << " M_r " << x.rolling_moment << " bond " << x.bond_strength << " vs (" << y.i
                  << ", " << y.j << ") ft " << y.tangential_force << " M_r " << y.rolling_moment
                  << " bond " << y.bond_strength;
    return;
  }
}

void ExpectIdenticalPackings(const RveSnapshot& a, const RveSnapshot& b, const std::string& where) {
  SCOPED_TRACE(where);
  ExpectIdenticalPackings(a, b);
}

void ExpectIdenticalStates(const RveState& a, const RveState& b, const std::string& where) {
  SCOPED_TRACE(where);
  EXPECT_TRUE(SameBits(a.stress, b.stress)) << a.stress << "\nvs\n" << b.stress;
  EXPECT_TRUE(SameBits(a.fabric, b.fabric));
  EXPECT_TRUE(SameBits(a.fabric_anisotropy_tensor, b.fabric_anisotropy_tensor));
  ASSERT_EQ(a.tangent.has_value(), b.tangent.has_value());
  if (a.tangent) {
    EXPECT_TRUE(SameBits(*a.tangent, *b.tangent));
  }
  EXPECT_EQ(a.fabric_defined, b.fabric_defined);
  EXPECT_EQ(a.num_contacts, b.num_contacts);
  EXPECT_EQ(a.steps, b.steps);
  for (auto [x, y, name] : {std::tuple{a.fabric_anisotropy, b.fabric_anisotropy, "Fa"},
                            {a.void_ratio, b.void_ratio, "void_ratio"},
                            {a.porosity, b.porosity, "porosity"},
                            {a.coordination, b.coordination, "coordination"},
                            {a.mechanical_coordination, b.mechanical_coordination, "mech_coord"},
                            {a.permeability, b.permeability, "permeability"},
                            {a.mean_rotation, b.mean_rotation, "mean_rotation"},
                            {a.kinetic_energy, b.kinetic_energy, "kinetic_energy"},
                            {a.unbalanced_force_ratio, b.unbalanced_force_ratio, "unbalanced"},
                            {a.volume, b.volume, "volume"},
                            {a.time_step, b.time_step, "time_step"},
                            {a.mass_scale, b.mass_scale, "mass_scale"}}) {
    EXPECT_TRUE(SameBits(x, y)) << name << ": " << x << " vs " << y;
  }
}

}  // namespace rvehub::dem::testing_util
