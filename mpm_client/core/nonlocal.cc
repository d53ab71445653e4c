#include "mpm_client/core/nonlocal.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

namespace rvehub::mpm {

double NonlocalWeight(double r, double radius) {
  if (!(r < radius)) return 0.0;
  const double s = 1.0 - (r * r) / (radius * radius);
  return s * s;
}

NonlocalMap NonlocalMap::Build(std::span<const Eigen::Vector2d> position,
                               std::span<const double> volume, std::span<const std::uint8_t> active,
                               double radius, double thickness, double fraction) {
  const std::size_t n = position.size();
  NonlocalMap map;
  map.start_.assign(n + 1, 0);
  if (n == 0 || !(radius > 0.0)) return map;

  // Bins of side ℓ: a neighbour lies in the point's bin or one of the eight
  // around it. Key = bx·rows + by, so the three bins of one column are one
  // range of the sorted keys.
  Eigen::Vector2d lower = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d upper = -lower;
  for (std::size_t p = 0; p < n; ++p) {
    if (!active[p]) continue;
    lower = lower.cwiseMin(position[p]);
    upper = upper.cwiseMax(position[p]);
  }
  if (!(lower.x() <= upper.x())) return map;  // no active point
  const auto bin = [&](double x, double low) {
    return static_cast<std::int64_t>(std::floor((x - low) / radius));
  };
  const std::int64_t rows = bin(upper.y(), lower.y()) + 3;  // by + 1 stays in its column
  const auto key = [&](std::int64_t bx, std::int64_t by) { return bx * rows + by + 1; };
  std::vector<std::pair<std::int64_t, std::int32_t>> sorted;
  sorted.reserve(n);
  for (std::size_t p = 0; p < n; ++p) {
    if (!active[p]) continue;
    sorted.emplace_back(key(bin(position[p].x(), lower.x()), bin(position[p].y(), lower.y())),
                        static_cast<std::int32_t>(p));
  }
  std::sort(sorted.begin(), sorted.end());

  // Pairs within ℓ with their weights, and each point's Σ_q w_pq V_q.
  std::vector<double> weight, support(n, 0.0);
  for (std::size_t p = 0; p < n; ++p) {
    map.start_[p] = static_cast<std::int64_t>(map.neighbour_.size());
    if (!active[p]) continue;
    support[p] = volume[p];  // w_pp = 1
    const std::int64_t bx = bin(position[p].x(), lower.x());
    const std::int64_t by = bin(position[p].y(), lower.y());
    for (std::int64_t cx = bx - 1; cx <= bx + 1; ++cx) {
      const auto first = std::lower_bound(sorted.begin(), sorted.end(),
                                          std::make_pair(key(cx, by - 1), std::int32_t{-1}));
      const auto last =
          std::lower_bound(first, sorted.end(), std::make_pair(key(cx, by + 2), std::int32_t{-1}));
      for (auto it = first; it != last; ++it) {
        const std::int32_t q = it->second;
        if (static_cast<std::size_t>(q) == p) continue;
        const double w = NonlocalWeight((position[q] - position[p]).norm(), radius);
        if (!(w > 0.0)) continue;
        map.neighbour_.push_back(q);
        weight.push_back(w);
        support[p] += w * volume[q];
      }
    }
  }
  map.start_[n] = static_cast<std::int64_t>(map.neighbour_.size());

  double full = std::numbers::pi * radius * radius * thickness / 3.0;
  for (std::size_t p = 0; p < n; ++p) full = std::max(full, support[p]);
  map.coefficient_.resize(weight.size());
  for (std::size_t k = 0; k < weight.size(); ++k) {
    map.coefficient_[k] = fraction * weight[k] * volume[map.neighbour_[k]] / full;
  }
  return map;
}

void NonlocalMap::Apply(std::span<const double> in, std::span<double> out) const {
  for (std::size_t p = 0; p < in.size(); ++p) {
    double change = 0.0;
    if (p + 1 < start_.size()) {
      for (std::int64_t k = start_[p]; k < start_[p + 1]; ++k) {
        change += coefficient_[k] * (in[neighbour_[k]] - in[p]);
      }
    }
    out[p] = in[p] + change;
  }
}

std::span<const std::int32_t> NonlocalMap::Neighbours(std::size_t p) const {
  return std::span<const std::int32_t>(neighbour_).subspan(start_[p], start_[p + 1] - start_[p]);
}

std::span<const double> NonlocalMap::Coefficients(std::size_t p) const {
  return std::span<const double>(coefficient_).subspan(start_[p], start_[p + 1] - start_[p]);
}

namespace {

// The map applied to the components (xx, yy, xy) of symmetric 2 × 2 tensors.
std::vector<Eigen::Matrix2d> AverageSymmetric(const NonlocalMap& map,
                                              const std::vector<Eigen::Matrix2d>& tensor) {
  const std::size_t n = tensor.size();
  std::vector<double> in(n), out(n);
  std::vector<Eigen::Matrix2d> averaged(n, Eigen::Matrix2d::Zero());
  for (auto [i, j] : {std::pair{0, 0}, std::pair{1, 1}, std::pair{0, 1}}) {
    for (std::size_t p = 0; p < n; ++p) in[p] = tensor[p](i, j);
    map.Apply(in, out);
    for (std::size_t p = 0; p < n; ++p) averaged[p](i, j) = averaged[p](j, i) = out[p];
  }
  return averaged;
}

}  // namespace

void AverageStrainIncrement(const NonlocalMap& map, std::span<Eigen::Matrix2d> df) {
  std::vector<Eigen::Matrix2d> strain(df.size());
  for (std::size_t p = 0; p < df.size(); ++p) {
    const Eigen::Matrix2d g = df[p] - Eigen::Matrix2d::Identity();
    strain[p] = 0.5 * (g + g.transpose());
  }
  const std::vector<Eigen::Matrix2d> averaged = AverageSymmetric(map, strain);
  for (std::size_t p = 0; p < df.size(); ++p) {
    // Only where the average changed it: an unchanged increment keeps its
    // own bits (sym + skew need not add back to them exactly).
    if (averaged[p] == strain[p]) continue;
    const Eigen::Matrix2d g = df[p] - Eigen::Matrix2d::Identity();
    df[p] = Eigen::Matrix2d::Identity() + averaged[p] + 0.5 * (g - g.transpose());
  }
}

std::vector<Eigen::Matrix2d> AverageInPlaneStress(const NonlocalMap& map,
                                                  std::span<const Eigen::Matrix3d> stress) {
  std::vector<Eigen::Matrix2d> own(stress.size());
  for (std::size_t p = 0; p < stress.size(); ++p) {
    own[p] = 0.5 * (stress[p].topLeftCorner<2, 2>() + stress[p].topLeftCorner<2, 2>().transpose());
  }
  return AverageSymmetric(map, own);
}

}  // namespace rvehub::mpm
