#include "mpm_client/core/two_phase.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace rvehub::mpm {

SurfaceProfile::SurfaceProfile(double x0, double h, int nx)
    : x0_(x0), h_(h), top_(std::max(nx, 1), -std::numeric_limits<double>::infinity()) {}

int SurfaceProfile::Column(double x) const {
  const double i = std::floor((x - x0_) / h_);
  const int last = static_cast<int>(top_.size()) - 1;
  if (!(i >= 0)) return 0;  // and NaN
  return i > last ? last : static_cast<int>(i);
}

void SurfaceProfile::Add(double x, double top) {
  double& t = top_[Column(x)];
  t = std::max(t, top);
}

double SurfaceProfile::HeightAt(double x) const {
  const int i = Column(x);
  const double own = top_[i];
  // Toward the neighbour on x's side of its column's centre.
  const double s = (x - x0_) / h_ - (i + 0.5);  // in cells, −½ … ½ inside
  const int j = s >= 0.0 ? i + 1 : i - 1;
  if (!std::isfinite(own) || j < 0 || j >= static_cast<int>(top_.size()) ||
      !std::isfinite(top_[j])) {
    return own;
  }
  return own + std::abs(s) * (top_[j] - own);
}

double TerzaghiExcessPressure(double p0, double z_over_h, double tv) {
  constexpr double kPi = std::numbers::pi;
  double sum = 0.0;
  for (int m = 0; m < 100000; ++m) {
    const double a = (2 * m + 1) * kPi / 2.0;  // (2m+1)π/2
    const double term = (2.0 / a) * std::sin(a * z_over_h) * std::exp(-a * a * tv);
    sum += term;
    // The amplitude 2/a·exp(−a² Tv) bounds every later term; for Tv = 0 the
    // series converges only conditionally, so stop on the amplitude 1/a too.
    if (2.0 / a * std::exp(-a * a * tv) < 1e-12 || (tv == 0.0 && m > 20000)) break;
  }
  return p0 * sum;
}

double TerzaghiDegreeOfConsolidation(double tv) {
  constexpr double kPi = std::numbers::pi;
  double sum = 0.0;
  for (int m = 0; m < 100000; ++m) {
    const double a = (2 * m + 1) * kPi / 2.0;
    const double term = 2.0 / (a * a) * std::exp(-a * a * tv);
    sum += term;
    if (term < 1e-14) break;
  }
  return 1.0 - sum;
}

}  // namespace rvehub::mpm
