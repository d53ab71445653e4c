// Contact-law kernels: small stateless functions, one formula each.
// Sign conventions: overlap δ > 0 in contact; normal force fn > 0 in
// compression (repulsion); tangential force ft along t = (−n_y, n_x) where n
// points from particle i to particle j; the force on i is −fn·n + ft·t.
#ifndef RVEHUB_RVE_SERVER_ENGINE_CONTACT_LAW_H_
#define RVEHUB_RVE_SERVER_ENGINE_CONTACT_LAW_H_

#include <algorithm>
#include <cmath>

#include "rve_server/values/material.h"

namespace rvehub::dem {

// r* = 2 r1 r2 / (r1 + r2), m (Guo & Zhao: kn = E·r*).
inline double EffectiveRadius(double r1, double r2) { return 2.0 * r1 * r2 / (r1 + r2); }

// Linear spring: kn = E·r* (N/m) with E in Pa; kt = (kt/kn)·kn.
inline double LinearNormalStiffness(double young, double r1, double r2) {
  return young * EffectiveRadius(r1, r2);
}

struct HertzResponse {
  double fn;  // N, normal force (4/3) E* sqrt(R* δ) δ
  double kn;  // N/m, tangent normal stiffness dfn/dδ = 2 E* sqrt(R* δ)
  double kt;  // N/m, Mindlin tangential stiffness 8 G* sqrt(R* δ)
};

// Hertz–Mindlin for two equal-material particles; E in Pa, radii and δ in m.
inline HertzResponse HertzMindlin(double young, double poisson, double r1, double r2,
                                  double overlap) {
  const double e_star = young / (2.0 * (1.0 - poisson * poisson));           // Pa
  const double g_star = young / (4.0 * (1.0 + poisson) * (2.0 - poisson));   // Pa, G/(2(2-ν))
  const double a = std::sqrt(r1 * r2 / (r1 + r2) * std::max(overlap, 0.0));  // m
  return {4.0 / 3.0 * e_star * a * overlap, 2.0 * e_star * a, 8.0 * g_star * a};
}

// The normal law of either contact model, with what the rest of a contact
// needs from it: fn (N), the tangent kn and the tangential kt (N/m), and the
// stored elastic energy ∫ fn dδ (J).
struct NormalResponse {
  double fn;
  double kn;
  double kt;
  double elastic;
};

// What the normal law reads of the material, taken once per pass.
struct NormalLawParams {
  double young;     // Pa, E
  double poisson;   // [-], ν (Hertz–Mindlin)
  double kt_ratio;  // [-], kt/kn (linear)
};
inline NormalLawParams NormalParams(const Material& m) {
  return {m.young_modulus, m.poisson_ratio, m.stiffness_ratio};
}

// The one dispatcher of the normal law: Hertz–Mindlin (kHertz) or linear
// springs with kn = `kn_linear` = LinearNormalStiffness (the step kernel
// caches it per pair; unused for Hertz). Overlap δ in m, radii in m.
template <bool kHertz>
inline NormalResponse NormalLaw(const NormalLawParams& p, double r1, double r2, double overlap,
                                double kn_linear) {
  if constexpr (kHertz) {
    const HertzResponse hz = HertzMindlin(p.young, p.poisson, r1, r2, overlap);
    return {hz.fn, hz.kn, hz.kt, 0.4 * hz.fn * overlap};  // ∫ fn dδ = (2/5) fn δ
  } else {
    const double fn = kn_linear * overlap;
    return {fn, kn_linear, p.kt_ratio * kn_linear, 0.5 * fn * overlap};
  }
}

// The same for the material's model chosen at run time (code outside the
// step kernel, which instantiates the model it runs).
inline NormalResponse NormalLaw(const Material& m, double r1, double r2, double overlap) {
  if (m.model == ContactModel::kHertzMindlin) {
    return NormalLaw<true>(NormalParams(m), r1, r2, overlap, 0.0);
  }
  return NormalLaw<false>(NormalParams(m), r1, r2, overlap,
                          LinearNormalStiffness(m.young_modulus, r1, r2));
}

// Coulomb limit |ft| ≤ μ·fn (N); returns the capped tangential force.
inline double CoulombCap(double ft, double fn, double friction) {
  const double limit = friction * std::max(fn, 0.0);
  return std::clamp(ft, -limit, limit);
}

// Rolling stiffness kr = kt·r1·r2·β, N·m/rad (Liang & Zhao eq. 24–28).
inline double RollingStiffness(double kt, double r1, double r2, double beta) {
  return kt * r1 * r2 * beta;
}

// Rolling moment limit |M| ≤ η·r_min·fn, N·m.
inline double RollingLimit(double eta, double r1, double r2, double fn) {
  return eta * std::min(r1, r2) * std::max(fn, 0.0);
}

// Bond strength c·min(r1, r2)², N, in tension and in shear (Guo et al. §2.4).
inline double BondStrength(double cohesion, double r1, double r2) {
  const double r = std::min(r1, r2);
  return cohesion * r * r;
}

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_ENGINE_CONTACT_LAW_H_
