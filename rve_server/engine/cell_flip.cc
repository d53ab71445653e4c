// Exact changes of the periodic representation: cell flips (a change of
// lattice basis that keeps a sheared cell reduced) and cell doubling (two
// copies of the cell side by side), and rigid rotations of the whole RVE.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "rve_server/engine/rve.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

using internal::Rotation;

// Keeps the cell reduced (|a·b| ≤ ½|a|², ½|b|²) by an exact change of
// lattice basis, so shear can go on without limit.
void Rve::MaybeFlip() {
  const Eigen::Vector2d a = p_.cell.col(0), b = p_.cell.col(1);
  const double ab = a.dot(b);
  int kb = 0, ka = 0;
  if (std::abs(ab) > 0.55 * a.squaredNorm())
    kb = static_cast<int>(std::lround(ab / a.squaredNorm()));
  else if (std::abs(ab) > 0.55 * b.squaredNorm())
    ka = static_cast<int>(std::lround(ab / b.squaredNorm()));
  if (kb == 0 && ka == 0) return;
  const std::size_t n = p_.radius.size();
  if (kb != 0) {  // b' = b − kb·a; s'_x = s_x + kb·s_y
    p_.cell.col(1) = b - kb * a;
    p_.reference_cell.col(1) -= kb * p_.reference_cell.col(0);
    for (std::size_t i = 0; i < n; ++i) p_.sx[i] += kb * p_.sy[i];
  } else {  // a' = a − ka·b; s'_y = s_y + ka·s_x
    p_.cell.col(0) = a - ka * b;
    p_.reference_cell.col(0) -= ka * p_.reference_cell.col(1);
    for (std::size_t i = 0; i < n; ++i) p_.sy[i] += ka * p_.sx[i];
  }
  for (std::size_t i = 0; i < n; ++i) {
    p_.sx[i] -= std::floor(p_.sx[i]);
    p_.sy[i] -= std::floor(p_.sy[i]);
  }
  Rebuild(CollectHistory());
}

absl::Status Rve::DoubleCell(int axis) {
  if (axis != 0 && axis != 1) {
    return absl::InvalidArgumentError(absl::StrCat("cell axis ", axis, " is not 0 or 1"));
  }
  const std::size_t n = p_.radius.size();
  if (2 * n > kMaxParticles) {
    return absl::FailedPreconditionError(absl::StrCat("doubling the cell would give ", 2 * n,
                                                      " particles; at most ", kMaxParticles));
  }
  RveSnapshot s = ToSnapshot();
  // Wrapped coordinate along the axis, [0, 1): copy c of particle i sits at
  // (w_i + c)/2 in the doubled cell.
  std::vector<double>& along = axis == 0 ? s.sx : s.sy;
  for (double& w : along) w -= std::floor(w);
  // A pair whose nearest image crosses the cell edge along the axis
  // (|w_j − w_i| > ½) joins copy c of i to copy 1 − c of j.
  std::vector<ContactHistory> contacts;
  contacts.reserve(2 * s.contacts.size());
  for (const ContactHistory& h : s.contacts) {
    const bool crosses = std::abs(along[h.j] - along[h.i]) > 0.5;
    for (std::uint32_t c = 0; c < 2; ++c) {
      const std::uint32_t i = h.i + c * static_cast<std::uint32_t>(n);
      const std::uint32_t j = h.j + (c ^ static_cast<std::uint32_t>(crosses)) * n;
      // Relabelled j < i: n and t both turn, so ft stays; the moment on the
      // new i is the one that acted on j.
      if (i < j) {
        contacts.push_back(h);
        contacts.back().i = i;
        contacts.back().j = j;
      } else {
        contacts.push_back({j, i, h.tangential_force, -h.rolling_moment, h.bond_strength});
      }
    }
  }
  std::sort(contacts.begin(), contacts.end(), [](const ContactHistory& a, const ContactHistory& b) {
    return a.i != b.i ? a.i < b.i : a.j < b.j;
  });
  s.contacts = std::move(contacts);
  for (std::vector<double>* v : {&s.radius, &s.sx, &s.sy, &s.vx, &s.vy, &s.omega, &s.theta}) {
    v->resize(2 * n);
    std::copy_n(v->begin(), n, v->begin() + n);
  }
  for (std::size_t i = 0; i < n; ++i) {
    along[i] *= 0.5;
    along[n + i] = along[n + i] * 0.5 + 0.5;
  }
  s.cell.col(axis) *= 2.0;
  s.reference_cell.col(axis) *= 2.0;  // F = cell·reference⁻¹ unchanged
  const bool track = track_energy_;
  *this = Rve(std::move(s));
  track_energy_ = track;
  MaybeFlip();  // [2a, b] may need a change of basis to stay reduced
  return absl::OkStatus();
}

void Rve::ApplyRigidRotation(double angle) {
  if (angle == 0.0) return;
  const Eigen::Matrix2d r = Rotation(angle);
  // The contact forces turn with the packing (the next step integrates
  // with them); the homogenised sums are measured again by that step.
  sums_valid_ = stress_valid_ = false;
  if (forces_valid_) {
    for (std::size_t i = 0; i < fx_.size(); ++i) {
      const double fx = fx_[i], fy = fy_[i];
      fx_[i] = r(0, 0) * fx + r(0, 1) * fy;
      fy_[i] = r(1, 0) * fx + r(1, 1) * fy;
    }
  }
  p_.cell = r * p_.cell;
  p_.frame = r * p_.frame;
  cell_at_build_ = r * cell_at_build_;
  for (std::size_t i = 0; i < p_.radius.size(); ++i) {
    const double vx = p_.vx[i], vy = p_.vy[i];
    p_.vx[i] = r(0, 0) * vx + r(0, 1) * vy;
    p_.vy[i] = r(1, 0) * vx + r(1, 1) * vy;
    p_.theta[i] += angle;
  }
}

}  // namespace rvehub::dem
