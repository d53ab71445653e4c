#include "rve_server/engine/rve.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <type_traits>
#include <utility>

#include "absl/strings/str_cat.h"
#include "rve_server/engine/contact_law.h"

namespace rvehub::dem {
namespace {

constexpr double kPi = std::numbers::pi;

// Round to nearest (ties to even) by the 1.5·2^52 trick: two additions, no
// libm call, exact for |x| < 2^51. Used for the minimum image in reduced
// coordinates, which needs the cell to be reduced (MaybeFlip) and the cutoff
// below half of each cell height (CheckCellSize).
inline double RoundNearest(double x) {
  constexpr double kMagic = 6755399441055744.0;
  return (x + kMagic) - kMagic;  // not folded to x: no -ffast-math (see CMakeLists)
}

// sign(x) ∈ {−1, 0, 1}.
inline double Sign(double x) { return (x > 0.0) - (x < 0.0); }

// Local non-viscous damping force −α|f|·sign(v) (N), one component; −0 for
// v = 0. Selects rather than multiplies by sign(v), so the compiler can blend
// it in SIMD lanes (sign(v) is unpredictable: no branch either way).
inline double Damping(double alpha, double f, double v) {
  const double d = alpha * std::abs(f);
  return v > 0.0 ? -d : (v < 0.0 ? d : -0.0);
}

// Heights of the cell (m): distance between the two pairs of opposite edges.
Eigen::Vector2d CellHeights(const Eigen::Matrix2d& h) {
  const double area = std::abs(h.determinant());
  return {area / h.col(1).norm(), area / h.col(0).norm()};
}

// Singular values (min, max) of a 2×2 matrix, closed form.
std::pair<double, double> SingularValues(const Eigen::Matrix2d& m) {
  const double a = m.squaredNorm();
  const double det = std::abs(m.determinant());
  const double root = std::sqrt(std::max(a * a - 4.0 * det * det, 0.0));
  return {std::sqrt(std::max((a - root) / 2.0, 0.0)), std::sqrt((a + root) / 2.0)};
}

Eigen::Matrix2d Rotation(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

absl::Status CheckFinite(double v, absl::string_view what, std::size_t index) {
  if (std::isfinite(v)) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(what, "[", index, "] = ", v, " is not finite"));
}

// Scratch shared by every RVE on a thread (keeps RVEs small): the contact
// pass's per-pair results and per-particle contact counts.
struct Scratch {
  std::vector<double> count;  // contacts per particle
  // Per listed pair, from the pair pass: force on i (N), torques on i and j
  // (N·m); while measuring, the six terms of the measured sums (see
  // PairPass), the elastic energy (J) and 1 for an active contact (else all 0).
  std::vector<double> fx, fy, ti, tj, elastic, active;
  std::array<std::vector<double>, 6> term;
};
Scratch& ThreadScratch() {
  thread_local Scratch scratch;
  return scratch;
}

}  // namespace

double SolidArea(const std::vector<double>& radius) {
  double a = 0.0;
  for (double r : radius) a += kPi * r * r;
  return a;
}

absl::Status Validate(const Controls& c) {
  auto check = [](bool ok, absl::string_view field, double v, absl::string_view rule) {
    return ok && std::isfinite(v)
               ? absl::OkStatus()
               : absl::InvalidArgumentError(absl::StrCat(field, " = ", v, " is invalid: ", rule));
  };
  for (const absl::Status& s : {
           check(c.time_step_factor > 0 && c.time_step_factor <= 1, "time_step_factor",
                 c.time_step_factor, "must lie in (0, 1]"),
           check(c.max_inertial_number >= kMinInertialNumber &&
                     c.max_inertial_number <= kMaxInertialNumber,
                 "max_inertial_number", c.max_inertial_number, "must lie in [1e-6, 1]"),
           check(c.pressure_floor >= kMinPressureFloor && c.pressure_floor <= kMaxPressure,
                 "pressure_floor", c.pressure_floor, "must lie in [1, 1e9] Pa"),
           check(c.min_steps >= 0 && c.min_steps <= kMaxMinSteps, "min_steps",
                 static_cast<double>(c.min_steps), "must lie in [0, 1e6]"),
           check(c.max_stretch > 0 && c.max_stretch <= 10, "max_stretch", c.max_stretch,
                 "must lie in (0, 10]"),
           check(c.max_rotation > 0 && c.max_rotation <= kPi / 2, "max_rotation", c.max_rotation,
                 "must lie in (0, π/2] rad"),
           check(c.mass_scale >= 1, "mass_scale", c.mass_scale, "must be >= 1"),
           check(c.skin > 0 && c.skin <= 2, "skin", c.skin, "must lie in (0, 2] (× r_min)"),
       }) {
    if (!s.ok()) return s;
  }
  return absl::OkStatus();
}

Rve::Rve(Packing packing) : p_(std::move(packing)) {
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

namespace {

// Cells of the neighbour search's grid for a cell of heights `heights` (m)
// and a pair cutoff (m); as a double, so that a huge cell cannot overflow.
double GridCells(const Eigen::Vector2d& heights, double cutoff) {
  return std::floor(heights.x() / cutoff) * std::floor(heights.y() / cutoff);
}

// The most grid cells a packing of n particles may need.
double MaxGridCells(std::size_t n) {
  return std::max(kMinGridCells, kMaxGridCellsPerParticle * static_cast<double>(n));
}

}  // namespace

absl::Status ValidatePacking(const Packing& p) {
  if (absl::Status s = Validate(p.material); !s.ok()) return s;
  if (p.material.name.size() > kMaxNameBytes) {
    return absl::InvalidArgumentError(absl::StrCat("material name has ", p.material.name.size(),
                                                   " bytes; at most ", kMaxNameBytes));
  }
  for (char c : p.material.name) {
    if (c < 0x20 || c > 0x7e) {
      return absl::InvalidArgumentError("material name must be printable ASCII");
    }
  }
  if (absl::Status s = Validate(p.controls); !s.ok()) return s;
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
      if (absl::Status s = CheckFinite((*vec)[i], name, i); !s.ok()) return s;
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
  if (p.total_steps < 0) {
    return absl::InvalidArgumentError(absl::StrCat("total_steps = ", p.total_steps, " < 0"));
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

absl::StatusOr<Rve> Rve::Create(Packing p) {
  if (absl::Status s = ValidatePacking(p); !s.ok()) return s;
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

double Rve::Cutoff() const { return 2.0 * radius_max_ + p_.controls.skin * radius_min_; }

Eigen::Vector2d Rve::Branch(std::uint32_t i, std::uint32_t j) const {
  double dsx = p_.sx[j] - p_.sx[i], dsy = p_.sy[j] - p_.sy[i];
  dsx -= RoundNearest(dsx);
  dsy -= RoundNearest(dsy);
  const Eigen::Matrix2d& h = p_.cell;
  return {h(0, 0) * dsx + h(0, 1) * dsy, h(1, 0) * dsx + h(1, 1) * dsy};
}

std::vector<ContactHistory> Rve::CollectHistory() const {
  std::vector<ContactHistory> out;
  const bool rolling = !nbr_moment_.empty(), bonds = !nbr_bond_.empty();
  for (std::size_t i = 0; i + 1 < row_start_.size(); ++i) {
    for (std::uint32_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
      const double moment = rolling ? nbr_moment_[k] : 0.0;
      const double bond = bonds ? nbr_bond_[k] : 0.0;
      if (nbr_ft_[k] != 0.0 || moment != 0.0 || bond != 0.0) {
        out.push_back({static_cast<std::uint32_t>(i), nbr_j_[k], nbr_ft_[k], moment, bond});
      }
    }
  }
  return out;
}

Packing Rve::ToPacking() const {
  Packing out = p_;
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

// Cell-list neighbour search in reduced coordinates (valid for any cell shape
// with enough bins), then a merge that carries the contact history over.
void Rve::Rebuild(const std::vector<ContactHistory>& history) {
  const std::size_t n = p_.radius.size();
  const Eigen::Matrix2d& h = p_.cell;
  const double cutoff_skin = p_.controls.skin * radius_min_;
  const Eigen::Vector2d heights = CellHeights(h);
  const double cutoff = Cutoff();
  const int nbx = static_cast<int>(heights.x() / cutoff);
  const int nby = static_cast<int>(heights.y() / cutoff);

  // Pairs as (i << 32 | j), i < j: one flat array, sorted once.
  thread_local std::vector<std::uint64_t> pairs;
  pairs.clear();
  auto add = [&](std::uint32_t i, std::uint32_t j) {
    pairs.push_back(static_cast<std::uint64_t>(std::min(i, j)) << 32 | std::max(i, j));
  };
  // Whether discs i and j are within the cutoff (Branch(i, j) inlined with
  // the cell hoisted: the search's inner loop).
  const double h00 = h(0, 0), h01 = h(0, 1), h10 = h(1, 0), h11 = h(1, 1);
  const double* __restrict sx = p_.sx.data();
  const double* __restrict sy = p_.sy.data();
  const double* __restrict rad = p_.radius.data();
  auto within = [&](std::uint32_t i, std::uint32_t j) {
    double dsx = sx[j] - sx[i], dsy = sy[j] - sy[i];
    dsx -= RoundNearest(dsx);
    dsy -= RoundNearest(dsy);
    const double dx = h00 * dsx + h01 * dsy, dy = h10 * dsx + h11 * dsy;
    const double reach = rad[i] + rad[j] + cutoff_skin;
    return dx * dx + dy * dy < reach * reach;
  };
  if (nbx >= 3 && nby >= 3) {
    const int nbins = nbx * nby;
    std::vector<int> bin_of(n);
    std::vector<std::uint32_t> bin_start(nbins + 1, 0), order(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double fx = p_.sx[i] - std::floor(p_.sx[i]);
      const double fy = p_.sy[i] - std::floor(p_.sy[i]);
      const int bx = std::min(static_cast<int>(fx * nbx), nbx - 1);
      const int by = std::min(static_cast<int>(fy * nby), nby - 1);
      bin_of[i] = by * nbx + bx;
      ++bin_start[bin_of[i] + 1];
    }
    for (int b = 0; b < nbins; ++b) bin_start[b + 1] += bin_start[b];
    std::vector<std::uint32_t> fill(bin_start.begin(), bin_start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) order[fill[bin_of[i]]++] = static_cast<std::uint32_t>(i);
    // Every candidate of the 9 bins is written and kept only if it is a
    // later particle within reach (about one in six is: a branch on that
    // would mispredict more often than the arithmetic costs).
    std::size_t kept = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      const int bx = bin_of[i] % nbx, by = bin_of[i] / nbx;
      int bins[9];
      std::size_t candidates = 0;
      for (int oy = -1, c = 0; oy <= 1; ++oy) {
        for (int ox = -1; ox <= 1; ++ox, ++c) {
          bins[c] = ((by + oy + nby) % nby) * nbx + (bx + ox + nbx) % nbx;
          candidates += bin_start[bins[c] + 1] - bin_start[bins[c]];
        }
      }
      if (pairs.size() < kept + candidates) pairs.resize(2 * (kept + candidates));
      std::uint64_t* __restrict out = pairs.data();
      for (const int b : bins) {
        for (std::uint32_t k = bin_start[b]; k < bin_start[b + 1]; ++k) {
          const std::uint32_t j = order[k];
          out[kept] = static_cast<std::uint64_t>(i) << 32 | j;
          kept += static_cast<std::size_t>((j > i) & within(i, j));
        }
      }
    }
    pairs.resize(kept);
  } else {
    for (std::uint32_t i = 0; i < n; ++i) {
      for (std::uint32_t j = i + 1; j < n; ++j) {
        if (within(i, j)) add(i, j);
      }
    }
  }
  // Bonded pairs stay listed whatever their distance.
  for (const ContactHistory& c : history) {
    if (c.bond_strength > 0) add(c.i, c.j);
  }

  const bool rolling = p_.material.rolling_beta > 0;
  const bool bonds = p_.material.bond_cohesion > 0 ||
                     std::any_of(history.begin(), history.end(),
                                 [](const ContactHistory& c) { return c.bond_strength > 0; });
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  row_start_.assign(n + 1, 0);
  nbr_i_.resize(pairs.size());
  nbr_j_.resize(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    nbr_i_[k] = static_cast<std::uint32_t>(pairs[k] >> 32);
    nbr_j_[k] = static_cast<std::uint32_t>(pairs[k]);
    ++row_start_[nbr_i_[k] + 1];
  }
  for (std::size_t i = 0; i < n; ++i) row_start_[i + 1] += row_start_[i];
  nbr_ft_.assign(nbr_j_.size(), 0.0);
  if (p_.material.model == ContactModel::kLinear) {
    nbr_kn_.resize(nbr_j_.size());
    for (std::uint32_t i = 0; i < n; ++i) {
      for (std::uint32_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
        nbr_kn_[k] =
            LinearNormalStiffness(p_.material.young_modulus, p_.radius[i], p_.radius[nbr_j_[k]]);
      }
    }
  }
  nbr_moment_.assign(rolling ? nbr_j_.size() : 0, 0.0);
  nbr_bond_.assign(bonds ? nbr_j_.size() : 0, 0.0);
  // Merge: both sequences are sorted by (i, j).
  for (const ContactHistory& c : history) {
    auto begin = nbr_j_.begin() + row_start_[c.i], end = nbr_j_.begin() + row_start_[c.i + 1];
    auto it = std::lower_bound(begin, end, c.j);
    if (it == end || *it != c.j) continue;  // out of reach: not in contact, no history
    const std::size_t k = it - nbr_j_.begin();
    nbr_ft_[k] = c.tangential_force;
    if (rolling) nbr_moment_[k] = c.rolling_moment;
    if (bonds) nbr_bond_[k] = c.bond_strength;
  }
  cell_at_build_ = p_.cell;
  displacement_bound_ = 0.0;
}

void Rve::MaybeRebuild() {
  // A pair not listed was at least r_i + r_j + skin apart at the rebuild; it
  // can touch only once the cell's stretch and the particles' own motion
  // have eaten the skin.
  const auto [smin, smax] = SingularValues(p_.cell * cell_at_build_.inverse());
  const double skin = p_.controls.skin * radius_min_;
  const double eaten =
      2.0 * 1.25 * displacement_bound_ + std::max(0.0, 1.0 - smin) * 2.0 * radius_max_;
  if (eaten >= smin * skin || smax > 1.1) Rebuild(CollectHistory());
}

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

void Rve::ApplyRigidRotation(double angle) {
  if (angle == 0.0) return;
  const Eigen::Matrix2d r = Rotation(angle);
  // The contact forces turn with the packing (the next step integrates
  // with them); the homogenised sums are measured again by that step.
  sums_valid_ = false;
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

namespace {

// What the pair pass reads and writes: particle and pair arrays, the cell
// h (m), the velocity gradient l (1/s) and the material.
struct PairPassArgs {
  const double* rad;  // m
  const double* sx;   // reduced coordinates
  const double* sy;
  const double* vx;  // m/s
  const double* vy;
  const double* om;             // rad/s
  const std::uint32_t* pair_i;  // pair k = (pair_i[k], pair_j[k]), i < j
  const std::uint32_t* pair_j;
  const double* kn;  // N/m, linear model's E·r* per pair
  double* ft;        // N, tangential history per pair
  double* moment;    // N·m, rolling history per pair
  double* bond;      // N, bond strength per pair (0: none)
  Scratch* out;
  double h00, h01, h10, h11, l00, l01, l10, l11;
  double dt;  // s
  const Material* mat;
};

// The contact law of every listed pair k ∈ [0, m): force on i −fn·n + ft·t
// (N) and the torques on i and j (N·m) into out->fx, fy, ti, tj, all 0 for a
// pair not in contact; kUpdate advances the history first (tangential spring
// by kt·v_t·Δt with the relative velocity of the affine motion l and of the
// particles, Coulomb cap, rolling spring, bond breakage) as the end of a DEM
// step does; without it the stored history is only read, so a recomputation
// gives the forces of the state bit for bit. kMeasure (0 none, 1 the servo's
// stress and stiffness, 2 the homogenisation sums) also stores each pair's
// terms for those sums. The pairs are independent: the loop runs in SIMD
// lanes (an AVX2 clone where the CPU has it) with selects for every branch,
// each lane doing the scalar operations in the scalar order, so the bits do
// not depend on the lane count or the CPU.
template <bool kRolling, bool kBonds, bool kHertz, int kMeasure, bool kUpdate>
__attribute__((target_clones("avx2", "default"))) void PairPass(const PairPassArgs& a,
                                                                std::size_t m) {
  const double h00 = a.h00, h01 = a.h01, h10 = a.h10, h11 = a.h11;
  const double l00 = a.l00, l01 = a.l01, l10 = a.l10, l11 = a.l11, dt = a.dt;
  const Material& mat = *a.mat;
  const double young = mat.young_modulus, poisson = mat.poisson_ratio;
  const double kt_ratio = mat.stiffness_ratio, mu = mat.friction;
  const double beta = mat.rolling_beta, eta = mat.rolling_eta;
  const double* __restrict rad = a.rad;
  const double* __restrict sx = a.sx;
  const double* __restrict sy = a.sy;
  const double* __restrict vx = a.vx;
  const double* __restrict vy = a.vy;
  const double* __restrict om = a.om;
  const std::uint32_t* __restrict pair_i = a.pair_i;
  const std::uint32_t* __restrict pair_j = a.pair_j;
  const double* __restrict nbr_kn = a.kn;
  double* __restrict nbr_ft = a.ft;
  double* __restrict nbr_moment = a.moment;
  double* __restrict nbr_bond = a.bond;
  double* __restrict o_fx = a.out->fx.data();
  double* __restrict o_fy = a.out->fy.data();
  double* __restrict o_ti = a.out->ti.data();
  double* __restrict o_tj = a.out->tj.data();
  double* __restrict o_t0 = a.out->term[0].data();
  double* __restrict o_t1 = a.out->term[1].data();
  double* __restrict o_t2 = a.out->term[2].data();
  double* __restrict o_t3 = a.out->term[3].data();
  double* __restrict o_t4 = a.out->term[4].data();
  double* __restrict o_t5 = a.out->term[5].data();
  double* __restrict o_el = a.out->elastic.data();
  double* __restrict o_act = a.out->active.data();
#pragma omp simd
  for (std::size_t k = 0; k < m; ++k) {
    const std::uint32_t i = pair_i[k], j = pair_j[k];
    double dsx = sx[j] - sx[i], dsy = sy[j] - sy[i];
    dsx -= RoundNearest(dsx);
    dsy -= RoundNearest(dsy);
    const double dx = h00 * dsx + h01 * dsy;  // branch vector i → j, m
    const double dy = h10 * dsx + h11 * dsy;
    const double ri = rad[i], rj = rad[j], rsum = ri + rj;
    const double d2 = dx * dx + dy * dy;
    const double bond = kBonds ? nbr_bond[k] : 0.0;
    bool bonded = kBonds && bond > 0;
    const bool touching = !(d2 >= rsum * rsum) || bonded;
    const double dist = std::sqrt(d2);
    const double inv = 1.0 / dist;
    const double nx = dx * inv, ny = dy * inv, tx = -ny, ty = nx;
    const double overlap = rsum - dist;  // m; < 0 only for a stretched bond
    double fn, kn, kt, elastic;
    if constexpr (kHertz) {
      const HertzResponse hz = HertzMindlin(young, poisson, ri, rj, overlap);
      fn = hz.fn;
      kn = hz.kn;
      kt = hz.kt;
      elastic = 0.4 * fn * overlap;  // ∫ fn dδ = (2/5) fn δ
    } else {
      kn = nbr_kn[k];  // E·r*, cached per pair at the rebuild
      kt = kt_ratio * kn;
      fn = kn * overlap;
      elastic = 0.5 * fn * overlap;
    }
    // Lever arms to the common contact point make a rigid motion of the
    // pair produce no relative tangential velocity.
    const double li = ri - 0.5 * overlap, lj = rj - 0.5 * overlap;
    double ft = nbr_ft[k];
    double moment = 0.0;
    bool gone = false;  // a broken bond's pair out of contact: no force
    if constexpr (kUpdate) {
      const double vrx = vx[j] - vx[i] + l00 * dx + l01 * dy;
      const double vry = vy[j] - vy[i] + l10 * dx + l11 * dy;
      const double vt = vrx * tx + vry * ty - (om[i] * li + om[j] * lj);
      ft += kt * vt * dt;
      if constexpr (kBonds) {
        const bool broken = bonded && (-fn > bond || std::abs(ft) > bond);
        nbr_bond[k] = broken ? 0.0 : bond;  // broken: purely frictional from now on
        bonded = bonded && !broken;
        gone = !bonded && overlap <= 0.0;
      }
      ft = bonded ? ft : CoulombCap(ft, fn, mu);
      if constexpr (kRolling) {
        const double kr = RollingStiffness(kt, ri, rj, beta);
        const double limit = RollingLimit(eta, ri, rj, fn);
        moment = std::clamp(nbr_moment[k] - kr * (om[i] - om[j]) * dt, -limit, limit);
      }
    } else {
      // The stored history as the last update left it. Capping again
      // changes nothing there (ft and M are already within the limits of
      // these very positions) and keeps a history from elsewhere (an
      // imported packing) physical.
      if constexpr (kBonds) gone = !bonded && overlap <= 0.0;
      ft = bonded ? ft : CoulombCap(ft, fn, mu);
      if constexpr (kRolling) {
        const double limit = RollingLimit(eta, ri, rj, fn);
        moment = std::clamp(nbr_moment[k], -limit, limit);
      }
    }
    const bool active = touching && !gone;
    if constexpr (kUpdate) {
      nbr_ft[k] = active ? ft : 0.0;
      if constexpr (kRolling) nbr_moment[k] = active ? moment : 0.0;
    }
    const double fcx = -fn * nx + ft * tx;  // force on i, N
    const double fcy = -fn * ny + ft * ty;
    o_fx[k] = active ? fcx : 0.0;
    o_fy[k] = active ? fcy : 0.0;
    o_ti[k] = active ? li * ft + moment : 0.0;
    o_tj[k] = active ? lj * ft - moment : 0.0;
    if constexpr (kMeasure != 0) {
      if constexpr (kMeasure == 1) {  // Σ f⊗b and the servo's Σ kn |b|² n_x⁴, n_y⁴
        const double kd2 = kn * d2;
        o_t0[k] = active ? fcx * dx : 0.0;
        o_t1[k] = active ? fcx * dy : 0.0;
        o_t2[k] = active ? fcy * dx : 0.0;
        o_t3[k] = active ? fcy * dy : 0.0;
        o_t4[k] = active ? kd2 * (nx * nx) * (nx * nx) : 0.0;
        o_t5[k] = active ? kd2 * (ny * ny) * (ny * ny) : 0.0;
      } else {  // sym Σ f⊗b (xy twice), Σ n⊗n (xx, xy) and Σ |f|
        o_t0[k] = active ? fcx * dx : 0.0;
        o_t1[k] = active ? fcx * dy + fcy * dx : 0.0;
        o_t2[k] = active ? fcy * dy : 0.0;
        o_t3[k] = active ? nx * nx : 0.0;
        o_t4[k] = active ? nx * ny : 0.0;
        o_t5[k] = active ? std::sqrt(fcx * fcx + fcy * fcy) : 0.0;
      }
      o_el[k] = touching ? elastic : 0.0;  // counted before a bond breaks, as always
      o_act[k] = active ? 1.0 : 0.0;
    }
  }
}

}  // namespace

// The contact pass: the pair pass above, then the forces and torques summed
// per particle into fx_, fy_, tq_ (N, N·m) in pair order, then (kMeasure)
// the sums, again in pair order. A pair not in contact adds +0, which
// changes no sum (none is ever −0), so the bits are those of one loop that
// skips such pairs. kServo sums the stress and the servo stiffness of the
// step (StepResult); kSums the homogenisation sums (sums_). Both measure the
// elastic energy (last_elastic_).
template <bool kRolling, bool kBonds, bool kHertz, Rve::Measure kMeasure, bool kUpdate>
Rve::StepResult Rve::ContactLoop(const Eigen::Matrix2d& l) {
  const std::size_t n = p_.radius.size();
  const std::size_t m = nbr_j_.size();
  constexpr bool kAny = kMeasure != Measure::kNone;
  constexpr bool kServo = kMeasure == Measure::kServo, kSums = kMeasure == Measure::kSums;
  Scratch& scratch = ThreadScratch();
  for (std::vector<double>* v : {&scratch.fx, &scratch.fy, &scratch.ti, &scratch.tj}) {
    if (v->size() < m) v->resize(m);
  }
  if constexpr (kAny) {
    for (std::vector<double>* v :
         {&scratch.elastic, &scratch.active, &scratch.term[0], &scratch.term[1], &scratch.term[2],
          &scratch.term[3], &scratch.term[4], &scratch.term[5]}) {
      if (v->size() < m) v->resize(m);
    }
  }
  const PairPassArgs args{p_.radius.data(),
                          p_.sx.data(),
                          p_.sy.data(),
                          p_.vx.data(),
                          p_.vy.data(),
                          p_.omega.data(),
                          nbr_i_.data(),
                          nbr_j_.data(),
                          nbr_kn_.data(),
                          nbr_ft_.data(),
                          nbr_moment_.data(),
                          nbr_bond_.data(),
                          &scratch,
                          p_.cell(0, 0),
                          p_.cell(0, 1),
                          p_.cell(1, 0),
                          p_.cell(1, 1),
                          l(0, 0),
                          l(0, 1),
                          l(1, 0),
                          l(1, 1),
                          dt_,
                          &p_.material};
  PairPass<kRolling, kBonds, kHertz, static_cast<int>(kMeasure), kUpdate>(args, m);

  // Forces and torques per particle, in the order of one loop over rows i:
  // row i's own pairs summed apart and added last.
  fx_.assign(n, 0.0);
  fy_.assign(n, 0.0);
  tq_.assign(n, 0.0);
  double* __restrict fx = fx_.data();
  double* __restrict fy = fy_.data();
  double* __restrict tq = tq_.data();
  const double* __restrict c_fx = scratch.fx.data();
  const double* __restrict c_fy = scratch.fy.data();
  const double* __restrict c_ti = scratch.ti.data();
  const double* __restrict c_tj = scratch.tj.data();
  const std::uint32_t* __restrict row_start = row_start_.data();
  const std::uint32_t* __restrict nbr_j = nbr_j_.data();
  for (std::uint32_t i = 0; i < n; ++i) {
    double fxi = 0, fyi = 0, tqi = 0;
    const std::uint32_t row_end = row_start[i + 1];
    for (std::uint32_t k = row_start[i]; k < row_end; ++k) {
      const std::uint32_t j = nbr_j[k];
      fxi += c_fx[k];
      fyi += c_fy[k];
      fx[j] -= c_fx[k];
      fy[j] -= c_fy[k];
      tqi += c_ti[k];
      tq[j] += c_tj[k];
    }
    fx[i] += fxi;
    fy[i] += fyi;
    tq[i] += tqi;
  }
  forces_valid_ = true;

  const double volume = p_.cell.determinant() * p_.material.thickness;
  StepResult out;
  if constexpr (kAny) {
    // The six sums, each in pair order.
    double sum[6] = {0, 0, 0, 0, 0, 0};
    const double* __restrict t0 = scratch.term[0].data();
    const double* __restrict t1 = scratch.term[1].data();
    const double* __restrict t2 = scratch.term[2].data();
    const double* __restrict t3 = scratch.term[3].data();
    const double* __restrict t4 = scratch.term[4].data();
    const double* __restrict t5 = scratch.term[5].data();
    for (std::size_t k = 0; k < m; ++k) {
      sum[0] += t0[k];
      sum[1] += t1[k];
      sum[2] += t2[k];
      sum[3] += t3[k];
      sum[4] += t4[k];
      sum[5] += t5[k];
    }
    if (kServo || track_energy_) {
      double elastic = 0;
      for (std::size_t k = 0; k < m; ++k) elastic += scratch.elastic[k];
      last_elastic_ = elastic;
    } else {
      last_elastic_ = 0.0;
    }
    if constexpr (kServo) {
      out.stress << sum[0] / volume, sum[1] / volume, sum[2] / volume, sum[3] / volume;
      out.stiffness = Eigen::Vector2d(sum[4], sum[5]) / volume;
      sums_valid_ = false;
    }
    if constexpr (kSums) {
      // Contacts per particle: integer counts, exact in any order.
      scratch.count.assign(n, 0.0);
      double* __restrict count = scratch.count.data();
      const double* __restrict c_act = scratch.active.data();
      const std::uint32_t* __restrict nbr_i = nbr_i_.data();
      double nc = 0;
      for (std::size_t k = 0; k < m; ++k) {
        count[nbr_i[k]] += c_act[k];
        count[nbr_j[k]] += c_act[k];
        nc += c_act[k];
      }
      Sums& s = sums_;
      s.stress << sum[0], 0.5 * sum[1], 0.5 * sum[1], sum[2];  // symmetric part of Σ f⊗b
      s.fabric << sum[3], sum[4], sum[4], nc - sum[3];
      s.force_sum = sum[5];
      s.num_contacts = static_cast<std::int64_t>(nc);
      s.rattlers0 = s.rattlers1 = 0;
      for (std::size_t i = 0; i < n; ++i) {
        s.rattlers0 += count[i] == 0.0;
        s.rattlers1 += count[i] == 1.0;
      }
      sums_valid_ = true;
    }
  } else {
    sums_valid_ = false;
  }
  return out;
}

Rve::StepResult Rve::Forces(const Eigen::Matrix2d& l, Measure measure, bool update) {
  const bool rolling = !nbr_moment_.empty(), bonds = !nbr_bond_.empty();
  const bool hertz = p_.material.model == ContactModel::kHertzMindlin;
  // One instantiation per feature set keeps unused features out of the loop;
  // a pass that only reads the history always measures (it serves Observe).
  auto pick = [&]<Measure kMeasure, bool kUpdate>() {
    if (hertz) {
      return rolling ? ContactLoop<true, false, true, kMeasure, kUpdate>(l)
                     : ContactLoop<false, false, true, kMeasure, kUpdate>(l);
    }
    if (rolling) {
      return bonds ? ContactLoop<true, true, false, kMeasure, kUpdate>(l)
                   : ContactLoop<true, false, false, kMeasure, kUpdate>(l);
    }
    return bonds ? ContactLoop<false, true, false, kMeasure, kUpdate>(l)
                 : ContactLoop<false, false, false, kMeasure, kUpdate>(l);
  };
  if (!update) return pick.template operator()<Measure::kSums, false>();
  switch (measure) {
    case Measure::kServo:
      return pick.template operator()<Measure::kServo, true>();
    case Measure::kSums:
      return pick.template operator()<Measure::kSums, true>();
    case Measure::kNone:
      break;
  }
  return pick.template operator()<Measure::kNone, true>();
}

namespace {

// The arrays one leapfrog step reads and writes, one entry per particle.
struct ParticleArrays {
  std::size_t n;
  const double* rad;          // m
  const double* fx;           // N
  const double* fy;           // N
  const double* tq;           // N·m
  const double* inv_mass;     // 1/kg
  const double* inv_inertia;  // 1/(kg m²)
  double* vx;                 // m/s
  double* vy;                 // m/s
  double* om;                 // rad/s
  double* sx;                 // reduced coordinates
  double* sy;
  double* th;  // rad
};

// Leapfrog with local non-viscous damping acting in the frame q (the cell's
// axes). Returns max |v|² (m²/s²). kMeasure adds the kinetic energy ×2 (J)
// at the force time into *kinetic2, in particle order. Each particle's
// update is independent, so without kMeasure the loop runs in SIMD lanes
// with the scalar operations' bits (a max needs no order).
template <bool kRotated, bool kMeasure>
__attribute__((target_clones("avx2", "default"))) double Leapfrog(
    const ParticleArrays& a, double dt, double alpha, const Eigen::Matrix2d& q,
    const Eigen::Matrix2d& hinv, double mass_per_r2, double* kinetic2) {
  const double q00 = q(0, 0), q01 = q(0, 1), q10 = q(1, 0), q11 = q(1, 1);
  const double i00 = hinv(0, 0), i01 = hinv(0, 1), i10 = hinv(1, 0), i11 = hinv(1, 1);
  const std::size_t n = a.n;
  const double* __restrict rad = a.rad;
  const double* __restrict ffx = a.fx;
  const double* __restrict ffy = a.fy;
  const double* __restrict ftq = a.tq;
  const double* __restrict inv_mass = a.inv_mass;
  const double* __restrict inv_inertia = a.inv_inertia;
  double* __restrict wvx = a.vx;
  double* __restrict wvy = a.vy;
  double* __restrict wom = a.om;
  double* __restrict wsx = a.sx;
  double* __restrict wsy = a.sy;
  double* __restrict wth = a.th;
  double vmax2 = 0.0;
  double k2 = 0.0;
#pragma omp simd reduction(max : vmax2) if (!kMeasure)
  for (std::size_t i = 0; i < n; ++i) {
    const double fx = ffx[i], fy = ffy[i], tq = ftq[i], vx = wvx[i], vy = wvy[i], om = wom[i];
    double ax, ay;
    if constexpr (!kRotated) {
      ax = (fx + Damping(alpha, fx, vx)) * inv_mass[i];
      ay = (fy + Damping(alpha, fy, vy)) * inv_mass[i];
    } else {
      const double lfx = q00 * fx + q10 * fy, lfy = q01 * fx + q11 * fy;
      const double lvx = q00 * vx + q10 * vy, lvy = q01 * vx + q11 * vy;
      const double dfx = Damping(alpha, lfx, lvx), dfy = Damping(alpha, lfy, lvy);
      ax = (fx + q00 * dfx + q01 * dfy) * inv_mass[i];
      ay = (fy + q10 * dfx + q11 * dfy) * inv_mass[i];
    }
    const double aw = (tq + Damping(alpha, tq, om)) * inv_inertia[i];
    if constexpr (kMeasure) {
      // Velocities at the force time (mean of the two half steps) for the energy;
      // m = c·r², I = ½ m r²: multiplications instead of dividing by 1/m.
      const double ux = vx + 0.5 * dt * ax, uy = vy + 0.5 * dt * ay, uw = om + 0.5 * dt * aw;
      const double r2 = rad[i] * rad[i];
      k2 += mass_per_r2 * r2 * (ux * ux + uy * uy + 0.5 * r2 * uw * uw);
    }
    const double nvx = vx + dt * ax, nvy = vy + dt * ay, nom = om + dt * aw;
    wvx[i] = nvx;
    wvy[i] = nvy;
    wom[i] = nom;
    wth[i] += dt * nom;
    const double dxr = dt * nvx, dyr = dt * nvy;
    wsx[i] += i00 * dxr + i01 * dyr;
    wsy[i] += i10 * dxr + i11 * dyr;
    const double v2 = nvx * nvx + nvy * nvy;
    vmax2 = v2 > vmax2 ? v2 : vmax2;
  }
  if constexpr (kMeasure) *kinetic2 = k2;
  return vmax2;
}

}  // namespace

// Leapfrog with local non-viscous damping, acting in the cell's frame, with
// the forces of the current positions (fx_, fy_, tq_).
void Rve::Integrate() {
  const Material& mat = p_.material;
  const ParticleArrays a{p_.radius.size(), p_.radius.data(), fx_.data(),          fy_.data(),
                         tq_.data(),       inv_mass_.data(), inv_inertia_.data(), p_.vx.data(),
                         p_.vy.data(),     p_.omega.data(),  p_.sx.data(),        p_.sy.data(),
                         p_.theta.data()};
  const double mass_per_r2 = mat.density * kPi * mat.thickness * p_.controls.mass_scale;  // kg/m²
  const Eigen::Matrix2d& q = p_.frame;
  const Eigen::Matrix2d hinv = p_.cell.inverse();
  const bool rotated = q != Eigen::Matrix2d::Identity();
  double kinetic2 = 0.0, vmax2;
  if (track_energy_) {
    vmax2 = rotated ? Leapfrog<true, true>(a, dt_, mat.damping, q, hinv, mass_per_r2, &kinetic2)
                    : Leapfrog<false, true>(a, dt_, mat.damping, q, hinv, mass_per_r2, &kinetic2);
    energy_ = {0.5 * kinetic2, last_elastic_};
  } else {
    vmax2 = rotated ? Leapfrog<true, false>(a, dt_, mat.damping, q, hinv, mass_per_r2, nullptr)
                    : Leapfrog<false, false>(a, dt_, mat.damping, q, hinv, mass_per_r2, nullptr);
  }
  displacement_bound_ += std::sqrt(vmax2) * dt_;
}

Rve::StepResult Rve::Step(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell,
                          bool measure) {
  const StepResult r =
      Forces(l, measure || track_energy_ ? Measure::kServo : Measure::kNone, /*update=*/true);
  Integrate();
  AdvanceCell(next_cell);
  forces_valid_ = sums_valid_ = false;  // they were those of the old positions
  return r;
}

Rve::StepResult Rve::StepForcesLast(const Eigen::Matrix2d& l, const Eigen::Matrix2d& next_cell,
                                    bool measure) {
  // The forces of the current positions: those the last step left, or (after
  // a restore, a Run or a change of the contacts) recomputed from the state.
  if (!forces_valid_ || (track_energy_ && !sums_valid_)) Forces(l, Measure::kSums, false);
  Integrate();
  AdvanceCell(next_cell);
  // The new positions' forces, with the history advanced by this step's
  // motion: the next step integrates with them and, measured, they are the
  // homogenised state of the new configuration.
  return Forces(l, measure || track_energy_ ? Measure::kSums : Measure::kNone, /*update=*/true);
}

void Rve::AdvanceCell(const Eigen::Matrix2d& next_cell) {
  p_.cell = next_cell;
  ++p_.total_steps;
  MaybeFlip();
  MaybeRebuild();
}

double Rve::QuasiStaticStrainRate(double inertial_number, double pressure) const {
  const double p = std::max(pressure, p_.controls.pressure_floor);
  const double rho = p_.material.density * p_.controls.mass_scale;
  return inertial_number / (2.0 * radius_mean_ * std::sqrt(rho / p));  // I = γ̇ d sqrt(ρ/p)
}

absl::Status ValidateDeltaF(const Eigen::Matrix3d& delta_f) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(delta_f(r, c))) {
        return absl::InvalidArgumentError(
            absl::StrCat("ΔF(", r, ",", c, ") = ", delta_f(r, c), " is not finite"));
      }
    }
  }
  constexpr double kPlaneTol = 1e-12;
  if (std::abs(delta_f(2, 2) - 1.0) > kPlaneTol || std::abs(delta_f(0, 2)) > kPlaneTol ||
      std::abs(delta_f(1, 2)) > kPlaneTol || std::abs(delta_f(2, 0)) > kPlaneTol ||
      std::abs(delta_f(2, 1)) > kPlaneTol) {
    return absl::InvalidArgumentError(
        "ΔF must be plane strain for a 2-D RVE: ΔF_zz = 1 and no out-of-plane coupling");
  }
  const double det = delta_f.topLeftCorner<2, 2>().determinant();
  if (!(det > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("det ΔF = ", det, " must be > 0"));
  }
  return absl::OkStatus();
}

absl::Status Validate(const ApplyOptions& o) {
  if (!(o.relax_tolerance >= kMinRelaxTolerance && o.relax_tolerance <= 1)) {
    return absl::InvalidArgumentError(absl::StrCat("relax_tolerance = ", o.relax_tolerance,
                                                   " is invalid: must lie in [", kMinRelaxTolerance,
                                                   ", 1]"));
  }
  if (o.relax_max_steps < 0 || o.relax_max_steps > kMaxRelaxSteps) {
    return absl::InvalidArgumentError(absl::StrCat("relax_max_steps = ", o.relax_max_steps,
                                                   " is invalid: must lie in [0, ", kMaxRelaxSteps,
                                                   "]"));
  }
  if (!(o.max_inertial_number == 0 || (o.max_inertial_number >= kMinInertialNumber &&
                                       o.max_inertial_number <= kMaxInertialNumber))) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_inertial_number = ", o.max_inertial_number, " is invalid: must be 0 or lie in [",
        kMinInertialNumber, ", ", kMaxInertialNumber, "]"));
  }
  return absl::OkStatus();
}

absl::StatusOr<RveState> Rve::Apply(const Eigen::Matrix3d& delta_f, const ApplyOptions& options,
                                    const Interrupt& interrupt) {
  if (absl::Status valid = ValidateDeltaF(delta_f); !valid.ok()) return valid;
  if (absl::Status valid = Validate(options); !valid.ok()) return valid;
  const Eigen::Matrix2d f = delta_f.topLeftCorner<2, 2>();
  // Polar split ΔF = V·R: rotate rigidly (exact, objective), then stretch.
  const double angle = std::atan2(f(1, 0) - f(0, 1), f(0, 0) + f(1, 1));
  const Eigen::Matrix2d v = f * Rotation(angle).transpose();
  const double stretch = (v - Eigen::Matrix2d::Identity()).norm();
  if (std::abs(angle) > p_.controls.max_rotation) {
    return absl::InvalidArgumentError(absl::StrCat("rotation of ΔF ", angle,
                                                   " rad exceeds the per-call limit ",
                                                   p_.controls.max_rotation, " rad"));
  }
  if (stretch > p_.controls.max_stretch) {
    return absl::InvalidArgumentError(absl::StrCat("stretch |V − I| = ", stretch,
                                                   " of ΔF exceeds the per-call limit ",
                                                   p_.controls.max_stretch));
  }
  if (CellHeights(f * p_.cell).minCoeff() <= 2.0 * Cutoff()) {
    return absl::FailedPreconditionError(
        "ΔF would make the periodic cell thinner than twice the pair cutoff");
  }
  if (!(GridCells(CellHeights(f * p_.cell), Cutoff()) <= MaxGridCells(p_.radius.size()))) {
    return absl::FailedPreconditionError(
        "ΔF would make the periodic cell too large for its particles (neighbour-grid limit)");
  }

  // p before the rotation (which leaves it unchanged): after an increment
  // it is known from that increment's last step.
  const double pressure = MeanPressure();
  const double inertial_number =
      options.max_inertial_number > 0
          ? std::min(options.max_inertial_number, p_.controls.max_inertial_number)
          : p_.controls.max_inertial_number;
  const double rate = QuasiStaticStrainRate(inertial_number, pressure);
  const double steps_needed = std::ceil(stretch / (rate * dt_));
  // Sized before anything changes (the cast below needs it in range, too).
  if (!(steps_needed <= static_cast<double>(kMaxStepsPerApply))) {
    return absl::InvalidArgumentError(absl::StrCat("the increment would take ", steps_needed,
                                                   " DEM steps at inertial number ",
                                                   inertial_number, "; at most ", kMaxStepsPerApply,
                                                   " per call: split ΔF into smaller increments"));
  }
  // Only a long call can be interrupted, and only a long call pays for the
  // copy that undoes it (a short one ends soon anyway).
  std::optional<Rve> before;
  const std::int64_t planned =
      std::max<std::int64_t>(p_.controls.min_steps, static_cast<std::int64_t>(steps_needed));
  if (interrupt && (planned > kInterruptCheckSteps || options.relax)) before.emplace(*this);
  ApplyRigidRotation(angle);
  Eigen::Matrix2d start = p_.cell;
  const Eigen::Matrix2d identity = Eigen::Matrix2d::Identity();
  const std::int64_t steps = planned;
  for (std::int64_t k = 0; k < steps; ++k) {
    if (before && k > 0 && k % kInterruptCheckSteps == 0) {
      if (absl::Status stop = interrupt(); !stop.ok()) {
        *this = *std::move(before);
        return stop;
      }
    }
    const double tau = static_cast<double>(k + 1) / static_cast<double>(steps);
    const Eigen::Matrix2d next = (identity + (v - identity) * tau) * start;
    const Eigen::Matrix2d l = (next - p_.cell) * p_.cell.inverse() / dt_;
    StepForcesLast(l, next, /*measure=*/k + 1 == steps);  // the last step homogenises
    // A flip in Step changed the lattice basis: follow it (h' = h·U, U integer).
    if (p_.cell != next) start = start * (next.inverse() * p_.cell).array().round().matrix();
  }
  std::int64_t used = steps;
  if (options.relax) {
    absl::Status stopped;
    used += RelaxSteps(options.relax_tolerance, options.relax_max_steps,
                       before ? &interrupt : nullptr, stopped)
                .steps;
    if (!stopped.ok()) {
      *this = *std::move(before);
      return stopped;
    }
  }
  RveState s = Observe(options.want_tangent);
  s.steps = used;
  return s;
}

RveState Rve::Run(CellControl& control, std::int64_t steps) {
  absl::Status stopped;
  return RunSteps(control, steps, nullptr, stopped);
}

absl::StatusOr<RveState> Rve::Run(CellControl& control, std::int64_t steps,
                                  const Interrupt& interrupt) {
  absl::Status stopped;
  RveState s = RunSteps(control, steps, interrupt ? &interrupt : nullptr, stopped);
  if (!stopped.ok()) return stopped;
  return s;
}

RveState Rve::RunSteps(CellControl& control, std::int64_t steps, const Interrupt* interrupt,
                       absl::Status& stopped) {
  Eigen::Matrix2d stress = DefinitionStress();
  Eigen::Vector2d stiffness = Eigen::Vector2d::Zero();
  const double cap = control.max_strain_rate;
  // PI servo on the strain rate: Δσ ≈ K·L·Δt, so gain·gap/(K·Δt) closes a
  // fraction `gain` of the stress gap per step; the integral removes the
  // steady-state error while the stress keeps being pushed (e.g. dilation).
  auto servo = [&](const ComponentControl& c, double sigma, double k, double& integral) {
    if (c.mode == ControlMode::kStrainRate) return c.value;
    const double gap = c.value - sigma;
    double p_term = k > 0 ? control.servo_gain * gap / (k * dt_) : Sign(gap) * cap;
    p_term = std::clamp(p_term, -cap, cap);
    if (control.servo_integral_steps <= 0) return p_term;
    integral = std::clamp(integral + p_term / control.servo_integral_steps, -cap, cap);
    return std::clamp(p_term + integral, -cap, cap);
  };
  Eigen::Vector3d& integral = control.servo_integral;
  // The step measures stress and stiffness only when a servo needs them.
  const bool servo_on = control.xx.mode == ControlMode::kStress ||
                        control.yy.mode == ControlMode::kStress ||
                        control.xy.mode == ControlMode::kStress;
  for (std::int64_t k = 0; k < steps; ++k) {
    if (interrupt != nullptr && k > 0 && k % kInterruptCheckSteps == 0) {
      stopped = (*interrupt)();
      if (!stopped.ok()) return RveState{};
    }
    Eigen::Matrix2d l = Eigen::Matrix2d::Zero();
    l(0, 0) = servo(control.xx, stress(0, 0), stiffness.x(), integral[0]);
    l(1, 1) = servo(control.yy, stress(1, 1), stiffness.y(), integral[1]);
    l(0, 1) =
        servo(control.xy, 0.5 * (stress(0, 1) + stress(1, 0)), 0.25 * stiffness.sum(), integral[2]);
    const Eigen::Matrix2d next = p_.cell + dt_ * l * p_.cell;
    const StepResult r = Step(l, next, servo_on);
    stress = r.stress;
    stiffness = r.stiffness;
  }
  RveState s = Observe();
  s.steps = steps;
  return s;
}

RveState Rve::Relax(double tolerance, std::int64_t max_steps) {
  absl::Status stopped;
  return RelaxSteps(tolerance, max_steps, nullptr, stopped);
}

absl::StatusOr<RveState> Rve::Relax(double tolerance, std::int64_t max_steps,
                                    const Interrupt& interrupt) {
  absl::Status stopped;
  RveState s = RelaxSteps(tolerance, max_steps, interrupt ? &interrupt : nullptr, stopped);
  if (!stopped.ok()) return stopped;
  return s;
}

RveState Rve::RelaxSteps(double tolerance, std::int64_t max_steps, const Interrupt* interrupt,
                         absl::Status& stopped) {
  constexpr std::int64_t kCheckEvery = 50;
  std::int64_t done = 0;
  std::int64_t since_asked = 0;  // steps since `interrupt` was last asked
  RveState s = Observe();
  while (done < max_steps && !(s.unbalanced_force_ratio < tolerance && s.num_contacts > 0)) {
    if (interrupt != nullptr && since_asked >= kInterruptCheckSteps) {
      since_asked = 0;
      stopped = (*interrupt)();
      if (!stopped.ok()) return s;
    }
    const std::int64_t chunk = std::min(kCheckEvery, max_steps - done);
    since_asked += chunk;
    for (std::int64_t k = 0; k < chunk; ++k)
      Step(Eigen::Matrix2d::Zero(), p_.cell, /*measure=*/false);
    done += chunk;
    s = Observe();
  }
  s.steps = done;
  return s;
}

template <typename F>
void Rve::ForEachContact(F&& f) const {
  const std::size_t n = p_.radius.size();
  const Material& mat = p_.material;
  const bool bonds = !nbr_bond_.empty();
  ContactForce c;
  for (std::uint32_t i = 0; i < n; ++i) {
    for (std::uint32_t k = row_start_[i]; k < row_start_[i + 1]; ++k) {
      const std::uint32_t j = nbr_j_[k];
      c.branch = Branch(i, j);
      const double rsum = p_.radius[i] + p_.radius[j];
      c.bonded = bonds && nbr_bond_[k] > 0;
      const double dist = c.branch.norm();
      if (dist >= rsum && !c.bonded) continue;
      c.i = i;
      c.j = j;
      c.normal = c.branch / dist;
      c.overlap = rsum - dist;
      if (mat.model == ContactModel::kHertzMindlin) {
        const HertzResponse hz = HertzMindlin(mat.young_modulus, mat.poisson_ratio, p_.radius[i],
                                              p_.radius[j], c.overlap);
        c.normal_force = hz.fn;
        c.kn = hz.kn;
        c.kt = hz.kt;
      } else {
        c.kn = mat.young_modulus * EffectiveRadius(p_.radius[i], p_.radius[j]);
        c.kt = mat.stiffness_ratio * c.kn;
        c.normal_force = c.kn * c.overlap;
      }
      c.tangential_force = nbr_ft_[k];
      if constexpr (std::is_invocable_v<F, const ContactForce&, std::uint32_t>) {
        f(c, k);
      } else {
        f(c);
      }
    }
  }
}

void Rve::EnsureSums() const {
  // A pass that only reads the contact history: it fills the caches and
  // changes no state, so a const Rve may run it.
  if (!sums_valid_) {
    const_cast<Rve*>(this)->Forces(Eigen::Matrix2d::Zero(), Measure::kSums, /*update=*/false);
  }
}

double Rve::MeanPressure() const {
  EnsureSums();
  return -0.5 * (sums_.stress(0, 0) + sums_.stress(1, 1)) /
         (p_.cell.determinant() * p_.material.thickness);
}

Eigen::Matrix2d Rve::DefinitionStress() const {
  Eigen::Matrix2d sum = Eigen::Matrix2d::Zero();  // Σ f⊗b, N·m
  ForEachContact([&](const ContactForce& c) { sum += c.ForceOnI() * c.branch.transpose(); });
  return 0.5 * (sum + sum.transpose()) / (p_.cell.determinant() * p_.material.thickness);
}

std::vector<ContactForce> Rve::Contacts() const {
  std::vector<ContactForce> out;
  ForEachContact([&](const ContactForce& c) { out.push_back(c); });
  return out;
}

// The homogenised state from the sums of the last measured contact pass
// (the last DEM step of an increment, or a pass that only reads the history)
// and one pass over the particles. Love–Weber stress σ = (1/V) sym Σ f⊗b.
RveState Rve::Observe(bool want_tangent) const {
  EnsureSums();
  const std::size_t n = p_.radius.size();
  const Sums& m = sums_;
  const std::int64_t nc = m.num_contacts;
  RveState s;
  const Eigen::Matrix2d& h = p_.cell;
  const Material& mat = p_.material;
  const double area = h.determinant();
  s.volume = area * mat.thickness;
  const Eigen::Matrix2d sym = 0.5 * (m.stress + m.stress.transpose()) / s.volume;
  s.stress.topLeftCorner<2, 2>() = sym;
  s.num_contacts = nc;
  if (nc > 0) {
    s.fabric_defined = true;
    const Eigen::Matrix2d phi = m.fabric / static_cast<double>(nc);
    s.fabric.topLeftCorner<2, 2>() = phi;
    const Eigen::Matrix2d fa = 4.0 * (phi - 0.5 * Eigen::Matrix2d::Identity());
    s.fabric_anisotropy_tensor.topLeftCorner<2, 2>() = fa;
    s.fabric_anisotropy = std::sqrt(0.5 * fa.squaredNorm());
  }
  s.void_ratio = (area - solid_area_) / solid_area_;
  s.porosity = s.void_ratio / (1.0 + s.void_ratio);
  s.coordination = 2.0 * static_cast<double>(nc) / static_cast<double>(n);
  double resultant = 0, rotation = 0, kinetic = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // |Σ contact forces on i|; forces are far from overflow, so no hypot.
    resultant += std::sqrt(fx_[i] * fx_[i] + fy_[i] * fy_[i]);
    rotation += p_.theta[i];
    kinetic += (p_.vx[i] * p_.vx[i] + p_.vy[i] * p_.vy[i]) / inv_mass_[i] +
               p_.omega[i] * p_.omega[i] / inv_inertia_[i];
  }
  // Thornton's mechanical coordination: rattlers (0 or 1 contact) left out.
  const double n0 = static_cast<double>(m.rattlers0), n1 = static_cast<double>(m.rattlers1);
  const double active = static_cast<double>(n) - n0 - n1;
  s.mechanical_coordination = active > 0 ? (2.0 * static_cast<double>(nc) - n1) / active : 0.0;
  s.unbalanced_force_ratio =
      nc > 0 ? (resultant / static_cast<double>(n)) / (m.force_sum / static_cast<double>(nc)) : 0.0;
  s.mean_rotation = rotation / static_cast<double>(n);
  s.kinetic_energy = 0.5 * kinetic;
  const double e = std::max(s.void_ratio, 0.0);
  s.permeability = p_.permeability_coefficient * e * e * e / (1.0 + e);
  s.time_step = dt_;
  s.mass_scale = p_.controls.mass_scale;
  if (want_tangent) {
    // D_ijkl = (1/V)Σ(kn n_i b_j n_k b_l + kt t_i b_j t_k b_l): rarely asked
    // for (the MPM time step), so one pass of its own.
    double d[2][2][2][2] = {};
    ForEachContact([&](const ContactForce& c) {
      const Eigen::Vector2d& nn = c.normal;
      const Eigen::Vector2d t(-nn.y(), nn.x());
      const Eigen::Vector2d& br = c.branch;
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
          for (int e2 = 0; e2 < 2; ++e2)
            for (int g = 0; g < 2; ++g)
              d[a][b][e2][g] +=
                  c.kn * nn[a] * br[b] * nn[e2] * br[g] + c.kt * t[a] * br[b] * t[e2] * br[g];
    });
    s.has_tangent = true;
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b)
        for (int c = 0; c < 2; ++c)
          for (int e2 = 0; e2 < 2; ++e2)
            s.tangent(3 * a + b, 3 * c + e2) = d[a][b][c][e2] / s.volume;
  }
  return s;
}

absl::Status Rve::SetFriction(double friction) {
  if (!(friction >= 0) || !std::isfinite(friction)) {
    return absl::InvalidArgumentError(
        absl::StrCat("friction = ", friction, " is invalid: μ = tan φ must be >= 0"));
  }
  p_.material.friction = friction;
  forces_valid_ = sums_valid_ = false;
  ForEachContact([&](const ContactForce& c, std::uint32_t k) {
    if (!c.bonded) nbr_ft_[k] = CoulombCap(c.tangential_force, c.normal_force, friction);
  });
  return absl::OkStatus();
}

void Rve::BondContacts() {
  const double c = p_.material.bond_cohesion;
  if (c <= 0) return;
  if (nbr_bond_.size() != nbr_j_.size()) nbr_bond_.assign(nbr_j_.size(), 0.0);
  forces_valid_ = sums_valid_ = false;
  ForEachContact([&](const ContactForce& contact, std::uint32_t k) {
    if (contact.overlap > 0) {
      nbr_bond_[k] = BondStrength(c, p_.radius[contact.i], p_.radius[contact.j]);
    }
  });
}

}  // namespace rvehub::dem
