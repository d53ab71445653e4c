// The RVE: creation from a packing and the checks it passes, the state as a
// packing, memory, friction and bonds. The DEM itself lives beside it:
// neighbour_list.cc, cell_flip.cc, step.cc (the kernel), control.cc
// (increments and relaxation) and homogenise.cc (the observed state).
#include "rve_server/engine/rve.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/contact_law.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

using internal::CellHeights;
using internal::GridCells;
using internal::kPi;
using internal::MaxGridCells;

namespace {

absl::Status CheckFinite(double v, absl::string_view what, std::size_t index) {
  if (std::isfinite(v)) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(what, "[", index, "] = ", v, " is not finite"));
}

}  // namespace

Rve::Rve(RveSnapshot packing) : p_(std::move(packing)) {
  const auto [rmin, rmax] = std::minmax_element(p_.radius.begin(), p_.radius.end());
  radius_min_ = *rmin;
  radius_max_ = *rmax;
  double sum = 0.0;
  for (double r : p_.radius) sum += r;
  radius_mean_ = sum / p_.radius.size();
  solid_area_ = SolidArea(p_.radius);
  const Material& m = p_.material;
  const std::size_t n = p_.radius.size();
  inv_mass_.resize(n);
  inv_inertia_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double r = p_.radius[i];
    const double mass = m.density * kPi * r * r * m.thickness * p_.controls.mass_scale;  // kg
    inv_mass_[i] = 1.0 / mass;
    inv_inertia_[i] = 2.0 / (mass * r * r);  // disc: I = ½ m r²
  }
  // Δt = factor·sqrt(m_min / kn_max). Linear: kn_max = E·r_max (two largest
  // discs). Hertz: tangent stiffness at an overlap of 1 % of r_max.
  const double m_min =
      m.density * kPi * radius_min_ * radius_min_ * m.thickness * p_.controls.mass_scale;
  double kn_max = m.young_modulus * radius_max_;
  if (m.model == ContactModel::kHertzMindlin) {
    const HertzResponse hz = HertzMindlin(m.young_modulus, m.poisson_ratio, radius_max_,
                                          radius_max_, 0.01 * radius_max_);
    kn_max = std::max(hz.kn, hz.kt);
  } else {
    kn_max *= std::max(1.0, m.stiffness_ratio);
  }
  dt_ = p_.controls.time_step_factor * std::sqrt(m_min / kn_max);
  std::vector<ContactHistory> history = std::move(p_.contacts);
  p_.contacts.clear();
  Rebuild(history);
}

absl::Status ValidatePacking(const RveSnapshot& p) {
  RETURN_IF_ERROR(Validate(p.material));
  if (p.material.name.size() > kMaxNameBytes) {
    return absl::InvalidArgumentError(absl::StrCat("material name has ", p.material.name.size(),
                                                   " bytes; at most ", kMaxNameBytes));
  }
  for (char c : p.material.name) {
    if (c < 0x20 || c > 0x7e) {
      return absl::InvalidArgumentError("material name must be printable ASCII");
    }
  }
  RETURN_IF_ERROR(Validate(p.controls));
  const std::size_t n = p.radius.size();
  if (n < 2)
    return absl::InvalidArgumentError(absl::StrCat("packing has ", n, " particles; needs >= 2"));
  if (n > kMaxParticles) {
    return absl::InvalidArgumentError(
        absl::StrCat("packing has ", n, " particles; at most ", kMaxParticles));
  }
  for (auto [vec, name] : {std::pair{&p.sx, "sx"},
                           {&p.sy, "sy"},
                           {&p.vx, "vx"},
                           {&p.vy, "vy"},
                           {&p.omega, "omega"},
                           {&p.theta, "theta"}}) {
    if (vec->size() != n) {
      return absl::InvalidArgumentError(
          absl::StrCat("packing field ", name, " has ", vec->size(), " entries; radius has ", n));
    }
    for (std::size_t i = 0; i < n; ++i) {
      RETURN_IF_ERROR(CheckFinite((*vec)[i], name, i));
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!(p.radius[i] > 0) || !std::isfinite(p.radius[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat("radius[", i, "] = ", p.radius[i], " must be > 0 m"));
    }
  }
  if (!p.cell.allFinite() || !(p.cell.determinant() > 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cell matrix must be finite with det > 0; det = ", p.cell.determinant()));
  }
  if (!p.reference_cell.allFinite() || !(p.reference_cell.determinant() > 0)) {
    return absl::InvalidArgumentError("reference_cell must be finite with det > 0");
  }
  if (!p.frame.allFinite() ||
      !(p.frame.transpose() * p.frame).isApprox(Eigen::Matrix2d::Identity(), 1e-9) ||
      !(p.frame.determinant() > 0)) {
    return absl::InvalidArgumentError("frame must be a rotation matrix");
  }
  for (std::size_t k = 0; k < p.contacts.size(); ++k) {
    const ContactHistory& c = p.contacts[k];
    if (c.i >= c.j || c.j >= n) {
      return absl::InvalidArgumentError(
          absl::StrCat("contact ", k, " has indices (", c.i, ", ", c.j, "); need i < j < ", n));
    }
    if (k > 0 && !(std::pair(p.contacts[k - 1].i, p.contacts[k - 1].j) < std::pair(c.i, c.j))) {
      return absl::InvalidArgumentError(
          absl::StrCat("contacts must be sorted by (i, j) without repeats; see entry ", k));
    }
    if (!std::isfinite(c.tangential_force) || !std::isfinite(c.rolling_moment) ||
        !std::isfinite(c.bond_strength) || c.bond_strength < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("contact ", k, " has a non-finite or negative value"));
    }
  }
  if (p.material.model == ContactModel::kHertzMindlin && p.material.bond_cohesion > 0) {
    return absl::InvalidArgumentError("contact bonds need the linear contact model");
  }
  const double rmax = *std::max_element(p.radius.begin(), p.radius.end());
  const double rmin = *std::min_element(p.radius.begin(), p.radius.end());
  const double cutoff = 2.0 * rmax + p.controls.skin * rmin;
  if (CellHeights(p.cell).minCoeff() <= 2.0 * cutoff) {
    return absl::InvalidArgumentError(absl::StrCat(
        "cell is too small for its particles: the smaller cell height ",
        CellHeights(p.cell).minCoeff(), " m must exceed twice the pair cutoff ", cutoff, " m"));
  }
  if (!std::isfinite(p.initial_void_ratio)) {
    return absl::InvalidArgumentError(
        absl::StrCat("initial_void_ratio = ", p.initial_void_ratio, " must be finite"));
  }
  if (!(p.permeability_coefficient >= 0) || !std::isfinite(p.permeability_coefficient)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "permeability_coefficient = ", p.permeability_coefficient, " must be finite and >= 0 m/s"));
  }
  if (p.total_steps < 0 || p.total_steps > kMaxTotalSteps) {
    return absl::InvalidArgumentError(absl::StrCat("total_steps = ", p.total_steps,
                                                   " must lie in 0..", kMaxTotalSteps, " (2^53)"));
  }
  // The neighbour search bins the cell by the cutoff: a cell far larger than
  // its particles (1000 m for 1 mm discs) would need billions of bins.
  const double grid = GridCells(CellHeights(p.cell), cutoff);
  if (!(grid <= MaxGridCells(n))) {
    return absl::InvalidArgumentError(
        absl::StrCat("cell is too large for its particles: ", CellHeights(p.cell).maxCoeff(),
                     " m across with a pair cutoff of ", cutoff, " m needs ", grid,
                     " neighbour-grid cells; at most ", MaxGridCells(n), " for ", n,
                     " particles (solid fraction too low)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<Rve> Rve::Create(RveSnapshot p) {
  RETURN_IF_ERROR(ValidatePacking(p));
  Rve rve(std::move(p));
  // Discs with (nearly) coincident centres have no contact normal.
  const double min_distance = 1e-6 * rve.radius_min_;
  for (const ContactForce& c : rve.Contacts()) {
    if (c.branch.norm() < min_distance) {
      return absl::InvalidArgumentError(
          absl::StrCat("particles ", c.i, " and ", c.j, " have coincident centres"));
    }
  }
  return rve;
}

RveSnapshot Rve::ToSnapshot() const {
  RveSnapshot out = p_;
  out.contacts = CollectHistory();
  return out;
}

std::size_t Rve::MemoryBytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  return sizeof(*this) + bytes(p_.radius) + bytes(p_.sx) + bytes(p_.sy) + bytes(p_.vx) +
         bytes(p_.vy) + bytes(p_.omega) + bytes(p_.theta) + bytes(p_.contacts) + bytes(row_start_) +
         bytes(nbr_i_) + bytes(nbr_j_) + bytes(nbr_kn_) + bytes(nbr_ft_) + bytes(nbr_moment_) +
         bytes(nbr_bond_) + bytes(inv_mass_) + bytes(inv_inertia_) + p_.material.name.capacity() +
         3 * p_.radius.size() * sizeof(double);  // fx_, fy_, tq_ (filled by the first step)
}

absl::Status Rve::SetFriction(double friction) {
  if (!(friction >= 0) || !std::isfinite(friction)) {
    return absl::InvalidArgumentError(
        absl::StrCat("friction = ", friction, " is invalid: μ = tan φ must be >= 0"));
  }
  p_.material.friction = friction;
  forces_valid_ = sums_valid_ = stress_valid_ = false;
  ForEachContact([&](const ContactForce& c, std::uint32_t k) {
    if (!c.bonded) nbr_ft_[k] = CoulombCap(c.tangential_force, c.normal_force, friction);
  });
  return absl::OkStatus();
}

void Rve::BondContacts() {
  const double c = p_.material.bond_cohesion;
  if (c <= 0) return;
  if (nbr_bond_.size() != nbr_j_.size()) nbr_bond_.assign(nbr_j_.size(), 0.0);
  forces_valid_ = sums_valid_ = stress_valid_ = false;
  ForEachContact([&](const ContactForce& contact, std::uint32_t k) {
    if (contact.overlap > 0) {
      nbr_bond_[k] = BondStrength(c, p_.radius[contact.i], p_.radius[contact.j]);
    }
  });
}

}  // namespace rvehub::dem
