#include "mpm_client/two_phase.h"

#include <cmath>
#include <numbers>

namespace rvehub::mpm {

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
