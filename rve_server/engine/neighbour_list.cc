// The neighbour list: cell-list search in reduced coordinates, the
// verlet-skin test that decides when to search again, and the contact
// history carried over from list to list.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "rve_server/engine/contact_law.h"
#include "rve_server/engine/rve.h"
#include "rve_server/engine/rve_internal.h"

namespace rvehub::dem {

using internal::CellHeights;
using internal::RoundNearest;
using internal::SingularValues;

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

  const bool rolling = HasRollingResistance(p_.material);
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

}  // namespace rvehub::dem
